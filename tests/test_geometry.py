import math
import struct

import numpy as np
import pytest
import shapely

from feeder.errors import FeederError
from feeder.parts import geometry as G
from feeder.parts.geometry import (
    PartGeometry,
    clean_outline,
    convex_decomposition,
    face_cloud,
    is_convex,
    load_part,
    polygon_moments,
    signed_area,
    stl_bytes,
)

L_SHAPE = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]


def test_rectangle_moments_by_hand():
    w, h = 0.04, 0.02
    g = PartGeometry.from_polygon("r", [(0, 0), (w, 0), (w, h), (0, h)], 0.01)
    assert g.area == pytest.approx(w * h)
    np.testing.assert_allclose(g.centroid, [w / 2, h / 2])
    ixx, iyy, ixy = g.second_moment
    assert ixx == pytest.approx(w * h**3 / 12)
    assert iyy == pytest.approx(h * w**3 / 12)
    assert abs(ixy) < 1e-20
    assert len(g.convex_pieces) == 1
    assert g.perimeter == pytest.approx(2 * (w + h))


def test_right_triangle_and_l_shape_moments_by_hand():
    a, b = 3.0, 2.0
    area, c, (ixx, iyy, ixy) = polygon_moments(np.array([(0, 0), (a, 0), (0, b)]))
    assert area == pytest.approx(a * b / 2)
    np.testing.assert_allclose(c, [a / 3, b / 3])
    assert ixx == pytest.approx(a * b**3 / 36)
    assert iyy == pytest.approx(b * a**3 / 36)
    assert ixy == pytest.approx(-(a**2) * b**2 / 72)
    # L = rect [0,2]x[0,1] + rect [0,1]x[1,2]; centroid (5/6, 5/6), parallel-axis sums
    area, c, (ixx, iyy, ixy) = polygon_moments(np.array(L_SHAPE, float))
    assert area == pytest.approx(3.0)
    np.testing.assert_allclose(c, [5 / 6, 5 / 6])
    assert ixx == pytest.approx(2 / 12 + 2 * (1 / 3) ** 2 + 1 / 12 + (2 / 3) ** 2)
    assert iyy == pytest.approx(ixx)
    assert ixy == pytest.approx(2 * (1 / 6) * (-1 / 3) + (-1 / 3) * (2 / 3))


def test_outline_is_cleaned_ccw_without_duplicates():
    cw_closed = [(0, 0), (0, 1), (1, 1), (1, 0.5), (1, 0), (0, 0)]  # CW, closing dup, collinear
    out = clean_outline(cw_closed)
    assert len(out) == 4
    assert signed_area(out) == pytest.approx(1.0)
    g = PartGeometry.from_polygon("sq", cw_closed, 0.005)
    assert g.outline.shape == (4, 2)
    with pytest.raises(ValueError):
        g.outline[0, 0] = 5.0  # frozen arrays


@pytest.mark.parametrize(
    "outline,msg",
    [
        ([(0, 0), (1, 1), (1, 0), (0, 1)], "not a simple polygon"),
        ([(0, 0), (1, 0)], "fewer than 3"),
        ([(0, 0), (1, 0), (2, 0)], "fewer than 3"),
        ([(0, 0), (1, np.nan), (0, 1)], "NaN"),
    ],
)
def test_bad_polygons(outline, msg):
    with pytest.raises(FeederError, match=msg):
        PartGeometry.from_polygon("bad", outline, 0.01)


def _star(n, ro, ri, phase=0.0):
    t = phase + np.pi * np.arange(2 * n) / n
    r = np.where(np.arange(2 * n) % 2 == 0, ro, ri)
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


@pytest.mark.parametrize(
    "outline",
    [
        np.array(L_SHAPE, float),
        _star(5, 3.0, 1.0),
        _star(12, 2.0, 1.6, 0.3),
        # comb: many reflex vertices
        np.array(
            [
                (0, 0),
                (7, 0),
                (7, 3),
                (6, 3),
                (6, 1),
                (5, 1),
                (5, 3),
                (4, 3),
                (4, 1),
                (3, 1),
                (3, 3),
                (2, 3),
                (2, 1),
                (1, 1),
                (1, 3),
                (0, 3),
            ],
            float,
        ),
    ],
)
def test_convex_decomposition_is_exact(outline):
    pieces = convex_decomposition(clean_outline(outline))
    total = shapely.Polygon(outline)
    assert all(is_convex(p) and signed_area(p) > 0 for p in pieces)
    assert sum(signed_area(p) for p in pieces) == pytest.approx(total.area, rel=1e-12)
    union = shapely.union_all([shapely.Polygon(p) for p in pieces])
    assert union.symmetric_difference(total).area < 1e-9 * total.area
    # only the outline's own vertices are used
    verts = {tuple(v) for v in outline}
    assert all(tuple(v) in verts for p in pieces for v in p)


def test_stl_round_trip_recovers_outline(tmp_path):
    outline = np.array(L_SHAPE, float) * 0.02 + [0.003, -0.01]
    path = tmp_path / "ell.stl"
    path.write_bytes(stl_bytes(outline, 0.008, "ell"))
    g = load_part(path)
    assert g.part_id == "ell"
    assert g.thickness == pytest.approx(0.008, rel=1e-6)
    assert len(g.outline) == 6
    # same vertex set, same frame (float32 precision of binary STL)
    d = np.linalg.norm(g.outline[:, None, :] - outline[None, :, :], axis=2)
    assert d.min(axis=1).max() < 1e-8
    assert g.area == pytest.approx(3 * 0.02**2, rel=1e-6)
    assert len(g.convex_pieces) == 2


def _ascii_stl(tris) -> str:
    lines = ["solid box"]
    for t in tris:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in t]
        lines += ["    endloop", "  endfacet"]
    return "\n".join(lines + ["endsolid box"]) + "\n"


def _binary_tris(data: bytes) -> np.ndarray:
    (n,) = struct.unpack_from("<I", data, 80)
    rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    return np.frombuffer(data, rec, count=n, offset=84)["v"].astype(float)


def test_ascii_stl_is_read(tmp_path):
    tris = _binary_tris(stl_bytes(np.array([(0, 0), (0.03, 0), (0.03, 0.02), (0, 0.02)]), 0.005))
    path = tmp_path / "box.stl"
    path.write_text(_ascii_stl(tris))
    g = load_part(path)
    assert g.area == pytest.approx(0.0006, rel=1e-6)


def _write_bad(tmp_path, kind):
    good = stl_bytes(np.array(L_SHAPE, float) * 0.02, 0.01)
    path = tmp_path / f"{kind}.stl"
    tris = _binary_tris(good)
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        path.write_bytes(good[:-30])
    elif kind == "truncated-ascii":
        path.write_text(_ascii_stl(tris)[:-200])
    elif kind == "open":
        path.write_text(_ascii_stl(tris[:-1]))
    elif kind == "midplane":
        t = tris.copy()
        v = t[0, 0].copy()
        same = np.all(t == v, axis=2)
        t[same, 2] = 0.004  # one vertex (everywhere it is used) moved to a third z level
        path.write_text(_ascii_stl(t))
    elif kind == "slanted":
        t = tris.copy()
        top = t[:, :, 2] > 0.005
        t[top, 0] += 0.003  # shear: top face shifted in x
        path.write_text(_ascii_stl(t))
    elif kind == "two-bodies":  # two separate squares in one file
        a = stl_bytes(np.array([(0, 0), (0.01, 0), (0.01, 0.01), (0, 0.01)], float), 0.005)
        b = stl_bytes(np.array([(0.02, 0), (0.03, 0), (0.03, 0.01), (0.02, 0.01)], float), 0.005)
        count = struct.unpack("<I", a[80:84])[0] + struct.unpack("<I", b[80:84])[0]
        path.write_bytes(a[:80] + struct.pack("<I", count) + a[84:] + b[84:])
    elif kind == "ring":  # square with a square hole, its STL built by hand
        outer = shapely.Polygon(
            [(0, 0), (0.04, 0), (0.04, 0.04), (0, 0.04)], [[(0.01, 0.01), (0.01, 0.03), (0.03, 0.03), (0.03, 0.01)]]
        )
        caps = shapely.constrained_delaunay_triangles(outer)
        out = []
        for tri in shapely.get_parts(caps):
            c = np.asarray(tri.exterior.coords)[:3]
            if signed_area(c) < 0:
                c = c[::-1]
            out.append([[*c[0], 0.01], [*c[1], 0.01], [*c[2], 0.01]])
            out.append([[*c[0], 0.0], [*c[2], 0.0], [*c[1], 0.0]])
        for ring, sign in [
            (np.asarray(outer.exterior.coords)[:-1], 1),
            (np.asarray(outer.interiors[0].coords)[:-1], -1),
        ]:
            if signed_area(ring) * sign < 0:
                ring = ring[::-1]
            for p, q in zip(ring, np.roll(ring, -1, axis=0)):
                out.append([[*p, 0], [*q, 0], [*q, 0.01]])
                out.append([[*p, 0], [*q, 0.01], [*p, 0.01]])
        path.write_text(_ascii_stl(out))
    elif kind == "millimetres":
        path.write_bytes(stl_bytes(np.array(L_SHAPE, float) * 20.0, 10.0))
    elif kind == "garbage":
        path.write_bytes(b"\x00\x01hello")
    return path


@pytest.mark.parametrize(
    "kind,msg",
    [
        ("empty", "empty"),
        ("truncated", "truncated binary STL"),
        ("truncated-ascii", "truncated ASCII STL"),
        ("open", "not watertight"),
        ("midplane", "not an extrusion along z"),
        ("slanted", "not an extrusion along z"),
        ("two-bodies", "more than one outer boundary loop"),
        ("garbage", "not an STL"),
        ("millimetres", "is the file in millimetres"),
    ],
)
def test_bad_stl_is_one_line_error_naming_the_file(tmp_path, kind, msg):
    path = _write_bad(tmp_path, kind)
    with pytest.raises(FeederError) as err:
        load_part(path)
    text = str(err.value)
    assert msg in text and str(path) in text and "\n" not in text


def test_face_cloud_hits_target_and_lies_in_face():
    outline = clean_outline(_star(5, 30.0, 12.0))
    pts = face_cloud(outline, 3000)
    assert abs(len(pts) - 3000) <= 30
    poly = shapely.Polygon(outline)
    assert np.all(shapely.distance(poly, shapely.points(pts)) < 1e-9)
    # boundary is covered: every vertex is a point
    assert all(np.min(np.linalg.norm(pts - v, axis=1)) == 0 for v in outline)
    # deterministic
    np.testing.assert_array_equal(pts, face_cloud(outline, 3000))


def test_library_parts_load_with_exact_decomposition():
    from pathlib import Path

    paths = sorted(Path("parts").glob("*.stl"))
    assert paths
    for path in paths:
        g = load_part(path)
        assert all(is_convex(p) for p in g.convex_pieces)
        assert sum(signed_area(p) for p in g.convex_pieces) == pytest.approx(g.area, rel=1e-9)
        ev = np.linalg.eigvalsh([[g.second_moment[0], g.second_moment[2]], [g.second_moment[2], g.second_moment[1]]])
        assert ev.min() > 0 and math.isfinite(ev.max())


def test_load_outline_is_load_parts_outline(tmp_path):
    from pathlib import Path

    from feeder.parts.geometry import load_outline

    parts = Path(__file__).resolve().parents[1] / "parts"
    for name in ("rect-a2", "crescent-a", "lshape-a"):
        want = load_part(parts / f"{name}.stl", "auto").outline
        assert load_outline(parts / f"{name}.stl", "auto").tobytes() == want.tobytes()
    mm = tmp_path / "mm.stl"
    mm.write_bytes(stl_bytes(np.array(L_SHAPE, dtype=float) * 20.0, 5.0))  # millimetres
    assert load_outline(mm, "auto").tobytes() == load_part(mm, "auto").outline.tobytes()
    with pytest.raises(FeederError, match="millimetres"):
        load_outline(mm, "m")
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid x\nendsolid x\n")
    with pytest.raises(FeederError, match="broken.stl"):
        load_outline(broken)


# ------------------------------------------------------------------------------------------
# through-holes
# ------------------------------------------------------------------------------------------
def test_a_hand_built_ring_loads_with_the_hole_taken_out(tmp_path):
    """A 40 mm square with a 20 mm square hole in the middle, its STL written by hand (not by
    stl_bytes): area 40² - 20², centroid at the middle, Ixx = Iyy = (40⁴ - 20⁴) / 12 (mm⁴)."""
    g = load_part(_write_bad(tmp_path, "ring"))
    assert len(g.holes) == 1 and g.outline.shape == (4, 2)
    assert g.area == pytest.approx(0.04**2 - 0.02**2, rel=1e-6)
    np.testing.assert_allclose(g.centroid, [0.02, 0.02], atol=1e-9)
    ixx, iyy, ixy = g.second_moment
    assert ixx == pytest.approx((0.04**4 - 0.02**4) / 12, rel=1e-5) and iyy == pytest.approx(ixx, rel=1e-9)
    assert abs(ixy) < 1e-15
    _assert_pieces_tile(g)


def test_an_off_centre_hole_moves_the_centroid_by_hand(tmp_path):
    """40 x 20 mm with a 10 x 10 mm hole centred at (15, 10): x̄ = (800·20 − 100·15) / 700 mm, and
    Iyy by the parallel-axis theorem."""
    hole = np.array([(0.01, 0.005), (0.02, 0.005), (0.02, 0.015), (0.01, 0.015)])
    g = PartGeometry.from_polygon("plate", [(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], 0.005, [hole])
    xbar = (800 * 20 - 100 * 15) / 700 / 1000
    assert g.area == pytest.approx(0.0007) and g.centroid == pytest.approx([xbar, 0.01])
    iyy = (0.02 * 0.04**3 / 12 + 0.0008 * (0.02 - xbar) ** 2) - (0.01**4 / 12 + 0.0001 * (0.015 - xbar) ** 2)
    assert g.second_moment[1] == pytest.approx(iyy, rel=1e-9)
    assert g.second_moment[0] == pytest.approx(0.04 * 0.02**3 / 12 - 0.01**4 / 12, rel=1e-9)
    _assert_pieces_tile(g)
    # the same through an STL: read back, the outline is the outer contour and the hole is kept
    path = tmp_path / "plate.stl"
    path.write_bytes(stl_bytes(g.outline, 0.005, "plate", holes=g.holes))
    back = load_part(path)
    assert back.area == pytest.approx(g.area, rel=1e-6) and back.centroid == pytest.approx(g.centroid, abs=1e-8)
    assert len(back.holes) == 1 and len(back.outline) == 4
    from feeder.parts.geometry import read_outline

    outer, thickness = read_outline(path)  # the contour the shape features use (as in the paper)
    assert shapely.Polygon(outer).area == pytest.approx(0.0008, rel=1e-6) and thickness == pytest.approx(0.005)


def _assert_pieces_tile(g):
    """The convex pieces are convex, cover the part's area exactly and none reaches into a hole."""
    pieces = [shapely.Polygon(p) for p in g.convex_pieces]
    assert all(is_convex(p) for p in g.convex_pieces)
    assert sum(p.area for p in pieces) == pytest.approx(g.area, rel=1e-9)
    region = shapely.Polygon(g.outline, [np.asarray(h) for h in g.holes])
    assert shapely.union_all(pieces).symmetric_difference(region).area < 1e-9 * g.area


@pytest.mark.parametrize(
    "outline, holes, msg",
    [
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (5, 1), (5, 3), (1, 3)]], "holes"),  # sticks out
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (2, 2), (1, 2)], [(1.5, 1.5), (3, 1.5), (3, 3)]], "holes"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(0, 2), (2, 1), (3, 2), (2, 3)]], "holes"),  # a corner on the edge
    ],
    ids=["hole-outside", "holes-overlap", "hole-touches-outline"],
)
def test_bad_holes_are_refused_when_building_or_writing(outline, holes, msg):
    with pytest.raises(FeederError, match=msg):
        PartGeometry.from_polygon("bad", outline, 0.01, holes)
    with pytest.raises(FeederError, match=msg):
        stl_bytes(np.array(outline, float), 0.01, holes=[np.array(h, float) for h in holes])


def test_a_part_without_holes_is_built_as_before():
    g = PartGeometry.from_polygon("l", L_SHAPE, 0.01)
    area, centroid, moments = polygon_moments(clean_outline(np.array(L_SHAPE, float)))
    assert g.holes == () and g.area == area and np.array_equal(g.centroid, centroid) and g.second_moment == moments
    assert [p.tolist() for p in g.convex_pieces] == [p.tolist() for p in convex_decomposition(g.outline)]


def test_holes_that_touch_each_other_are_refused_by_name():
    outline = np.array([(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], float)
    left = np.array([(0.01, 0.01), (0.005, 0.015), (0.005, 0.005)])
    right = np.array([(0.01, 0.01), (0.015, 0.005), (0.015, 0.015)])  # shares the vertex (0.01, 0.01)
    with pytest.raises(FeederError, match="holes 1 and 2 touch or overlap"):
        G.PartGeometry.from_polygon("x", outline, 0.003, [left, right])
    with pytest.raises(FeederError, match="^hole 2 has fewer than 3 distinct"):
        G.PartGeometry.from_polygon("x", outline, 0.003, [left, np.array([(0.02, 0.01), (0.02, 0.01), (0.03, 0.01)])])


@pytest.mark.parametrize("radius", [1e-6, 3e-6, 1e-4])
def test_a_tiny_hole_still_gives_convex_pieces_that_tile_the_region(radius):
    """The convexity test judges the turn, not the cross product against the longest edge, so a
    hole whose edges are a millionth of the part's size does not make a reflex piece look convex."""
    import shapely

    t = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    hole = np.column_stack([0.01 + radius * np.cos(t), 0.01 + radius * np.sin(t)])
    outline = np.array([(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], float)
    g = G.PartGeometry.from_polygon("x", outline, 0.003, [hole])
    pieces = [shapely.Polygon(p) for p in g.convex_pieces]
    assert all(p.is_valid and p.convex_hull.area - p.area <= 1e-9 * p.area for p in pieces)
    region = shapely.Polygon(outline, [hole])
    assert shapely.union_all(pieces).symmetric_difference(region).area <= 1e-12 * region.area
    assert sum(p.area for p in pieces) == pytest.approx(region.area, rel=1e-12)


def test_is_convex_judges_the_turn_whatever_the_edge_lengths():
    # a dent of 1e-12 between two edges 1e-6 long in the top of the unit square: a reflex turn of
    # 2e-6 rad, whose cross product (2e-18) an edge of 1 used to hide
    dent = np.array([(0, 0), (1, 0), (1, 1), (0.5 + 1e-6, 1), (0.5, 1 - 1e-12), (0.5 - 1e-6, 1), (0, 1)], float)
    assert G.signed_area(dent) > 0 and not G.is_convex(dent)
    assert G.is_convex(np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.5, 1.0), (0.0, 1.0)]))  # collinear: allowed


def test_thinnest_wall_is_the_least_material_around_a_hole_by_hand():
    outline = np.array([(0, 0), (0.04, 0), (0.04, 0.02), (0, 0.02)], float)
    square = lambda a, b, c, d: np.array([(a, b), (c, b), (c, d), (a, d)], float)  # noqa: E731
    assert G.thinnest_wall(outline, []) == np.inf
    assert G.thinnest_wall(outline, [square(0.005, 0.003, 0.01, 0.01)]) == pytest.approx(0.003)  # to y = 0
    # two holes 2 mm apart, each at least 5 mm from the outline
    assert G.thinnest_wall(outline, [square(0.005, 0.005, 0.01, 0.01), square(0.012, 0.005, 0.02, 0.01)]) == (
        pytest.approx(0.002)
    )


def _clean_outline_by_rescans(outline, rel_tol=G._REL_TOL):
    """The reference of clean_outline: after every removal the whole polygon is tested again
    (quadratic; the rule as first written). clean_outline must give its result to the bit."""
    pts = np.asarray(outline, dtype=np.float64)
    tol = rel_tol * float(np.max(np.ptp(pts, axis=0)))
    changed = True
    while changed and len(pts) >= 3:
        changed = False
        nxt = np.roll(pts, -1, axis=0)
        keep = np.linalg.norm(nxt - pts, axis=1) > tol
        if not keep.all():
            pts = pts[keep]
            changed = True
            continue
        prv = np.roll(pts, 1, axis=0)
        nxt = np.roll(pts, -1, axis=0)
        d1, d2 = pts - prv, nxt - pts
        cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
        chord = np.linalg.norm(nxt - prv, axis=1)
        dev = np.abs(cross) / np.maximum(chord, tol)
        straight = (dev <= tol) & (np.sum(d1 * d2, axis=1) > 0)
        if straight.any():
            pts = np.delete(pts, int(np.flatnonzero(straight)[0]), axis=0)
            changed = True
    if len(pts) < 3:
        raise FeederError("fewer than 3 distinct non-collinear vertices")
    return pts if G.signed_area(pts) >= 0 else pts[::-1].copy()


def _outlines_to_clean():
    rng = np.random.default_rng(20261128)
    t = np.linspace(0.0, 2 * np.pi, 3001)[:-1]
    yield "fine circle (every vertex within tolerance of its chord)", 0.02 * np.column_stack([np.cos(t), np.sin(t)])
    yield "fine circle, clockwise", 0.02 * np.column_stack([np.cos(t), -np.sin(t)])
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    dense = np.vstack([np.linspace(a, b, 40, endpoint=False) for a, b in zip(square, np.roll(square, -1, 0))])
    for shift in (0, 1, 39, 40, 159):  # collinear runs across the wrap at 0/360 of the index
        yield f"square with collinear runs, rolled {shift}", np.roll(dense, shift, axis=0)
    yield "closing duplicate", np.vstack([square, square[:1]])
    yield "repeated vertices", np.repeat(square, 3, axis=0)
    near = dense.copy()
    near[1::2] += rng.normal(scale=1e-7, size=near[1::2].shape)  # within and beyond the tolerance
    yield "noisy collinear runs", near
    for k in range(40):  # random walks: repeated, collinear and nearly collinear vertices at random
        n = int(rng.integers(3, 60))
        pts = np.cumsum(rng.choice([-1.0, 0.0, 1.0], size=(n, 2)) * rng.choice([1e-7, 1e-3, 1.0], size=(n, 1)), axis=0)
        yield f"random walk {k}", pts
    yield "all on one line", np.column_stack([np.linspace(0, 1, 7), np.zeros(7)])


@pytest.mark.parametrize("name, outline", list(_outlines_to_clean()), ids=lambda v: v if isinstance(v, str) else "")
def test_clean_outline_equals_the_rescanning_rule_to_the_bit(name, outline):
    try:
        want = _clean_outline_by_rescans(outline)
    except FeederError:
        with pytest.raises(FeederError):
            G.clean_outline(outline)
        return
    got = G.clean_outline(outline)
    assert got.dtype == np.float64 and got.shape == want.shape
    assert got.tobytes() == want.tobytes()


def test_clean_outline_of_a_finely_faceted_part_is_linear_not_quadratic():
    """A CAD export of a round part: 16,000 facets, each within the tolerance of its chord, most
    removed one by one. Counted, not timed: every vertex test and every removal takes one square
    root, and they stay within a few per vertex (a rescan after each removal tested each vertex
    again: about 16,000 x 15,000)."""
    import unittest.mock as mock

    t = np.linspace(0.0, 2 * np.pi, 16001)[:-1]
    circle = 0.02 * np.column_stack([np.cos(t), np.sin(t)])
    with mock.patch.object(G.math, "sqrt", wraps=math.sqrt) as sqrt:
        out = G.clean_outline(circle)
    assert 100 < len(out) < len(circle) // 4  # most facets were within the tolerance
    assert sqrt.call_count <= 4 * len(circle)
