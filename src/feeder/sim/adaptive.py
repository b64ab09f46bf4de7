"""The adaptive initial-yaw design: samples of the drop map, refined where it jumps.

With one part per world the simulator is deterministic in the initial yaw β, so a configuration
is a map ``f(β) = (final yaw, status)``. ``f`` is piecewise smooth (basins that map an interval of β to a narrow,
slowly drifting range of final yaws; jumps between basins; arcs of failed drops) and sometimes
has chaotic bands. :func:`refine` samples ``f`` adaptively where it jumps (``feeder simulate
--yaw-sampling adaptive``, :mod:`feeder.sim.simulate`); the label of the samples is their
push-forward (:func:`feeder.sim.pushforward.pushforward_pmf`).

Everything is a pure numpy function. Conventions:

* Angles are in degrees. Final yaws are reduced to ``[0, 360)`` (:func:`feeder.circular.normalize_yaw`);
  a non-ok drop's final yaw is NaN. The *circular distance* of two yaws is
  ``|((a − b + 180) mod 360) − 180|`` ∈ [0, 180].
* A design covers one *period* ``[offset, offset + period)`` of initial yaws; the stored
  ``Design.yaws`` are sorted and *not* reduced mod 360 (so intervals increase); the yaws handed to
  ``evaluate`` are reduced to ``[0, 360)``. Sample ``i`` starts the interval
  ``[β_i, β_{i+1})``; the last one wraps to ``β_0 + period``, whose outcome is that of ``β_0``
  with the final yaw turned by ``period`` (``f(β + P) = f(β) + P``: exact for ``P = 360``, and
  for ``P = 360 / n`` when the part has n-fold rotational symmetry, see
  :mod:`feeder.parts.symmetry` and :func:`unfold`).
* Two ends of an interval *agree* when they have the same status and, if that status is ``ok``,
  their final yaws are at most ``tolerance_deg`` apart on the circle, or the interval continues
  its neighbours' slopes (a steep smooth stretch, see :func:`_continues_linearly`). Inside an agreeing ok
  interval ``f`` is taken to be linear in β along the shorter arc between the two final yaws;
  inside an agreeing failed interval every drop has that status. A *disagreeing* interval is
  unresolved: its mass is split half to each end's outcome (the left half of the interval takes
  the left end's outcome) — the stratified treatment of a jump or a chaotic band.
* ``unresolved_share`` (``label_bound`` until 2026-11-27: not a bound on the label's error, which
  islands between agreeing samples escape; :mod:`feeder.sim.errest` estimates that) is the measure
  of the unresolved intervals divided by the period: the most
  probability mass the label can have misplaced (interpolation error inside agreeing intervals
  is not counted; it is zero for maps that are linear in every basin). Unresolved are:

  - the disagreeing intervals (each jump leaves one, at most ``min_width_deg`` wide once
    bisected), and agreeing stretches of total width ≤ ``band_gap_deg`` between two of them;
  - *chaotic bands*: a run of such closed-up intervals holding at least ``CHAOS_MIN_JUMPS`` = 2
    jumps, merged with agreeing stretches ≤ ``max_width_deg`` between two bands. Inside a band
    two ends may agree by chance, so the whole band counts. Refinement samples a band, and the
    intervals within ``band_gap_deg`` of its ends, down to ``min_width_deg``: while the outcome
    keeps switching the band grows, so a band is explored until ``band_gap_deg`` of agreement
    on each side. Agreeing intervals in that neighbourhood still wider than ``min_width_deg``
    when the budget runs out count as unresolved too. A basin narrower than ``band_gap_deg``
    looks like the start of a band at this resolution and is treated as one (a few extra
    simulations; its mass, < band_gap / period, is counted). To find bands whose edges look
    clean, refinement also samples ``edge_check_deg`` on both sides of every jump bisected down
    to ``min_width_deg`` at that width: a band's first switches show up there.

  The bound holds for the map as sampled: a basin or band that no sample touched is not in it
  (the midpoint checks of ``max_width_deg`` limit how wide such a thing can be). See
  :func:`feeder.sim.pushforward.label_cdf_bound` for the bound on the normalised, smoothed label's CDF.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from feeder.circular import FULL_TURN_DEG, circular_distance, normalize_yaw, wrap180
from feeder.errors import FeederError

OK = "ok"  # the status of a drop that made it (feeder.sim.drops.STATUSES[0]); kept here: no pybullet import

# Defaults of :func:`refine` (the reasoning is in its docstring).
DEFAULT_N0 = 16  # initial grid samples per period (22.5° apart over a full turn)
DEFAULT_TOLERANCE_DEG = 2.0  # two 1° label bins: ends closer than this are one basin
DEFAULT_MIN_WIDTH_DEG = 0.5  # half a 1° label bin: an unresolved jump misplaces ≤ 0.5/360 ≈ 0.0014
DEFAULT_BUDGET = 64  # simulations per period; 40–70 reached sup|ΔCDF| 0.002–0.009
DEFAULT_UNSEEN_BASIN_FRACTION = 1.0 / 32.0  # max_width = period / 32 (11.25° over a full turn)
DEFAULT_BAND_GAP_FACTOR = 4.0  # band_gap = 4 · min_width (2° at the default min_width)
DEFAULT_EDGE_CHECK_FACTOR = 2.0  # edge_check = 2 · min_width (1°): both sides of a jump sampled finely
CHAOS_MIN_JUMPS = 2  # jumps within band_gap of each other that make a chaotic band (a

_PERIOD_REL_TOL = 1e-9  # |n · period − 360| allowed, relative to 360
MAX_SMOOTH_TURN_DEG = 90.0  # a change of final yaw larger than this across one interval is never a slope
_WIDTH_DECIMALS = 9  # widths rounded to this many decimals before ranking (ties decided by rule, not round-off)
_WIDTH_SLACK = 1e-9  # relative: a width within round-off of a threshold is not "wider"


Evaluate = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray]"]


def _turns(period_deg: float) -> int:
    """n = 360 / period as an integer, or FeederError when the period does not divide 360."""
    if not (math.isfinite(period_deg) and 0 < period_deg <= FULL_TURN_DEG):
        raise FeederError(f"period_deg must be in (0, 360], got {period_deg!r}")
    n = round(FULL_TURN_DEG / period_deg)
    if abs(n * period_deg - FULL_TURN_DEG) > _PERIOD_REL_TOL * FULL_TURN_DEG:
        raise FeederError(
            f"period_deg {period_deg:g} does not divide 360 (360 / period = {FULL_TURN_DEG / period_deg:g})"
        )
    return int(n)


def grid_yaws(n: int, offset_deg: float = 0.0, period_deg: float = FULL_TURN_DEG) -> np.ndarray:
    """The ``grid`` design: ``offset + period · i / n`` for i = 0..n−1, reduced to [0, 360).

    Returned in that order (ascending from the offset, so it wraps past 360 once at most).
    """
    if int(n) != n or n < 1:
        raise FeederError(f"grid_yaws: n must be a positive integer, got {n!r}")
    if not math.isfinite(offset_deg):
        raise FeederError(f"grid_yaws: offset_deg must be finite, got {offset_deg!r}")
    _turns(period_deg)
    return normalize_yaw(_grid(int(n), float(offset_deg), float(period_deg)))


def _grid(n: int, offset: float, period: float) -> np.ndarray:
    return offset + period * np.arange(n, dtype=np.float64) / n


# Design
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Design:
    """Samples of the drop map over one period, and what they leave unresolved.

    ``yaws``: sorted initial yaws in ``[offset_deg, offset_deg + period_deg)`` (degrees, not
    reduced mod 360). ``final``: final yaws in [0, 360), NaN where the status is not ok.
    ``status``: one status string per sample. ``evaluations``: simulations run (``len(yaws)``);
    ``calls``: batches handed to ``evaluate``. ``unresolved``: (k, 2) intervals ``(start, end)``
    (``end`` may pass ``offset + period`` for the wrapping interval) counted in ``unresolved_share``
    = their total width / period. ``unchecked``: agreeing intervals still wider than
    ``max_width_deg`` because the budget ran out (not in ``unresolved_share``: they may hide a basin).
    """

    yaws: np.ndarray
    final: np.ndarray
    status: np.ndarray
    evaluations: int
    calls: int
    unresolved: np.ndarray
    unresolved_share: float
    unchecked: np.ndarray
    period_deg: float
    offset_deg: float
    tolerance_deg: float
    min_width_deg: float
    max_width_deg: float
    band_gap_deg: float
    edge_check_deg: float


@dataclass(frozen=True)
class Intervals:
    start: np.ndarray
    end: np.ndarray
    final_a: np.ndarray
    final_b: np.ndarray  # end's final yaw, continued by the period for the wrapping interval
    status_a: np.ndarray
    status_b: np.ndarray
    agree: np.ndarray

    @property
    def width(self) -> np.ndarray:
        return self.end - self.start


def intervals(yaws, final, status, period: float, tolerance: float) -> Intervals:
    """The circular intervals between consecutive samples and whether their ends agree."""
    end = np.append(yaws[1:], yaws[0] + period)
    final_b = np.append(final[1:], normalize_yaw(final[0] + period))
    status_b = np.append(status[1:], status[0])
    same = status == status_b
    ok = status == OK
    with np.errstate(invalid="ignore"):
        close = circular_distance(final, final_b) <= tolerance
        linear = _continues_linearly(final, final_b, end - yaws, same & ok, tolerance)
    agree = same & (~ok | close | linear)
    return Intervals(yaws, end, final, final_b, status, status_b, agree)


def _continues_linearly(final_a, final_b, width, ok_pair, tolerance: float) -> np.ndarray:
    """Ok intervals whose change of final yaw is what both neighbouring ok intervals' slopes
    predict, within ``tolerance``: a steep but smooth stretch of the map (with no fence in reach
    the map is the identity, 22.5° of final yaw over 22.5° of β), not a jump between flat basins.

    Guards against what could pass for a slope: a change of more than ``MAX_SMOOTH_TURN_DEG``
    (two basins half a turn apart alternate with wrapped changes of one sign), and a neighbour
    narrower than half the interval (a slope from a short neighbour extrapolates its noise).
    A staircase with exactly one sample per step still aliases into a ramp; the midpoint checks
    of ``max_width_deg`` sample every interval at least that finely."""
    delta = wrap180(final_b - final_a)
    slope = delta / width
    if delta.size < 3:
        return np.zeros(delta.size, dtype=bool)
    turn_ok = ok_pair & (np.abs(delta) <= MAX_SMOOTH_TURN_DEG)

    def predicted_by(shift: int) -> np.ndarray:  # shift 1: the left neighbour, -1: the right one
        wide = np.roll(width, shift) >= 0.5 * width
        return np.roll(turn_ok, shift) & wide & (np.abs(delta - np.roll(slope, shift) * width) <= tolerance)

    return turn_ok & predicted_by(1) & predicted_by(-1)


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Maximal circular runs of True in ``mask`` as index arrays (one run if all True)."""
    m = mask.size
    if not mask.any():
        return []
    if mask.all():
        return [np.arange(m)]
    first_false = int(np.flatnonzero(~mask)[0])
    runs, cur = [], []
    for step in range(1, m + 1):
        j = (first_false + step) % m
        if mask[j]:
            cur.append(j)
        elif cur:
            runs.append(np.asarray(cur))
            cur = []
    if cur:
        runs.append(np.asarray(cur))
    return runs


def _close_gaps(flag: np.ndarray, width: np.ndarray, gap: float) -> np.ndarray:
    """``flag`` plus every run of unflagged intervals, lying between two flagged ones, whose
    total width is ≤ ``gap`` (on a circle every unflagged run lies between flagged ones)."""
    out = flag.copy()
    if flag.any():
        for run in _runs(~flag):
            if width[run].sum() <= gap:
                out[run] = True
    return out


def _neighbourhood(band: np.ndarray, width: np.ndarray, reach: float) -> np.ndarray:
    """Intervals outside the band runs that start or end less than ``reach`` away from one."""
    near = np.zeros_like(band)
    m = band.size
    for run in _runs(band):
        if run.size == m:
            break
        for direction, edge in ((1, run[-1]), (-1, run[0])):
            dist, j = 0.0, (edge + direction) % m
            while not band[j] and dist < reach:
                near[j] = True
                dist += width[j]
                j = (j + direction) % m
    return near & ~band


@dataclass(frozen=True)
class _Classes:
    unresolved: np.ndarray  # counted in unresolved_share
    fine: np.ndarray  # to be bisected down to min_width: jumps, bands and their surroundings


def _classify(iv: Intervals, min_width: float, max_width: float, band_gap: float, edge_check: float = 0.0) -> _Classes:
    """Jumps, chaotic bands and their neighbourhoods (see the module docstring)."""
    width = iv.width
    jump = ~iv.agree
    closed = _close_gaps(jump, width, band_gap)
    band = np.zeros_like(jump)
    for run in _runs(closed):
        if jump[run].sum() >= CHAOS_MIN_JUMPS:
            band[run] = True
    band = _close_gaps(band, width, max_width) if band.any() else band
    near = _neighbourhood(band, width, band_gap)
    coarse = width > min_width * (1.0 + _WIDTH_SLACK)
    # both sides of every jump bisected to the end: a band's first switch shows up there
    done = jump & ~coarse
    edge = _neighbourhood(done, width, edge_check) if edge_check > 0 else np.zeros_like(jump)
    return _Classes(unresolved=closed | band | (near & coarse), fine=jump | band | near | edge)


def _check_evaluation(yaws: np.ndarray, result) -> tuple[np.ndarray, np.ndarray]:
    try:
        final, status = result
    except (TypeError, ValueError):
        raise FeederError("refine: evaluate must return (final_deg, status) arrays") from None
    final = np.ravel(np.asarray(final, dtype=np.float64))
    status = np.ravel(np.asarray(status)).astype(str)
    if final.shape != yaws.shape or status.shape != yaws.shape:
        raise FeederError(
            f"refine: evaluate returned {final.size} final yaws and {status.size} statuses for {yaws.size} yaws"
        )
    ok = status == OK
    if not np.isfinite(final[ok]).all():
        raise FeederError("refine: evaluate returned a non-finite final yaw for an ok drop")
    return np.where(ok, normalize_yaw(np.where(ok, final, 0.0)), np.nan), status


def _refine_settings(
    n0, tolerance_deg, min_width_deg, budget, offset_deg, period_deg, max_width_deg, band_gap_deg, edge_check_deg
) -> tuple[int, int, float, float, float, float, float]:
    """:func:`refine`'s settings checked, defaults filled in: ``(n0, budget, period, offset,
    max_width, band_gap, edge_check)``; a one-line FeederError for any bad value."""
    if int(n0) != n0 or n0 < 2:
        raise FeederError(f"refine: n0 must be an integer >= 2, got {n0!r}")
    if int(budget) != budget or budget < n0:
        raise FeederError(f"refine: budget ({budget!r}) must be an integer >= n0 ({n0})")
    if not (math.isfinite(tolerance_deg) and tolerance_deg > 0):
        raise FeederError(f"refine: tolerance_deg must be > 0, got {tolerance_deg!r}")
    if not (math.isfinite(min_width_deg) and min_width_deg > 0):
        raise FeederError(f"refine: min_width_deg must be > 0, got {min_width_deg!r}")
    if not math.isfinite(offset_deg):
        raise FeederError(f"refine: offset_deg must be finite, got {offset_deg!r}")
    _turns(period_deg)
    n0, budget, period = int(n0), int(budget), float(period_deg)
    if max_width_deg is None:
        max_width = max(period * DEFAULT_UNSEEN_BASIN_FRACTION, float(min_width_deg))
    else:
        max_width = float(max_width_deg)
    if not (math.isfinite(max_width) and max_width >= min_width_deg):
        raise FeederError(f"refine: max_width_deg ({max_width!r}) must be >= min_width_deg ({min_width_deg!r})")
    band_gap = DEFAULT_BAND_GAP_FACTOR * min_width_deg if band_gap_deg is None else float(band_gap_deg)
    if not (math.isfinite(band_gap) and band_gap >= 0):
        raise FeederError(f"refine: band_gap_deg must be >= 0, got {band_gap!r}")
    edge_check = DEFAULT_EDGE_CHECK_FACTOR * min_width_deg if edge_check_deg is None else float(edge_check_deg)
    if not (math.isfinite(edge_check) and edge_check >= 0):
        raise FeederError(f"refine: edge_check_deg must be >= 0, got {edge_check!r}")
    offset = float(normalize_yaw(offset_deg))

    return n0, budget, period, offset, max_width, band_gap, edge_check


def _next_midpoints(
    iv: Intervals, min_width, max_width, band_gap, edge_check, room: int, offset: float, period: float
) -> np.ndarray:
    """The initial yaws of :func:`refine`'s next round: the midpoints of the intervals that need
    one (jumps, bands and their surroundings bisected down to ``min_width``; agreeing intervals
    wider than ``max_width`` checked), widest first (ties: disagreeing before agreeing, then by
    position), at most ``room``, inside ``[offset, offset + period)``. Empty when none needs one."""
    fine = _classify(iv, min_width, max_width, band_gap, edge_check).fine
    width = iv.width
    mid = 0.5 * (iv.start + iv.end)
    inside = (mid > iv.start) & (mid < iv.end)  # float guard for absurdly narrow intervals
    limit = np.where(fine, min_width, max_width) * (1.0 + _WIDTH_SLACK)
    want = inside & (width > limit)
    if not want.any():
        return np.empty(0)
    idx = np.flatnonzero(want)
    ranked = -np.round(width[idx], _WIDTH_DECIMALS)
    order = np.lexsort((iv.start[idx], iv.agree[idx], ranked))  # last key is primary
    new = mid[idx[order[:room]]]
    return np.where(new >= offset + period, new - period, new)


def _merge_samples(samples: tuple, new: tuple) -> tuple:
    """``(yaws, final, status)`` with a round's samples added, sorted by initial yaw."""
    yaws, final, status = (np.concatenate([old, more]) for old, more in zip(samples, new))
    perm = np.argsort(yaws, kind="stable")
    return yaws[perm], final[perm], status[perm]


def refine(
    evaluate: Evaluate,
    n0: int = DEFAULT_N0,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
    min_width_deg: float = DEFAULT_MIN_WIDTH_DEG,
    budget: int = DEFAULT_BUDGET,
    offset_deg: float = 0.0,
    period_deg: float = FULL_TURN_DEG,
    *,
    max_width_deg: float | None = None,
    band_gap_deg: float | None = None,
    edge_check_deg: float | None = None,
    stop_if_none_ok: bool = False,
) -> Design:
    """Sample the drop map over one period, bisecting where it jumps, within a budget.

    Starts from the grid ``offset + period · i / n0`` and then runs *rounds*: each round
    collects every interval that needs its midpoint simulated and hands all those midpoints to
    ``evaluate`` in one batch (one call per round, so the caller can run a batch in one world).
    ``evaluate(yaws)`` gets initial yaws in [0, 360) and returns ``(final_deg, status)``; final
    yaws of non-ok drops are ignored.

    An interval (circular: the last sample's runs to the first + period) needs its midpoint when

    * its ends disagree (different status, or both ok and more than ``tolerance_deg`` apart on
      the circle) and it is wider than ``min_width_deg`` (bisection of a jump);
    * it belongs to a chaotic band or lies within ``band_gap_deg`` of one (see the module
      docstring) and is wider than ``min_width_deg`` (ends agreeing by chance prove nothing
      there);
    * it lies within ``edge_check_deg`` of a jump already bisected down to ``min_width_deg`` and
      is wider than ``min_width_deg`` (the edge check: where a chaotic band begins, its first
      switches are right next to the jump into it), or
    * its ends agree but it is wider than ``max_width_deg`` (a midpoint check: an agreeing
      interval can hide a whole basin; after the checks no agreeing interval is wider than
      ``max_width_deg``, so no basin wider than that can be missed entirely).

    It stops when no interval needs a midpoint or the evaluations reach ``budget`` (never
    exceeded); every round adds at least one sample, so it always ends. When a round's
    candidates exceed the remaining budget the widest go first (ties: disagreeing before
    agreeing, then by position) — the widest interval can misplace or hide the most mass.

    Defaults (per period): ``n0 = 16``; ``tolerance_deg = 2`` (two label bins: basins drift a
    few degrees over tens of degrees of β, so neighbours in one basin differ by well under 2°,
    while jumps between basins are tens of degrees); ``min_width_deg = 0.5`` (half a label bin;
    each unresolved jump then misplaces at most 0.5/360 ≈ 0.0014 of the mass, an order below the
    ~0.017 of 1,000 random drops); ``budget = 64`` (40–70 simulations reached sup|ΔCDF|
    0.002–0.009 on simple scenes); ``max_width_deg = max(period / 32, min_width)`` (11.25° over
    a full turn: with n0 = 16 every grid interval gets its midpoint, checks and bisections
    together in the first round, and a basin carrying more than 1/32 of the mass cannot be
    missed; ``max_width_deg ≥ period / n0`` turns the checks off); ``band_gap_deg = 4 · min_width``
    (jumps this close make a chaotic band; at 2° the chance that a band of two outcomes hides
    its switching over a whole gap, about six samples at the resolution reached, is 2⁻⁶);
    ``edge_check_deg = 2 · min_width`` (1°). Measured on an analytic map with a 20° band of two
    outcomes switching at random (tests/test_pushforward.py) over 45 grid offsets: with the edge
    check the band was found at all 45 (about 105 simulations), without it at 35; the edge check
    costs about 5 simulations per jump on clean maps (a two-jump map: 53 instead of 42).
    ``edge_check_deg = 0`` turns it off.

    ``stop_if_none_ok``: when no drop of the start grid ends ``ok`` (every one jams, falls off ...),
    stop there. Such a configuration carries no orientation label: rounds after it only bisect
    between outcomes that are all not ok (at most midpoint checks), and the label it gets is
    excluded from the datasets anyway (``sim.min_ok_mass``). Measured on the default run of 0b7d41b
    (docs/data.md): 80 of 1,439 configurations had no ok drop on the grid of 16; 77 ended with none
    after 32 simulations, 3 with a few, all under ``min_ok_mass``.

    Raises FeederError for n0 < 2, budget < n0, tolerance ≤ 0, min_width ≤ 0,
    max_width < min_width, band_gap < 0, edge_check < 0, a period that does not divide 360,
    or a malformed evaluation.
    """
    n0, budget, period, offset, max_width, band_gap, edge_check = _refine_settings(
        n0, tolerance_deg, min_width_deg, budget, offset_deg, period_deg, max_width_deg, band_gap_deg, edge_check_deg
    )
    yaws = _grid(n0, offset, period)
    final, status = _check_evaluation(yaws, evaluate(normalize_yaw(yaws)))
    none_ok = bool(stop_if_none_ok) and not np.any(status == "ok")
    (yaws, final, status), evaluations, calls = _rounds(
        evaluate,
        (yaws, final, status),
        n0,
        1,
        n0 if none_ok else budget,
        period,
        offset,
        tolerance_deg,
        min_width_deg,
        max_width,
        band_gap,
        edge_check,
    )
    return _finish(
        yaws,
        final,
        status,
        evaluations,
        calls,
        period,
        offset,
        float(tolerance_deg),
        float(min_width_deg),
        max_width,
        band_gap,
        edge_check,
    )


def _rounds(
    evaluate, samples, evaluations, calls, budget, period, offset, tolerance, min_width, max_width, band_gap, edge_check
):
    """The refinement rounds shared by :func:`refine` and :func:`extend`: while the budget allows,
    simulate the midpoints the intervals ask for and merge them in. Returns ``((yaws, final,
    status), evaluations, calls)``."""
    yaws, final, status = samples
    while evaluations < budget:
        iv = intervals(yaws, final, status, period, tolerance)
        new = _next_midpoints(iv, min_width, max_width, band_gap, edge_check, budget - evaluations, offset, period)
        if new.size == 0:
            break
        f_new, s_new = _check_evaluation(new, evaluate(normalize_yaw(new)))
        evaluations += new.size
        calls += 1
        yaws, final, status = _merge_samples((yaws, final, status), (new, f_new, s_new))
    return (yaws, final, status), evaluations, calls


def extend(
    design: Design, evaluate: Evaluate, budget: int, *, samples=None, max_width_deg: float | None = None
) -> Design:
    """Go on refining ``design`` (the rounds of :func:`refine`) until no interval needs a midpoint
    or its evaluations reach ``budget``. ``samples``: ``(yaws, final, status)`` already simulated
    (e.g. audit yaws, inside ``[offset, offset + period)``), merged first and counted in the
    evaluations. ``max_width_deg``: a narrower midpoint-check width than the design's (it never
    widens). FeederError for a budget below the evaluations already spent."""
    evaluations = design.evaluations
    yaws, final, status = design.yaws, design.final, design.status
    if samples is not None:
        new = np.asarray(samples[0], dtype=np.float64)
        f_new, s_new = _check_evaluation(new, (samples[1], samples[2]))
        yaws, final, status = _merge_samples((yaws, final, status), (new, f_new, s_new))
        evaluations += new.size
    if int(budget) != budget or budget < evaluations:
        raise FeederError(f"extend: budget ({budget!r}) must be an integer >= the evaluations spent ({evaluations})")
    max_width = design.max_width_deg if max_width_deg is None else min(float(max_width_deg), design.max_width_deg)
    max_width = max(max_width, design.min_width_deg)
    period, offset = design.period_deg, design.offset_deg
    (yaws, final, status), evaluations, calls = _rounds(
        evaluate,
        (yaws, final, status),
        evaluations,
        design.calls,
        int(budget),
        period,
        offset,
        design.tolerance_deg,
        design.min_width_deg,
        max_width,
        design.band_gap_deg,
        design.edge_check_deg,
    )
    return _finish(
        yaws,
        final,
        status,
        evaluations,
        calls,
        period,
        offset,
        design.tolerance_deg,
        design.min_width_deg,
        max_width,
        design.band_gap_deg,
        design.edge_check_deg,
    )


def _finish(
    yaws, final, status, evaluations, calls, period, offset, tolerance, min_width, max_width, band_gap, edge_check
) -> Design:
    iv = intervals(yaws, final, status, period, tolerance)
    bad = _classify(iv, min_width, max_width, band_gap).unresolved
    unresolved = np.column_stack([iv.start[bad], iv.end[bad]]).reshape(-1, 2)
    unchecked_mask = iv.agree & ~bad & (iv.width > max_width * (1.0 + _WIDTH_SLACK))
    unchecked = np.column_stack([iv.start[unchecked_mask], iv.end[unchecked_mask]]).reshape(-1, 2)
    return Design(
        yaws=yaws,
        final=final,
        status=status,
        evaluations=int(evaluations),
        calls=int(calls),
        unresolved=unresolved,
        unresolved_share=float(iv.width[bad].sum() / period),
        unchecked=unchecked,
        period_deg=period,
        offset_deg=offset,
        tolerance_deg=tolerance,
        min_width_deg=min_width,
        max_width_deg=max_width,
        band_gap_deg=band_gap,
        edge_check_deg=edge_check,
    )


def design_from_samples(
    yaws,
    final,
    status,
    *,
    period_deg: float,
    offset_deg: float,
    tolerance_deg: float,
    min_width_deg: float,
    max_width_deg: float | None = None,
    band_gap_deg: float | None = None,
    edge_check_deg: float | None = None,
    calls: int = 1,
) -> Design:
    """A :class:`Design` rebuilt from stored samples (a simulation file): the intervals, what is
    unresolved and ``unresolved_share`` are recomputed from the samples exactly as :func:`refine`
    leaves them. ``yaws`` are sorted into ``[offset, offset + period)``; a grid design is one
    with ``min_width_deg`` = its spacing (no interval was bisected)."""
    period = float(period_deg)
    _turns(period)
    yaws = np.asarray(yaws, dtype=np.float64)
    rel = np.mod(yaws - offset_deg, period) + offset_deg
    order = np.argsort(rel, kind="stable")
    final = np.asarray(final, dtype=np.float64)[order]
    status = np.asarray(status).astype(str)[order]
    max_width = max(period * DEFAULT_UNSEEN_BASIN_FRACTION, min_width_deg) if max_width_deg is None else max_width_deg
    band_gap = DEFAULT_BAND_GAP_FACTOR * min_width_deg if band_gap_deg is None else band_gap_deg
    edge_check = DEFAULT_EDGE_CHECK_FACTOR * min_width_deg if edge_check_deg is None else edge_check_deg
    return _finish(
        rel[order],
        final,
        status,
        rel.size,
        calls,
        period,
        float(offset_deg),
        float(tolerance_deg),
        float(min_width_deg),
        float(max_width),
        float(band_gap),
        float(edge_check),
    )


def unfold(design: Design, n: int | None = None) -> Design:
    """Map a design over one period ``360 / n`` to the full circle by the n-fold symmetry.

    Copy ``k`` (k = 0..n−1) has initial yaws ``β + k·P`` and final yaws ``f(β) + k·P`` reduced
    to [0, 360) (statuses repeat); unresolved and unchecked intervals are copied the same way.
    ``unresolved_share`` (a fraction of the period) and ``evaluations`` are unchanged. ``n`` defaults
    to 360 / period; a full-turn design is returned as is.
    """
    turns = _turns(design.period_deg)
    n = turns if n is None else n
    if int(n) != n or n != turns:
        raise FeederError(
            f"unfold: n = {n!r} does not match the design's period {design.period_deg:g}° (360 / period = {turns})"
        )
    if turns == 1:
        return design
    P = design.period_deg
    shifts = P * np.arange(turns, dtype=np.float64)
    yaws = (design.yaws[None, :] + shifts[:, None]).ravel()
    final = normalize_yaw((design.final[None, :] + shifts[:, None]).ravel())
    status = np.tile(design.status, turns)
    unres = (design.unresolved[None, :, :] + shifts[:, None, None]).reshape(-1, 2)
    unchk = (design.unchecked[None, :, :] + shifts[:, None, None]).reshape(-1, 2)
    return replace(
        design, yaws=yaws, final=final, status=status, unresolved=unres, unchecked=unchk, period_deg=FULL_TURN_DEG
    )
