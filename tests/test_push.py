"""Analytic fence response (feeder.mechanics) against hand-computed values."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.mechanics.distribution import YAW_SAMPLES, analytic_distribution, fence_response, jam_probability
from feeder.mechanics.exitturn import corner_push, exit_turn
from feeder.mechanics.features import PUSH_FEATURE_NAMES, fourier_coefficients, push_features
from feeder.mechanics.fence import (
    default_scene,
    fence_models,
    fence_mu,
    fence_normal_deg,
    friction_margin_deg,
    resting_yaw,
)
from feeder.mechanics.hull import as_geometry, push_geometry, radius_function
from feeder.mechanics.pmf import DEFAULT_SMOOTH_DEG, PMF_BINS, analytic_pmf
from feeder.mechanics.pushfunction import contact_patch, push_function, rolling_density

MU = 0.4  # the scene's part-fence friction, 0.8 x 0.5


def rect(w, h):
    return np.array([(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)])


def rotate(outline, deg, about=(0.0, 0.0)):
    a = math.radians(deg)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return (np.asarray(outline) - about) @ r.T + about


TRIANGLE = np.array([(0.0, 0.0), (0.03, 0.0), (0.015, 0.015 * math.sqrt(3.0))])
L_SHAPE = np.array([(0, 0), (0.04, 0), (0.04, 0.01), (0.01, 0.01), (0.01, 0.03), (0, 0.03)], dtype=float)
SCENE = default_scene()


def basin_of(push, normal_deg):
    """Measure of the basin of the stable normal ``normal_deg``."""
    idx = np.flatnonzero(np.isclose(np.mod(push.normals_deg - normal_deg + 180.0, 360.0) - 180.0, 0.0, atol=1e-9))
    assert idx.size == 1
    return float(push.measures[idx[0]])


# --------------------------------------------------------------------------------------------
# geometry
# --------------------------------------------------------------------------------------------
def test_radius_function_of_a_rectangle_about_its_centroid():
    g = push_geometry(rect(0.04, 0.02))
    assert g.area == pytest.approx(0.04 * 0.02)
    np.testing.assert_allclose(g.centroid, [0.02, 0.01])
    np.testing.assert_allclose(radius_function(g, [0.0, 90.0, 180.0, 270.0]), [0.02, 0.01, 0.02, 0.01])
    corner = math.degrees(math.atan2(0.01, 0.02))
    assert float(radius_function(g, corner)) == pytest.approx(math.hypot(0.02, 0.01))


def test_limit_surface_radius_of_a_square_is_its_mean_distance_from_the_centre():
    g = push_geometry(rect(1.0, 1.0))
    assert g.limit_radius == pytest.approx((math.sqrt(2.0) + math.log(1.0 + math.sqrt(2.0))) / 6.0, rel=1e-12)


def test_concave_outline_uses_its_hull_about_the_outline_centroid():
    g = push_geometry(L_SHAPE)
    assert len(g.hull) == 5  # the reflex corner (0.01, 0.01) is not a hull vertex
    reflex = np.array([0.01, 0.01]) - g.centroid
    assert not np.any(np.all(np.isclose(g.hull, reflex), axis=1))
    # the centroid is the L's own (area-weighted), not the hull's
    np.testing.assert_allclose(
        g.centroid, [(0.04 * 0.01 * 0.02 + 0.01 * 0.02 * 0.005) / 6e-4, (4e-4 * 0.005 + 2e-4 * 0.02) / 6e-4]
    )


@pytest.mark.parametrize(
    "outline",
    [
        np.array([(0.0, 0.0), (0.01, 0.0), (0.02, 0.0)]),  # collinear
        np.array([(0.0, 0.0), (0.01, 0.01), (0.02, 0.02), (0.03, 0.03)]),  # collinear, more points
        np.array([(0.0, 0.0), (0.0, 0.0), (0.0, 0.0)]),  # one point: no extent
        np.array([(0.0, 0.0), (np.nan, 0.0), (0.0, 1.0)]),  # not finite
        np.zeros((2, 2)),  # too few points
    ],
)
def test_degenerate_outline_is_a_feeder_error(outline):
    with pytest.raises(FeederError):
        push_geometry(outline)
    with pytest.raises(FeederError):
        push_features(outline, "straight:30", "none", SCENE)


# --------------------------------------------------------------------------------------------
# push function
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mu,side", [(0.0, 1), (MU, 1), (MU, -1)])
def test_two_to_one_rectangle_long_edges_take_two_atan2_over_pi(mu, side):
    push = push_function(rect(0.04, 0.02), mu, side)
    assert sorted(push.normals_deg.tolist()) == pytest.approx([0.0, 90.0, 180.0, 270.0])
    long_edges = basin_of(push, 90.0) + basin_of(push, 270.0)
    assert long_edges == pytest.approx(2.0 * math.atan(2.0) / math.pi, abs=1e-12)  # 0.7048
    assert push.measures.sum() == pytest.approx(1.0)


def test_frictionless_rectangle_basins_end_at_the_corner_directions():
    push = push_function(rect(0.04, 0.02))
    corner = math.degrees(math.atan(0.5))
    lo, hi = push.lower_deg[push.normals_deg == 90.0][0], push.upper_deg[push.normals_deg == 90.0][0]
    assert (lo, hi) == pytest.approx((corner, 180.0 - corner))


def test_square_has_four_equal_basins():
    for mu in (0.0, MU):
        push = push_function(rect(0.02, 0.02), mu)
        assert len(push.edges) == 4
        np.testing.assert_allclose(push.measures, 0.25)


def test_equilateral_triangle_has_three_equal_basins():
    for mu, side in ((0.0, 1), (MU, 1), (MU, -1)):
        push = push_function(TRIANGLE, mu, side)
        assert len(push.edges) == 3
        np.testing.assert_allclose(push.measures, 1.0 / 3.0)


def test_friction_turns_every_basin_boundary_by_atan_mu_against_the_side():
    f0, fr, fl = (push_function(rect(0.04, 0.02), mu, side) for mu, side in ((0.0, 1), (MU, 1), (MU, -1)))
    lam = math.degrees(math.atan(MU))
    np.testing.assert_allclose(fr.upper_deg, f0.upper_deg - lam)
    np.testing.assert_allclose(fl.upper_deg, f0.upper_deg + lam)


def test_the_boundary_friction_turns_the_boundaries_alone():
    """``boundary_mu`` turns the basin boundaries by its own friction angle and leaves which edges
    are stable to ``mu``; left out, it is ``mu`` (the same object field by field)."""
    f0 = push_function(rect(0.04, 0.02), 0.0, 1)
    fb = push_function(rect(0.04, 0.02), MU, 1, boundary_mu=0.2)
    np.testing.assert_allclose(fb.upper_deg, f0.upper_deg - math.degrees(math.atan(0.2)))
    thin = rect(0.06, 0.02)  # at mu its short edges are unstable whatever turns the boundaries
    assert len(push_function(thin, MU, 1, boundary_mu=0.0).edges) == 2
    a, b = push_function(thin, MU, -1), push_function(thin, MU, -1, boundary_mu=MU)
    for field in ("edges", "normals_deg", "lower_deg", "upper_deg", "measures"):
        assert np.array_equal(getattr(a, field), getattr(b, field))
    with pytest.raises(FeederError, match="boundary friction"):
        push_function(thin, MU, 1, boundary_mu=-1.0)


def regular_polygon(n: int, radius: float) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def test_contact_patch_of_a_hexagon_by_hand():
    """A regular hexagon of circumradius R: edges R long, each neighbour turned by 60°. Its far
    vertex lies R·sin 60° below the edge's line, R·cos 60° back; a gap g below that reaches
    g / tan 60° past each end, and any gap beyond it the whole neighbour (the next edge runs back
    towards the edge's start, so it adds nothing)."""
    r = 0.01
    hexagon = regular_polygon(6, r)
    lo, hi = contact_patch(hexagon, 0.0)
    np.testing.assert_allclose(lo, 0.0, atol=1e-15)
    np.testing.assert_allclose(hi, r)
    g = 0.001
    lo, hi = contact_patch(hexagon, g)
    np.testing.assert_allclose(lo, -g / math.sqrt(3.0))
    np.testing.assert_allclose(hi, r + g / math.sqrt(3.0))
    lo, hi = contact_patch(hexagon, r)  # past the neighbour's far vertex (depth 0.866 R)
    np.testing.assert_allclose(lo, -0.5 * r)
    np.testing.assert_allclose(hi, 1.5 * r)
    lo, hi = contact_patch(rect(0.04, 0.02), 0.001)  # right-angled corners: nothing within the gap
    np.testing.assert_allclose(lo, 0.0, atol=1e-15)
    np.testing.assert_allclose(hi, [0.04, 0.02, 0.04, 0.02])
    with pytest.raises(FeederError, match="patch gap"):
        contact_patch(hexagon, -1e-4)


def test_a_contact_patch_holds_a_polygonised_disc_that_rolls_on_its_edges():
    """A 16-gon rolls at mu = 0.4: the shifted foot (L/2 + mu·h = 0.59 R) is past every edge
    (L = 0.39 R). It holds once the patch reaches past the shift, within the neighbouring edge, at
    gap (mu·h − L/2)·tan θ (θ = 22.5°, the turn between neighbours); a gap of 0 is the edge
    itself, field by field."""
    n, r = 16, 0.02
    disc = push_geometry(regular_polygon(n, r))
    assert push_function(disc, MU, 1).rolls
    threshold = (MU * disc.heights[0] - 0.5 * disc.lengths[0]) * math.tan(2 * math.pi / n)
    assert push_function(disc, MU, 1, patch_gap=0.99 * threshold).rolls
    held = push_function(disc, MU, -1, patch_gap=1.01 * threshold)
    assert len(held.edges) == n  # every edge holds: each keeps the drops of its own cone
    np.testing.assert_allclose(held.measures, 1.0 / n)
    thin = rect(0.06, 0.02)
    a, b = push_function(thin, MU, 1), push_function(thin, MU, 1, patch_gap=0.0)
    for field in ("edges", "normals_deg", "lower_deg", "upper_deg", "measures"):
        assert np.array_equal(getattr(a, field), getattr(b, field))


def test_a_held_edge_stops_the_drops_flowing_past_it_and_keeps_its_own_cell():
    """A half 16-gon (radius 20 mm) on its chord, fence on the right, mu = 0.4: the arc edge of
    normal 118.125° is stable and its basin reaches far below it. With a 0.1 mm patch the arc
    edge below it (106.875°) holds too: every drop that flowed up through it stops there, its cell
    ending half way to 118.125° (112.5°); the stable edge keeps what lies above. Nothing else
    moves."""
    t = np.linspace(0.0, np.pi, 17)
    half = push_geometry(0.02 * np.column_stack([np.cos(t), np.sin(t)]))
    base = push_function(half, MU, 1)
    held = push_function(half, MU, 1, patch_gap=1e-4)
    s = int(np.argmin(np.abs(base.normals_deg - 118.125)))
    h = int(np.argmin(np.abs(held.normals_deg - 106.875)))
    assert abs(held.normals_deg[h] - 106.875) < 1e-9 and abs(base.normals_deg[s] - 118.125) < 1e-9
    assert len(held.edges) == len(base.edges) + 1
    np.testing.assert_allclose(held.lower_deg[h], base.lower_deg[s])
    np.testing.assert_allclose(held.upper_deg[h], 112.5)
    np.testing.assert_allclose(held.measures[h + 1], (base.upper_deg[s] - 112.5) / 360.0)
    others_base = np.delete(np.arange(len(base.edges)), s)
    others_held = np.delete(np.arange(len(held.edges)), [h, h + 1])
    np.testing.assert_allclose(held.measures[others_held], base.measures[others_base])
    assert held.measures.sum() == pytest.approx(1.0)


def test_friction_makes_the_short_edges_of_a_thin_rectangle_unstable():
    # 3:1: the foot shifted by mu * d = 0.4 * 30 mm lies beyond the 10 mm half edge
    assert len(push_function(rect(0.06, 0.02)).edges) == 4
    push = push_function(rect(0.06, 0.02), MU, 1)
    assert sorted(push.normals_deg.tolist()) == [90.0, 270.0]
    np.testing.assert_allclose(push.measures, 0.5)


def test_frictionless_stable_normals_are_minima_and_basin_ends_maxima_of_r():
    rng = np.random.default_rng(0)
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, 9))
    blob = np.column_stack([np.cos(angles), np.sin(angles)]) * rng.uniform(0.01, 0.03, (9, 1))
    for outline in (L_SHAPE, TRIANGLE, blob):
        g = push_geometry(outline)
        push = push_function(g)
        eps = 1e-3
        for n, lo, hi in zip(push.normals_deg, push.lower_deg, push.upper_deg):
            r = radius_function(g, [n - eps, n, n + eps])
            assert r[1] < r[0] and r[1] < r[2]  # a local minimum at the stable normal
            for b in (lo, hi):
                rb = radius_function(g, [b - eps, b, b + eps])
                assert rb[1] >= rb[0] and rb[1] >= rb[2]  # a local maximum at each basin end
        assert push.measures.sum() == pytest.approx(1.0)


def test_push_function_wraps_around_zero():
    push = push_function(rect(0.04, 0.02))  # the edge of normal 0 has the basin (-26.6, 26.6)
    assert float(push(359.9)) == float(push(0.1)) == 0.0
    assert float(push(-0.1)) == float(push(720.1)) == 0.0
    np.testing.assert_array_equal(push([350.0, 10.0, 100.0, 190.0, 280.0]), [0.0, 0.0, 90.0, 180.0, 270.0])


def test_a_reflex_vertex_never_becomes_a_stable_edge():
    g = push_geometry(L_SHAPE)
    for mu, side in ((0.0, 1), (MU, 1), (MU, -1)):
        push = push_function(g, mu, side)
        for k in push.edges:  # every stable edge is a hull edge, whose ends are convex outline vertices
            for v in (g.hull[k], g.hull[(k + 1) % len(g.hull)]):
                i = int(np.argmin(np.hypot(*(g.outline - v).T)))
                assert g.convex[i]
        assert push.measures.sum() == pytest.approx(1.0)


def test_a_roundish_part_rolls_with_friction():
    circle = np.column_stack(
        [np.cos(np.linspace(0, 2 * np.pi, 48, endpoint=False)), np.sin(np.linspace(0, 2 * np.pi, 48, endpoint=False))]
    )
    push = push_function(0.02 * circle, MU, 1)
    assert push.rolls
    w = rolling_density(0.02 * circle, MU, 1, np.arange(360.0))
    assert w.sum() == pytest.approx(1.0) and (w > 0).all()


# --------------------------------------------------------------------------------------------
# conventions
# --------------------------------------------------------------------------------------------
def test_flush_edge_normal_points_at_the_fence():
    # right side (Location 1) at 45: the fence runs along 135 and the edge normal points along 45
    assert float(fence_normal_deg(45.0, 1)) == pytest.approx(45.0)
    assert float(fence_normal_deg(60.0, -1)) == pytest.approx(120.0)
    # a 2:1 rectangle flush on its long edge (normal 270 in the file frame) has its long axis along the fence
    assert float(resting_yaw(270.0, 45.0, 1)) == pytest.approx(135.0)


def test_fence_models_follow_the_simulator_geometry():
    up, down = fence_models("curved:45", "straight:30", SCENE)
    assert (up.location, up.side, down.location, down.side) == ("loc2", -1, "loc1", 1)
    assert up.exit_deg == pytest.approx(30.0) and not up.curved
    segments = int(SCENE["fences"]["curved"]["segments"])
    assert down.curved and down.exit_deg == pytest.approx(45.0 + SCENE["fences"]["curved"]["span_deg"] / (2 * segments))


def test_friction_margin():
    assert float(friction_margin_deg(30.0, MU)) == pytest.approx(90.0 - math.degrees(math.atan(MU)) - 30.0)
    assert float(friction_margin_deg(75.0, MU)) < 0.0  # tests/test_sim_physics.py: a jam at 75


# --------------------------------------------------------------------------------------------
# exit turn
# --------------------------------------------------------------------------------------------
def test_rectangle_turns_towards_the_travel_direction_after_the_tip():
    g = push_geometry(rect(0.04, 0.02))
    push = push_function(g, MU, 1)
    k = int(push.edges[push.normals_deg == 270.0][0])
    turn = exit_turn(g, k, 45.0, 1, MU)
    # flush at 135 (long axis along the fence), then turned clockwise towards 90: the design
    # bench's 2,880-yaw reference (results/bench/designs) peaks at 100
    assert turn.reason == "released"
    assert -45.0 < turn.delta_deg < -25.0
    left = exit_turn(g, int(push_function(g, MU, -1).edges[0]), 45.0, -1, MU)
    assert left.delta_deg > 0.0  # mirrored on the left


def test_a_corner_met_head_on_turns_the_part_away_from_its_side_and_mirrors():
    """A 40 x 20 mm rectangle riding the belt with its long edge leading meets a fence's tip
    corner 15 mm right of its centroid: the corner holds back the right end of the leading edge,
    so the part turns clockwise (negative) before anything else touches it, and it meets the
    corner where its path first crosses the outline (the leading edge, 10 mm ahead of the
    centroid). Mirrored (the fence on the left, the corner 15 mm left) it turns the other way by
    the same angle. A corner beside the part does not touch it."""
    g = push_geometry(rect(0.04, 0.02))
    right = corner_push(g, 80.0, 1, MU, 0.0, -0.015)
    left = corner_push(g, 80.0, -1, MU, 0.0, 0.015)
    assert right.phases.startswith("C") and right.delta_deg < 0.0
    assert left.delta_deg == pytest.approx(-right.delta_deg, abs=1e-9)
    assert left.offset == pytest.approx((-right.offset[0], right.offset[1]), abs=1e-12)
    # the centroid stays behind the corner (upstream) and on its own side
    assert right.offset[1] < 0.0 and right.offset[0] < 0.0
    assert corner_push(g, 80.0, 1, MU, 0.0, -0.05) is None  # 5 cm to the left: the 2 cm half-length misses it
    assert corner_push(g, 80.0, 1, MU, 90.0, -0.015) is None  # turned lengthwise: a 1 cm half-width misses it


# --------------------------------------------------------------------------------------------
# analytic PMF
# --------------------------------------------------------------------------------------------
def test_no_fence_is_uniform():
    pmf = analytic_pmf(rect(0.04, 0.02), "none", "none", SCENE, smooth_deg=0.0)
    np.testing.assert_allclose(pmf, 1.0 / PMF_BINS)


@pytest.mark.parametrize("config", [("straight:30", "none"), ("none", "curved:40"), ("curved:20", "straight:45")])
def test_analytic_pmf_is_a_pmf(config):
    for smooth in (0.0, DEFAULT_SMOOTH_DEG):
        pmf = analytic_pmf(L_SHAPE, *config, SCENE, smooth_deg=smooth)
        assert pmf.shape == (PMF_BINS,)
        assert (pmf >= 0).all() and pmf.sum() == pytest.approx(1.0)


def test_rectangle_on_one_straight_fence_rests_exactly_at_the_predicted_yaws():
    outline = rect(0.04, 0.02)
    pmf = analytic_pmf(outline, "straight:30", "none", SCENE, smooth_deg=0.0, exit_turns=False)
    push = push_function(outline, MU, 1)
    rest = resting_yaw(push.normals_deg, 30.0, 1)  # psi = 30 minus the normals 0, 90, 180, 270
    np.testing.assert_allclose(np.sort(rest), [30.0, 120.0, 210.0, 300.0])
    expected = np.zeros(PMF_BINS)
    np.add.at(expected, np.round(rest).astype(int), push.measures)  # bin i holds [i, i + 1)
    np.testing.assert_allclose(pmf, expected, atol=2.0 / YAW_SAMPLES)
    assert pmf[np.round(rest).astype(int)].sum() == pytest.approx(1.0)
    # with the exit turn the mass still sits at one yaw per stable edge
    turned = analytic_distribution(outline, "straight:30", "none", SCENE)
    assert np.unique(np.round(turned.yaws, 9)).size == 4


def test_pmf_follows_a_rotation_of_the_outline_in_its_file_frame():
    outline = L_SHAPE
    base = analytic_pmf(outline, "straight:35", "curved:30", SCENE, smooth_deg=0.0)
    turned = rotate(outline, 40.0, about=(0.3, -0.2))
    # the same body: its file-frame yaws are 40 less; in a label frame that follows it, identical
    same = analytic_pmf(turned, "straight:35", "curved:30", SCENE, smooth_deg=0.0, frame_deg=40.0)
    np.testing.assert_allclose(same, base, atol=2e-3)
    shifted = analytic_pmf(turned, "straight:35", "curved:30", SCENE, smooth_deg=0.0)
    np.testing.assert_allclose(L.shift_pmf(shifted, 40.0), base, atol=2e-3)


def test_two_identical_fences_give_the_same_pmf_as_one():
    outline = rect(0.04, 0.02)
    (fence,) = fence_models("straight:30", "none", SCENE)
    one = analytic_distribution(outline, None, None, SCENE, exit_turns=False, fences=[fence])
    two = analytic_distribution(outline, None, None, SCENE, exit_turns=False, fences=[fence, fence])
    p1 = analytic_pmf(outline, None, None, SCENE, smooth_deg=0.0, distribution=one)
    p2 = analytic_pmf(outline, None, None, SCENE, smooth_deg=0.0, distribution=two)
    np.testing.assert_allclose(p1, p2, atol=1e-12)


def test_composition_feeds_the_first_fence_s_resting_yaws_to_the_second():
    outline = rect(0.04, 0.02)
    first, second = fence_models("straight:45", "straight:30", SCENE)  # Location 2 is met first
    dist = analytic_distribution(outline, "straight:45", "straight:30", SCENE)
    r1 = fence_response(outline, first, MU)
    r2 = fence_response(outline, second, MU)
    phi = fence_normal_deg(second.exit_deg, second.side) - r1.exit_deg  # inputs to the second fence
    expected = r2.exit_deg[r2.push.basin_index(phi)]
    np.testing.assert_allclose(np.sort(np.unique(np.round(dist.yaws, 9))), np.sort(np.unique(np.round(expected, 9))))


def test_curved_fence_at_zero_does_not_reach_a_small_part():
    small = rect(0.01, 0.008)  # reaches 6 mm from its centroid; the curved:0 tip is 35 mm out
    dist = analytic_distribution(small, "curved:0", "none", SCENE, samples=720)
    assert dist.touch["loc1"] == 0.0
    np.testing.assert_allclose(analytic_pmf(small, "curved:0", "none", SCENE, smooth_deg=0.0), 1.0 / PMF_BINS)


def test_the_turn_budget_scale_multiplies_a_binding_budget():
    """curved:0 reaches only the edge of a 80 x 30 mm rectangle: every drop it touches turns by its
    budget overlap / (2c), short of its stable edge; twice the budget turns each twice as far, and
    the drops it misses stay as they were (without the arc ride, which would start the turn from the
    ridden yaw: tests/test_arcride.py)."""
    part = rect(0.08, 0.03)
    n = 72
    start = (np.arange(n) + 0.5) * (360.0 / n)
    turns = []
    for scale in (1.0, 2.0):
        dist = analytic_distribution(part, "curved:0", "none", SCENE, samples=n, turn_budget_scale=scale, arc_ride=None)
        turns.append((dist.yaws - start + 180.0) % 360.0 - 180.0)
    assert np.count_nonzero(turns[0]) > n // 4
    np.testing.assert_allclose(turns[1], 2.0 * turns[0], atol=1e-9)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(FeederError, match="turn_budget_scale"):
            analytic_distribution(part, "curved:0", "none", SCENE, samples=n, turn_budget_scale=bad)


def test_steep_curved_fences_jam_in_the_friction_cone():
    dist = analytic_distribution(rect(0.04, 0.02), "curved:70", "none", SCENE, samples=720)
    assert dist.jam["loc1"] > 0.5 and dist.margin["loc1"] < 0.0
    hard = analytic_distribution(rect(0.04, 0.02), "straight:30", "none", SCENE, samples=720, jam_spread_deg=0.0)
    assert hard.jam["loc1"] == 0.0 and hard.ok_mass == 1.0
    # soft jams: straight:30 lies 38.2° outside the cone, a jam share of Phi(-38.2 / 3) ~ 2e-37
    soft = analytic_distribution(rect(0.04, 0.02), "straight:30", "none", SCENE, samples=720, jam_spread_deg=3.0)
    assert 0.0 < soft.jam["loc1"] < 1e-30
    soft = analytic_distribution(rect(0.04, 0.02), "curved:70", "none", SCENE, samples=720, jam_spread_deg=3.0)
    assert 0.5 < soft.jam["loc1"] < dist.jam["loc1"] and soft.ok_mass > dist.ok_mass


GRAZES = ("corner", "face", "swing")


def test_a_drop_grazing_a_steep_curved_fence_is_left_or_pushed_by_its_last_chord():
    """curved:80's tip stops 7 mm short of the centre line and its circle lies beyond the tip for a
    centred 40 x 20 mm rectangle: with ``graze="corner"`` it is left as it came (the PMF stays
    uniform); with ``"face"`` the last chord (82.8°) pushes it as a straight fence of that angle
    would, to a yaw flush with the chord, and none jams although the chord lies in the cone;
    ``"swing"`` turns those yaws on about the tip."""
    part = rect(0.04, 0.02)
    n = 720
    left = analytic_distribution(part, "curved:80", "none", SCENE, samples=n)
    np.testing.assert_allclose(np.sort(left.yaws), (np.arange(n) + 0.5) * 360.0 / n)
    assert left.touch["loc1"] == 0.0
    face = analytic_distribution(part, "curved:80", "none", SCENE, samples=n, graze="face")
    (model,) = fence_models("curved:80", "none", SCENE)
    assert face.touch["loc1"] == 1.0 and face.jam["loc1"] == 0.0 and face.ok_mass == pytest.approx(1.0)
    assert friction_margin_deg(model.exit_deg, MU) < 0.0  # the chord alone would hold it
    flush = np.mod(resting_yaw(push_function(part, MU, model.side).normals_deg, model.exit_deg, model.side), 90.0)
    turned = np.isin(np.round(np.mod(face.yaws, 90.0), 6), np.round(flush, 6))
    assert turned.mean() > 0.5  # most end flush with the chord; the rest run out of turn budget
    # "swing": then about the tip by 2·82.8° − 90° against the side (side +1 here: yaw decreases)
    swing = analytic_distribution(part, "curved:80", "none", SCENE, samples=n, graze="swing")
    assert swing.touch["loc1"] == 1.0 and swing.jam["loc1"] == 0.0
    np.testing.assert_allclose(
        np.mod(swing.yaws - face.yaws + 180.0, 360.0) - 180.0, -(2.0 * model.exit_deg - 90.0), atol=1e-9
    )
    # curved:0's chord lies outside the cone: what grazes it is left as it came, as with "corner"
    wide = rect(0.08, 0.03)  # some of its drops meet curved:0's circle beyond the tip
    got = {mode: analytic_distribution(wide, "curved:0", "none", SCENE, samples=n, graze=mode) for mode in GRAZES}
    assert got["face"].touch["loc1"] > got["corner"].touch["loc1"]
    assert np.array_equal(got["swing"].yaws, got["corner"].yaws)
    assert np.array_equal(got["swing"].weights, got["corner"].weights)
    with pytest.raises(FeederError, match="graze"):
        analytic_distribution(part, "curved:80", "none", SCENE, samples=n, graze="edge")


def test_jam_probability_by_hand():
    # Phi(0) = 1/2 on the cone's edge; Phi(-1) = 0.158655 one spread inside the slide side
    np.testing.assert_allclose(jam_probability([0.0, 3.0, -3.0], 3.0), [0.5, 0.15865525, 0.84134475], rtol=1e-7)
    np.testing.assert_array_equal(jam_probability([-1e-9, 0.0, 2.0], 0.0), [1.0, 0.0, 0.0])
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(FeederError, match="jam_spread_deg"):
            jam_probability(1.0, bad)


def test_soft_jams_weigh_a_straight_fence_on_the_cones_edge():
    # a straight fence at 90 - atan(0.4) = 68.2°: every drop touches it with margin 0, so each
    # keeps half its weight; the PMF (over the ok drops) is that of the slide rule
    edge = math.degrees(math.atan2(1.0, 0.4))
    fence = replace(fence_models("straight:30", "none", SCENE)[0], exit_deg=edge, slot_deg=edge)
    part = rect(0.04, 0.02)
    soft = analytic_distribution(part, None, None, SCENE, fences=[fence], samples=720, jam_spread_deg=3.0)
    slide = analytic_distribution(part, None, None, SCENE, fences=[fence], samples=720, jams=False)
    assert soft.jam["loc1"] == pytest.approx(0.5 * soft.touch["loc1"], abs=1e-12)
    assert soft.ok_mass == pytest.approx(1.0 - 0.5 * soft.touch["loc1"], abs=1e-12)
    pmfs = [analytic_pmf(part, None, None, SCENE, distribution=d) for d in (soft, slide)]
    np.testing.assert_allclose(*pmfs)


# --------------------------------------------------------------------------------------------
# feature block
# --------------------------------------------------------------------------------------------
def test_feature_block_layout():
    vec = push_features(L_SHAPE, "straight:30", "curved:40", SCENE)
    names = PUSH_FEATURE_NAMES
    assert vec.shape == (len(names),) and len(set(names)) == len(names)
    assert np.isfinite(vec).all()
    f = dict(zip(names, vec))
    assert f["loc1_present"] == 1.0 and f["loc2_present"] == 1.0
    assert 0.0 <= f["ok_mass"] <= 1.0 and 0.0 < f["peak_mass"] <= 1.0
    pmf = analytic_pmf(L_SHAPE, "straight:30", "curved:40", SCENE)
    c = fourier_coefficients(pmf)
    assert (f["re_c1"], f["im_c1"]) == pytest.approx((c[0].real, c[0].imag))
    empty = dict(zip(names, push_features(L_SHAPE, "none", "none", SCENE)))
    assert empty["loc1_present"] == 0.0 and empty["ok_mass"] == 1.0
    assert abs(complex(empty["re_c1"], empty["im_c1"])) < 1e-12


def test_a_part_with_holes_pushes_about_the_regions_centroid_with_the_outlines_hull():
    """The holes move the centroid and thin the limit surface; the hull, which meets the fences,
    is the outline's. ∫|x| dA is additive: the region's is the square's less the hole's."""
    from feeder.parts.geometry import PartGeometry

    square = np.array([(-0.01, -0.01), (0.01, -0.01), (0.01, 0.01), (-0.01, 0.01)])
    hole = 0.5 * square  # centred: the centroid stays at the origin
    solid, ring = push_geometry(square), push_geometry(square, [hole])
    inner = push_geometry(hole)
    assert ring.area == pytest.approx(0.0004 - 0.0001)
    np.testing.assert_allclose(ring.centroid, [0.0, 0.0], atol=1e-15)
    want = (solid.limit_radius * solid.area - inner.limit_radius * inner.area) / ring.area
    assert ring.limit_radius == pytest.approx(want, rel=1e-12)
    assert ring.limit_radius > solid.limit_radius  # the material left is farther out
    np.testing.assert_array_equal(ring.hull, solid.hull)
    # off-centre: a 10 x 10 mm hole centred at x = +4 mm moves the centroid to -4/3 mm
    off = push_geometry(square, [hole + [0.004, 0.0]])
    np.testing.assert_allclose(off.centroid, [-0.004 / 3.0, 0.0], atol=1e-15)
    geom = PartGeometry.from_polygon("ring", square, 0.003, [hole + [0.004, 0.0]])
    np.testing.assert_allclose(as_geometry(geom).centroid, off.centroid)  # a PartGeometry's holes count
    with pytest.raises(FeederError, match="holes are not inside the outline"):
        push_geometry(square, [hole + [0.01, 0.0]])  # reaches the outline


def test_a_fence_that_no_drop_reaches_gives_finite_features():
    """Hard case from the wider library (randblob-15, straight:25 | curved:50): the curved fence
    upstream jams every drop (its margin is -1.4 deg), so the straight fence downstream meets an
    empty set. Its margin is the margin at its exit angle, not the mean of nothing (NaN, which
    stopped the dataset build). Under the hard jam rule (``jam_spread_deg=0``): soft jams let a
    little weight through a margin of -1.4 deg."""
    from pathlib import Path

    from feeder.parts.geometry import load_part

    part = load_part(Path(__file__).resolve().parents[1] / "parts" / "randblob-15.stl")
    dist = analytic_distribution(part, "straight:25", "curved:50", jam_spread_deg=0.0)
    mu = fence_mu(default_scene())
    assert dist.margin["loc1"] == pytest.approx(float(friction_margin_deg(25.0, mu)))
    assert dist.jam["loc2"] == 1.0 and dist.ok_mass == 0.0
    assert dist.touch["loc1"] == 0.0 and dist.jam["loc1"] == 0.0
    assert np.isfinite(push_features(part, "straight:25", "curved:50")).all()


def test_a_jammed_distribution_without_its_fences_is_refused():
    """A distribution where every drop jams has no PMF of its own; analytic_pmf gives the PMF of
    the configuration without jams, which it needs the fences for. Given only the distribution it
    once returned the PMF of no fence at all (uniform): now a clear error."""
    part = rect(0.04, 0.02)
    jammed = analytic_distribution(part, "curved:70", "none", SCENE, samples=720, jam_spread_deg=0.0)
    assert jammed.weights.sum() == 0.0
    for no_fence in (None, "none"):
        with pytest.raises(FeederError, match="every drop of the given distribution jams"):
            analytic_pmf(part, no_fence, no_fence, SCENE, distribution=jammed)
    got = analytic_pmf(part, "curved:70", "none", SCENE, distribution=jammed)
    want = analytic_pmf(
        part, None, None, SCENE, distribution=analytic_distribution(part, "curved:70", "none", SCENE, jams=False)
    )
    np.testing.assert_array_equal(got, want)
