"""A prior for unseen parts: the analytic PMF blended with the training-mean PMF (issue #20).

The analytic PMF (:mod:`feeder.mechanics`, the dataset's ``pmf_analytic``) puts the mass within a
few degrees where the quasi-static theory holds and far off where it does not (jams, two fences,
a part that leaves the fence before it settles); the training-mean PMF is never sharp and never
far off. Their blend

    prior = λ · widen(analytic, σ) + (1 − λ) · mean_pmf,

with ``widen`` a wrapped Gaussian of σ bins (:func:`feeder.circular.wrapped_gaussian_smooth`;
σ = 0 leaves it alone), keeps the analytic peaks and hedges them. σ and λ are chosen on training
rows only, from given grids, by the mean CDF R² (:func:`fit_blend`). Measured on the default run's
dataset (docs/results.md, "Unseen parts"): every GroupKFold fold chose σ = 4, λ = 0.6.

The grids are the ``prior`` node of the Hydra training config (``config/hydra/train.yaml``), the
one source for the evaluation baseline (``baseline_analytic_prior``, :mod:`feeder.learn.evaluate`)
and for networks that start from the prior (``model.base: prior``, :mod:`feeder.learn.models`);
:func:`grids` reads and checks it. Everything else here is a pure function on arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError


@dataclass(frozen=True)
class Blend:
    sigma_bins: float  # width of the wrapped Gaussian that widens the analytic PMF (0: as is)
    weight: float  # λ: the analytic PMF's share; 1 − λ goes to the training-mean PMF
    score: float  # mean CDF R² of the blend on the rows it was fitted on


@dataclass(frozen=True)
class Grids:
    sigmas_bins: tuple[float, ...]  # candidate widths of the wrapped Gaussian (bins; 0: as is)
    weights: tuple[float, ...]  # candidate λ in [0, 1]


def grids(prior_cfg) -> Grids:
    """The checked grids of a ``prior`` config node (``sigmas_bins``, ``weights``); a missing key,
    an empty grid, a negative width or a weight outside [0, 1] is a one-line FeederError."""
    try:
        sigmas = tuple(float(s) for s in prior_cfg["sigmas_bins"])
        weights = tuple(float(w) for w in prior_cfg["weights"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"prior: needs lists sigmas_bins and weights of numbers ({err})") from None
    if not sigmas or not weights:
        raise FeederError("prior: sigmas_bins and weights must each hold at least one value")
    if not all(np.isfinite(sigmas)) or min(sigmas) < 0:
        raise FeederError(f"prior.sigmas_bins {list(sigmas)}: must be finite and >= 0")
    if not all(np.isfinite(weights)) or min(weights) < 0 or max(weights) > 1:
        raise FeederError(f"prior.weights {list(weights)}: must lie in [0, 1]")
    return Grids(sigmas, weights)


def _check_pmfs(name: str, pmf) -> np.ndarray:
    pmf = np.asarray(pmf, dtype=np.float64)
    if pmf.ndim != 2 or pmf.shape[1] < 2:
        raise FeederError(f"{name}: need rows of PMF bins, got shape {pmf.shape}")
    if not np.isfinite(pmf).all() or (pmf < 0).any():
        raise FeederError(f"{name}: PMF values must be finite and >= 0")
    if not np.allclose(pmf.sum(axis=1), 1.0, atol=1e-6):
        raise FeederError(f"{name}: every PMF row must sum to 1")
    return pmf


def widen(analytic, sigma_bins: float) -> np.ndarray:
    """Rows of ``analytic`` convolved with a wrapped Gaussian of ``sigma_bins`` (0: unchanged)."""
    from feeder.circular import wrapped_gaussian_smooth

    analytic = _check_pmfs("analytic PMF", analytic)
    if sigma_bins == 0:
        return analytic.copy()
    return wrapped_gaussian_smooth(analytic, float(sigma_bins))


def blend(analytic, mean_pmf, sigma_bins: float, weight: float) -> np.ndarray:
    """``weight · widen(analytic, sigma_bins) + (1 − weight) · mean_pmf`` for every row."""
    if not 0.0 <= weight <= 1.0:
        raise FeederError(f"blend weight {weight}: must lie in [0, 1]")
    mean_pmf = _check_pmfs("mean PMF", np.atleast_2d(mean_pmf))[0]
    return weight * widen(analytic, sigma_bins) + (1.0 - weight) * mean_pmf


def fit_blend(pmf, analytic, train_mask, sigmas, weights) -> Blend:
    """The (σ, λ) of the grids whose blend scores the best mean CDF R² on the training rows
    (the mean PMF is that of the same rows). Ties keep the first in grid order (σ outer)."""
    from feeder.labels.metrics import r2_cdf

    pmf, analytic = _check_pmfs("label PMF", pmf), _check_pmfs("analytic PMF", analytic)
    if pmf.shape != analytic.shape:
        raise FeederError(f"label PMFs {pmf.shape} and analytic PMFs {analytic.shape} differ in shape")
    train = np.asarray(train_mask, dtype=bool)
    if train.shape != (pmf.shape[0],) or not train.any():
        raise FeederError("fit_blend: the training mask must select at least one row")
    sigmas, weights = [float(s) for s in sigmas], [float(w) for w in weights]
    if not sigmas or not weights:
        raise FeederError("fit_blend: give at least one sigma and one weight")
    if min(sigmas) < 0:
        raise FeederError(f"fit_blend: sigmas {sigmas} must be >= 0")
    target = np.cumsum(pmf[train], axis=1)
    mean_pmf = pmf[train].mean(axis=0)
    best = None
    for sigma in sigmas:
        wide = widen(analytic[train], sigma)
        for weight in weights:
            if not 0.0 <= weight <= 1.0:
                raise FeederError(f"fit_blend: weight {weight} must lie in [0, 1]")
            pred = np.cumsum(weight * wide + (1.0 - weight) * mean_pmf, axis=1)
            score = float(r2_cdf(target, pred).mean())
            if best is None or score > best.score:
                best = Blend(sigma, weight, score)
    return best
