import json

import numpy as np
import pandas as pd
import pytest
import torch
from factories import BINS, LEVELS, make_level_dataset

from feeder.cli import main as cli
from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels.dataset import load_dataset
from feeder.learn import delta

TINY = ["train.max_epochs=3", "train.batch_size=16"]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("delta") / "dataset.npz"
    make_level_dataset(path, n_parts=5, n_configs=8)
    return path


def tiny_cfg(dataset, *extra):
    return compose_config("delta", [f"dataset={dataset}", *TINY, *extra])


def test_checkpoints_zero_pad_below_zero_percent():
    rng = np.random.default_rng(0)
    pl = rng.dirichlet(np.ones(BINS), size=(3, LEVELS.size))
    ck, present = delta.checkpoints(pl, LEVELS, 5, [5, 10])
    assert present.tolist() == [True, False, False]
    np.testing.assert_array_equal(ck[:, 0], pl[:, 0])
    assert not ck[:, 1:].any()
    ck, present = delta.checkpoints(pl, LEVELS, 10, [5, 10])
    assert present.tolist() == [True, True, False]
    np.testing.assert_array_equal(ck[:, 1], pl[:, 0])
    ck, present = delta.checkpoints(pl, LEVELS, 50, [5, 10])
    assert present.all()
    np.testing.assert_array_equal(ck[:, 2], pl[:, list(LEVELS).index(40)])
    with pytest.raises(FeederError):
        delta.checkpoints(pl[:, [0, 1, 3]], [5, 10, 20], 20, [5, 10])  # 15 % missing


def test_stability_features_hand_values():
    uniform = np.full(BINS, 1.0 / BINS)
    a, b = np.eye(BINS)[0], np.eye(BINS)[1]
    ck = np.stack([np.stack([a, b, b]), np.stack([uniform, uniform, np.zeros(BINS)])])
    feats = delta.stability_features(ck, np.array([True, True, True]))
    # pair (a, b): disjoint one-bin PMFs one bin apart: JS 1 bit, TV 1, W1 1° / 360°
    np.testing.assert_allclose(feats[0, :4], [1.0, 1.0, 1.0, 1.0 / 360.0])
    # pair (b, b): identical
    np.testing.assert_allclose(feats[0, 4:8], [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    # per checkpoint: entropy / log2(bins) and peak mass
    np.testing.assert_allclose(feats[0, 8:], [0, 1, 0, 1, 0, 1], atol=1e-12)
    np.testing.assert_allclose(feats[1, 8:10], [1.0, 1.0 / BINS])
    feats = delta.stability_features(ck, np.array([True, True, False]))
    assert not feats[:, 4:8].any() and not feats[:, 12:].any()


def test_inputs_layout():
    ck = np.random.default_rng(1).dirichlet(np.ones(BINS), size=(2, 3))
    x = delta.delta_inputs(np.zeros((2, 53)), ck, np.ones(3, dtype=bool))
    assert x.shape == (2, 53 + 5 * BINS + 14)
    np.testing.assert_allclose(x[:, 53 : 53 + BINS], BINS * ck[:, 0])
    np.testing.assert_allclose(x[:, 53 + 3 * BINS : 53 + 4 * BINS], BINS * (ck[:, 0] - ck[:, 1]))


def test_corrected_pmf_is_valid_by_construction():
    torch.manual_seed(0)
    pmf_k = torch.cat(
        [torch.eye(BINS)[[0, 359]], torch.full((1, BINS), 1.0 / BINS), torch.softmax(torch.randn(1, BINS) * 5, -1)]
    )
    for scale in (0.0, 1.0, 1e4):
        out = torch.randn(4, BINS + 1) * scale
        out[:, -1] = torch.tensor([-1e4, 0.0, 3.0, 1e4]) if scale else 0.0
        q, log_q, w = delta.corrected_pmf(out, pmf_k)
        assert (q >= 0).all() and torch.allclose(q.sum(-1), torch.ones(4), atol=1e-5)
        assert torch.isfinite(log_q).all() and ((w >= 0) & (w <= 1)).all()
        big = q > 1e-6
        assert torch.allclose(log_q[big], torch.log(q[big]), atol=1e-4)
    out = torch.zeros(4, BINS + 1)
    out[:, -1] = -1e4  # gate closed: the partial PMF is returned unchanged (the baseline)
    q, _, _ = delta.corrected_pmf(out, pmf_k)
    assert torch.allclose(q, pmf_k)


def test_sweep_level_scores_every_row_once_and_is_deterministic(dataset):
    cfg = tiny_cfg(dataset)
    a = delta.sweep_level(cfg, 5)
    b = delta.sweep_level(cfg, 5)
    n = a["n_rows"]
    assert n == 40
    for mode in delta.MODES:
        ma, mb = a["modes"][mode], b["modes"][mode]
        assert len(ma["per_row"]["r2"]) == n == sum(f["n_test"] for f in ma["folds"])
        assert np.isfinite(ma["per_row"]["r2"]).all()
        np.testing.assert_allclose([ma["r2_mean"], ma["r2_sd"]], [mb["r2_mean"], mb["r2_sd"]], rtol=0, atol=1e-6)
    assert len(a["modes"]["part"]["folds"]) == 3 and len(a["modes"]["config"]["folds"]) == 5
    assert a["checkpoints_present"] == [True, False, False]
    assert a["modes"]["part"]["baseline_mean"] == a["modes"]["config"]["baseline_mean"] < 1.0


def test_full_level_baseline_is_exact(dataset):
    res = delta.sweep_level(tiny_cfg(dataset), 100)
    assert res["modes"]["part"]["baseline_mean"] == pytest.approx(1.0)
    assert res["cost_saved_pct"] == 0.0


def test_part_split_holds_out_whole_parts(dataset):
    cfg = tiny_cfg(dataset)
    data = load_dataset(dataset)
    rows = np.arange(len(data["part"]))
    labels = delta.folds(data, rows, "part", cfg)
    for f in np.unique(labels):
        assert not set(data["part"][labels == f]) & set(data["part"][labels != f])
    cfg_labels = delta.folds(data, rows, "config", cfg)
    assert np.bincount(cfg_labels).tolist() == [8] * 5


def test_cli_sweep_and_table(dataset, tmp_path):
    outs = []
    for level in (10, 5):
        outs.append(tmp_path / f"level_{level}.json")
        assert delta.main(["sweep", "--level", str(level), "--out", str(outs[-1]), f"dataset={dataset}", *TINY]) == 0
    assert json.loads(outs[1].read_text())["level_pct"] == 5
    table, fig = tmp_path / "table10.csv", tmp_path / "s11.png"
    assert delta.main(["table", "--table", str(table), *map(str, outs)]) == 0
    frame = pd.read_csv(table)
    assert list(frame.columns) == delta.TABLE10_COLUMNS and frame["level_pct"].tolist() == [5, 10]
    assert frame["cost_saved_pct"].tolist() == [95.0, 90.0]
    md = table.with_suffix(".md").read_text()
    assert "| 5% | 95.0 |" in md and "Levels not in this sweep: 25%, 50%, 75%, 90%." in md
    assert cli(["figure", "s11_delta_sweep", "--data", str(table), "--out", str(fig)]) == 0
    assert fig.stat().st_size > 1000


def test_errors_write_nothing(dataset, tmp_path):
    out = tmp_path / "x.json"
    for args in (
        ["sweep", "--level", "12", "--out", str(out), f"dataset={dataset}", *TINY],
        ["sweep", "--level", "5", "--out", str(out), f"dataset={dataset}", *TINY, "+loss.nonsense=1"],
        ["sweep", "--level", "5", "--out", str(out), f"dataset={dataset}", *TINY, "random_folds=1"],
    ):
        with pytest.raises(FeederError) as err:
            delta.main(args)
        assert "\n" not in str(err.value)
    assert not out.exists()


def test_model_beats_the_partial_pmf_at_five_percent(dataset):
    """At 5 % (10 of 200 drops) the fixture's partial PMFs are noisy while the full PMFs follow
    the part and fences: the learned correction must beat the partial PMF under both splits."""
    res = delta.sweep_level(
        compose_config("delta", [f"dataset={dataset}", "train.max_epochs=20", "train.batch_size=16"]), 5
    )
    for mode in delta.MODES:
        m = res["modes"][mode]
        assert m["r2_mean"] > m["baseline_mean"] + 0.02
