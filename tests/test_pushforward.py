"""Adaptive refinement and the exact push-forward label, against analytic drop maps."""

from __future__ import annotations

import numpy as np
import pytest

from feeder import circular as C
from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.sim import adaptive as A
from feeder.sim import pushforward as P

BINS = 360
NUMERIC = 1e-4  # sup|ΔCDF| slack for the dense-sampling reference (≈ 1/DENSE per jump)
DENSE = 720_000  # midpoint-rule samples of the exact push-forward
BAND = (200.0, 220.0)  # the chaotic band of the chaotic map


# ----------------------------------------------------------------------------------------------
# Analytic maps: β (degrees, [0, 360)) → (final yaw, status)
# ----------------------------------------------------------------------------------------------
def all_ok(final):
    final = np.asarray(final, dtype=np.float64)
    return final, np.full(final.shape, "ok")


def step_map(beta):
    return all_ok(np.where(beta < 120.0, 30.0, 200.0))


def ramp_map(beta):
    return all_ok(beta / 2.0 + 10.0)


def wrap_map(beta):
    return all_ok(C.normalize_yaw(355.0 + beta / 36.0))


def jam_map(beta):
    jammed = (beta < 90.0) | (beta >= 350.0)
    return np.where(jammed, np.nan, 45.0 + 0.05 * beta), np.where(jammed, "jammed", "ok")


def coin(beta):
    """A deterministic fair coin per float value (splitmix64 of its bits): chaotic at any width."""
    x = np.ascontiguousarray(beta, dtype=np.float64).view(np.uint64).copy()
    with np.errstate(over="ignore"):
        x ^= x >> np.uint64(30)
        x *= np.uint64(0xBF58476D1CE4E5B9)
        x ^= x >> np.uint64(27)
        x *= np.uint64(0x94D049BB133111EB)
        x ^= x >> np.uint64(31)
    return (x >> np.uint64(63)).astype(bool)


def smooth_part(beta):
    return 250.0 + 3.0 * np.sin(np.radians(beta))


def chaotic_map(beta):
    band = (beta >= BAND[0]) & (beta < BAND[1])
    return all_ok(np.where(band, np.where(coin(beta), 10.0, 100.0), smooth_part(beta)))


def symmetric_map(beta):
    """4-fold: f(β + 90) = f(β) + 90; per period a jump at 40° and a jam arc [80, 85)."""
    k = np.floor(beta / 90.0)
    b = beta - 90.0 * k
    final = np.where(b < 40.0, 20.0 + 0.02 * b, 70.0 + 0.02 * b) + 90.0 * k
    jammed = (b >= 80.0) & (b < 85.0)
    return np.where(jammed, np.nan, C.normalize_yaw(final)), np.where(jammed, "jammed", "ok")


class Counting:
    """An evaluate that counts its calls and yaws and checks the yaws it is handed."""

    def __init__(self, fmap):
        self.fmap, self.calls, self.sizes, self.seen = fmap, 0, [], []

    def __call__(self, yaws):
        yaws = np.asarray(yaws)
        assert yaws.ndim == 1 and yaws.size >= 1
        assert (yaws >= 0).all() and (yaws < 360).all()
        self.calls += 1
        self.sizes.append(yaws.size)
        self.seen.append(yaws.copy())
        return self.fmap(yaws)


def dense_reference(fmap, bins=BINS):
    """The exact push-forward by a fine midpoint rule: (ok histogram normalised, masses)."""
    beta = (np.arange(DENSE) + 0.5) * 360.0 / DENSE
    final, status = fmap(beta)
    ok = status == "ok"
    hist = L.histogram(final[ok], bins)
    masses = {s: float(np.mean(status == s)) for s in np.unique(status)}
    return hist / hist.sum(), masses


def sup_cdf(p, q):
    return float(np.abs(L.cdf(p) - L.cdf(q)).max())


# ----------------------------------------------------------------------------------------------
# Tests
# ----------------------------------------------------------------------------------------------
def test_grid_yaws():
    np.testing.assert_allclose(A.grid_yaws(4, 0.0), [0, 90, 180, 270])
    np.testing.assert_allclose(A.grid_yaws(4, 300.0), [300, 30, 120, 210])
    np.testing.assert_allclose(A.grid_yaws(3, 10.0, 90.0), [10, 40, 70])
    with pytest.raises(FeederError):
        A.grid_yaws(0, 0.0)
    with pytest.raises(FeederError):
        A.grid_yaws(4, 0.0, 50.0)


def test_step_map_two_basins_exact_masses():
    ev = Counting(step_map)
    d = A.refine(ev)
    pmf, masses = P.pushforward_pmf(d, BINS, 0.0)
    jumps = 2  # at 120° and at 360°/0°
    assert d.unresolved_share <= jumps * d.min_width_deg / 360.0
    assert d.unresolved_share > 0
    assert pmf[30] == pytest.approx(1 / 3, abs=d.unresolved_share + 1e-12)
    assert pmf[200] == pytest.approx(2 / 3, abs=d.unresolved_share + 1e-12)
    assert pmf[30] + pmf[200] == pytest.approx(1.0)
    assert masses == {"ok": pytest.approx(1.0)}
    exact = np.zeros(BINS)
    exact[30], exact[200] = 1 / 3, 2 / 3
    assert sup_cdf(pmf, exact) <= d.unresolved_share + 1e-12
    # few simulations: 16 grid + 16 first-round midpoints + 5 bisections and a few edge checks per jump
    assert d.evaluations <= 16 + 16 + 12 * jumps
    assert d.evaluations == d.yaws.size == sum(ev.sizes) and d.calls == ev.calls
    # the unresolved intervals bracket the two jumps
    assert d.unresolved.shape == (2, 2)
    assert any(a < 120.0 <= b for a, b in d.unresolved)
    assert any(a < 360.0 <= b for a, b in d.unresolved)
    assert np.sum(d.unresolved[:, 1] - d.unresolved[:, 0]) / 360.0 == pytest.approx(d.unresolved_share)


def test_step_map_without_checks_is_pure_bisection():
    d = A.refine(step_map, max_width_deg=360.0 / 16, edge_check_deg=0.0)
    assert d.evaluations == 16 + 6 * 2  # 22.5° → 0.35° is six bisections per jump
    assert d.unresolved_share <= 2 * d.min_width_deg / 360.0
    with_checks = A.refine(step_map, max_width_deg=360.0 / 16)
    assert d.evaluations < with_checks.evaluations <= d.evaluations + 2 * 8
    assert with_checks.unresolved_share == pytest.approx(d.unresolved_share)


def test_narrow_basin_is_counted_as_a_band():
    # a 1° basin (β in [168.3, 169.3) → 300°, holding the check sample 168.75) inside the 30°
    # basin: two jumps 1° apart look like the start of a chaotic band
    def narrow(beta):
        return all_ok(np.where((beta >= 168.3) & (beta < 169.3), 300.0, 30.0))

    d = A.refine(narrow, budget=200)
    pmf, _ = P.pushforward_pmf(d, BINS, 0.0)
    assert pmf[300] == pytest.approx(1 / 360, abs=d.unresolved_share)
    assert d.unresolved_share >= 1 / 360  # the basin's inside is in the bound
    assert d.unresolved_share <= 1 / 360 + 2 * d.min_width_deg / 360
    exact = np.zeros(BINS)
    exact[30], exact[300] = 359 / 360, 1 / 360
    assert sup_cdf(pmf, exact) <= d.unresolved_share + 1e-12


def test_a_basin_between_samples_is_missed_and_unchecked_lists_what_the_budget_skipped():
    # the same 1° basin between samples: no sample sees it (documented limit of max_width)
    def hidden(beta):
        return all_ok(np.where((beta >= 150.0) & (beta < 151.0), 300.0, 30.0))

    d = A.refine(hidden)
    assert d.unresolved_share == 0 and d.evaluations == 32 and d.unchecked.size == 0
    # a budget below n0 + the checks leaves agreeing intervals wider than max_width unchecked
    d = A.refine(hidden, budget=20)
    assert d.unchecked.shape == (12, 2)
    np.testing.assert_allclose(d.unchecked[:, 1] - d.unchecked[:, 0], 22.5)


def test_linear_ramp_is_uniform_and_exact():
    d = A.refine(ramp_map, tolerance_deg=8.0)
    pmf, _ = P.pushforward_pmf(d, BINS, 0.0)
    exact = np.zeros(BINS)
    exact[10:190] = 1 / 180
    assert d.unresolved_share <= d.min_width_deg / 360.0  # one jump, at 360°/0°
    assert sup_cdf(pmf, exact) <= d.unresolved_share + 1e-9
    inner = pmf[12:188]  # bins away from the jump's point masses are exactly uniform
    np.testing.assert_allclose(inner, 1 / 180, rtol=0, atol=1e-12)
    ref, _ = dense_reference(ramp_map)
    assert sup_cdf(pmf, ref) <= d.unresolved_share + NUMERIC
    # smoothing as the workflow's labels: both sides smoothed alike, the bound still holds
    smooth, _ = P.pushforward_pmf(d, BINS, 1.0)
    assert sup_cdf(smooth, C.wrapped_gaussian_smooth(ref, 1.0)) <= d.unresolved_share + NUMERIC


def test_wraparound_basin_is_interpolated_the_short_way():
    d = A.refine(wrap_map)
    pmf, _ = P.pushforward_pmf(d, BINS, 0.0)
    exact = np.zeros(BINS)
    exact[355:] = 0.1
    exact[:5] = 0.1
    assert sup_cdf(pmf, exact) <= d.unresolved_share + 1e-9
    assert pmf[5:355].sum() <= d.unresolved_share + 1e-12  # nothing the long way round
    np.testing.assert_allclose(pmf[[356, 357, 358, 359, 0, 1, 2, 3]], 0.1, atol=d.unresolved_share + 1e-12)


def test_jam_arc_mass():
    d = A.refine(jam_map)
    pmf, masses = P.pushforward_pmf(d, BINS, 1.0)
    assert set(masses) == {"ok", "jammed"}
    assert sum(masses.values()) == pytest.approx(1.0)
    assert masses["jammed"] == pytest.approx(100 / 360, abs=d.unresolved_share + 1e-12)
    assert d.unresolved_share <= 2 * d.min_width_deg / 360.0  # jumps at 90° and 350°
    ref, ref_masses = dense_reference(jam_map)
    assert ref_masses["jammed"] == pytest.approx(100 / 360, abs=1e-5)
    bound = P.label_cdf_bound(d, masses["ok"])
    assert sup_cdf(pmf, C.wrapped_gaussian_smooth(ref, 1.0)) <= bound + NUMERIC
    # the ok basin maps [90, 350) to [49.5, 62.5): the unsmoothed label lives there
    raw, _ = P.pushforward_pmf(d, BINS, 0.0)
    assert raw[:49].sum() < 1e-12 and raw[63:].sum() < 1e-12  # FFT round-off of sigma = 0


def test_no_ok_mass_raises():
    d = A.refine(lambda b: (np.full(b.shape, np.nan), np.full(b.shape, "fell_off")), budget=20)
    assert d.evaluations == 20 and d.unresolved_share == 0  # 4 midpoint checks of the widest intervals
    with pytest.raises(FeederError, match="no ok"):
        P.pushforward_pmf(d, BINS, 1.0)


def chaotic_exact():
    """The band's mass split 50/50 over 10° and 100°, the smooth part's push-forward elsewhere."""
    band_mass = (BAND[1] - BAND[0]) / 360.0
    beta = (np.arange(DENSE) + 0.5) * 360.0 / DENSE
    outside = (beta < BAND[0]) | (beta >= BAND[1])
    exact = L.histogram(smooth_part(beta[outside]), BINS) / DENSE
    exact[10] += band_mass / 2
    exact[100] += band_mass / 2
    assert exact.sum() == pytest.approx(1.0)
    return exact


def test_chaotic_band_terminates_and_is_bounded():
    band_mass = (BAND[1] - BAND[0]) / 360.0
    exact = chaotic_exact()
    ev = Counting(chaotic_map)
    d = A.refine(ev, budget=200)
    assert d.evaluations < 200 and sum(ev.sizes) == d.evaluations  # ended by itself
    pmf, masses = P.pushforward_pmf(d, BINS, 0.0)
    # the unresolved set is the band, to within a bisected interval at either end
    assert d.unresolved.min() >= BAND[0] - d.min_width_deg
    assert d.unresolved.max() <= BAND[1] + d.min_width_deg
    assert band_mass <= d.unresolved_share <= band_mass + 2 * d.min_width_deg / 360.0
    # bisected to the minimum width inside the band
    assert (d.unresolved[:, 1] - d.unresolved[:, 0] <= d.min_width_deg).all()
    assert sup_cdf(pmf, exact) <= P.label_cdf_bound(d, masses["ok"]) + NUMERIC
    smooth, _ = P.pushforward_pmf(d, BINS, 1.0)
    assert sup_cdf(smooth, C.wrapped_gaussian_smooth(exact, 1.0)) <= d.unresolved_share + NUMERIC
    # the band's mass is split about evenly
    assert pmf[10] == pytest.approx(band_mass / 2, abs=d.unresolved_share / 2)


@pytest.mark.parametrize("offset", np.arange(0.0, 11.25, 1.25))
def test_chaotic_band_found_from_any_grid_offset(offset):
    d = A.refine(chaotic_map, budget=200, offset_deg=offset)
    pmf, masses = P.pushforward_pmf(d, BINS, 0.0)
    assert d.unresolved_share >= 0.9 * (BAND[1] - BAND[0]) / 360.0
    assert sup_cdf(pmf, chaotic_exact()) <= P.label_cdf_bound(d, masses["ok"]) + NUMERIC


@pytest.mark.parametrize("budget", [16, 40, 48, 64])
def test_chaotic_band_with_a_small_budget_terminates(budget):
    ev = Counting(chaotic_map)
    d = A.refine(ev, budget=budget)
    assert d.evaluations == budget == sum(ev.sizes)
    assert 0 < d.unresolved_share < 1
    P.pushforward_pmf(d, BINS, 1.0)


def test_fourfold_symmetry_unfolds_to_the_full_circle():
    kw = dict(tolerance_deg=2.0, min_width_deg=0.5, max_width_deg=5.0)
    one = A.refine(symmetric_map, n0=4, budget=200, period_deg=90.0, **kw)
    full = A.refine(symmetric_map, n0=16, budget=800, period_deg=360.0, **kw)
    assert one.evaluations < 200 and full.evaluations < 800  # budgets did not bind
    assert full.evaluations == 4 * one.evaluations
    un = A.unfold(one, 4)
    np.testing.assert_allclose(un.yaws, full.yaws, atol=1e-9)
    np.testing.assert_array_equal(un.status, full.status)
    np.testing.assert_allclose(un.final, full.final, atol=1e-9)
    assert un.unresolved_share == pytest.approx(full.unresolved_share)
    np.testing.assert_allclose(un.unresolved, full.unresolved, atol=1e-9)
    for sigma in (0.0, 1.0):
        p1, m1 = P.pushforward_pmf(one, BINS, sigma)  # unfolds by itself
        p2, m2 = P.pushforward_pmf(full, BINS, sigma)
        np.testing.assert_allclose(p1, p2, atol=1e-12)
        assert m1.keys() == m2.keys() and all(m1[k] == pytest.approx(m2[k]) for k in m1)
    ref, ref_masses = dense_reference(symmetric_map)
    p1, m1 = P.pushforward_pmf(one, BINS, 0.0)
    assert m1["jammed"] == pytest.approx(ref_masses["jammed"], abs=one.unresolved_share + 1e-5)
    assert sup_cdf(p1, ref) <= P.label_cdf_bound(one, m1["ok"]) + NUMERIC
    with pytest.raises(FeederError):
        A.unfold(one, 3)


@pytest.mark.parametrize("fmap", [step_map, ramp_map, wrap_map, jam_map, chaotic_map, symmetric_map])
@pytest.mark.parametrize("budget", [16, 17, 20, 31, 33, 40, 64, 101])
def test_budget_never_exceeded_and_batched(fmap, budget):
    ev = Counting(fmap)
    d = A.refine(ev, n0=16, budget=budget, offset_deg=3.7)
    assert d.evaluations <= budget
    assert d.evaluations == d.yaws.size == sum(ev.sizes)
    assert d.calls == ev.calls
    assert ev.sizes[0] == 16
    assert ev.calls <= 1 + max(0, d.evaluations - 16)  # every later call simulates ≥ 1 yaw
    if budget == 16:
        assert ev.calls == 1
    # each round is one batch: far fewer calls than simulations once refinement runs
    if d.evaluations >= 40:
        assert ev.calls <= 12
    seen = np.concatenate(ev.seen)
    assert np.unique(np.round(seen, 9)).size == seen.size  # no yaw simulated twice
    assert (np.diff(d.yaws) > 0).all()
    assert d.yaws[0] >= d.offset_deg and d.yaws[-1] < d.offset_deg + d.period_deg


def test_widest_first_when_the_budget_binds():
    # 16 grid intervals of 22.5°, two disagree; a budget of 18 bisects exactly those two first
    ev = Counting(step_map)
    A.refine(ev, budget=18)
    assert ev.sizes == [16, 2]
    np.testing.assert_allclose(np.sort(ev.seen[1]), [123.75, 348.75])
    # budget 20: the two disagreeing intervals come before the agreeing checks of equal width
    ev = Counting(step_map)
    A.refine(ev, budget=20)
    assert ev.sizes == [16, 4]
    assert {123.75, 348.75} <= set(np.round(ev.seen[1], 9))


def test_offset_and_wrapping_interval():
    d = A.refine(step_map, offset_deg=-10.0)
    assert d.offset_deg == pytest.approx(350.0)
    assert d.yaws.min() >= 350.0 and d.yaws.max() < 710.0
    pmf, _ = P.pushforward_pmf(d, BINS, 0.0)
    assert pmf[30] == pytest.approx(1 / 3, abs=d.unresolved_share + 1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(budget=10), "budget"),
        (dict(n0=1, budget=10), "n0"),
        (dict(n0=2.5), "n0"),
        (dict(tolerance_deg=0.0), "tolerance"),
        (dict(tolerance_deg=-1.0), "tolerance"),
        (dict(min_width_deg=0.0), "min_width"),
        (dict(min_width_deg=float("nan")), "min_width"),
        (dict(period_deg=50.0), "divide"),
        (dict(period_deg=0.0), "period"),
        (dict(period_deg=720.0), "period"),
        (dict(max_width_deg=0.1), "max_width"),
        (dict(band_gap_deg=-1.0), "band_gap"),
        (dict(edge_check_deg=-1.0), "edge_check"),
        (dict(offset_deg=float("inf")), "offset"),
    ],
)
def test_bad_inputs_raise(kwargs, match):
    with pytest.raises(FeederError, match=match):
        A.refine(step_map, **kwargs)


def test_bad_evaluations_raise():
    with pytest.raises(FeederError, match="returned"):
        A.refine(lambda b: (b[:-1], np.full(b.size - 1, "ok")))
    with pytest.raises(FeederError, match="non-finite"):
        A.refine(lambda b: (np.full(b.shape, np.nan), np.full(b.shape, "ok")))
    with pytest.raises(FeederError):
        A.refine(lambda b: b)
    d = A.refine(step_map)
    with pytest.raises(FeederError):
        P.pushforward_pmf(d, 0, 1.0)
    with pytest.raises(FeederError):
        P.pushforward_pmf(d, BINS, -1.0)
    with pytest.raises(FeederError):
        P.emulate_drops(d, -1, 0)


@pytest.mark.parametrize("fmap", [jam_map, chaotic_map, wrap_map])
def test_emulated_drops_match_the_pushforward(fmap):
    d = A.refine(fmap, budget=100)
    pmf, masses = P.pushforward_pmf(d, BINS, 0.0)
    final, status = P.emulate_drops(d, 100_000, seed=7)
    ok = status == "ok"
    assert np.isnan(final[~ok]).all() and np.isfinite(final[ok]).all()
    assert ((final[ok] >= 0) & (final[ok] < 360)).all()
    for s, m in masses.items():
        assert np.mean(status == s) == pytest.approx(m, abs=0.005)
    emp = L.histogram(final[ok], BINS) / ok.sum()
    assert sup_cdf(emp, pmf) <= 0.01
    # seeded: the same drops again, other drops for another seed
    again, _ = P.emulate_drops(d, 100_000, seed=7)
    np.testing.assert_array_equal(final, again)
    other, _ = P.emulate_drops(d, 100_000, seed=8)
    assert not np.array_equal(np.nan_to_num(final), np.nan_to_num(other))


def test_emulated_drops_unfold_symmetric_designs():
    d = A.refine(symmetric_map, n0=4, budget=60, period_deg=90.0, max_width_deg=5.0)
    pmf, masses = P.pushforward_pmf(d, BINS, 0.0)
    final, status = P.emulate_drops(d, 100_000, seed=1)
    ok = status == "ok"
    assert np.mean(status == "jammed") == pytest.approx(masses["jammed"], abs=0.005)
    assert sup_cdf(L.histogram(final[ok], BINS) / ok.sum(), pmf) <= 0.01


def test_a_steep_smooth_map_is_resolved_not_bisected_as_jumps():
    """With no fence in reach the map is the identity: 22.5° of final yaw between grid samples is
    a slope, not a jump. Refinement stops after the first round of midpoint checks, the label is
    the exact uniform push-forward, and nothing is left unresolved."""
    calls = []

    def identity(yaws):
        calls.append(len(yaws))
        return np.asarray(yaws, dtype=float) % 360.0, np.full(len(yaws), "ok")

    design = A.refine(identity, n0=16, budget=64, offset_deg=3.0)
    assert design.unresolved_share == 0.0 and design.evaluations == 32
    pmf, masses = P.pushforward_pmf(design, 360, 0.0)
    np.testing.assert_allclose(pmf, np.full(360, 1.0 / 360.0), atol=1e-12)
    # a jump inside a steep map is still a jump: identity with a 90° step at 200°
    stepped = A.refine(
        lambda y: ((np.asarray(y) + 90.0 * (np.asarray(y) >= 200.0)) % 360.0, np.full(len(y), "ok")),
        n0=16,
        budget=96,
        offset_deg=3.0,
    )
    assert 0 < stepped.unresolved_share <= 3 * 0.5 / 360.0 + 1e-12


def test_two_basins_half_a_turn_apart_alternating_are_never_a_slope():
    """The review's counterexample (finals 10, 190.2, 10.4, 190.6, ... on a 30° grid): drifting by
    −179.8° a step, the wrapped changes all have one sign and one size, a steady "slope" that only
    the under-90° guard refuses. They must stay jumps."""
    yaws = np.arange(12) * 30.0
    final = np.mod(10.0 - 179.8 * np.arange(12), 360.0)
    design = A.design_from_samples(
        yaws,
        final,
        np.full(12, "ok"),
        period_deg=360.0,
        offset_deg=0.0,
        tolerance_deg=2.0,
        min_width_deg=30.0,
        max_width_deg=30.0,
    )
    assert design.unresolved_share == pytest.approx(1.0)  # every interval unresolved
    pmf, _ = P.pushforward_pmf(design, 360, 0.0)
    assert pmf[(pmf > 1e-12)].size <= 12  # all mass on sampled outcomes, none smeared between basins


def test_a_slope_from_a_narrow_noisy_neighbour_does_not_hide_a_jump():
    """A 9.7° jump across an 11.25° interval between two 0.35° neighbours that both slope the same
    way (so both would predict it); the rest of the map is resolved (flat, one narrow jump back),
    so only the neighbour-width guard keeps the interval unresolved."""
    yaws = np.array([0.0, 0.35, 11.6, 11.95, 300.0, 300.25])
    final = np.array([10.0, 10.3, 20.0, 20.3, 20.3, 10.0])
    design = A.design_from_samples(
        yaws,
        final,
        np.full(6, "ok"),
        period_deg=360.0,
        offset_deg=0.0,
        tolerance_deg=2.0,
        min_width_deg=0.25,
        max_width_deg=400.0,
    )
    assert [0.35, 11.6] in design.unresolved.tolist()
    assert design.unresolved_share == pytest.approx((11.25 + 0.25) / 360.0)


def narrow_ok_map(beta):
    """Every drop jams but those in a 10° window (which the start grid of 16 cannot hit at offset 3.7)."""
    ok = (beta >= 30.0) & (beta < 40.0)
    return np.where(ok, 100.0, np.nan), np.where(ok, "ok", "jammed")


def all_fell_map(beta):
    return np.full(np.shape(beta), np.nan), np.full(np.shape(beta), "fell_off")


@pytest.mark.parametrize("fmap", [narrow_ok_map, all_fell_map])
def test_stop_if_none_ok_ends_after_the_start_grid_when_no_start_drop_is_ok(fmap):
    """No ok drop among the n0 start drops: the stop ends the design there (one call of 16). Without
    it the midpoint checks run on: 32 simulations where every drop fails; on the narrow window a
    check lands in it and bisection spends the budget, finding ok mass (10/360) the stop gives up:
    far below sim.min_ok_mass, so the configuration is excluded either way."""
    ev = Counting(fmap)
    d = A.refine(ev, n0=16, budget=40, offset_deg=3.7, stop_if_none_ok=True)
    assert (d.evaluations, d.calls, ev.calls) == (16, 1, 1)
    assert not np.any(d.status == "ok")
    on = A.refine(Counting(fmap), n0=16, budget=40, offset_deg=3.7)
    assert np.all(np.isin(np.round(d.yaws, 9), np.round(on.yaws, 9)))  # the same start grid
    if fmap is narrow_ok_map:
        assert on.evaluations == 40 and np.any(on.status == "ok")
    else:
        assert on.evaluations == 32 and not np.any(on.status == "ok")


@pytest.mark.parametrize("fmap", [step_map, jam_map, chaotic_map])
def test_stop_if_none_ok_changes_nothing_when_a_start_drop_is_ok(fmap):
    a = A.refine(Counting(fmap), n0=16, budget=40, offset_deg=3.7, stop_if_none_ok=True)
    b = A.refine(Counting(fmap), n0=16, budget=40, offset_deg=3.7)
    np.testing.assert_array_equal(a.yaws, b.yaws)
    np.testing.assert_array_equal(a.status, b.status)
    assert a.evaluations == b.evaluations and a.unresolved_share == b.unresolved_share
