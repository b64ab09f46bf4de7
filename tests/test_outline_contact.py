"""The part meets walls and fences through its outline slabs (issue #37): pure geometry and settings."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from shapely.geometry import Polygon
from shapely.ops import unary_union

from feeder.bench import decomposition as D
from feeder.bench.decomposition_table import pad_ladders
from feeder.errors import FeederError
from feeder.sim.body import outline_slabs
from feeder.sim.scene import table1_rows, wall_contact_setting

RECT = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.02], [0.0, 0.02]])
ELL = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.01], [0.01, 0.01], [0.01, 0.03], [0.0, 0.03]])
NEEDLE = np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.01]])  # an 11.3 degree tip


def _convex(p: np.ndarray) -> bool:
    poly = Polygon(p)
    return abs(poly.convex_hull.area - poly.area) <= 1e-12 * max(poly.area, 1e-30)


def test_a_rectangle_gets_one_band_per_edge_by_hand():
    """40 x 20 mm, 2 mm deep: two 40 x 2 and two 20 x 2 bands (square corners cut nothing)."""
    slabs = outline_slabs(RECT, 0.002)
    areas = sorted(round(Polygon(s).area * 1e6, 9) for s in slabs)
    assert areas == [40.0, 40.0, 80.0, 80.0]
    assert all(_convex(s) for s in slabs)


def test_slabs_stay_inside_past_a_sharp_corner_and_cover_the_rim():
    for outline in (NEEDLE, ELL, RECT[::-1]):  # clockwise input too
        poly = Polygon(outline)
        slabs = outline_slabs(outline, 0.002)
        assert len(slabs) == len(outline)
        assert all(_convex(s) and poly.buffer(1e-12).contains(Polygon(s)) for s in slabs)
        union = unary_union([Polygon(s) for s in slabs])
        assert union.buffer(1e-12).contains(poly.exterior)  # every point of the outline is in some slab


def test_the_l_band_misses_only_the_square_inside_its_reflex_corner():
    """The band of width d along an L is the L minus its inset; the slabs leave out only the d x d
    square beyond the reflex corner (no wall can reach it): 264 - 4 = 260 mm²."""
    union = unary_union([Polygon(s) for s in outline_slabs(ELL, 0.002)])
    assert union.area * 1e6 == pytest.approx(260.0, abs=1e-6)


def test_a_part_thinner_than_the_depth_gets_shallower_slabs():
    bar = np.array([[0.0, 0.0], [0.05, 0.0], [0.05, 0.001], [0.0, 0.001]])  # 1 mm thick
    slabs = outline_slabs(bar, 0.002)
    assert len(slabs) == 4
    assert all(Polygon(bar).buffer(1e-12).contains(Polygon(s)) for s in slabs)
    long_edge = max(slabs, key=lambda s: Polygon(s).area)
    assert Polygon(long_edge).area == pytest.approx(0.05 * 0.001)  # halved once, to the whole thickness


def test_outline_slabs_refuse_a_broken_outline():
    with pytest.raises(FeederError, match="simple polygon"):
        outline_slabs(np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]), 0.002)  # a bow tie
    with pytest.raises(FeederError, match="simple polygon"):
        outline_slabs(np.array([[0.0, 0.0], [1.0, 0.0]]), 0.002)


def _scene(wall_contact, footprint="pads"):
    from feeder.config import load_study_config

    scene = copy.deepcopy(load_study_config("config/config.yaml")["scene"])
    scene["belt"]["footprint"]["model"] = footprint
    if wall_contact is None:
        scene["part"].pop("wall_contact", None)
    else:
        scene["part"]["wall_contact"] = wall_contact
    return scene


def test_wall_contact_setting_and_its_table1_row():
    assert wall_contact_setting(_scene(None)) == ("pieces", 0.0)
    assert wall_contact_setting(_scene({"model": "outline", "depth": 0.003})) == ("outline", 0.003)
    rows = {r[0]: r for r in table1_rows(_scene({"model": "outline", "depth": 0.003}), {})}
    assert rows["Wall and fence contact"][1] == "outline slabs, 0.003 m deep"
    for bad in ({"model": "hull", "depth": 0.002}, {"model": "outline", "depth": 0}, {"model": "outline"}):
        with pytest.raises(FeederError, match="wall_contact"):
            wall_contact_setting(_scene(bad))
    with pytest.raises(FeederError, match="footprint pads"):  # the slabs would carry the weight on the rim
        wall_contact_setting(_scene({"model": "outline", "depth": 0.002}, footprint="pieces"))


def test_the_part_model_uses_the_slabs_only_when_asked():
    from feeder.parts.geometry import load_part
    from feeder.sim.body import part_model

    geom = load_part("parts/lshape-a.stl")
    pieces = part_model(geom, _scene({"model": "pieces", "depth": 0.002}))
    outline = part_model(geom, _scene({"model": "outline", "depth": 0.002}))
    assert pieces.slabs is None and pieces.shell is pieces.pieces
    assert outline.shell is outline.slabs and len(outline.slabs) >= len(geom.outline) - 2
    assert (outline.mass, outline.inertia) == (pieces.mass, pieces.inertia)  # the body is the same part


def test_contact_model_names():
    scene = _scene({"model": "pieces", "depth": 0.002})
    out = D.model_scene(scene, "pads16+outline")
    assert out["belt"]["footprint"]["pads"] == 16 and out["part"]["wall_contact"]["model"] == "outline"
    assert D.model_scene(scene, "pieces")["part"]["wall_contact"]["model"] == "pieces"
    for bad in ("pads", "pads16+hull", "outline", "pads0"):
        with pytest.raises(FeederError, match="contact model"):
            D.model_scene(scene, bad)
    assert pad_ladders(["pieces", "pads16+outline", "pads8", "pads8+outline", "pads32"]) == [
        ["pads8", "pads32"],
        ["pads8+outline", "pads16+outline"],
    ]
