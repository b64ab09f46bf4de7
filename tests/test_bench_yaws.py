"""feeder.bench.yaws: drops needed per initial-yaw design (pure summary, power law, a tiny run)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from feeder.bench import yaws as bench_yaws
from feeder.labels import metrics as labels

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())


def test_power_law_fit_and_inverse_hand_values():
    a, b = bench_yaws.power_law([25, 100, 400], [20.0, 10.0, 5.0])  # W1 = 100 / sqrt(N)
    assert a == pytest.approx(100.0) and b == pytest.approx(-0.5)
    assert bench_yaws.drops_for(2.0, a, b) == pytest.approx(2500.0)
    assert math.isnan(bench_yaws.drops_for(2.0, 1.0, 0.1))  # a fit that does not fall: no answer
    assert math.isnan(bench_yaws.power_law([10, 10], [1.0, 2.0])[0])  # one distinct N: no fit
    assert math.isnan(bench_yaws.drops_for(0.0, a, b))


def test_summary_counts_the_drops_a_design_saves():
    """Two designs on a two-mode process: 'golden' made from evenly spread quantiles is closer."""
    rng = np.random.default_rng(0)
    levels, n_cfg = [20, 40, 80, 160], 40

    def quant(u):  # yaw from a uniform u
        return np.where(u < 0.7, 90.0 + 10 * u, 270.0 + 10 * u)

    ref = {i: quant((np.arange(20000) + 0.5) / 20000) for i in range(n_cfg)}  # the exact distribution
    u_even = [np.mod(rng.uniform() + np.arange(160) * (math.sqrt(5) - 1) / 2, 1.0) for _ in range(n_cfg)]
    results = {("random", i): (quant(rng.uniform(size=160)), 1.6) for i in range(n_cfg)}
    results.update({("golden", i): (quant(u_even[i]), 1.6) for i in range(n_cfg)})
    panel = [("rect-40x20", f"straight:{20 + i}", "none") for i in range(n_cfg)]
    df = bench_yaws.summarize(results, ref, panel, levels, CFG["labels"])
    mean = df[df["config"] == "mean"].set_index(["design", "drops"])
    assert mean.loc[("random", 80), "ms_per_drop"] == pytest.approx(10.0)  # 1.6 s / 160 drops
    for k in levels:
        assert mean.loc[("golden", k), "w1_deg"] < mean.loc[("random", k), "w1_deg"]
        # random against its own fit: about the drops it used
        assert mean.loc[("random", k), "drops_saved_factor"] == pytest.approx(1.0, abs=0.3)
    assert mean.loc[("golden", 160), "drops_saved_factor"] > 3.0
    u_even = u_even[0]
    # the per-configuration distance is the labels module's W1 of the first k drops
    one = df[(df["design"] == "golden") & (df["drops"] == 40) & (df["config"] != "mean")].iloc[0]
    bins, sigma = CFG["labels"]["bins"], CFG["labels"]["sigma_bins"]
    p, q = labels.pmf_from_yaws(quant(u_even)[:40], bins, sigma), labels.pmf_from_yaws(ref[0], bins, sigma)
    assert one["w1_deg"] == pytest.approx(float(labels.w1(labels.cdf(p), labels.cdf(q))))


@pytest.mark.slow
def test_bench_yaws_cli_tiny_panel(tmp_path):
    cfg = {"scene": CFG["scene"], "labels": CFG["labels"], "sim": dict(CFG["sim"])}
    cfg["sim"]["bench"] = dict(CFG["sim"]["bench"], panel=[["rect-40x20", "straight:45", "none"]])
    cfg["sim"]["yaw_bench"] = dict(
        CFG["sim"]["yaw_bench"], preset="coarse", reference_drops=6, drop_levels=[2, 4], workers=1
    )
    csv, png = tmp_path / "y.csv", tmp_path / "y.png"
    r = subprocess.run(
        [sys.executable, "-m", "feeder", "bench-yaws", "--settings", json.dumps(cfg), "--out-csv", str(csv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(csv)
    assert set(df["design"]) == {"random", "golden"} and set(df["drops"]) == {2, 4}
    assert (df["reference_drops"] == 6).all() and df["js"].notna().all()
    r = subprocess.run(
        [sys.executable, "-m", "feeder", "figure", "yaw_sampling", "--data", str(csv), "--out", str(png)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    cfg["sim"]["yaw_bench"]["drop_levels"] = [2, 40]
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "feeder",
            "bench-yaws",
            "--settings",
            json.dumps(cfg),
            "--out-csv",
            str(tmp_path / "z.csv"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode != 0 and "reference_drops" in r.stderr and not (tmp_path / "z.csv").exists()
