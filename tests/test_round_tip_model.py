"""The analytic model of a round fence tip: the part's outline grown by the cap's radius
(feeder.mechanics.hull.dilate), pushed by the cap's centre in the exit turn
(feeder.mechanics.distribution.fence_response; docs/structured.md, "A round tip in the analytic model")."""

import copy
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feeder.errors import FeederError
from feeder.lane import geometry as lane_geometry
from feeder.lane.fences import Fence
from feeder.mechanics.distribution import fence_response
from feeder.mechanics.fence import fence_models, fence_mu
from feeder.mechanics.hull import as_geometry, dilate, push_geometry

ROOT = Path(__file__).resolve().parents[1]
STUDY = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["scene"]
SCENE = copy.deepcopy(STUDY)  # the study's scene with a square tip, whichever tip the study has
SCENE["fences"].pop("tip", None)
ROUND = copy.deepcopy(SCENE)
ROUND["fences"]["tip"] = "round"
MU = fence_mu(SCENE)


def _rect(w, h):
    return np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])


def test_growing_a_rectangle_keeps_its_edges_and_adds_the_radius_to_every_height():
    geom = push_geometry(_rect(0.06, 0.02))
    grown = dilate(geom, 0.005, 8)
    for k, normal in enumerate(geom.normals_deg):
        j = int(np.argmin(np.abs((grown.normals_deg - normal + 180.0) % 360.0 - 180.0)))
        assert grown.normals_deg[j] == pytest.approx(normal, abs=1e-9)
        assert grown.lengths[j] == pytest.approx(geom.lengths[k], abs=1e-12)
        assert grown.heights[j] == pytest.approx(geom.heights[k] + 0.005, abs=1e-12)
    # four quarter discs of 8 chords each: the area of the grown polygon, by hand
    chords = 0.5 * 32 * 0.005**2 * math.sin(2.0 * math.pi / 32)
    grown_area = float(
        0.5
        * abs(
            np.sum(
                grown.outline[:, 0] * np.roll(grown.outline[:, 1], -1)
                - np.roll(grown.outline[:, 0], -1) * grown.outline[:, 1]
            )
        )
    )
    assert grown_area == pytest.approx(0.06 * 0.02 + 2 * 0.005 * (0.06 + 0.02) + chords, rel=1e-12)
    # the part itself is unchanged: centroid, area, limit surface
    assert grown.area == geom.area and grown.limit_radius == geom.limit_radius
    np.testing.assert_array_equal(grown.centroid, geom.centroid)
    assert dilate(geom, 0.0, 8) is geom


def test_a_slot_narrower_than_the_disc_fills_in_and_a_wide_one_stays():
    def u_shape(slot):  # 60 x 40 mm, a 20 mm deep slot of width `slot` in the middle of the top
        a, b = 0.03 - slot / 2, 0.03 + slot / 2
        return np.array([[0, 0], [0.06, 0], [0.06, 0.04], [b, 0.04], [b, 0.02], [a, 0.02], [a, 0.04], [0, 0.04]])

    def floor(slot):  # lowest point of the grown outline over the slot (part file frame)
        geom = push_geometry(u_shape(slot))
        pts = dilate(geom, 0.005, 8).outline + geom.centroid
        return float(np.min(pts[np.abs(pts[:, 0] - 0.03) < slot / 2, 1]))

    # 8 mm < 10 mm: the disc cannot enter; two arcs of 5 mm about the slot's top corners meet
    # sqrt(5² - 4²) = 3 mm above the top
    assert floor(0.008) == pytest.approx(0.04 + 0.003, abs=1e-4)
    assert floor(0.016) == pytest.approx(0.02 + 0.005, abs=1e-12)  # 16 mm: the disc reaches the floor


def test_a_bridge_over_a_notch_survives_growing_with_its_normal_and_length():
    """The hull edge across a V notch is no outline edge, nor in line with one: the discs at its
    two ends must carry a vertex at its normal (here 100°, off the 11.25° grid of 8 chords a
    quarter) for it to lie exactly ``r`` further out."""
    u = np.array([[0, 0], [0.06, 0], [0.06, 0.04], [0.03, 0.02], [0, 0.04]])
    turn = math.radians(10.0)
    geom = push_geometry(u @ np.array([[math.cos(turn), math.sin(turn)], [-math.sin(turn), math.cos(turn)]]))
    grown = dilate(geom, 0.005, 8)
    assert len(grown.hull) >= len(geom.hull)
    assert int((~grown.convex).sum()) == 1  # the notch's own corner, no false one beside its edges
    for k, normal in enumerate(geom.normals_deg):
        gap = np.abs((grown.normals_deg - normal + 180.0) % 360.0 - 180.0)
        j = int(np.argmin(gap))
        assert gap[j] < 1e-9 and grown.lengths[j] == pytest.approx(geom.lengths[k], abs=1e-12)
        # exactly r further out (a disc polygon without that vertex falls short by r (1 - cos 1.25°))
        assert grown.heights[j] == pytest.approx(geom.heights[k] + 0.005, abs=1e-12)


@pytest.mark.parametrize("part", ["keyhole-a", "star5-a", "gear8-a", "randpoly-01", "blob-a", "crescent-a"])
def test_growing_a_library_part_adds_no_concave_corner(part):
    """Off-grid edge normals (star arms, gear teeth, notch walls) once left the corners of the
    edges' rectangles poking past the disc polygon: tiny false notches that stopped the exit turn."""
    from feeder.parts.geometry import load_part

    geom = as_geometry(load_part(ROOT / "parts" / f"{part}.stl"))
    grown = dilate(geom, 0.005, 16)
    assert int((~grown.convex).sum()) <= int((~geom.convex).sum())


@pytest.mark.parametrize("radius, segs", [(-0.001, 8), (float("nan"), 8), (0.005, 0)])
def test_a_bad_radius_or_resolution_is_a_feeder_error(radius, segs):
    with pytest.raises(FeederError):
        dilate(push_geometry(_rect(0.06, 0.02)), radius, segs)


def test_fence_models_carry_the_cap_of_a_round_tip_only():
    square = fence_models("straight:30", "curved:40", SCENE)
    rounded = fence_models("straight:30", "curved:40", ROUND)
    assert all(m.cap is None and m.cap_radius == 0.0 for m in square)
    for m, fg in zip(rounded, lane_geometry.scene_fences(ROUND, Fence("straight", 30.0), Fence("curved", 40.0))):
        x, y, r = fg.tip_cap()
        assert m.cap == pytest.approx((x, y)) and m.cap_radius == pytest.approx(0.5 * SCENE["fences"]["thickness"])
        # everything else is the square tip's model
        assert dataclasses.replace(m, cap=None, cap_radius=0.0) in square


def test_a_vanishing_cap_is_the_corner_model_moved_to_the_cap_centre():
    geom = as_geometry(push_geometry(_rect(0.06, 0.02)))
    corner = fence_models("straight:30", "none", SCENE)[0]
    cap = fence_models("straight:30", "none", ROUND)[0]
    tiny = dataclasses.replace(cap, cap_radius=1e-9)
    a, b = fence_response(geom, corner, MU), fence_response(geom, tiny, MU)
    np.testing.assert_allclose(b.exit_deg, a.exit_deg, atol=1e-4)
    shift = np.subtract(cap.cap, corner.tip)  # the face line runs through the cap's centre
    np.testing.assert_allclose(b.exit_offset, a.exit_offset + shift, atol=1e-6)
    assert b.exit_reason == a.exit_reason and len(a.exit_reason) == len(a.push.edges)


def test_the_cap_changes_only_the_exit_turn():
    geom = as_geometry(push_geometry(_rect(0.06, 0.02)))
    corner = fence_models("straight:55", "none", SCENE)[0]
    cap = fence_models("straight:55", "none", ROUND)[0]
    a, b = fence_response(geom, corner, MU), fence_response(geom, cap, MU)
    np.testing.assert_array_equal(b.push.edges, a.push.edges)
    np.testing.assert_array_equal(b.rest_deg, a.rest_deg)
    assert np.max(np.abs((b.exit_deg - a.exit_deg + 180.0) % 360.0 - 180.0)) > 0.1  # the disc turns it otherwise
    # without exit turns the cap plays no part
    c, d = fence_response(geom, corner, MU, exit_turns=False), fence_response(geom, cap, MU, exit_turns=False)
    np.testing.assert_array_equal(c.exit_deg, d.exit_deg)
    np.testing.assert_array_equal(c.exit_offset, d.exit_offset)


GOLDEN = ROOT / "tests" / "data" / "analytic_square_golden.json"
PINNED = (
    ("rect-a3", "straight:55", "none"),
    ("keyhole-a", "curved:40", "straight:30"),
    ("star5-a", "none", "curved:80"),
)
PMF_ATOL = 1e-3  # elsewhere: a drop sample's basin may flip (1/7200 of the mass, smoothed)
EXIT_ATOL_DEG = 1e-6


def _square_values(parts_dir: Path = ROOT / "parts") -> dict:
    """What a square tip gives: per pinned configuration, each fence's exit yaws and offsets and
    the analytic PMF. Recorded with the code before the cap existed (a5a48c7), under the hard jam
    rule, the unscaled turn budget and the exit chord's basins of that code (``jam_spread_deg=0``,
    ``turn_budget_scale=1``, ``arc_ride=None``; soft jams, the scale and the arc ride came later)."""
    from feeder.mechanics.distribution import analytic_distribution
    from feeder.mechanics.pmf import analytic_pmf
    from feeder.parts.geometry import load_part

    out = {}
    for part, loc1, loc2 in PINNED:
        geom = as_geometry(load_part(parts_dir / f"{part}.stl"))
        fences = [fence_response(geom, m, MU) for m in fence_models(loc1, loc2, SCENE)]
        out[f"{part} {loc1} {loc2}"] = {
            "exit_deg": [r.exit_deg.tolist() for r in fences],
            "exit_offset": [r.exit_offset.tolist() for r in fences],
            "pmf": analytic_pmf(
                geom,
                loc1,
                loc2,
                SCENE,
                distribution=analytic_distribution(
                    geom, loc1, loc2, SCENE, jam_spread_deg=0.0, turn_budget_scale=1.0, arc_ride=None
                ),
            ).tolist(),
        }
    return out


def test_a_square_tip_is_pinned_from_before_the_cap():
    """The study's square tip gives what the code gave before the cap was modelled
    (tests/data/analytic_square_golden.json, recorded at a5a48c7): to the bit under the recording
    arithmetic (tests/pins.py), within PMF_ATOL and EXIT_ATOL_DEG elsewhere."""
    import json

    from pins import assert_pinned

    golden = json.loads(GOLDEN.read_text())
    got = _square_values()
    assert sorted(got) == sorted(golden["values"])
    for key, want in golden["values"].items():
        for a, b in zip(got[key]["exit_deg"], want["exit_deg"], strict=True):
            assert_pinned(a, b, golden["recorded_on"], 0.0, EXIT_ATOL_DEG, f"{key} exit_deg")
        for a, b in zip(got[key]["exit_offset"], want["exit_offset"], strict=True):
            assert_pinned(a, b, golden["recorded_on"], 0.0, EXIT_ATOL_DEG, f"{key} exit_offset")
        assert_pinned(got[key]["pmf"], want["pmf"], golden["recorded_on"], 0.0, PMF_ATOL, f"{key} pmf")


@pytest.mark.parametrize("angle", [45.0, 65.0])
def test_a_cap_caught_in_a_notch_turns_the_flush_edge_along_the_travel_direction(angle):
    """keyhole-a's grown hull edge 9 bridges the keyhole's slot; leaving a steep straight fence, the cap
    reaches the slot's concave corner (reason ``notch``). Let go there, the part keeps its yaw;
    hooked (the round tip's model), it turns about the cap's centre until that edge lies along
    the travel direction: by the fence's own angle, since the edge rode the face (by hand)."""
    from feeder.mechanics.exitturn import exit_turn
    from feeder.parts.geometry import load_part

    geom = as_geometry(load_part(ROOT / "parts" / "keyhole-a.stl"))
    cap = fence_models(f"straight:{angle:g}", "none", ROUND)[0]
    grown = dilate(geom, cap.cap_radius, 16)
    let_go = exit_turn(grown, 9, cap.exit_deg, cap.side, MU)
    hooked = exit_turn(grown, 9, cap.exit_deg, cap.side, MU, hook=True)
    assert let_go.reason == hooked.reason == "notch"
    assert hooked.phases == let_go.phases + "N"
    turn = hooked.delta_deg - let_go.delta_deg
    assert abs(turn) > 1.0
    # the edge was along the face (angle° off the travel direction) and now lies along the travel
    assert hooked.delta_deg == pytest.approx(-angle, abs=1e-9)
    # about the corner: the centroid keeps its distance from it and turns with the part
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    np.testing.assert_allclose(hooked.offset, np.array([[c, -s], [s, c]]) @ np.array(let_go.offset), atol=1e-12)
    # the response of the round tip hooks; its exit yaw for that edge is the rest yaw turned by -angle
    resp = fence_response(geom, cap, MU)
    normals = geom.normals_deg[resp.push.edges]  # the part's own hull edge of grown edge 9's normal
    k = int(np.argmin(np.abs((normals - grown.normals_deg[9] + 180.0) % 360.0 - 180.0)))
    assert resp.exit_reason[k] == "notch"
    assert (resp.exit_deg[k] - resp.rest_deg[k] + angle + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)


def test_a_square_tip_at_a_notch_still_lets_the_part_go():
    """keyhole-a leaving a straight 65° fence: with the square tip, four stable edges reach a notch
    of the outline itself; the model of a square tip keeps letting go there (their exit turns are
    the plain ``exit_turn``'s, with no hook phase)."""
    from feeder.mechanics.exitturn import exit_turn
    from feeder.parts.geometry import load_part

    geom = as_geometry(load_part(ROOT / "parts" / "keyhole-a.stl"))
    square = fence_models("straight:65", "none", SCENE)[0]
    resp = fence_response(geom, square, MU)
    notches = [k for k, why in enumerate(resp.exit_reason) if why == "notch"]
    assert len(notches) >= 2
    for k in notches:
        plain = exit_turn(geom, int(resp.push.edges[k]), square.exit_deg, square.side, MU)
        assert "N" not in plain.phases
        gap = (resp.exit_deg[k] - resp.rest_deg[k] - plain.delta_deg + 180.0) % 360.0 - 180.0
        assert gap == pytest.approx(0.0, abs=1e-9)


def test_the_hook_on_the_left_side_turns_the_other_way():
    """The same part and edge against a fence at Location 2 (left side, mirrored): the flush edge
    is turned along the travel direction by the fence's angle the other way round (by hand)."""
    from feeder.mechanics.exitturn import exit_turn
    from feeder.parts.geometry import load_part

    geom = as_geometry(load_part(ROOT / "parts" / "keyhole-a.stl"))
    cap = fence_models("none", "straight:45", ROUND)[0]
    assert cap.side == -1
    grown = dilate(geom, cap.cap_radius, 16)
    hooked = [exit_turn(grown, int(k), cap.exit_deg, cap.side, MU, hook=True) for k in range(len(grown.hull))]
    turned = [t for t in hooked if t.phases.endswith("N")]
    assert turned  # some edge's exit reaches a notch
    for t in turned:
        assert t.reason == "notch" and t.delta_deg == pytest.approx(45.0, abs=1e-9)


@pytest.mark.parametrize("angle", [30.0, 55.0])
def test_where_the_tip_force_acts_matters_only_through_friction(angle):
    """The tip's forces taken on the part (``contact_offset``: the cap's radius further in along each
    contact's normal) move a normal force along its own line, which changes neither its moment nor
    the normal velocity: frictionless, the exit turn is the same to rounding. With friction the
    moment of the friction force changes, and so does the turn (measured and not adopted:
    docs/experiments/tip_contact.py)."""
    from feeder.mechanics.exitturn import exit_turn

    geom = push_geometry(_rect(0.06, 0.02))
    cap = fence_models(f"straight:{angle:g}", "none", ROUND)[0]
    grown = dilate(geom, cap.cap_radius, 16)
    for edge in range(len(grown.hull)):
        at_centre = exit_turn(grown, edge, angle, cap.side, 0.0, hook=True)
        on_part = exit_turn(grown, edge, angle, cap.side, 0.0, hook=True, contact_offset=cap.cap_radius)
        assert on_part.delta_deg == pytest.approx(at_centre.delta_deg, abs=1e-9)
        assert on_part.reason == at_centre.reason
    moved = [
        abs(
            exit_turn(grown, e, angle, cap.side, MU, hook=True, contact_offset=cap.cap_radius).delta_deg
            - exit_turn(grown, e, angle, cap.side, MU, hook=True).delta_deg
        )
        for e in range(len(grown.hull))
    ]
    assert max(moved) > 0.1


@pytest.mark.parametrize("offset", [-0.001, float("nan"), float("inf")])
def test_a_bad_contact_offset_is_a_feeder_error(offset):
    from feeder.mechanics.exitturn import exit_turn

    with pytest.raises(FeederError, match="contact_offset"):
        exit_turn(push_geometry(_rect(0.06, 0.02)), 0, 30.0, 1, MU, contact_offset=offset)


def test_the_default_takes_the_tip_force_at_its_centre():
    """``fence_response`` by default is the model the study's dataset was built with (forces at the
    cap's centre); ``tip_force_at_contact=True`` is the variant measured against it."""
    from feeder.mechanics import distribution as D

    geom = push_geometry(_rect(0.06, 0.02))
    cap = fence_models("straight:45", "none", ROUND)[0]
    assert D.TIP_FORCE_AT_CONTACT is False
    default = fence_response(geom, cap, MU)
    np.testing.assert_array_equal(default.exit_deg, fence_response(geom, cap, MU, True, False).exit_deg)
    assert not np.array_equal(default.exit_deg, fence_response(geom, cap, MU, True, True).exit_deg)
