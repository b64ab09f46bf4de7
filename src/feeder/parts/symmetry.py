"""Rotational symmetry of a part's outline (for refining labels over one period).

A part with n-fold rotational symmetry is the same body after a turn of 360/n about its area
centroid, so the drop map satisfies ``f(β + 360/n) = f(β) + 360/n`` (statuses repeat) whatever
the fences: they need not be symmetric, the part is. Only rotations count — a mirror symmetry
does not give this relation. See :func:`feeder.sim.adaptive.refine` (``period_deg``) and
:func:`feeder.sim.adaptive.unfold`.

Conventions: an outline is a closed simple polygon, (k, 2) vertices in any frame and unit, CW or
CCW, with or without the closing duplicate; through-holes (``holes``) are polygons inside it, and
their rings are part of the boundary. The *symmetry error* of a turn by 360/n is the
symmetric Hausdorff distance between the outline's boundary and the boundary turned about the
area centroid (segments densified, so it is not only vertex-to-vertex), divided by the part's
size: the largest distance from the centroid to a vertex. It is 0 for an exact symmetry.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import LinearRing, MultiLineString, Polygon

from feeder.errors import FeederError

FULL_TURN_DEG = 360.0
# 0.5 % of the part's radius: a 32-gon "circle" passes the 30° turn (error 0.43 %), a feature
# (notch, tooth, slot) standing out more than 0.5 % of the radius breaks the symmetry.
DEFAULT_SYMMETRY_TOLERANCE = 0.005
# Largest order reported: periods below 30° leave too few samples per period to refine, and a
# part that is round to within the tolerance is treated as 12-fold symmetric.
DEFAULT_MAX_ORDER = 12
# Densification of the boundary for the Hausdorff distance (fraction of each segment).
_DENSIFY = 0.05
# Margin (a share of the part's size, like the errors) by which the cheap lower bound
# (_vertex_error) must exceed the tolerance to skip the full measurement: far above the round-off
# of two ways of measuring one distance (~1e-15, more for a part far from its origin), so that
# rotational_order answers exactly as if it measured every order in full.
_BOUND_SLACK = 1e-9


def _polygon(outline, holes=()) -> Polygon:
    rings = []
    for what, ring in [("outline", outline), *(("hole", h) for h in holes)]:
        pts = np.asarray(ring, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 3:
            raise FeederError(f"{what} must be a (k, 2) array with k >= 3, got shape {pts.shape}")
        if not np.isfinite(pts).all():
            raise FeederError(f"{what} has non-finite coordinates")
        rings.append(pts)
    poly = Polygon(rings[0], rings[1:])
    if not poly.is_valid or poly.area <= 0:
        raise FeederError(f"outline is not a simple polygon with positive area ({shapely.is_valid_reason(poly)})")
    return poly


def _check_tolerance(tolerance: float) -> float:
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise FeederError(f"symmetry tolerance must be > 0, got {tolerance!r}")
    return float(tolerance)


def _turned(poly: Polygon, n: int) -> tuple[list[np.ndarray], list[np.ndarray], float]:
    """(the boundary's rings: the outline's, then the holes', the same turned by 360/n about the
    centroid of the region, the size: the largest distance of an outline vertex from that
    centroid)."""
    rings = [np.asarray(poly.exterior.coords), *(np.asarray(h.coords) for h in poly.interiors)]
    c = np.asarray(poly.centroid.coords[0])
    size = float(np.linalg.norm(rings[0] - c, axis=1).max())
    a = math.radians(FULL_TURN_DEG / n)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return rings, [(ring - c) @ rot.T + c for ring in rings], size


def _boundary(rings: list[np.ndarray]):
    """One ring as a LinearRing (a simply connected part, as before holes were supported), several
    as a MultiLineString."""
    return LinearRing(rings[0]) if len(rings) == 1 else MultiLineString(rings)


def _error(poly: Polygon, n: int) -> float:
    rings, turned, size = _turned(poly, n)
    dist = shapely.hausdorff_distance(_boundary(rings), _boundary(turned), densify=_DENSIFY)
    return float(dist) / size


def _vertex_error(poly: Polygon, n: int) -> float:
    """A lower bound of :func:`_error`, cheap: the largest distance from a turned vertex to the
    boundary (the Hausdorff distance measures every turned vertex, and more), over the same size
    (same centroid, size and turn as :func:`_error`)."""
    rings, turned, size = _turned(poly, n)
    return float(shapely.distance(_boundary(rings), shapely.points(np.concatenate(turned))).max()) / size


def symmetry_error(outline, n: int, holes=()) -> float:
    """Relative symmetry error (see the module docstring) of a turn by 360/n; 0.0 for n = 1."""
    if int(n) != n or n < 1:
        raise FeederError(f"symmetry order must be a positive integer, got {n!r}")
    poly = _polygon(outline, holes)
    return 0.0 if n == 1 else _error(poly, int(n))


def rotational_order(
    outline, tolerance: float = DEFAULT_SYMMETRY_TOLERANCE, max_order: int = DEFAULT_MAX_ORDER, holes=()
) -> int:
    """The largest n ≤ ``max_order`` whose turn by 360/n about the area centroid maps the outline
    onto itself within ``tolerance`` (relative symmetry error); 1 when there is none.

    Square → 4, equilateral triangle → 3, 2:1 rectangle → 2, regular hexagon → 6, L-shape → 1,
    a finely polygonised circle → ``max_order``. Through-holes (``holes``) count: they move the
    centroid and must map onto holes too.
    """
    tol = _check_tolerance(tolerance)
    if int(max_order) != max_order or max_order < 1:
        raise FeederError(f"max_order must be a positive integer, got {max_order!r}")
    poly = _polygon(outline, holes)
    for n in range(int(max_order), 1, -1):
        if _vertex_error(poly, n) > tol + _BOUND_SLACK:
            continue  # the full error is at least this: no need to measure it
        if _error(poly, n) <= tol:
            return n
    return 1


def check_order(outline, n: int, tolerance: float = DEFAULT_SYMMETRY_TOLERANCE, holes=()) -> None:
    """FeederError unless a turn by 360/n maps the outline (and holes) onto itself within ``tolerance``."""
    tol = _check_tolerance(tolerance)
    err = symmetry_error(outline, n, holes)
    if err > tol:
        raise FeederError(
            f"part has no {int(n)}-fold symmetry: turning it by {FULL_TURN_DEG / n:g}° about its "
            f"centroid moves its outline by {err:.3g} of its radius (tolerance {tol:g})"
        )


def _reflected(poly: Polygon, axis_deg: float) -> tuple[list[np.ndarray], list[np.ndarray], float]:
    """(the boundary's rings, the same reflected across the line through the area centroid at
    ``axis_deg``, the size), as :func:`_turned` for a turn."""
    rings = [np.asarray(poly.exterior.coords), *(np.asarray(h.coords) for h in poly.interiors)]
    c = np.asarray(poly.centroid.coords[0])
    size = float(np.linalg.norm(rings[0] - c, axis=1).max())
    a = 2.0 * math.radians(axis_deg)
    ref = np.array([[math.cos(a), math.sin(a)], [math.sin(a), -math.cos(a)]])
    return rings, [(ring - c) @ ref.T + c for ring in rings], size


def mirror_error(outline, axis_deg: float, holes=()) -> float:
    """Relative symmetry error (as :func:`symmetry_error`) of the reflection across the line through
    the area centroid at ``axis_deg`` (degrees from the frame's x axis)."""
    if not math.isfinite(float(axis_deg)):
        raise FeederError(f"mirror axis must be finite, got {axis_deg!r}")
    return _mirror_error(_polygon(outline, holes), float(axis_deg))


def _mirror_error(poly: Polygon, axis_deg: float) -> float:
    rings, reflected, size = _reflected(poly, axis_deg)
    return float(shapely.hausdorff_distance(_boundary(rings), _boundary(reflected), densify=_DENSIFY)) / size


def mirror_axis(outline, tolerance: float = DEFAULT_SYMMETRY_TOLERANCE, holes=()) -> float | None:
    """A mirror axis of the outline (and holes) through its area centroid, degrees in [0, 180) from
    the frame's x axis, or None when no reflection maps it onto itself within ``tolerance``.

    A polygon's mirror axis crosses its outline at points the reflection fixes: a vertex, or the
    midpoint of an edge the axis meets at a right angle. So the axes tried are the lines from the
    centroid through every outline vertex and edge midpoint; the one with the least error is
    returned. A rectangle in its own frame → 0 (or 90), an L-shape → the diagonal of its corner
    where its legs are equal, a parallelogram that is not a rhombus → None.
    """
    tol = _check_tolerance(tolerance)
    poly = _polygon(outline, holes)
    ring = np.asarray(poly.exterior.coords)[:-1]
    c = np.asarray(poly.centroid.coords[0])
    points = np.concatenate([ring, 0.5 * (ring + np.roll(ring, -1, axis=0))])
    offsets = points - c
    keep = np.hypot(offsets[:, 0], offsets[:, 1]) > 1e-12 * float(np.abs(ring).max() + 1.0)
    axes = np.unique(np.round(np.mod(np.degrees(np.arctan2(offsets[keep, 1], offsets[keep, 0])), 180.0), 9))
    best, best_err = None, math.inf
    for axis in axes:
        rings, reflected, size = _reflected(poly, float(axis))
        bound = float(shapely.distance(_boundary(rings), shapely.points(np.concatenate(reflected))).max()) / size
        if bound > tol + _BOUND_SLACK or bound >= best_err:
            continue
        err = _mirror_error(poly, float(axis))
        if err <= tol and err < best_err:
            best, best_err = float(axis) % 180.0, err
    return best
