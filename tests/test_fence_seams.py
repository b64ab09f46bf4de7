"""scene.fences.curved.build: a curved fence as boxes (the default: one per chord) or as one convex
piece, the hull of its outer face, which has no seam between boxes for a sharp part to catch on
(docs/simulation.md, "The seams between a fence's boxes catch sharp parts")."""

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.config import check_study_config
from feeder.errors import FeederError
from feeder.lane import geometry as lane_geometry
from feeder.lane.fences import Fence, parse_location
from feeder.parts.geometry import load_part
from feeder.sim import drops as sim

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
STUDY = CFG["scene"]
PRESET = CFG["sim"]["presets"][CFG["sim"]["preset"]]


def _with_build(build):
    scene = copy.deepcopy(STUDY)
    scene["fences"]["curved"].pop("build", None)
    if build is not None:
        scene["fences"]["curved"]["build"] = build
    return scene


def test_a_curved_fence_is_boxes_unless_the_scene_says_hull():
    assert lane_geometry.curved_build(_with_build(None)) == "boxes"  # absent: the study's build
    assert lane_geometry.curved_build(_with_build("hull")) == "hull"
    with pytest.raises(FeederError, match=r"scene\.fences\.curved\.build must be one of boxes, hull, got 'mesh'"):
        lane_geometry.curved_build(_with_build("mesh"))


def test_the_schema_takes_the_build_and_refuses_another():
    cfg = copy.deepcopy(CFG)
    cfg["scene"]["fences"]["curved"]["build"] = "hull"
    assert check_study_config(cfg)["scene"]["fences"]["curved"]["build"] == "hull"
    cfg["scene"]["fences"]["curved"]["build"] = "mesh"
    with pytest.raises(FeederError, match="build"):
        check_study_config(cfg)


def test_the_outer_points_are_the_boxes_outer_chords():
    """The hull is built on the same outer face as the boxes: each box's outer chord runs between
    two consecutive outer points (hand check of the shared construction)."""
    fence = Fence("curved", 40.0)
    pts, centre = lane_geometry.curved_outer_points(STUDY, "loc2", fence)
    geom = lane_geometry.fence_geometry(STUDY, "loc2", fence)
    assert len(pts) == len(geom.boxes) + 1 == STUDY["fences"]["curved"]["segments"] + 1
    ro = STUDY["fences"]["curved"]["radius"] + 0.5 * STUDY["fences"]["thickness"]
    np.testing.assert_allclose(np.hypot(*(pts - centre).T), ro, rtol=1e-12)
    for (a, b), box in zip(zip(pts[:-1], pts[1:], strict=True), geom.boxes, strict=True):
        corners = lane_geometry.box_corners(*box)
        near = [np.min(np.hypot(*(corners - p).T)) for p in (a, b)]
        assert max(near) < 1e-12  # both chord ends are corners of this box


def test_a_hull_built_world_holds_one_convex_piece_per_curved_fence():
    """Bodies in a lane with a straight fence at Location 1 and a curved one at Location 2: the boxes
    build holds the curved fence's 16 boxes in one compound; the hull build holds, in its place,
    one convex piece spanning its outer points (the straight fence's box and the tips as before)."""
    import pybullet as pb

    from feeder.sim.body import World

    loc1, loc2 = parse_location("straight:30"), parse_location("curved:40")
    geom = load_part(ROOT / "parts" / "rect-a3.stl")
    pts, _ = lane_geometry.curved_outer_points(STUDY, "loc2", loc2)
    shapes, spans = {}, {}
    for build in ("boxes", "hull"):
        scene = _with_build(build)
        setup = sim.prepare_drops(geom, loc1, loc2, scene, PRESET)
        world = World(scene, PRESET, setup.plan, 1, setup.model)
        try:
            n = pb.getNumBodies(physicsClientId=world.cid)
            bodies = [pb.getBodyUniqueId(i, physicsClientId=world.cid) for i in range(n)]
            shapes[build] = [[d[2] for d in pb.getCollisionShapeData(b, -1, physicsClientId=world.cid)] for b in bodies]
            spans[build] = [np.subtract(*pb.getAABB(b, physicsClientId=world.cid)[::-1])[:2] for b in bodies]
        finally:
            world.close()
    assert [s.count(pb.GEOM_BOX) for s in shapes["boxes"]].count(16) == 1  # the curved fence's compound
    assert [s.count(pb.GEOM_BOX) for s in shapes["hull"]].count(16) == 0
    assert len(shapes["hull"]) == len(shapes["boxes"])  # one body for one: the compound became the hull
    piece = [
        span
        for s, span in zip(shapes["hull"], spans["hull"], strict=True)
        if s == [pb.GEOM_MESH] and np.allclose(span, np.ptp(pts, axis=0), atol=5e-3)  # Bullet's AABB margin
    ]
    assert len(piece) == 1  # the convex piece spans the fence's outer face


@pytest.mark.slow
def test_a_star_catches_on_the_seams_of_the_boxes_and_not_on_the_hull():
    """star4-a on none_curved40 in the study's scene and preset, from four of the study's own
    initial yaws of that configuration (its adaptive design's drops 16-19, all jammed in the study's
    simulation file): with the study's 16 boxes it jams on a seam (pybullet's main contact force
    sits at a chord joint); as one convex piece it slides along the face and leaves ok. The face
    is the same, only its seams differ: a decomposition test (docs/simulation.md)."""
    yaws = np.array([28.06395098, 30.87645098, 33.68895098, 36.50145098])
    geom = load_part(ROOT / "parts" / "star4-a.stl")
    loc1, loc2 = parse_location("none"), parse_location("curved:40")
    boxes = sim.run_drops(geom, loc1, loc2, yaws, _with_build("boxes"), PRESET)
    hull = sim.run_drops(geom, loc1, loc2, yaws, _with_build("hull"), PRESET)
    assert (boxes["status"] == "jammed").sum() >= 3
    assert (hull["status"] == "ok").all()
