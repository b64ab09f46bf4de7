"""An estimate of a sampled-map label's own error, from a few stratified random audit drops.

A sampled-map label (:func:`feeder.sim.pushforward.pushforward_pmf`) is the push-forward of
the uniform initial yaw β through the *interpolated* map ``g`` of a design's samples; the label
it stands for is the push-forward through the simulator's map ``f``. Coupling the two by β gives
upper bounds on their distance that are expectations over β, so a few audit drops — initial yaws
drawn at random, one in each of ``k`` equal strata of the period, simulated for real — estimate
them without bias (stratification only lowers the variance):

* **circular W1** ≤ E_β[cost(g(β), f(β))] / m̂, where ``cost`` is the circular distance of the two
  final yaws' label bins (degrees), and when only one end is ok, the mean circular distance from
  that ok yaw to the label (the mass missing in one label is spread over the other); m̂ is the
  label's ok mass (labels are normalised over it). Misses of every kind count: an island of good
  drops between two jammed samples, a jam arc inside a basin, interpolation error inside a basin.
* **sup|ΔCDF|** ≤ max over the bin edges e of P_β(the mass at β crosses e) / m̂ (mass moving from
  bin a to bin b changes the CDF at every edge between them; a drop ok in one map only changes
  it everywhere), estimated on the audits that fall outside the design's unresolved intervals;
  inside those the half split is already bounded by :func:`feeder.sim.pushforward.label_cdf_bound`
  (the measure of the unresolved intervals), which is added.

Each estimate is the audit mean plus ``z`` standard errors (``z`` from the setting
``confidence``, one-sided normal), so it is an upper confidence bound on the coupling bound, which
is itself ≥ the error. The standard error of a few audits that all agree is zero: such an
estimate says nothing about an island narrower than a stratum that no audit touched. The bench
(``feeder bench-errest``, results/tables/design_error_estimate.csv) measures how often it covers.

:func:`targeted` is the design whose budget follows the scene: the adaptive refinement
(:func:`feeder.sim.adaptive.refine`) up to ``min_budget`` simulations, then rounds of ``audits``
audit drops; it stops as soon as the estimate is within the target errors (``target_w1_deg``,
``target_sup_cdf``) or the next round would pass ``cap``. Otherwise the audits join the samples
(they are real drops), refinement goes on for ``step`` more simulations (narrowing the
midpoint-check width by half whenever nothing is left to refine), and a fresh set of audits is
drawn. The label is that of every sample, the last audits included (they are simulations paid
for); the estimate is the last round's, made before those audits joined.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from feeder.circular import FULL_TURN_DEG, circular_distance, normalize_yaw
from feeder.errors import FeederError
from feeder.sim.adaptive import OK, Design, extend, refine

# Defaults of the targeted design for callers without a config (feeder simulate --stop target); the
# study's are sim.adaptive_target in config/config.yaml (the same values, reasoned there).
DEFAULT_TARGET = {
    "target_w1_deg": 1.5,  # below the budget-40 design's measured mean circular W1 (1.58 deg)
    "target_sup_cdf": 0.02,  # below its mean sup|dCDF| (0.0218)
    "min_budget": 24,  # n0 = 16 and a first round of midpoint checks
    "cap": 96,  # the largest budget the design bench simulates for real
    "audits": 8,  # half of n0: one audit per 45 deg of a full turn
    "step": 8,
    "confidence": 0.9,  # the coverage the issue asks for
}
TARGET_KEYS = ("target_w1_deg", "target_sup_cdf", "min_budget", "cap", "audits", "step", "confidence")


@dataclass(frozen=True)
class ErrorEstimate:
    """An upper estimate of a label's distance to the exact push-forward label.

    ``sup_cdf`` and ``circular_w1_deg``: the estimates. ``audits``: audit drops it rests on;
    ``misses``: audits whose label bin or status differs from the interpolated map's.
    ``split_sup``: the part from the unresolved intervals (:func:`label_cdf_bound`)."""

    sup_cdf: float
    circular_w1_deg: float
    audits: int
    misses: int
    split_sup: float


def check_target(target: dict, n0: int) -> dict:
    """The targeted design's settings (``sim.adaptive_target``) checked: a one-line FeederError
    for a target error ≤ 0, a minimum budget below ``n0``, a cap below the minimum budget plus
    one round of audits, fewer than 2 audits, a step < 1 or a confidence outside (0.5, 1)."""
    missing = [k for k in TARGET_KEYS if k not in target]
    if missing:
        raise FeederError(f"sim.adaptive_target lacks {', '.join(missing)}")
    for key in ("target_w1_deg", "target_sup_cdf"):
        v = target[key]
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise FeederError(f"sim.adaptive_target.{key} must be a number > 0, got {v!r}")
    for key in ("min_budget", "cap", "audits", "step"):
        v = target[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or int(v) != v:
            raise FeederError(f"sim.adaptive_target.{key} must be an integer, got {v!r}")
    if target["audits"] < 2:
        raise FeederError(f"sim.adaptive_target.audits must be at least 2, got {target['audits']!r}")
    if target["step"] < 1:
        raise FeederError(f"sim.adaptive_target.step must be at least 1, got {target['step']!r}")
    if target["min_budget"] < n0:
        raise FeederError(f"sim.adaptive_target.min_budget ({target['min_budget']}) must be >= sim.adaptive.n0 ({n0})")
    least = int(target["min_budget"]) + int(target["audits"])
    if target["cap"] < least:
        raise FeederError(
            f"sim.adaptive_target.cap ({target['cap']}) is below the minimum budget plus one round of audits ({least})"
        )
    c = target["confidence"]
    if not (isinstance(c, (int, float)) and 0.5 < c < 1):
        raise FeederError(f"sim.adaptive_target.confidence must be in (0.5, 1), got {c!r}")
    return {
        k: (float(target[k]) if k in ("target_w1_deg", "target_sup_cdf", "confidence") else int(target[k]))
        for k in TARGET_KEYS
    }


def audit_yaws(rng: np.random.Generator, k: int, offset_deg: float, period_deg: float) -> np.ndarray:
    """``k`` stratified random initial yaws over ``[offset, offset + period)``: one uniform draw in
    each of ``k`` equal strata, ascending (not reduced mod 360)."""
    if int(k) != k or k < 1:
        raise FeederError(f"audit_yaws: k must be a positive integer, got {k!r}")
    u = rng.uniform(0.0, 1.0, int(k))
    return offset_deg + period_deg * (np.arange(int(k)) + u) / int(k)


def _bin_of(yaw: np.ndarray, bins: int) -> np.ndarray:
    return np.clip(np.floor(normalize_yaw(yaw) / (FULL_TURN_DEG / bins)).astype(np.int64), 0, bins - 1)


def _mean_distance_to(pmf: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Mean circular distance (degrees) from each yaw to the label ``pmf`` (bin centres)."""
    bins = pmf.size
    centres = (np.arange(bins) + 0.5) * FULL_TURN_DEG / bins
    return circular_distance(yaw[:, None], centres[None, :]) @ pmf


def _in_intervals(beta: np.ndarray, spans: np.ndarray, period: float) -> np.ndarray:
    """Whether each β lies in one of the (start, end) intervals (``end`` may pass a period)."""
    inside = np.zeros(beta.size, dtype=bool)
    for start, end in np.asarray(spans).reshape(-1, 2):
        rel = np.mod(beta - start, period)
        inside |= rel < (end - start)
    return inside


def _copies(yaw: np.ndarray, design: Design, bins: int) -> np.ndarray:
    """(len(yaw), bins): each ok yaw's mass over the label bins, spread evenly over the copies
    of a symmetric design (final yaw + k · period)."""
    n = round(FULL_TURN_DEG / design.period_deg)
    out = np.zeros((yaw.size, bins))
    rows = np.repeat(np.arange(yaw.size), n)
    cols = _bin_of((yaw[:, None] + design.period_deg * np.arange(n)[None, :]).ravel(), bins)
    np.add.at(out, (rows, cols), 1.0 / n)
    return out


def audit_moves(design: Design, pmf: np.ndarray, final, status, interpolated) -> np.ndarray:
    """(k, bins): per audit drop, the signed change of the label (unnormalised, before
    smoothing) that replacing the interpolated outcome by the simulated one makes: +its mass in
    the simulated bin, −in the interpolated one, and for a drop ok in one map only the change of
    the normalisation (−``pmf`` times the ok difference). Zero for two failed outcomes."""
    bins = pmf.size
    final, status = np.asarray(final, dtype=np.float64), np.asarray(status).astype(str)
    g_final, g_status = np.asarray(interpolated[0], dtype=np.float64), np.asarray(interpolated[1]).astype(str)
    ok_f, ok_g = status == OK, g_status == OK
    moves = _copies(np.where(ok_f, final, 0.0), design, bins) * ok_f[:, None]
    moves -= _copies(np.where(ok_g, g_final, 0.0), design, bins) * ok_g[:, None]
    return moves - (ok_f.astype(float) - ok_g.astype(float))[:, None] * pmf[None, :]


def _distances(delta_pmf: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """sup|ΔCDF| and circular W1 (degrees) of signed label differences (rows), smoothed as the
    labels are (a wrapped Gaussian of ``sigma`` bins, linear in the difference)."""
    from feeder.circular import wrapped_gaussian_kernel

    bins = delta_pmf.shape[-1]
    kernel = wrapped_gaussian_kernel(bins, sigma)
    smooth = np.fft.irfft(np.fft.rfft(delta_pmf, axis=-1) * np.fft.rfft(kernel), n=bins, axis=-1)
    d_cdf = np.cumsum(smooth, axis=-1)
    w = FULL_TURN_DEG / bins
    sup = np.abs(d_cdf).max(axis=-1)
    w1 = np.abs(d_cdf - np.median(d_cdf, axis=-1, keepdims=True)).sum(axis=-1) * w
    return sup, w1


def split_terms(design: Design, pmf: np.ndarray) -> tuple[float, float]:
    """The jumps' share of the error, from their ends (not sampled by audits): ``(sup, w1)``,
    unnormalised. A jump's interval (ends disagree) gives each half its own end's outcome, so at
    most half its width over the period is misplaced, from one end's outcome to the other's: its
    mass crosses the CDF edges between the two ends' bins (every edge when one end is not ok)
    and travels their circular bin distance (or, for an ok end against a failed one, that yaw's
    mean circular distance to the label). Summed over the jumps without cancelling."""
    from feeder.sim.adaptive import intervals

    bins = pmf.size
    iv = intervals(design.yaws, design.final, design.status, design.period_deg, design.tolerance_deg)
    idx = np.flatnonzero(~iv.agree)
    if idx.size == 0:
        return 0.0, 0.0
    mass = 0.5 * iv.width[idx] / design.period_deg
    a = (iv.final_a[idx], iv.status_a[idx])
    b = (iv.final_b[idx], iv.status_b[idx])
    ok_a, ok_b = a[1] == OK, b[1] == OK
    w = FULL_TURN_DEG / bins
    edges = np.arange(bins)
    cross = np.zeros((idx.size, bins))
    cost = np.zeros(idx.size)
    both = ok_a & ok_b
    for j in np.flatnonzero(both):
        shifts = design.period_deg * np.arange(round(FULL_TURN_DEG / design.period_deg))
        ba, bb = _bin_of(a[0][j] + shifts, bins), _bin_of(b[0][j] + shifts, bins)
        d = np.abs(ba - bb)
        cost[j] = np.mean(np.minimum(d, bins - d)) * w
        lo, hi = np.minimum(ba, bb), np.maximum(ba, bb)
        cross[j] = np.mean((edges[None, :] >= lo[:, None]) & (edges[None, :] < hi[:, None]), axis=0)
    one = ok_a != ok_b
    if one.any():
        cost[one] = _mean_distance_to(pmf, np.where(ok_a, a[0], b[0])[one])
        cross[one] = 1.0
    return float(np.max(mass @ cross)), float(mass @ cost)


def island_terms(design: Design, pmf: np.ndarray, beta) -> tuple[float, float]:
    """The largest island an audit cannot have seen: ``(sup, w1)``, unnormalised. Between two
    samples that agree a whole basin or jam arc can hide (a band of good drops between two
    jammed samples); audits that all agree say nothing about one narrower than a stratum. The
    widest agreeing interval that holds no audit drop bounds the mass of such an island. Where
    that mass went is unknown, so it is charged its worst place: every CDF edge, and for W1 the
    largest mean circular distance from any yaw to the label (an island added to or removed from
    the label costs its mass times that distance; the interval's own ends say nothing about it).
    Charging the label's average distance instead covered the error on only 16 of 20 offsets of
    a reference with a 9.5° band of good drops between jammed samples (lshape-a,
    ``feeder bench-errest``)."""
    from feeder.sim.adaptive import intervals

    iv = intervals(design.yaws, design.final, design.status, design.period_deg, design.tolerance_deg)
    beta = np.asarray(beta, dtype=np.float64)
    hit = np.zeros(iv.start.size, dtype=bool)
    for j in np.flatnonzero(iv.agree):
        hit[j] = bool(np.any(np.mod(beta - iv.start[j], design.period_deg) < iv.width[j]))
    free = iv.agree & ~hit
    if not free.any():
        return 0.0, 0.0
    j = int(np.flatnonzero(free)[np.argmax(iv.width[free])])
    mass = float(iv.width[j] / design.period_deg)
    centres = (np.arange(pmf.size) + 0.5) * FULL_TURN_DEG / pmf.size
    farthest = float(_mean_distance_to(pmf, centres).max())
    return mass, mass * farthest


def estimate_error(
    design: Design, pmf: np.ndarray, ok_mass: float, beta, final, status, confidence: float, sigma: float
) -> ErrorEstimate:
    """The error estimate of a design's label from audit drops (see the module docstring)."""
    from feeder.sim.adaptive import intervals
    from feeder.sim.pushforward import map_yaws

    beta = np.asarray(beta, dtype=np.float64)
    k = beta.size
    if k < 2:
        raise FeederError(f"estimate_error: need at least 2 audit drops, got {k}")
    if not ok_mass > 0:
        raise FeederError(f"estimate_error: ok mass must be > 0, got {ok_mass!r}")
    z = NormalDist().inv_cdf(float(confidence))
    moves = audit_moves(design, pmf, final, status, map_yaws(design, beta))
    iv = intervals(design.yaws, design.final, design.status, design.period_deg, design.tolerance_deg)
    jumps = np.column_stack([iv.start[~iv.agree], iv.end[~iv.agree]])
    in_jump = _in_intervals(beta, jumps, design.period_deg)
    moves[in_jump] = 0.0  # the jumps' share is bounded from their ends (split_terms)
    total = moves.sum(axis=0)
    rows = np.vstack([total / k, (total[None, :] - moves) / (k - 1)])  # the estimate and its jackknife
    sup, w1 = _distances(rows, sigma)
    jack = lambda v: math.sqrt((k - 1) / k * float(np.sum((v[1:] - v[1:].mean()) ** 2)))  # noqa: E731
    s_sup, s_w1 = split_terms(design, pmf)
    i_sup, i_w1 = island_terms(design, pmf, beta)
    s_sup, s_w1 = s_sup + i_sup, s_w1 + i_w1
    misses = int(np.count_nonzero(np.abs(moves).max(axis=1) > 0))
    return ErrorEstimate(
        sup_cdf=float(min(1.0, (sup[0] + z * jack(sup) + s_sup) / ok_mass)),
        circular_w1_deg=float(min(FULL_TURN_DEG / 2, (w1[0] + z * jack(w1) + s_w1) / ok_mass)),
        audits=int(k),
        misses=misses,
        split_sup=float(min(1.0, s_sup / ok_mass)),
    )


def targeted(evaluate, seed: int, adaptive: dict, order: int, bins: int, sigma: float):
    """The design whose budget follows the scene (module docstring): ``(design, estimate,
    rounds)``. ``adaptive`` is ``sim.adaptive`` (n0, tolerance_deg, min_width_deg) with
    ``target`` = ``sim.adaptive_target``; the offset and the grid start are those of
    :func:`feeder.sim.simulate.run_design` for the same ``seed``; audits draw from their own
    stream of ``seed``. ``evaluate(yaws)`` as for :func:`feeder.sim.adaptive.refine`."""
    n0 = int(adaptive["n0"])
    t = check_target(adaptive.get("target") or {}, n0)
    period = FULL_TURN_DEG / order
    offset = float(np.random.default_rng(seed).uniform(0.0, period / n0))
    design = refine(
        evaluate,
        n0=n0,
        tolerance_deg=float(adaptive["tolerance_deg"]),
        min_width_deg=float(adaptive["min_width_deg"]),
        budget=t["min_budget"],
        offset_deg=offset,
        period_deg=period,
    )
    rng = np.random.default_rng([int(seed), t["audits"]])  # the audits' own stream
    rounds = 0
    while True:
        rounds += 1
        beta = audit_yaws(rng, t["audits"], design.offset_deg, period)
        final, status = evaluate(normalize_yaw(beta))
        final = np.asarray(final, dtype=np.float64)
        status = np.asarray(status).astype(str)
        est = estimate_or_worst(design, beta, final, status, bins, sigma, t["confidence"])
        within = est.circular_w1_deg <= t["target_w1_deg"] and est.sup_cdf <= t["target_sup_cdf"]
        room = t["cap"] - design.evaluations - t["audits"]
        if within or room < t["audits"] + 1:
            design = extend(design, evaluate, design.evaluations + beta.size, samples=(beta, final, status))
            return design, est, rounds
        budget = design.evaluations + t["audits"] + min(t["step"], room - t["audits"])
        grown = extend(design, evaluate, budget, samples=(beta, final, status))
        if grown.evaluations < budget:  # nothing left to refine at this width: check agreeing intervals finer
            grown = extend(grown, evaluate, budget, max_width_deg=0.5 * grown.max_width_deg)
        design = grown


def estimate_or_worst(design, beta, final, status, bins, sigma, confidence) -> ErrorEstimate:
    """:func:`estimate_error` of the design's label; the worst values when it has no ok mass."""
    from feeder.sim.pushforward import pushforward_pmf

    if not (design.status == OK).any():
        return ErrorEstimate(1.0, FULL_TURN_DEG / 2, int(np.size(beta)), int(np.size(beta)), 1.0)
    pmf, masses = pushforward_pmf(design, bins, sigma)
    return estimate_error(design, pmf, masses[OK], beta, final, status, confidence, sigma)
