import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from feeder.cli import main as cli
from feeder.errors import FeederError
from feeder.parts.geometry import load_part
from feeder.parts.library import (
    LIBRARY_ID_RE,
    diversity_summary,
    family_outline,
    generate,
    list_parts,
    shape_metrics,
)

PARTS = Path("parts")
CATALOG = pd.read_csv(PARTS / "catalog.csv")
SPEC = yaml.safe_load((PARTS / "library.yaml").read_text())


# ---------------------------------------------------------------- list_parts
def test_list_parts_sorted_and_include(tmp_path):
    for name in ["b-2", "a-1", "C3"]:
        (tmp_path / f"{name}.stl").write_bytes(b"x")
    (tmp_path / "a-1.xyz").write_text("")
    (tmp_path / "notes.txt").write_text("")
    assert list_parts(tmp_path) == ["C3", "a-1", "b-2"]
    assert list_parts(tmp_path, ["b-2", "a-1"]) == ["a-1", "b-2"]
    assert list_parts(tmp_path, "b-2") == ["b-2"]
    assert list_parts(tmp_path, exclude=["a-*", "C?"]) == ["b-2"]
    assert list_parts(tmp_path, ["b-2", "a-1"], exclude=["b-2"]) == ["a-1"]
    assert list_parts(tmp_path, exclude=["zz*"]) == ["C3", "a-1", "b-2"]
    with pytest.raises(FeederError, match="no STL.*zz-9"):
        list_parts(tmp_path, ["a-1", "zz-9"])
    with pytest.raises(FeederError, match="does not exist"):
        list_parts(tmp_path / "missing")
    (tmp_path / "bad_name.stl").write_bytes(b"x")
    with pytest.raises(FeederError, match="bad_name"):
        list_parts(tmp_path)


# ---------------------------------------------------------------- shapes and metrics
def test_shape_metrics_of_a_rectangle_by_hand():
    m = shape_metrics(np.array([(0, 0), (4, 0), (4, 1), (0, 1)], float))
    assert m["area"] == pytest.approx(4)
    assert m["perimeter"] == pytest.approx(10)
    assert m["aspect_ratio"] == pytest.approx(4)
    assert m["convexity"] == pytest.approx(1)
    assert m["compactness"] == pytest.approx(4 * math.pi * 4 / 100)
    assert m["eigen_ratio"] == pytest.approx(16)


def test_family_outlines_by_hand():
    hexagon = family_outline("ngon", {"n": 6, "radius": 10}, 64)
    assert shape_metrics(hexagon)["area"] == pytest.approx(1.5 * math.sqrt(3) * 100)
    lsh = family_outline("lshape", {"width": 6, "height": 4, "leg_x": 1, "leg_y": 2}, 64)
    assert shape_metrics(lsh)["area"] == pytest.approx(6 * 1 + 2 * 3)
    ib = family_outline("ibeam", {"width": 5, "height": 6, "flange": 1, "web": 1}, 64)
    assert shape_metrics(ib)["area"] == pytest.approx(2 * 5 + 4 * 1)
    # Z: two flanges (w + t)/2 x f and the web t x (h - 2f); hat: two brims b x t, two walls t x h
    # and the crown (w - 2b - 2t) x t
    zs = family_outline("zshape", {"width": 8, "height": 10, "flange": 2, "web": 2}, 64)
    assert shape_metrics(zs)["area"] == pytest.approx(2 * 5 * 2 + 2 * 6)
    assert shape_metrics(zs)["convexity"] < 1
    hat = family_outline("hat", {"width": 20, "height": 6, "wall": 1, "brim": 3}, 64)
    assert shape_metrics(hat)["area"] == pytest.approx(2 * 3 * 1 + 2 * 1 * 6 + 12 * 1)
    np.testing.assert_allclose(np.ptp(hat, axis=0), [20, 6])
    with pytest.raises(FeederError, match="zshape needs"):
        family_outline("zshape", {"width": 8, "height": 4, "flange": 2, "web": 2}, 64)
    with pytest.raises(FeederError, match="hat needs"):
        family_outline("hat", {"width": 8, "height": 6, "wall": 1, "brim": 3}, 64)
    star = family_outline("star", {"points": 5, "outer": 2, "inner": 1}, 64)
    assert len(star) == 10
    # crescent: disc minus lens; analytic area of the bite (circle-circle intersection)
    big, r, d = 30.0, 24.0, 14.0
    cres = family_outline("crescent", {"radius": big, "inner_radius": r, "offset": d}, 4096)
    lens = (
        r * r * math.acos((d * d + r * r - big * big) / (2 * d * r))
        + big * big * math.acos((d * d + big * big - r * r) / (2 * d * big))
        - 0.5 * math.sqrt((-d + r + big) * (d + r - big) * (d - r + big) * (d + r + big))
    )
    assert shape_metrics(cres)["area"] == pytest.approx(math.pi * big * big - lens, rel=1e-4)
    # rotation keeps the shape, the bounding box stays at the origin
    rot = family_outline("rect", {"width": 10, "height": 2, "rotation_deg": 90}, 64)
    np.testing.assert_allclose(rot.min(axis=0), [0, 0], atol=1e-12)
    np.testing.assert_allclose(np.ptp(rot, axis=0), [2, 10])
    with pytest.raises(FeederError, match="unknown part family"):
        family_outline("torus", {}, 64)
    with pytest.raises(FeederError, match="missing parameter"):
        family_outline("rect", {"width": 1}, 64)


# ---------------------------------------------------------------- the committed library
def test_library_meets_the_diversity_targets():
    s = diversity_summary(CATALOG)
    assert s["parts"] >= 120  # the wider library of #20 (59 protocol parts + 62 wide)
    assert s["highly_concave(convexity<0.75)"] >= 8
    assert s["elongated(aspect_ratio>=4)"] >= 8
    assert s["near_symmetric(eigen_ratio<1.05)"] >= 4
    fams = set(CATALOG["family"])
    for fam in [
        "ngon",
        "triangle",
        "rect",
        "rrect",
        "ellipse",
        "ibeam",
        "lshape",
        "tshape",
        "ushape",
        "crescent",
        "star",
        "gear",
        "keyhole",
        "blob",
        "randpoly",
        "randblob",
        "zshape",
        "hat",
    ]:
        assert fam in fams
    assert list(CATALOG["id"]) == list_parts(PARTS)
    assert all(LIBRARY_ID_RE.match(i) for i in CATALOG["id"])


def test_library_files_meet_the_format():
    for row in CATALOG.itertuples():
        assert 0.005 <= row.thickness <= 0.015
        assert 0.020 <= row.size <= 0.120
        json.loads(row.params)
        pts = np.loadtxt(PARTS / f"{row.id}.xyz")
        assert pts.shape[1] == 3 and 1400 <= len(pts) <= 8200
        assert len(pts) == row.n_points
        assert np.ptp(pts[:, 2]) == 0 and pts[0, 2] == pytest.approx(row.thickness * 1000)
        assert 20 <= np.max(np.ptp(pts[:, :2], axis=0)) <= 120  # millimetres


def test_catalog_agrees_with_the_stl_within_one_percent():
    for row in CATALOG.itertuples():
        g = load_part(PARTS / f"{row.id}.stl")
        m = shape_metrics(g.outline, g.holes)
        for key in ["area", "perimeter", "aspect_ratio", "convexity", "compactness", "eigen_ratio"]:
            assert m[key] == pytest.approx(getattr(row, key), rel=0.01), (row.id, key)
        assert g.area == pytest.approx(row.area, rel=0.01)
        assert g.thickness == pytest.approx(row.thickness, rel=0.01)
        assert g.size == pytest.approx(row.size, rel=0.01)


def test_generator_reproduces_the_committed_library_byte_for_byte(tmp_path):
    ids = generate(PARTS / "library.yaml", tmp_path, progress=False)
    assert sorted(ids) == list(CATALOG["id"])
    for name in sorted(p.name for p in tmp_path.iterdir()):
        assert (tmp_path / name).read_bytes() == (PARTS / name).read_bytes(), name


def _mini_spec(tmp_path, parts):
    spec = {k: v for k, v in SPEC.items() if k != "parts"}
    spec["parts"] = parts
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_generate_cli_twice_is_identical(tmp_path, capsys):
    spec = _mini_spec(
        tmp_path,
        [
            {"id": "sq-1", "family": "rect", "thickness_mm": 6, "params": {"width": 30, "height": 30}},
            {"id": "st-1", "family": "star", "thickness_mm": 9, "params": {"points": 4, "outer": 20, "inner": 8}},
        ],
    )
    for out in ["a", "b"]:
        assert cli(["parts", "generate", "--spec", str(spec), "--out", str(tmp_path / out)]) == 0
    summary = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert summary["generated"] == 2
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == ["catalog.csv", "sq-1.stl", "sq-1.xyz", "st-1.stl", "st-1.xyz"]
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


_RANDPOLY = {"n": 9, "radius": 30, "irregularity": 0.4, "spikiness": 0.25, "seed": 3}
_RANDBLOB = {"radius": 28, "harmonics": 3, "max_order": 7, "amplitude": 0.45, "seed": 5}


def _holed(*holes) -> dict:
    """A 60 x 30 x 8 mm plate with ``holes``, as a library entry."""
    params = {"width": 60, "height": 30, "holes": list(holes)}
    return {"id": "plate-h", "family": "rect", "thickness_mm": 8, "params": params}


def test_shape_metrics_with_holes_by_hand():
    square = np.array([(0, 0), (4, 0), (4, 2), (0, 2)], float)
    hole = np.array([(1, 0.5), (2, 0.5), (2, 1.5), (1, 1.5)], float)
    m = shape_metrics(square, [hole])
    assert m["area"] == pytest.approx(8 - 1) and m["perimeter"] == pytest.approx(12 + 4)
    assert m["convexity"] == pytest.approx(7 / 8)
    assert m["compactness"] == pytest.approx(4 * math.pi * 7 / 16**2)
    assert shape_metrics(square, []) == shape_metrics(square)  # no holes: the metrics as before


@pytest.mark.parametrize("family, params", [("randpoly", _RANDPOLY), ("randblob", _RANDBLOB)])
def test_random_families_are_seeded_simple_and_differ_by_seed(family, params):
    import shapely

    a = family_outline(family, params, 64)
    np.testing.assert_array_equal(a, family_outline(family, params, 64))
    assert shapely.Polygon(a).is_valid and a.min() == 0.0
    b = family_outline(family, params | {"seed": params["seed"] + 1}, 64)
    assert a.shape != b.shape or not np.allclose(a, b)
    if family == "randpoly":
        assert len(a) == params["n"]
        r = np.linalg.norm(a - a.mean(axis=0), axis=1)
        assert r.max() / r.min() > 1.2  # irregular, not a regular polygon


def test_a_library_part_with_holes_has_them_in_its_stl_face_cloud_and_catalog(tmp_path):
    import shapely

    entry = _holed({"circle": [15, 15, 6]}, {"rect": [45, 15, 10, 8]})
    spec = _mini_spec(tmp_path, [entry])
    assert generate(spec, tmp_path / "out", progress=False) == ["plate-h"]
    geom = load_part(tmp_path / "out" / "plate-h.stl")
    assert len(geom.holes) == 2
    assert len(geom.holes[0]) == SPEC["hole_segments"] and len(geom.holes[1]) == 4
    circle_area = 0.5 * SPEC["hole_segments"] * 6**2 * math.sin(2 * math.pi / SPEC["hole_segments"])
    want_area = (60 * 30 - circle_area - 10 * 8) * 1e-6
    row = pd.read_csv(tmp_path / "out" / "catalog.csv").iloc[0]
    assert row["area"] == pytest.approx(want_area, rel=1e-9)
    assert json.loads(row["params"])["holes"] == entry["params"]["holes"]
    cloud = np.loadtxt(tmp_path / "out" / "plate-h.xyz")[:, :2]
    rings = [shapely.Polygon(h * 1000.0) for h in geom.holes]
    for ring in rings:  # no point inside a hole (but for the 4-decimal rounding), and points along its edge
        assert not shapely.contains_xy(ring.buffer(-1e-3), cloud[:, 0], cloud[:, 1]).any()
        assert (shapely.distance(ring.exterior, shapely.points(cloud)) < 1e-6).sum() >= 4
    # the face cloud's density is that of the face, holes left out
    assert len(cloud) == pytest.approx(SPEC["cloud"]["points_per_cm2"] * want_area * 1e4, rel=0.05)


@pytest.mark.parametrize(
    "entry,msg",
    [
        ({"id": "bad_id", "family": "rect", "thickness_mm": 6, "params": {"width": 30, "height": 30}}, "lowercase"),
        ({"id": "big", "family": "rect", "thickness_mm": 6, "params": {"width": 300, "height": 30}}, "size"),
        ({"id": "thin", "family": "rect", "thickness_mm": 2, "params": {"width": 30, "height": 30}}, "thickness"),
        (
            {"id": "blobby", "family": "blob", "thickness_mm": 6, "params": {"radius": 20, "harmonics": [[2, 1.2, 0]]}},
            "vanish",
        ),
        (_holed({"circle": [55, 15, 10]}), "not inside the outline and apart"),  # pokes out of the 60 x 30 plate
        (_holed({"circle": [15, 15, 5]}, {"circle": [22, 15, 5]}), "not inside the outline and apart"),
        (_holed({"circle": [15, 15, 14]}), "limits.min_wall_mm"),  # 1 mm of wall
        (_holed({"square": [15, 15, 5]}), "hole 1 must be one of"),
        (_holed({"rect": [15, 15, 5]}), "rect takes 4 numbers"),
        (_holed({"circle": [15, 15, -5]}), "sizes positive"),
        ({"id": "rp", "family": "randpoly", "thickness_mm": 6, "params": _RANDPOLY | {"n": 2}}, "randpoly needs"),
    ],
)
def test_bad_spec_entries_fail_before_writing(tmp_path, capsys, entry, msg):
    spec = _mini_spec(tmp_path, [entry])
    out = tmp_path / "out"
    assert cli(["parts", "generate", "--spec", str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_xyz_subcommand_derives_a_face_cloud(tmp_path):
    out = tmp_path / "d.xyz"
    assert cli(["parts", "xyz", str(PARTS / "lshape-a.stl"), "--out", str(out), "--points", "2000"]) == 0
    pts = np.loadtxt(out)
    assert abs(len(pts) - 2000) <= 20
    assert np.ptp(pts[:, 2]) == 0
