"""pybullet drops of one part through one fence configuration: the drop loop (``feeder simulate``).

The scene (see :mod:`feeder.sim.scene`) is a belt moving along ``+y`` with containment walls and up to
two fences. One *drop* places the part flat, centred, already moving with the belt, with a yaw
drawn uniformly from [0, 360) (independently, or as an evenly spread golden-ratio sequence:
:func:`initial_yaws`), carries it past the fences and records its final in-plane yaw
once it is past the last fence and at rest on the belt.

What is simulated (the preset decides; ``faithful`` is the paper's setting, the reference):

* no fence the part's lane can reach → no physics at all: final yaw = initial yaw (exact: a part
  at rest on a belt is carried without turning). Fences the lane cannot reach are not built.
* ``full_path: true``: the part starts at ``belt.start_y`` and is recorded at the record point
  ``max(end_y, last fence end + end_margin)`` once at rest.
* ``full_path: false``: the part starts ``approach_margin`` before its own first contact (its
  convex hull at its initial yaw, carried straight along the belt); whenever it rests on the belt
  with a fence still ahead of its hull it is moved forward to just before that fence (free
  transport is a pure translation); it is recorded as soon as it rests with nothing ahead.
* ``skip_slides``: a part sliding steadily along a straight fence (same yaw, velocity along the
  fence, faster than ``slide_min_speed``) for ``slide_window_s`` is moved along the fence to
  ``skip_margin`` before its tip, keeping its velocity: the steady slide is translation-invariant.
* ``lanes``: that many drops run side by side in one world, each on its own copy of the belt
  lane (walls and fences), their parts collision-filtered so they never touch each other.
  A lane takes the next drop as soon as its part is done.

Each drop ends ``ok``, ``jammed`` (moved less than ``jam_travel`` in ``jam_window_s``),
``fell_off``, ``flipped``, ``timed_out`` or ``nan``; a non-ok drop has a NaN final yaw and never
stops the configuration. Seeds: the initial yaws come from a generator seeded by a SHA-256 hash
of (part id, fence configuration id, base seed); a rerun of one configuration is bit-identical.

The part body and the world (:mod:`feeder.sim.body`): a compound of the part's exact convex
pieces in its centroidal principal frame; each lane's belt is a fixed-base box given the belt
velocity (and its start pose) when a drop starts, which Bullet carries along (see
:class:`feeder.sim.body.World` for why it is not reset every step). The output file is written by
:mod:`feeder.sim.record`.
Measured (``feeder bench-sim``, results/tables/sim_accuracy_vs_time.csv): internal steps of 1 ms
or more move the distributions beyond the noise floor (small parts, fences near the friction
limit), so ``fast`` keeps the paper's 0.5 ms steps and saves time only by stepping the fence
region; several collision-filtered lanes per world did not lower the cost per drop.

The belt contact is compliant by default (``scene.belt.contact_stiffness`` / ``contact_damping``):
with a rigid contact the split of a flat part's weight over its contact points is left to the
solver and depended on how long the part had ridden the belt, which put ``fast`` (placed just
before the fences) outside the noise floor on concave parts (docs/simulation.md). With the
compliant contact ``fast`` is as close to ``faithful`` as ``faithful`` started 0.5 m earlier.
A part is at rest when its displacement between two state checks says so: Bullet's reported
velocity of a part held by the compliant contact can keep a residual of ~1 mm/s.
"""

from __future__ import annotations

import hashlib
import math
import sys
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import shapely

from feeder.errors import FeederError
from feeder.lane.fences import Fence
from feeder.lane.geometry import FenceGeom, scene_fences
from feeder.sim.body import PartModel, Plan, World, part_model, quat_tilt_deg, quat_yaw, quiet_pybullet

STATUSES = ("ok", "jammed", "fell_off", "timed_out", "flipped", "nan")
PRESET_KEYS = ("time_step", "substeps", "solver_iterations", "lanes", "full_path", "skip_slides", "merge_tolerance")
_REACH_SAMPLE = 0.001  # m: spacing of fence outline samples used for lane-reach queries


# --------------------------------------------------------------------------------------------
# Seeds
# --------------------------------------------------------------------------------------------
def drop_seed(part_id: str, cfg_id: str, base_seed: int) -> int:
    """Stable 64-bit seed from (part id, fence configuration id, base seed)."""
    digest = hashlib.sha256(f"{part_id}|{cfg_id}|{int(base_seed)}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


YAW_SAMPLINGS = ("random", "golden", "grid", "adaptive")
# designs whose drops are independent of each other's outcome, drawn up front (initial_yaws)
DRAWN_SAMPLINGS = ("random", "golden")
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0  # 1/phi: the additive recurrence with the most even prefixes


def initial_yaws(seed: int, drops: int, sampling: str = "random") -> np.ndarray:
    """Initial yaws in degrees on [0, 360), in drop order.

    ``random``: independent uniform draws (the paper's design). ``golden``: a randomly shifted
    golden-ratio sequence, yaw_i = 360 * frac(u + i / phi) with u uniform from the seed. Every yaw
    is still uniform on [0, 360), but the drops are not independent: every prefix (every partial
    level) covers the circle evenly, with gaps of at most three lengths (three-gap theorem), so a
    distribution estimated from N drops has less sampling error where the final yaw depends on
    the initial one piecewise smoothly (``feeder bench-yaws`` measures how much). ``grid``: N
    evenly spaced yaws with a random offset from the seed (sorted). The ``adaptive`` design
    chooses its yaws as it goes (:func:`run_design`).
    """
    if sampling not in YAW_SAMPLINGS or sampling == "adaptive":
        raise FeederError(f"initial yaws are drawn for {', '.join(DRAWN_SAMPLINGS)} or grid, got {sampling!r}")
    rng = np.random.default_rng(seed)
    if sampling == "random":
        return rng.uniform(0.0, 360.0, size=int(drops))
    u = rng.uniform(0.0, 1.0)
    if sampling == "grid":
        n = int(drops)
        return 360.0 * (u + np.arange(n, dtype=np.float64)) / n
    return 360.0 * np.mod(u + _GOLDEN * np.arange(int(drops), dtype=np.float64), 1.0)


# --------------------------------------------------------------------------------------------
# Settings
# --------------------------------------------------------------------------------------------
def get_preset(presets: dict, name: str) -> dict:
    if name not in presets:
        raise FeederError(f"preset {name!r} is not one of {', '.join(sorted(presets))}")
    preset = dict(presets[name])
    missing = [k for k in PRESET_KEYS if k not in preset]
    if missing:
        raise FeederError(f"preset {name!r} lacks {', '.join(missing)}")
    if preset["time_step"] <= 0 or preset["substeps"] < 1 or preset["solver_iterations"] < 1 or preset["lanes"] < 1:
        raise FeederError(f"preset {name!r}: time_step, substeps, solver_iterations and lanes must be positive")
    return preset


# --------------------------------------------------------------------------------------------
# Scene plan: what to build and where a part starts (pure)
# --------------------------------------------------------------------------------------------
def fence_samples(fences: list[FenceGeom]) -> np.ndarray:
    """Points every ``_REACH_SAMPLE`` along the outlines of the fences' footprints, (P, 2)."""
    pts = []
    for f in fences:
        fp = f.footprint()
        rings = [fp.exterior] if fp.geom_type == "Polygon" else [g.exterior for g in fp.geoms]
        for ring in rings:
            n = max(4, int(math.ceil(ring.length / _REACH_SAMPLE)))
            d = np.linspace(0.0, ring.length, n, endpoint=False)
            pts.append(shapely.get_coordinates(shapely.line_interpolate_point(ring, d)))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def reach_y(samples: np.ndarray, x: float, half_band: float, y_from: float) -> float | None:
    """Smallest fence y in the band |X - x| <= half_band (widened by the sample spacing), Y >= y_from."""
    if samples.size == 0:
        return None
    sel = (np.abs(samples[:, 0] - x) <= half_band + _REACH_SAMPLE) & (samples[:, 1] >= y_from)
    if not sel.any():
        return None
    return float(samples[sel, 1].min())


def hull_at(hull: np.ndarray, yaw_rad: float, x: float, y: float) -> np.ndarray:
    """The part's convex hull (principal frame) placed at body yaw ``yaw_rad`` and centroid (x, y)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return hull @ np.array([[c, s], [-s, c]]) + np.array([x, y])


def gap_ahead(poly: np.ndarray, samples: np.ndarray, pad: float) -> float | None:
    """How far the convex polygon ``poly`` can move along +y before touching a fence sample point.

    Only fence points within ``pad`` of the polygon's x-range and not behind it (at or above its
    lower boundary, less ``pad``) count. None: nothing ahead (the part is clear of every fence).
    A point inside the polygon gives a gap <= 0.
    """
    if samples.size == 0:
        return None
    xlo, xhi = poly[:, 0].min() - pad, poly[:, 0].max() + pad
    cand = samples[(samples[:, 0] >= xlo) & (samples[:, 0] <= xhi)]
    if cand.size == 0:
        return None
    a, b = poly, np.roll(poly, -1, axis=0)
    ax, ay, bx, by = a[:, 0], a[:, 1], b[:, 0], b[:, 1]
    px = np.clip(cand[:, 0], poly[:, 0].min(), poly[:, 0].max())[:, None]  # x-padding: clamp
    lo_x, hi_x = np.minimum(ax, bx), np.maximum(ax, bx)
    cover = (px >= lo_x) & (px <= hi_x) & (hi_x > lo_x)
    with np.errstate(divide="ignore", invalid="ignore"):
        ys = ay + (px - ax) * (by - ay) / np.where(hi_x > lo_x, bx - ax, 1.0)
    upper = np.where(cover, ys, -np.inf).max(axis=1)
    lower = np.where(cover, ys, np.inf).min(axis=1)
    ahead = cand[:, 1] >= lower - pad
    if not ahead.any():
        return None
    return float(np.min(cand[ahead, 1] - upper[ahead]))


def make_plan(scene: dict, loc1: Fence, loc2: Fence, model: PartModel, full_path: bool, prune: bool = True) -> Plan:
    st, belt = scene["status"], scene["belt"]
    pad = float(st["clear_margin"])
    half = model.radius + pad
    all_fences = scene_fences(scene, loc1, loc2)  # upstream first
    built: list[FenceGeom] = []
    for f in all_fences:
        own = fence_samples([f])
        in_lane = reach_y(own, 0.0, half, -math.inf) is not None
        # A fence downstream of a built one can be reached from anywhere the first one pushes to.
        if in_lane or built or not prune:
            built.append(f)
    samples = fence_samples(built)
    v = float(belt["speed"])
    start = float(belt["start_y"])
    fence_end = float(samples[:, 1].max()) if samples.size else start
    record = max(float(belt["end_y"]), fence_end + float(belt["end_margin"]))
    if built and not full_path:
        first = reach_y(samples, 0.0, half, -math.inf)
        if first is None:  # only reachable through the upstream fence's push: start before any fence
            first = float(samples[:, 1].min())
        start = max(start, first - model.radius - float(st["approach_margin"]))
    fence_len = sum(f.length for f in built)
    limit = float(st["timeout_factor"]) * ((record - start) + fence_len) / v + float(st["timeout_extra_s"])
    return Plan(built, samples, start, record, limit)


# --------------------------------------------------------------------------------------------
# Drops: the limits, one lane's part and its state checks
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Limits:
    """``scene.status`` and the preset's switches as the state checks use them (built once)."""

    belt_speed: float  # m/s
    check_steps: int  # stepSimulation calls between two state checks
    t_check: float  # s between two state checks
    rest_checks: int  # checks at rest before a part counts as resting
    rest_speed: float  # m/s off the belt velocity
    rest_omega: float  # rad/s
    jam_window: float  # s
    jam_travel: float  # m
    flip_tilt: float  # deg
    fall_z: float  # m
    lateral: float  # m
    approach: float  # m: a part starts / is moved this far before its next contact
    pad: float  # m: clear margin around a part
    full_path: bool
    skip_slides: bool  # only without full_path
    slide_checks: int  # checks of steady sliding before a skip
    slide_tol: float  # velocity across the fence, as a fraction of the speed
    slide_yaw: float  # deg
    slide_min_speed: float  # m/s
    skip_margin: float  # m before the fence tip
    skip_min: float  # m: shorter skips and teleports are not made


def drop_limits(scene: dict, preset: dict) -> Limits:
    """The limits of one configuration's drops from the scene's ``status`` section and the preset."""
    st = scene["status"]
    dt = float(preset["time_step"])
    check_steps = max(1, int(round(float(st["check_interval_s"]) / dt)))
    t_check = check_steps * dt
    full_path = bool(preset["full_path"])
    return Limits(
        belt_speed=float(scene["belt"]["speed"]),
        check_steps=check_steps,
        t_check=t_check,
        rest_checks=max(1, int(math.ceil(float(st["rest_window_s"]) / t_check))),
        rest_speed=float(st["rest_speed"]),
        rest_omega=math.radians(float(st["rest_omega_deg_s"])),
        jam_window=float(st["jam_window_s"]),
        jam_travel=float(st["jam_travel"]),
        flip_tilt=float(st["flip_tilt_deg"]),
        fall_z=float(st["fall_z"]),
        lateral=float(st["lateral_limit"]),
        approach=float(st["approach_margin"]),
        pad=float(st["clear_margin"]),
        full_path=full_path,
        skip_slides=bool(preset["skip_slides"]) and not full_path,
        slide_checks=max(1, int(math.ceil(float(st["slide_window_s"]) / t_check))),
        slide_tol=float(st["slide_tol"]),
        slide_yaw=float(st["slide_yaw_deg"]),
        slide_min_speed=float(st["slide_min_speed"]),
        skip_margin=float(st["skip_margin"]),
        skip_min=float(st["skip_min"]),
    )


@dataclass(frozen=True)
class Slideway:
    """A straight fence as a part slides along it (lane coordinates)."""

    wall_end: np.ndarray  # (2,) where the fence leaves the wall
    along: np.ndarray  # (2,) unit direction from the wall end to the tip
    normal: np.ndarray  # (2,) unit normal
    length: float  # m from the wall end to the tip
    half_thickness: float  # m


def slideways(fences: list[FenceGeom]) -> list[Slideway]:
    """The straight fences among ``fences`` (a straight fence is one box)."""
    ways = []
    for f in fences:
        if f.fence.type == "straight":
            cx, cy, hl, ht, yaw = f.boxes[0]
            d = np.array([math.cos(yaw), math.sin(yaw)])
            ways.append(Slideway(np.array([cx, cy]) - hl * d, d, np.array([-d[1], d[0]]), 2.0 * hl, ht))
    return ways


@dataclass
class _Lane:
    """The drop running in one lane: its part body and what the state checks remember of it."""

    drop: int
    body: int
    t0: float
    hist: deque  # (elapsed, x, y, yaw rad) of the checks within the jam window; cleared when the part is moved
    rest: int = 0  # consecutive checks at rest
    max_speed: float = 0.0
    max_omega: float = 0.0
    slide: int = 0  # consecutive checks of the current steady slide ...
    slide_way: int = -1  # ... along this slideway ...
    slide_yaw0: float = 0.0  # ... and the yaw (deg) at its first check
    skips: int = 0
    inside_fence: bool = False
    teleports: int = 0
    probe_yaw: float = math.nan


@dataclass(frozen=True)
class PartState:
    """A lane's part at one state check, in the lane's coordinates."""

    elapsed: float  # s since its drop started
    x: float
    y: float
    z: float
    q: tuple  # orientation (x, y, z, w)
    lin: tuple  # linear velocity (world)
    ang: tuple  # angular velocity (world)
    yaw_rad: float  # yaw of the body (the part's principal frame)
    yaw_deg: float  # yaw of the part's own frame in [0, 360): what a drop records


class Probes(NamedTuple):
    """Diagnostics only: fence boxes to test for tunnelling (None: not tested) and the x where
    the yaw is probed (None: not probed)."""

    fence_boxes: np.ndarray | None
    probe_x: float | None


@dataclass(frozen=True)
class DropEnd:
    """How a drop ended: its status, the final yaw (ok only) and where the part was."""

    status: str
    yaw_deg: float = math.nan
    pos: tuple[float, float] | None = None


def part_state(world: World, lane: int, body: int, elapsed: float) -> PartState | None:
    """The part's state now; None when Bullet's state is not finite (status ``nan``)."""
    pos, q, lin, ang = world.part_motion(body)
    if not (
        math.isfinite(pos[0] + pos[1] + pos[2] + q[0] + q[1] + q[2] + q[3])
        and math.isfinite(lin[0] + lin[1] + lin[2] + ang[0] + ang[1] + ang[2])
    ):
        return None
    yaw_rad = quat_yaw(q)
    return PartState(
        elapsed,
        pos[0] - world.lane_x[lane],
        pos[1],
        pos[2],
        q,
        lin,
        ang,
        yaw_rad,
        (math.degrees(yaw_rad - world.model.alpha)) % 360.0,
    )


def note_diagnostics(ln: _Lane, s: PartState, probes: Probes) -> None:
    """Peak speeds; whether the centroid entered a fence (tunnelling); the yaw when the centroid
    first reached ``x <= probe_x``."""
    ln.max_speed = max(ln.max_speed, math.hypot(s.lin[0], s.lin[1]))
    ln.max_omega = max(ln.max_omega, abs(s.ang[2]))
    if probes.fence_boxes is not None and _inside_any_box(probes.fence_boxes, s.x, s.y):
        ln.inside_fence = True
    if probes.probe_x is not None and math.isnan(ln.probe_yaw) and s.x <= probes.probe_x:
        ln.probe_yaw = s.yaw_deg


def failure(ln: _Lane, s: PartState, lim: Limits, time_limit: float) -> str | None:
    """``flipped``, ``fell_off``, ``jammed`` or ``timed_out`` (the first that applies), or None."""
    if quat_tilt_deg(s.q) > lim.flip_tilt:
        return "flipped"
    if s.z < lim.fall_z or abs(s.x) > lim.lateral:
        return "fell_off"
    remember(ln.hist, s, lim.jam_window)
    if jammed(ln.hist, s, lim):
        return "jammed"
    if s.elapsed > time_limit:
        return "timed_out"
    return None


def remember(hist: deque, s: PartState, window: float) -> None:
    """Add this check to the lane's history, which keeps the checks within the jam window."""
    hist.append((s.elapsed, s.x, s.y, s.yaw_rad))
    while hist and s.elapsed - hist[0][0] > window + 1e-9:
        hist.popleft()


def jammed(hist: deque, s: PartState, lim: Limits) -> bool:
    """Moved less than ``jam_travel`` over a whole jam window."""
    h0 = hist[0]
    return s.elapsed - h0[0] >= lim.jam_window - 1e-9 and math.hypot(s.x - h0[1], s.y - h0[2]) < lim.jam_travel


def at_rest(hist: deque, s: PartState, lim: Limits) -> bool:
    """Moving with the belt since the previous check (not since the part was moved), judged from
    the displacement: Bullet's reported velocity of a part held by a compliant contact can keep a
    small residual while the part does not move (docs/simulation.md)."""
    if len(hist) < 2:
        return False
    tp, xp, yp, rp = hist[-2]
    span = s.elapsed - tp
    turn = (s.yaw_rad - rp + math.pi) % (2.0 * math.pi) - math.pi
    return (
        math.hypot((s.x - xp) / span, (s.y - yp) / span - lim.belt_speed) < lim.rest_speed
        and abs(turn) / span < lim.rest_omega
    )


def sliding_along(ways: list[Slideway], s: PartState, lim: Limits, radius: float) -> int:
    """The slideway the part slides along (velocity along it and faster than ``slide_min_speed``,
    centroid within reach of it), or -1."""
    vx, vy = s.lin[0], s.lin[1]
    speed = math.hypot(vx, vy)
    if not speed > lim.slide_min_speed:
        return -1
    for k, w in enumerate(ways):
        d, n, p = w.along, w.normal, w.wall_end
        if (
            vx * d[0] + vy * d[1] > 0
            and abs(vx * d[1] - vy * d[0]) < lim.slide_tol * speed
            and abs((s.x - p[0]) * n[0] + (s.y - p[1]) * n[1]) <= radius + w.half_thickness + lim.pad
        ):
            return k
    return -1


def steady_slide(ln: _Lane, way: int, s: PartState, lim: Limits) -> bool:
    """Count the checks of a steady slide: along the same slideway throughout, the yaw within
    ``slide_yaw`` of its first check's. True once it has lasted ``slide_checks`` checks."""
    dyaw = abs((s.yaw_deg - ln.slide_yaw0 + 180.0) % 360.0 - 180.0)
    if way >= 0 and way == ln.slide_way and dyaw < lim.slide_yaw:
        ln.slide += 1
    else:  # (re)start a run here
        ln.slide, ln.slide_way, ln.slide_yaw0 = (1 if way >= 0 else 0), way, s.yaw_deg
    return ln.slide >= lim.slide_checks


def skip_slide(world: World, ln: _Lane, s: PartState, way: Slideway, lim: Limits) -> None:
    """Move a steadily sliding part along its fence until its leading point is ``skip_margin``
    before the tip, keeping its velocity (the steady slide is translation-invariant)."""
    d, p = way.along, way.wall_end
    cb, sb = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
    dl = (d[0] * cb + d[1] * sb, -d[0] * sb + d[1] * cb)  # d in the body frame
    lead = (s.x - p[0]) * d[0] + (s.y - p[1]) * d[1] + float(np.max(world.model.hull @ dl))
    jump = way.length - lead - lim.skip_margin
    if jump > lim.skip_min:
        world.move_part(ln.body, jump * d[0], jump * d[1], keep_velocity=(s.lin, s.ang))
        ln.skips += 1
        ln.hist.clear()
    ln.slide = 0


def arrived(world: World, ln: _Lane, s: PartState, lim: Limits) -> bool:
    """A resting part is done at the record point (full path) or with no fence ahead of it; with a
    fence ahead it is moved to just before that fence (free transport: a pure translation)."""
    if lim.full_path:
        return s.y >= world.plan.record_y
    gap = gap_ahead(hull_at(world.model.hull, s.yaw_rad, s.x, s.y), world.plan.samples, lim.pad)
    if gap is None:
        return True
    if gap - lim.approach > lim.skip_min:
        world.move_part(ln.body, 0.0, gap - lim.approach)
        ln.teleports += 1
        ln.hist.clear()
        ln.rest = 0
    return False


def check_lane(
    world: World, lane: int, ln: _Lane, t: float, lim: Limits, ways: list[Slideway], probes: Probes
) -> DropEnd | None:
    """One state check of the lane's part: how its drop ended, or None while it goes on (the part
    may have been moved ahead: a slide skipped, free transport)."""
    s = part_state(world, lane, ln.body, t - ln.t0)
    if s is None:
        return DropEnd("nan")
    note_diagnostics(ln, s, probes)
    status = failure(ln, s, lim, world.plan.time_limit)
    if status is not None:
        return DropEnd(status, pos=(s.x, s.y))
    resting = at_rest(ln.hist, s, lim)
    if lim.skip_slides and ways and not resting:
        way = sliding_along(ways, s, lim, world.model.radius)
        if steady_slide(ln, way, s, lim):
            skip_slide(world, ln, s, ways[way], lim)
    ln.rest = ln.rest + 1 if resting else 0
    if ln.rest >= lim.rest_checks and arrived(world, ln, s, lim):
        return DropEnd("ok", s.yaw_deg, (s.x, s.y))
    return None


def _fence_boxes_array(fences: list[FenceGeom]) -> np.ndarray:
    rows = [b for f in fences for b in f.boxes]
    return np.array(rows, dtype=np.float64).reshape(-1, 5)


def _inside_any_box(boxes: np.ndarray, x: float, y: float) -> bool:
    if boxes.size == 0:
        return False
    dx, dy = x - boxes[:, 0], y - boxes[:, 1]
    c, s = np.cos(boxes[:, 4]), np.sin(boxes[:, 4])
    u, v = c * dx + s * dy, -s * dx + c * dy
    return bool(np.any((np.abs(u) < boxes[:, 2]) & (np.abs(v) < boxes[:, 3])))


# --------------------------------------------------------------------------------------------
# Drops: scheduling them over the lanes
# --------------------------------------------------------------------------------------------
def start_y(plan: Plan, model: PartModel, yaw_deg: float, lim: Limits) -> float:
    """Where a drop starts along the belt: the plan's start, or (not full path) ``approach``
    before the part's own first contact, its hull carried straight along the belt."""
    y0 = plan.start_y
    if not lim.full_path:
        gap = gap_ahead(hull_at(model.hull, math.radians(yaw_deg) + model.alpha, 0.0, y0), plan.samples, lim.pad)
        if gap is not None and gap - lim.approach > 0:
            y0 += gap - lim.approach
    return y0


def start_drop(world: World, lane: int, queue: deque, yaws0: np.ndarray, t: float, lim: Limits) -> _Lane:
    """The next drop of the queue in this lane: its belt reset, the part placed on it."""
    i = queue.popleft()
    yaw = float(yaws0[i])
    world.reset_belt(lane)
    body = world.add_part(lane, 0.0, start_y(world.plan, world.model, yaw, lim), yaw)
    return _Lane(i, body, t, deque())


def empty_results(drops: int) -> dict:
    """``final_yaw_deg`` (NaN), ``status`` (ok) and the per-drop diagnostics, to be filled in."""
    diag = {k: np.zeros(drops) for k in ("sim_time", "max_speed", "max_omega", "teleports", "skips")}
    diag["inside_fence"] = np.zeros(drops, dtype=bool)
    diag["probe_yaw"] = np.full(drops, np.nan)
    diag["final_x"] = np.full(drops, np.nan)
    diag["final_y"] = np.full(drops, np.nan)
    return {"final_yaw_deg": np.full(drops, np.nan), "status": np.array(["ok"] * drops, dtype="<U9"), "diag": diag}


def record_drop(out: dict, ln: _Lane, end: DropEnd, t: float) -> None:
    """Write an ended drop's status, final yaw (NaN unless ok) and diagnostics into ``out``."""
    i, diag = ln.drop, out["diag"]
    out["status"][i] = end.status
    out["final_yaw_deg"][i] = end.yaw_deg if end.status == "ok" else math.nan
    diag["sim_time"][i] = t - ln.t0
    diag["max_speed"][i], diag["max_omega"][i] = ln.max_speed, ln.max_omega
    diag["inside_fence"][i], diag["teleports"][i] = ln.inside_fence, ln.teleports
    diag["skips"][i] = ln.skips
    diag["probe_yaw"][i] = ln.probe_yaw
    if end.pos is not None:
        diag["final_x"][i], diag["final_y"][i] = end.pos


def run_lanes(
    world: World, yaws0: np.ndarray, lim: Limits, ways: list[Slideway], probes: Probes, out: dict, bar=None
) -> None:
    """Every drop, over the world's lanes: step the world from one state check to the next; a lane
    whose drop has ended takes the next one in the queue, until every drop has ended."""
    queue = deque(range(len(yaws0)))
    t = 0.0
    lanes: list[_Lane | None] = [start_drop(world, j, queue, yaws0, t, lim) for j in range(len(world.lane_x))]
    while any(ln is not None for ln in lanes):
        for _ in range(lim.check_steps):
            world.step()
        t += lim.t_check
        for j, ln in enumerate(lanes):
            if ln is None:
                continue
            end = check_lane(world, j, ln, t, lim, ways, probes)
            if end is None:
                continue
            record_drop(out, ln, end, t)
            world.remove_part(ln.body)
            lanes[j] = None
            if bar is not None:
                bar.update(1)
            if queue:
                lanes[j] = start_drop(world, j, queue, yaws0, t, lim)


def run_drops(
    geom,
    loc1: Fence,
    loc2: Fence,
    yaws0: np.ndarray,
    scene: dict,
    preset: dict,
    progress: bool = False,
    probe_x: float | None = None,
    check_fences: bool = False,
    prune: bool = True,
) -> dict:
    """Simulate every drop; returns final yaws, statuses and per-drop diagnostics.

    ``check_fences`` tests at every state check whether the part's centroid lies inside a fence
    (tunnelling; diagnostics only). ``probe_x`` records the yaw when the centroid first reaches
    fence-frame ``x <= probe_x`` (e.g. while a part is pushed along a fence).
    """
    setup = prepare_drops(geom, loc1, loc2, scene, preset, prune)
    return drops_in_world(setup, yaws0, progress=progress, probe_x=probe_x, check_fences=check_fences)


class DropSetup(NamedTuple):
    """What every drop of one part through one fence configuration shares (:func:`prepare_drops`)."""

    scene: dict
    preset: dict
    model: PartModel
    plan: Plan
    lim: Limits
    ways: list[Slideway]


def prepare_drops(geom, loc1: Fence, loc2: Fence, scene: dict, preset: dict, prune: bool = True) -> DropSetup:
    """The part's model, the scene's plan, the limits and the slideways, made once per configuration
    (pure: no world is built)."""
    merge = preset["merge_tolerance"]  # None: the pieces as given (feeder.bench.decomposition)
    model = part_model(geom, scene, None if merge is None else float(merge))
    plan = make_plan(scene, loc1, loc2, model, bool(preset["full_path"]), prune=prune)
    return DropSetup(scene, preset, model, plan, drop_limits(scene, preset), slideways(plan.fences))


def drops_in_world(
    setup: DropSetup,
    yaws0: np.ndarray,
    progress: bool = False,
    probe_x: float | None = None,
    check_fences: bool = False,
    client: int | None = None,
) -> dict:
    """:func:`run_drops` on a prepared configuration: every drop of ``yaws0`` in one world, built
    in a new pybullet client or in ``client`` (an open one, reset first and left open)."""
    scene, preset, model, plan, lim, ways = setup
    drops = len(yaws0)
    out = empty_results(drops)
    out["diag"]["plan_fences"] = [f.location for f in plan.fences]
    if not plan.fences:  # nothing in reach: a part at rest on the belt is carried without turning
        out["final_yaw_deg"][:] = np.mod(yaws0, 360.0)
        return out
    probes = Probes(_fence_boxes_array(plan.fences) if check_fences else None, probe_x)
    world = World(scene, preset, plan, int(min(int(preset["lanes"]), drops)), model, client)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=drops, unit="drop", file=sys.stderr, leave=False)
    try:
        run_lanes(world, yaws0, lim, ways, probes, out, bar)
    finally:
        if bar is not None:
            bar.close()
        world.close()
    return out


def run_each(geom, loc1: Fence, loc2: Fence, yaws0: np.ndarray, scene: dict, preset: dict, **options) -> dict:
    """Every drop in a world of its own (:func:`run_drops` once per initial yaw): a drop's outcome
    is then a function of its initial yaw alone. In a shared world it is not quite: a drop that
    follows another one (a jammed one, measured) can end a few hundredths of a degree elsewhere.
    Building a world costs next to nothing beside a drop (measured: six drops alone and in one
    world, 2.04 s of CPU either way). Returns what :func:`run_drops` returns, the diagnostics
    concatenated per drop (``plan_fences`` once).

    What the drops share is made once (:func:`prepare_drops`), and the worlds are built one after
    another in one pybullet client, reset before each: a new client per drop cost ~12 ms, and the
    plan's fence samples ~10 ms, beside a mean drop of ~100 ms (docs/performance.md). A drop's
    result is bit-identical either way (tests/test_sim.py)."""
    yaws0 = np.asarray(yaws0, dtype=np.float64)
    setup = prepare_drops(geom, loc1, loc2, scene, preset, options.pop("prune", True))
    pb = quiet_pybullet()
    client = pb.connect(pb.DIRECT) if setup.plan.fences and len(yaws0) else None
    try:
        runs = [drops_in_world(setup, yaws0[i : i + 1], client=client, **options) for i in range(len(yaws0))]
    finally:
        if client is not None:
            pb.disconnect(physicsClientId=client)
    if not runs:
        return empty_results(0)
    diag = {k: np.concatenate([r["diag"][k] for r in runs]) for k in runs[0]["diag"] if k != "plan_fences"}
    diag["plan_fences"] = runs[0]["diag"].get("plan_fences", [])
    return {
        "final_yaw_deg": np.concatenate([r["final_yaw_deg"] for r in runs]),
        "status": np.concatenate([r["status"] for r in runs]),
        "diag": diag,
    }
