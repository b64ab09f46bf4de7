"""Labels as the exact push-forward of the uniform initial yaw through the drop map.

With one part per world the simulator is deterministic in the initial yaw β, so a configuration
is a map ``f(β) = (final yaw, status)`` and its label is the push-forward of the uniform measure
on β through ``f``. The adaptive design (:func:`feeder.sim.adaptive.refine`) samples ``f`` where it
jumps; :func:`pushforward_pmf` turns the samples into a label by interpolating ``f`` linearly
inside every resolved interval. Conventions (agreeing and disagreeing intervals, ``unresolved_share``)
as in :mod:`feeder.sim.adaptive`. Everything is a pure numpy function.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.circular import FULL_TURN_DEG, LABEL_BINS, LABEL_SIGMA_BINS, normalize_yaw, wrap180, wrapped_gaussian_smooth
from feeder.errors import FeederError
from feeder.sim.adaptive import OK, Design, intervals, unfold

DEFAULT_BINS, DEFAULT_SIGMA = LABEL_BINS, LABEL_SIGMA_BINS  # the labels' defaults
_POINT_IMAGE_DEG = 1e-12  # a linear segment shorter than this is a point mass
_ALL_OK_SLACK = 1e-12  # ok mass this close to 1 means every sampled drop was ok


def _segment_hist(lo: np.ndarray, length: np.ndarray, mass: np.ndarray, bins: int) -> np.ndarray:
    """Exact bin masses of uniform distributions on arcs ``[lo, lo + length]`` (lo in [0, 360),
    0 ≤ length ≤ 180), each carrying ``mass``; arcs shorter than a numeric floor are points."""
    hist = np.zeros(bins)
    w = FULL_TURN_DEG / bins
    point = length <= _POINT_IMAGE_DEG
    if point.any():
        idx = np.clip(np.floor(lo[point] / w).astype(np.int64), 0, bins - 1)
        np.add.at(hist, idx, mass[point])
    seg = ~point
    if seg.any():
        edges = w * np.arange(2 * bins + 1, dtype=np.float64)  # two turns: lo + length < 540
        lo_s, len_s, m_s = lo[seg], length[seg], mass[seg]
        chunk = max(1, int(2**22 // edges.size))  # bound the (k, edges) work array
        for s in range(0, lo_s.size, chunk):
            frac = np.clip((edges[None, :] - lo_s[s : s + chunk, None]) / len_s[s : s + chunk, None], 0.0, 1.0)
            per_bin = np.diff(frac, axis=1) * m_s[s : s + chunk, None]
            hist += per_bin.sum(axis=0).reshape(2, bins).sum(axis=0)
    return hist


def _check_sigma_bins(bins: int, sigma: float) -> None:
    if int(bins) != bins or bins < 1:
        raise FeederError(f"pushforward_pmf: bins must be a positive integer, got {bins!r}")
    if not (math.isfinite(sigma) and sigma >= 0):
        raise FeederError(f"pushforward_pmf: sigma must be a finite number of bins >= 0, got {sigma!r}")


def pushforward_pmf(
    design: Design, bins: int = DEFAULT_BINS, sigma: float = DEFAULT_SIGMA
) -> tuple[np.ndarray, dict[str, float]]:
    """The label of a design: the push-forward of the uniform β through the interpolated map.

    A design over a period ``360 / n`` is :func:`unfold`-ed first. Every interval carries
    ``width / 360`` of the probability:

    * agreeing ok ends: the final yaw runs linearly in β from one end's final yaw to the other's
      along the shorter arc (wrapping at 0/360); the mass is spread over the final-yaw bins in
      proportion to the overlap of that arc with each bin (all in one bin for a point image);
    * agreeing failed ends: all the mass goes to that status;
    * disagreeing ends: half the mass goes to each end's outcome (a point mass at an ok end's
      final yaw, or that end's failed status).

    Returns ``(pmf, masses)``: ``pmf`` is the histogram of the ok mass normalised to 1 and smoothed
    with :func:`metrics.wrapped_gaussian_smooth` (``sigma`` bins, 0 = none), as the workflow's
    labels; ``masses`` maps every status seen (``"ok"`` included, the ok mass) to its probability
    (they sum to 1). FeederError when there is no ok mass.
    """
    _check_sigma_bins(bins, sigma)
    bins = int(bins)
    d = unfold(design)
    iv = intervals(d.yaws, d.final, d.status, FULL_TURN_DEG, d.tolerance_deg)
    mass = iv.width / FULL_TURN_DEG
    masses: dict[str, float] = {}

    def add(status_arr, m):
        for s in np.unique(status_arr):
            masses[str(s)] = masses.get(str(s), 0.0) + float(m[status_arr == s].sum())

    good = iv.agree & (iv.status_a == OK)
    lin_a = iv.final_a[good]
    delta = wrap180(iv.final_b[good] - lin_a)
    lo = normalize_yaw(np.minimum(lin_a, lin_a + delta))
    hist = _segment_hist(lo, np.abs(delta), mass[good], bins)
    failed = iv.agree & (iv.status_a != OK)
    add(iv.status_a[failed], mass[failed])
    add(iv.status_a[good], mass[good])
    split = ~iv.agree
    for fin, st in ((iv.final_a[split], iv.status_a[split]), (iv.final_b[split], iv.status_b[split])):
        half = 0.5 * mass[split]
        add(st, half)
        ok_end = st == OK
        hist += _segment_hist(fin[ok_end], np.zeros(int(ok_end.sum())), half[ok_end], bins)
    if masses.get(OK, 0.0) <= 0.0 or hist.sum() <= 0.0:
        raise FeederError("pushforward_pmf: the design has no ok drop mass (every sampled drop failed)")
    return wrapped_gaussian_smooth(hist / hist.sum(), sigma), masses


def label_cdf_bound(design: Design, ok_mass: float) -> float:
    """A bound on sup|ΔCDF| between the design's label and the exact push-forward label.

    Only the unresolved mass U = ``unresolved_share`` is misplaced (interpolation error aside). The
    labels are normalised over the ok mass m̂ (``masses["ok"]``); the total-variation distance
    of the normalised labels is at most 1.5 · U / m̂ (U when m̂ = 1: every sample ok), and TV bounds
    sup|ΔCDF| from any origin and does not grow under smoothing. Capped at 1.
    """
    if not ok_mass > 0:
        raise FeederError(f"label_cdf_bound: ok mass must be > 0, got {ok_mass!r}")
    u = design.unresolved_share
    all_ok = ok_mass >= 1.0 - _ALL_OK_SLACK
    return float(min(1.0, u if all_ok else 1.5 * u / ok_mass))


def map_yaws(design: Design, beta) -> tuple[np.ndarray, np.ndarray]:
    """The interpolated drop map at initial yaws ``beta`` (degrees, any real values): linear along
    the shorter arc inside agreeing ok intervals, the nearer end's outcome inside disagreeing ones
    (the rule of :func:`pushforward_pmf`). Returns ``(final_deg, status)``; final yaws in [0, 360),
    NaN for failed drops."""
    d = unfold(design)
    iv = intervals(d.yaws, d.final, d.status, FULL_TURN_DEG, d.tolerance_deg)
    beta = np.asarray(beta, dtype=np.float64)
    # position relative to the first sample, in [0, 360): intervals tile [y0, y0 + 360)
    rel = np.mod(beta - d.yaws[0], FULL_TURN_DEG) + d.yaws[0]
    k = np.clip(np.searchsorted(d.yaws, rel, side="right") - 1, 0, d.yaws.size - 1)
    t = (rel - iv.start[k]) / iv.width[k]
    agree = iv.agree[k]
    right = ~agree & (t >= 0.5)
    status = np.where(right, iv.status_b[k], iv.status_a[k])
    lin = normalize_yaw(iv.final_a[k] + t * wrap180(iv.final_b[k] - iv.final_a[k]))
    final = np.where(agree, lin, np.where(right, iv.final_b[k], iv.final_a[k]))
    final = np.where(status == OK, final, np.nan)
    return final, status


def emulate_drops(design: Design, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` i.i.d. drops through the interpolated map, for studies that need i.i.d. drops.

    Initial yaws are uniform on [0, 360) from ``numpy.random.default_rng(seed)``; each is mapped
    by :func:`map_yaws`. Returns ``(final_deg, status)`` in drop order; final yaws are in
    [0, 360), NaN for failed drops.
    """
    if int(n) != n or n < 0:
        raise FeederError(f"emulate_drops: n must be a non-negative integer, got {n!r}")
    beta = np.random.default_rng(seed).uniform(0.0, FULL_TURN_DEG, int(n))
    return map_yaws(design, beta)
