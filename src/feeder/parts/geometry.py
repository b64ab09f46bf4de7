"""Exact planar geometry of an extruded part, read from its STL.

A part is a prism: a simple polygon (the *outline*, in the STL's x-y frame) extruded along +z
from ``z = 0`` to ``z = thickness``. :func:`load_part` recovers the outline exactly from the
mesh (the boundary edges of the top face), checks that the mesh really is a closed extrusion,
and computes what the simulator needs:

* ``area`` (m²) and ``centroid`` (m) of the outline;
* ``second_moment = (Ixx, Iyy, Ixy)``: second moments of *area* about the centroid (m⁴),
  ``Ixx = ∫(y - cy)² dA``, ``Iyy = ∫(x - cx)² dA``, ``Ixy = ∫(x - cx)(y - cy) dA`` (product of
  area, positive sign). For a uniform prism of density ρ the mass moment about the vertical axis
  through the centroid is ``ρ · thickness · (Ixx + Iyy)``;
* ``convex_pieces``: an exact convex decomposition (constrained Delaunay triangulation merged
  greedily, Hertel–Mehlhorn style): CCW convex polygons whose union is the outline and whose
  interiors are disjoint. A convex outline is one piece.

Everything is in metres. :meth:`PartGeometry.from_polygon` builds the same object from a vertex
list (tests, hand-made parts).
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

# Relative tolerance (of the part's in-plane size) for "the same z level" and collinear vertices.
_REL_TOL = 1e-6
# Plausibility bound for an STL in metres: a part wider than this is almost surely in millimetres.
MAX_PART_SIZE_M = 1.0
# What one unit of a part file is, in metres (``--units`` / ``parts.units``; ``auto`` picks one).
UNITS_M = {"m": 1.0, "mm": 1e-3}
UNIT_CHOICES = ("auto", *UNITS_M)


# --------------------------------------------------------------------------------------------
# Pure polygon math
# --------------------------------------------------------------------------------------------
def signed_area(poly: np.ndarray) -> float:
    """Shoelace signed area of a closed polygon given without the closing duplicate (CCW > 0)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_moments(poly: np.ndarray) -> tuple[float, np.ndarray, tuple[float, float, float]]:
    """Area, centroid and central second moments ``(Ixx, Iyy, Ixy)`` of a simple polygon.

    Green's theorem formulas, evaluated after shifting to the vertex mean for accuracy. The
    polygon may be CW or CCW; the area returned is positive.
    """
    poly = np.asarray(poly, dtype=np.float64)
    ref = poly.mean(axis=0)
    p = poly - ref
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * np.sum(cross)
    if a == 0.0:
        raise FeederError("polygon has zero area")
    cx = np.sum((x + xn) * cross) / (6.0 * a)
    cy = np.sum((y + yn) * cross) / (6.0 * a)
    ixx_o = np.sum((y * y + y * yn + yn * yn) * cross) / 12.0
    iyy_o = np.sum((x * x + x * xn + xn * xn) * cross) / 12.0
    ixy_o = np.sum((x * yn + 2 * x * y + 2 * xn * yn + xn * y) * cross) / 24.0
    sgn = 1.0 if a > 0 else -1.0
    area = abs(a)
    ixx = sgn * ixx_o - area * cy * cy
    iyy = sgn * iyy_o - area * cx * cx
    ixy = sgn * ixy_o - area * cx * cy
    centroid = np.array([cx, cy]) + ref
    return float(area), centroid, (float(ixx), float(iyy), float(ixy))


def clean_outline(outline: np.ndarray, rel_tol: float = _REL_TOL, what: str = "outline") -> np.ndarray:
    """Drop a closing duplicate, repeated vertices and collinear vertices; return CCW (N, 2).
    ``what`` names the polygon in errors (e.g. ``hole 2``).

    Repeated vertices (an edge no longer than ``rel_tol`` of the outline's size) go first, all at
    once; then collinear ones (within that distance of the chord of their neighbours, turning by
    less than 90°) one at a time, always the first by index, and repeated ones again whenever a
    removal makes one. Linear in the vertices (:func:`_drop_collinear`), so a finely faceted
    CAD export of a round part (every vertex within the tolerance of its chord) takes
    milliseconds, not the seconds a rescan after every removal took."""
    pts = np.asarray(outline, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise FeederError(f"{what} must be an (N, 2) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise FeederError(f"{what} has NaN or infinite coordinates")
    size = float(np.max(np.ptp(pts, axis=0))) if len(pts) else 0.0
    if size <= 0.0:
        raise FeederError(f"{what} has no extent")
    tol = rel_tol * size
    done = False
    while not done and len(pts) >= 3:
        nxt = np.roll(pts, -1, axis=0)
        keep = np.linalg.norm(nxt - pts, axis=1) > tol
        if not keep.all():
            pts = pts[keep]
            continue
        pts, done = _drop_collinear(pts, tol)
    if len(pts) < 3:
        raise FeederError(f"{what} has fewer than 3 distinct non-collinear vertices")
    if signed_area(pts) < 0:
        pts = pts[::-1].copy()
    return pts


def _drop_collinear(pts: np.ndarray, tol: float) -> tuple[np.ndarray, bool]:
    """Remove collinear vertices of a polygon with no repeated vertices, one at a time and always
    the first by index (as a rescan of the whole polygon after each removal would find it), until
    none is left (``done``) or a removal leaves an edge no longer than ``tol`` (not ``done``: the
    caller drops repeated vertices first). All vertices are tested at once first; from the first
    collinear one a scan goes on vertex by vertex: a removal changes only its two neighbours, so it
    resumes one vertex back. The scan's arithmetic is the vectorised test's, value for value."""
    prv, nxt = np.roll(pts, 1, axis=0), np.roll(pts, -1, axis=0)
    d1, d2 = pts - prv, nxt - pts
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    chord = np.linalg.norm(nxt - prv, axis=1)
    straight = (np.abs(cross) / np.maximum(chord, tol) <= tol) & (np.sum(d1 * d2, axis=1) > 0)
    if not straight.any():  # the usual outline: one vectorised test of every vertex
        return pts, True
    xs, ys = pts[:, 0].tolist(), pts[:, 1].tolist()
    i = int(np.flatnonzero(straight)[0])  # every vertex before it is not collinear
    while len(xs) >= 3 and i < len(xs):
        n = len(xs)
        p, q = (i - 1) % n, (i + 1) % n
        d1x, d1y = xs[i] - xs[p], ys[i] - ys[p]
        d2x, d2y = xs[q] - xs[i], ys[q] - ys[i]
        cross = d1x * d2y - d1y * d2x
        cx, cy = xs[q] - xs[p], ys[q] - ys[p]
        chord = math.sqrt(cx * cx + cy * cy)  # its distance from the chord p -> q
        if not (abs(cross) / max(chord, tol) <= tol and d1x * d2x + d1y * d2y > 0):
            i += 1
            continue
        del xs[i], ys[i]
        n -= 1
        if n < 3:
            break
        # every vertex before i - 1 kept its neighbours, except vertex 0 when the last one went
        p, i = (i - 1) % n, (0 if i in (0, n) else i - 1)
        ex, ey = xs[(p + 1) % n] - xs[p], ys[(p + 1) % n] - ys[p]
        if not math.sqrt(ex * ex + ey * ey) > tol:
            return np.column_stack([xs, ys]), False
    return np.column_stack([xs, ys]), True


def is_convex(poly: np.ndarray, rel_tol: float = 1e-9) -> bool:
    """True when a CCW polygon has no reflex vertex (collinear vertices allowed): no vertex turns
    clockwise by more than ``rel_tol`` radians (the sine of the turn, so that the short edges of a
    small hole are judged like long ones)."""
    p = np.asarray(poly, dtype=np.float64)
    d1 = p - np.roll(p, 1, axis=0)
    d2 = np.roll(p, -1, axis=0) - p
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    lengths = np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)
    return bool(np.all(cross >= -rel_tol * lengths))


def _check_simple(outline: np.ndarray, what: str) -> None:
    import shapely

    poly = shapely.Polygon(outline)
    if not poly.is_valid:
        reason = shapely.is_valid_reason(poly)
        raise FeederError(f"{what} is not a simple polygon ({reason})")


def clean_holes(holes) -> list[np.ndarray]:
    """:func:`clean_outline` of each hole, errors naming the hole (``hole 1``, ...)."""
    return [clean_outline(h, what=f"hole {k}") for k, h in enumerate(holes, start=1)]


def _check_holes(outline: np.ndarray, holes, what: str) -> None:
    """FeederError unless every hole lies strictly inside the outline, apart from the others
    (touching at a point counts as touching)."""
    import shapely

    poly = shapely.Polygon(outline, [np.asarray(h) for h in holes])
    if not poly.is_valid:
        raise FeederError(f"{what}: the holes are not inside the outline and apart ({shapely.is_valid_reason(poly)})")
    outer = shapely.Polygon(outline)
    rings = [shapely.Polygon(h) for h in holes]
    for k, ring in enumerate(rings, start=1):
        if not outer.contains(ring) or ring.exterior.intersects(outer.exterior):
            raise FeederError(f"{what}: the holes must lie inside the outline; hole {k} touches or crosses it")
    for i in range(len(rings)):
        for j in range(i + 1, len(rings)):
            if rings[i].intersects(rings[j]):
                raise FeederError(f"{what}: holes {i + 1} and {j + 1} touch or overlap")


def thinnest_wall(outline: np.ndarray, holes) -> float:
    """The narrowest material between a hole and the outline or between two holes (metres);
    infinite without holes."""
    import shapely

    rings = [shapely.LinearRing(h) for h in holes]
    if not rings:
        return math.inf
    boundary = shapely.LinearRing(outline)
    gaps = [boundary.distance(r) for r in rings]
    gaps += [rings[i].distance(rings[j]) for i in range(len(rings)) for j in range(i + 1, len(rings))]
    return float(min(gaps))


def triangulate(outline: np.ndarray, holes=()) -> list[tuple[int, int, int]]:
    """Constrained Delaunay triangulation of a simple polygon as CCW index triples (no new vertices).

    With ``holes`` (simple polygons inside it), the indices run over ``outline`` and then each hole
    in turn (:func:`profile_vertices`), and the holes are left out."""
    import shapely

    outline = np.asarray(outline, dtype=np.float64)
    holes = [np.asarray(h, dtype=np.float64) for h in holes]
    verts = profile_vertices(outline, holes)
    index = {(float(x), float(y)): i for i, (x, y) in enumerate(verts)}
    tris = shapely.constrained_delaunay_triangles(shapely.Polygon(outline, holes))
    out = []
    for tri in shapely.get_parts(tris):
        coords = np.asarray(tri.exterior.coords)[:3]
        try:
            ids = [index[(float(x), float(y))] for x, y in coords]
        except KeyError as err:  # pragma: no cover - CDT adds no Steiner points
            raise FeederError("triangulation introduced a vertex not on the outline") from err
        if signed_area(verts[ids]) < 0:
            ids = ids[::-1]
        out.append(tuple(ids))
    expected = len(verts) - 2 + 2 * len(holes)  # Euler: each hole adds two triangles
    if len(out) != expected:
        raise FeederError(f"triangulation gave {len(out)} triangles for {len(verts)} vertices and {len(holes)} holes")
    return out


def profile_vertices(outline: np.ndarray, holes=()) -> np.ndarray:
    """The vertices of an outline and then of each hole, one (N, 2) array: what the indices of
    :func:`triangulate` and :func:`convex_decomposition` run over."""
    return np.concatenate([np.asarray(outline, dtype=np.float64), *[np.asarray(h, dtype=np.float64) for h in holes]])


def profile_moments(outline: np.ndarray, holes=()) -> tuple[float, np.ndarray, tuple[float, float, float]]:
    """:func:`polygon_moments` of an outline with holes: area, centroid and central second moments
    of the outline's region less each hole's (the parallel-axis theorem moves every part to the
    common centroid)."""
    if not len(holes):
        return polygon_moments(outline)
    parts = [polygon_moments(outline), *[polygon_moments(h) for h in holes]]
    signs = [1.0] + [-1.0] * len(holes)
    area = sum(sg * a for sg, (a, _, _) in zip(signs, parts, strict=True))
    if not area > 0:
        raise FeederError("the holes leave no area")
    centroid = sum(sg * a * c for sg, (a, c, _) in zip(signs, parts, strict=True)) / area
    ixx = iyy = ixy = 0.0
    for sg, (a, c, (jxx, jyy, jxy)) in zip(signs, parts, strict=True):
        dx, dy = c - centroid
        ixx += sg * (jxx + a * dy * dy)
        iyy += sg * (jyy + a * dx * dx)
        ixy += sg * (jxy + a * dx * dy)
    return float(area), np.asarray(centroid, dtype=np.float64), (float(ixx), float(iyy), float(ixy))


def convex_decomposition(outline: np.ndarray, holes=()) -> list[np.ndarray]:
    """Exact convex pieces of a simple CCW polygon (Hertel–Mehlhorn on a constrained triangulation).

    Pieces use only the outline's own vertices, so their union is exactly the outline. Diagonals
    are removed greedily, longest first (ties by vertex index), whenever the merged piece stays
    convex; the result has at most 4x the minimum number of pieces. With ``holes`` (simple
    polygons inside the outline), the pieces cover the outline less the holes, from the vertices of
    both.
    """
    outline = np.asarray(outline, dtype=np.float64)
    holes = [np.asarray(h, dtype=np.float64) for h in holes]
    if not holes and is_convex(outline):
        return [outline.copy()]
    tris = triangulate(outline, holes)
    n_tris = len(tris)
    outline = profile_vertices(outline, holes)  # the indices run over every vertex
    pieces = [list(t) for t in tris]

    def edges(piece: list[int]) -> list[tuple[int, int]]:
        return [(piece[i], piece[(i + 1) % len(piece)]) for i in range(len(piece))]

    # interior diagonals: directed edges whose reverse is also a piece edge
    owner: dict[tuple[int, int], int] = {}
    for k, piece in enumerate(pieces):
        for e in edges(piece):
            owner[e] = k
    diagonals = sorted(
        {(min(a, b), max(a, b)) for (a, b) in owner if (b, a) in owner},
        key=lambda d: (-float(np.linalg.norm(outline[d[0]] - outline[d[1]])), d),
    )
    alive = {k: p for k, p in enumerate(pieces)}
    for a, b in diagonals:
        k1, k2 = owner.get((a, b)), owner.get((b, a))
        if k1 is None or k2 is None or k1 == k2:
            continue
        p1, p2 = alive[k1], alive[k2]
        # p1 contains a->b, p2 contains b->a; merged: p1 from b round to a, then p2 from a to b
        i = p1.index(b)
        walk1 = p1[i:] + p1[:i]  # starts at b, ends at a
        j = p2.index(a)
        walk2 = p2[j:] + p2[:j]  # starts at a, ends at b
        merged = walk1 + walk2[1:-1]
        if not is_convex(outline[merged]):
            continue
        del alive[k2]
        alive[k1] = merged
        for e in edges(merged):
            owner[e] = k1
        owner.pop((a, b), None)
        owner.pop((b, a), None)
    assert sum(len(p) - 2 for p in alive.values()) == n_tris  # triangles conserved
    return [clean_outline(outline[p], rel_tol=1e-12) for _, p in sorted(alive.items())]


# --------------------------------------------------------------------------------------------
# The part
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PartGeometry:
    """Outline (N, 2) CCW in metres without closing duplicate, thickness (m) and derived values.

    ``holes``: through-holes, each a CCW (M, 2) polygon inside the outline (none for a simply
    connected part). The area, centroid, second moments and convex pieces are those of the
    outline less its holes; ``outline`` stays the outer contour (what the fences meet and what the
    shape features describe)."""

    part_id: str
    outline: np.ndarray
    thickness: float
    area: float
    centroid: np.ndarray
    second_moment: tuple[float, float, float]
    convex_pieces: list[np.ndarray] = field(repr=False)
    holes: tuple[np.ndarray, ...] = field(default=(), repr=False)

    @classmethod
    def from_polygon(cls, part_id: str, outline, thickness: float, holes=()) -> PartGeometry:
        """Build from a vertex list (CW or CCW, closing duplicate optional), metres, and optional
        hole vertex lists (the same conventions)."""
        thickness = float(thickness)
        if not np.isfinite(thickness) or thickness <= 0:
            raise FeederError(f"part {part_id}: thickness must be positive, got {thickness!r}")
        pts = clean_outline(outline)
        _check_simple(pts, f"part {part_id}: outline")
        cut = tuple(clean_holes(holes))
        if cut:
            _check_holes(pts, cut, f"part {part_id}")
        area, centroid, moments = profile_moments(pts, cut)
        pieces = convex_decomposition(pts, cut)
        for arr in [pts, centroid, *pieces, *cut]:
            arr.setflags(write=False)
        return cls(part_id, pts, thickness, area, centroid, moments, pieces, cut)

    @property
    def perimeter(self) -> float:
        return float(np.sum(np.linalg.norm(np.roll(self.outline, -1, axis=0) - self.outline, axis=1)))

    @property
    def size(self) -> float:
        """Largest in-plane extent of the outline's bounding box (m)."""
        return float(np.max(np.ptp(self.outline, axis=0)))


# --------------------------------------------------------------------------------------------
# STL
# --------------------------------------------------------------------------------------------
def read_stl(path: str | os.PathLike) -> np.ndarray:
    """Triangles (T, 3, 3) float64 from a binary or ASCII STL; FeederError on a bad file."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise FeederError(f"{path}: cannot read ({err.strerror})") from err
    if not data.strip():
        raise FeederError(f"{path}: empty STL file")
    if len(data) >= 84:
        (count,) = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * count:
            if count == 0:
                raise FeederError(f"{path}: STL has no triangles")
            rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
            with np.errstate(invalid="ignore"):  # a signalling NaN warns when cast; _finite refuses it
                tris = np.frombuffer(data, dtype=rec, count=count, offset=84)["v"].astype(np.float64)
            return _finite(tris, path)
    head = data[:512].lstrip().lower()
    if head.startswith(b"solid"):
        return _read_ascii(data, path)
    if len(data) >= 84:
        (count,) = struct.unpack_from("<I", data, 80)
        raise FeederError(
            f"{path}: truncated binary STL ({len(data)} bytes, header announces {count} triangles "
            f"= {84 + 50 * count} bytes)"
        )
    raise FeederError(f"{path}: not an STL file (too short for binary, no 'solid' header)")


def _finite(tris: np.ndarray, path: Path) -> np.ndarray:
    if not np.all(np.isfinite(tris)):
        raise FeederError(f"{path}: STL has NaN or infinite vertex coordinates")
    return tris


def _read_ascii(data: bytes, path: Path) -> np.ndarray:
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError as err:
        raise FeederError(f"{path}: not a valid ASCII STL (non-ASCII bytes)") from err
    tokens = text.split()
    verts: list[list[float]] = []
    n_facets = n_endfacets = 0
    i = 0
    try:
        while i < len(tokens):
            tok = tokens[i].lower()
            if tok == "vertex":
                verts.append([float(tokens[i + 1]), float(tokens[i + 2]), float(tokens[i + 3])])
                i += 4
                continue
            if tok == "facet":
                n_facets += 1
            elif tok == "endfacet":
                n_endfacets += 1
            i += 1
    except (IndexError, ValueError) as err:
        raise FeederError(f"{path}: malformed ASCII STL vertex line") from err
    if n_facets == 0:
        raise FeederError(f"{path}: ASCII STL has no facets")
    if n_facets != n_endfacets or len(verts) != 3 * n_facets or "endsolid" not in text.lower():
        raise FeederError(
            f"{path}: truncated ASCII STL ({n_facets} facets, {n_endfacets} complete, {len(verts)} vertices)"
        )
    return _finite(np.asarray(verts, dtype=np.float64).reshape(-1, 3, 3), path)


def stl_bytes(outline: np.ndarray, thickness: float, name: str = "part", holes=()) -> bytes:
    """Binary STL of the prism ``outline x [0, thickness]`` (outline CCW, metres), less the
    through-holes ``holes`` (polygons inside the outline).

    Caps are the constrained Delaunay triangulation (no new vertices); side walls are two
    triangles per edge, the holes' walls facing into the hole. Normals point outwards; output is
    deterministic.
    """
    outline = clean_outline(outline)
    cut = clean_holes(holes)
    if cut:
        _check_holes(outline, cut, f"part {name}")
    verts = profile_vertices(outline, cut)
    tris: list[np.ndarray] = []
    z0, z1 = 0.0, float(thickness)
    for ia, ib, ic in triangulate(outline, cut):
        a, b, c = verts[ia], verts[ib], verts[ic]
        tris.append(np.array([[*a, z1], [*b, z1], [*c, z1]]))  # top, CCW from above: +z
        tris.append(np.array([[*a, z0], [*c, z0], [*b, z0]]))  # bottom: -z
    for loop in [outline, *[h[::-1] for h in cut]]:  # a hole's boundary runs CW
        n = len(loop)
        for i in range(n):
            p, q = loop[i], loop[(i + 1) % n]
            tris.append(np.array([[*p, z0], [*q, z0], [*q, z1]]))
            tris.append(np.array([[*p, z0], [*q, z1], [*p, z1]]))
    arr = np.asarray(tris, dtype=np.float64)
    normals = np.cross(arr[:, 1] - arr[:, 0], arr[:, 2] - arr[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    rec = np.zeros(len(arr), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = normals
    rec["v"] = arr
    header = f"feeder extruded part {name}".encode("ascii")[:80].ljust(80, b" ")
    return header + struct.pack("<I", len(arr)) + rec.tobytes()


def _profile_from_mesh(tris: np.ndarray, path: Path) -> tuple[np.ndarray, list[np.ndarray], float]:
    """Check the mesh is a closed z-extrusion; return (outer outline in x-y, its holes, thickness)."""
    verts, inv = np.unique(tris.reshape(-1, 3), axis=0, return_inverse=True)
    faces = inv.reshape(-1, 3)
    # watertight and consistently oriented: each directed edge once, its reverse exactly once
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    if np.any(directed[:, 0] == directed[:, 1]):
        raise FeederError(f"{path}: STL has degenerate triangles (repeated vertex)")
    keys = directed[:, 0].astype(np.int64) * len(verts) + directed[:, 1]
    rkeys = directed[:, 1].astype(np.int64) * len(verts) + directed[:, 0]
    uniq, counts = np.unique(keys, return_counts=True)
    if np.any(counts > 1):
        raise FeederError(
            f"{path}: STL is not a valid closed surface (an edge is used twice in "
            f"the same direction: inconsistent orientation or non-manifold)"
        )
    if not np.all(np.isin(rkeys, uniq)):
        open_edges = int(np.sum(~np.isin(rkeys, uniq)))
        raise FeederError(f"{path}: STL is not watertight ({open_edges} open edges)")

    z = verts[:, 2]
    zmin, zmax = float(z.min()), float(z.max())
    size = float(np.max(np.ptp(verts[:, :2], axis=0)))
    if size <= 0:
        raise FeederError(f"{path}: STL has no in-plane extent")
    tol = max(_REL_TOL * size, 1e-7 * max(abs(zmin), abs(zmax), size))
    thickness = zmax - zmin
    if thickness <= tol:
        raise FeederError(f"{path}: STL is flat (no extent along z)")
    at_bottom = np.abs(z - zmin) <= tol
    at_top = np.abs(z - zmax) <= tol
    if not np.all(at_bottom | at_top):
        raise FeederError(f"{path}: not an extrusion along z (vertices between the two z levels)")
    ftop = at_top[faces].all(axis=1)
    fbot = at_bottom[faces].all(axis=1)
    side = ~(ftop | fbot)
    xy = verts[:, :2]
    f_xy = xy[faces]
    cross = (f_xy[:, 1, 0] - f_xy[:, 0, 0]) * (f_xy[:, 2, 1] - f_xy[:, 0, 1]) - (f_xy[:, 1, 1] - f_xy[:, 0, 1]) * (
        f_xy[:, 2, 0] - f_xy[:, 0, 0]
    )
    if np.any(np.abs(cross[side]) > tol * size):
        raise FeederError(f"{path}: not an extrusion along z (a side facet is not vertical)")
    if not ftop.any() or not fbot.any():
        raise FeederError(f"{path}: not an extrusion along z (missing top or bottom face)")

    def boundary(mask: np.ndarray) -> np.ndarray:
        f = faces[mask]
        d = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        k = d[:, 0].astype(np.int64) * len(verts) + d[:, 1]
        rk = d[:, 1].astype(np.int64) * len(verts) + d[:, 0]
        return d[~np.isin(rk, k)]

    top_edges = boundary(ftop)
    # chain the directed boundary edges into loops
    nxt: dict[int, int] = {}
    for a, b in top_edges:
        if int(a) in nxt:
            raise FeederError(f"{path}: top face boundary is not a simple loop")
        nxt[int(a)] = int(b)
    loops: list[list[int]] = []
    remaining = dict(nxt)
    while remaining:
        start = min(remaining)
        loop = [start]
        cur = remaining.pop(start)
        while cur != start:
            if cur not in remaining:
                raise FeederError(f"{path}: top face boundary is not a closed loop")
            loop.append(cur)
            cur = remaining.pop(cur)
        loops.append(loop)
    # one outer loop (the largest) and holes, which a consistently oriented face runs the other way
    areas = [signed_area(xy[loop]) for loop in loops]
    k_outer = int(np.argmax(np.abs(areas)))
    if any(np.sign(a) == np.sign(areas[k_outer]) for k, a in enumerate(areas) if k != k_outer):
        raise FeederError(
            f"{path}: top face has more than one outer boundary loop (several bodies); a part must be one piece"
        )
    outline = xy[loops[k_outer]]
    holes = [xy[loop] for k, loop in enumerate(loops) if k != k_outer]
    bot_edges = boundary(fbot)
    top_set = {tuple(np.round(xy[i], 12)) for loop in loops for i in loop}
    bot_set = {tuple(np.round(xy[i], 12)) for i in np.unique(bot_edges)}
    if top_set != bot_set:
        raise FeederError(f"{path}: not an extrusion along z (top and bottom outlines differ)")
    top_area = 0.5 * float(np.sum(np.abs(cross[ftop])))
    face_area = abs(signed_area(outline)) - sum(abs(signed_area(h)) for h in holes)
    if abs(top_area - face_area) > 1e-6 * top_area:
        raise FeederError(f"{path}: top face overlaps itself")
    _check_simple(outline, f"{path}: top face outline")  # a loop can cross itself with no overlap left
    for h in holes:
        _check_simple(h, f"{path}: a hole of the top face")
    if holes:
        _check_holes(outline, holes, f"{path}: top face")
    return outline, holes, thickness


def read_profile(path: str | os.PathLike) -> tuple[np.ndarray, list[np.ndarray], float]:
    """Outer outline (N, 2), through-holes (each (M, 2)) and thickness of an extruded STL in the
    file's own units (no unit check)."""
    path = Path(path)
    return _profile_from_mesh(read_stl(path), path)


def read_outline(path: str | os.PathLike) -> tuple[np.ndarray, float]:
    """Outer outline (N, 2) and thickness of an extruded STL in the file's own units (no unit
    check): the contour the shape features describe, holes or not (as in the paper)."""
    outline, _, thickness = read_profile(path)
    return outline, thickness


def file_units(size: float, units: str) -> str:
    """The units of a part file whose outline is ``size`` file units across: ``units`` itself
    when it is ``m`` or ``mm``; for ``auto``, millimetres when the part would be wider than
    ``MAX_PART_SIZE_M`` metres (CAD tools export millimetres by default), else metres."""
    if units not in UNIT_CHOICES:
        raise FeederError(f"units must be one of {', '.join(UNIT_CHOICES)}, got {units!r}")
    if units != "auto":
        return units
    return "mm" if size > MAX_PART_SIZE_M else "m"


def load_part(path: str | os.PathLike, units: str = "m") -> PartGeometry:
    """Read ``<id>.stl`` (extruded along z) into a :class:`PartGeometry` in metres.

    ``units``: ``m``, ``mm`` or ``auto`` (:func:`file_units`). The outline is scaled to metres and
    stays in the STL's own x-y frame (no recentring); the thickness is the z extent. A part wider
    than ``MAX_PART_SIZE_M`` once in metres, or any defect, is a one-line FeederError naming the file.
    """
    return load_part_units(path, units)[0]


def load_part_units(path: str | os.PathLike, units: str = "m") -> tuple[PartGeometry, str]:
    """:func:`load_part` and the units the file was read in (what ``auto`` chose)."""
    path = Path(path)
    outline, holes, thickness, unit = _read_in_metres(path, units)
    try:
        return PartGeometry.from_polygon(path.stem, outline, thickness, holes), unit
    except FeederError as err:
        raise FeederError(f"{path}: {err}") from err


def load_outline(path: str | os.PathLike, units: str = "m") -> np.ndarray:
    """The outline of :func:`load_part` (cleaned, CCW, metres, the file's frame), checked to be a
    simple polygon, without the rest of the part (its convex decomposition costs more than
    reading the file): for the symmetry order or a drawing of the part."""
    return load_footprint(path, units)[0]


def load_profile(path: str | os.PathLike, units: str = "m") -> tuple[np.ndarray, list[np.ndarray], float]:
    """(outline, holes, thickness) of :func:`load_part` in metres, cleaned and checked, without the
    convex decomposition: what the symmetry of a part needs."""
    path = Path(path)
    outline, holes, thickness, _ = _read_in_metres(path, units)
    try:
        pts = clean_outline(outline)
        _check_simple(pts, "outline")
        cut = clean_holes(holes)
        if cut:
            _check_holes(pts, cut, "part")
    except FeederError as err:
        raise FeederError(f"{path}: {err}") from err
    return pts, cut, thickness


def load_footprint(path: str | os.PathLike, units: str = "m") -> tuple[np.ndarray, float]:
    """(outline, thickness) of :func:`load_part` in metres, the outline cleaned and checked to be
    simple, without the convex decomposition: what a check of the part against the scene needs."""
    path = Path(path)
    outline, _, thickness, _ = _read_in_metres(path, units)
    try:
        pts = clean_outline(outline)
        _check_simple(pts, "outline")
    except FeederError as err:
        raise FeederError(f"{path}: {err}") from err
    return pts, thickness


def _read_in_metres(path: Path, units: str) -> tuple[np.ndarray, list[np.ndarray], float, str]:
    """(outline, holes, thickness) of an STL scaled to metres, and the units it was read in. A face point
    cloud (``.xyz``) is refused by name: it has no thickness, and read as an STL it would fail with
    a message about STL bytes."""
    if path.suffix.lower() == ".xyz":
        raise FeederError(f"{path}: a face point cloud (.xyz) has no thickness or solid; give the part's .stl")
    outline, holes, thickness = read_profile(path)
    size = float(np.max(np.ptp(outline, axis=0)))
    unit = file_units(size, units)
    scale = UNITS_M[unit]
    if size * scale > MAX_PART_SIZE_M:
        raise FeederError(
            f"{path}: part is {size * scale:g} m across read as {unit}; "
            f"is the file in millimetres? (--units mm, or auto)"
        )
    return outline * scale, [h * scale for h in holes], thickness * scale, unit


# --------------------------------------------------------------------------------------------
# Face point clouds (what a CAD tool's point-cloud export of the planar face looks like)
# --------------------------------------------------------------------------------------------
def face_points(outline: np.ndarray, spacing: float, holes=()) -> np.ndarray:
    """Points on the planar face of ``outline`` less its through-``holes``, at lattice spacing
    ``spacing`` (same units).

    Boundary: every vertex plus evenly spaced points on each edge (at most ``spacing`` apart), of
    the outline and then of each hole. Interior: a triangular lattice anchored at the bounding
    box, keeping the points inside the face (not in a hole) and at least ``spacing / 2`` from
    every edge. Deterministic, (M, 2) float64.
    """
    return _Face(outline, holes).points(float(spacing))


def face_cloud(outline: np.ndarray, n_points: int, holes=()) -> np.ndarray:
    """:func:`face_points` with the spacing chosen (bisection) so that it has about ``n_points``."""
    face = _Face(outline, holes)
    outline = face.outline

    def perimeter(ring: np.ndarray) -> float:
        return float(np.sum(np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1)))

    area = abs(signed_area(outline)) - sum(abs(signed_area(h)) for h in face.holes)
    perim = perimeter(outline) + sum(perimeter(h) for h in face.holes)
    # lattice estimate: n = 2A / (sqrt(3) h^2) + P / h, solved for h
    a_coef = 2.0 * area / np.sqrt(3.0)
    h = (perim + np.sqrt(perim**2 + 4.0 * a_coef * n_points)) / (2.0 * n_points)
    lo_h, hi_h = h / 2.0, h * 2.0
    count = face.count(h)
    for _ in range(24):
        if abs(count - n_points) <= max(5, n_points // 200):
            break
        if count > n_points:
            lo_h = h
        else:
            hi_h = h
        h = float(np.sqrt(lo_h * hi_h))
        count = face.count(h)
    return face.points(h)


# The exact boundary-distance test of the face lattice is run only where a cheap lower bound
# cannot decide it (:meth:`_Face._certainly_far`): the bound comes from a distance transform of
# the boundary drawn on a raster of FAR_RASTER_CELLS_PER_LIMIT cells per distance limit, sampled
# every half cell; FAR_RASTER_SAFETY_CELLS absorbs rounding (float32 distances, pixel lookup),
# and a raster over FAR_RASTER_MAX_CELLS cells is not drawn (every point is measured exactly).
FAR_RASTER_CELLS_PER_LIMIT = 1
FAR_RASTER_SAFETY_CELLS = 0.25
FAR_RASTER_MAX_CELLS = 4_000_000


class _Face:
    """An outline's face lattice (less its holes), set up once for :func:`face_points` at several
    spacings (what :func:`face_cloud`'s bisection needs); the points are those of the
    straightforward per-edge construction, bit for bit. The edges are the outline's, then each
    hole's (``vertices``/``step``: every ring's vertices and edge vectors, one after another)."""

    def __init__(self, outline: np.ndarray, holes=()):
        import shapely

        self.outline = np.asarray(outline, dtype=np.float64)
        self.holes = [np.asarray(h, dtype=np.float64) for h in holes]
        rings = [self.outline, *self.holes]
        self.vertices = np.concatenate(rings)
        self.step = np.concatenate([np.roll(r, -1, axis=0) - r for r in rings])
        # each edge's length exactly as np.linalg.norm(q - p) gives it (spacing-independent)
        self.lengths = np.array([np.linalg.norm(d) for d in self.step])
        self.lo, self.hi = self.outline.min(axis=0), self.outline.max(axis=0)
        self.poly = shapely.Polygon(self.outline, self.holes or None)
        # the edges a lattice point keeps its distance from (the outline's ring alone without holes)
        self.edges = self.poly.boundary if self.holes else self.poly.exterior

    def _per_edge(self, h: float) -> np.ndarray:
        return np.maximum(1, np.ceil(self.lengths / h).astype(np.int64))

    def boundary(self, h: float) -> np.ndarray:
        """Every vertex plus ``m - 1`` evenly spaced points on each edge (``m = ceil(length / h)``)."""
        per_edge = self._per_edge(h)
        first = np.repeat(np.cumsum(per_edge) - per_edge, per_edge)
        t = (np.arange(int(per_edge.sum())) - first) / np.repeat(per_edge, per_edge)
        return np.repeat(self.vertices, per_edge, axis=0) + t[:, None] * np.repeat(self.step, per_edge, axis=0)

    def interior(self, h: float) -> np.ndarray:
        """The triangular lattice points inside the face at least ``h / 2`` from every edge."""
        import shapely

        lo, hi = self.lo, self.hi
        dy = h * np.sqrt(3.0) / 2.0
        ys = lo[1] + dy / 2 + dy * np.arange(int(np.floor((hi[1] - lo[1]) / dy)) + 1)
        xs = lo[0] + h / 4 + h * np.arange(int(np.floor((hi[0] - lo[0]) / h)) + 1)
        gx, gy = np.meshgrid(xs, ys)
        gx = gx + (np.arange(len(ys))[:, None] % 2) * (h / 2)
        grid = np.column_stack([gx.ravel(), gy.ravel()])
        inside = shapely.contains_xy(self.poly, grid[:, 0], grid[:, 1])
        grid = grid[inside]
        limit = h / 2
        far = self._certainly_far(grid, limit)
        unsure = ~far
        far[unsure] = shapely.distance(self.edges, shapely.points(grid[unsure])) >= limit
        return grid[far]

    def points(self, h: float) -> np.ndarray:
        return np.concatenate([self.boundary(h), self.interior(h)])

    def count(self, h: float) -> int:
        """``len(self.points(h))`` without building the boundary points."""
        return int(self._per_edge(h).sum()) + len(self.interior(h))

    def _certainly_far(self, pts: np.ndarray, limit: float) -> np.ndarray:
        """True where a point is certainly farther than ``limit`` from the boundary; False where
        it is not, or where the bound cannot tell (those are measured exactly).

        The bound: the boundary, sampled at most half a cell apart (so every boundary point is
        within a quarter cell of a sample), marks the raster cells of its samples; a point in cell
        C whose centre is D cells from the nearest marked cell's centre (exact Euclidean distance
        transform) is at least ``cell * (D - sqrt(2)) - cell / 4`` from the boundary.
        """
        import cv2

        out = np.zeros(len(pts), dtype=bool)
        cell = limit / FAR_RASTER_CELLS_PER_LIMIT
        origin = self.lo - cell
        shape = np.floor((self.hi - self.lo) / cell).astype(np.int64) + 3  # (x cells, y cells)
        if len(pts) == 0 or not cell > 0 or int(shape[0]) * int(shape[1]) > FAR_RASTER_MAX_CELLS:
            return out
        per_edge = np.maximum(1, np.ceil(self.lengths / (cell / 2)).astype(np.int64)) + 1
        first = np.repeat(np.cumsum(per_edge) - per_edge, per_edge)
        t = (np.arange(int(per_edge.sum())) - first) / np.repeat(per_edge - 1, per_edge)
        samples = np.repeat(self.vertices, per_edge, axis=0) + t[:, None] * np.repeat(self.step, per_edge, axis=0)
        raster = np.full((int(shape[1]), int(shape[0])), 255, dtype=np.uint8)
        cells, on_raster = self._cells(samples, origin, cell, shape)
        if not on_raster.all():  # cannot happen (a cell of margin round the outline): measure all
            return out
        raster[cells[:, 1], cells[:, 0]] = 0
        dist = cv2.distanceTransform(raster, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        cells, on_raster = self._cells(pts, origin, cell, shape)
        bound = FAR_RASTER_CELLS_PER_LIMIT + math.sqrt(2.0) + 0.25 + FAR_RASTER_SAFETY_CELLS
        out[on_raster] = dist[cells[on_raster, 1], cells[on_raster, 0]] > bound
        return out

    @staticmethod
    def _cells(pts: np.ndarray, origin: np.ndarray, cell: float, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raster cell (x, y) of each point and whether it lies on the raster."""
        idx = np.floor((pts - origin) / cell).astype(np.int64)
        return idx, np.all((idx >= 0) & (idx < shape), axis=1)
