"""scene.fences.tip: a square box end (the default) or a round one, a cylinder of the fence's half
thickness capping its free end (docs/simulation.md, "A square fence tip")."""

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.errors import FeederError
from feeder.lane import geometry as lane_geometry
from feeder.lane.fences import Fence, parse_location
from feeder.mechanics.distribution import fence_response
from feeder.mechanics.fence import fence_models, fence_mu
from feeder.mechanics.hull import as_geometry
from feeder.parts.geometry import load_part
from feeder.sim import body as simbody
from feeder.sim import drops as sim

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
STUDY = CFG["scene"]
SCENE = copy.deepcopy(STUDY)  # the study's scene with a square tip, whichever tip the study has
SCENE["fences"].pop("tip", None)
PRESET = CFG["sim"]["presets"][CFG["sim"]["preset"]]


def _with_tip(tip):
    scene = copy.deepcopy(SCENE)
    if tip is not None:
        scene["fences"]["tip"] = tip
    return scene


def test_the_tip_is_square_unless_the_scene_says_round():
    assert lane_geometry.fence_tip(SCENE) == "square"  # absent
    assert lane_geometry.fence_tip(STUDY) == STUDY["fences"].get("tip", "square")
    assert lane_geometry.fence_tip(_with_tip("round")) == "round"
    with pytest.raises(FeederError, match=r"scene\.fences\.tip must be one of square, round, got 'pointy'"):
        lane_geometry.fence_tip(_with_tip("pointy"))


def test_a_round_tip_caps_the_end_of_the_centre_line_hand_values():
    square = lane_geometry.fence_geometry(SCENE, "loc1", Fence("straight", 30.0))
    rounded = lane_geometry.fence_geometry(_with_tip("round"), "loc1", Fence("straight", 30.0))
    assert rounded.boxes == square.boxes and square.tip_cap() is None
    x, y, r = rounded.tip_cap()
    # the centre line ends 0.06 past the belt's centre, 0.30 / tan 30° downstream of the slot
    assert (x, y) == pytest.approx((-0.06, 1.0 + 0.30 / math.tan(math.radians(30.0))))
    assert r == pytest.approx(0.5 * SCENE["fences"]["thickness"])
    # half the disc lies inside the box: the footprint grows by half a disc (16 segments a quarter)
    grown = rounded.footprint().area - square.footprint().area
    assert grown == pytest.approx(0.5 * math.pi * r**2, rel=1e-2)
    curved = lane_geometry.fence_geometry(_with_tip("round"), "loc2", Fence("curved", 40.0))
    cx, cy, hl, ht, yaw = curved.boxes[-1]  # a curved fence is capped at its last box, the tip
    assert curved.tip_cap() == pytest.approx((cx + hl * math.cos(yaw), cy + hl * math.sin(yaw), ht))


def test_trimming_keeps_a_round_tip_and_its_gap():
    scene = _with_tip("round")
    gap = scene["fences"]["min_gap"]
    up, down = lane_geometry.scene_fences(scene, Fence("straight", 30.0), Fence("straight", 15.0))
    assert up.round_tip and down.round_tip
    assert gap <= up.footprint().distance(down.footprint()) < gap + 1e-3
    square_up, _ = lane_geometry.scene_fences(SCENE, Fence("straight", 30.0), Fence("straight", 15.0))
    assert up.boxes[0][2] < square_up.boxes[0][2]  # the cap reaches further: trimmed a little more


def _bodies(scene):
    model = simbody.part_model(load_part(ROOT / "parts" / "rect-a3.stl"), scene)
    plan = sim.make_plan(scene, parse_location("straight:60"), parse_location("none"), model, False)
    world = simbody.World(scene, PRESET, plan, 1, model)
    try:
        pb, c = world.pb, world.cid
        ids = [pb.getBodyUniqueId(i, physicsClientId=c) for i in range(pb.getNumBodies(physicsClientId=c))]
        return plan, [pb.getBasePositionAndOrientation(b, physicsClientId=c)[0] for b in ids]
    finally:
        world.close()


def test_the_world_builds_the_cap_where_the_geometry_puts_it():
    _, square = _bodies(SCENE)
    plan, rounded = _bodies(_with_tip("round"))
    assert len(rounded) == len(square) + 1
    x, y, _ = plan.fences[0].tip_cap()
    fh, clearance = SCENE["fences"]["height"], SCENE["fences"]["clearance"]
    assert rounded[-1] == pytest.approx((x, y, clearance + 0.5 * fh))


def test_a_round_tip_pushes_with_the_edge_normal_where_a_square_one_pushes_with_the_face():
    """rect-a3 (3:1) on a 60° fence, one drop: past the tip a square box end keeps pushing with the
    face's normal and turns the part some 38° further than the quasi-static exit turn, which pushes
    with the edge's normal; a round tip ends within a few degrees of it, and within 1.5° of the exit turn
    around the cap (docs/simulation.md)."""
    part = load_part(ROOT / "parts" / "rect-a3.stl")
    geom = as_geometry(part)
    model = fence_models("straight:60", "none", SCENE)[0]
    exits = fence_response(geom, model, fence_mu(SCENE)).exit_deg  # the two long edges, 180° apart
    preset = dict(PRESET) | {"skip_slides": True}
    ends, finals = {}, {}
    for tip in ("square", "round"):
        out = sim.run_drops(
            part, parse_location("straight:60"), parse_location("none"), np.array([141.1]), _with_tip(tip), preset
        )
        assert out["status"][0] == "ok"
        finals[tip] = float(out["final_yaw_deg"][0])
        ends[tip] = float(np.min(np.abs((finals[tip] - exits + 90.0) % 180.0 - 90.0)))
    assert ends["round"] < 5.0
    assert ends["square"] > 20.0
    # the analytic model of the cap (the outline grown by its radius, pushed by its centre) is closer
    capped = fence_models("straight:60", "none", _with_tip("round"))[0]
    discs = fence_response(geom, capped, fence_mu(SCENE)).exit_deg
    gap = float(np.min(np.abs((finals["round"] - discs + 90.0) % 180.0 - 90.0)))
    assert gap < 1.5 < ends["round"]
