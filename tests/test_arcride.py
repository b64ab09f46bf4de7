"""The ride along a curved fence's arc (feeder.mechanics.arcride) and its use in the analytic
distribution (``arc_ride``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import feeder.mechanics.distribution as D
from feeder.errors import FeederError
from feeder.mechanics import arcride
from feeder.mechanics.arcride import arc_span_deg, arc_yaw, contact_twists
from feeder.mechanics.distribution import analytic_distribution, fence_response
from feeder.mechanics.exitturn import _contact_twist
from feeder.mechanics.fence import default_scene, fence_models, fence_mu
from feeder.mechanics.hull import push_geometry

SCENE = default_scene()
MU = fence_mu(SCENE)
RECT = push_geometry(np.array([(0.0, 0.0), (0.04, 0.0), (0.04, 0.02), (0.0, 0.02)]))


def test_frictionless_push_turns_by_a_over_c2_plus_a2():
    """A frictionless push along -y at moment arm a turns the part at -a / (c² + a²) per unit
    travel and moves it with the pusher along the normal (by hand: k = 1 / (1 + a²/c²))."""
    c2, a, h = 0.01**2, 0.004, 0.01
    tw = contact_twists(np.array([[a, h]]), np.array([[0.0, -1.0]]), 0.0, c2)[0]
    k = 1.0 / (1.0 + a * a / c2)
    assert tw[0] == pytest.approx(0.0, abs=1e-15)
    assert tw[1] == pytest.approx(-k)
    assert tw[2] == pytest.approx(-a / (c2 + a * a))


def test_a_contact_the_pusher_leaves_gives_no_twist():
    tw = contact_twists(np.array([[0.0, -0.01]]), np.array([[0.0, 1.0]]), 0.4, 1e-4)
    assert np.all(tw == 0.0)


def test_vectorised_twists_match_the_exit_turns_scalar_ones():
    rng = np.random.default_rng(3)
    n = 400
    ang = rng.uniform(-math.pi, 0.0, n)  # inward normals with a component against the pusher's travel
    nrm = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    r = rng.uniform(-0.02, 0.02, (n, 2))
    for mu in (0.0, 0.4, 1.5):
        got = contact_twists(r, nrm, mu, 1.2e-4)
        for i in range(n):
            e = (-nrm[i, 1], nrm[i, 0])
            want = _contact_twist(r[i, 0], r[i, 1], nrm[i, 0], nrm[i, 1], e[0], e[1], mu, 1.2e-4)
            assert want is not None
            np.testing.assert_allclose(got[i], want, rtol=1e-9, atol=1e-12)


def test_the_arc_spans_from_its_slot_end_to_its_tip_on_either_side():
    for loc1, loc2 in (("curved:30", "none"), ("none", "curved:30")):
        (m,) = fence_models(loc1, loc2, SCENE)
        tip, slot = arc_span_deg(m)
        assert abs(slot - tip) == pytest.approx(m.slot_deg - m.exit_deg)
        # the slot end lies on the wall's side of the tip
        slot_x = m.centre[0] + m.outer_radius * math.cos(math.radians(slot))
        assert m.side * slot_x > m.side * m.tip[0]


def test_a_straight_fence_has_no_arc():
    (m,) = fence_models("straight:30", "none", SCENE)
    with pytest.raises(FeederError, match="not curved"):
        arc_span_deg(m)


@pytest.mark.parametrize("loc1,loc2", [("curved:30", "none"), ("none", "curved:30"), ("curved:40", "none")])
def test_a_rectangle_leaves_the_arc_flush_on_an_edge_at_the_tip(loc1, loc2):
    """Riding the arc turns a rectangle flush with the face: at the tip its yaw is that of a
    stable edge resting on the exit chord, for nearly every drop the arc pushes (within half a
    chord's turn, 2.8°: the circle's face at the tip is half a chord shallower than the chord's).
    On curved:10 it is not: the arc there is too shallow to finish the turn (as in the simulator)."""
    (m,) = fence_models(loc1, loc2, SCENE)
    resp = fence_response(RECT, m, MU)
    yaws = np.arange(0.0, 360.0, 7.5)
    got = arc_yaw(RECT, m, yaws, np.zeros(yaws.size), MU)
    touched = np.isfinite(got)
    assert touched.mean() > 0.9
    gap = np.abs(np.mod(got[touched, None] - resp.rest_deg[None, :] + 180.0, 360.0) - 180.0).min(axis=1)
    assert np.mean(gap < 3.5) > 0.9


def test_a_drop_beside_the_arc_is_never_touched():
    (m,) = fence_models("curved:30", "none", SCENE)
    far = -m.side * 0.2  # 20 cm to the other side of the lane's centre line
    assert np.all(np.isnan(arc_yaw(RECT, m, np.array([0.0, 45.0, 90.0]), np.full(3, far), MU)))


def test_drops_within_the_quantum_share_one_ride():
    (m,) = fence_models("curved:30", "none", SCENE)
    q = arcride.ARC_YAW_QUANTUM_DEG
    got = arc_yaw(RECT, m, np.array([40.0, 40.0 + 0.4 * q]), np.zeros(2), MU)
    assert got[0] == got[1]


def test_arc_yaw_refuses_a_bad_friction():
    (m,) = fence_models("curved:30", "none", SCENE)
    with pytest.raises(FeederError, match="friction"):
        arc_yaw(RECT, m, np.array([0.0]), np.zeros(1), float("nan"))


def test_the_arc_ride_leaves_straight_fences_alone():
    a = analytic_distribution(RECT, "straight:30", "straight:45", SCENE, samples=720)
    for mode in ("basin", "state"):
        b = analytic_distribution(RECT, "straight:30", "straight:45", SCENE, samples=720, arc_ride=mode)
        np.testing.assert_array_equal(a.yaws, b.yaws)
        np.testing.assert_array_equal(a.weights, b.weights)


@pytest.mark.parametrize("mode", ["basin", "state"])
def test_the_arc_ride_moves_the_basin_edges_of_a_rectangle_on_a_curved_fence(mode):
    """A 40 x 20 mm rectangle on curved:30 arriving at 40° leaves at ≈ 96° (modulo 180°) after
    riding the arc, where the exit chord's push function alone sends it to ≈ 4°; arriving at 90°
    it is the other way round: the ride moves the ≈ 4° basin from arrivals of 30°-80° to 45°-95°.
    The simulator moves it further the same way (rect-a2, 60 x 30 mm, on curved:30: ≈ 2° from
    arrivals of 46° to 112°, ≈ 97° elsewhere)."""
    (m,) = fence_models("curved:30", "none", SCENE)
    resp = fence_response(RECT, m, MU)
    yaws = np.array([40.0, 90.0])

    def final(arc_ride):
        y, _, _, _ = D._apply(RECT, resp, MU, yaws, np.zeros(2), np.ones(2), True, 0.0, D.TURN_BUDGET_SCALE, arc_ride)
        return np.mod(y, 180.0)

    np.testing.assert_allclose(final(None), [4.0, 96.0], atol=2.0)
    np.testing.assert_allclose(final(mode), [96.0, 4.0], atol=2.0)


def test_arc_ride_mode_is_checked():
    with pytest.raises(FeederError, match="arc_ride"):
        analytic_distribution(RECT, "curved:30", "none", SCENE, samples=10, arc_ride="sometimes")


def test_a_memo_of_rides_changes_nothing():
    (m,) = fence_models("curved:40", "none", SCENE)
    yaws = np.arange(0.0, 360.0, 3.0)
    plain = arc_yaw(RECT, m, yaws, np.zeros(yaws.size), MU)
    memo: dict = {}
    first = arc_yaw(RECT, m, yaws[::2], np.zeros(yaws.size // 2), MU, memo)
    again = arc_yaw(RECT, m, yaws, np.zeros(yaws.size), MU, memo)  # half of them from the memo
    np.testing.assert_array_equal(first, plain[::2])
    np.testing.assert_array_equal(again, plain)
    a = analytic_distribution(RECT, "straight:20", "curved:40", SCENE, samples=720, arc_ride="state")
    responses: dict = {}
    for _ in range(2):
        b = analytic_distribution(
            RECT, "straight:20", "curved:40", SCENE, samples=720, arc_ride="state", responses=responses
        )
        np.testing.assert_array_equal(a.yaws, b.yaws)
        np.testing.assert_array_equal(a.weights, b.weights)
