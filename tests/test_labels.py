import math

import numpy as np
import pytest

from feeder import circular as C
from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.labels import pmf as pmf_cli

# Z = sum over all integer offsets d of exp(-d^2 / 2) (sigma = 1 bin), written out by hand
Z = 1 + 2 * sum(math.exp(-d * d / 2) for d in range(1, 40))
E1, E2, E3 = math.exp(-0.5), math.exp(-2.0), math.exp(-4.5)


def test_normalize_yaw_hand_values():
    beta = np.array([-180.0, -0.5, 0.0, 359.5, 360.0, 720.25, -400.0, 179.999])
    expect = np.array([180.0, 359.5, 0.0, 359.5, 0.0, 0.25, 320.0, 179.999])
    np.testing.assert_allclose(C.normalize_yaw(beta), expect, atol=1e-12)


def test_normalize_yaw_never_returns_360_and_keeps_nan():
    out = C.normalize_yaw([-1e-20, -360 - 1e-15, -1e-13, np.nan, np.inf])
    assert (out[:3] >= 0).all() and (out[:3] < 360).all()
    assert np.isnan(out[3:]).all()


def test_histogram_wraparound_bins():
    h = L.histogram([359.5, 0.5, -0.5, 360.5], 360)
    assert h[359] == 2 and h[0] == 2 and h.sum() == 4
    h4 = L.histogram([0.0, 89.999, 90.0, 359.999999], 4)
    np.testing.assert_array_equal(h4, [2, 1, 0, 1])
    with pytest.raises(FeederError):
        L.histogram([1.0, np.nan], 360)


def test_kernel_hand_values():
    k = C.wrapped_gaussian_kernel(360, 1.0)
    assert k.sum() == pytest.approx(1.0)
    assert k[0] == pytest.approx(1 / Z)
    assert k[1] == pytest.approx(E1 / Z) and k[359] == pytest.approx(E1 / Z)
    assert k[2] == pytest.approx(E2 / Z) and k[358] == pytest.approx(E2 / Z)
    np.testing.assert_array_equal(C.wrapped_gaussian_kernel(8, 0.0), [1, 0, 0, 0, 0, 0, 0, 0])


def test_all_mass_in_one_bin_spreads_to_both_neighbours():
    pmf = L.pmf_from_yaws([0.2] * 7, 360, 1.0)
    assert pmf.sum() == pytest.approx(1.0)
    assert pmf[0] == pytest.approx(1 / Z)
    assert pmf[1] == pytest.approx(E1 / Z) and pmf[359] == pytest.approx(E1 / Z)
    assert pmf[3] == pytest.approx(E3 / Z) and pmf[357] == pytest.approx(E3 / Z)
    assert pmf[180] < 1e-12


def test_wraparound_mass_at_359_5_and_0_5():
    pmf = L.pmf_from_yaws([359.5, 0.5], 360, 1.0)
    assert pmf[0] == pytest.approx((1 + E1) / (2 * Z))
    assert pmf[359] == pytest.approx((1 + E1) / (2 * Z))
    assert pmf[1] == pytest.approx((E1 + E2) / (2 * Z))
    assert pmf[358] == pytest.approx((E1 + E2) / (2 * Z))
    c = L.cdf(pmf)
    assert c[-1] == pytest.approx(1.0)
    assert c[0] == pytest.approx(pmf[0])


def test_uniform_stays_uniform_and_cdf_is_linear():
    pmf = C.wrapped_gaussian_smooth(np.ones(360), 1.0)
    np.testing.assert_allclose(pmf, 1 / 360)
    np.testing.assert_allclose(L.cdf(pmf), np.arange(1, 361) / 360)


def test_zeros_are_errors_not_nan():
    with pytest.raises(FeederError):
        C.wrapped_gaussian_smooth(np.zeros(360), 1.0)
    with pytest.raises(FeederError):
        L.pmf_from_yaws([], 360, 1.0)


def test_smoothing_is_vectorised_over_rows():
    rows = np.zeros((2, 360))
    rows[0, 10] = 3
    rows[1, 200] = 1
    out = C.wrapped_gaussian_smooth(rows, 1.0)
    np.testing.assert_allclose(out.sum(axis=1), 1.0)
    assert out[0, 10] == pytest.approx(1 / Z) and out[1, 201] == pytest.approx(E1 / Z)


def test_js_hand_values():
    assert L.js_divergence([1, 0], [0, 1]) == pytest.approx(1.0)
    # m = (.75, .25): KL(p||m) = .5 log2(2/3) + .5 log2(2), KL(q||m) = log2(4/3)
    expect = 0.5 * (0.5 * math.log2(2 / 3) + 0.5) + 0.5 * math.log2(4 / 3)
    assert L.js_divergence([0.5, 0.5], [1.0, 0.0]) == pytest.approx(expect)
    u = np.full(360, 1 / 360)
    assert L.js_divergence(u, u) == 0.0
    rows = L.js_divergence(np.array([[1, 0], [0.5, 0.5]]), np.array([0, 1]))
    np.testing.assert_allclose(rows, [1.0, expect])  # mirror image of the case above


def test_w1_ks_mse_hand_values():
    a = np.ones(360)  # all mass in bin 0
    b = np.r_[0.0, np.ones(359)]  # all mass in bin 1
    assert L.w1(a, b) == pytest.approx(1.0)
    assert L.ks(a, b) == 1.0
    assert L.mse(a, b) == pytest.approx(1 / 360)
    c4 = np.array([0.25, 0.5, 0.75, 1.0])
    d4 = np.array([0.0, 0.5, 1.0, 1.0])
    assert L.w1(c4, d4) == pytest.approx(90 * 0.5)  # 4 bins of 90 degrees
    assert L.ks(c4, d4) == 0.25
    assert L.mse(c4, d4) == pytest.approx((0.0625 + 0.0625) / 4)


def test_r2_cdf_hand_values_and_constant_truth():
    t = np.array([0.0, 0.5, 1.0, 1.0])
    p = np.array([0.0, 0.5, 0.5, 1.0])
    # mean .625; SS_tot = .390625 + .015625 + .140625 + .140625 = .6875; SS_res = .25
    assert L.r2_cdf(t, p) == pytest.approx(1 - 0.25 / 0.6875)
    assert L.r2_cdf(t, t) == 1.0
    const = np.ones(4)
    assert L.r2_cdf(const, const) == 1.0
    assert L.r2_cdf(const, p) == 0.0
    np.testing.assert_allclose(L.r2_cdf(np.stack([t, const]), np.stack([p, const])), [1 - 0.25 / 0.6875, 1.0])


def test_partial_pmfs_first_k_percent_of_all_drops():
    yaws = np.array([10, np.nan, 100, 190, np.nan, 280, 10, 10, 100, 10], dtype=float)
    pmfs, n_ok = L.partial_pmfs(yaws, [10, 20, 50, 100], bins=4, sigma=0.0)
    # first 1, 2, 5, 10 drops; ok among them: 1, 1, 3, 8
    np.testing.assert_array_equal(n_ok, [1, 1, 3, 8])
    np.testing.assert_allclose(pmfs[0], [1, 0, 0, 0])
    np.testing.assert_allclose(pmfs[1], [1, 0, 0, 0])
    np.testing.assert_allclose(pmfs[2], [1 / 3, 1 / 3, 1 / 3, 0])
    np.testing.assert_allclose(pmfs[3], [4 / 8, 2 / 8, 1 / 8, 1 / 8])


def test_partial_pmfs_level_without_ok_drops_is_uniform_and_counted():
    yaws = np.array([np.nan, np.nan, 5.0, 95.0])
    pmfs, n_ok = L.partial_pmfs(yaws, [25, 50, 100], bins=4, sigma=0.0)
    np.testing.assert_array_equal(n_ok, [0, 0, 2])
    np.testing.assert_allclose(pmfs[0], 0.25)
    np.testing.assert_allclose(pmfs[2], [0.5, 0.5, 0, 0])
    with pytest.raises(FeederError):
        L.partial_pmfs(yaws, [50], bins=4, sigma=0.0, ok=np.ones(4, bool))


def test_partial_full_level_matches_pmf_from_yaws():
    rng = np.random.default_rng(3)
    yaws = rng.uniform(0, 360, 200)
    yaws[rng.random(200) < 0.1] = np.nan
    pmfs, n_ok = L.partial_pmfs(yaws, [100], bins=360, sigma=1.0)
    np.testing.assert_allclose(pmfs[0], L.pmf_from_yaws(yaws[np.isfinite(yaws)], 360, 1.0))
    assert n_ok[0] == np.isfinite(yaws).sum()


def test_ecdf_sup_and_dkw():
    assert L.ecdf_sup_distance([1.0], [1.0, 2.0]) == 0.5
    assert L.ecdf_sup_distance([1.0, 2.0], [1.0, 2.0]) == 0.0
    assert L.ecdf_sup_distance([3.0], [1.0, 2.0]) == 1.0
    assert L.dkw_epsilon(100, 0.05) == pytest.approx(math.sqrt(math.log(40) / 200))


def test_labels_cli_summarises_a_sim_file(tmp_path, capsys):
    import json

    path = tmp_path / "s.npz"
    status = np.array(["ok", "ok", "jammed", "ok"])
    np.savez(
        path,
        final_yaw_deg=np.array([10.2, 10.7, np.nan, 350.0]),
        status=status,
        initial_yaw_deg=np.zeros(4),
        wall_s=np.float64(1.0),
        meta=np.array("{}"),
    )
    assert pmf_cli.main(["pmf", str(path), "--bins", "360", "--sigma", "1"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["simulations"] == 4 and out["masses"] == {"jammed": 0.25, "ok": 0.75} and out["mode_deg"] == 10.5
    assert out["design"] == "random" and out["cdf_bound"] is None  # a file from before the key: random


# ---------------------------------------------------------------- shifting a PMF between frames
def test_shift_pmf_hand_values():
    p = np.zeros(360)
    p[0] = 1.0
    np.testing.assert_array_equal(L.shift_pmf(p, 1.0), np.roll(p, 1))  # whole bins: a roll
    np.testing.assert_array_equal(L.shift_pmf(p, 360.0), p)
    np.testing.assert_array_equal(L.shift_pmf(p, -1.0), np.roll(p, -1))  # wraps 0 -> 359
    half = L.shift_pmf(p, 0.5)  # half a bin: split between bins 0 and 1
    assert half[0] == pytest.approx(0.5) and half[1] == pytest.approx(0.5) and half.sum() == pytest.approx(1.0)
    back = L.shift_pmf(p, -0.5)  # wrap-around at 0/360: bins 359 and 0
    assert back[359] == pytest.approx(0.5) and back[0] == pytest.approx(0.5)
    q = L.shift_pmf(p, 90.25)
    assert q[90] == pytest.approx(0.75) and q[91] == pytest.approx(0.25)


def test_shift_pmf_matches_shifting_the_yaws_and_conserves_mass():
    rng = np.random.default_rng(3)
    yaws = rng.uniform(0, 360, 500)
    p = L.pmf_from_yaws(yaws, 360, 1.0)
    for delta in (17.0, -123.0, 359.0, 720.0):
        np.testing.assert_allclose(
            L.shift_pmf(p, delta), L.pmf_from_yaws(C.normalize_yaw(yaws + delta), 360, 1.0), atol=1e-12
        )
    batch = rng.dirichlet(np.ones(360), size=4)
    for delta in (0.3, 200.7, -45.9):
        out = L.shift_pmf(batch, delta)
        np.testing.assert_allclose(out.sum(axis=1), 1.0)
        assert (out >= 0).all()
        np.testing.assert_allclose(L.shift_pmf(out, -delta).sum(axis=1), 1.0)
    np.testing.assert_array_equal(L.shift_pmf(np.zeros(360), 12.5), np.zeros(360))  # zeros stay zeros
    with pytest.raises(FeederError):
        L.shift_pmf(p, float("nan"))


# ---------------------------------------------------------------- circular W1
def test_circular_w1_hand_values_and_wrap_around():
    a, b = np.zeros(360), np.zeros(360)
    a[359], b[1] = 1.0, 1.0  # point masses 2 degrees apart across 0/360
    assert L.w1(L.cdf(a), L.cdf(b)) == pytest.approx(358.0)
    assert L.circular_w1(L.cdf(a), L.cdf(b)) == pytest.approx(2.0)
    c = np.zeros(360)
    c[[10, 190]] = 0.5  # two opposite halves against a point between them: each half moves 90
    d = np.zeros(360)
    d[100] = 1.0
    assert L.circular_w1(L.cdf(c), L.cdf(d)) == pytest.approx(90.0)
    assert L.circular_w1(L.cdf(a), L.cdf(a)) == 0.0


def test_circular_w1_does_not_depend_on_where_the_circle_is_cut():
    rng = np.random.default_rng(3)
    p, q = rng.dirichlet(np.ones(72)), rng.dirichlet(np.ones(72))
    base = L.circular_w1(L.cdf(p), L.cdf(q))
    for k in (1, 17, 50):
        assert L.circular_w1(L.cdf(np.roll(p, k)), L.cdf(np.roll(q, k))) == pytest.approx(base)
    assert base <= L.w1(L.cdf(p), L.cdf(q)) + 1e-12


# ---------------------------------------------------------------- R² at the best common cut
def test_r2_best_cut_hand_values_across_the_wrap():
    """8 bins; a point mass predicted one bin late. With truth at bin 3 the paper's R² is
    1 - 1/1.875; with truth at bin 7 (prediction at bin 0, across 0/360) it is 1 - 7/0.875 = -7.
    At the best cut both are the same configuration up to rotation: the truth's CDF holds k ones
    out of 8 with a one-bin error, R² = 1 - 1 / (k (8 - k) / 8), best at k = 4: 0.5."""

    def point(k):
        p = np.zeros(8)
        p[k] = 1.0
        return L.cdf(p)

    assert L.r2_cdf(point(3), point(4)) == pytest.approx(1 - 1 / 1.875)
    assert L.r2_cdf(point(7), point(0)) == pytest.approx(-7.0)
    assert L.r2_cdf_best_cut(point(3), point(4)) == pytest.approx(0.5)
    assert L.r2_cdf_best_cut(point(7), point(0)) == pytest.approx(0.5)
    assert L.r2_cdf_best_cut(point(5), point(5)) == pytest.approx(1.0)


def test_r2_best_cut_does_not_depend_on_the_frame_and_bounds_the_paper_r2():
    rng = np.random.default_rng(4)
    p, q = rng.dirichlet(np.ones(72), size=3), rng.dirichlet(np.ones(72), size=3)
    base = L.r2_cdf_best_cut(L.cdf(p), L.cdf(q))
    assert base.shape == (3,)
    for k in (1, 17, 50):
        rolled = L.r2_cdf_best_cut(L.cdf(np.roll(p, k, axis=-1)), L.cdf(np.roll(q, k, axis=-1)))
        np.testing.assert_allclose(rolled, base)
    assert (base >= L.r2_cdf(L.cdf(p), L.cdf(q)) - 1e-12).all()


def test_r2_best_cut_every_cut_at_once_equals_the_cut_by_cut_definition():
    """The prefix-sum form scores every cut as rebuilding both CDFs from that cut does: smooth,
    sharp (one bin, across 0/360), unnormalised and constant predictions, a truth with all its mass
    in one bin (scored cut by cut, exactly), in a batch of any shape."""
    rng = np.random.default_rng(11)
    n = 360
    smooth = rng.dirichlet(np.full(n, 0.05), size=(4, 6))
    sharp = np.zeros((3, n))
    sharp[0, 0], sharp[1, 359], sharp[2, [0, 359]] = 1.0, 1.0, 0.5
    truths = [L.cdf(smooth), L.cdf(sharp)]
    preds = [L.cdf(rng.dirichlet(np.ones(n), size=(4, 6))) * 0.97 + 0.01, L.cdf(np.roll(sharp, 2, axis=-1))]
    for t, q in zip(truths, preds, strict=True):
        fast = L.r2_cdf_best_cut(t, q)
        assert fast.shape == t.shape[:-1]
        slow = L._r2_cdf_best_cut_by_cuts(t.reshape(-1, n), q.reshape(-1, n)).reshape(t.shape[:-1])
        np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-10)
    flat = np.full(n, 1.0 / n)
    np.testing.assert_allclose(
        L.r2_cdf_best_cut(L.cdf(smooth[0]), L.cdf(flat)),
        L._r2_cdf_best_cut_by_cuts(L.cdf(smooth[0]), np.broadcast_to(L.cdf(flat), (6, n))),
        rtol=0,
        atol=1e-10,
    )
    assert L.r2_cdf_best_cut(L.cdf(sharp[0]), L.cdf(sharp[0])) == 1.0  # exact, as r2_cdf's constant case


def test_is_uniform_takes_rounding_noise_as_flat_and_a_real_bump_as_not():
    from feeder.labels.metrics import is_uniform

    flat = np.full(360, 1.0 / 360)
    assert is_uniform(flat)
    noisy = flat.copy()
    noisy[216] = np.nextafter(noisy[216], 1.0)  # one ulp above the rest, as a summed PMF can be
    assert is_uniform(noisy)
    assert is_uniform(0.3 * flat)  # a PMF over the drops that leave: total below 1
    bump = flat.copy()
    bump[0] *= 1.001  # 0.1 % above the rest: a preferred orientation, however slight
    assert not is_uniform(bump)
    assert not is_uniform(np.zeros(360))  # nothing leaves: not "every orientation equally likely"
    assert not is_uniform(np.array([0.5, 0.5, np.nan]))
    with pytest.raises(FeederError, match="1-D PMF"):
        is_uniform(np.ones((2, 3)))


def test_resting_orientations_are_the_modes_with_their_basin_mass():
    from feeder.labels.metrics import resting_orientations as modes

    def resting_orientations(pmf, top=None):
        return np.asarray(modes(pmf, top)).ravel().tolist()

    # 8 bins of 45 deg: peaks at bins 2 and 6, each collecting the bins that climb to it
    two = [0.0, 0.1, 0.3, 0.1, 0.0, 0.2, 0.25, 0.05]
    assert resting_orientations(two) == pytest.approx([112.5, 0.5, 292.5, 0.5])
    assert resting_orientations(two, top=1)[0] in (112.5, 292.5)
    # a flat peak across 0/360 is one orientation at 0 deg; empty bins are none
    wrap = [0.4, 0.1, 0, 0, 0, 0, 0.1, 0.4]
    assert resting_orientations(wrap) == pytest.approx([0.0, 1.0])
    unequal = [0.1, 0.6, 0.1, 0.0, 0.0, 0.0, 0.2, 0.0]
    assert resting_orientations(unequal) == pytest.approx([67.5, 0.8, 292.5, 0.2])
    assert resting_orientations(np.full(4, 0.25)) == pytest.approx([180.0, 1.0])
