"""The analytic PMF of a configuration: the final yaws of its drops binned in the label frame and
smoothed, as :func:`feeder.labels.metrics.histogram` and the labels bin them."""

from __future__ import annotations

import math

import numpy as np

from feeder.circular import FULL_TURN_DEG, normalize_yaw, wrapped_gaussian_smooth
from feeder.errors import FeederError
from feeder.mechanics.distribution import Distribution, analytic_distribution
from feeder.mechanics.fence import as_fence

PMF_BINS = 360  # labels.bins: 1° bins over [0, 360), as feeder.labels.metrics.histogram
DEFAULT_SMOOTH_DEG = 2.0  # circular Gaussian sigma of the analytic PMF (degrees)


# Yaws are snapped to this grid (degrees) before binning: round-off of 30° − 0° (29.999...) must
# not move a resting yaw into the bin below.
YAW_SNAP_DEG = 1e-9


def bin_masses(yaws, weights, bins: int) -> np.ndarray:
    theta = normalize_yaw(np.round(np.asarray(yaws, dtype=np.float64) / YAW_SNAP_DEG) * YAW_SNAP_DEG)
    idx = np.clip(np.floor(theta * (bins / FULL_TURN_DEG)).astype(np.int64), 0, bins - 1)
    return np.bincount(idx, weights=weights, minlength=bins).astype(np.float64)


def analytic_pmf(
    part,
    loc1,
    loc2,
    scene: dict | None = None,
    *,
    frame_deg: float = 0.0,
    smooth_deg: float = DEFAULT_SMOOTH_DEG,
    bins: int = PMF_BINS,
    mu: float | None = None,
    exit_turns: bool = True,
    distribution: Distribution | None = None,
) -> np.ndarray:
    """The analytic PMF of a configuration over ``bins`` equal yaw bins of [0, 360) in the label
    frame (``yaw + frame_deg``), over the ok (not jammed) drops, smoothed by a wrapped Gaussian of
    ``smooth_deg`` degrees (0: none). When every drop jams, the PMF of the same configuration
    without jams is returned (the label of such a configuration is excluded anyway): with
    ``distribution`` given, that needs its ``loc1``/``loc2`` (a FeederError without them), and it
    is built with the defaults of :func:`analytic_distribution` but ``mu`` and ``exit_turns`` (a
    caller whose distribution used other fences or settings builds its own)."""
    if int(bins) != bins or bins < 1:
        raise FeederError(f"bins must be a positive integer, got {bins!r}")
    if not (math.isfinite(smooth_deg) and smooth_deg >= 0):
        raise FeederError(f"smooth_deg must be finite and >= 0, got {smooth_deg!r}")
    if not math.isfinite(frame_deg):
        raise FeederError(f"frame_deg must be finite, got {frame_deg!r}")
    dist = distribution or analytic_distribution(part, loc1, loc2, scene, mu=mu, exit_turns=exit_turns)
    if dist.weights.sum() <= 0.0:
        if not (as_fence(loc1).present or as_fence(loc2).present):  # no fence to push the drops through again
            raise FeederError(
                "every drop of the given distribution jams: pass its loc1/loc2 (the PMF is then that of the "
                "configuration without jams) or a distribution without jams"
            )
        dist = analytic_distribution(part, loc1, loc2, scene, mu=mu, exit_turns=exit_turns, jams=False)
    hist = bin_masses(dist.yaws + frame_deg, dist.weights, int(bins))
    hist /= hist.sum()
    if smooth_deg == 0:
        return hist
    return wrapped_gaussian_smooth(hist, smooth_deg * bins / FULL_TURN_DEG)
