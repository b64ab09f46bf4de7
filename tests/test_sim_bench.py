"""feeder.bench.accuracy: the accuracy-against-time summary (pure) and a tiny end-to-end run."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from feeder.bench import accuracy as bench
from feeder.labels import metrics as labels

ROOT = Path(__file__).resolve().parents[1]
CFG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())


def _fake_results(rng, drops):
    panel = [("rect-40x20", "straight:45", "none"), ("tri-40x25", "curved:45", "none")]
    settings = {
        "faithful": dict(CFG["sim"]["presets"]["faithful"]),
        "fast": dict(CFG["sim"]["presets"]["fast"]),
        "biased": dict(CFG["sim"]["presets"]["fast"]),
    }
    res = {}
    ok = np.array(["ok"] * drops)
    for i in range(len(panel)):
        ref0 = (180.0 + np.degrees(rng.vonmises(0.0, 4.0, drops))) % 360
        ref1 = (180.0 + np.degrees(rng.vonmises(0.0, 4.0, drops))) % 360
        res[("faithful", 0, i)] = (ref0, ok, 10.0)
        res[("faithful", 1, i)] = (ref1, ok, 10.0)
        res[("fast", 1, i)] = (ref1.copy(), ok, 0.5)  # the same sample as the floor: distance = floor
        res[("biased", 1, i)] = ((ref1 + 40.0) % 360, ok, 0.25)  # shifted by 40°
    return res, settings, panel


def test_summary_floor_speedup_and_bias():
    rng = np.random.default_rng(0)
    drops = 200
    res, settings, panel = _fake_results(rng, drops)
    bcfg = dict(CFG["sim"]["bench"], drop_levels=[50])
    df = bench.summarize(res, settings, panel, [0, 1], "faithful", drops, bcfg, CFG["labels"])
    agg = df[(df["config"] == "mean") & (df["drops"] == drops)].set_index("setting")
    assert agg.loc["fast", "js"] == pytest.approx(agg.loc["fast", "js_floor"])
    assert agg.loc["fast", "within_floor"] and not agg.loc["biased", "within_floor"]
    assert agg.loc["fast", "speedup_vs_reference"] == pytest.approx(20.0)  # 10 s vs 0.5 s of CPU
    assert agg.loc["biased", "speedup_vs_reference"] == pytest.approx(40.0)
    assert agg.loc["fast", "ms_per_drop"] == pytest.approx(0.5e3 / drops)
    # W1 of a 40° shift between two concentrated distributions is about 40°
    assert agg.loc["biased", "w1_deg"] == pytest.approx(40.0, abs=8.0)
    # drop levels: the first 50 drops, per configuration and as a mean
    assert set(df["drops"]) == {50, drops}
    one = df[(df["setting"] == "fast") & (df["drops"] == 50) & (df["config"] != "mean")].iloc[0]
    p = labels.pmf_from_yaws(res[("fast", 1, 0)][0][:50], CFG["labels"]["bins"], CFG["labels"]["sigma_bins"])
    q = labels.pmf_from_yaws(res[("faithful", 0, 0)][0], CFG["labels"]["bins"], CFG["labels"]["sigma_bins"])
    assert one["js"] == pytest.approx(float(labels.js_divergence(p, q)))


def test_resolve_setting_overrides_base():
    s = bench.resolve_setting(CFG["sim"]["presets"], {"name": "x", "substeps": 7})
    assert s["substeps"] == 7 and s["lanes"] == CFG["sim"]["presets"]["fast"]["lanes"]
    with pytest.raises(Exception, match="unknown base"):
        bench.resolve_setting(CFG["sim"]["presets"], {"name": "x", "base": "nope"})


@pytest.mark.slow
def test_bench_cli_tiny_panel(tmp_path):
    cfg = {"scene": CFG["scene"], "labels": CFG["labels"], "sim": dict(CFG["sim"])}
    cfg["sim"]["bench"] = dict(
        CFG["sim"]["bench"],
        drops=4,
        drop_levels=[2],
        workers=1,
        panel=[["rect-40x20", "straight:45", "none"]],
        sweep=[{"name": "fast"}],
    )
    csv, png = tmp_path / "b.csv", tmp_path / "b.png"
    r = subprocess.run(
        [sys.executable, "-m", "feeder", "bench-sim", "--settings", json.dumps(cfg), "--out-csv", str(csv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(csv)
    assert set(df["setting"]) == {"faithful", "fast"}
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "feeder",
            "figure",
            "sim_accuracy_vs_time",
            "--data",
            str(csv),
            "--reference",
            CFG["sim"]["bench"]["reference"],
            "--out",
            str(png),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:4] == b"\x89PNG"
    agg = df[(df["config"] == "mean") & (df["drops"] == 4)].set_index("setting")
    assert agg.loc["fast", "speedup_vs_reference"] > 1.0


def test_bootstrap_floor_of_an_all_jammed_configuration_is_nan():
    """A fence that jams every part leaves no distribution: the floor is NaN, the bench goes on."""
    import math

    from feeder.bench.accuracy import bootstrap_js_floor

    jammed = np.full(10, np.nan)
    assert math.isnan(bootstrap_js_floor(jammed, jammed, 5, 360, 1.0, 20, 0.95, seed=0))


def test_merge_scene_replaces_nested_values_only():
    scene = {"belt": {"speed": 0.1, "start_y": 0.0}, "gravity": 9.81}
    out = bench.merge_scene(scene, {"belt": {"start_y": -0.5}})
    assert out == {"belt": {"speed": 0.1, "start_y": -0.5}, "gravity": 9.81}
    assert scene["belt"]["start_y"] == 0.0  # the input is untouched
    assert bench.merge_scene(scene, None) == scene
    with pytest.raises(Exception, match="unknown scene key"):
        bench.merge_scene(scene, {"belt": {"colour": "red"}})


def test_bench_settings_can_be_config_overlays(monkeypatch):
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    _, scene, sim_cfg, _ = bench.bench_cli(
        "feeder bench-sim", "doc", ["--out-csv", "x.csv", "--configfile", "config/rigid.yaml"]
    )
    assert scene["belt"]["contact_stiffness"] is None and scene["belt"]["speed"] == 0.10  # overlaid, rest kept
    assert [s["name"] for s in sim_cfg["bench"]["sweep"]][1] == "fast"
    _, plain, _, _ = bench.bench_cli("feeder bench-sim", "doc", ["--out-csv", "x.csv"])
    assert plain["belt"]["contact_stiffness"] == 1000.0


def _pairs(rng, n, configs, shift_a=0.0, same=False):
    out = []
    for _ in range(configs):
        ref = (90.0 + np.degrees(rng.vonmises(0.0, 8.0, n))) % 360
        b = (90.0 + np.degrees(rng.vonmises(0.0, 8.0, n))) % 360
        a = b.copy() if same else (90.0 + np.degrees(rng.vonmises(0.0, 8.0, n))) % 360
        out.append(((a + shift_a) % 360, b, ref))
    return out


def test_paired_excess_identical_runs_have_zero_excess_and_p_one():
    t = bench.paired_excess(_pairs(np.random.default_rng(1), 60, 3, same=True), 360, 1.0, 50, seed=0)
    assert t["js"] == (0.0, 1.0) and t["w1"] == (0.0, 1.0)


def test_paired_excess_flags_a_systematic_shift_but_not_sampling():
    rng = np.random.default_rng(2)
    shifted = bench.paired_excess(_pairs(rng, 80, 4, shift_a=5.0), 360, 1.0, 100, seed=0)
    assert shifted["w1"][0] > 2.0 and shifted["w1"][1] < 0.05  # a quarter of the spread: W1 sees it
    far = bench.paired_excess(_pairs(rng, 80, 4, shift_a=20.0), 360, 1.0, 100, seed=0)
    assert far["js"][1] < 0.05 and far["w1"][1] < 0.05
    fair = bench.paired_excess(_pairs(rng, 80, 4), 360, 1.0, 100, seed=0)
    assert fair["js"][1] > 0.05 and fair["w1"][1] > 0.05


def test_paired_excess_wraps_around_zero_and_skips_failed_drops():
    rng = np.random.default_rng(3)
    b, r = np.degrees(rng.vonmises(0.0, 8.0, (2, 40))) % 360  # both straddle 0/360
    a = b.copy()
    a[:5] = np.nan  # failed drops of the setting: left out of its PMF, not an error
    t = bench.paired_excess([(a, b, r)], 360, 1.0, 50, seed=0)
    assert np.isfinite(t["js"][0]) and 0.0 < t["js"][1] <= 1.0
    # a sample straddling 0/360 shifted by one full turn is the same sample
    t2 = bench.paired_excess([((b + 360.0) % 360, b, r)], 360, 1.0, 20, seed=0)
    assert t2["js"] == (0.0, 1.0)
    with pytest.raises(Exception, match="differ in length"):
        bench.paired_excess([(a[:10], b, r)], 360, 1.0, 5, seed=0)
