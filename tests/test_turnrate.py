"""How fast a fence turns a part (feeder.mechanics.turnrate) and its use in the analytic
distribution (``turn_rate``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feeder.errors import FeederError
from feeder.mechanics.distribution import analytic_distribution
from feeder.mechanics.fence import default_scene, fence_normal_deg
from feeder.mechanics.hull import push_geometry
from feeder.mechanics.pushfunction import push_function
from feeder.mechanics.turnrate import TURN_RATE_FLOOR, turn_cost, turn_rates, unwrap_into

SCENE = default_scene()
W, H = 0.04, 0.02
RECT = push_geometry(np.array([(0.0, 0.0), (W, 0.0), (W, H), (0.0, H)]))


def _moment_arm(phi_deg: float) -> float:
    """By hand, frictionless: the contact is the rectangle's support corner in the direction
    ``phi``, the force along ``−phi``; its line passes ``|v| |sin(phi − θ_v)|`` from the centroid."""
    u = np.array([math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))])
    corners = np.array([(W / 2, H / 2), (-W / 2, H / 2), (-W / 2, -H / 2), (W / 2, -H / 2)])
    v = corners[np.argmax(corners @ u)]
    return abs(v[0] * u[1] - v[1] * u[0])


@pytest.mark.parametrize("angle, side", [(30.0, 1), (45.0, -1), (10.0, 1)])
def test_a_frictionless_push_turns_at_2ca_over_c2_plus_a2(angle, side):
    """Per unit push along the normal a frictionless contact at moment arm ``a`` turns the part by
    ``a / (c² + a²)``; relative to the bound ``1 / (2c)`` that is ``2ca / (c² + a²)``, whatever the
    face's angle and side."""
    c = RECT.limit_radius
    for phi in (5.0, 20.0, 40.0, 100.0, 170.0, 250.0):
        a = _moment_arm(phi)
        got = float(turn_rates(RECT, angle, side, 0.0, phi))
        assert got == pytest.approx(2.0 * c * a / (c * c + a * a), rel=1e-9)


def test_the_rate_vanishes_where_the_line_of_force_meets_the_centroid():
    corner = math.degrees(math.atan2(H / 2, W / 2))  # the direction of the corner (W/2, H/2)
    assert float(turn_rates(RECT, 30.0, 1, 0.0, corner)) == pytest.approx(0.0, abs=1e-9)
    # with friction the zero moves by atan(mu) against the side (push function's vertex rule)
    mu = 0.4
    lam = math.degrees(math.atan(mu))
    q = turn_rates(RECT, 30.0, 1, mu, np.array([corner - lam, corner, corner + lam]))
    assert q[0] == pytest.approx(0.0, abs=1e-9)
    assert q[1] > 0.1 and q[2] > 0.1


def test_rates_are_periodic_and_bounded_without_friction():
    phi = np.linspace(0.0, 360.0, 721)
    q = turn_rates(RECT, 25.0, 1, 0.0, phi)
    assert np.all(q >= 0.0) and np.all(q <= 1.0 + 1e-12)  # 2ca/(c²+a²) <= 1
    np.testing.assert_allclose(q[0], q[-1], rtol=1e-12)


def test_the_cost_table_inverts():
    """Turning from phi by the budget ``between`` says it takes lands on the target; the cost of a
    turn adds over its pieces; and it is never less than the turn at the bound's rate where the
    frictionless rate is at most 1."""
    tc = turn_cost(RECT, 30.0, 1, 0.0)
    assert np.all(np.diff(tc.cost) > 0.0)
    for a, b in ((10.0, 80.0), (-200.0, 100.0), (400.0, 350.0)):
        need = tc.between(a, b)
        assert float(tc.advance(a, b - a, need)) == pytest.approx(b, abs=1e-6)
        assert need >= abs(b - a) - 1e-9
    mid = 37.0
    assert tc.between(10.0, 80.0) == pytest.approx(tc.between(10.0, mid) + tc.between(mid, 80.0))


def test_turning_through_a_line_of_force_on_the_centroid_costs_far_more_than_elsewhere():
    """Near the corner's direction the line of force passes the centroid: the part barely turns,
    so a cell there costs thousands of times its width; a cell mid-edge costs about its width."""
    corner = math.degrees(math.atan2(H / 2, W / 2))
    tc = turn_cost(RECT, 30.0, 1, 0.0)
    step = tc.grid_deg[1] - tc.grid_deg[0]
    i = np.searchsorted(tc.grid_deg, corner)
    assert tc.cost[i] - tc.cost[i - 1] > 1000.0 * step
    assert np.max(np.diff(tc.cost)) <= step / TURN_RATE_FLOOR + 1e-9
    j = np.searchsorted(tc.grid_deg, 90.0 + 45.0)  # a = |v| sin(45° off the corner): about c
    assert tc.cost[j] - tc.cost[j - 1] < 3.0 * step


def test_unwrap_into_a_basin():
    np.testing.assert_allclose(unwrap_into([350.0, -10.0, 5.0, 725.0], [-30.0, -30.0, 0.0, 0.0]), [-10, -10, 5, 5])


def test_the_moment_rate_turns_no_further_than_the_bound_without_friction():
    """Frictionless, every rate is at most the bound's: with the same budget each drop turns at most
    as far, and a budget that reaches every stable edge gives the same PMF either way."""
    for scale in (0.05, 1.5):
        a = analytic_distribution(RECT, "straight:30", "none", mu=0.0, turn_budget_scale=scale, samples=720)
        b = analytic_distribution(
            RECT, "straight:30", "none", mu=0.0, turn_budget_scale=scale, samples=720, turn_rate="moment"
        )
        pf = push_function(RECT, 0.0, 1)
        normal = float(fence_normal_deg(30.0, 1))
        start = (np.arange(720) + 0.5) * 0.5
        phi = normal - start
        target = pf(phi)
        far_a = np.abs(np.mod(normal - a.yaws - target + 180.0, 360.0) - 180.0)
        far_b = np.abs(np.mod(normal - b.yaws - target + 180.0, 360.0) - 180.0)
        if scale < 1.0:
            assert np.mean(far_b) > np.mean(far_a)  # turned less far towards the stable edge
    big = dict(mu=0.0, turn_budget_scale=1e4, samples=720)
    a = analytic_distribution(RECT, "straight:30", "none", **big)
    b = analytic_distribution(RECT, "straight:30", "none", turn_rate="moment", **big)
    np.testing.assert_allclose(np.sort(a.yaws), np.sort(b.yaws))


def test_the_moment_rate_turns_the_way_the_push_function_flows():
    """A basin wider than a half turn: the bound's rule turns the short way to its stable edge,
    against the flow; the moment rule turns with it (towards the edge the long way round)."""
    # a disc cut by a chord 0.8 R from its centre: the centroid lies too near the centre for any
    # arc edge to hold under friction, so the chord is the one stable edge, its basin the whole turn
    cut = math.acos(0.8)
    t = np.linspace(-math.pi / 2 + cut, 1.5 * math.pi - cut, 241)
    half = push_geometry(np.column_stack([0.03 * np.cos(t), 0.03 * np.sin(t)]))
    pf = push_function(half, 0.4, 1)
    assert len(pf.normals_deg) == 1
    d = analytic_distribution(
        half, "straight:30", "none", turn_budget_scale=0.2, samples=360, turn_rate="moment", exit_turns=False
    )
    normal = float(fence_normal_deg(30.0, 1))
    start = np.arange(360) + 0.5
    lo = float(pf.lower_deg[0])
    here = unwrap_into(normal - start, lo)
    after = unwrap_into(normal - d.yaws, lo)
    target = float(unwrap_into(pf.normals_deg[0], lo))
    moved = after - here
    turned = np.abs(moved) > 1e-9
    assert turned.sum() > 100
    assert np.all(np.sign(moved[turned]) == np.sign(target - here[turned]))
    bound = analytic_distribution(half, "straight:30", "none", turn_budget_scale=0.2, samples=360, exit_turns=False)
    moved = unwrap_into(normal - bound.yaws, lo) - here
    turned = np.abs(moved) > 1e-9
    assert np.any(np.sign(moved[turned]) != np.sign(target - here[turned]))  # the short way, against the flow


def test_a_bad_turn_rate_is_refused():
    with pytest.raises(FeederError, match="turn_rate"):
        analytic_distribution(RECT, "straight:30", "none", turn_rate="fast")
    with pytest.raises(FeederError, match="friction"):
        turn_rates(RECT, 30.0, 1, -0.1, 10.0)
