"""Training losses of the regression models (paper Table 2, §3.4.1), as pure torch functions.

Every function takes predictions and targets of shape ``(batch, bins)`` (bins along the last
axis) and returns a scalar: the mean over the batch of a per-row quantity. CDFs are unshifted
cumulative sums from 0° (``F_i = p_0 + … + p_i``), the convention of the labels and metrics.

Terms (the names used in the Hydra model configs, ``loss.terms``):

``pmf_mse``   mean over bins of (p̂ − p)²
``cdf_mse``   mean over bins of (F̂ − F)²
``cdf_ks``    max over bins of |F̂ − F| (Kolmogorov–Smirnov statistic)
``pmf_kl``    KL(p̂ ‖ p) = Σ p̂ (log p̂ − log p), the direction written in §3.4.1
``pmf_kl_fwd``  KL(p ‖ p̂) = Σ p (log p − log p̂), the direction of torch's ``KLDivLoss``; the
              one Models 3–4 use (``config/hydra/model/m3.yaml`` says why: measured, ``pmf_kl``
              with sparse targets is dominated by the log floor of empty bins)

Numerical safety: KL terms work in log space. The predicted log-PMF comes straight from
``log_softmax`` (never ``log(softmax)``), the target's log is taken of ``max(p, eps)`` and
``0·log 0 = 0`` is honoured for the forward direction, so one-hot targets, empty bins and
huge logits give finite values and finite gradients.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

# Floor for target probabilities inside a logarithm (empty bins of one-hot or sparse PMFs).
LOG_FLOOR = 1e-12


def cdf_from_pmf(pmf: torch.Tensor) -> torch.Tensor:
    """Unshifted CDF: cumulative sum from bin 0 along the last axis."""
    return torch.cumsum(pmf, dim=-1)


def pmf_from_cdf(cdf: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`cdf_from_pmf`: p_0 = F_0, p_i = F_i − F_{i−1}."""
    return torch.diff(cdf, dim=-1, prepend=torch.zeros_like(cdf[..., :1]))


def mse(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean over rows of the per-row mean squared difference (= mean over all elements)."""
    return ((pred - target) ** 2).mean()


def ks(pred_cdf: torch.Tensor, target_cdf: torch.Tensor) -> torch.Tensor:
    """Mean over rows of max_i |F̂_i − F_i|."""
    return (pred_cdf - target_cdf).abs().amax(dim=-1).mean()


def kl_pred_target(log_pred: torch.Tensor, target: torch.Tensor, floor: float = LOG_FLOOR) -> torch.Tensor:
    """Mean over rows of KL(p̂ ‖ p) = Σ_i p̂_i (log p̂_i − log max(p_i, floor)).

    ``log_pred`` is the predicted log-PMF (from ``log_softmax``); ``target`` a PMF.
    """
    log_target = torch.log(torch.clamp(target, min=floor))
    p_hat = torch.exp(log_pred)
    return (p_hat * (log_pred - log_target)).sum(dim=-1).mean()


def kl_target_pred(log_pred: torch.Tensor, target: torch.Tensor, floor: float = LOG_FLOOR) -> torch.Tensor:
    """Mean over rows of KL(p ‖ p̂) = Σ_i p_i (log p_i − log p̂_i), with 0·log 0 = 0."""
    log_target = torch.log(torch.clamp(target, min=floor))
    terms = torch.where(target > 0, target * (log_target - log_pred), torch.zeros_like(target))
    return terms.sum(dim=-1).mean()


# A term maps (pred_pmf, pred_log_pmf, pred_cdf, true_pmf, true_cdf) -> scalar.
Term = Callable[[torch.Tensor, torch.Tensor | None, torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]


def _needs_log(name: str) -> bool:
    return name in ("pmf_kl", "pmf_kl_fwd")


TERMS: dict[str, Term] = {
    "pmf_mse": lambda p, lp, f, tp, tf: mse(p, tp),
    "cdf_mse": lambda p, lp, f, tp, tf: mse(f, tf),
    "cdf_ks": lambda p, lp, f, tp, tf: ks(f, tf),
    "pmf_kl": lambda p, lp, f, tp, tf: kl_pred_target(lp, tp),
    "pmf_kl_fwd": lambda p, lp, f, tp, tf: kl_target_pred(lp, tp),
}


def check_terms(weights: dict[str, float], has_log_pmf: bool) -> None:
    """Raise ValueError for unknown terms, or KL terms on an output without a log-PMF."""
    if not weights:
        raise ValueError("a model needs at least one loss term")
    for name in weights:
        if name not in TERMS:
            raise ValueError(f"unknown loss term {name!r} (known: {', '.join(TERMS)})")
        if _needs_log(name) and not has_log_pmf:
            raise ValueError(f"loss term {name!r} needs a softmax PMF output")


def composite(
    weights: dict[str, float],
    pred_pmf: torch.Tensor,
    pred_log_pmf: torch.Tensor | None,
    pred_cdf: torch.Tensor,
    true_pmf: torch.Tensor,
    true_cdf: torch.Tensor,
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Σ_k w_k · term_k. Returns the total and the unweighted terms (for the history)."""
    parts = {name: TERMS[name](pred_pmf, pred_log_pmf, pred_cdf, true_pmf, true_cdf) for name in weights}
    total = sum(float(w) * parts[name] for name, w in weights.items())
    return total, parts
