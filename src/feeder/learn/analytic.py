"""The untrained analytic predictor: ``feeder predict --model analytic``.

It answers with the configuration's analytic push PMF (:mod:`feeder.mechanics`: quasi-static
pushing of the part's convex hull against each fence, with exit turns) over the drops that do not
jam, smoothed as
the study's labels are (``labels.sigma_bins``), in the part file's own frame. It reads no
training row. It is the evaluation tables' ``baseline_analytic_pmf`` (the dataset's
``pmf_analytic``, whose CDF is its cumulative sum) offered as a predictor: by circular W1 no trained
network beats it on unseen parts (``results/tables/groupkfold_*_paired.csv``; docs/results.md).

Its share of drops that jam is not in the PMF: :meth:`AnalyticModel.ok_mass` gives the share that
does not, which ``feeder predict`` prints and ``feeder recommend`` ranks by (the evaluation scores
the PMF on configurations that are not excluded as jammed). The class answers :meth:`predict`
like :class:`feeder.learn.spec.Predictor`, so
``feeder predict`` and ``feeder recommend`` use it in place of a network. It needs the part as an
STL (its outline): the PMFs come from :func:`feeder.learn.predict.push_inputs`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError

ANALYTIC_MODEL = "analytic"  # the --model value that names this predictor


@dataclass(frozen=True)
class AnalyticSpec:
    """What the commands read of a model's spec: its name and its number of yaw bins."""

    name: str
    bins: int


class AnalyticModel:
    """The analytic push PMF as a predictor over ``bins`` yaw bins, in the part's own frame."""

    label_frame = "part"
    inputs = "outline"  # what it reads of the part: the STL's outline, no DFT feature
    needs_push = True  # the push block: its ok mass (:meth:`ok_mass`)
    needs_analytic = True

    def __init__(self, bins: int):
        if int(bins) != bins or bins < 1:
            raise FeederError(f"the analytic predictor needs a positive number of bins, got {bins!r}")
        self.spec = AnalyticSpec(ANALYTIC_MODEL, int(bins))

    def predict(self, part_raw, feeder_raw, push_raw=None, analytic=None) -> tuple[np.ndarray, np.ndarray]:
        """(pmf, cdf) of each row: the rows' analytic PMFs, normalised, and their cumulative sums.
        ``part_raw``, ``feeder_raw`` and ``push_raw`` are not read (the PMFs already hold the
        configuration)."""
        if analytic is None:
            raise FeederError("the analytic predictor needs the configurations' analytic PMFs (the part's outline)")
        pmf = np.atleast_2d(np.asarray(analytic, dtype=np.float64))
        rows = np.atleast_2d(np.asarray(feeder_raw)).shape[0]
        if pmf.shape != (rows, self.spec.bins):
            raise FeederError(f"analytic PMFs of shape {pmf.shape}, need ({rows}, {self.spec.bins})")
        total = pmf.sum(axis=1, keepdims=True)
        if not np.all(np.isfinite(pmf)) or np.any(pmf < 0) or np.any(total <= 0):
            raise FeederError("the analytic PMFs must be finite, non-negative and hold some mass")
        pmf = pmf / total
        return pmf, np.cumsum(pmf, axis=1)

    def ok_mass(self, push_raw) -> np.ndarray:
        """The analytic share of drops that leave without jamming, per row of the push block
        (its ``ok_mass`` feature): the PMF itself is over the ok drops only, so a configuration
        that always jams needs this beside it."""
        from feeder.mechanics.features import PUSH_FEATURE_NAMES

        return np.atleast_2d(np.asarray(push_raw, dtype=np.float64))[:, PUSH_FEATURE_NAMES.index("ok_mass")]


def is_analytic(model_arg) -> bool:
    """Whether ``--model`` names the analytic predictor rather than a model folder."""
    return model_arg is not None and str(model_arg) == ANALYTIC_MODEL
