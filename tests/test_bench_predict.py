"""`feeder bench-predict` on a tiny trained model: well-formed timings and statistics (no timing
is asserted: the goals are what the bench reports, not what a test checks)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from factories import make_regression_dataset, small_overrides

from feeder.bench import predict as B
from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.learn import train as T

PARTS = Path(__file__).resolve().parents[1] / "parts"
SMALL_FENCES = {  # a small grid of the study's layout: 2 + 2 + 4 + 4 configurations
    "straight_angles": [20, 40],
    "curved_angles": [30, 60],
    "combos": ["straight_none", "none_curved", "straight_curved", "curved_curved"],
}


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("bench_predict")
    make_regression_dataset(root / "ds.npz")
    T.train(compose_config("train", small_overrides(root / "ds.npz", root / "m3", "m3", epochs=1)))
    return root / "m3"


@pytest.fixture(scope="module")
def own_part(tmp_path_factory):
    """A part that is not in the library: an L-shape in millimetres."""
    from feeder.parts.geometry import stl_bytes

    path = tmp_path_factory.mktemp("part") / "my-l.stl"
    path.write_bytes(stl_bytes(np.array([[0, 0], [30, 0], [30, 8], [9, 8], [9, 20], [0, 20]], float), 5.0))
    return path


def test_bench_writes_every_timing_and_its_summary(model_dir, own_part, tmp_path, capsys):
    from feeder.cli import main
    from feeder.learn.recommend import grid_configurations

    out, summary = tmp_path / "speed.csv", tmp_path / "summary.csv"
    parts = [PARTS / "rect-a2.stl", own_part]
    argv = ["bench-predict", "--model", str(model_dir), "--parts", *map(str, parts), "--repeats", "2"]
    argv += ["--cold-repeats", "0", "--settings", json.dumps({"fences": SMALL_FENCES})]
    assert main([*argv, "--out", str(out), "--summary", str(summary)]) == 0
    raw = pd.read_csv(out)
    assert list(raw.columns) == B.RAW_COLUMNS
    n_grid = len(grid_configurations(SMALL_FENCES))
    for part in ("rect-a2", "my-l"):
        mine = raw[raw.part == part]
        assert list(mine.stage.unique()) == list(B.WARM_STAGES)
        for stage, group in mine.groupby("stage"):
            assert sorted(group.repeat) == [0, 1], stage
            assert set(group.configs) == {n_grid if stage == "grid" else int(stage == "config")}
    assert np.all(np.isfinite(raw.ms)) and (raw.ms > 0).all()

    stats = pd.read_csv(summary)
    assert list(stats.columns) == B.SUMMARY_COLUMNS
    assert len(stats) == 3 * len(B.WARM_STAGES) and list(stats.part.unique()) == ["rect-a2", "my-l", "all"]
    for row in stats.itertuples(index=False):
        ms = raw.ms if row.part == B.ALL_PARTS else raw.ms[raw.part == row.part]
        ms = ms[raw.stage == row.stage]
        assert row.repeats == len(ms) and row.min_ms <= row.median_ms <= row.max_ms
        assert row.median_ms == pytest.approx(np.median(ms))
        if row.stage in B.GOALS_MS:
            assert row.goal_ms == B.GOALS_MS[row.stage] and row.meets_goal == (row.median_ms <= row.goal_ms)
        else:
            assert np.isnan(row.goal_ms) and pd.isna(row.meets_goal)
    grid = stats[(stats.part == B.ALL_PARTS) & (stats.stage == "grid")].iloc[0]
    assert grid.configs == n_grid and grid.median_ms_per_config == pytest.approx(grid.median_ms / n_grid)
    assert "features: median" in capsys.readouterr().out


def test_cold_runs_time_a_fresh_interpreter(model_dir):
    part = PARTS / "keyhole-a.stl"
    rows = pd.DataFrame(B.cold_timings(model_dir, part, B.DEFAULT_LOC1, B.DEFAULT_LOC2, 2, interval_s=0.0))
    assert list(rows.stage) == 2 * list(B.COLD_STAGES) and set(rows.part) == {"keyhole-a"}
    assert list(rows.repeat) == [0] * len(B.COLD_STAGES) + [1] * len(B.COLD_STAGES)
    rows = rows[rows.repeat == 0]
    ms = dict(zip(rows.stage, rows.ms, strict=True))
    assert all(v > 0 for v in ms.values())
    assert dict(zip(rows.stage, rows.configs, strict=True))["predict"] == 1  # feeder predict: one configuration
    # the child's steps happen inside its lifetime, which the parent's clock spans
    assert ms["process"] >= ms["import"] + ms["model_load"] + ms["features_cold"] + ms["config_cold"]


def test_summary_by_hand():
    raw = pd.DataFrame(
        [
            {"part": "a", "stage": "features", "repeat": r, "configs": 0, "ms": ms}
            for r, ms in enumerate([300.0, 100.0, 250.0])
        ]
        + [{"part": "b", "stage": "grid", "repeat": r, "configs": 10, "ms": ms} for r, ms in enumerate([40.0, 20.0])]
        + [{"part": "b", "stage": "process", "repeat": 0, "configs": 0, "ms": 900.0}]
    )
    stats = B.summarise(raw).set_index(["part", "stage"])
    feats = stats.loc[("a", "features")]
    assert (feats.repeats, feats.median_ms, feats.min_ms, feats.max_ms) == (3, 250.0, 100.0, 300.0)
    assert feats.goal_ms == B.FEATURES_GOAL_MS and not feats.meets_goal  # 250 ms > 200 ms
    grid = stats.loc[("b", "grid")]
    assert grid.median_ms == 30.0 and grid.median_ms_per_config == 3.0 and grid.meets_goal
    assert pd.isna(stats.loc[("b", "process")].meets_goal)
    assert stats.loc[(B.ALL_PARTS, "features")].median_ms == 250.0
    assert list(stats.index) == [
        ("a", "features"),
        ("b", "grid"),
        ("b", "process"),
        (B.ALL_PARTS, "features"),
        (B.ALL_PARTS, "grid"),
        (B.ALL_PARTS, "process"),
    ]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--parts", "nope.stl"], "missing"),
        (["--parts", str(PARTS / "rect-a2.stl"), "--repeats", "0"], "--repeats"),
        (["--parts", str(PARTS / "rect-a2.stl"), "--loc1", "straight:95"], "straight"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(model_dir, tmp_path, capsys, extra, message):
    from feeder.cli import main

    out, summary = tmp_path / "speed.csv", tmp_path / "summary.csv"
    argv = ["bench-predict", "--model", str(model_dir), *extra, "--cold-repeats", "0"]
    assert main([*argv, "--out", str(out), "--summary", str(summary)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists() and not summary.exists()


def test_missing_model_is_an_error(tmp_path):
    with pytest.raises(FeederError):
        B.run(tmp_path / "no-model", [PARTS / "rect-a2.stl"], SMALL_FENCES, repeats=1, cold_repeats=0)
