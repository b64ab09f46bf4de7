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


def test_a_curved_hull_needs_two_chords():
    scene = _with_build("hull")
    scene["fences"]["curved"]["segments"] = 1
    with pytest.raises(FeederError, match="hull needs segments >= 2"):
        lane_geometry.curved_build(scene)


@pytest.mark.parametrize(
    "loc1, loc2, mirror",
    [("straight:30", "curved:40", False), ("curved:90", "curved:0", False), ("curved:40", "none", True)],
)
def test_a_hull_built_fence_has_the_boxes_face_in_every_lane(loc1, loc2, mirror):
    """A small sphere 5 mm outside the middle of each chord of each curved fence, in both lanes of
    a two-lane world, is as far from the hull-built fence as from the boxes (the collision margin
    inset, the lane offsets, either side, the mirror). At `curved:90 | curved:0` the upstream fence is
    trimmed to its gap: the hull loses the same chords, so a sphere off the first removed chord is
    as far from it as from the trimmed boxes. The boxes build holds the curved fence's boxes in
    compounds, the hull build one convex piece in their place."""
    import pybullet as pb

    from feeder.sim.body import World

    geom = load_part(ROOT / "parts" / "rect-a3.stl")
    a, b = parse_location(loc1), parse_location(loc2)
    found = {}
    for build in ("boxes", "hull"):
        scene = _with_build(build)
        scene["mirror"] = mirror
        setup = sim.prepare_drops(geom, a, b, scene, PRESET)
        world = World(scene, PRESET, setup.plan, 2, setup.model)
        try:
            ids = [
                pb.getBodyUniqueId(i, physicsClientId=world.cid)
                for i in range(pb.getNumBodies(physicsClientId=world.cid))
            ]
            kinds = [[d[2] for d in pb.getCollisionShapeData(i, -1, physicsClientId=world.cid)] for i in ids]
            sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.001, physicsClientId=world.cid)
            distances = []
            for f in [g for g in setup.plan.fences if g.fence.type == "curved"]:
                pts, centre = lane_geometry.curved_outer_points(scene, f.location, f.fence)
                for k in range(min(len(f.boxes) + 1, len(pts) - 1)):  # and the first trimmed chord
                    mid = 0.5 * (pts[k] + pts[k + 1])
                    p = mid + 0.005 * (mid - centre) / np.hypot(*(mid - centre))
                    for x0 in world.lane_x:
                        probe = pb.createMultiBody(
                            0, sphere, basePosition=[x0 + p[0], p[1], 0.02], physicsClientId=world.cid
                        )
                        near = [
                            c[8] for i in ids for c in pb.getClosestPoints(probe, i, 0.05, physicsClientId=world.cid)
                        ]
                        distances.append(min(near, default=0.05))
                        pb.removeBody(probe, physicsClientId=world.cid)
            found[build] = (kinds, np.array(distances))
        finally:
            world.close()
    np.testing.assert_allclose(found["hull"][1], found["boxes"][1], atol=5e-5)
    assert (found["boxes"][1] < 0.0045).any()  # the spheres do sit by a face
    pieces = 2 * sum(t.startswith("curved") for t in (loc1, loc2))  # per lane, per curved fence
    assert sum(k.count(pb.GEOM_BOX) >= 8 for k in found["boxes"][0]) == pieces  # a compound of chords
    assert sum(k.count(pb.GEOM_BOX) >= 8 for k in found["hull"][0]) == 0
    assert sum(k == [pb.GEOM_MESH] for k in found["hull"][0]) == pieces


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
    # it met the fence: turned to the exit the ok drops of the study's file reach (153.8° modulo 90°)
    gap = np.abs(np.mod(hull["final_yaw_deg"] - 63.8 + 45.0, 90.0) - 45.0)
    assert (gap < 3.0).all()
