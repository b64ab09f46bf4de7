"""A configuration: evenly spaced drops of a part pushed through its fences.

Configurations (:func:`analytic_distribution`)
    The initial yaw is uniform, sampled at ``YAW_SAMPLES`` evenly spaced yaws, each a drop of
    equal weight with the part centred (x = 0), as in ``feeder.sim.drops``. The fences act in the
    order a part meets them (Location 2, then Location 1): a drop's yaw after the first fence,
    exit turn included, is its input to the second. A fence acts on a drop only if the part
    reaches it laterally (its support towards the fence beyond the fence's innermost point, from
    the drop's lateral position, which the exit from an upstream fence moves): curved fences at
    small angles miss the centre line. A straight fence pushes with the push function at ``θ``. A
    curved fence is taken as the straight fence of its last chord, whose push function picks the
    basin from the yaw the part has turned to riding the arc (:mod:`feeder.mechanics.arcride`,
    :data:`ARC_RIDE`; the part meets the arc where it is steeper and turns as it flattens); the
    local angle where a disc of the part's support radius first meets the arc (*entry*) only
    decides whether the part jams (using the push function at the entry angle to choose the basin
    did worse on the simulated two-fence configurations). A part whose disc would meet the circle beyond the tip only
    grazes the tip corner and is left unchanged (an approximation: on ``curved:80`` the
    simulator turns such parts; :data:`GRAZE` holds two measured alternatives).
    A fence turns a part only as far as it pushes it: pushed sideways by the overlap ``o``
    between the part and the fence's innermost point, a part turns by at most ``o / (2c)``
    radians (a unit push at moment arm ``a`` turns it by ``a / (c² + a²) ≤ 1 / (2c)`` on the
    limit surface), so a part that would need more (a shallow curved fence reaching only its
    edge: ``curved:0``) turns that far towards its stable edge and leaves unaligned.
    With ``jam_spread_deg`` > 0 jams are soft: a drop that touches a fence jams with probability
    ``Φ(−margin / jam_spread_deg)`` of its entry's friction margin (one half on the cone's edge),
    and leaves with the rest of its weight. The disc estimate of the entry angle is rough, and near
    the cone's edge the simulator lets many drops through that the quasi-static rule holds, and
    holds some it lets go (one curved fence at 50°: simulated jam share 0.83 where the margin is
    −5° to −2°, 0.47 at −2° to 0°, 0.29 at 0° to 2°). Measured against the hard rule on the
    study's labels, the soft rule's gain is within noise (``JAM_SPREAD_DEG``), so the default is
    ``0``: the hard rule (a drop jams iff its margin is negative), each drop's likeliest outcome.
    A round fence tip (``scene.fences.tip: round``) is a disc: the exit turn pushes the outline
    grown by the disc's radius (:func:`feeder.mechanics.hull.dilate`) with the disc's centre as
    the corner, its forces taken there (taken on the part, ``r`` further in where they act, the
    model scores about 3° worse against the simulator: :data:`TIP_FORCE_AT_CONTACT`); the face
    still meets the outline itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import ndtr

from feeder.circular import FULL_TURN_DEG, HALF_TURN_DEG, QUARTER_TURN_DEG, wrap360
from feeder.errors import FeederError
from feeder.mechanics.arcride import arc_yaw
from feeder.mechanics.exitturn import exit_turn
from feeder.mechanics.fence import (
    FenceModel,
    default_scene,
    fence_models,
    fence_mu,
    fence_normal_deg,
    friction_margin_deg,
    resting_yaw,
)
from feeder.mechanics.hull import PushGeometry, as_geometry, dilate, radius_function
from feeder.mechanics.pushfunction import PushFunction, push_function, rolling_density
from feeder.mechanics.turnrate import TurnCost, turn_cost, unwrap_into

# Chords per quarter turn of the arcs that round the outline's corners for a round fence tip
# (feeder.mechanics.hull.dilate): docs/structured.md, "A round tip in the analytic model".
TIP_ARC_QUAD_SEGS = 16
EDGE_MATCH_DEG = 0.01  # a grown hull edge keeps its normal to this (outline vertices within the hull's
# collinearity tolerance of a hull edge split it: 0.002° at most over the library)
YAW_SAMPLES = 7200  # evenly spaced initial yaws (0.05° apart): a basin's mass is off by < 1/7200
# Spread (degrees of friction margin) of the jam rule; 0: the hard rule. Soft spreads were measured
# and not adopted: chosen on the training split (3°), no split gains by an interval that excludes 0
# (docs/experiments/soft_jams.py, results/tables/soft_jams_summary.csv; docs/structured.md, "Soft jams").
JAM_SPREAD_DEG = 0.0
# Factor on the turn budget overlap / (2c) (below). 1 is the bound as derived; 1.5 was chosen on the
# round-tip study's training split (−0.62° [−1.11, −0.11]) and gains on the held-out splits pooled
# (−0.79° [−1.19, −0.42]): docs/experiments/analytic_dropwise.py --budget-scales,
# results/tables/analytic_turn_budget_round_summary.csv; docs/structured.md, "Soft jams, the entry
# angle again, and the turn budget". The default since stop 68 (PUSH_FEATURES_VERSION 2).
TURN_BUDGET_SCALE = 1.5
# Where a round tip's forces act in the exit turn: False, at the tip's centre, where the grown outline
# touches (the first model of the round tip); True, on the part, the tip's radius further in along
# each contact's normal (the moment of friction and the slip taken there).
TIP_FORCE_AT_CONTACT = False
# How a curved fence picks a drop's basin: None, the push function at the exit chord from the yaw the
# drop arrives with; "basin", from the yaw it has turned to riding the arc
# (feeder.mechanics.arcride.arc_yaw), the turn budget still counted from the arriving yaw; "state",
# the same with the budget counted from the ridden yaw. "state" is the default since stop 69
# (PUSH_FEATURES_VERSION 3): best on the training split, and on the held-out splits pooled it gains
# by an interval that excludes 0 (docs/experiments/arc_ride.py, results/tables/arc_ride_pmf.csv;
# docs/structured.md, "The arc a part rides").
ARC_RIDE = "state"
ARC_RIDE_MODES = (None, "basin", "state")
# How fast a fence turns a part within its turn budget: None, at the bound's rate 1 / (2c) wherever it
# is (the budget's degrees are turned degrees, the short way to the stable edge); "moment", at the rate
# of the contact's own moment arm (feeder.mechanics.turnrate: slow where the line of force passes near
# the centroid), turning the way the push function flows.
TURN_RATE = None
TURN_RATE_MODES = (None, "moment")
# A drop whose disc would meet a curved fence's circle beyond the tip (curved:80): "corner", it only
# grazes the tip corner and leaves as it came; "face", the last chord pushes it as a straight fence
# of the exit angle would, and it does not jam (the corner lets it round; the simulator jams 0-5 %
# of such drops); "swing", "face" and then a swing about the tip by 2·exit − 90° against the fence's
# side (read off three parts' drops on curved:80: the edge flush with the chord ends as far from the
# travel direction as the chord lies from the transverse), only where the chord lies in the friction
# cone (curved:70-90; elsewhere as "corner"). Measured by docs/experiments/fence_turns.py.
GRAZE = "corner"
GRAZE_MODES = ("corner", "face", "swing")
# Contact normals at which a rolling part (no stable edge) may leave a fence: 0.5° apart.
ROLL_SAMPLES = 720


@dataclass(frozen=True)
class FenceResponse:
    """What one fence does to a part arriving at any yaw: its push function (at the fence's
    friction and side), the yaw each stable edge rests at on the exit face, and its exit turn."""

    model: FenceModel
    push: PushFunction
    rest_deg: np.ndarray  # (S,) yaw flush on the exit face
    exit_deg: np.ndarray  # (S,) yaw after the exit turn
    exit_offset: np.ndarray  # (S, 2) centroid relative to the tip corner when released
    exit_reason: tuple = ()  # (S,) why each exit turn stopped (ExitTurn.reason; "" without one)


def fence_response(
    part, model: FenceModel, mu: float, exit_turns: bool = True, tip_force_at_contact: bool = TIP_FORCE_AT_CONTACT
) -> FenceResponse:
    """The push function and resting/exit yaws of each stable edge on ``model``
    (``tip_force_at_contact``: :data:`TIP_FORCE_AT_CONTACT`)."""
    geom = as_geometry(part)
    push = push_function(geom, mu, model.side)
    rest = resting_yaw(push.normals_deg, model.exit_deg, model.side)
    # no exit turn where the exit face holds the part (in the friction cone): it jams there
    turning = exit_turns and float(friction_margin_deg(model.exit_deg, mu)) > 0.0
    grown = dilate(geom, model.cap_radius, TIP_ARC_QUAD_SEGS) if turning and model.cap is not None else None
    reach = model.cap_radius if tip_force_at_contact else 0.0  # how far further in the tip's forces act
    turns = [_exit(geom, grown, model, int(k), mu, reach) if turning else None for k in push.edges]
    delta = np.array([t.delta_deg if t else 0.0 for t in turns])
    reasons = tuple(t.reason if t else "" for t in turns)
    if turning:
        offset = np.array([t.offset for t in turns])
    else:  # flush at the tip: the centroid sits at its height from the face, over the foot
        normal = np.radians(fence_normal_deg(model.exit_deg, model.side))
        offset = -np.outer(geom.heights[push.edges], [math.cos(normal), math.sin(normal)])
    return FenceResponse(model, push, rest, wrap360(rest + delta), offset, reasons)


def _turn_cost(geom: PushGeometry, model: FenceModel, mu: float, memo: dict | None) -> TurnCost:
    """The budget each turn on ``model``'s exit face takes (``turn_rate="moment"`` only), kept in
    ``memo`` (the part's own dict) when given."""
    key = ("turn_cost", model, mu)
    if memo is not None and key in memo:
        return memo[key]
    cost = turn_cost(geom, model.exit_deg, model.side, mu)
    if memo is not None:
        memo[key] = cost
    return cost


def _exit(geom: PushGeometry, grown: PushGeometry | None, model: FenceModel, edge: int, mu: float, reach: float = 0.0):
    """The exit turn of hull edge ``edge`` leaving ``model``'s tip; its offset is from ``model.tip``.
    Around a round tip (``grown``: the outline grown by its radius): the grown outline's edge of
    the same normal, flush on the line through the disc's centre, which is the corner (the offset
    moved from it to ``model.tip``), and a corner caught in a notch hooks there (``exit_turn``'s
    ``hook``); ``reach``: how far further in the forces act (``exit_turn``'s ``contact_offset``)."""
    if grown is None:
        return exit_turn(geom, edge, model.exit_deg, model.side, mu)
    gap = np.abs(np.mod(grown.normals_deg - geom.normals_deg[edge] + HALF_TURN_DEG, FULL_TURN_DEG) - HALF_TURN_DEG)
    match = int(np.argmin(gap))
    if gap[match] > EDGE_MATCH_DEG:  # pragma: no cover - dilate keeps every hull edge's normal
        raise FeederError(f"hull edge {edge} has no edge of the same normal once grown by the tip's radius")
    turn = exit_turn(grown, match, model.exit_deg, model.side, mu, hook=True, contact_offset=reach)
    shift = (model.cap[0] - model.tip[0], model.cap[1] - model.tip[1])
    return replace(turn, offset=(turn.offset[0] + shift[0], turn.offset[1] + shift[1]))


@dataclass(frozen=True)
class Distribution:
    """Final yaws of the sampled drops (part frame, degrees) with their weights (jammed drops
    removed), and per fence met: the share of arriving drops that touched it and that jammed, and
    its friction margin (degrees)."""

    yaws: np.ndarray
    weights: np.ndarray
    ok_mass: float
    touch: dict
    jam: dict
    margin: dict


def _support_towards(geom: PushGeometry, yaw_deg: np.ndarray, side: int) -> np.ndarray:
    """The part's extent from its centroid towards world direction ``side · x`` at each yaw."""
    world = 0.0 if side > 0 else HALF_TURN_DEG
    return radius_function(geom, world - yaw_deg)


def jam_probability(margin_deg, spread_deg: float) -> np.ndarray:
    """Probability that a drop touching a fence with friction margin ``margin_deg`` jams:
    ``Φ(−margin / spread)``, and for ``spread_deg == 0`` the hard rule (1 inside the friction
    cone, margin < 0, else 0)."""
    m = np.asarray(margin_deg, dtype=np.float64)
    if not (math.isfinite(spread_deg) and spread_deg >= 0.0):
        raise FeederError(f"jam_spread_deg must be finite and >= 0, got {spread_deg!r}")
    if spread_deg == 0.0:
        return (m < 0.0).astype(np.float64)
    return ndtr(-m / spread_deg)


def _apply(
    geom,
    resp: FenceResponse,
    mu: float,
    yaw,
    x,
    w,
    jams: bool = True,
    spread: float = JAM_SPREAD_DEG,
    budget_scale: float = TURN_BUDGET_SCALE,
    arc_ride: str | None = ARC_RIDE,
    memo: dict | None = None,
    turn_rate: str | None = TURN_RATE,
    graze: str = GRAZE,
):
    """One fence on the drops (yaws, lateral centroid positions, weights); returns the new
    arrays and (touch share, jam share, mean entry margin) of the arriving weight. A touching
    drop jams with :func:`jam_probability` of its margin (``spread``) and goes on with the rest
    of its weight; drops left with no weight are dropped. ``budget_scale`` multiplies the turn
    budget; ``arc_ride`` how a curved fence picks the basin (:data:`ARC_RIDE`), its rides kept in
    ``memo`` (the part's own dict, as :func:`analytic_distribution`'s ``responses``); ``turn_rate``
    how fast it turns within the budget (:data:`TURN_RATE`); ``graze`` what a drop that would meet
    a curved fence beyond its tip does (:data:`GRAZE`). The margin is
    over the drops that touch, else over all arriving drops, else (nothing arrives: an upstream
    fence jammed every drop) the margin at the fence's exit angle."""
    m = resp.model
    side = m.side
    reach = _support_towards(geom, yaw, side)
    touch = side * x + reach > m.inner
    entry = np.full(yaw.shape, m.exit_deg)
    grazing = np.zeros(yaw.shape, dtype=bool)
    if m.curved:
        # a disc of the part's support radius meets the arc's face at local angle acos(...)
        cos_a = side * (m.centre[0] - x) / (m.outer_radius + reach)
        entry = np.degrees(np.arccos(np.clip(cos_a, -1.0, 1.0)))
        beyond = entry < m.exit_deg  # would meet the circle beyond the tip
        # which of those the last chord pushes ("swing": only where it lies in the friction cone)
        held = graze == "face" or (graze == "swing" and bool(friction_margin_deg(m.exit_deg, mu) < 0.0))
        grazing = beyond & held
        touch &= ~beyond | grazing  # the rest graze the tip corner only: left as they came
        entry = np.minimum(entry, m.slot_deg)
    margin = friction_margin_deg(entry, mu)
    p_jam = np.where(touch, jam_probability(margin, spread), 0.0) if jams else np.zeros(yaw.shape)
    p_jam = np.where(grazing, 0.0, p_jam)  # the corner lets a drop the chord pushes round
    jam = p_jam >= 1.0  # every bit of the drop's weight jams
    push = touch & ~jam
    passed = w * (1.0 - p_jam)  # the weight that goes on
    total = float(w.sum())
    if w[touch].sum() > 0:
        mean_margin = np.average(margin[touch], weights=w[touch])
    elif margin.size:
        mean_margin = margin.mean()
    else:  # nothing arrives: an upstream fence jammed every drop
        mean_margin = friction_margin_deg(m.exit_deg, mu)
    stats = (
        float(w[touch].sum()) / total if total > 0 else 0.0,
        float((w[p_jam > 0.0] * p_jam[p_jam > 0.0]).sum()) / total if total > 0 else 0.0,
        float(mean_margin),
    )
    if push.any() and resp.push.rolls:  # every pushed drop leaves at the rolling density
        phi = (np.arange(ROLL_SAMPLES) + 0.5) * (FULL_TURN_DEG / ROLL_SAMPLES)
        normal = float(fence_normal_deg(m.exit_deg, side))
        keep = ~(jam | push)
        yaw = np.concatenate([yaw[keep], wrap360(normal - phi)])
        x = np.concatenate([x[keep], m.tip[0] - radius_function(geom, phi) * math.cos(math.radians(normal))])
        w = np.concatenate([w[keep], float(passed[push].sum()) * rolling_density(geom, mu, side, phi)])
        return yaw, x, w, stats
    if push.any():
        # the exit face decides the basin (its push function at the entry angle did worse on the
        # simulated two-fence configurations: the disc estimate of the entry is rough)
        start = yaw[push]  # the yaw the turn starts from
        phi = fence_normal_deg(m.exit_deg, side) - start
        if arc_ride is not None and m.curved:  # the yaw it has turned to riding the arc, where it touches it
            rode = arc_yaw(geom, m, start, x[push], mu, memo)
            rode = np.where(np.isfinite(rode), rode, start)
            idx = resp.push.basin_index(fence_normal_deg(m.exit_deg, side) - rode)
            if arc_ride == "state":
                start = rode
                phi = fence_normal_deg(m.exit_deg, side) - start
        else:
            idx = resp.push.basin_index(phi)
        # the turn the fence can give: a sideways push by the overlap turns the part by at most
        # overlap / (2c) (unit push at moment arm a turns it by a / (c² + a²) <= 1 / (2c))
        overlap = side * x[push] + reach[push] - m.inner
        budget = budget_scale * np.degrees(overlap / (2.0 * geom.limit_radius))
        if turn_rate == "moment":  # the way the push function flows, at the contact's own rate
            here = unwrap_into(phi, resp.push.lower_deg[idx])
            need = unwrap_into(resp.push.normals_deg[idx], resp.push.lower_deg[idx]) - here
            cost = _turn_cost(geom, m, mu, memo)
            full = cost.between(here, here + need) <= budget
            turned = cost.advance(here, need, budget) - here
        else:
            need = np.mod(resp.push.normals_deg[idx] - phi + HALF_TURN_DEG, FULL_TURN_DEG) - HALF_TURN_DEG
            full = np.abs(need) <= budget
            turned = np.sign(need) * budget
        new_yaw = np.where(full, resp.exit_deg[idx], start - turned)
        if graze == "swing":
            new_yaw = np.where(grazing[push], new_yaw - side * (2.0 * m.exit_deg - QUARTER_TURN_DEG), new_yaw)
        new_x = np.where(full, m.tip[0] + resp.exit_offset[idx, 0], x[push] - side * overlap)
        yaw = yaw.copy()
        x = x.copy()
        yaw[push], x[push] = new_yaw, new_x
    keep = passed > 0.0
    return yaw[keep], x[keep], passed[keep], stats


def analytic_distribution(
    part,
    loc1,
    loc2,
    scene: dict | None = None,
    *,
    mu: float | None = None,
    exit_turns: bool = True,
    samples: int = YAW_SAMPLES,
    fences: list[FenceModel] | None = None,
    jams: bool = True,
    responses: dict | None = None,
    jam_spread_deg: float = JAM_SPREAD_DEG,
    turn_budget_scale: float = TURN_BUDGET_SCALE,
    tip_force_at_contact: bool = TIP_FORCE_AT_CONTACT,
    arc_ride: str | None = ARC_RIDE,
    turn_rate: str | None = TURN_RATE,
    graze: str = GRAZE,
) -> Distribution:
    """Push ``samples`` evenly spaced initial yaws (centred parts) through the configuration.

    ``mu``: part–fence friction (default :func:`fence_mu` of ``scene``); ``exit_turns``: apply the
    exit turn (False: parts leave a fence flush with it); ``fences``: an explicit list of fence
    models in the order met (overrides loc1/loc2); ``jams``: False pushes drops in the friction
    cone as if they slid; ``jam_spread_deg``: the soft jam rule's spread (0: the hard rule,
    :func:`jam_probability`); ``turn_budget_scale``: a factor (> 0) on how far a fence can turn a
    part that it pushes sideways by an overlap (``TURN_BUDGET_SCALE``); ``tip_force_at_contact``:
    where a round tip's forces act in the exit turn (:data:`TIP_FORCE_AT_CONTACT`); ``arc_ride``:
    how a curved fence picks a drop's basin (:data:`ARC_RIDE`); ``turn_rate``: how fast a fence turns a
    part within its budget (:data:`TURN_RATE`); ``graze``: what a drop that would meet a curved fence
    beyond its tip does (:data:`GRAZE`); ``responses``: a memo of
    :func:`fence_response` for this one part, filled and reused across calls (the exit-turn
    integration is most of the cost, and configurations of a part share fences): give each part
    its own dict."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu = fence_mu(scene) if mu is None else float(mu)
    if fences is None:
        fences = fence_models(loc1, loc2, scene)
    if not (math.isfinite(turn_budget_scale) and turn_budget_scale > 0.0):
        raise FeederError(f"turn_budget_scale must be finite and > 0, got {turn_budget_scale!r}")
    if arc_ride not in ARC_RIDE_MODES:
        raise FeederError(f"arc_ride must be one of {ARC_RIDE_MODES}, got {arc_ride!r}")
    if turn_rate not in TURN_RATE_MODES:
        raise FeederError(f"turn_rate must be one of {TURN_RATE_MODES}, got {turn_rate!r}")
    if graze not in GRAZE_MODES:
        raise FeederError(f"graze must be one of {GRAZE_MODES}, got {graze!r}")
    n = int(samples)
    if n < 1:
        raise FeederError(f"samples must be a positive integer, got {samples!r}")
    yaw = (np.arange(n) + 0.5) * (FULL_TURN_DEG / n)
    x = np.zeros(n)
    w = np.full(n, 1.0 / n)
    touch, jam, margin = {}, {}, {}
    for m in fences:
        key = (m, mu, bool(exit_turns), bool(tip_force_at_contact))
        resp = None if responses is None else responses.get(key)
        if resp is None:
            resp = fence_response(geom, m, mu, exit_turns, bool(tip_force_at_contact))
            if responses is not None:
                responses[key] = resp
        yaw, x, w, (t, j, mg) = _apply(
            geom, resp, mu, yaw, x, w, jams, jam_spread_deg, turn_budget_scale, arc_ride, responses, turn_rate, graze
        )
        touch[m.location], jam[m.location], margin[m.location] = t, j, mg
    ok = float(w.sum())
    return Distribution(wrap360(yaw), w, ok, touch, jam, margin)
