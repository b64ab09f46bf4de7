"""The simulated part and the pybullet world it rides in (used by :mod:`feeder.sim.drops`).

The part body is a compound of the exact convex pieces of its outline, each inset by the
collision margin and extruded (so the margin-inflated shape is the true part), in the part's
centroidal principal frame; mass, centre of mass and the inertia diagonal are set from the
polygon (:func:`part_model`, pure). :class:`World` is one pybullet client holding one or more
copies of the belt lane (belt, containment walls, fences) and the part's collision shape.

How the part rests on the belt is a setting (``scene.belt.footprint``). ``pieces`` (the paper's
way): every convex piece touches the belt, and Bullet keeps up to four contact points per piece, so
the weight splits over the pieces' corners and the outcome depends on how the outline was cut
(measured: the same 60 x 30 mm rectangle as one piece, two halves, two triangles or six strips ends
up to 4 degrees apart after a curved fence, or in another basin), and the cost grows with the
number of pieces. ``pads``: a fixed number of small spheres at the centroids of equal-area cells
of the footprint (:func:`footprint_pads`) carry the weight, a uniform pressure whatever the
decomposition, on fixed links of the part that collide only with the belt; the exact pieces
collide only with the walls and fences.

Bullet combines friction coefficients by multiplication: part-belt 0.8 x 1.0, part-fence
0.8 x 0.5 = 0.4 (a straight fence holds parts for θ > atan(1/0.4) = 68.2°).
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.lane.geometry import FenceGeom
from feeder.sim.scene import belt_contact, footprint_setting, wall_contact_setting

# Part collision filter: group bit 1 (dynamic) colliding only with static bodies (group bit 2).
_PART_GROUP, _PART_MASK = 1, 2
# With footprint pads (pybullet filters pairs by OR: a pair collides when either body's group is
# in the other's mask, so every body involved gets an explicit group and mask): the part's pieces
# meet walls and fences, its pads meet the belt, nothing else meets anything.
_WALLS_GROUP, _BELT_GROUP, _PADS_GROUP = 2, 4, 8
# Share of the part's mass (and inertia) carried by the pad links, all placed at the centre of
# mass so the totals stay exact. Measured: pad links carrying 1 % of the mass let the part slip on
# the belt (2.4 mm/s at rest, turning); 50 % or 99 % ride exactly with it.
_PAD_MASS_SHARE = 0.5
_MAX_COMPOUND = 16  # pybullet's createCollisionShapeArray silently drops shapes beyond 16
# A part must be at least this many times as thick as the gap under the fences, or it slips
# under them: measured (20 mm L-shape, fences 0.5 mm above the belt, 8 drops each), 0.6 mm
# thick parts ended at their initial yaw, 0.8 mm ones half turned, 0.9 mm and thicker like 5 mm ones.
MIN_THICKNESS_PER_CLEARANCE = 2.0


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
    pads: np.ndarray | None = field(repr=False, default=None)  # (K, 2) belt footprint pads (None: the pieces)
    pad_radius: float = 0.0  # m: radius of each pad sphere
    slabs: tuple[np.ndarray, ...] | None = field(repr=False, default=None)  # outline slabs (None: the pieces)

    @property
    def shell(self) -> tuple[np.ndarray, ...]:
        """The convex shapes that meet walls and fences: the outline slabs, else the pieces."""
        return self.pieces if self.slabs is None else self.slabs


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

    polys = [Polygon(p) for p in pieces]
    while (pair := _mergeable_pair(polys, tolerance)) is not None:
        i, j, hull = pair
        polys = [q for k, q in enumerate(polys) if k not in (i, j)] + [hull]
    return [np.asarray(q.exterior.coords)[:-1] for q in polys]


def _mergeable_pair(polys, tolerance: float):
    """The first pair (i, j, hull of their union) of touching polygons whose hull adds nothing
    beyond ``tolerance``, or None."""
    from shapely.ops import unary_union

    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            a, b = polys[i], polys[j]
            if a.distance(b) > 0.0:
                continue
            union = unary_union([a, b])
            hull = union.convex_hull
            if hull.difference(union).area <= 1e-12 * hull.area or (
                tolerance > 0 and union.buffer(tolerance, join_style=2).contains(hull)
            ):
                return i, j, hull
    return None


def outline_slabs(outline, depth: float, max_turn_deg: float, min_depth_share: float = 1.0 / 64.0) -> list[np.ndarray]:
    """Convex slabs along the outline of a simple polygon, reaching ``depth`` into it (pure).

    The outline is cut into *chains*: runs of consecutive edges that turn left (convex corners)
    by at most ``max_turn_deg`` in all; a reflex corner always ends a chain. A chain's slab is the
    convex hull of its vertices and of each vertex moved ``depth`` inward (along the corner's
    bisector, so never out past a sharp corner); its outer side is the chain itself. A slab that leaves the
    polygon (a part thinner than ``depth``, a chord across a concave neighbour) is split in half,
    and a single edge's slab is made shallower, halving ``depth`` down to ``min_depth_share`` of it
    (then the edge gets none; its neighbours' cover its ends). The slabs depend only on the
    outline, so every decomposition of a part meets walls and fences the same way, and their
    union covers the outline, the only place a wall or fence can touch a part (holes are closed).
    """
    from shapely.geometry import Polygon
    from shapely.geometry.polygon import orient

    outline = np.asarray(outline, np.float64)
    if outline.ndim != 2 or outline.shape[0] < 3 or outline.shape[1] != 2 or not Polygon(outline).is_valid:
        raise FeederError("outline slabs: the outline is not a simple polygon with an area")
    if not 0.0 <= float(max_turn_deg) < 180.0:
        raise FeederError(f"outline slabs: max_turn_deg must lie in [0, 180) (got {max_turn_deg!r})")
    ring = np.asarray(orient(Polygon(outline), 1.0).exterior.coords)[:-1]
    poly = Polygon(ring)
    if poly.area <= 0:
        raise FeederError("outline slabs: the outline is not a simple polygon with an area")
    n = len(ring)
    slack = 1e-9 * math.sqrt(poly.area)
    inside = poly.buffer(slack)
    turn = np.array([_turn(ring[k - 1], ring[k], ring[(k + 1) % n]) for k in range(n)])  # at vertex k, rad
    slabs = []
    for chain in _chains(turn, math.radians(float(max_turn_deg))):
        slabs += _chain_slabs(ring, turn, chain, float(depth), min_depth_share, inside, slack)
    if not slabs:
        raise FeederError("outline slabs: no edge of the outline holds a slab")
    return slabs


def _turn(p, q, r) -> float:
    """Signed turn (rad) of the path p -> q -> r at q: > 0 to the left (a convex corner of a
    counter-clockwise ring), < 0 to the right (reflex)."""
    u, v = q - p, r - q
    return math.atan2(_cross(u, v), float(np.dot(u, v)))


def _chains(turn: np.ndarray, max_turn: float) -> list[list[int]]:
    """Edges (edge k runs from vertex k to k+1) in runs whose inner corners turn left by at most
    ``max_turn`` in all; a run starts after a reflex corner, or after the sharpest corner when none
    is reflex (the same outline always gives the same runs)."""
    n = len(turn)
    reflex = np.flatnonzero(turn < 0)
    start = int(reflex[0]) if len(reflex) else int(np.argmax(turn))
    chains, current, total = [], [start], 0.0
    for k in range(start + 1, start + n):
        edge, t = k % n, float(turn[k % n])  # t: the corner between the current edge and this one
        if t >= 0 and total + t <= max_turn:
            current.append(edge)
            total += t
        else:
            chains.append(current)
            current, total = [edge], 0.0
    chains.append(current)
    return chains


def _chain_slabs(ring, turn, chain, depth, min_depth_share, inside, slack) -> list[np.ndarray]:
    """The slab of one chain, or of its halves when it leaves the polygon (:func:`outline_slabs`):
    the convex hull of the chain's vertices and of each vertex moved ``depth`` inward, along the
    corner's bisector where the corner is convex (so never out past a sharp corner), along the
    chain's own edge normal at a reflex end."""
    from shapely.geometry import MultiPoint
    from shapely.geometry.polygon import orient

    n = len(ring)
    vertices = [chain[0]] + [(k + 1) % n for k in chain]

    def normal(k):  # inward unit normal of edge k (the interior lies left of ring[k] -> ring[k + 1])
        e = ring[(k + 1) % n] - ring[k]
        return np.array([-e[1], e[0]]) / max(float(np.hypot(*e)), slack)

    inward = []
    for pos, v in enumerate(vertices):
        if turn[v] >= 0:
            w = normal(v - 1) + normal(v)
            w = w / max(float(np.hypot(*w)), slack)
        else:  # a reflex corner ends the chain: go in along the chain's edge
            w = normal(chain[0]) if pos == 0 else normal(chain[-1])
        inward.append(w)
    d = depth
    while d >= min_depth_share * depth:
        points = [ring[v] for v in vertices] + [ring[v] + d * w for v, w in zip(vertices, inward)]
        slab = MultiPoint(points).convex_hull
        if slab.geom_type == "Polygon" and slab.area > 0 and inside.contains(slab):
            return [np.asarray(orient(slab, 1.0).exterior.coords)[:-1]]
        if len(chain) > 1:
            half = len(chain) // 2
            return _chain_slabs(ring, turn, chain[:half], depth, min_depth_share, inside, slack) + _chain_slabs(
                ring, turn, chain[half:], depth, min_depth_share, inside, slack
            )
        d *= 0.5
    return []


def _cross(u, v) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def footprint_pads(outline, count: int, samples_per_pad: int = 400, holes=()) -> np.ndarray:
    """``count`` points that stand for a uniform pressure over the polygon ``outline`` (N, 2), less
    its ``holes``: the centroids of ``count`` cells of equal area, moved together so their mean is
    the footprint's centroid exactly (pure).

    The polygon is sampled on a square grid of about ``count * samples_per_pad`` points inside it;
    the cells come from splitting the samples in two, across x at even depths and across y at odd
    depths (in the principal frame: the long axis first), at the sample quantile that gives each
    side its share of the cells (a ``k``-cell group splits into ``k // 2`` and ``k - k // 2``),
    until every group is one cell. Alternating keeps pads on both sides of the long axis, so a
    thin part stands on them (splitting the longer side only put all 16 pads of an 80 x 8 mm bar
    on its centre line, and it tipped over at every drop). Equal-area cells carry equal weight on
    a compliant belt when the points' mean lies under the centre of mass, which the final shift
    makes exact.
    """
    from shapely import contains_xy
    from shapely.geometry import Polygon

    count = int(count)
    if count < 1:
        raise FeederError(f"footprint pads: need at least one pad (got {count})")
    poly = Polygon(np.asarray(outline, np.float64), [np.asarray(h, np.float64) for h in holes])
    if not poly.is_valid or poly.area <= 0:
        raise FeederError("footprint pads: the outline is not a simple polygon with an area (and holes inside it)")
    x0, y0, x1, y1 = poly.bounds
    side = math.sqrt(poly.area / (count * samples_per_pad))
    xs, ys = np.arange(x0 + 0.5 * side, x1, side), np.arange(y0 + 0.5 * side, y1, side)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    pts = pts[contains_xy(poly, pts[:, 0], pts[:, 1])]
    if len(pts) < count:
        raise FeederError(f"footprint pads: {count} pads need a finer sample ({len(pts)} points inside)")

    def cells(points: np.ndarray, k: int, depth: int) -> list[np.ndarray]:
        if k == 1:
            return [points.mean(axis=0)]
        order = np.argsort(points[:, depth % 2], kind="stable")
        cut = int(round(len(points) * (k // 2) / k))
        return cells(points[order[:cut]], k // 2, depth + 1) + cells(points[order[cut:]], k - k // 2, depth + 1)

    pads = np.array(cells(pts, count, 0))
    c = poly.centroid
    return pads - pads.mean(axis=0) + np.array([c.x, c.y])


def quiet_pybullet():
    """The pybullet module, imported without the build-time line its C extension writes to the
    process's stderr on import (so a command that fails after simulating prints one error line)."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


def check_scene_fit(geom, scene: dict) -> None:
    """A one-line FeederError for a part the scene cannot hold: one that fits between the belt's
    walls at no yaw (its circumradius about the centroid reaches ``belt.half_width``; parts are
    placed centred), or one too thin for the fences to push (``MIN_THICKNESS_PER_CLEARANCE``
    times ``fences.clearance``). Either would give a label of nothing but falls or untouched drops.
    Also one whose material between a hole and the outline (or two holes) is no thicker than twice
    ``part.collision_margin``: each convex piece is inset by the margin, so such a wall would
    vanish from the collision shape and leave a gap a fence could push into."""
    from feeder.parts.geometry import thinnest_wall

    check_fit(geom.part_id, geom.outline, geom.centroid, geom.thickness, scene)
    least = 2.0 * float(scene["part"]["collision_margin"])
    wall = thinnest_wall(geom.outline, getattr(geom, "holes", ()))
    if wall <= least:
        raise FeederError(
            f"part {geom.part_id}: {1e3 * wall:.3g} mm of material between a hole and the outline or another "
            f"hole, no more than {1e3 * least:g} mm (2 x scene.part.collision_margin): the collision shape "
            "would lose that wall"
        )


# What a refusal of check_fit adds where the command reading the part has ``--units``.
UNITS_HINT = "; is the part file in other units? (--units)"


def check_fit(part_id: str, outline, centroid, thickness: float, scene: dict, hint: str = UNITS_HINT) -> None:
    """:func:`check_scene_fit` from the outline (metres), its area centroid and the thickness,
    without a :class:`~feeder.parts.geometry.PartGeometry` (whose convex decomposition
    ``feeder predict`` does not need). ``hint`` ends the message (a command without ``--units``
    says how it read the file's units instead)."""
    centred = np.asarray(outline, np.float64) - np.asarray(centroid, np.float64)
    radius = float(np.max(np.hypot(centred[:, 0], centred[:, 1])))
    half_width = float(scene["belt"]["half_width"])
    if radius >= half_width:
        raise FeederError(
            f"part {part_id}: {2 * radius:.3g} m across (its circumscribed circle), wider than the belt "
            f"between its walls ({2 * half_width:g} m){hint}"
        )
    least = MIN_THICKNESS_PER_CLEARANCE * float(scene["fences"]["clearance"])
    if thickness < least:
        raise FeederError(
            f"part {part_id}: {thickness:.3g} m thick, thinner than {least:g} m "
            f"({MIN_THICKNESS_PER_CLEARANCE:g} x scene.fences.clearance): it would slip under the fences{hint}"
        )


def part_model(geom, scene: dict, merge_tolerance: float | None = 0.0) -> PartModel:
    """Pieces (merged within ``merge_tolerance``; exactly as given for None, as the decomposition
    bench needs) in the centroidal principal frame, inset by the margin."""
    from shapely.geometry import MultiPoint, Point, Polygon

    check_scene_fit(geom, scene)
    pc = scene["part"]
    margin = float(pc["collision_margin"])
    mass, inertia, alpha = principal_inertia(geom.area, geom.second_moment, geom.thickness, float(pc["density"]))
    c, s = math.cos(-alpha), math.sin(-alpha)
    rot = np.array([[c, -s], [s, c]])
    centroid = np.asarray(geom.centroid, dtype=np.float64)
    pieces = []
    given = geom.convex_pieces if merge_tolerance is None else merge_pieces(geom.convex_pieces, merge_tolerance)
    for piece in given:
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
    footprint, count, pad_radius = footprint_setting(scene)
    holes = [(np.asarray(h, np.float64) - centroid) @ rot.T for h in geom.holes]
    pads = footprint_pads(outline @ rot.T, count, holes=holes) if footprint == "pads" else None
    slabs = _slabs(outline @ rot.T, scene, margin)
    if pads is not None and not MultiPoint(pads).convex_hull.contains(Point(0.0, 0.0)):
        raise FeederError(
            f"part {geom.part_id}: its {count} footprint pads do not surround its centre of mass; "
            "it would tip over (scene.belt.footprint.pads)"
        )
    return PartModel(
        geom.part_id, float(geom.thickness), mass, inertia, alpha, radius, tuple(pieces), hull, pads, pad_radius, slabs
    )


def _slabs(outline: np.ndarray, scene: dict, margin: float) -> tuple[np.ndarray, ...] | None:
    """The outline slabs of ``scene.part.wall_contact`` (inset by the margin), or None (the pieces)."""
    from shapely.geometry import Polygon

    model, depth, max_turn = wall_contact_setting(scene)
    if model == "pieces":
        return None
    inset = Polygon(outline).buffer(-margin, join_style=2)
    if inset.geom_type != "Polygon" or inset.is_empty:
        raise FeederError("outline slabs: the outline falls apart when inset by the collision margin")
    return tuple(outline_slabs(np.asarray(inset.exterior.coords)[:-1], depth, max_turn))


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
# The world
# --------------------------------------------------------------------------------------------
@dataclass
class Plan:
    """What a world holds and where its drops run (made by :func:`feeder.sim.drops.make_plan`)."""

    fences: list[FenceGeom]  # fences to build
    samples: np.ndarray  # (P, 2) outline samples of the built fences (reach queries)
    start_y: float
    record_y: float
    time_limit: float


def connect_world(pb, scene: dict, preset: dict, client: int | None = None) -> int:
    """A fresh DIRECT client with the scene's gravity and the preset's solver settings (the
    study's worlds and the bare world of ``feeder bench-step`` alike). ``client``: an open client
    to reuse instead: ``resetSimulation`` deletes its world and builds an empty one (a new solver
    included), so what follows runs as in a new client, bit for bit (tests/test_sim.py), without
    the ~12 ms a ``connect`` costs (docs/performance.md)."""
    c = pb.connect(pb.DIRECT) if client is None else int(client)
    pb.resetSimulation(physicsClientId=c)
    pb.setGravity(0, 0, -float(scene["gravity"]), physicsClientId=c)
    pb.setPhysicsEngineParameter(
        fixedTimeStep=float(preset["time_step"]),
        numSubSteps=int(preset["substeps"]),
        numSolverIterations=int(preset["solver_iterations"]),
        enableConeFriction=1,
        deterministicOverlappingPairs=1,
        enableFileCaching=0,
        physicsClientId=c,
    )
    if preset.get("engine"):
        pb.setPhysicsEngineParameter(**dict(preset["engine"]), physicsClientId=c)
    return c


HULL_MARGIN_M = 1e-4  # m: Bullet's collision margin around a hull-built curved fence, which is inset by it


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

    def __init__(self, scene: dict, preset: dict, plan: Plan, lanes: int, model: PartModel, client: int | None = None):
        pb = quiet_pybullet()
        self.pb = pb
        self.scene, self.preset, self.plan, self.model = scene, preset, plan, model
        self.owns_client = client is None  # else the caller's open client, reset here and left open by close()
        self.cid = self._connect(client)
        belt = scene["belt"]
        self.speed = float(belt["speed"])
        self.belt_vel = [0.0, self.speed, 0.0]
        self.pitch = 2.0 * (float(belt["half_width"]) + float(scene["walls"]["thickness"])) + 0.1
        self.lane_x = [(j - 0.5 * (lanes - 1)) * self.pitch for j in range(lanes)]
        travel = self.speed * plan.time_limit  # how far a belt moves during one drop
        # a lane's belt at drop start: from behind the start (a held part stays while the belt
        # runs on) to past the record point (parts may be moved forward by shortcuts)
        bt = float(belt["thickness"])
        blo, bhi = plan.start_y - travel - 1.0, plan.record_y + 1.0
        self.belt_start = [0.5 * (blo + bhi), -0.5 * bt]
        belt_shape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[0.5 * self.pitch, 0.5 * (bhi - blo), 0.5 * bt], physicsClientId=self.cid
        )
        walls_y = (min(blo, plan.start_y - 1.0), bhi + travel)
        self.belts = []
        for x0 in self.lane_x:
            self.belts.append(self._add_belt(x0, belt_shape))
            self._add_walls(x0, *walls_y)
            self._add_fences(x0)
        self.part_shape = self._add_part_shape()
        self.pad_shapes = self._add_pad_shapes()
        if self.pad_shapes:  # explicit groups for every static body (pybullet's OR filter)
            for body in range(pb.getNumBodies(physicsClientId=self.cid)):
                group, mask = (_BELT_GROUP, _PADS_GROUP) if body in self.belts else (_WALLS_GROUP, _PART_GROUP)
                pb.setCollisionFilterGroupMask(body, -1, group, mask, physicsClientId=self.cid)

    def _connect(self, client: int | None = None) -> int:
        return connect_world(self.pb, self.scene, self.preset, client)

    def _add_belt(self, x0: float, shape: int) -> int:
        """The lane's belt slab at its start pose (compliant contact when the scene asks for it)."""
        pb, c, belt = self.pb, self.cid, self.scene["belt"]
        body = pb.createMultiBody(0, shape, basePosition=[x0, *self.belt_start], physicsClientId=c)
        self._surface(body, float(belt["friction"]))
        contact = belt_contact(belt)
        if contact is not None:  # compliant belt: a spring-damper per contact point (Bullet: ERP/CFM)
            pb.changeDynamics(body, -1, contactStiffness=contact[0], contactDamping=contact[1], physicsClientId=c)
        return body

    def _add_walls(self, x0: float, wlo: float, whi: float) -> None:
        """The two containment walls of the lane, from ``wlo`` to ``whi`` along the belt."""
        pb, c = self.pb, self.cid
        belt, walls = self.scene["belt"], self.scene["walls"]
        wt, wh = float(walls["thickness"]), float(walls["height"])
        wx = float(belt["half_width"]) + 0.5 * wt
        shape = pb.createCollisionShapeArray(
            shapeTypes=[pb.GEOM_BOX, pb.GEOM_BOX],
            halfExtents=[[0.5 * wt, 0.5 * (whi - wlo), 0.5 * wh]] * 2,
            collisionFramePositions=[[-wx, 0, 0], [wx, 0, 0]],
            physicsClientId=c,
        )
        body = pb.createMultiBody(0, shape, basePosition=[x0, 0.5 * (wlo + whi), 0.5 * wh], physicsClientId=c)
        self._surface(body, float(walls["friction"]))

    def _add_fences(self, x0: float) -> None:
        """The plan's fences in the lane: static compounds of their boxes (:meth:`_add_boxes`), or
        for a curved fence with ``scene.fences.curved.build: hull`` one convex piece
        (:meth:`_add_hull`), and a round tip's cylinder (:meth:`feeder.lane.geometry.FenceGeom.tip_cap`)."""
        from feeder.lane.geometry import curved_build

        pb, c, fc = self.pb, self.cid, self.scene["fences"]
        fh, fclr = float(fc["height"]), float(fc["clearance"])
        hull = curved_build(self.scene) == "hull"
        for f in self.plan.fences:
            if hull and f.fence.type == "curved":
                self._add_hull(f, x0)
            else:
                self._add_boxes(f, x0)
            cap = f.tip_cap()
            if cap is not None:  # a round tip: a static cylinder of its own (a compound holds <= 16 shapes)
                shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=cap[2], height=fh, physicsClientId=c)
                body = pb.createMultiBody(
                    0, shape, basePosition=[x0 + cap[0], cap[1], fclr + 0.5 * fh], physicsClientId=c
                )
                self._surface(body, float(fc["friction"]))

    def _add_boxes(self, f, x0: float) -> None:
        """The fence ``f`` as static compounds of its boxes (at most 16 per body)."""
        pb, c, fc = self.pb, self.cid, self.scene["fences"]
        fh, fclr = float(fc["height"]), float(fc["clearance"])
        for k in range(0, len(f.boxes), _MAX_COMPOUND):  # pybullet keeps <= 16 shapes per array
            chunk = f.boxes[k : k + _MAX_COMPOUND]
            shape = pb.createCollisionShapeArray(
                shapeTypes=[pb.GEOM_BOX] * len(chunk),
                halfExtents=[[b[2], b[3], 0.5 * fh] for b in chunk],
                collisionFramePositions=[[b[0], b[1], 0.0] for b in chunk],
                collisionFrameOrientations=[pb.getQuaternionFromEuler([0, 0, b[4]]) for b in chunk],
                physicsClientId=c,
            )
            body = pb.createMultiBody(0, shape, basePosition=[x0, 0.0, fclr + 0.5 * fh], physicsClientId=c)
            self._surface(body, float(fc["friction"]))

    def _add_hull(self, f, x0: float) -> None:
        """The curved fence ``f`` as one static convex piece: the hull of its outer face's points
        (:func:`feeder.lane.geometry.curved_outer_points`) over the fence's height, so a part
        sliding along it meets no seam between boxes."""
        from feeder.lane.geometry import curved_outer_points

        pb, c, fc = self.pb, self.cid, self.scene["fences"]
        fh, fclr = float(fc["height"]), float(fc["clearance"])
        pts, centre = curved_outer_points(self.scene, f.location, f.fence)
        pts = pts[: len(f.boxes) + 1]  # a fence trimmed to its gap (trim_to_gap) lost boxes at its tip
        # Bullet grows a convex hull by its collision margin: set the margin and inset the points by
        # it (towards the arc's centre, and from the top and bottom), so the face is the boxes' face
        out = pts - centre
        pts = pts - HULL_MARGIN_M * out / np.hypot(out[:, 0], out[:, 1])[:, None]
        half = 0.5 * fh - HULL_MARGIN_M
        verts = [[float(p[0]), float(p[1]), z] for z in (-half, half) for p in pts]
        shape = pb.createCollisionShape(pb.GEOM_MESH, vertices=verts, physicsClientId=c)
        body = pb.createMultiBody(0, shape, basePosition=[x0, 0.0, fclr + 0.5 * fh], physicsClientId=c)
        pb.changeDynamics(body, -1, collisionMargin=HULL_MARGIN_M, physicsClientId=c)
        self._surface(body, float(fc["friction"]))

    def _add_part_shape(self) -> int:
        """The part's collision shape (its pieces as one OBJ compound), shared by every part body."""
        model = self.model
        self._tmp = tempfile.TemporaryDirectory(prefix="feeder-sim-")
        obj = Path(self._tmp.name) / "part.obj"
        margin = float(self.scene["part"]["collision_margin"])
        obj.write_text(obj_text(model.shell, 0.5 * model.thickness - margin))
        shape = self.pb.createCollisionShape(self.pb.GEOM_MESH, fileName=str(obj), physicsClientId=self.cid)
        if shape < 0:
            raise FeederError(f"part {model.part_id}: pybullet rejected its collision shape")
        return shape

    def _add_pad_shapes(self) -> list[int]:
        """The footprint pads as sphere compounds of at most 16 (one per pad link); none without pads."""
        m, pb = self.model, self.pb
        if m.pads is None:
            return []
        z = -0.5 * m.thickness + m.pad_radius  # each sphere touches the belt where the part's bottom does
        shapes = []
        for k in range(0, len(m.pads), _MAX_COMPOUND):
            chunk = m.pads[k : k + _MAX_COMPOUND]
            shape = pb.createCollisionShapeArray(
                shapeTypes=[pb.GEOM_SPHERE] * len(chunk),
                radii=[m.pad_radius] * len(chunk),
                collisionFramePositions=[[float(x), float(y), z] for x, y in chunk],
                physicsClientId=self.cid,
            )
            if shape < 0:
                raise FeederError(f"part {m.part_id}: pybullet rejected its footprint pads")
            shapes.append(shape)
        return shapes

    def _surface(self, body: int, friction: float, link: int = -1) -> None:
        self.pb.changeDynamics(
            body,
            link,
            lateralFriction=friction,
            restitution=float(self.scene["restitution"]),
            rollingFriction=0.0,
            spinningFriction=0.0,
            physicsClientId=self.cid,
        )

    def reset_belt(self, lane: int) -> None:
        """Put the lane's belt back at its start pose, moving at the belt speed (no part on it)."""
        pb, c = self.pb, self.cid
        pb.resetBasePositionAndOrientation(
            self.belts[lane], [self.lane_x[lane], *self.belt_start], [0, 0, 0, 1], physicsClientId=c
        )
        pb.resetBaseVelocity(self.belts[lane], self.belt_vel, [0.0, 0.0, 0.0], physicsClientId=c)

    def add_part(self, lane: int, x: float, y: float, yaw_deg: float) -> int:
        """A part flat on the lane's belt at (x, y), moving with the belt."""
        pb, c, m = self.pb, self.cid, self.model
        yb = math.radians(yaw_deg) + m.alpha
        pose = dict(
            basePosition=[self.lane_x[lane] + x, y, 0.5 * m.thickness],
            baseOrientation=[0.0, 0.0, math.sin(0.5 * yb), math.cos(0.5 * yb)],
        )
        if self.pad_shapes:
            return self._add_padded_part(pose)
        body = pb.createMultiBody(m.mass, self.part_shape, **pose, physicsClientId=c)
        pb.changeDynamics(
            body,
            -1,
            localInertiaDiagonal=list(m.inertia),
            collisionMargin=float(self.scene["part"]["collision_margin"]),
            linearDamping=0.0,
            angularDamping=0.0,
            physicsClientId=c,
        )
        self._surface(body, float(self.scene["part"]["friction"]))
        pb.setCollisionFilterGroupMask(body, -1, _PART_GROUP, _PART_MASK, physicsClientId=c)
        pb.resetBaseVelocity(body, self.belt_vel, [0.0, 0.0, 0.0], physicsClientId=c)
        return body

    def _add_padded_part(self, pose: dict) -> int:
        """The part as its pieces (base: walls and fences) and fixed pad links (the belt only), the
        mass and inertia shared between them about the one centre of mass."""
        pb, c, m = self.pb, self.cid, self.model
        links = len(self.pad_shapes)
        share = _PAD_MASS_SHARE / links
        origin, identity = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]
        body = pb.createMultiBody(
            (1.0 - _PAD_MASS_SHARE) * m.mass,
            self.part_shape,
            **pose,
            linkMasses=[share * m.mass] * links,
            linkCollisionShapeIndices=self.pad_shapes,
            linkVisualShapeIndices=[-1] * links,
            linkPositions=[origin] * links,
            linkOrientations=[identity] * links,
            linkInertialFramePositions=[origin] * links,
            linkInertialFrameOrientations=[identity] * links,
            linkParentIndices=[0] * links,
            linkJointTypes=[pb.JOINT_FIXED] * links,
            linkJointAxis=[[0.0, 0.0, 1.0]] * links,
            physicsClientId=c,
        )
        friction = float(self.scene["part"]["friction"])
        for link, weight in [(-1, 1.0 - _PAD_MASS_SHARE)] + [(j, share) for j in range(links)]:
            # inertia alone: pybullet 3.2.7 writes a link's localInertiaDiagonal into the base when
            # the same call also sets damping (measured: the part turned with 40-83 % of its inertia)
            pb.changeDynamics(body, link, localInertiaDiagonal=[weight * i for i in m.inertia], physicsClientId=c)
            self._surface(body, friction, link)
            group, mask = (_PART_GROUP, _WALLS_GROUP) if link == -1 else (_PADS_GROUP, _BELT_GROUP)
            pb.setCollisionFilterGroupMask(body, link, group, mask, physicsClientId=c)
        pb.changeDynamics(
            body,
            -1,
            collisionMargin=float(self.scene["part"]["collision_margin"]),
            linearDamping=0.0,
            angularDamping=0.0,
            physicsClientId=c,
        )
        pb.resetBaseVelocity(body, self.belt_vel, [0.0, 0.0, 0.0], physicsClientId=c)
        return body

    def part_motion(self, body: int):
        """``(position, orientation, linear velocity, angular velocity)`` of a part, world frame."""
        pb, c = self.pb, self.cid
        pos, q = pb.getBasePositionAndOrientation(body, physicsClientId=c)
        lin, ang = pb.getBaseVelocity(body, physicsClientId=c)
        return pos, q, lin, ang

    def move_part(self, body: int, dx: float, dy: float, keep_velocity=None) -> None:
        """Translate a part (same orientation); velocity: the given (lin, ang) or riding the belt."""
        pb, c = self.pb, self.cid
        pos, q = pb.getBasePositionAndOrientation(body, physicsClientId=c)
        pb.resetBasePositionAndOrientation(body, [pos[0] + dx, pos[1] + dy, pos[2]], q, physicsClientId=c)
        lin, ang = keep_velocity if keep_velocity is not None else (self.belt_vel, [0.0, 0.0, 0.0])
        pb.resetBaseVelocity(body, lin, ang, physicsClientId=c)

    def remove_part(self, body: int) -> None:
        self.pb.removeBody(body, physicsClientId=self.cid)

    def step(self) -> None:
        self.pb.stepSimulation(physicsClientId=self.cid)

    def close(self) -> None:
        try:
            if self.owns_client:
                self.pb.disconnect(physicsClientId=self.cid)
        finally:
            self._tmp.cleanup()
