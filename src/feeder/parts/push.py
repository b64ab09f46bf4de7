"""Analytic fence response of a part from its outline alone ("push function" features).

A flat part carried by the belt into a passive fence turns until an edge of its convex hull lies
flush against the fence, then slides along it (quasi-static pushing: Mason 1986; Peshkin &
Sanderson 1988; Goldberg 1993, "Orienting polygonal parts without sensors"; for fences over a
belt, Wiegley, Goldberg, Peshkin & Brokowski 1996). This module computes that response from the
outline polygon (the part file's own frame, metres, as :func:`feeder.parts.geometry.read_outline`
and :class:`~feeder.parts.geometry.PartGeometry` give it) and the scene's fence geometry, and turns
a fence configuration into an analytic 360-bin PMF and a fixed-size feature block. Everything is a
pure function of its arguments; the only file read is the study config when no ``scene`` is given
(:func:`default_scene`).

Geometry (:func:`push_geometry`)
    The convex hull of the outline, taken about the outline's **area centroid** (the centre of
    mass of the uniform part, which is what the fence torques act about), not the hull's own
    centroid: for a concave part the two differ, and a hull edge is stable with respect to the
    centre of mass. The radius function ``r(φ)`` (:func:`radius_function`) is the support distance
    from that centroid to the hull's supporting line of outward normal ``φ`` (degrees, part frame).
    The *limit-surface radius* ``c = ∫|x − x_c| dA / A`` (exact, per edge) sets how the belt's
    friction resists turning against sliding (ellipsoidal limit surface, Lee & Cutkosky 1991,
    uniform pressure).

Push function (:func:`push_function`)
    Orientation is parametrised by ``φ``, the direction in the part frame of the contact normal
    pointing from the part at the fence. Frictionless (``mu = 0``, Goldberg): the part turns to
    decrease ``r``; the stable orientations are the local minima of ``r``, the normals of hull
    edges whose foot from the centroid falls strictly inside the edge, and each basin extends to
    the neighbouring local maxima (the vertex directions). With fence friction ``mu`` and the
    part sliding along the fence (which it does outside the friction cone, see *jams*), Mason's
    voting theorem gives the turning sense from the friction-cone edge that opposes the slide:
    the contact force ``F = n − mu t`` (``n`` the fence's normal into the part, ``t`` the fence
    direction downstream) makes the moment ``∝ s − mu d`` about the centroid, ``s`` the contact's
    offset downstream from the centroid's foot and ``d`` its distance from the fence. Hence an edge
    is stable iff the foot shifted ``mu · d`` downstream lies strictly inside it, and every basin
    boundary is the vertex direction turned by ``−side · atan(mu)`` (``side`` +1 for a fence on
    the right of the travel direction, −1 on the left). ``mu = 0`` is exactly Goldberg's function;
    the measures of basins do not change with ``mu`` as long as the set of stable edges does not
    (a 2:1 rectangle keeps ``2·atan(2)/π`` on its long edges), but a thin part's short edges stop
    being stable (a 3:1 rectangle: ``mu·d = 0.4 · 30 mm > 10 mm``, all mass on the long edges).

Conventions (checked against the simulator; file and line references as of this module)
    * Yaw: ``feeder.sim.body.World.add_part`` sets the body yaw to ``yaw + alpha`` with the body
      in the principal frame (``part_model`` rotates the pieces by ``−alpha``), so a recorded yaw
      ``y`` (``feeder.sim.drops``: ``degrees(yaw_rad − alpha)``) turns the part file's outline by
      ``y`` about its area centroid: a part-frame direction ``φ`` points along ``φ + y`` in the
      world.
    * World: parts travel along ``+y``, ``+x`` is the right-hand side (``feeder.sim.scene``).
      Location 1 (downstream) is on the right (``side = +1``), Location 2 (upstream) on the left
      (``side = −1``); ``scene.mirror`` swaps them (``feeder.sim.scene.location_side``). A part
      meets Location 2 first (``scene_fences`` lists it first).
    * A straight fence at ``θ`` runs from the wall downstream and inward along
      ``(−side·sin θ, cos θ)`` (``straight_polyline``); its face seen by the part has the normal
      ``(−side·cos θ, −sin θ)``, so a flush edge's outward normal points along
      ``ψ = atan2(sin θ, side·cos θ)``: ``θ`` on the right, ``180° − θ`` on the left
      (``tests/test_sim_physics.py``: a rectangle flush on the right fence at 45° has its long
      axis along 135°). The resting yaw of an edge of part-frame normal ``φ_e`` is ``ψ − φ_e``.
    * A curved fence at ``θ`` is an arc whose local fence angle (between its tangent and the
      travel direction) runs from ``θ + span`` at the slot to ``θ`` at the tip
      (``curved_polyline``: the tangent at polar angle ``φ`` is ``(sin φ, −cos φ)``, i.e. angle
      ``φ + 180°``). Its face is the chain of box chords (``arc_boxes``), so the part leaves it
      along the **last chord**, at ``θ + span / (2 · segments)`` (2.8° more than the exit tangent
      with the default 16 boxes): that is the effective straight fence used for the resting
      yaw (an approximation: a part wider than a chord rests on chord corners).
    * Labels: ``labels.frame: principal`` measures ``yaw + frame_deg``
      (``feeder.labels.dataset.label_yaws``), ``frame_deg`` from
      :func:`feeder.parts.features.frame_deg`; :func:`analytic_pmf` takes ``frame_deg`` (0: the
      part file's frame) and bins like :func:`feeder.labels.metrics.histogram`.

Rolling parts (:func:`rolling_density`)
    With friction, a roundish part may have no stable edge at all (every hull edge shorter than
    its foot's shift ``mu·d``: a 48-gon ellipse, a gear): ``r' − side·mu·r`` then keeps one sign
    all round and the part rolls along the fence for as long as it touches it. Where it leaves is
    taken from the stationary density of that rotation, ``∝ 1 / |r' − side·mu·r|``.

Leaving a fence (:func:`exit_turn`)
    Past the fence tip the part does not stay flush: measured on the design bench's 2,880-yaw
    references (``results/bench/designs``), a 2:1 rectangle flush at 135° on a 45° fence ends at
    100°. The exit is integrated as quasi-static pushing of the actual outline by the fence (belt
    frame: the fence moves at ``−y``), with the ellipsoidal limit surface
    ``(v, ω) ∝ (F, (r × F) / c²)`` and every contact sliding on the friction-cone edge that
    opposes its slip or sticking inside the cone (Lynch, Maekawa & Tanie 1992). Phases:
    *flush* (sliding, no turn) until the foot shifted ``mu·d`` leaves the part of the face still
    under the part; then *C*, the tip corner on an outline edge (the edge turns about the corner
    towards the travel direction until the corner slides off its end or onto the next convex
    edge); *F*, where the hull edge bridges a concavity (a star's two tips, a keyhole's stem and
    head), the last supported vertex pivoting on the face until it passes the tip or another
    vertex lands (flush again; rolling on a polygonal curve); *B*, both at once (a keyhole's stem
    on the face while its head rolls over the corner). After the corner lets go, the part rides
    the belt and meets the corner again if that path hits its outline. Not modelled, and where
    the integration stops with the part as it is: the fence's end face (a star's tip swinging
    back behind the tip), a corner caught in a concave vertex of the outline or on a vertex lying
    on the face (a C shape open towards the fence: −50° in the simulator, ~0° here), and two
    contacts with no consistent sliding/sticking solution (*wedged*).

Configurations (:func:`analytic_distribution`)
    The initial yaw is uniform, sampled at ``YAW_SAMPLES`` evenly spaced yaws, each a drop of
    equal weight with the part centred (x = 0), as in ``feeder.sim.drops``. The fences act in the
    order a part meets them (Location 2, then Location 1): a drop's yaw after the first fence,
    exit turn included, is its input to the second. A fence acts on a drop only if the part
    reaches it laterally (its support towards the fence beyond the fence's innermost point, from
    the drop's lateral position, which the exit from an upstream fence moves): curved fences at
    small angles miss the centre line. A straight fence pushes with the push function at ``θ``. A
    curved fence is taken as the straight fence of its last chord (an approximation: the part
    rides the arc, turning with it, and leaves along that chord); the local angle where a disc of
    the part's support radius first meets the arc (*entry*) only decides whether the part jams
    (using the push function at the entry angle to choose the basin did worse on the simulated
    two-fence configurations). A part whose disc would meet the circle beyond the tip only
    grazes the tip corner and is left unchanged (an approximation: on ``curved:80`` the
    simulator turns such parts).
    A fence turns a part only as far as it pushes it: pushed sideways by the overlap ``o``
    between the part and the fence's innermost point, a part turns by at most ``o / (2c)``
    radians (a unit push at moment arm ``a`` turns it by ``a / (c² + a²) ≤ 1 / (2c)`` on the
    limit surface), so a part that would need more (a shallow curved fence reaching only its
    edge: ``curved:0``) turns that far towards its stable edge and leaves unaligned.

Jams
    A part slides along a fence face only outside the friction cone: the belt velocity makes the
    angle ``β = 90° − α`` with the face normal (``α`` the local fence angle), and quasi-static
    equilibrium of belt drag, normal force and Coulomb friction along the face gives a sliding
    speed ``v (sin β − mu cos β)``, positive iff ``tan β > mu``, i.e. ``α < 90° − atan(mu)``
    (68.2° with the scene's part–fence ``mu = 0.8 × 0.5 = 0.4``, Bullet multiplying the two
    coefficients; the belt's own friction cancels out). The signed margin
    ``90° − atan(mu) − α`` is a feature per fence (straight: ``α = θ``; curved: the mean entry
    angle of the drops that touch it), and a drop whose entry angle lies in the cone is counted
    as jammed (removed from the PMF, which is over ok drops as the labels are). Against
    ``results/tables/jam_rates.csv`` (``feeder bench-jams``, one fence alone, 8 parts x 42 fence
    rows): jammed share > 0.5 predicted right in 90 % of rows; curved 60/70 jam (predicted), 80/90
    do not (grazed); missed: straight 65° (margin +3.2°, yet 55 % jam: a slide slower than
    ``status.jam_travel / jam_window_s`` = 5 mm/s counts as jammed, and ``v (sin β − mu cos β)``
    is 6 mm/s there) and the 10–25 % of drops that jam on curved 30–50 (predicted 0 below 50°).

Features (:func:`push_features`, :data:`PUSH_FEATURE_NAMES`)
    ``2·FOURIER_K`` values ``Re c_k, Im c_k`` (k = 1..K) of the smoothed analytic PMF in the label
    frame, ``c_k = Σ_b p_b e^{−i k θ_b}`` at bin centres ``θ_b``; then per location (loc1, loc2):
    present, touch (share of the drops reaching it that touch it), jam (share of them jammed),
    friction margin (degrees; ``90° − atan(mu)`` for an absent fence, i.e. a fence along the
    travel direction); then ok mass, peak mass (largest share of ok drops at one resting yaw),
    entropy (bits) of the unsmoothed analytic PMF, the number of stable edges and the largest basin
    measure of the frictionless push function. When every drop jams, the PMF, peak mass and
    entropy describe the same configuration with jams ignored (ok mass is then 0).
    :func:`push_block` gives the block and the analytic PMF from one pass of the drops (the
    dataset's ``push_raw`` and ``pmf_analytic``, :mod:`feeder.labels.dataset`); a hand-bumped
    :data:`PUSH_FEATURES_VERSION` marks changed values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from feeder.errors import FeederError
from feeder.lane.fences import Fence, parse_location
from feeder.parts.geometry import _check_holes, clean_holes, clean_outline, profile_moments

FULL_TURN_DEG = 360.0
HALF_TURN_DEG = 180.0
RIGHT_ANGLE_DEG = 90.0
PMF_BINS = 360  # labels.bins: 1° bins over [0, 360), as feeder.labels.metrics.histogram
DEFAULT_SMOOTH_DEG = 2.0  # circular Gaussian sigma of the analytic PMF (degrees)
FOURIER_K = 8  # leading complex Fourier coefficients of the PMF kept as features (k = 1..K)
YAW_SAMPLES = 7200  # evenly spaced initial yaws (0.05° apart): a basin's mass is off by < 1/7200
# Relative tolerance (of the hull's circumradius) for "strictly inside an edge" and collinearity.
REL_TOL = 1e-9
# Exit turn integration: steps per circumradius of fence travel (midpoint rule; 200 steps move
# the exit yaws of the library parts by < 0.2° from 1,600) and the most travel integrated
# (circumradii) before giving up.
EXIT_STEPS_PER_RADIUS = 200
EXIT_MAX_TRAVEL_RADII = 20.0
EXIT_MAX_PHASES = 64  # flush / pivot / corner phases followed before giving up
EXIT_SAME_RAD = 1e-9  # two flush states this close in yaw (radians) are the same state
# Distance (of the circumradius) within which an outline vertex counts as on the fence face.
EXIT_CONTACT_TOL = 1e-6
# How far (of the circumradius) a vertex is moved past the tip when it leaves the face.
EXIT_PASS_MARGIN = 1e-4
# A vertex on the face this close (of the circumradius) to the corner's contact is caught on it.
EXIT_HOOK_TOL = 1e-2
# Pusher (fence corner) velocity relative to the belt: the belt carries the part along +y.
_PUSHER_VELOCITY = (0.0, -1.0)
# Contact normals at which a rolling part (no stable edge) may leave a fence: 0.5° apart.
ROLL_SAMPLES = 720
# Yaws are snapped to this grid (degrees) before binning: round-off of 30° − 0° (29.999...) must
# not move a resting yaw into the bin below.
YAW_SNAP_DEG = 1e-9
# Two drops closer than this (degrees) count as one resting yaw for ``peak_mass`` (pushed drops
# of one basin share their yaw exactly).
MODE_MERGE_DEG = 1e-6


# ----------------------------------------------------------------------------------------------
# Geometry
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PushGeometry:
    """The convex hull of an outline about the outline's area centroid (part file frame, metres).

    ``hull``: (H, 2) CCW vertices relative to ``centroid``; edge ``i`` runs from vertex ``i`` to
    ``i + 1``. ``normals_deg``: outward normal angle of each edge in [0, 360); ``lengths``: edge
    lengths; ``heights``: distance of each edge's line from the centroid (``r`` at its normal);
    ``feet``: position of the centroid's foot along each edge from its first vertex;
    ``limit_radius``: ``∫|x − centroid| dA / A`` of the outline; ``circumradius``: the largest
    vertex distance from the centroid; ``outline``: the cleaned CCW outline relative to the
    centroid, ``convex``: whether each of its vertices is convex (a left turn)."""

    centroid: np.ndarray
    area: float
    hull: np.ndarray
    normals_deg: np.ndarray
    lengths: np.ndarray
    heights: np.ndarray
    feet: np.ndarray
    limit_radius: float
    circumradius: float
    outline: np.ndarray
    convex: np.ndarray


def convex_hull(points: np.ndarray, tol: float) -> np.ndarray:
    """CCW convex hull (Andrew's monotone chain) without collinear vertices; FeederError when the
    points span no area."""
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)  # sorted by x, then y

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def chain(seq) -> list:
        out: list = []
        for p in seq:
            while len(out) >= 2 and cross(out[-2], out[-1], p) <= tol * float(np.hypot(*(p - out[-2]))):
                out.pop()
            out.append(p)
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    hull = np.array(lower[:-1] + upper[:-1])
    if len(hull) < 3:
        raise FeederError("outline's convex hull is degenerate (collinear points, zero area)")
    return hull


def _mean_distance_integral(poly: np.ndarray) -> float:
    """``∫|x| dA`` over a polygon given relative to the reference point (any simple polygon: the
    signed triangles (0, a, b) of its edges add up to it). Per triangle in polar coordinates,
    ``∫ ρ(θ)³ / 3 dθ`` with ``ρ = h / cos x``: ``h³/3 · [½(sec x tan x + ln(sec x + tan x))]``;
    an edge whose line passes through the reference point adds nothing."""
    a, b = poly, np.roll(poly, -1, axis=0)
    edge = b - a
    length = np.hypot(edge[:, 0], edge[:, 1])
    e = edge / length[:, None]
    h = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / length  # signed distance of the edge's line
    ta, tb = np.sum(a * e, axis=1), np.sum(b * e, axis=1)  # positions along the line from the foot
    habs = np.abs(h)
    ok = habs > REL_TOL * np.maximum(np.abs(ta), np.abs(tb))  # an edge through the point adds nothing
    total = 0.0
    for hi, ha, t0, t1 in zip(h[ok], habs[ok], ta[ok], tb[ok]):

        def prim(t: float, ha: float = ha) -> float:
            tan = t / ha
            sec = math.sqrt(1.0 + tan * tan)
            return 0.5 * (sec * tan + math.asinh(tan))  # asinh(x) = ln(sec + tan), stable for x < 0

        total += math.copysign(ha**3 / 3.0, hi) * (prim(t1) - prim(t0))
    return float(total)


def push_geometry(outline, holes=()) -> PushGeometry:
    """Hull, centroid and limit-surface radius of an outline ((N, 2), any orientation, metres),
    less its through-holes ``holes`` (polygons inside it): the centroid and the limit surface are
    the region's; the hull, and so every fence contact, is the outline's.

    A degenerate outline (fewer than three non-collinear points, zero area, non-finite values) is
    a one-line :class:`FeederError`."""
    pts = clean_outline(outline)  # FeederError on collinear / repeated / non-finite points
    cut = clean_holes(holes)
    if cut:
        _check_holes(pts, cut, "part")
    area, centroid, _ = profile_moments(pts, cut)
    rel = pts - centroid
    size = float(np.max(np.hypot(rel[:, 0], rel[:, 1])))
    hull = convex_hull(rel, REL_TOL * size)
    nxt = np.roll(hull, -1, axis=0)
    edge = nxt - hull
    lengths = np.hypot(edge[:, 0], edge[:, 1])
    e = edge / lengths[:, None]
    normals = np.column_stack([e[:, 1], -e[:, 0]])  # outward for a CCW hull
    heights = np.sum(hull * normals, axis=1)
    if np.any(heights <= REL_TOL * size):
        raise FeederError("outline's area centroid lies on its convex hull (degenerate outline)")
    feet = -np.sum(hull * e, axis=1)
    normals_deg = np.mod(np.degrees(np.arctan2(normals[:, 1], normals[:, 0])), FULL_TURN_DEG)
    # ∫|x| dA over the region: the outline's less each hole's (all CCW, about the same centroid)
    limit_radius = (_mean_distance_integral(rel) - sum(_mean_distance_integral(h - centroid) for h in cut)) / area
    d1, d2 = rel - np.roll(rel, 1, axis=0), np.roll(rel, -1, axis=0) - rel
    convex = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] >= 0.0
    for arr in (centroid, hull, normals_deg, lengths, heights, feet, rel, convex):
        arr.setflags(write=False)
    return PushGeometry(centroid, area, hull, normals_deg, lengths, heights, feet, limit_radius, size, rel, convex)


def as_geometry(part) -> PushGeometry:
    """A :class:`PushGeometry` from itself, a PartGeometry (its ``outline`` less its ``holes``) or
    an outline array."""
    if isinstance(part, PushGeometry):
        return part
    if hasattr(part, "outline"):
        return push_geometry(part.outline, getattr(part, "holes", ()))
    return push_geometry(part)


def radius_function(part, phi_deg) -> np.ndarray:
    """Support distance ``r(φ)`` from the area centroid to the hull's supporting line of outward
    normal ``φ`` (degrees, part frame); broadcasts over ``phi_deg``."""
    geom = as_geometry(part)
    phi = np.radians(np.asarray(phi_deg, dtype=np.float64))
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    return np.max(u @ geom.hull.T, axis=-1)


# ----------------------------------------------------------------------------------------------
# Push function
# ----------------------------------------------------------------------------------------------
def _wrap(angle_deg):
    return np.mod(angle_deg, FULL_TURN_DEG)


@dataclass(frozen=True, eq=False)
class PushFunction:
    """Stable edges of a hull against a fence and their basins in the contact normal ``φ``.

    ``edges``: hull edge indices (increasing normal angle); ``normals_deg``: their outward normals
    (part frame); ``lower_deg``/``upper_deg``: each basin is ``[lower, upper)`` going CCW (upper
    may exceed 360); ``measures``: basin widths / 360, summing to 1. Calling it maps contact
    normals ``φ`` (degrees, any real) to the stable normal their part comes to rest on.

    With friction a roundish part can have no stable edge at all (every edge shorter than the
    foot's shift): it then rolls along the fence for as long as it touches it (``rolls``), and
    :func:`rolling_density` gives where it leaves."""

    edges: np.ndarray
    normals_deg: np.ndarray
    lower_deg: np.ndarray
    upper_deg: np.ndarray
    measures: np.ndarray

    @property
    def rolls(self) -> bool:
        return len(self.edges) == 0

    def basin_index(self, phi_deg) -> np.ndarray:
        """Index (into ``edges``) of the basin holding each ``φ``."""
        if self.rolls:
            raise FeederError("a rolling part has no basins (push_function(...).rolls)")
        phi = np.asarray(phi_deg, dtype=np.float64)
        start = float(self.lower_deg[0])
        rel = _wrap(phi - start)
        bounds = self.upper_deg - start  # increasing, last = 360
        return np.minimum(np.searchsorted(bounds, rel, side="right"), len(self.edges) - 1)

    def __call__(self, phi_deg) -> np.ndarray:
        return self.normals_deg[self.basin_index(phi_deg)]


def push_function(part, mu: float = 0.0, side: int = 1) -> PushFunction:
    """The push function of a part's hull against a straight fence (see the module doc).

    ``mu``: part–fence friction coefficient (0: Goldberg's frictionless function); ``side``: +1
    for a fence on the right of the travel direction, −1 on the left (matters only when ``mu >
    0``: the friction shifts the foot downstream)."""
    geom = as_geometry(part)
    if not (math.isfinite(mu) and mu >= 0.0):
        raise FeederError(f"fence friction must be finite and >= 0, got {mu!r}")
    if side not in (1, -1):
        raise FeederError(f"fence side must be +1 (right) or -1 (left), got {side!r}")
    n = len(geom.hull)
    tol = REL_TOL * geom.circumradius
    shifted = geom.feet + side * mu * geom.heights  # the foot shifted by mu·d downstream
    flow_up_into = shifted > tol  # r' - side·mu·r < 0 just below the normal: φ increases to it
    flow_down_into = shifted < geom.lengths - tol  # > 0 just above: φ decreases to it
    stable = flow_up_into & flow_down_into
    if not stable.any():  # the part rolls: r' - side·mu·r keeps one sign all round
        empty = np.empty(0)
        return PushFunction(np.empty(0, dtype=np.int64), empty, empty, empty, empty)
    lam = math.degrees(math.atan(mu))
    vert_deg = np.degrees(np.arctan2(geom.hull[:, 1], geom.hull[:, 0]))
    # unstable points: inside vertex j's normal cone [normal(j-1), normal(j)] where the flow turns
    # from decreasing φ (after edge j-1) to increasing φ (before edge j), at the vertex direction
    # turned by -side·λ; or at an edge normal where neither side flows into it
    events: list[tuple[float, int]] = []  # (angle, +1 stable edge index / -1 unstable)
    for i in range(n):
        a = float(geom.normals_deg[i])
        if stable[i]:
            events.append((a, i))
        elif not flow_up_into[i] and not flow_down_into[i]:
            events.append((a, -1))
        j = (i + 1) % n  # the vertex after edge i: its cone runs from normal(i) to normal(j)
        if flow_down_into[i] and flow_up_into[j]:
            width = float(_wrap(geom.normals_deg[j] - a))
            offset = float(_wrap(vert_deg[j] - side * lam - a + HALF_TURN_DEG)) - HALF_TURN_DEG
            events.append((a + min(max(offset, 0.0), width), -1))
    events.sort(key=lambda ev: _wrap(ev[0]))
    stables = [(ang, k) for ang, k in events if k >= 0]
    unstables = np.array([ang for ang, k in events if k < 0], dtype=np.float64)
    m = len(stables)
    edges = np.array([k for _, k in stables], dtype=np.int64)
    normals = np.array([float(_wrap(ang)) for ang, _ in stables])
    # boundary between consecutive stable normals: the (first) unstable point between them
    bounds = np.empty(m)
    for s in range(m):
        lo = normals[s]
        gap = float(_wrap(normals[(s + 1) % m] - lo)) if m > 1 else FULL_TURN_DEG
        rel = _wrap(unstables - lo) if unstables.size else np.empty(0)
        inside = rel[(rel > 0.0) & (rel < gap)] if m > 1 else rel
        bounds[s] = lo + (float(np.min(inside)) if inside.size else 0.5 * gap)
    upper = bounds.copy()  # basin s is [lower[s], upper[s]) and holds normals[s]
    lower = np.roll(bounds, 1)
    lower[0] -= FULL_TURN_DEG  # the last boundary, one turn back
    measures = (upper - lower) / FULL_TURN_DEG
    return PushFunction(edges, normals, lower, upper, measures / measures.sum())


def rolling_density(part, mu: float, side: int, phi_deg) -> np.ndarray:
    """Weights (summing to 1) of contact normals ``φ`` at which a rolling part (no stable edge)
    leaves a long fence: the flow ``dφ/dτ ∝ −g(φ)``, ``g = r'(φ) − side·mu·r(φ)``, spends time
    ``∝ 1/|g|`` at each ``φ``, its stationary density."""
    geom = as_geometry(part)
    phi = np.radians(np.asarray(phi_deg, dtype=np.float64))
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    support = geom.hull[np.argmax(u @ geom.hull.T, axis=-1)]
    r = np.sum(support * u, axis=-1)
    dr = support[..., 1] * u[..., 0] - support[..., 0] * u[..., 1]  # support · (−sin φ, cos φ)
    g = np.abs(dr - side * mu * r)
    w = 1.0 / np.maximum(g, REL_TOL * geom.circumradius)
    return w / w.sum()


# ----------------------------------------------------------------------------------------------
# Fence orientation conventions
# ----------------------------------------------------------------------------------------------
def fence_normal_deg(fence_angle_deg, side: int) -> np.ndarray:
    """World direction (degrees) of the outward normal of a part edge lying flush on a fence face
    whose local angle to the travel direction is ``fence_angle_deg`` on ``side`` (+1 right)."""
    a = np.radians(np.asarray(fence_angle_deg, dtype=np.float64))
    return _wrap(np.degrees(np.arctan2(np.sin(a), side * np.cos(a))))


def resting_yaw(edge_normal_deg, fence_angle_deg, side: int) -> np.ndarray:
    """Part-frame yaw (degrees, [0, 360)) at which the edge of part-frame outward normal
    ``edge_normal_deg`` lies flush on the fence: its normal then points at the fence."""
    return _wrap(fence_normal_deg(fence_angle_deg, side) - np.asarray(edge_normal_deg, dtype=np.float64))


def friction_margin_deg(fence_angle_deg, mu: float) -> np.ndarray:
    """``90° − atan(mu) − α``: positive where a part slides along a face at local angle ``α``,
    negative inside the friction cone (the part sticks: a jam)."""
    return RIGHT_ANGLE_DEG - math.degrees(math.atan(mu)) - np.asarray(fence_angle_deg, dtype=np.float64)


# ----------------------------------------------------------------------------------------------
# Leaving a fence: quasi-static pushing by the fence face and its tip corner
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ExitTurn:
    """How a part leaves a fence tip: its yaw change (degrees), the centroid's position relative
    to the tip corner when it is let go (world, metres), why the integration stopped
    (``released``: nothing pushes any more; ``stuck``: flush again where it was before;
    ``wedged``: two contacts that neither slide nor stick consistently;
    ``notch``: the corner reached a concave vertex of the
    outline, where it would hook; ``end face``: a vertex past the tip swung back against the
    fence's end face, left out of the model; ``travel``: the travel limit) and the contact phases it went
    through (``F``: an outline vertex pivoting on the face, ``C``: the corner on an outline edge,
    ``B``: both at once)."""

    delta_deg: float
    offset: tuple[float, float]
    reason: str
    phases: str = ""


def _contact_twist(rx, ry, nx, ny, ex, ey, mu, c2):
    """Twist ``(vx, vy, ω)`` of a part pushed at ``r`` (from its centroid, world) through a
    contact of inward normal ``n`` and tangent ``e`` by a pusher moving at ``_PUSHER_VELOCITY``
    (belt frame), quasi-static with the ellipsoidal limit surface ``(v, ω) ∝ (F, r × F / c2)``;
    the contact sticks when the pusher's velocity lies in the motion cone, else it slides on the
    friction-cone edge that opposes the slip. None when the pusher does not push."""
    vpx, vpy = _PUSHER_VELOCITY
    vpn = vpx * nx + vpy * ny
    if vpn <= 0.0:
        return None
    cand = []
    for sgn in (1.0, -1.0):
        fx, fy = nx + sgn * mu * ex, ny + sgn * mu * ey
        w = (rx * fy - ry * fx) / c2
        cand.append((sgn, fx, fy, w, fx - w * ry, fy + w * rx))
    (_, f1x, f1y, w1, c1x, c1y), (_, f2x, f2y, w2, d2x, d2y) = cand
    det = c1x * d2y - c1y * d2x
    if det != 0.0:
        k1 = (vpx * d2y - vpy * d2x) / det
        k2 = (c1x * vpy - c1y * vpx) / det
        if k1 >= 0.0 and k2 >= 0.0:  # the pusher's velocity lies in the motion cone: sticking
            return k1 * f1x + k2 * f2x, k1 * f1y + k2 * f2y, k1 * w1 + k2 * w2
    for sgn, fx, fy, w0, cx, cy in cand:
        cn = cx * nx + cy * ny
        if cn <= 0.0:
            continue
        k = vpn / cn
        if sgn * ((k * cx - vpx) * ex + (k * cy - vpy) * ey) <= 0.0:  # friction opposes the slip
            return k * fx, k * fy, k * w0
    return None  # pragma: no cover - one cone edge is always consistent


def _two_contact_twist(r1, n1, e1, r2, n2, e2, mu, c2):
    """Twist ``(vx, vy, ω)`` of a part pushed through two contacts of the same pusher (points
    ``r_i`` from the centroid, inward normals ``n_i``, tangents ``e_i``, world arrays), quasi-static
    with the ellipsoidal limit surface. Each contact either slides, its force on the friction-cone
    edge that opposes the slip, or sticks (moves with the pusher, its force inside the cone); the
    first consistent combination (sliding first) is returned, None when there is none."""
    vp = np.array(_PUSHER_VELOCITY)
    scale = np.array([1.0, 1.0, 1.0 / c2])
    contacts = ((r1, n1, e1), (r2, n2, e2))

    def col(r, f):  # the wrench of force f at r
        return np.array([f[0], f[1], r[0] * f[1] - r[1] * f[0]])

    modes = [(a, b) for a in (1.0, -1.0, 0.0) for b in (1.0, -1.0, 0.0)]  # ±: slides on that edge; 0: sticks
    for mode in sorted(modes, key=lambda m: (m[0] == 0.0) + (m[1] == 0.0)):
        cols, rows, rhs = [], [], []
        for (r, n, e), sg in zip(contacts, mode):
            if sg == 0.0:
                cols += [col(r, (1.0, 0.0)), col(r, (0.0, 1.0))]
                rows += [np.array([1.0, 0.0, -r[1]]), np.array([0.0, 1.0, r[0]])]
                rhs += [vp[0], vp[1]]
            else:
                cols.append(col(r, n + sg * mu * e))
                rows.append(col(r, n))
                rhs.append(float(n @ vp))
        bmat = np.array(cols).T * scale[:, None]  # (3, m): twists of the unknowns
        m = np.array(rows) @ bmat
        if m.shape[0] != m.shape[1] or abs(np.linalg.det(m)) < 1e-300:
            continue
        u = np.linalg.solve(m, np.array(rhs))
        tw = bmat @ u
        ok, i = True, 0
        for (r, n, e), sg in zip(contacts, mode):
            if sg == 0.0:
                f = u[i : i + 2]
                i += 2
                fn, ft = float(f @ n), float(f @ e)
                ok &= fn >= 0.0 and abs(ft) <= mu * fn + 1e-12
            else:
                slip = (np.array([tw[0] - tw[2] * r[1], tw[1] + tw[2] * r[0]]) - vp) @ e
                ok &= bool(u[i] >= 0.0) and sg * slip <= 1e-12
                i += 1
        if ok:
            return float(tw[0]), float(tw[1]), float(tw[2])
    return None


def _inside(poly: np.ndarray, p: np.ndarray) -> bool:
    """Whether point ``p`` lies inside the simple polygon ``poly`` (crossing number)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (a[:, 1] > p[1]) != (b[:, 1] > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[:, 0] + (p[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(cross & (p[0] < x)) % 2)


class _Exit:
    """The exit state machine of :func:`exit_turn` in the fence frame: tip corner at the origin,
    ``t`` the fence direction downstream, ``nf`` the face normal into the part's side; the fence
    face is the line ``p · nf = 0`` for ``p · t < 0``. The part's pose is its centroid ``X`` and
    yaw; the pusher moves at ``_PUSHER_VELOCITY`` relative to the belt."""

    def __init__(self, geom: PushGeometry, alpha_deg: float, side: int, mu: float, yaw_rad: float):
        a = math.radians(alpha_deg)
        self.t = np.array([-side * math.sin(a), math.cos(a)])
        self.nf = np.array([-side * math.cos(a), -math.sin(a)])
        self.geom, self.mu, self.yaw = geom, mu, yaw_rad
        self.c2 = geom.limit_radius**2
        self.poly = geom.outline
        self.n = len(self.poly)
        self.step = geom.circumradius / EXIT_STEPS_PER_RADIUS
        self.tol = EXIT_CONTACT_TOL * geom.circumradius
        self.steps_left = int(EXIT_MAX_TRAVEL_RADII * EXIT_STEPS_PER_RADIUS)
        self.hand = float(self.t[0] * self.nf[1] - self.t[1] * self.nf[0])  # (t, nf) handedness
        self.X = np.zeros(2)
        self.phases = ""
        # vertices that have passed the tip: they never land on the face again (where they would
        # meet the fence's end face instead, which the model leaves out)
        self.passed = np.zeros(self.n, dtype=bool)

    def rot(self, yaw=None) -> np.ndarray:
        y = self.yaw if yaw is None else yaw
        c, s = math.cos(y), math.sin(y)
        return np.array([[c, -s], [s, c]])

    def world(self, X=None, yaw=None) -> np.ndarray:
        return (self.X if X is None else X) + self.poly @ self.rot(yaw).T

    def landed(self, pts: np.ndarray, *skip: int) -> np.ndarray:
        """Vertices (not yet past the tip) that have crossed the face upstream of the tip."""
        q = pts @ self.t
        self.passed |= q > self.tol
        hit = (pts @ self.nf < -self.tol) & (q < -self.tol) & ~self.passed
        hit[list(skip)] = False
        return hit

    def caught(self, pts: np.ndarray) -> bool:
        """Whether a vertex past the tip has come back behind it below the face line: it would
        meet the fence's end face, which the model leaves out (the part is let go there)."""
        return bool(np.any(self.passed & (pts @ self.t < -self.tol) & (pts @ self.nf < -self.tol)))

    # -- phases -------------------------------------------------------------------------------
    def flush(self):
        """Slide flush on the face until the shifted foot leaves the supported part of the face;
        returns the next phase ``("C", edge, s)`` or ``("F", vertex)``."""
        pts = self.world()
        on = np.flatnonzero(np.abs(pts @ self.nf) <= self.tol)
        on = on[np.argsort(pts[on] @ self.t)]
        q_all = pts @ self.t
        self.passed |= q_all > self.tol
        sup = [int(k) for k in on if not self.passed[k]]  # on the face, upstream of the tip
        if not sup:
            return ("free", "released")
        q = [float(q_all[k]) for k in sup]
        last = sup[-1]
        crossing = [int(k) for k in on if self.passed[k] and self.adjacent(last, int(k))]
        qf = float(self.X @ self.t) + self.mu * float(self.X @ self.nf)  # foot shifted mu·d downstream
        if qf <= q[0] and len(sup) > 1:
            return ("F", sup[0])
        if crossing and qf >= q[-1]:  # the edge through the tip carries the foot: the corner takes over
            self.X = self.X + max(0.0, -qf) * self.t
            return self.on_edge(last, crossing[0])
        if qf >= q[-1]:
            return ("F", last)
        i = int(np.searchsorted(q, qf)) - 1
        if self.adjacent(sup[i], sup[i + 1]):  # a face segment: slide until the tip reaches the foot
            self.X = self.X + max(0.0, -qf) * self.t
            return self.on_edge(sup[i], sup[i + 1])
        # a gap: pivot once the vertex past it has left the face (by a margin past the tip)
        self.X = self.X + (max(0.0, -q[i + 1]) + EXIT_PASS_MARGIN * self.geom.circumradius) * self.t
        return ("F", sup[i])

    def adjacent(self, a: int, b: int) -> bool:
        return (a + 1) % self.n == b or (b + 1) % self.n == a

    def on_edge(self, a: int, b: int):
        """``("C", k, s)``: the corner (origin) on the outline edge joining vertices a and b."""
        k = a if (a + 1) % self.n == b else b
        e = self.poly[(k + 1) % self.n] - self.poly[k]
        rel = -(self.X + self.rot() @ self.poly[k])  # the corner relative to vertex k, world
        return ("C", k, float(rel @ (self.rot() @ e)) / float(np.hypot(*e)))

    def pivot(self, v: int):
        """Vertex ``v`` on the face pivots until it passes the tip (free) or another vertex lands
        on the face (flush again)."""
        self.phases += "F"
        nf, t, P = self.nf, self.t, self.poly
        for _ in range(self.steps_left):
            self.steps_left -= 1

            def deriv(X, yaw, v=v):
                r = self.rot(yaw) @ P[v]
                tw = _contact_twist(r[0], r[1], nf[0], nf[1], t[0], t[1], self.mu, self.c2)
                return None if tw is None else (np.array([tw[0], tw[1]]) - _PUSHER_VELOCITY, tw[2])

            k1 = deriv(self.X, self.yaw)
            if k1 is None:
                return ("free", "released")
            k2 = deriv(self.X + 0.5 * self.step * k1[0], self.yaw + 0.5 * self.step * k1[1])
            if k2 is None:
                return ("free", "released")
            self.yaw += self.step * k2[1]
            self.X = self.X + self.step * k2[0]
            pv = self.X + self.rot() @ P[v]
            self.X = self.X - float(pv @ nf) * nf  # keep the vertex on the face
            pv = self.X + self.rot() @ P[v]
            if float(pv @ t) >= 0.0:  # past the tip: the corner meets the edge upstream of v
                if self.hand > 0:  # CCW order runs downstream along the face
                    k = (v - 1) % self.n
                    return ("C", k, float(np.hypot(*(P[v] - P[k]))))
                return ("C", v, 0.0)
            corner = self.rot().T @ -self.X  # the tip corner in the part frame
            if _inside(P, corner):  # the corner now holds an outline edge too
                k, sk, gap = self.nearest_edge(corner)
                if gap > self.tol:
                    return ("B", v, k, sk)
            pts = self.world()
            depth = pts @ nf
            hit = self.landed(pts, v)
            if self.caught(pts):
                return ("free", "end face")
            if hit.any():  # turn back about v until the deepest vertex lies on the face
                k = int(np.argmin(np.where(hit, depth, np.inf)))
                w = pts[k] - pv
                ang = math.atan2(float(w @ nf), float(w @ t))  # in the (t, nf) basis
                delta = -ang if float(w @ t) > 0.0 else (math.pi - ang + math.pi) % (2 * math.pi) - math.pi
                self.yaw += self.hand * delta
                self.X = pv - self.rot() @ P[v]
                qk = float((self.X + self.rot() @ P[k]) @ t)
                qf = float(self.X @ t) + self.mu * float(self.X @ nf)
                if self.adjacent(v, k) and qk > float(pv @ t) and qf > qk:
                    v = k  # rolling on a polygonal curve: the foot is past the new vertex too
                    continue
                return ("flush",)
        return ("free", "travel")

    def corner(self, k: int, s: float):
        """The corner pushes outline edge ``k`` at ``s`` (metres from vertex ``k``) until it
        leaves the outline, stops pushing or meets a concave vertex."""
        self.phases += "C"
        P, n = self.poly, self.n
        switches = 0
        while True:
            a = P[k]
            e = P[(k + 1) % n] - a
            length = float(np.hypot(*e))
            e = e / length

            def deriv(yaw, s, a=a, e=e):
                R = self.rot(yaw)
                ew = R @ e
                r = R @ (a + s * e)
                tw = _contact_twist(r[0], r[1], -ew[1], ew[0], ew[0], ew[1], self.mu, self.c2)
                if tw is None:
                    return None
                vx, vy, w = tw
                rel = np.array(_PUSHER_VELOCITY) - np.array([vx - w * r[1], vy + w * r[0]])
                return w, float(rel @ ew)

            while self.steps_left > 0:
                self.steps_left -= 1
                k1 = deriv(self.yaw, s)
                if k1 is None:
                    return self.release(k, s, "released")
                k2 = deriv(self.yaw + 0.5 * self.step * k1[0], s + 0.5 * self.step * k1[1])
                if k2 is None:
                    return self.release(k, s, "released")
                self.yaw += self.step * k2[0]
                s += self.step * k2[1]
                if not 0.0 <= s <= length:
                    break
                self.X = -(self.rot() @ (a + s * e))
                pts = self.world()
                hit = self.landed(pts)
                if hit.any():  # an upstream vertex meets the face: both contacts hold
                    return ("B", int(np.argmin(np.where(hit, pts @ self.nf, np.inf))), k, s)
            else:
                return self.release(k, s, "travel")
            switches += 1
            j = (k + 1) % n if s > length else k  # the vertex reached
            if not self.geom.convex[j] or switches > 2 * n:
                return self.release(k, min(max(s, 0.0), length), "notch")
            k, s = (j, 0.0) if s > length else ((k - 1) % n, float(np.hypot(*(P[k] - P[(k - 1) % n]))))

    def nearest_edge(self, p: np.ndarray) -> tuple[int, float, float]:
        """The outline edge nearest to part-frame point ``p``, the position of its foot along it
        and its distance."""
        a, b = self.poly, np.roll(self.poly, -1, axis=0)
        e = b - a
        length = np.hypot(e[:, 0], e[:, 1])
        s = np.clip(np.sum((p - a) * e, axis=1) / length, 0.0, length)
        foot = a + (s / length)[:, None] * e
        dist = np.hypot(*(foot - p).T)
        k = int(np.argmin(dist))
        return k, float(s[k]), float(dist[k])

    def both(self, v: int, k: int, s: float):
        """Vertex ``v`` slides on the face while the corner holds outline edge ``k`` (at ``s``),
        until one of them lets go."""
        self.phases += "B"
        P, n, nf, t, vp = self.poly, self.n, self.nf, self.t, np.array(_PUSHER_VELOCITY)
        edge = P[(k + 1) % n] - P[k]
        if (
            float(np.hypot(*(P[k] + s * edge / float(np.hypot(*edge)) - P[v])))
            <= EXIT_HOOK_TOL * self.geom.circumradius
        ):
            return self.hooked()
        switches = 0

        def twist(yaw, s, a, e):
            R = self.rot(yaw)
            ew = R @ e
            en = np.array([-ew[1], ew[0]])
            rv, rc = R @ P[v], R @ (a + s * e)
            return _two_contact_twist(rv, nf, t, rc, en, ew, self.mu, self.c2), rv, rc, en, ew

        def onto(X, yaw, a, e):
            """X moved back onto both constraints (v on the face, the corner on edge k's line)
            and the corner's position along the edge."""
            R = self.rot(yaw)
            ew = R @ e
            en = np.array([-ew[1], ew[0]])
            dv = float((X + R @ P[v]) @ nf)
            dc = float(-(X + R @ a) @ en)
            X = X + np.linalg.solve(np.array([nf, en]), np.array([-dv, dc]))
            return X, float(-(X + R @ a) @ ew)

        while self.steps_left > 0:
            self.steps_left -= 1
            a = P[k]
            e = P[(k + 1) % n] - a
            length = float(np.hypot(*e))
            e = e / length
            tw, rv, rc, en, ew = twist(self.yaw, s, a, e)
            if tw is None:  # one lets go: the one whose motion alone leaves the other free
                tc = _contact_twist(rc[0], rc[1], en[0], en[1], ew[0], ew[1], self.mu, self.c2)
                if tc is not None:
                    vel = np.array([tc[0] - tc[2] * rv[1], tc[1] + tc[2] * rv[0]])
                    if float((vel - vp) @ nf) >= 0.0:
                        return ("C", k, s)
                tf = _contact_twist(rv[0], rv[1], nf[0], nf[1], t[0], t[1], self.mu, self.c2)
                if tf is not None:
                    vel = np.array([tf[0] - tf[2] * rc[1], tf[1] + tf[2] * rc[0]])
                    if float((vel - vp) @ en) >= 0.0:
                        return ("F", v)
                return ("free", "wedged")
            if math.hypot(tw[0] - vp[0], tw[1] - vp[1]) + abs(tw[2]) * self.geom.circumradius <= EXIT_CONTACT_TOL:
                return ("free", "wedged")  # the part moves with the fence: held at the tip
            half = 0.5 * self.step
            xh, sh = onto(self.X + half * (np.array(tw[:2]) - vp), self.yaw + half * tw[2], a, e)
            tw2 = twist(self.yaw + half * tw[2], sh, a, e)[0] or tw  # midpoint rule
            self.yaw += self.step * tw2[2]
            self.X, s = onto(self.X + self.step * (np.array(tw2[:2]) - vp), self.yaw, a, e)
            R = self.rot()
            if float((self.X + R @ P[v]) @ t) >= 0.0:  # v passed the tip: the corner alone
                return ("C", k, min(max(s, 0.0), length))
            if not 0.0 <= s <= length:
                switches += 1
                j = (k + 1) % n if s > length else k
                if not self.geom.convex[j] or switches > 2 * n:
                    return self.release(k, min(max(s, 0.0), length), "notch")
                k, s = (j, 0.0) if s > length else ((k - 1) % n, float(np.hypot(*(P[k] - P[(k - 1) % n]))))
                continue
            pts = self.world()
            hit = self.landed(pts, v)
            if self.caught(pts):
                return ("free", "end face")
            if hit.any():
                w = int(np.argmin(np.where(hit, pts @ nf, np.inf)))
                if not self.adjacent(v, w):
                    return ("flush",)
                # rolling on a polygonal curve: turn about the corner until w lies on the face
                ang = math.atan2(float(pts[w] @ nf), float(pts[w] @ t))
                self.yaw += self.hand * ((math.pi - ang + math.pi) % (2 * math.pi) - math.pi)
                self.X = -(self.rot() @ (a + s * e))
                v = w
        return ("free", "travel")

    def hooked(self):
        """A vertex caught on the tip corner (both contacts at one point): the part would swing
        about the corner, which the model does not follow; it is let go as it is (a known miss:
        a C shape open towards the fence turns by about −50° in the simulator, not 0°)."""
        self.phases += "H"
        return ("free", "hooked")

    def release(self, k, s, reason):
        """Let the corner go at edge ``k``, position ``s``; the part then rides the belt (the
        corner moves at ``_PUSHER_VELOCITY`` relative to it) and the corner meets it again if
        that ray hits the outline (a concave part hooking the tip: e.g. a C open to the fence)."""
        a = self.poly[k]
        e = self.poly[(k + 1) % self.n] - a
        p = a + s * e / float(np.hypot(*e))
        self.X = -(self.rot() @ p)  # the corner is at the contact point
        if reason != "released":
            return ("free", reason)
        d = self.rot().T @ np.array(_PUSHER_VELOCITY)  # the corner's path in the part frame
        hit = self.ray(p, d)
        if hit is None:
            return ("free", reason)
        j, sj, dist = hit
        self.X = self.X - dist * np.array(_PUSHER_VELOCITY)
        return ("C", j, sj)

    def ray(self, p: np.ndarray, d: np.ndarray):
        """First outline edge hit by the ray ``p + λ d`` (part frame, λ beyond a small margin):
        ``(edge, position along it, λ)`` or None."""
        a, b = self.poly, np.roll(self.poly, -1, axis=0)
        e = b - a
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        w = a - p
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den
            u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den
        ok = (den != 0.0) & (u >= 0.0) & (u <= 1.0) & (lam > EXIT_PASS_MARGIN * self.geom.circumradius)
        if not ok.any():
            return None
        j = int(np.argmin(np.where(ok, lam, np.inf)))
        return j, float(u[j] * np.hypot(*e[j])), float(lam[j])


def exit_turn(part, edge: int, fence_angle_deg: float, side: int, mu: float) -> ExitTurn:
    """The turn of a part leaving the tip of a fence (local angle ``fence_angle_deg``) resting
    flush on hull edge ``edge`` (a stable edge of :func:`push_function` with the same ``mu`` and
    ``side``). Quasi-static phases, with the actual outline: the part slides flush until the foot
    shifted ``mu·d`` downstream leaves the supported part of the face; then either the tip corner
    pushes an outline edge (``C``: the edge turns about the corner towards the travel direction
    until the corner slides off its end) or, where the hull edge bridges a concavity, the last
    supported vertex pivots on the face (``F``) until it passes the tip or another vertex lands
    on the face (flush again)."""
    geom = as_geometry(part)
    yaw0 = math.radians(float(resting_yaw(geom.normals_deg[edge], fence_angle_deg, side)))
    ex = _Exit(geom, fence_angle_deg, side, mu, yaw0)
    a = geom.hull[edge]
    along = ex.rot() @ (geom.hull[(edge + 1) % len(geom.hull)] - a)
    ex.X = -(ex.rot() @ a)  # hull edge on the face line, first vertex at the tip ...
    ex.X = ex.X - max(0.0, float(along @ ex.t)) * ex.t  # ... and its downstream end there
    state: tuple = ("flush",)
    seen: set = set()
    for _ in range(EXIT_MAX_PHASES):
        if state[0] == "flush":
            state = ex.flush()
            key = (state, round(ex.yaw / EXIT_SAME_RAD))
            if key in seen:  # back where it was: no progress (a part wedged on the face)
                state = ("free", "stuck")
                break
            seen.add(key)
        elif state[0] == "F":
            state = ex.pivot(state[1])
        elif state[0] == "C":
            state = ex.corner(state[1], state[2])
        elif state[0] == "B":
            state = ex.both(state[1], state[2], state[3])
        else:
            break
    reason = state[1] if state[0] == "free" else "phases"
    return ExitTurn(math.degrees(ex.yaw - yaw0), (float(ex.X[0]), float(ex.X[1])), reason, ex.phases)


# ----------------------------------------------------------------------------------------------
# Scene: fences as the part meets them
# ----------------------------------------------------------------------------------------------
@lru_cache(maxsize=1)
def default_scene() -> dict:
    """The ``scene`` section of the study config (``config/config.yaml``), read once."""
    from feeder.lane.settings import load_settings

    return load_settings()[0]


def fence_mu(scene: dict) -> float:
    """Part–fence friction as pybullet combines it: ``scene.part.friction × scene.fences.friction``."""
    return float(scene["part"]["friction"]) * float(scene["fences"]["friction"])


@dataclass(frozen=True)
class FenceModel:
    """One built fence as the analytic model sees it (lane coordinates, metres, degrees).

    ``side``: +1 right, −1 left; ``inner``: innermost reach ``min(side · x)`` of its footprint;
    ``exit_deg``: local angle of the face the part leaves from (straight: θ; curved: last chord);
    ``slot_deg``: local angle at the slot end (straight: θ); ``tip``: the corner the part leaves
    around; ``centre``/``outer_radius``: the arc of a curved fence's face (None for straight)."""

    location: str
    fence: Fence
    side: int
    inner: float
    exit_deg: float
    slot_deg: float
    tip: tuple[float, float]
    centre: tuple[float, float] | None = None
    outer_radius: float | None = None

    @property
    def curved(self) -> bool:
        return self.centre is not None


def _local_angle(yaw_rad: float, side: int) -> float:
    """Local fence angle (degrees, to the travel direction) of a box running along ``yaw_rad``
    from the slot towards the tip."""
    return math.degrees(math.atan2(-side * math.cos(yaw_rad), math.sin(yaw_rad)))


def fence_models(loc1, loc2, scene: dict | None = None) -> list[FenceModel]:
    """The fences of a configuration in the order a part meets them (Location 2, then 1), built
    by the simulator's own geometry (:func:`feeder.sim.scene.scene_fences`, with the upstream
    fence trimmed to ``min_gap``)."""
    from feeder.sim.scene import box_corners, curved_polyline, scene_fences

    scene = default_scene() if scene is None else scene
    loc1, loc2 = _fence(loc1), _fence(loc2)
    out = []
    for fg in scene_fences(scene, loc1, loc2):
        side = fg.side
        corners = np.concatenate([box_corners(*b) for b in fg.boxes])
        inner = float(np.min(side * corners[:, 0]))
        cx, cy, hl, ht, yaw = fg.boxes[-1]
        d = np.array([math.cos(yaw), math.sin(yaw)])
        face = np.array([-d[1], d[0]])
        face = face if face[1] < 0 else -face  # the face the part meets is on the upstream side
        tip = np.array([cx, cy]) + hl * d + ht * face
        exit_deg = _local_angle(yaw, side)
        slot_deg = _local_angle(fg.boxes[0][4], side)
        centre = radius = None
        if fg.fence.type == "curved":
            fc = scene["fences"]
            cc = fc["curved"]
            slot_x = float(fc["slots"][cc["slot"]])
            y0 = float(fc["locations"][fg.location]["y"])
            _, ctr = curved_polyline(
                fg.fence.angle, side, slot_x, y0, float(cc["radius"]), float(cc["span_deg"]), int(cc["segments"])
            )
            centre = (float(ctr[0]), float(ctr[1]))
            radius = float(cc["radius"]) + float(ht)
        out.append(
            FenceModel(
                fg.location, fg.fence, side, inner, exit_deg, slot_deg, (float(tip[0]), float(tip[1])), centre, radius
            )
        )
    return out


def _fence(loc) -> Fence:
    return loc if isinstance(loc, Fence) else parse_location(loc)


# ----------------------------------------------------------------------------------------------
# A configuration: drops pushed through the fences
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FenceResponse:
    """What one fence does to a part arriving at any yaw: its push function (at the fence's
    friction and side), the yaw each stable edge rests at on the exit face, and its exit turn."""

    model: FenceModel
    push: PushFunction
    rest_deg: np.ndarray  # (S,) yaw flush on the exit face
    exit_deg: np.ndarray  # (S,) yaw after the exit turn
    exit_offset: np.ndarray  # (S, 2) centroid relative to the tip corner when released


def fence_response(part, model: FenceModel, mu: float, exit_turns: bool = True) -> FenceResponse:
    """The push function and resting/exit yaws of each stable edge on ``model``."""
    geom = as_geometry(part)
    push = push_function(geom, mu, model.side)
    rest = resting_yaw(push.normals_deg, model.exit_deg, model.side)
    # no exit turn where the exit face holds the part (in the friction cone): it jams there
    turning = exit_turns and float(friction_margin_deg(model.exit_deg, mu)) > 0.0
    turns = [exit_turn(geom, int(k), model.exit_deg, model.side, mu) if turning else None for k in push.edges]
    delta = np.array([t.delta_deg if t else 0.0 for t in turns])
    if turning:
        offset = np.array([t.offset for t in turns])
    else:  # flush at the tip: the centroid sits at its height from the face, over the foot
        normal = np.radians(fence_normal_deg(model.exit_deg, model.side))
        offset = -np.outer(geom.heights[push.edges], [math.cos(normal), math.sin(normal)])
    return FenceResponse(model, push, rest, _wrap(rest + delta), offset)


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


def _apply(geom, resp: FenceResponse, mu: float, yaw, x, w, jams: bool = True):
    """One fence on the drops (yaws, lateral centroid positions, weights); returns the new
    arrays and (touch share, jam share, mean entry margin) of the arriving weight. The margin is
    over the drops that touch, else over all arriving drops, else (nothing arrives: an upstream
    fence jammed every drop) the margin at the fence's exit angle."""
    m = resp.model
    side = m.side
    reach = _support_towards(geom, yaw, side)
    touch = side * x + reach > m.inner
    entry = np.full(yaw.shape, m.exit_deg)
    if m.curved:
        # a disc of the part's support radius meets the arc's face at local angle acos(...)
        cos_a = side * (m.centre[0] - x) / (m.outer_radius + reach)
        entry = np.degrees(np.arccos(np.clip(cos_a, -1.0, 1.0)))
        graze = entry < m.exit_deg  # would meet the circle beyond the tip: the corner only
        touch &= ~graze
        entry = np.minimum(entry, m.slot_deg)
    margin = friction_margin_deg(entry, mu)
    jam = touch & (margin < 0.0) if jams else np.zeros(yaw.shape, dtype=bool)
    push = touch & ~jam
    total = float(w.sum())
    if w[touch].sum() > 0:
        mean_margin = np.average(margin[touch], weights=w[touch])
    elif margin.size:
        mean_margin = margin.mean()
    else:  # nothing arrives: an upstream fence jammed every drop
        mean_margin = friction_margin_deg(m.exit_deg, mu)
    stats = (
        float(w[touch].sum()) / total if total > 0 else 0.0,
        float(w[jam].sum()) / total if total > 0 else 0.0,
        float(mean_margin),
    )
    if push.any() and resp.push.rolls:  # every pushed drop leaves at the rolling density
        phi = (np.arange(ROLL_SAMPLES) + 0.5) * (FULL_TURN_DEG / ROLL_SAMPLES)
        normal = float(fence_normal_deg(m.exit_deg, side))
        keep = ~(jam | push)
        yaw = np.concatenate([yaw[keep], _wrap(normal - phi)])
        x = np.concatenate([x[keep], m.tip[0] - radius_function(geom, phi) * math.cos(math.radians(normal))])
        w = np.concatenate([w[keep], float(w[push].sum()) * rolling_density(geom, mu, side, phi)])
        return yaw, x, w, stats
    if push.any():
        # the exit face decides the basin (its push function at the entry angle did worse on the
        # simulated two-fence configurations: the disc estimate of the entry is rough)
        phi = fence_normal_deg(m.exit_deg, side) - yaw[push]
        idx = resp.push.basin_index(phi)
        # the turn the fence can give: a sideways push by the overlap turns the part by at most
        # overlap / (2c) (unit push at moment arm a turns it by a / (c² + a²) <= 1 / (2c))
        overlap = side * x[push] + reach[push] - m.inner
        budget = np.degrees(overlap / (2.0 * geom.limit_radius))
        need = np.mod(resp.push.normals_deg[idx] - phi + HALF_TURN_DEG, FULL_TURN_DEG) - HALF_TURN_DEG
        full = np.abs(need) <= budget
        new_yaw = np.where(full, resp.exit_deg[idx], yaw[push] - np.sign(need) * budget)
        new_x = np.where(full, m.tip[0] + resp.exit_offset[idx, 0], x[push] - side * overlap)
        yaw = yaw.copy()
        x = x.copy()
        yaw[push], x[push] = new_yaw, new_x
    keep = ~jam
    return yaw[keep], x[keep], w[keep], stats


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
) -> Distribution:
    """Push ``samples`` evenly spaced initial yaws (centred parts) through the configuration.

    ``mu``: part–fence friction (default :func:`fence_mu` of ``scene``); ``exit_turns``: apply the
    exit turn (False: parts leave a fence flush with it); ``fences``: an explicit list of fence
    models in the order met (overrides loc1/loc2); ``jams``: False pushes drops in the friction
    cone as if they slid (their jam share is still reported); ``responses``: a memo of
    :func:`fence_response` for this one part, filled and reused across calls (the exit-turn
    integration is most of the cost, and configurations of a part share fences): give each part
    its own dict."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu = fence_mu(scene) if mu is None else float(mu)
    if fences is None:
        fences = fence_models(loc1, loc2, scene)
    n = int(samples)
    if n < 1:
        raise FeederError(f"samples must be a positive integer, got {samples!r}")
    yaw = (np.arange(n) + 0.5) * (FULL_TURN_DEG / n)
    x = np.zeros(n)
    w = np.full(n, 1.0 / n)
    touch, jam, margin = {}, {}, {}
    for m in fences:
        key = (m, mu, bool(exit_turns))
        resp = None if responses is None else responses.get(key)
        if resp is None:
            resp = fence_response(geom, m, mu, exit_turns)
            if responses is not None:
                responses[key] = resp
        yaw, x, w, (t, j, mg) = _apply(geom, resp, mu, yaw, x, w, jams)
        touch[m.location], jam[m.location], margin[m.location] = t, j, mg
    ok = float(w.sum())
    return Distribution(_wrap(yaw), w, ok, touch, jam, margin)


def _bin_masses(yaws, weights, bins: int) -> np.ndarray:
    from feeder.labels.metrics import normalize_yaw

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
    without jams is returned (the label of such a configuration is excluded anyway)."""
    from feeder.labels.metrics import wrapped_gaussian_smooth

    if int(bins) != bins or bins < 1:
        raise FeederError(f"bins must be a positive integer, got {bins!r}")
    if not (math.isfinite(smooth_deg) and smooth_deg >= 0):
        raise FeederError(f"smooth_deg must be finite and >= 0, got {smooth_deg!r}")
    if not math.isfinite(frame_deg):
        raise FeederError(f"frame_deg must be finite, got {frame_deg!r}")
    dist = distribution or analytic_distribution(part, loc1, loc2, scene, mu=mu, exit_turns=exit_turns)
    if dist.weights.sum() <= 0.0:
        dist = analytic_distribution(part, loc1, loc2, scene, mu=mu, exit_turns=exit_turns, jams=False)
    hist = _bin_masses(dist.yaws + frame_deg, dist.weights, int(bins))
    hist /= hist.sum()
    if smooth_deg == 0:
        return hist
    return wrapped_gaussian_smooth(hist, smooth_deg * bins / FULL_TURN_DEG)


def fourier_coefficients(pmf, k: int = FOURIER_K) -> np.ndarray:
    """``c_1..c_k`` (complex) of a circular PMF, ``c_k = Σ_b p_b exp(−i k θ_b)`` at bin centres."""
    p = np.asarray(pmf, dtype=np.float64)
    bins = p.shape[-1]
    centres = (np.arange(bins) + 0.5) * (2.0 * math.pi / bins)
    ks = np.arange(1, int(k) + 1)
    return p @ np.exp(-1j * np.outer(centres, ks))


# ----------------------------------------------------------------------------------------------
# The feature block
# ----------------------------------------------------------------------------------------------
LOCATIONS = ("loc1", "loc2")
_PER_LOCATION = ("present", "touch", "jam", "margin_deg")
_SCALARS = ("ok_mass", "peak_mass", "entropy_bits", "stable_edges", "largest_basin")
# Bump by hand when the feature block's values change for the same names (a model trained on
# the old values would read the new ones wrongly): part of feeder.labels.dataset.features_version.
PUSH_FEATURES_VERSION = 1
PUSH_FEATURE_NAMES: tuple[str, ...] = (
    *(f"{part}_c{k}" for k in range(1, FOURIER_K + 1) for part in ("re", "im")),
    *(f"{loc}_{name}" for loc in LOCATIONS for name in _PER_LOCATION),
    *_SCALARS,
)


def _peak_mass(yaws, weights) -> float:
    """Largest share of the ok weight at one resting yaw (yaws within MODE_MERGE_DEG merged)."""
    order = np.argsort(yaws)
    y, w = yaws[order], weights[order] / weights.sum()
    if y.size == 0:
        return 0.0
    new = np.concatenate([[True], np.diff(y) > MODE_MERGE_DEG])
    groups = np.cumsum(new) - 1
    sums = np.bincount(groups, weights=w)
    if groups[-1] > 0 and (y[0] + FULL_TURN_DEG - y[-1]) <= MODE_MERGE_DEG:  # wrap-around
        sums[0] += sums[-1]
        sums = sums[:-1]
    return float(sums.max())


def _shape_of(geom, scene, mu_f, exit_turns, fences, responses) -> tuple[Distribution, Distribution]:
    """(the distribution of the ok drops, the distribution its PMF describes): the latter is the
    same configuration with jams ignored when every drop jams."""
    dist = analytic_distribution(
        geom, None, None, scene, mu=mu_f, exit_turns=exit_turns, fences=fences, responses=responses
    )
    shape = dist
    if dist.weights.sum() <= 0.0:
        shape = analytic_distribution(
            geom, None, None, scene, mu=mu_f, exit_turns=exit_turns, fences=fences, jams=False, responses=responses
        )
    return dist, shape


def _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, smooth_deg, bins) -> np.ndarray:
    """The feature block of :func:`push_features` from the configuration's distributions."""
    pmf = analytic_pmf(
        geom, None, None, scene, frame_deg=frame_deg, smooth_deg=smooth_deg, bins=bins, distribution=shape
    )
    coef = fourier_coefficients(pmf, FOURIER_K)
    out = [v for c in coef for v in (c.real, c.imag)]
    present = {"loc1": _fence(loc1).present, "loc2": _fence(loc2).present}
    no_fence_margin = float(friction_margin_deg(0.0, mu_f))
    for loc in LOCATIONS:
        out += [
            1.0 if present[loc] else 0.0,
            dist.touch.get(loc, 0.0),
            dist.jam.get(loc, 0.0),
            dist.margin.get(loc, no_fence_margin),
        ]
    raw = _bin_masses(shape.yaws + frame_deg, shape.weights, int(bins))
    raw /= raw.sum()
    nz = raw[raw > 0]
    frictionless = push_function(geom)
    out += [
        dist.ok_mass,
        _peak_mass(shape.yaws, shape.weights),
        float(-np.sum(nz * np.log2(nz))),
        float(len(frictionless.edges)),
        float(frictionless.measures.max()),
    ]
    vec = np.asarray(out, dtype=np.float64)
    assert vec.shape == (len(PUSH_FEATURE_NAMES),)
    return vec


def push_features(
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
    responses: dict | None = None,
) -> np.ndarray:
    """The fixed-size feature block (:data:`PUSH_FEATURE_NAMES`, layout in the module doc) of a
    part (outline array, PartGeometry or PushGeometry) in a configuration (``none``,
    ``straight:θ``, ``curved:θ`` or :class:`~feeder.lane.fences.Fence`). ``responses``: the
    per-part memo of :func:`analytic_distribution`."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu_f = fence_mu(scene) if mu is None else float(mu)
    fences = fence_models(loc1, loc2, scene)
    dist, shape = _shape_of(geom, scene, mu_f, exit_turns, fences, responses)
    return _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, smooth_deg, bins)


def push_block(
    part,
    loc1,
    loc2,
    scene: dict | None = None,
    *,
    frame_deg: float = 0.0,
    bins: int = PMF_BINS,
    pmf_smooth_deg: float = DEFAULT_SMOOTH_DEG,
    responses: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(push_features(...), analytic_pmf(...))`` of one configuration from a single pass of the
    drops: the feature block with its default smoothing and the PMF smoothed by
    ``pmf_smooth_deg`` (a dataset uses its labels' smoothing), both in the frame ``frame_deg``
    over ``bins`` bins. Equal to the two calls (the scene's friction, exit turns on)."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu_f = fence_mu(scene)
    fences = fence_models(loc1, loc2, scene)
    dist, shape = _shape_of(geom, scene, mu_f, True, fences, responses)
    features = _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, DEFAULT_SMOOTH_DEG, bins)
    pmf = analytic_pmf(
        geom, None, None, scene, frame_deg=frame_deg, smooth_deg=pmf_smooth_deg, bins=bins, distribution=shape
    )
    return features, pmf
