"""The part as a fence pushes it: the convex hull of its outline about its area centroid.

Geometry (:func:`push_geometry`)
    The convex hull of the outline, taken about the outline's **area centroid** (the centre of
    mass of the uniform part, which is what the fence torques act about), not the hull's own
    centroid: for a concave part the two differ, and a hull edge is stable with respect to the
    centre of mass. The radius function ``r(φ)`` (:func:`radius_function`) is the support distance
    from that centroid to the hull's supporting line of outward normal ``φ`` (degrees, part frame).
    The *limit-surface radius* ``c = ∫|x − x_c| dA / A`` (exact, per edge) sets how the belt's
    friction resists turning against sliding (ellipsoidal limit surface, Lee & Cutkosky 1991,
    uniform pressure).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.circular import FULL_TURN_DEG
from feeder.errors import FeederError
from feeder.parts.geometry import _check_holes, clean_holes, clean_outline, profile_moments

# Relative tolerance (of the hull's circumradius) for "strictly inside an edge" and collinearity.
REL_TOL = 1e-9


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
    # ∫|x| dA over the region: the outline's less each hole's (all CCW, about the same centroid)
    limit_radius = (_mean_distance_integral(rel) - sum(_mean_distance_integral(h - centroid) for h in cut)) / area
    centroid.setflags(write=False)
    return _about_centroid(rel, centroid, area, limit_radius)


def _about_centroid(rel: np.ndarray, centroid: np.ndarray, area: float, limit_radius: float) -> PushGeometry:
    """The hull fields of a cleaned CCW outline ``rel`` given about the area centroid."""
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
    d1, d2 = rel - np.roll(rel, 1, axis=0), np.roll(rel, -1, axis=0) - rel
    convex = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] >= 0.0
    for arr in (hull, normals_deg, lengths, heights, feet, rel, convex):
        arr.setflags(write=False)
    return PushGeometry(centroid, area, hull, normals_deg, lengths, heights, feet, limit_radius, size, rel, convex)


def dilate(part, radius: float, quad_segs: int) -> PushGeometry:
    """The part as a disc of ``radius`` sees it: its outline grown by ``radius`` (the Minkowski
    sum with the disc), about the same centroid, with the same area and limit-surface radius (the
    part itself is unchanged: only the contact is). The centre of a disc of radius ``r`` touching
    the outline lies on the grown outline, so a round fence tip's centre is a point pusher on it
    (the contact itself, and so where friction acts, lies ``r`` further in). Concavities narrower
    than the disc fill in; holes play no part.

    The union of the outline, each edge's rectangle swept out by ``r`` along its outward normal,
    and at each convex vertex the arc between its two edges' normals: a fan with a vertex every
    ``90 / quad_segs`` degrees, at both ends (where the rectangles end, so no false concave corner
    appears between them) and at the normal of every hull edge in between (so a hull edge
    bridging a concavity stays a hull edge of the grown outline, ``r`` further out).
    ``radius`` 0 returns the geometry itself."""
    import shapely
    from shapely.ops import unary_union

    geom = as_geometry(part)
    radius = float(radius)
    if not (math.isfinite(radius) and radius >= 0.0):
        raise FeederError(f"dilation radius must be a finite number >= 0, got {radius!r}")
    if int(quad_segs) < 1:
        raise FeederError(f"quad_segs must be a positive integer, got {quad_segs!r}")
    if radius == 0.0:
        return geom
    step = FULL_TURN_DEG / (4 * int(quad_segs))
    rel = geom.outline
    nxt = np.roll(rel, -1, axis=0)
    edge = nxt - rel
    unit = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.hypot(edge[:, 0], edge[:, 1])[:, None]  # outward
    normal_deg = np.degrees(np.arctan2(unit[:, 1], unit[:, 0]))
    shapes = [shapely.Polygon(rel)]
    shapes += [shapely.Polygon([a, b, b + radius * n, a + radius * n]) for a, b, n in zip(rel, nxt, unit)]
    for i in np.flatnonzero(geom.convex):
        start = normal_deg[i - 1]  # the incoming edge's normal; the arc turns CCW to the outgoing one
        span = float(np.mod(normal_deg[i] - start, FULL_TURN_DEG))
        inner = np.arange(math.floor(start / step) + 1, math.ceil((start + span) / step)) * step
        bridges = np.mod(geom.normals_deg - start, FULL_TURN_DEG)
        between = np.concatenate([np.mod(inner - start, FULL_TURN_DEG), bridges[bridges < span]])
        between = np.radians(start + np.unique(between[(between > 0.0) & (between < span)]))
        arc = rel[i] + radius * np.column_stack([np.cos(between), np.sin(between)])
        # the ends exactly where the two edges' rectangles end: the pieces share those sides
        shapes.append(
            shapely.Polygon(np.vstack([rel[i], rel[i] + radius * unit[i - 1], arc, rel[i] + radius * unit[i]]))
        )
    try:
        grown = unary_union(shapes)
    except shapely.errors.GEOSException as err:
        raise FeederError(f"outline cannot be grown by {radius} ({err})") from None
    outline = clean_outline(np.asarray(grown.exterior.coords)[:-1], what="grown outline")
    return _about_centroid(outline, geom.centroid, geom.area, geom.limit_radius)


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
