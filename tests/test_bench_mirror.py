"""feeder bench-mirror (issue #38 item 3): a fence at Location 2 against its mirror image at Location 1."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from feeder.bench import mirror as M
from feeder.cli import main as cli
from feeder.errors import FeederError

BENCH = {
    "parts": [],
    "fences": ["straight:30"],
    "drops": 4,
    "sampling": "grid",
    "nudge_deg": 0.01,
    "offset_b_seed": 1,
    "floor_factor": 2.0,
    "preset": "fast",
    "workers": 1,
}


def test_bench_parts_take_the_first_of_each_family():
    catalog = pd.DataFrame({"id": ["rect-b", "rect-a", "gear-a", "blob-c"], "family": ["rect", "rect", "gear", "blob"]})
    assert M.bench_parts(BENCH, catalog) == ["blob-c", "gear-a", "rect-a"]
    assert M.bench_parts(dict(BENCH, parts=["x"]), catalog) == ["x"]
    with pytest.raises(FeederError, match="catalog"):
        M.bench_parts(BENCH, pd.DataFrame())


def test_the_mirror_run_starts_from_the_negated_yaws():
    runs = {r["run"]: r["yaws"] for r in M.plan_runs(["rect-a2"], BENCH, 0)}
    assert set(runs) == set(M.RUNS)
    np.testing.assert_array_equal(runs["mirror"], -runs["a"])
    np.testing.assert_allclose(runs["nudged"] - runs["a"], 0.01)
    assert not np.allclose(runs["b"], runs["a"])


def _raw(mirror_final):
    rows = []
    finals = {"a": [10.0, 100.0, 200.0, 300.0], "nudged": [10.0, 100.0, 200.0, 300.0], "b": [10.0, 100.0, 200.0, 300.0]}
    finals["mirror"] = mirror_final
    for run, yaws in finals.items():
        for i, y in enumerate(yaws):
            rows.append(
                {
                    "part": "p",
                    "fence": "straight:30",
                    "run": run,
                    "drop": i,
                    "final_yaw_deg": y,
                    "status": "ok",
                    "cpu_s": 1.0,
                }
            )
    return pd.DataFrame(rows)


def test_summarize_negates_the_mirror_and_applies_the_floors():
    exact = M.summarize(_raw([350.0, 260.0, 160.0, 60.0]), 360, 1.0, 2.0)  # -10, -100, -200, -300
    row = exact.iloc[0]
    assert row["same_basin"] == 1.0 and row["median_dyaw_deg"] == pytest.approx(0.0, abs=1e-9) and row["passes"]
    off = M.summarize(_raw([340.0, 250.0, 150.0, 50.0]), 360, 1.0, 2.0).iloc[0]  # every drop 10 degrees away
    assert off["same_basin"] == 0.0 and not off["passes"]
    verdict = exact.iloc[-1]
    assert verdict["part"] == "all" and verdict["rows"] == 1 and verdict["rows_passed"] == 1


def test_cli_runs_a_part_and_its_mirror(tmp_path):
    from feeder.config import load_study_config

    cfg = load_study_config("config/config.yaml")
    cfg["sim"]["mirror_bench"] = dict(BENCH, parts=["rect-a2"], drops=2)
    settings = {k: cfg[k] for k in ("scene", "sim", "labels", "parts")}
    raw, out = tmp_path / "raw.csv", tmp_path / "t.csv"
    assert cli(["bench-mirror", "--settings", json.dumps(settings), "--out-raw", str(raw), "--out-csv", str(out)]) == 0
    table = pd.read_csv(out)
    assert table.iloc[0]["part"] == "rect-a2" and table.iloc[-1]["part"] == "all"
    assert set(pd.read_csv(raw)["run"]) == set(M.RUNS)
    cfg["sim"]["mirror_bench"] = dict(BENCH, parts=["rect-a2"], fences=["none"])
    bad = {k: cfg[k] for k in ("scene", "sim", "labels", "parts")}
    none = tmp_path / "none.csv"
    assert cli(["bench-mirror", "--settings", json.dumps(bad), "--out-raw", str(none), "--out-csv", str(none)]) != 0
    assert not none.exists()
