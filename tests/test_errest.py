"""The label error estimate (feeder.sim.errest), the targeted design and feeder bench-errest's
bad input, on hand-made maps whose errors are computed by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from feeder.bench import errest as BE
from feeder.cli import main
from feeder.errors import FeederError
from feeder.sim import errest as E
from feeder.sim.adaptive import design_from_samples
from feeder.sim.pushforward import pushforward_pmf

TARGET = dict(E.DEFAULT_TARGET)
ADAPTIVE = {"n0": 16, "tolerance_deg": 2.0, "min_width_deg": 0.5}


def _design(yaws, final, status=None):
    status = np.full(len(yaws), "ok") if status is None else np.asarray(status)
    return design_from_samples(
        np.asarray(yaws, float),
        np.asarray(final, float),
        status,
        period_deg=360.0,
        offset_deg=0.0,
        tolerance_deg=2.0,
        min_width_deg=0.5,
    )


def test_audit_yaws_put_one_draw_in_each_stratum():
    beta = E.audit_yaws(np.random.default_rng(3), 8, 10.0, 180.0)
    assert beta.size == 8
    np.testing.assert_array_equal(np.floor((beta - 10.0) / 22.5), np.arange(8))


def test_a_jump_counts_half_its_interval_moved_by_the_bin_distance():
    # 30° on [1, 180), 200° on [181, 360) and around 0: two jumps of 1°, ends 170° apart (bins 30 and 200)
    d = _design([0, 1, 180, 181], [30, 200, 200, 30])
    pmf, _ = pushforward_pmf(d, 360, 1.0)
    sup, w1 = E.split_terms(d, pmf)
    assert sup == pytest.approx(2 * 0.5 / 360)  # both move half a degree of mass across edges 30..199
    assert w1 == pytest.approx(2 * 0.5 / 360 * 170)  # by 170° each


def test_audits_that_agree_leave_the_widest_unaudited_interval_as_a_possible_island():
    d = _design([0, 90, 180, 270], [0, 90, 180, 270])  # the identity: every interval agrees (a slope)
    pmf, masses = pushforward_pmf(d, 360, 1.0)
    beta = np.array([10.0, 100.0, 200.0])  # nothing in [270, 360)
    est = E.estimate_error(d, pmf, masses["ok"], beta, beta, np.full(3, "ok"), 0.9, 1.0)
    assert est.misses == 0
    assert est.sup_cdf == pytest.approx(0.25)  # the island term alone: 90° of 360°
    # the label is uniform: every yaw lies a mean 90° from it, so the island costs 0.25 x 90°
    assert est.circular_w1_deg == pytest.approx(22.5, rel=1e-6)


def test_an_unseen_island_is_charged_at_the_yaw_farthest_from_the_label():
    # every sample and audit ends at 100°: the label is one sharp basin. An island hidden in the
    # unaudited quarter [270, 360) could end anywhere; the worst place is 280°, 180° away. (The
    # interval's ends, at 100°, said 0.8°: a band of good drops between jammed samples was missed so.)
    d = _design([0, 90, 180, 270], [100, 100, 100, 100])
    pmf, masses = pushforward_pmf(d, 360, 1.0)
    beta = np.array([10.0, 100.0, 200.0])
    est = E.estimate_error(d, pmf, masses["ok"], beta, np.full(3, 100.0), np.full(3, "ok"), 0.9, 1.0)
    assert est.misses == 0
    # the label is bin 100 smoothed (weights p_b): from 280.5° each bin b lies 180 - |b - 100| bins away
    spread = float(np.sum(pmf * np.abs(np.arange(360) - 100)))
    assert 0.5 < spread < 1.5
    assert est.circular_w1_deg == pytest.approx(0.25 * (180.0 - spread), rel=1e-9)


def test_an_audit_in_a_missed_island_raises_the_estimate_above_the_true_error():
    # the map: 100° everywhere but a 20° island [40, 60) of 250°; the samples missed it
    d = _design(np.arange(0, 360, 22.5), np.full(16, 100.0))
    pmf, masses = pushforward_pmf(d, 360, 1.0)
    beta = E.audit_yaws(np.random.default_rng(0), 16, 0.0, 360.0)
    beta[2] = 50.0  # the stratum [45, 67.5) audits inside the island
    final = np.where((beta >= 40) & (beta < 60), 250.0, 100.0)
    est = E.estimate_error(d, pmf, masses["ok"], beta, final, np.full(16, "ok"), 0.9, 1.0)
    true_sup = 20 / 360  # the island's mass sits at 250° in the truth, at 100° in the label
    assert est.misses == 1
    assert est.sup_cdf >= true_sup
    assert est.circular_w1_deg >= true_sup * 150 * 0.99  # moved 150°; round-off of the smoothing aside


def _identity(yaws):
    return np.asarray(yaws, float), np.full(np.size(yaws), "ok")


def _chaos(yaws):  # two basins switching every 0.45° or so: a chaotic band over the whole turn
    return np.where(np.sin(7.0 * np.asarray(yaws)) > 0, 10.0, 200.0), np.full(np.size(yaws), "ok")


def test_an_easy_map_stops_at_the_first_audit_round_and_a_chaotic_one_at_the_cap():
    loose = {**ADAPTIVE, "target": {**TARGET, "target_w1_deg": 45.0, "target_sup_cdf": 0.5}}
    d, est, rounds = E.targeted(_identity, 1, loose, 1, 360, 1.0)
    assert rounds == 1 and d.evaluations == TARGET["min_budget"] + TARGET["audits"]
    assert est.circular_w1_deg <= 45.0
    tight = {**ADAPTIVE, "target": {**TARGET, "cap": 64}}
    d, est, rounds = E.targeted(_chaos, 1, tight, 1, 360, 1.0)
    assert rounds > 1 and 64 - TARGET["audits"] <= d.evaluations <= 64
    assert est.sup_cdf > TARGET["target_sup_cdf"]


@pytest.mark.parametrize(
    "change, message",
    [
        ({"target_w1_deg": 0.0}, "target_w1_deg must be a number > 0"),
        ({"target_sup_cdf": -0.01}, "target_sup_cdf must be a number > 0"),
        ({"cap": 30}, "cap .30. is below the minimum budget plus one round of audits .32."),
        ({"min_budget": 8}, "min_budget .8. must be >= sim.adaptive.n0 .16."),
    ],
)
def test_bad_targets_are_one_line_errors(change, message):
    with pytest.raises(FeederError, match=message):
        E.check_target({**TARGET, **change}, 16)


def _settings(tmp_path, **changes):
    from workflow_helpers import ROOT

    from feeder.config import load_study_config

    cfg = load_study_config("config/config.yaml", root=ROOT)
    for dotted, value in changes.items():
        *path, last = dotted.split("__")
        node = cfg
        for p in path:
            node = node[p]
        node[last] = value
    return json.dumps(cfg)


@pytest.mark.parametrize(
    "changes",
    [
        {"sim__adaptive_target": {**TARGET, "target_w1_deg": 0}},
        {"sim__adaptive_target": {**TARGET, "cap": 20}},
        {"sim__errest_bench": {"designs": ["adaptive", "oracle"], "target_scales": [1]}},
    ],
)
def test_bench_errest_bad_input_exits_nonzero_with_one_line_and_no_output(tmp_path, capsys, changes):
    settings = _settings(tmp_path, **changes)
    out, summary = tmp_path / "rows.csv", tmp_path / "summary.csv"
    code = main(["bench-errest", "--settings", settings, "--references", str(tmp_path / "none.npz"),
                 "--out-csv", str(out), "--out-summary", str(summary)])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code != 0 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not summary.exists()


def test_check_errest_names_the_unknown_design():
    cfg = {"sim": {"errest_bench": {"designs": ["grid"], "target_scales": [1]}, "adaptive": ADAPTIVE,
                   "adaptive_target": TARGET}}  # fmt: skip
    with pytest.raises(FeederError, match="unknown design 'grid'"):
        BE.check_errest(cfg)
