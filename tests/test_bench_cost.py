"""feeder.bench.cost: the projection (pure, hand-computed) and a tiny end-to-end run of real jobs."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder.bench import cost as bench_cost
from feeder.cli import main as cli
from feeder.config import load_study_config
from feeder.errors import FeederError

ROOT = Path(__file__).resolve().parents[1]


def test_project_total_by_hand():
    # mean 2.5, sd (n-1) sqrt(5/3), N = 8: total 20, se = 8 * sqrt(5/3) / 2 * sqrt(1 - 4/8)
    total, lo, hi = bench_cost.project_total([1.0, 2.0, 3.0, 4.0], 8)
    se = 8 * math.sqrt(5 / 3) / 2 * math.sqrt(0.5)
    assert total == pytest.approx(20.0)
    assert hi - total == pytest.approx(total - lo)
    assert hi - total == pytest.approx(3.182446305 * se, rel=1e-6)  # t(0.975, 3 dof)


def test_a_census_or_equal_costs_have_no_interval():
    assert bench_cost.project_total([1.0, 2.0, 6.0], 3) == pytest.approx((9.0, 9.0, 9.0))
    assert bench_cost.project_total([5.0, 5.0], 1000) == pytest.approx((5000.0, 5000.0, 5000.0))


def test_project_total_refuses_what_it_cannot_estimate():
    with pytest.raises(FeederError, match="at least two"):
        bench_cost.project_total([1.0], 10)
    with pytest.raises(FeederError, match="larger than the population"):
        bench_cost.project_total([1.0, 2.0, 3.0], 2)
    with pytest.raises(FeederError, match="finite"):
        bench_cost.project_total([1.0, float("nan")], 10)


def test_sample_rows_is_seeded_unique_and_capped():
    a = bench_cost.sample_rows(100, 10, 3)
    assert np.array_equal(a, bench_cost.sample_rows(100, 10, 3))
    assert not np.array_equal(a, bench_cost.sample_rows(100, 10, 4))
    assert np.all(np.diff(a) > 0) and a.min() >= 0 and a.max() < 100
    assert np.array_equal(bench_cost.sample_rows(5, 10, 0), np.arange(5))
    with pytest.raises(FeederError, match="at least 2"):
        bench_cost.sample_rows(100, 1, 0)
    with pytest.raises(FeederError, match="no configurations"):
        bench_cost.sample_rows(0, 5, 0)


def test_wall_hours_divides_by_cores_but_not_below_the_longest_job():
    assert bench_cost.wall_hours(7200.0, 2, 10.0) == pytest.approx(1.0)
    assert bench_cost.wall_hours(7200.0, 4, 3600.0) == pytest.approx(1.0)
    with pytest.raises(FeederError, match="cores"):
        bench_cost.wall_hours(1.0, 0, 0.0)


def test_bench_cost_runs_real_jobs_and_projects_them(tmp_path):
    cfg = load_study_config("config/smoke.yaml", root=ROOT)
    cfg["parts"]["dir"] = str(ROOT / "parts")
    cfg["parts"]["include"] = ["rect-a2", "ellipse-a2", "tshape-a"]
    cfg["datasets"].update(n_holdout=1, fences_parts=0, fences_samples=0, parts_per_part=1)
    cfg["fences"]["main_per_part"] = 2
    cfg["sim"]["drops"] = 500
    cfg["sim"]["cost_bench"] = {"configurations": 3, "drops": 2, "seed": 1, "workers": 2, "cores": 2}
    sample_csv, summary_csv = tmp_path / "sample.csv", tmp_path / "summary.csv"
    assert (
        cli(
            [
                "bench-cost",
                "--settings",
                json.dumps(cfg),
                "--out-csv",
                str(sample_csv),
                "--out-summary",
                str(summary_csv),
            ]
        )
        == 0
    )
    sample, summary = pd.read_csv(sample_csv), pd.read_csv(summary_csv)
    assert list(sample.columns) == bench_cost.SAMPLE_COLUMNS and len(sample) == 3
    assert set(sample["part"]) <= {"rect-a2", "ellipse-a2", "tshape-a"} and (sample["drops"] == 2).all()
    # the process costs more than its simulation (interpreter, imports, the part file)
    assert (sample["sim_s"] > 0).all() and (sample["overhead_s"] > 0).all()
    assert np.allclose(sample["projected_job_cpu_s"], sample["overhead_s"] + 500 * sample["sim_s"] / 2)
    s = summary.iloc[0]
    assert (s["configurations"], s["drops"], s["sampled"], s["cores"], s["preset"]) == (5, 500, 3, 2, "coarse")
    assert s["cpu_s_lo"] <= s["cpu_s"] <= s["cpu_s_hi"]
    assert s["cpu_s"] == pytest.approx(5 * sample["projected_job_cpu_s"].mean())
    assert s["wall_h"] == pytest.approx(max(s["cpu_s"] / 2, sample["projected_job_cpu_s"].max()) / 3600)


def test_bench_cost_names_a_missing_section(tmp_path, capsys):
    cfg = load_study_config(root=ROOT)
    del cfg["sim"]["cost_bench"]
    assert (
        cli(
            [
                "bench-cost",
                "--settings",
                json.dumps(cfg),
                "--out-csv",
                str(tmp_path / "a.csv"),
                "--out-summary",
                str(tmp_path / "b.csv"),
            ]
        )
        == 2
    )
    assert "sim.cost_bench" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_check_projection_compares_the_jobs_that_ran(tmp_path, capsys):
    sample = pd.DataFrame(
        {
            "part": ["a", "b", "c"],
            "config_id": ["straight30_none", "none_curved0", "x_y"],
            "ms_per_drop": [100.0, 40.0, 10.0],
        }
    )
    sim, bench = tmp_path / "sim", tmp_path / "bench"
    for part, cid, drops, cpu in (("a", "straight30_none", 50, 6.0), ("b", "none_curved0", 100, 3.0)):
        (sim / part).mkdir(parents=True)
        np.savez(sim / part / f"{cid}.npz", final_yaw_deg=np.zeros(drops), cpu_s=np.float64(cpu))
    (bench / "a").mkdir(parents=True)
    (bench / "a" / "straight30_none.tsv").write_text("s\th:m:s\tmax_rss\tcpu_time\n7.5\t0:00:07\t80\t5.0\n")
    out = bench_cost.check_projection(sample, sim, bench)
    assert list(out["part"]) == ["a", "b", "total"]  # c never ran
    assert out["projected_sim_cpu_s"].tolist() == pytest.approx([5.0, 4.0, 9.0])
    assert out["ratio"].tolist() == pytest.approx([6.0 / 5.0, 3.0 / 4.0, 9.0 / 9.0])
    assert out["benchmark_cpu_s"].iloc[0] == 5.0 and np.isnan(out["benchmark_cpu_s"].iloc[1])
    assert out["benchmark_cpu_s"].iloc[2] == 5.0 and out["benchmark_wall_s"].iloc[0] == 7.5

    csv = tmp_path / "sample.csv"
    sample.to_csv(csv, index=False)
    assert (
        cli(
            [
                "bench-cost",
                "--check",
                str(csv),
                "--sim-dir",
                str(sim),
                "--benchmarks",
                str(bench),
                "--out-csv",
                str(tmp_path / "check.csv"),
            ]
        )
        == 0
    )
    assert "2 sampled jobs have run" in capsys.readouterr().err
    assert (
        cli(
            [
                "bench-cost",
                "--check",
                str(csv),
                "--sim-dir",
                str(tmp_path / "none"),
                "--out-csv",
                str(tmp_path / "check2.csv"),
            ]
        )
        == 2
    )
    assert "none of the 3 sampled jobs" in capsys.readouterr().err
    assert not (tmp_path / "check2.csv").exists()
