"""pybullet simulation of one part through one fence configuration (``feeder simulate``).

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

The part body is a compound of the exact convex pieces of its outline, each inset by the
collision margin and extruded (so the margin-inflated shape is the true part), in the part's
centroidal principal frame; mass, centre of mass and the inertia diagonal are set from the
polygon. Each lane's belt is a fixed-base box given the belt velocity (and its start pose) when
a drop starts; Bullet carries it along (see :class:`World` for why it is not reset every step).
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

Bullet combines friction coefficients by multiplication: part-belt 0.8 x 1.0, part-fence
0.8 x 0.5 = 0.4 (a straight fence holds parts for θ > atan(1/0.4) = 68.2°).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import tempfile
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.sim.fences import Fence, config_id, parse_location
from feeder.sim.scene import FenceGeom, belt_contact, load_settings, scene_fences

STATUSES = ("ok", "jammed", "fell_off", "timed_out", "flipped", "nan")
PRESET_KEYS = ("time_step", "substeps", "solver_iterations", "lanes", "full_path", "skip_slides", "merge_tolerance")
# Part collision filter: group bit 1 (dynamic) colliding only with static bodies (group bit 2).
_PART_GROUP, _PART_MASK = 1, 2
_TRACE = None  # debugging: a list collects per-check states when set
_REACH_SAMPLE = 0.001
_MAX_COMPOUND = 16  # pybullet's createCollisionShapeArray silently drops shapes beyond 16  # m: spacing of fence outline samples used for lane-reach queries


# --------------------------------------------------------------------------------------------
# Seeds
# --------------------------------------------------------------------------------------------
def drop_seed(part_id: str, cfg_id: str, base_seed: int) -> int:
    """Stable 64-bit seed from (part id, fence configuration id, base seed)."""
    digest = hashlib.sha256(f"{part_id}|{cfg_id}|{int(base_seed)}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


YAW_SAMPLINGS = ("random", "golden")
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0  # 1/phi: the additive recurrence with the most even prefixes


def initial_yaws(seed: int, drops: int, sampling: str = "random") -> np.ndarray:
    """Initial yaws in degrees on [0, 360), in drop order.

    ``random``: independent uniform draws (the paper's design). ``golden``: a randomly shifted
    golden-ratio sequence, yaw_i = 360 * frac(u + i / phi) with u uniform from the seed. Every yaw
    is still uniform on [0, 360), but the drops are not independent: every prefix (every partial
    level) covers the circle evenly, with gaps of at most three lengths (three-gap theorem), so a
    distribution estimated from N drops has less sampling error where the final yaw depends on
    the initial one piecewise smoothly (``feeder bench-yaws`` measures how much).
    """
    if sampling not in YAW_SAMPLINGS:
        raise FeederError(f"yaw sampling must be one of {', '.join(YAW_SAMPLINGS)}, got {sampling!r}")
    rng = np.random.default_rng(seed)
    if sampling == "random":
        return rng.uniform(0.0, 360.0, size=int(drops))
    u = rng.uniform(0.0, 1.0)
    return 360.0 * np.mod(u + _GOLDEN * np.arange(int(drops), dtype=np.float64), 1.0)


# --------------------------------------------------------------------------------------------
# Part model (pure)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PartModel:
    """A part ready for pybullet: pieces in its centroidal principal frame (inset), mass, inertia."""

    part_id: str
    thickness: float
    mass: float
    inertia: tuple[float, float, float]  # principal diagonal (kg m²)
    alpha: float  # rad: principal frame yaw in the part's own frame
    radius: float  # m: circumradius about the centroid
    pieces: tuple[np.ndarray, ...] = field(repr=False)  # (M, 2) inset convex pieces, principal frame
    hull: np.ndarray = field(repr=False, default=None)  # (H, 2) convex hull of the outline, principal frame


def principal_inertia(area, second_moment, thickness, density):
    """(mass, (Ixx, Iyy, Izz) principal, alpha) of a uniform prism from its area moments.

    ``second_moment = (∫y², ∫x², ∫xy)`` about the centroid (geometry convention). ``alpha`` is the
    yaw of the principal x axis (largest ∫x'²) in the part frame.
    """
    sxx_y, sxx_x, sxy = second_moment  # ∫y², ∫x², ∫xy
    alpha = 0.5 * math.atan2(2.0 * sxy, sxx_x - sxx_y)
    mean = 0.5 * (sxx_x + sxx_y)
    half = math.hypot(0.5 * (sxx_x - sxx_y), sxy)
    lam1, lam2 = mean + half, mean - half  # ∫x'², ∫y'²
    rho_t = density * thickness
    mass = rho_t * area
    flat = mass * thickness**2 / 12.0
    return mass, (rho_t * lam2 + flat, rho_t * lam1 + flat, rho_t * (lam1 + lam2)), alpha


def merge_pieces(pieces, tolerance: float) -> list[np.ndarray]:
    """Merge touching convex pieces whose union's convex hull lies within ``tolerance`` of the union.

    Greedy: any pair whose hull adds nothing beyond ``tolerance`` (m) is replaced by that hull,
    until no pair qualifies. ``tolerance = 0`` merges only pieces whose union is exactly convex.
    Fewer pieces make fewer contact manifolds (the simulation's cost grows with the piece count);
    the shape changes by at most ``tolerance`` (concave corners filled).
    """
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    polys = [Polygon(p) for p in pieces]
    merged = True
    while merged:
        merged = False
        for i in range(len(polys)):
            for j in range(i + 1, len(polys)):
                a, b = polys[i], polys[j]
                if a.distance(b) > 0.0:
                    continue
                union = unary_union([a, b])
                hull = union.convex_hull
                if hull.difference(union).area <= 1e-12 * hull.area or (
                        tolerance > 0 and union.buffer(tolerance, join_style=2).contains(hull)):
                    polys = [q for k, q in enumerate(polys) if k not in (i, j)] + [hull]
                    merged = True
                    break
            if merged:
                break
    return [np.asarray(q.exterior.coords)[:-1] for q in polys]


def part_model(geom, scene: dict, merge_tolerance: float = 0.0) -> PartModel:
    """Pieces (merged within ``merge_tolerance``) in the centroidal principal frame, inset by the margin."""
    from shapely.geometry import Polygon

    pc = scene["part"]
    margin = float(pc["collision_margin"])
    mass, inertia, alpha = principal_inertia(geom.area, geom.second_moment, geom.thickness,
                                             float(pc["density"]))
    c, s = math.cos(-alpha), math.sin(-alpha)
    rot = np.array([[c, -s], [s, c]])
    centroid = np.asarray(geom.centroid, dtype=np.float64)
    pieces = []
    for piece in merge_pieces(geom.convex_pieces, merge_tolerance):
        local = (np.asarray(piece, np.float64) - centroid) @ rot.T
        poly = Polygon(local).buffer(-margin, join_style=2)
        if poly.is_empty or poly.area <= 0 or poly.geom_type != "Polygon":
            continue  # a sliver thinner than twice the margin: the neighbours' margins cover it
        pieces.append(np.asarray(poly.exterior.coords)[:-1])
    if not pieces:
        raise FeederError(f"part {geom.part_id}: thinner than twice the collision margin")
    if geom.thickness <= 2 * margin:
        raise FeederError(f"part {geom.part_id}: thickness {geom.thickness} <= 2 x collision margin")
    outline = np.asarray(geom.outline, np.float64) - centroid
    radius = float(np.max(np.hypot(outline[:, 0], outline[:, 1])))
    hull = np.asarray(Polygon(outline @ rot.T).convex_hull.exterior.coords)[:-1]
    return PartModel(geom.part_id, float(geom.thickness), mass, inertia, alpha, radius, tuple(pieces), hull)


def obj_text(pieces, half_height: float) -> str:
    """Wavefront OBJ with one object per convex piece extruded to ±half_height (pybullet: compound)."""
    lines, base = [], 1
    for k, piece in enumerate(pieces):
        n = len(piece)
        lines.append(f"o piece{k}")
        for z in (-half_height, half_height):
            lines += [f"v {x:.10g} {y:.10g} {z:.10g}" for x, y in piece]
        lines += [f"f {base} {base + i + 1} {base + i}" for i in range(1, n - 1)]  # bottom
        lines += [f"f {base + n} {base + n + i} {base + n + i + 1}" for i in range(1, n - 1)]  # top
        for i in range(n):
            j = (i + 1) % n
            lines.append(f"f {base + i} {base + j} {base + n + j} {base + n + i}")
        base += 2 * n
    return "\n".join(lines) + "\n"


def quat_yaw(q) -> float:
    """Yaw (rad) of a quaternion (x, y, z, w) about world z."""
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_tilt_deg(q) -> float:
    """Angle between the body z axis and world z (degrees)."""
    x, y, _, _ = q
    cz = 1.0 - 2.0 * (x * x + y * y)
    return math.degrees(math.acos(max(-1.0, min(1.0, cz))))


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
@dataclass
class Plan:
    fences: list[FenceGeom]  # fences to build
    samples: np.ndarray  # (P, 2) outline samples of the built fences (reach queries)
    start_y: float
    record_y: float
    time_limit: float


def fence_samples(fences: list[FenceGeom]) -> np.ndarray:
    pts = []
    for f in fences:
        fp = f.footprint()
        rings = [fp.exterior] if fp.geom_type == "Polygon" else [g.exterior for g in fp.geoms]
        for ring in rings:
            n = max(4, int(math.ceil(ring.length / _REACH_SAMPLE)))
            d = np.linspace(0.0, ring.length, n, endpoint=False)
            pts.append(np.array([[p.x, p.y] for p in (ring.interpolate(v) for v in d)]))
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


def make_plan(scene: dict, loc1: Fence, loc2: Fence, model: PartModel, full_path: bool,
              prune: bool = True) -> Plan:
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
# The world
# --------------------------------------------------------------------------------------------
class World:
    """One pybullet DIRECT client with ``lanes`` copies of the belt lane (belt, walls, fences).

    Each lane has its own belt: a fixed-base (mass 0) slab whose velocity is set to the belt speed
    when a drop starts in that lane, together with its pose; Bullet then carries it along
    consistently (a mass-0 body keeps its velocity). It is never snapped back while a part rides
    on it: resetting a moving belt to its start pose every step disturbs the contacts (parts sank
    into the belt and spun at internal steps >= 1 ms), and the belt's frame (belt still, fences
    moving at -v) lets parts creep along fences that should hold them. The slab is long enough for
    one drop's time limit. Walls and fences are static. Lane j's coordinates: ``x - lane_x[j]``, y.
    Measured (tests/test_sim_physics.py): at internal steps of 2.5 ms a part held by a steep fence
    still creeps along it (up to ~10 mm/s); at 1.67 ms and below it is held.
    """

    def __init__(self, scene: dict, preset: dict, plan: Plan, lanes: int, model: PartModel):
        import pybullet as pb

        self.pb = pb
        self.scene, self.preset, self.plan, self.model = scene, preset, plan, model
        self.cid = pb.connect(pb.DIRECT)
        c = self.cid
        pb.resetSimulation(physicsClientId=c)
        pb.setGravity(0, 0, -float(scene["gravity"]), physicsClientId=c)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=float(preset["time_step"]), numSubSteps=int(preset["substeps"]),
            numSolverIterations=int(preset["solver_iterations"]), enableConeFriction=1,
            deterministicOverlappingPairs=1, enableFileCaching=0, physicsClientId=c)
        if preset.get("engine"):
            pb.setPhysicsEngineParameter(**dict(preset["engine"]), physicsClientId=c)
        belt, walls, fc = scene["belt"], scene["walls"], scene["fences"]
        self.speed = float(belt["speed"])
        self.belt_vel = [0.0, self.speed, 0.0]
        self.pitch = 2.0 * (float(belt["half_width"]) + float(walls["thickness"])) + 0.1
        self.lane_x = [(j - 0.5 * (lanes - 1)) * self.pitch for j in range(lanes)]
        travel = self.speed * plan.time_limit  # how far a belt moves during one drop
        # a lane's belt at drop start: from behind the start (a held part stays while the belt
        # runs on) to past the record point (parts may be moved forward by shortcuts)
        bt = float(belt["thickness"])
        blo, bhi = plan.start_y - travel - 1.0, plan.record_y + 1.0
        self.belt_start = [0.5 * (blo + bhi), -0.5 * bt]
        bshape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[0.5 * self.pitch, 0.5 * (bhi - blo), 0.5 * bt], physicsClientId=c)
        wlo, whi = min(blo, plan.start_y - 1.0), bhi + travel
        wt, wh = float(walls["thickness"]), float(walls["height"])
        wx = float(belt["half_width"]) + 0.5 * wt
        fh, fclr = float(fc["height"]), float(fc["clearance"])
        contact = belt_contact(belt)
        self.belts = []
        for x0 in self.lane_x:
            bb = pb.createMultiBody(0, bshape, basePosition=[x0, *self.belt_start], physicsClientId=c)
            self._surface(bb, float(belt["friction"]))
            if contact is not None:  # compliant belt: a spring-damper per contact point (Bullet: ERP/CFM)
                pb.changeDynamics(bb, -1, contactStiffness=contact[0], contactDamping=contact[1], physicsClientId=c)
            self.belts.append(bb)
            ws = pb.createCollisionShapeArray(
                shapeTypes=[pb.GEOM_BOX, pb.GEOM_BOX], halfExtents=[[0.5 * wt, 0.5 * (whi - wlo), 0.5 * wh]] * 2,
                collisionFramePositions=[[-wx, 0, 0], [wx, 0, 0]], physicsClientId=c)
            wb = pb.createMultiBody(0, ws, basePosition=[x0, 0.5 * (wlo + whi), 0.5 * wh], physicsClientId=c)
            self._surface(wb, float(walls["friction"]))
            for f in plan.fences:
                for k in range(0, len(f.boxes), _MAX_COMPOUND):  # pybullet keeps <= 16 shapes per array
                    chunk = f.boxes[k:k + _MAX_COMPOUND]
                    fs = pb.createCollisionShapeArray(
                        shapeTypes=[pb.GEOM_BOX] * len(chunk),
                        halfExtents=[[b[2], b[3], 0.5 * fh] for b in chunk],
                        collisionFramePositions=[[b[0], b[1], 0.0] for b in chunk],
                        collisionFrameOrientations=[pb.getQuaternionFromEuler([0, 0, b[4]]) for b in chunk],
                        physicsClientId=c)
                    fb = pb.createMultiBody(0, fs, basePosition=[x0, 0.0, fclr + 0.5 * fh], physicsClientId=c)
                    self._surface(fb, float(fc["friction"]))
        # the part's collision shape, shared by every part body
        self._tmp = tempfile.TemporaryDirectory(prefix="feeder-sim-")
        obj = Path(self._tmp.name) / "part.obj"
        margin = float(scene["part"]["collision_margin"])
        obj.write_text(obj_text(model.pieces, 0.5 * model.thickness - margin))
        self.part_shape = pb.createCollisionShape(pb.GEOM_MESH, fileName=str(obj), physicsClientId=c)
        if self.part_shape < 0:
            raise FeederError(f"part {model.part_id}: pybullet rejected its collision shape")

    def _surface(self, body: int, friction: float) -> None:
        self.pb.changeDynamics(body, -1, lateralFriction=friction, restitution=float(self.scene["restitution"]),
                               rollingFriction=0.0, spinningFriction=0.0, physicsClientId=self.cid)

    def reset_belt(self, lane: int) -> None:
        """Put the lane's belt back at its start pose, moving at the belt speed (no part on it)."""
        pb, c = self.pb, self.cid
        pb.resetBasePositionAndOrientation(self.belts[lane], [self.lane_x[lane], *self.belt_start], [0, 0, 0, 1],
                                          physicsClientId=c)
        pb.resetBaseVelocity(self.belts[lane], self.belt_vel, [0.0, 0.0, 0.0], physicsClientId=c)

    def add_part(self, lane: int, x: float, y: float, yaw_deg: float) -> int:
        """A part flat on the lane's belt at (x, y), moving with the belt."""
        pb, c, m = self.pb, self.cid, self.model
        yb = math.radians(yaw_deg) + m.alpha
        body = pb.createMultiBody(
            m.mass, self.part_shape, basePosition=[self.lane_x[lane] + x, y, 0.5 * m.thickness],
            baseOrientation=[0.0, 0.0, math.sin(0.5 * yb), math.cos(0.5 * yb)], physicsClientId=c)
        pb.changeDynamics(body, -1, localInertiaDiagonal=list(m.inertia),
                          collisionMargin=float(self.scene["part"]["collision_margin"]),
                          linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        self._surface(body, float(self.scene["part"]["friction"]))
        pb.setCollisionFilterGroupMask(body, -1, _PART_GROUP, _PART_MASK, physicsClientId=c)
        pb.resetBaseVelocity(body, self.belt_vel, [0.0, 0.0, 0.0], physicsClientId=c)
        return body

    def move_part(self, body: int, dx: float, dy: float, keep_velocity=None) -> None:
        """Translate a part (same orientation); velocity: the given (lin, ang) or riding the belt."""
        pb, c = self.pb, self.cid
        pos, q = pb.getBasePositionAndOrientation(body, physicsClientId=c)
        pb.resetBasePositionAndOrientation(body, [pos[0] + dx, pos[1] + dy, pos[2]], q, physicsClientId=c)
        lin, ang = keep_velocity if keep_velocity is not None else (self.belt_vel, [0.0, 0.0, 0.0])
        pb.resetBaseVelocity(body, lin, ang, physicsClientId=c)

    def step(self) -> None:
        self.pb.stepSimulation(physicsClientId=self.cid)

    def close(self) -> None:
        try:
            self.pb.disconnect(physicsClientId=self.cid)
        finally:
            self._tmp.cleanup()


# --------------------------------------------------------------------------------------------
# Drops
# --------------------------------------------------------------------------------------------
@dataclass
class _Lane:
    drop: int
    body: int
    t0: float
    hist: deque  # (elapsed, x, y, yaw rad) of the checks within the jam window; cleared when the part is moved
    rest: int = 0
    max_speed: float = 0.0
    max_omega: float = 0.0
    slide: int = 0
    slide_f: int = -1
    w_prev: tuple = (0.0, 0.0)
    skips: int = 0
    inside_fence: bool = False
    teleports: int = 0
    probe_yaw: float = math.nan


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


def run_drops(geom, loc1: Fence, loc2: Fence, yaws0: np.ndarray, scene: dict, preset: dict,
              progress: bool = False, probe_x: float | None = None, check_fences: bool = False,
              prune: bool = True) -> dict:
    """Simulate every drop; returns final yaws, statuses and per-drop diagnostics.

    ``check_fences`` tests at every state check whether the part's centroid lies inside a fence
    (tunnelling; diagnostics only). ``probe_x`` records the yaw when the centroid first reaches
    fence-frame ``x <= probe_x`` (e.g. while a part is pushed along a fence).
    """
    drops = len(yaws0)
    final = np.full(drops, np.nan)
    status = np.array(["ok"] * drops, dtype="<U9")
    diag = {k: np.zeros(drops) for k in ("sim_time", "max_speed", "max_omega", "teleports", "skips")}
    diag["inside_fence"] = np.zeros(drops, dtype=bool)
    diag["probe_yaw"] = np.full(drops, np.nan)
    diag["final_x"] = np.full(drops, np.nan)
    diag["final_y"] = np.full(drops, np.nan)
    model = part_model(geom, scene, float(preset["merge_tolerance"]))
    plan = make_plan(scene, loc1, loc2, model, bool(preset["full_path"]), prune=prune)
    diag["plan_fences"] = [f.location for f in plan.fences]
    if not plan.fences:
        final[:] = np.mod(yaws0, 360.0)
        return {"final_yaw_deg": final, "status": status, "diag": diag}

    st = scene["status"]
    v = float(scene["belt"]["speed"])
    dt = float(preset["time_step"])
    check_steps = max(1, int(round(float(st["check_interval_s"]) / dt)))
    t_check = check_steps * dt
    rest_checks = max(1, int(math.ceil(float(st["rest_window_s"]) / t_check)))
    jam_window, jam_travel = float(st["jam_window_s"]), float(st["jam_travel"])
    rest_speed, rest_omega = float(st["rest_speed"]), math.radians(float(st["rest_omega_deg_s"]))
    flip, fall_z, lat = float(st["flip_tilt_deg"]), float(st["fall_z"]), float(st["lateral_limit"])
    approach, pad = float(st["approach_margin"]), float(st["clear_margin"])
    full_path = bool(preset["full_path"])
    half = model.radius + pad
    boxes = _fence_boxes_array(plan.fences)
    skip_slides = bool(preset["skip_slides"]) and not full_path
    straight = []  # (wall end P, unit direction d to the tip, normal n, length to the tip)
    for f in plan.fences:
        if f.fence.type == "straight":
            cx, cy, hl, ht_, yaw_f = f.boxes[0]
            d = np.array([math.cos(yaw_f), math.sin(yaw_f)])
            pw = np.array([cx, cy]) - hl * d
            straight.append((pw, d, np.array([-d[1], d[0]]), 2.0 * hl, ht_))
    slide_checks = max(1, int(math.ceil(float(st["slide_window_s"]) / t_check)))
    slide_tol, slide_yaw = float(st["slide_tol"]), float(st["slide_yaw_deg"])
    slide_min_speed = float(st["slide_min_speed"])
    skip_margin, skip_min = float(st["skip_margin"]), float(st["skip_min"])

    n_lanes = int(min(int(preset["lanes"]), drops))
    world = World(scene, preset, plan, n_lanes, model)
    pb, c = world.pb, world.cid
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=drops, unit="drop", file=sys.stderr, leave=False)
    try:
        queue = deque(range(drops))
        lanes: list[_Lane | None] = [None] * n_lanes
        t = 0.0

        def start(j: int) -> None:
            i = queue.popleft()
            world.reset_belt(j)
            y0 = plan.start_y
            if not full_path:  # start just before the part's own first contact
                gap = gap_ahead(hull_at(model.hull, math.radians(float(yaws0[i])) + model.alpha, 0.0, y0),
                                plan.samples, pad)
                if gap is not None and gap - approach > 0:
                    y0 += gap - approach
            body = world.add_part(j, 0.0, y0, float(yaws0[i]))
            lanes[j] = _Lane(i, body, t, deque())

        def finish(j: int, code: str, yaw: float = math.nan, pos=None) -> None:
            ln = lanes[j]
            i = ln.drop
            status[i] = code
            final[i] = yaw if code == "ok" else math.nan
            diag["sim_time"][i] = t - ln.t0
            diag["max_speed"][i], diag["max_omega"][i] = ln.max_speed, ln.max_omega
            diag["inside_fence"][i], diag["teleports"][i] = ln.inside_fence, ln.teleports
            diag["skips"][i] = ln.skips
            diag["probe_yaw"][i] = ln.probe_yaw
            if pos is not None:
                diag["final_x"][i], diag["final_y"][i] = pos[0], pos[1]
            pb.removeBody(ln.body, physicsClientId=c)
            lanes[j] = None
            if bar is not None:
                bar.update(1)
            if queue:
                start(j)

        for j in range(n_lanes):
            start(j)
        while any(ln is not None for ln in lanes):
            for _ in range(check_steps):
                world.step()
            t += t_check
            for j, ln in enumerate(lanes):
                if ln is None:
                    continue
                pos, q = pb.getBasePositionAndOrientation(ln.body, physicsClientId=c)
                lin, ang = pb.getBaseVelocity(ln.body, physicsClientId=c)
                if not (math.isfinite(pos[0] + pos[1] + pos[2] + q[0] + q[1] + q[2] + q[3])
                        and math.isfinite(lin[0] + lin[1] + lin[2] + ang[0] + ang[1] + ang[2])):
                    finish(j, "nan")
                    continue
                x, y, z = pos[0] - world.lane_x[j], pos[1], pos[2]
                speed = math.hypot(lin[0], lin[1])
                ln.max_speed = max(ln.max_speed, speed)
                ln.max_omega = max(ln.max_omega, abs(ang[2]))
                if check_fences and _inside_any_box(boxes, x, y):
                    ln.inside_fence = True
                yaw = (math.degrees(quat_yaw(q) - world.model.alpha)) % 360.0
                if probe_x is not None and math.isnan(ln.probe_yaw) and x <= probe_x:
                    ln.probe_yaw = yaw
                elapsed = t - ln.t0
                if _TRACE is not None:
                    _TRACE.append((ln.drop, elapsed, x, y, yaw, lin[0], lin[1], ang[2], ln.slide, ln.rest))
                if quat_tilt_deg(q) > flip:
                    finish(j, "flipped", pos=(x, y))
                    continue
                if z < fall_z or abs(x) > lat:
                    finish(j, "fell_off", pos=(x, y))
                    continue
                yr = quat_yaw(q)
                ln.hist.append((elapsed, x, y, yr))
                while ln.hist and elapsed - ln.hist[0][0] > jam_window + 1e-9:
                    ln.hist.popleft()
                h0 = ln.hist[0]
                if elapsed - h0[0] >= jam_window - 1e-9 and math.hypot(x - h0[1], y - h0[2]) < jam_travel:
                    finish(j, "jammed", pos=(x, y))
                    continue
                if elapsed > plan.time_limit:
                    finish(j, "timed_out", pos=(x, y))
                    continue
                # at rest: moving with the belt since the previous check, judged from the displacement
                # (Bullet's reported velocity of a part held by a compliant contact can keep a small
                # residual while the part does not move: docs/simulation.md)
                at_rest = False
                if len(ln.hist) >= 2:  # the previous check, unless the part was moved since
                    tp, xp, yp, rp = ln.hist[-2]
                    span = elapsed - tp
                    turn = (yr - rp + math.pi) % (2.0 * math.pi) - math.pi
                    at_rest = (math.hypot((x - xp) / span, (y - yp) / span - v) < rest_speed
                               and abs(turn) / span < rest_omega)
                if skip_slides and straight and not at_rest:
                    # steady sliding along a straight fence is translation-invariant: skip ahead
                    wx_, wy_ = lin[0], lin[1]
                    sp = math.hypot(wx_, wy_)
                    match = -1
                    if sp > slide_min_speed:
                        for k, (pw, d, nrm, flen, fht) in enumerate(straight):
                            if (wx_ * d[0] + wy_ * d[1] > 0 and abs(wx_ * d[1] - wy_ * d[0]) < slide_tol * sp
                                    and abs((x - pw[0]) * nrm[0] + (y - pw[1]) * nrm[1]) <= model.radius + fht + pad):
                                match = k
                                break
                    # steady: the same fence throughout, yaw within slide_yaw of the run's first check
                    dyaw = abs((yaw - ln.w_prev[0] + 180.0) % 360.0 - 180.0)
                    if match >= 0 and match == ln.slide_f and dyaw < slide_yaw:
                        ln.slide += 1
                    else:  # (re)start a run here
                        ln.slide, ln.slide_f, ln.w_prev = (1 if match >= 0 else 0), match, (yaw, 0.0)
                    if ln.slide >= slide_checks:
                        pw, d, nrm, flen, fht = straight[match]
                        yb = quat_yaw(q)
                        cb, sb = math.cos(yb), math.sin(yb)
                        dl = (d[0] * cb + d[1] * sb, -d[0] * sb + d[1] * cb)  # d in the body frame
                        lead = (x - pw[0]) * d[0] + (y - pw[1]) * d[1] + float(np.max(model.hull @ dl))
                        jump = flen - lead - skip_margin
                        if jump > skip_min:
                            world.move_part(ln.body, jump * d[0], jump * d[1], keep_velocity=(lin, ang))
                            ln.skips += 1
                            ln.hist.clear()
                        ln.slide = 0
                ln.rest = ln.rest + 1 if at_rest else 0
                if ln.rest < rest_checks:
                    continue
                if full_path:
                    if y >= plan.record_y:
                        finish(j, "ok", yaw, pos=(x, y))
                    continue
                gap = gap_ahead(hull_at(model.hull, quat_yaw(q), x, y), plan.samples, pad)
                if gap is None:
                    finish(j, "ok", yaw, pos=(x, y))
                    continue
                if gap - approach > skip_min:
                    # free transport to just before the next fence: a pure translation
                    world.move_part(ln.body, 0.0, gap - approach)
                    ln.teleports += 1
                    ln.hist.clear()
                    ln.rest = 0
    finally:
        if bar is not None:
            bar.close()
        world.close()
    return {"final_yaw_deg": final, "status": status, "diag": diag}


def simulate(geom, loc1: Fence, loc2: Fence, drops: int, seed: int, scene: dict, preset: dict,
             preset_name: str = "custom", progress: bool = False, probe_x: float | None = None,
             check_fences: bool = False, prune: bool = True, yaw_sampling: str = "random") -> dict:
    """One configuration: the npz payload (docs/data.md) plus ``diag`` (not written)."""
    if int(drops) != drops or drops < 1:
        raise FeederError(f"drops must be a positive integer, got {drops!r}")
    cfg = config_id(loc1, loc2)
    s = drop_seed(geom.part_id, cfg, seed)
    y0 = initial_yaws(s, int(drops), yaw_sampling)
    t0, c0 = time.perf_counter(), time.process_time()
    out = run_drops(geom, loc1, loc2, y0, scene, preset, progress=progress, probe_x=probe_x,
                    check_fences=check_fences, prune=prune)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    meta = {"part": geom.part_id, "loc1": loc1.spec, "loc2": loc2.spec, "config_id": cfg,
            "preset": preset_name, "seed": int(seed), "drops": int(drops), "yaw_sampling": yaw_sampling,
            "settings": {"scene": scene, "preset": preset},
            "status_counts": {k: int(np.sum(out["status"] == k)) for k in STATUSES}}
    return {"final_yaw_deg": out["final_yaw_deg"].astype(np.float64), "initial_yaw_deg": y0,
            "status": out["status"].astype(str), "wall_s": np.float64(wall),
            "cpu_s": np.float64(cpu),
            "meta": json.dumps(meta, sort_keys=True), "diag": out["diag"]}


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder simulate", description=__doc__.splitlines()[0])
    parser.add_argument("--part", required=True, help="parts/<id>.stl")
    parser.add_argument("--loc1", required=True, help="none | straight:ANGLE | curved:ANGLE (downstream)")
    parser.add_argument("--loc2", required=True, help="none | straight:ANGLE | curved:ANGLE (upstream)")
    parser.add_argument("--drops", type=int, required=True)
    parser.add_argument("--seed", type=int, default=0, help="base seed")
    parser.add_argument("--preset", default="fast")
    parser.add_argument("--yaw-sampling", default="random", choices=YAW_SAMPLINGS,
                        help="initial yaws: random (independent, the paper) or golden (even prefixes)")
    parser.add_argument("--settings", default=None, help="JSON {scene, presets}; default config/config.yaml")
    parser.add_argument("--out", required=True, help="output .npz")
    args = parser.parse_args(argv)

    loc1, loc2 = parse_location(args.loc1), parse_location(args.loc2)
    if args.drops < 1:
        raise FeederError(f"--drops must be positive, got {args.drops}")
    scene, presets = load_settings(args.settings)
    preset = get_preset(presets, args.preset)
    from feeder.parts.geometry import load_part

    path = Path(args.part)
    if not path.is_file():
        raise FeederError(f"part file {path} not found")
    geom = load_part(path)
    try:
        res = simulate(geom, loc1, loc2, args.drops, args.seed, scene, preset, args.preset,
                       progress=sys.stderr.isatty(), yaw_sampling=args.yaw_sampling)
    except KeyError as err:
        raise FeederError(f"scene settings lack key {err}") from None
    from feeder.io import write_npz

    write_npz(args.out, **{k: v for k, v in res.items() if k != "diag"})
    counts = json.loads(res["meta"])["status_counts"]
    print(f"{geom.part_id} {config_id(loc1, loc2)}: {args.drops} drops in {float(res['wall_s']):.1f} s; "
          + ", ".join(f"{k} {n}" for k, n in counts.items() if n), file=sys.stderr)
    return 0
