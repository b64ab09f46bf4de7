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


def test_paired_ratio_by_hand():
    # R = 12 / 10; d = x - R y = [-0.2, 0.6, -0.6, 0.2], s_d^2 = 0.8 / 3; N = 8, n = 4, mean(y) = 2.5
    ratio, lo, hi = bench_cost.paired_ratio([1.0, 3.0, 3.0, 5.0], [1.0, 2.0, 3.0, 4.0], 8)
    se = math.sqrt(0.5 * (0.8 / 3) / 4) / 2.5
    assert ratio == pytest.approx(1.2)
    assert hi - ratio == pytest.approx(ratio - lo)
    assert hi - ratio == pytest.approx(3.182446305 * se, rel=1e-6)
    # proportional costs or a census: no error; the pairing removes the shared spread
    assert bench_cost.paired_ratio([2.0, 20.0, 200.0], [1.0, 10.0, 100.0], 1000) == pytest.approx((2.0, 2.0, 2.0))
    assert bench_cost.paired_ratio([1.0, 3.0, 3.0, 5.0], [1.0, 2.0, 3.0, 4.0], 4) == pytest.approx((1.2, 1.2, 1.2))
    with pytest.raises(FeederError, match="length"):
        bench_cost.paired_ratio([1.0, 2.0], [1.0, 2.0, 3.0], 10)
    with pytest.raises(FeederError, match="at least two"):
        bench_cost.paired_ratio([1.0], [1.0], 10)


def test_designs_put_the_study_first_and_run_an_equal_baseline_once():
    sim = {"yaw_sampling": "adaptive", "drops": 64}
    cb = {"baseline": {"yaw_sampling": "random", "drops": 1000}}
    assert bench_cost.designs(sim, cb) == [
        {"yaw_sampling": "adaptive", "drops": 64},
        {"yaw_sampling": "random", "drops": 1000},
    ]
    assert bench_cost.designs({"yaw_sampling": "random", "drops": 1000}, cb) == [
        {"yaw_sampling": "random", "drops": 1000}
    ]
    with pytest.raises(FeederError, match="baseline"):
        bench_cost.designs(sim, {})


def test_a_sampled_adaptive_job_runs_the_real_design_at_the_full_budget():
    sim = {
        "base_seed": 7,
        "preset": "fast",
        "adaptive": {"n0": 16, "tolerance_deg": 2.0, "min_width_deg": 0.25, "symmetry": "auto"},
    }
    args = ("part.stl", "straight:30", "none")
    cmd = bench_cost.job_command(["feeder"], *args, {"yaw_sampling": "adaptive", "drops": 64}, 20, sim, "{}", "o.npz")
    assert cmd[:2] == ["feeder", "simulate"]
    opts = dict(zip(cmd[2::2], cmd[3::2]))
    assert opts == {
        "--part": "part.stl",
        "--loc1": "straight:30",
        "--loc2": "none",
        "--drops": "64",
        "--seed": "7",
        "--yaw-sampling": "adaptive",
        "--n0": "16",
        "--tolerance-deg": "2.0",
        "--min-width-deg": "0.25",
        "--symmetry": "auto",
        "--preset": "fast",
        "--settings": "{}",
        "--out": "o.npz",
    }
    # a fixed design runs cost_bench.drops drops, without the adaptive options
    cmd = bench_cost.job_command(["feeder"], *args, {"yaw_sampling": "random", "drops": 1000}, 20, sim, "{}", "o.npz")
    opts = dict(zip(cmd[2::2], cmd[3::2]))
    assert opts["--drops"] == "20" and opts["--yaw-sampling"] == "random" and "--n0" not in opts
    with pytest.raises(FeederError, match="sim.adaptive"):
        bench_cost.design_options({"yaw_sampling": "adaptive", "drops": 64}, None)


def _two_design_sample():
    # 3 configurations; adaptive (budget 64) ran 30/64/40 simulations, random (1000) ran 20 drops each
    jobs = pd.DataFrame(
        {
            "part": ["a", "b", "c"] * 2,
            "config_id": ["x", "y", "z"] * 2,
            "dataset": ["main"] * 6,
            "yaw_sampling": ["adaptive"] * 3 + ["random"] * 3,
            "design_drops": [64] * 3 + [1000] * 3,
            "drops": [30, 64, 40, 20, 20, 20],
            "job_cpu_s": [4.0, 8.0, 5.0, 1.2, 1.4, 1.3],
            "sim_s": [3.0, 7.0, 4.0, 0.2, 0.4, 0.3],
        }
    )
    return bench_cost.project_sample(jobs)


def test_adaptive_jobs_are_projected_at_their_measured_cpu_and_fixed_designs_linearly():
    sample = _two_design_sample()
    adaptive, random = sample.iloc[:3], sample.iloc[3:]
    assert adaptive["projected_job_cpu_s"].tolist() == pytest.approx([4.0, 8.0, 5.0])
    assert random["projected_job_cpu_s"].tolist() == pytest.approx([1.0 + 10.0, 1.0 + 20.0, 1.0 + 15.0])
    assert sample["ms_per_drop"].tolist() == pytest.approx([100.0, 7000.0 / 64, 100.0, 10.0, 20.0, 15.0])
    assert bench_cost.projected_job_cpu([4.0], [3.0], [30], 64, "golden") == pytest.approx([1.0 + 64 * 0.1])


def test_summary_has_a_row_per_design_and_the_paired_ratio():
    sample = _two_design_sample()
    s = bench_cost.summarize(sample, 9, 2, "fast", {"yaw_sampling": "random", "drops": 1000}, 20)
    assert s["yaw_sampling"].tolist() == ["adaptive", "random"]
    assert s["drops"].tolist() == [64, 1000] and s["sample_drops"].tolist() == [64, 20]
    assert s["simulations_per_job"].tolist() == pytest.approx([134 / 3, 1000.0])
    assert s["cpu_s"].tolist() == pytest.approx([9 * 17 / 3, 9 * 48 / 3])
    ratio = bench_cost.paired_ratio([4.0, 8.0, 5.0], [11.0, 21.0, 16.0], 9)
    a, r = s.iloc[0], s.iloc[1]
    assert (a["cpu_ratio_to_baseline"], a["cpu_ratio_to_baseline_lo"], a["cpu_ratio_to_baseline_hi"]) == pytest.approx(
        ratio
    )
    assert a["cpu_ratio_to_baseline"] == pytest.approx(17 / 48)
    assert a["cpu_ratio_to_baseline_lo"] < a["cpu_ratio_to_baseline"] < a["cpu_ratio_to_baseline_hi"]
    assert (r["cpu_ratio_to_baseline"], r["cpu_ratio_to_baseline_lo"], r["cpu_ratio_to_baseline_hi"]) == (1.0, 1.0, 1.0)
    assert a["wall_h"] == pytest.approx(max(a["cpu_s"] / 2, 8.0) / 3600)
    with pytest.raises(FeederError, match="baseline design"):
        bench_cost.summarize(sample, 9, 2, "fast", {"yaw_sampling": "golden", "drops": 1000}, 20)
    unpaired = sample.copy()
    unpaired.loc[4, "config_id"] = "w"
    with pytest.raises(FeederError, match="configurations"):
        bench_cost.summarize(unpaired, 9, 2, "fast", {"yaw_sampling": "random", "drops": 1000}, 20)


def test_bench_cost_runs_real_jobs_and_projects_them(tmp_path):
    cfg = load_study_config("config/smoke.yaml", root=ROOT)
    cfg["parts"]["dir"] = str(ROOT / "parts")
    cfg["parts"]["include"] = ["rect-a2", "ellipse-a2", "tshape-a"]
    cfg["datasets"].update(n_holdout=1, fences_parts=0, fences_samples=0, parts_per_part=1)
    cfg["fences"]["main_per_part"] = 2
    cfg["sim"].update(drops=6, yaw_sampling="adaptive")
    cfg["sim"]["adaptive"]["n0"] = 4
    cfg["sim"]["cost_bench"] = {
        "configurations": 3,
        "drops": 2,
        "seed": 1,
        "workers": 2,
        "cores": 2,
        "baseline": {"yaw_sampling": "random", "drops": 500},
    }
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
    assert list(sample.columns) == bench_cost.SAMPLE_COLUMNS and len(sample) == 6
    adaptive, random = sample.iloc[:3], sample.iloc[3:]
    assert (adaptive["yaw_sampling"] == "adaptive").all() and (random["yaw_sampling"] == "random").all()
    assert adaptive["part"].tolist() == random["part"].tolist()  # paired on the same configurations
    assert set(sample["part"]) <= {"rect-a2", "ellipse-a2", "tshape-a"} and (random["drops"] == 2).all()
    assert adaptive["drops"].between(4, 6).all() and (adaptive["design_drops"] == 6).all()
    # the process costs more than its simulation (interpreter, imports, the part file)
    assert (sample["sim_s"] > 0).all() and (sample["overhead_s"] > 0).all()
    assert np.allclose(random["projected_job_cpu_s"], random["overhead_s"] + 500 * random["sim_s"] / 2)
    assert np.allclose(adaptive["projected_job_cpu_s"], adaptive["job_cpu_s"])
    assert summary["yaw_sampling"].tolist() == ["adaptive", "random"]
    for s, jobs, drops in ((summary.iloc[0], adaptive, 6), (summary.iloc[1], random, 500)):
        assert (s["configurations"], s["drops"], s["sampled"], s["cores"], s["preset"]) == (5, drops, 3, 2, "coarse")
        assert s["cpu_s_lo"] <= s["cpu_s"] <= s["cpu_s_hi"]
        assert s["cpu_s"] == pytest.approx(5 * jobs["projected_job_cpu_s"].mean())
        assert s["wall_h"] == pytest.approx(max(s["cpu_s"] / 2, jobs["projected_job_cpu_s"].max()) / 3600)
    assert summary["simulations_per_job"].tolist() == pytest.approx([adaptive["drops"].mean(), 500])
    assert summary["cpu_ratio_to_baseline"].iloc[0] == pytest.approx(
        summary["cpu_s"].iloc[0] / summary["cpu_s"].iloc[1]
    )


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


def test_check_projection_matches_the_design_each_run_records(tmp_path):
    sample = pd.DataFrame(
        {
            "part": ["a", "a"],
            "config_id": ["x_y", "x_y"],
            "yaw_sampling": ["adaptive", "random"],
            "design_drops": [64, 1000],
            "ms_per_drop": [100.0, 10.0],
        }
    )
    (tmp_path / "a").mkdir()
    meta = json.dumps({"yaw_sampling": "adaptive", "drops": 64})
    np.savez(tmp_path / "a" / "x_y.npz", final_yaw_deg=np.zeros(40), cpu_s=np.float64(5.0), meta=meta)
    out = bench_cost.check_projection(sample, tmp_path)
    assert list(out["part"]) == ["a", "total"]  # the baseline's row is not this run
    assert out["projected_sim_cpu_s"].tolist() == pytest.approx([4.0, 4.0])
    np.savez(tmp_path / "a" / "x_y.npz", final_yaw_deg=np.zeros(1000), cpu_s=np.float64(11.0))  # no meta: random
    out = bench_cost.check_projection(sample, tmp_path)
    assert out["projected_sim_cpu_s"].tolist() == pytest.approx([10.0, 10.0])
