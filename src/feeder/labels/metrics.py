"""Orientation labels: yaw normalisation, PMF/CDF construction and the distribution metrics.

Everything here is a pure numpy function. Conventions (docs/data.md):

* A final yaw is mapped to ``[0, 360)`` by ``θ = (β + 360) mod 360``.
* ``bins`` equal bins cover ``[0, 360)``; bin ``i`` holds ``[i·w, (i+1)·w)`` with ``w = 360 / bins``.
* The histogram is smoothed by a *wrapped* (circular) Gaussian kernel of ``sigma`` bins whose
  weights are ``exp(-d² / 2σ²)`` over the circular bin distance ``d`` (every image of the kernel
  around the circle is summed), normalised to sum 1; the smoothed histogram is renormalised to a
  PMF summing to 1. ``sigma = 0`` means no smoothing.
* The CDF is the cumulative sum of the PMF from 0°.
* Metrics compare distributions row by row along the last axis and broadcast over leading axes:
  JS divergence in bits, W1 = Σ|ΔCDF|·w in degrees, KS = max|ΔCDF|, MSE = mean squared difference,
  and R² = 1 − SS_res / SS_tot of one CDF against its truth (see :func:`r2_cdf` for SS_tot = 0).
* Label frame (``labels.frame``): ``part`` measures the yaw of the part's own (CAD) frame, as the
  simulation records it; ``principal`` measures the yaw of its feature frame (the frame the DFT
  features are computed in, at ``frame_deg`` in the part's frame, :func:`feeder.parts.features.frame_deg`),
  i.e. ``θ + frame_deg``. :func:`shift_pmf` moves a PMF between the two.
* Partial levels use the first ``k %`` of *all* drops (``floor(drops · k / 100)`` drops in drop
  order), and only the ok drops among them enter the PMF (see :func:`partial_pmfs`).
"""

from __future__ import annotations

import math

import numpy as np

from feeder.circular import FULL_TURN_DEG, check_bins, normalize_yaw, wrapped_gaussian_smooth
from feeder.errors import FeederError

LABEL_FRAMES = ("principal", "part")  # labels.frame: the feature frame or the part file's own frame


# ----------------------------------------------------------------------------------------------
# PMF construction
# ----------------------------------------------------------------------------------------------
def histogram(yaws, bins: int) -> np.ndarray:
    """Counts of yaws (degrees, normalised to [0, 360) first) in ``bins`` equal bins (float64)."""
    bins = check_bins(bins)
    theta = normalize_yaw(np.ravel(yaws))
    if np.isnan(theta).any():
        raise FeederError("histogram: yaw angles must be finite (drop non-ok drops first)")
    idx = np.floor(theta * (bins / FULL_TURN_DEG)).astype(np.int64)
    idx = np.clip(idx, 0, bins - 1)  # guards θ·bins/360 rounding up to ``bins``
    return np.bincount(idx, minlength=bins).astype(np.float64)


def pmf_from_yaws(yaws, bins: int, sigma: float) -> np.ndarray:
    """Smoothed PMF (``bins`` values summing to 1) of a set of yaws in degrees."""
    yaws = np.ravel(np.asarray(yaws, dtype=np.float64))
    if yaws.size == 0:
        raise FeederError("pmf_from_yaws: no yaw angles")
    return wrapped_gaussian_smooth(histogram(yaws, bins), sigma)


def cdf(pmf) -> np.ndarray:
    """Cumulative sum of the PMF from 0° along the last axis."""
    return np.cumsum(np.asarray(pmf, dtype=np.float64), axis=-1)


def shift_pmf(pmf, delta_deg: float) -> np.ndarray:
    """The PMF of ``yaw + delta_deg`` given the PMF of ``yaw`` (circular, along the last axis).

    Whole-bin shifts are exact rolls; a fractional part ``f`` of a bin splits each bin's mass
    linearly between its two destination bins (``1 − f`` and ``f``), so mass is conserved.
    """
    p = np.asarray(pmf, dtype=np.float64)
    bins = p.shape[-1]
    if not math.isfinite(delta_deg):
        raise FeederError(f"shift_pmf: shift must be finite, got {delta_deg!r}")
    steps = (float(delta_deg) % FULL_TURN_DEG) * bins / FULL_TURN_DEG
    whole = int(math.floor(steps))
    frac = steps - whole
    if whole >= bins:  # steps rounded up to a full turn
        whole, frac = 0, 0.0
    out = np.roll(p, whole, axis=-1)
    if frac > 0.0:
        out = (1.0 - frac) * out + frac * np.roll(out, 1, axis=-1)
    return out


def level_drop_counts(drops: int, levels_pct) -> np.ndarray:
    """Number of drops (in drop order) used by each partial level: floor(drops · k / 100)."""
    levels = np.asarray(levels_pct, dtype=np.int64)
    if levels.ndim != 1 or levels.size == 0 or (levels < 1).any() or (levels > 100).any():
        raise FeederError(f"levels_pct must be percentages in 1..100, got {list(levels_pct)!r}")
    return (int(drops) * levels) // 100


def partial_pmfs(yaws_in_drop_order, levels_pct, bins: int, sigma: float, ok=None):
    """PMFs from the first k % of the drops, for every level k in ``levels_pct``.

    ``k %`` is of *all* drops (``floor(drops · k / 100)`` drops in drop order, ok or not); the ok
    drops among them make the PMF. ``ok`` is a boolean mask (default: the finite yaws). A level
    with no ok drop gets the uniform PMF (nothing is known yet); its count in the returned
    ``n_ok`` is 0 so callers can see it.

    Returns ``(pmfs (L, bins), n_ok (L,))``.
    """
    yaws = np.ravel(np.asarray(yaws_in_drop_order, dtype=np.float64))
    ok = np.isfinite(yaws) if ok is None else np.ravel(np.asarray(ok, dtype=bool))
    if ok.shape != yaws.shape:
        raise FeederError("partial_pmfs: ok mask and yaws differ in length")
    if not np.isfinite(yaws[ok]).all():
        raise FeederError("partial_pmfs: an ok drop has a non-finite yaw")
    bins = check_bins(bins)
    counts = level_drop_counts(yaws.size, levels_pct)
    theta = normalize_yaw(np.where(ok, yaws, 0.0))
    idx = np.clip(np.floor(theta * (bins / FULL_TURN_DEG)).astype(np.int64), 0, bins - 1)
    # cumulative histograms in drop order: hist of the first n drops = cum[n]
    hists = np.zeros((counts.size, bins))
    n_ok = np.zeros(counts.size, dtype=np.int64)
    for i, n in enumerate(counts):
        sel = idx[:n][ok[:n]]
        hists[i] = np.bincount(sel, minlength=bins)
        n_ok[i] = sel.size
    pmfs = np.full((counts.size, bins), 1.0 / bins)
    has = n_ok > 0
    if has.any():
        pmfs[has] = wrapped_gaussian_smooth(hists[has], sigma)
    return pmfs, n_ok


# ----------------------------------------------------------------------------------------------
# Metrics (last axis = bins; leading axes broadcast)
# ----------------------------------------------------------------------------------------------
def _pair(a, b):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    try:
        np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise FeederError(f"shapes {a.shape} and {b.shape} do not broadcast") from None
    return a, b


def _kl_to_mixture(p, m):
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0) / np.where(m > 0, m, 1.0)), 0.0)
    return terms.sum(axis=-1)


def js_divergence(p, q) -> np.ndarray:
    """Jensen–Shannon divergence in bits between PMFs (0 log 0 = 0); in [0, 1]."""
    p, q = _pair(p, q)
    if (p < 0).any() or (q < 0).any():
        raise FeederError("js_divergence: probabilities must be >= 0")
    m = 0.5 * (p + q)
    js = 0.5 * _kl_to_mixture(p, m) + 0.5 * _kl_to_mixture(q, m)
    return np.clip(js, 0.0, None)


def w1(cdf_a, cdf_b, bin_width_deg: float | None = None) -> np.ndarray:
    """Wasserstein-1 on unshifted CDFs: Σ|F_a − F_b| · bin width, in degrees.
    The bin width defaults to 360 / bins."""
    a, b = _pair(cdf_a, cdf_b)
    width = FULL_TURN_DEG / a.shape[-1] if bin_width_deg is None else float(bin_width_deg)
    return np.abs(a - b).sum(axis=-1) * width


def circular_w1(cdf_a, cdf_b, bin_width_deg: float | None = None) -> np.ndarray:
    """Wasserstein-1 on the circle, in degrees: the W1 of :func:`w1` minimised over where the
    circle is cut, ``min_c Σ|F_a − F_b − c| · w``, reached at ``c`` = the median of ``F_a − F_b``
    (Rabin, Delon & Gousseau 2011). Unlike :func:`w1` it does not depend on where 0° falls: two
    peaks 2° apart either side of 0° are 2° apart, not 358°."""
    a, b = _pair(cdf_a, cdf_b)
    width = FULL_TURN_DEG / a.shape[-1] if bin_width_deg is None else float(bin_width_deg)
    d = a - b
    return np.abs(d - np.median(d, axis=-1, keepdims=True)).sum(axis=-1) * width


def ks(cdf_a, cdf_b) -> np.ndarray:
    """Kolmogorov–Smirnov distance max|F_a − F_b| over the bins."""
    a, b = _pair(cdf_a, cdf_b)
    return np.abs(a - b).max(axis=-1)


def mse(a, b) -> np.ndarray:
    """Mean squared difference over the last axis."""
    a, b = _pair(a, b)
    return ((a - b) ** 2).mean(axis=-1)


def r2_cdf(cdf_true, cdf_pred) -> np.ndarray:
    """Per-configuration R² = 1 − SS_res / SS_tot over the bins of one CDF (sklearn convention).

    SS_tot = 0 happens for a constant true CDF (all mass in the first bin): R² is then 1.0 when
    the prediction is exact (SS_res = 0) and 0.0 otherwise, as sklearn's ``force_finite``.
    """
    t, p = _pair(cdf_true, cdf_pred)
    t, p = np.broadcast_arrays(t, p)
    ss_res = ((t - p) ** 2).sum(axis=-1)
    ss_tot = ((t - t.mean(axis=-1, keepdims=True)) ** 2).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = 1.0 - ss_res / ss_tot
    const = ss_tot == 0
    return np.where(const, np.where(ss_res == 0, 1.0, 0.0), r2)


def r2_cdf_best_cut(cdf_true, cdf_pred) -> np.ndarray:
    """:func:`r2_cdf` with the circle cut where it scores best: both CDFs are rebuilt from the
    bin ``c`` on (the same ``c`` for both) and the largest R² over the ``bins`` cuts is returned.

    :func:`r2_cdf` depends on where 0° falls: a prediction 2° off a peak that straddles 0° has a
    CDF jump at the other end of the axis and scores far below the same prediction of a peak at
    180°. Maximised over the common cut, R² no longer depends on the frame; it is an upper
    envelope of the paper's R² (the cut ``c = 0`` is one of the candidates), as
    :func:`circular_w1` is the lower envelope of :func:`w1`.

    Every cut at once, O(bins) per row (:func:`_r2_every_cut`); a row whose true CDF is constant
    under some cut (all its mass in one bin) is scored cut by cut as :func:`r2_cdf` scores it
    (:func:`_r2_cdf_best_cut_by_cuts`), so its exact 1.0 / 0.0 stays exact.
    """
    t, p = _pair(cdf_true, cdf_pred)
    t, p = np.broadcast_arrays(t, p)
    shape = t.shape[:-1]
    n = t.shape[-1]
    t2, p2 = t.reshape(-1, n), p.reshape(-1, n)
    r2, ss_tot = _r2_every_cut(t2, p2)
    best = r2.max(axis=-1)
    scale = np.maximum(1.0, np.abs(t2).max(axis=-1)) ** 2
    near_constant = (ss_tot <= _CONST_CDF_RTOL * n * scale[:, None]).any(axis=-1)
    if near_constant.any():
        best[near_constant] = _r2_cdf_best_cut_by_cuts(t2[near_constant], p2[near_constant])
    return best.reshape(shape)


_CONST_CDF_RTOL = 1e-9  # SS_tot this small (relative) at some cut: score that row cut by cut
# Bins of a PMF that differ by no more than this share of their mean are equal up to rounding:
# such a PMF is uniform, with no preferred orientation (:func:`is_uniform`).
UNIFORM_RTOL = 1e-9


def _r2_every_cut(t: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R² of the CDFs rebuilt from every cut ``c`` and their SS_tot, ``(rows, bins)`` each.

    Rebuilt from bin ``c`` on, the true CDF takes the values ``F_k − F_{c−1} + M·[k < c]`` (``F`` the
    CDF, ``M = F_{bins−1}`` its mass, ``F_{−1} = 0``) in the order ``k = c, c+1, …``; R² does not
    depend on that order, so with ``D = F_true − F_pred`` both sums follow from prefix sums:
    ``SS_res(c) = Σ_k (D_k + ΔM·[k < c] − D_{c−1})²`` and ``SS_tot(c)`` = the centred sum of
    squares of ``F_k + M·[k < c]`` (the shift ``−F_{c−1}`` drops out)."""
    n = t.shape[-1]
    m_t, m_p = t[:, -1:], p[:, -1:]
    c = np.arange(n, dtype=np.float64)[None, :]
    before = np.concatenate([np.zeros((t.shape[0], 1)), np.cumsum(t, axis=-1)[:, :-1]], axis=-1)  # Σ_{k<c}
    f = t - t.mean(axis=-1, keepdims=True)  # centred: SS_tot is shift-invariant, the sums stay small
    f_before = before - c * t.mean(axis=-1, keepdims=True)
    u1 = f.sum(axis=-1, keepdims=True) + m_t * c
    u2 = (f**2).sum(axis=-1, keepdims=True) + 2.0 * m_t * f_before + m_t**2 * c
    ss_tot = u2 - u1**2 / n
    d = t - p
    dm = m_t - m_p
    d_before = np.concatenate([np.zeros((d.shape[0], 1)), np.cumsum(d, axis=-1)[:, :-1]], axis=-1)
    a = np.concatenate([np.zeros((d.shape[0], 1)), d[:, :-1]], axis=-1)  # D_{c−1}
    s1 = d.sum(axis=-1, keepdims=True) + dm * c
    s2 = (d**2).sum(axis=-1, keepdims=True) + 2.0 * dm * d_before + dm**2 * c
    ss_res = np.maximum(s2 - 2.0 * a * s1 + n * a**2, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = 1.0 - ss_res / ss_tot
    return r2, ss_tot


def _r2_cdf_best_cut_by_cuts(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """:func:`r2_cdf_best_cut` one cut at a time (the definition; O(bins²) per row)."""
    zero = np.zeros(t.shape[:-1] + (1,))
    pmf_t = np.diff(t, axis=-1, prepend=zero)
    pmf_p = np.diff(p, axis=-1, prepend=zero)
    best = np.full(t.shape[:-1], -np.inf)
    for cut in range(t.shape[-1]):
        r2 = r2_cdf(
            np.cumsum(np.roll(pmf_t, -cut, axis=-1), axis=-1), np.cumsum(np.roll(pmf_p, -cut, axis=-1), axis=-1)
        )
        best = np.maximum(best, r2)
    return best


def ecdf_sup_distance(sample, reference) -> float:
    """sup_x |F_sample(x) − F_reference(x)| of two empirical CDFs (exact, no binning)."""
    a = np.sort(np.asarray(sample, dtype=np.float64))
    b = np.sort(np.asarray(reference, dtype=np.float64))
    if a.size == 0 or b.size == 0:
        raise FeederError("ecdf_sup_distance: empty sample")
    xs = np.concatenate([a, b])
    fa = np.searchsorted(a, xs, side="right") / a.size
    fb = np.searchsorted(b, xs, side="right") / b.size
    return float(np.abs(fa - fb).max())


def dkw_epsilon(n, alpha: float) -> np.ndarray:
    """Dvoretzky–Kiefer–Wolfowitz band half-width sqrt(ln(2/α) / 2n)."""
    n = np.asarray(n, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return np.sqrt(math.log(2.0 / alpha) / (2.0 * n))


def _climb(pmf) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """(pmf, owner, run_of, is_peak, bin width) of :func:`resting_orientations`' climbing."""
    p = np.asarray(pmf, dtype=np.float64)
    n = p.size
    if p.ndim != 1 or n < 1:
        raise FeederError(f"resting_orientations: need a 1-D PMF, got shape {p.shape}")
    width = FULL_TURN_DEG / n
    left, right = np.roll(p, 1), np.roll(p, -1)
    up = np.where(right >= left, (np.arange(n) + 1) % n, (np.arange(n) - 1) % n)
    step = np.where(np.maximum(left, right) > p, up, np.arange(n))  # a peak stays
    peak = np.arange(n)
    for _ in range(n):  # at most n climbs
        nxt = step[peak]
        if np.array_equal(nxt, peak):
            break
        peak = nxt
    # flat runs of peak bins are one peak: label each run by its first bin (circular)
    is_peak = step == np.arange(n)
    run_of = np.arange(n)
    if is_peak.all():
        run_of[:] = 0
    else:
        start = int(np.flatnonzero(~is_peak)[0])
        for k in range(1, n + 1):
            i = (start + k) % n
            j = (i - 1) % n
            if is_peak[i] and is_peak[j] and p[i] == p[j]:
                run_of[i] = run_of[j]
    owner = run_of[peak]
    return p, owner, run_of, is_peak, width


def is_uniform(pmf, rtol: float = UNIFORM_RTOL) -> bool:
    """Whether a PMF (any total > 0) is uniform up to rounding: its bins differ by at most ``rtol``
    of their mean. Such a PMF has no preferred orientation, and its climbing
    (:func:`resting_orientations`) would follow rounding noise to made-up peaks."""
    p = np.asarray(pmf, dtype=np.float64)
    if p.ndim != 1 or p.size < 1:
        raise FeederError(f"is_uniform: need a 1-D PMF, got shape {p.shape}")
    mean = float(p.mean())
    return bool(np.isfinite(p).all()) and mean > 0.0 and float(p.max() - p.min()) <= rtol * mean


def basin_owners(pmf) -> np.ndarray:
    """Each bin's basin, as :func:`resting_orientations` forms them: the first bin of the flat run
    of peak bins that the bin climbs to (wrap-around at 0/360)."""
    return _climb(pmf)[1]


def resting_orientations(pmf, top: int | None = None) -> list[tuple[float, float]]:
    """The modes of a circular PMF and the probability of each one's basin, largest first.

    Every bin climbs to its higher neighbour (the higher one when both are higher; wrap-around at
    0/360) until no neighbour is higher; bins that end on the same peak, or on one flat run of
    equal peak bins, form one basin. Returns ``(yaw_deg, mass)`` per basin: the yaw is the centre
    of the peak (bin centres, ``360 / bins`` degrees wide; the middle of a flat run), the mass
    the basin's total PMF. A flat PMF is one basin. ``top`` keeps the largest ``top``.
    """
    p, owner, run_of, is_peak, width = _climb(pmf)
    out = []
    for r in np.unique(owner):
        members = np.flatnonzero(run_of == r)  # the flat run of peak bins labelled r
        members = members[is_peak[members]]
        # the middle of the run along the circle, from its first bin r
        length = members.size
        centre = (r + 0.5 * (length - 1) + 0.5) * width % FULL_TURN_DEG
        mass = float(p[owner == r].sum())
        if mass > 0:  # a flat run of empty bins is no orientation
            out.append((float(centre), mass))
    out.sort(key=lambda t: -t[1])
    return out if top is None else out[: int(top)]
