"""The part meets walls and fences through its outline slabs (issue #37): pure geometry and settings."""

from __future__ import annotations

import copy
import math

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
_PHI = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False) + 0.01
GON64 = 0.02 * np.stack([np.cos(_PHI), np.sin(_PHI)], axis=1)


def _convex(p: np.ndarray) -> bool:
    poly = Polygon(p)
    return abs(poly.convex_hull.area - poly.area) <= 1e-12 * max(poly.area, 1e-30)


def test_a_rectangle_by_hand():
    """Slab per edge (max turn 0): a trapezoid, its inner corners ``depth`` in along the 45 degree
    bisectors, i.e. h = 2 / sqrt 2 mm deep: (L - h) h mm². With 90 degrees a slab takes two edges."""
    h = 2.0 / math.sqrt(2.0)
    slabs = outline_slabs(RECT, 0.002, 0.0)
    areas = sorted(Polygon(s).area * 1e6 for s in slabs)
    assert areas == pytest.approx(sorted([(20 - h) * h] * 2 + [(40 - h) * h] * 2), rel=1e-9)
    assert all(_convex(s) for s in slabs)
    assert len(outline_slabs(RECT, 0.002, 90.0)) == 2  # two corners of 90 degrees each take one slab
    assert len(outline_slabs(RECT, 0.002, 89.0)) == 4


def test_slabs_stay_inside_past_a_sharp_corner_and_cover_the_rim():
    for outline in (NEEDLE, ELL, RECT[::-1], GON64):  # clockwise input too
        poly = Polygon(outline)
        for turn in (0.0, 45.0, 90.0, 170.0):
            slabs = outline_slabs(outline, 0.002, turn)
            assert all(_convex(s) and poly.buffer(1e-12).contains(Polygon(s)) for s in slabs)
            union = unary_union([Polygon(s) for s in slabs])
            assert union.buffer(1e-12).contains(poly.exterior)  # every point of the outline is in some slab


def test_a_chain_turns_at_most_max_turn_and_a_reflex_corner_ends_it():
    """A 64-gon turns 5.625 degrees a corner: 90 degrees take 16 edges, so 4 slabs; 45 take 8. The
    L's reflex corner ends a chain: at 90 degrees its 6 edges make 4 slabs, not 3."""
    assert len(outline_slabs(GON64, 0.002, 90.0)) == 4
    assert len(outline_slabs(GON64, 0.002, 45.0)) == 8
    assert len(outline_slabs(GON64, 0.002, 0.0)) == 64
    assert len(outline_slabs(ELL, 0.002, 0.0)) == 6
    assert len(outline_slabs(ELL, 0.002, 90.0)) == 4


def test_a_part_thinner_than_the_depth_gets_shallower_slabs():
    """A 1 mm bar: 2 mm along the bisector leaves it, 1 mm does not, so the long edges' slabs are
    (50 - h) h mm² with h = 1 / sqrt 2 mm."""
    bar = np.array([[0.0, 0.0], [0.05, 0.0], [0.05, 0.001], [0.0, 0.001]])
    slabs = outline_slabs(bar, 0.002, 0.0)
    assert len(slabs) == 4
    assert all(Polygon(bar).buffer(1e-12).contains(Polygon(s)) for s in slabs)
    h = 1.0 / math.sqrt(2.0)
    assert max(Polygon(s).area for s in slabs) * 1e6 == pytest.approx((50 - h) * h, rel=1e-9)


def test_outline_slabs_refuse_a_broken_outline():
    with pytest.raises(FeederError, match="simple polygon"):
        outline_slabs(np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]), 0.002, 0.0)  # a bow tie
    with pytest.raises(FeederError, match="simple polygon"):
        outline_slabs(np.array([[0.0, 0.0], [1.0, 0.0]]), 0.002, 0.0)
    with pytest.raises(FeederError, match="max_turn_deg"):
        outline_slabs(RECT, 0.002, 180.0)


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
    wc = {"model": "outline", "depth": 0.003, "max_turn_deg": 45}
    assert wall_contact_setting(_scene(None)) == ("pieces", 0.0, 0.0)
    assert wall_contact_setting(_scene(wc)) == ("outline", 0.003, 45.0)
    rows = {r[0]: r for r in table1_rows(_scene(wc), {})}
    assert rows["Wall and fence contact"][1] == "outline slabs, 0.003 m deep, 45 deg a slab"
    for bad in (
        {"model": "hull", "depth": 0.002, "max_turn_deg": 45},
        {"model": "outline", "depth": 0, "max_turn_deg": 45},
        {"model": "outline", "max_turn_deg": 45},
        {"model": "outline", "depth": 0.002, "max_turn_deg": 180},
        {"model": "outline", "depth": 0.002},
    ):
        with pytest.raises(FeederError, match="wall_contact"):
            wall_contact_setting(_scene(bad))
    with pytest.raises(FeederError, match="footprint pads"):  # the slabs would carry the weight on the rim
        wall_contact_setting(_scene(dict(wc, depth=0.002), footprint="pieces"))


def test_the_part_model_uses_the_slabs_only_when_asked():
    from feeder.parts.geometry import load_part
    from feeder.sim.body import part_model

    geom = load_part("parts/lshape-a.stl")
    pieces = part_model(geom, _scene({"model": "pieces", "depth": 0.002, "max_turn_deg": 0}))
    outline = part_model(geom, _scene({"model": "outline", "depth": 0.002, "max_turn_deg": 0}))
    assert pieces.slabs is None and pieces.shell is pieces.pieces
    assert outline.shell is outline.slabs and len(outline.slabs) == len(geom.outline)
    assert (outline.mass, outline.inertia) == (pieces.mass, pieces.inertia)  # the body is the same part


def test_contact_model_names():
    scene = _scene({"model": "pieces", "depth": 0.002, "max_turn_deg": 90})
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
