"""The part's own neighbour (feeder.learn.neighbour): nearest angle, the analytic shift, the fallback."""

from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

from feeder.errors import FeederError
from feeder.learn import neighbour as N
from feeder.learn.prior import Grids

BINS = 360


def spike(deg: int, bins: int = BINS) -> np.ndarray:
    p = np.zeros(bins)
    p[deg % bins] = 1.0
    return p


def test_fence_key_by_hand():
    assert N.fence_key("straight30_none") == (("straight", "none"), (30.0, 0.0))
    assert N.fence_key("curved0_straight45") == (("curved", "straight"), (0.0, 45.0))


def test_nearest_angle_of_the_same_part_and_combination():
    parts = ["a", "a", "a", "a", "b", "a"]
    cids = [
        "straight30_none",
        "straight40_none",
        "straight50_none",
        "none_straight35",
        "straight35_none",
        "straight36_none",
    ]
    train = np.array([1, 1, 1, 1, 1, 0], bool)
    # row 5 (a, straight36): 40 is 4 deg away, 30 six; b's straight35 and a's none_straight35 do not count
    assert N.neighbour_index(parts, cids, train, [5]).tolist() == [1]
    # a tie (35 between 30 and 40) goes to the earlier row; a row is never its own neighbour
    assert N.neighbour_index(parts[:4] + ["a"], cids[:4] + ["straight35_none"], np.ones(5, bool), [4]).tolist() == [0]
    assert N.neighbour_index(parts, cids, train, [3, 4]).tolist() == [-1, -1]  # alone in its group


def test_two_fence_distance_sums_both_angles():
    parts = ["a"] * 3
    cids = ["straight30_curved20", "straight40_curved20", "straight32_curved30"]
    # to row 2: |30-32| + |20-30| = 12 against |40-32| + |20-30| = 18
    assert N.neighbour_index(parts, cids, np.array([1, 1, 0], bool), [2]).tolist() == [0]


def test_best_shift_by_hand_and_across_zero():
    assert N.best_shift(spike(15), spike(10), 30) == 5
    assert N.best_shift(spike(2), spike(357), 30) == 5  # across 0/360
    assert N.best_shift(spike(357), spike(2), 30) == -5
    assert N.best_shift(spike(100), spike(10), 30) in range(-30, 31)  # out of reach: stays within the bound
    assert N.best_shift(spike(10), spike(10), 30) == 0
    assert N.best_shift(np.zeros(BINS), spike(10), 30) == 0  # no analytic mass: no shift
    # a symmetric PMF: shift 0 is exact
    two = (spike(0) + spike(180)) / 2
    assert N.best_shift(two, two, 30) == 0


def test_roll_wraps():
    np.testing.assert_array_equal(N.roll_pmf(spike(358), 5), spike(3))


def test_neighbour_pmfs_shift_the_label_and_fall_back_to_analytic():
    parts = ["a", "a", "b"]
    cids = ["straight30_none", "straight40_none", "straight40_none"]
    label = np.stack([spike(100), np.zeros(BINS), np.zeros(BINS)])
    label[0, 101] = 1.0
    label[0] /= 2
    analytic = np.stack([spike(90), spike(97), spike(200)])
    out = N.neighbour_pmfs(label, analytic, parts, cids, np.array([1, 0, 0], bool), [1, 2], 30)
    assert out["index"].tolist() == [0, -1] and out["shift"].tolist() == [7, 0]
    np.testing.assert_array_equal(out[N.NEIGHBOUR][0], label[0])
    np.testing.assert_array_equal(out[N.SHIFTED][0], np.roll(label[0], 7))
    np.testing.assert_array_equal(out[N.SHIFTED][1], analytic[2])  # no row of part b to learn from
    assert out["fallback"].tolist() == [False, True]


def _data():
    """A known part whose basin follows the fence angle (final yaw = 2 x angle), a few parts."""
    rng = np.random.default_rng(0)
    parts, cids, split, pmf, analytic = [], [], [], [], []
    for p in range(6):
        for a in range(15, 65, 5):
            parts.append(f"p{p}")
            cids.append(f"straight{a}_none")
            split.append("test" if rng.random() < 0.25 else "train")
            pmf.append(spike(2 * a + 3 * p))
            analytic.append(spike(2 * a + 3 * p + 4))  # right shape, offset by 4 deg
    return {
        "part": np.array(parts),
        "config_id": np.array(cids),
        "split": np.array(split),
        "pmf": np.stack(pmf),
        "pmf_analytic": np.stack(analytic),
    }


def _cfg(**neighbour):
    return OmegaConf.create(
        {
            "seed": 1,
            "protocol": {
                "main_repeats": 2,
                "test_fraction": 0.25,
                "bootstrap": {"resamples": 200, "level": 0.95, "seed": 0},
            },
            "neighbour": {"max_shift_deg": 30.0, "gates_deg": [0, 5, 90], **neighbour},
        }
    )


GRIDS = Grids(sigmas_bins=(0.0, 2.0), weights=(1.0, 0.5))


def test_the_experiment_on_a_part_whose_basin_follows_the_angle():
    long, table = N.run_neighbour(_data(), _cfg(), GRIDS)
    cw1 = table[table.metric == "cw1"].set_index(["predictor", "baseline"])
    # the shifted neighbour carries the 10-deg-per-5-deg step exactly; the analytic PMF is 4 deg off
    assert cw1.loc[(N.SHIFTED, N.ANALYTIC), "value"] == pytest.approx(0.0, abs=1e-9)
    assert cw1.loc[(N.SHIFTED, N.ANALYTIC), "baseline_value"] == pytest.approx(4.0)
    assert cw1.loc[(N.NEIGHBOUR, N.ANALYTIC), "value"] > 5.0  # the nearest angle as it is: 10 deg or more off
    assert set(cw1.loc[N.SHIFTED, "verdict"]) == {"better"}  # against every baseline and the plain neighbour
    assert len(table) == 2 * len(N.COMPARISONS)
    assert set(long.repeat) == {0, 1} and not long.fallback.any()
    # repeat 0 is the dataset's own Test split
    own = set(zip(*(_data()[k][_data()["split"] == "test"] for k in ("part", "config_id")), strict=True))
    assert set(zip(long[long.repeat == 0].part, long[long.repeat == 0].config_id, strict=True)) == own


@pytest.mark.parametrize(
    "data, cfg, message",
    [
        ({k: v for k, v in _data().items() if k != "pmf_analytic"}, _cfg(), "pmf_analytic"),
        (_data(), _cfg(max_shift_deg=-1), "max_shift_deg"),
        (dict(_data(), split=np.array(["fences"] * 60)), _cfg(), "no Main rows"),
    ],
)
def test_bad_input_is_one_clear_error(data, cfg, message):
    with pytest.raises(FeederError, match=message):
        N.run_neighbour(data, cfg, GRIDS)


def test_the_gate_is_chosen_on_training_rows_by_hand():
    # part a: the label does not move with the angle (the neighbour is exact), the analytic PMF is
    # 4 deg off; angles 5 deg apart, so every gate from 5 on scores 0 and 5 is the smallest
    parts = ["a"] * 4
    cids = ["straight20_none", "straight25_none", "straight30_none", "straight35_none"]
    pmf = np.stack([spike(50)] * 4)
    analytic = np.stack([spike(54)] * 4)
    train = np.ones(4, bool)
    assert N.choose_gate(pmf, analytic, parts, cids, train, [0, 2.5, 5, 10]) == 5.0
    assert N.choose_gate(pmf, analytic, parts, cids, train, [10, 0]) == 10.0
    # the analytic PMF exact instead: no neighbour is better, gate 0 (the analytic PMF everywhere)
    assert N.choose_gate(analytic, analytic, parts, cids, train, [0, 5, 10]) == 0.0
    assert N.angle_distance("straight30_curved20", "straight35_curved40") == 25.0


def test_the_gated_neighbour_follows_its_gate():
    long, _ = N.run_neighbour(_data(), _cfg(gates_deg=[0, 5]), GRIDS)
    # on _data the neighbour (10 deg off) is worse than the analytic PMF (4 deg): gate 0, the analytic PMF
    gated = long[long.predictor == N.GATED]
    assert set(gated.gate_deg) == {0.0}
    assert gated.cw1.to_numpy() == pytest.approx(long[long.predictor == N.ANALYTIC].cw1.to_numpy())
