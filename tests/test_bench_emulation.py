"""The emulation bench on analytic drop maps (no simulator): real i.i.d. drops through a map and
drops emulated through the adaptive design of the same map must agree; emulated through a wrong
map they must not. Plus the command's one-line errors and one tiny real run."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from workflow_helpers import ROOT

from feeder.bench import emulation as E
from feeder.bench.reference import seed_of
from feeder.cli import main as cli
from feeder.config import load_study_config
from feeder.errors import FeederError
from feeder.labels.pmf import level_drops, record_design
from feeder.sim.adaptive import refine
from feeder.sim.pushforward import emulate_drops

BUDGET = 64


def settings(**bench):
    cfg = load_study_config(root=ROOT)
    cfg["sim"]["emulation_bench"] |= {"real_drops": 1000, "levels": [50, 100, 500], "repeats": 3, "seed": 0} | bench
    return cfg


def two_basins(boundary, spread_a, spread_b, jam=None):
    """β < boundary: final yaw 40 + spread_a · β / boundary; else 220 + spread_b · (β − boundary) /
    (360 − boundary); β in ``jam`` (an interval) jams."""

    def f(beta):
        beta = np.mod(np.asarray(beta, dtype=np.float64), 360.0)
        a = beta < boundary
        final = np.where(
            a, 40.0 + spread_a * beta / boundary, 220.0 + spread_b * (beta - boundary) / (360.0 - boundary)
        )
        status = np.full(beta.shape, "ok", dtype="<U8")
        if jam is not None:
            status[(beta >= jam[0]) & (beta < jam[1])] = "jammed"
        return np.where(status == "ok", np.mod(final, 360.0), np.nan), status

    return f


def run_of(key, real_map, design_map, real_drops=1000, seed=0):
    """A run file's content: ``real_drops`` i.i.d. drops through ``real_map`` and the adaptive design
    (budget 64) of ``design_map``, as :func:`feeder.bench.emulation.run_arrays` packs them."""
    rng = np.random.default_rng(seed_of(key, seed))
    beta = rng.uniform(0.0, 360.0, real_drops)
    final, status = real_map(beta)
    offset = float(rng.uniform(0.0, 360.0 / 16))
    d = refine(design_map, n0=16, tolerance_deg=2.0, min_width_deg=0.5, budget=BUDGET, offset_deg=offset)
    design = {
        k: getattr(d, k)
        for k in ("period_deg", "offset_deg", "tolerance_deg", "min_width_deg", "max_width_deg", "band_gap_deg")
    } | {"edge_check_deg": d.edge_check_deg, "calls": d.calls}
    part, cid = key.split("__")
    meta = {"part": part, "config_id": cid, "seed": seed, "yaw_sampling": "adaptive", "design": design}
    real = {"initial_yaw_deg": beta, "final_yaw_deg": final, "status": status, "cpu_s": 1.0, "meta": json.dumps({})}
    ada = {
        "initial_yaw_deg": d.yaws,
        "final_yaw_deg": d.final,
        "status": d.status,
        "cpu_s": 0.1,
        "meta": json.dumps(meta),
    }
    entry = {"kind": "part", "part": part, "loc1": "straight:30", "loc2": "none", "key": key}
    arrays = E.run_arrays(entry, "fast", real, ada)
    return arrays | {"meta": json.loads(str(arrays["meta"])), "path": f"{key}.npz"}


def panel(wrong=None, n=24):
    """``n`` configurations of two-basin maps of varied boundary and spread (a jam arc in every
    third); ``wrong(f_args)`` gives the map the design samples instead of the true one."""
    rng = np.random.default_rng(1)
    runs = []
    for i in range(n):
        args = dict(
            boundary=float(rng.uniform(60, 300)),
            spread_a=float(rng.uniform(0, 120)),
            spread_b=float(rng.uniform(0, 120)),
            jam=(300.0, 330.0) if i % 3 == 0 else None,
        )
        true = two_basins(**args)
        runs.append(run_of(f"p{i}__c{i}", true, true if wrong is None else two_basins(**wrong(args))))
    return runs


def table(runs, cfg):
    frame = pd.DataFrame([row for r in runs for row in E.entry_rows(r, cfg)])
    return frame, E.summary(frame).set_index("n_drops")


def test_emulated_drops_through_the_true_map_agree_with_real_ones():
    cfg = settings()
    frame, s = table(panel(), cfg)
    assert set(frame.source) == {"real", "emulated"} and frame.usable.all()
    assert len(frame) == 24 * 3 * (1 + 3) and list(s.index) == [50, 100, 500]
    assert (s.verdict == "agree").all(), s[["mannwhitney_p", "ks_p"]]
    assert (s.mannwhitney_p > 0.2).all() and (s.ks_p > 0.2).all()
    # the labels agree: a 64-simulation map of a two-basin map is within sampling error of 1,000 drops
    real = frame[frame.source == "real"]
    assert (real.sup_cdf_label < real.dkw_epsilon).all()
    # real JS shrinks with N, as sampling error does
    assert s.real_median_js.is_monotonic_decreasing


def test_emulated_drops_through_a_wrong_map_are_caught():
    cfg = settings()
    # the design samples a map whose basins collapse to points: prefixes converge far too fast
    _, s = table(panel(wrong=lambda a: a | {"spread_a": 0.0, "spread_b": 0.0}), cfg)
    assert (s.verdict == "differ").all() and (s.mannwhitney_p < 1e-3).all()
    assert (s.emulated_median_js < 0.5 * s.real_median_js).all()
    # basin masses shifted by 60 degrees of initial yaw: the JS of prefixes cannot see it (it
    # measures sampling noise), the labels' sup|dCDF| does
    frame, _ = table(panel(wrong=lambda a: a | {"boundary": a["boundary"] - 50.0}), cfg)
    real = frame[frame.source == "real"]
    assert (real.sup_cdf_label > 2 * real.dkw_epsilon).all()


def test_a_prefix_is_further_from_the_exact_label_than_from_its_own_full_run():
    """A prefix against the push-forward label is further off than against all emulated drops
    (which contain the prefix): why the study compares with the 100 % level (full_run_pmf)."""
    frame, s = table(panel(n=12), settings())
    emu = frame[frame.source == "emulated"]
    assert (emu.js_label.groupby(emu.n_drops).median() > emu.js.groupby(emu.n_drops).median()).all()
    assert s.loc[500, "label_emulated_median_js"] > 1.5 * s.loc[500, "emulated_median_js"]


def test_repeat_zero_is_the_studys_own_emulation():
    run = panel(n=1)[0]
    rec = E.adaptive_record(run)
    final, ok = level_drops(rec, 1000)
    seeds = E.emulation_seeds(run, 3, 0)
    ours, status = emulate_drops(record_design(rec), 1000, seeds[0])
    np.testing.assert_array_equal(np.where(status == "ok", ours, np.nan), final)
    assert len(set(seeds)) == 3


def test_unusable_configurations_are_kept_but_left_out_of_the_summary():
    cfg = settings(repeats=2)
    jammy = two_basins(180.0, 30.0, 30.0, jam=(0.0, 250.0))  # 69 % jams: below sim.min_ok_mass
    runs = panel(n=4) + [run_of("jam__c", jammy, jammy)]
    frame, s = table(runs, cfg)
    assert not frame[frame.config == "jam__c"].usable.any()
    assert (s.configurations == 4).all() and (s.excluded_configurations == 1).all()


def test_stale_or_short_files_are_refused(tmp_path):
    run = panel(n=1)[0]
    with pytest.raises(FeederError, match="holds 1000 real drops"):
        E.entry_rows(run, settings(real_drops=500))
    with pytest.raises(FeederError, match="exceed the 1000 real drops"):
        E.entry_rows(run, settings(levels=[50, 2000]))
    bad = tmp_path / "bad.npz"
    np.savez(bad, real_initial=np.zeros(2))
    with pytest.raises(FeederError, match="lacks the array"):
        E.load_run(bad)


def test_entries_and_keys():
    cfg = load_study_config(root=ROOT)
    keys = [e["key"] for e in E.entries(cfg)]
    assert len(keys) == 32 and "circle-a__curved10_straight30" in keys and "tshape-a__straight15_straight40" in keys
    cfg["sim"]["emulation_bench"]["configurations"].append(["circle-a", "curved:10", "straight:30"])
    with pytest.raises(FeederError, match="listed twice"):
        E.entries(cfg)


def test_a_run_jobs_settings_hold_its_own_configuration_only():
    cfg = load_study_config(root=ROOT)
    s = json.loads(E.run_settings(cfg, "rect-a2__straight25_none"))
    assert s["sim"]["emulation_bench"] == {
        "configurations": [["rect-a2", "straight:25", "none"]],
        "preset": "fast",
        "real_drops": 1000,
        "seed": 0,
    }
    assert list(s["sim"]["presets"]) == ["fast"] and s["sim"]["drops"] == cfg["sim"]["drops"]
    assert E.entry_by_key(s, "rect-a2__straight25_none")["loc1"] == "straight:25"
    unknown = json.loads(E.run_settings(cfg, "nope"))
    with pytest.raises(FeederError, match="no configuration 'nope'"):
        E.entry_by_key(unknown, "nope")


def _one_line_error(capsys, argv, text):
    assert cli(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("feeder bench-emulation: error:") and text in err and "\n" not in err


def test_unknown_key_and_missing_file_are_one_line_errors(tmp_path, capsys):
    out = tmp_path / "x.npz"
    argv = ["bench-emulation", "run", "--configfile", "config/smoke.yaml", "--key", "nope", "--out", str(out)]
    _one_line_error(capsys, argv, "no configuration 'nope'")
    assert not out.exists()
    csv, summ = tmp_path / "rows.csv", tmp_path / "summary.csv"
    argv = ["bench-emulation", "table", "--configfile", "config/smoke.yaml", "--runs", str(tmp_path / "missing.npz")]
    _one_line_error(capsys, [*argv, "--out-csv", str(csv), "--out-summary", str(summ)], "missing.npz is missing")
    assert not csv.exists() and not summ.exists()
    _one_line_error(capsys, ["bench-emulation", "list", "--settings", "{}"], "lack section sim.emulation_bench")


def test_table_command_writes_rows_and_summary(tmp_path, capsys):
    from feeder.io import write_npz

    runs = []
    for r in panel(n=3):
        path = tmp_path / f"{r['meta']['entry']['key']}.npz"
        write_npz(path, **{k: r[k] for k in E.RUN_KEYS if k != "meta"}, meta=np.array(json.dumps(r["meta"])))
        runs.append(str(path))
    cfg = settings(repeats=2)
    csv, summ = tmp_path / "rows.csv", tmp_path / "summary.csv"
    argv = ["bench-emulation", "table", "--settings", json.dumps(cfg), "--runs", *runs]
    assert cli([*argv, "--out-csv", str(csv), "--out-summary", str(summ)]) == 0
    assert len(pd.read_csv(csv)) == 3 * 3 * 3 and list(pd.read_csv(summ).n_drops) == [50, 100, 500]
    assert "N    50: JS median real" in capsys.readouterr().err
    _one_line_error(capsys, [*argv, runs[0], "--out-csv", str(csv), "--out-summary", str(summ)], "twice")


def test_a_tiny_real_run(tmp_path):
    """One cheap configuration simulated for real: 6 random drops and an adaptive design of 16."""
    pytest.importorskip("pybullet")
    cfg = load_study_config("config/smoke.yaml", root=ROOT)
    cfg["sim"]["drops"] = 16
    cfg["sim"]["emulation_bench"] |= {"real_drops": 6, "levels": [3], "repeats": 2}
    out = tmp_path / "run.npz"
    key = "rect-a2__straight45_none"
    assert cli(["bench-emulation", "run", "--settings", json.dumps(cfg), "--key", key, "--out", str(out)]) == 0
    run = E.load_run(out)
    assert run["real_final"].size == 6 and run["adaptive_final"].size == 16
    assert run["meta"]["entry"]["key"] == key and run["meta"]["adaptive"]["design"]["evaluations"] == 16
    rows = pd.DataFrame(E.entry_rows(run, cfg))
    assert len(rows) == 1 + 2 and rows.js.notna().all()
