"""feeder.figures: every figure drawn from a tiny synthetic data file, the dispatcher, the data
readers' one-line errors, and the workflow property the split exists for (a figure module is an
input of its own drawing job only)."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeder import figures
from feeder.cli import main as cli
from feeder.errors import FeederError
from feeder.figures import style

ROOT = Path(__file__).resolve().parents[1]
LEVELS = np.array([10, 50, 100])


def _fig6(path):
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    outline = np.stack([0.5 * np.cos(t) + 0.25j * np.sin(t), 0.4 * np.cos(t) + 0.4j * np.sin(t)])
    np.savez(
        path,
        name=np.array(["ellipse", "circle"]),
        outline=outline,
        reconstruction=outline * 0.98,
        mse=np.array([1.5e-2, 2.0e-3]),
        coefficients=np.int64(15),
    )


def _s1(path):
    n = np.arange(1, 21)
    mse = 10.0 / n**2
    pd.DataFrame(
        {
            "n_coefficients": n,
            "mean_mse": mse,
            "std_mse": mse / 3,
            "q25_mse": mse / 2,
            "median_mse": mse * 0.9,
            "q75_mse": mse * 1.5,
            "max_mse": mse * 3,
            "n_parts": 5,
        }
    ).to_csv(path, index=False)


def _fig4(path):
    pd.DataFrame(
        {
            "level_pct": LEVELS,
            "n_drops": LEVELS * 10,
            "mean_js": [0.2, 0.05, 0.0],
            "sd_js": [0.05, 0.01, 0.0],
            "configurations": 7,
        }
    ).to_csv(path, index=False)


def _fig5(path):
    rng = np.random.default_rng(0)
    np.savez(
        path,
        js=rng.gamma(2.0, 0.01, size=50),
        noise_floor=np.float64(0.03),
        noise_quantile=np.float64(0.95),
        n_drops=np.int64(500),
        n_drops_full=np.int64(1000),
    )


def _fig9(path):
    yaw = (np.arange(36) + 0.5) * 10.0
    pmf = np.stack([np.exp(-(((yaw - c) / 20.0) ** 2)) for c in (90.0, 180.0, 270.0)])
    np.savez(
        path,
        part=np.array(["a", "b", "c"]),
        config_id=np.array(["straight30_none"] * 3),
        label=np.array(["1 peak", "most concentrated", "most spread"]),
        pmf=pmf / pmf.sum(axis=1, keepdims=True),
        yaw_deg=yaw,
    )


def _dkw(path):
    n = LEVELS * 10
    eps = np.sqrt(np.log(2 / 0.05) / (2 * n))
    np.savez(
        path,
        level_pct=LEVELS,
        n_drops=n,
        q10_sup=np.array([0.02, 0.01, 0.0]),
        median_sup=np.array([0.05, 0.02, 0.0]),
        q90_sup=np.array([0.1, 0.04, 0.0]),
        dkw_epsilon=eps,
        fraction_inside_band=np.array([0.9, 0.97, 1.0]),
        alpha=np.float64(0.05),
        n_drops_full=np.int64(1000),
    )


def _p2(path):
    pd.DataFrame(
        {
            "level_pct": LEVELS,
            "within_r2_mean": [0.8, 0.9, 0.95],
            "within_r2_sd": [0.1, 0.05, 0.02],
            "cross_r2_mean": [0.6, 0.85, 0.95],
            "cross_r2_sd": [0.2, 0.1, 0.02],
            "partial_baseline_r2_mean": [0.3, 0.8, 1.0],
        }
    ).to_csv(path, index=False)


def _table10(path):
    frame = {"level_pct": LEVELS, "cost_saved_pct": 100.0 - LEVELS}
    for mode in ("part", "config"):
        frame.update(
            {
                f"{mode}_r2_mean": [0.7, 0.9, 0.99],
                f"{mode}_r2_sd": [0.2, 0.05, 0.01],
                f"{mode}_baseline_mean": [0.2, 0.8, 1.0],
                f"{mode}_baseline_sd": [0.3, 0.1, 0.0],
            }
        )
    pd.DataFrame(frame).to_csv(path, index=False)


def _predictions(path):
    yaw = np.arange(36) * 10.0
    true = np.stack([np.clip((yaw - 60.0 * i) / 180.0, 0, 1) for i in range(4)])
    pred = np.clip(true + 0.03, 0, 1)
    np.savez(
        path,
        part=np.array(["a", "b", "c", "d"]),
        config_id=np.array(["straight30_none"] * 4),
        yaw_deg=yaw,
        cdf_true=true,
        cdf_pred=pred,
        r2=np.array([0.99, 0.9, 0.7, 0.4]),
        model=np.array("m3"),
        split=np.array("Test"),
    )


def _bench(path):
    rows = []
    for setting, ms, js, w1 in (("faithful", 40.0, 0.02, 1.0), ("fast", 4.0, 0.03, 1.5), ("coarse", 1.0, 0.2, 9.0)):
        for drops in (10, 50):
            rows.append(
                {
                    "setting": setting,
                    "drops": drops,
                    "config": "mean",
                    "ms_per_drop": ms,
                    "js": js * 50 / drops,
                    "js_floor": 0.025,
                    "w1_deg": w1,
                    "w1_floor_deg": 1.2,
                    "within_floor": js <= 0.025,
                }
            )
            rows.append({**rows[-1], "config": "rect|straight:45|none"})
    pd.DataFrame(rows).to_csv(path, index=False)


def _cost(path):
    pd.DataFrame(
        {
            "stage": ["simulate", "train", "figures", "TOTAL"],
            "jobs": [30, 2, 9, 41],
            "wall_s": [120.0, 40.0, 9.0, 169.0],
            "cpu_s": [110.0, 70.0, 8.0, 188.0],
            "max_rss_mb": [300.0, 900.0, 120.0, 900.0],
        }
    ).to_csv(path, index=False)


def _jams(path):
    # the rates differ by location and by part, so a line or point drawn from the wrong rows shows
    rows = [
        {"fence": f, "angle_deg": a, "location": loc, "part": p, "ok_rate": r * scale * share}
        for f, a, r in (("straight", 30.0, 1.0), ("straight", 65.0, 0.4), ("curved", 60.0, 0.2))
        for loc, scale in (("loc1", 1.0), ("loc2", 0.8))
        for p, share in (("a", 0.5), ("b", 1.0), ("mean", 0.75))
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _yaws(path):
    rows = [
        {
            "design": d,
            "drops": n,
            "config": c,
            "js": (1.0 if c == "mean" else 1.5) * 0.5 / n**e,
            "w1_deg": (1.0 if c == "mean" else 1.5) * 30.0 / n**e,
            "random_drops_same_w1": n ** (2 * e),
            "reference_drops": 1000,
        }
        for d, e in (("random", 0.5), ("golden", 0.8))
        for n in (25, 50, 100)
        for c in ("a|straight:30|none", "mean")
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _sim_cost(path):
    pd.DataFrame(
        {
            "part": ["rect", "rect", "crescent"] * 2,
            "config_id": ["straight30_none", "none_curved60", "straight30_none"] * 2,
            "yaw_sampling": ["adaptive"] * 3 + ["random"] * 3,
            "design_drops": [64] * 3 + [1000] * 3,
            "drops": [30, 64, 41, 20, 20, 20],
            "ms_per_drop": [90.0, 130.0, 1600.0, 80.0, 120.0, 1500.0],
        }
    ).to_csv(path, index=False)


# figure -> (data file name, writer, extra CLI options)
def _label_designs(path):
    rows = []
    for design, sims, e in (
        ("random", (50, 100, 200), 0.5),
        ("grid", (50, 100, 200), 1.0),
        ("adaptive", (32, 64), 1.5),
    ):
        for n in sims:
            row = {"design": design, "drops": n, "simulations": n, "configurations": 3}
            for col, scale in (("sup_cdf", 0.5), ("circular_w1_deg", 50.0)):
                row[col] = scale / n**e
                row[f"{col}_lo"], row[f"{col}_hi"] = 0.8 * row[col], 1.2 * row[col]
            rows.append(row)
    pd.DataFrame(rows).to_csv(path, index=False)


def _label_emulation(path):
    rng = np.random.default_rng(0)
    rows = [
        {
            "config": f"c{i}",
            "n_drops": n,
            "source": src,
            "repeat": r,
            "js": float(rng.gamma(2, 2.0 / n)),
            "usable": i < 9,
        }
        for i in range(10)
        for n in (50, 100, 500)
        for src, repeats in (("real", 1), ("emulated", 3))
        for r in range(repeats)
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _contact(path):
    # two configurations per part with different values, so a missing mean over them shows
    rows = [
        {
            "part": p,
            "pieces": n,
            "configuration": c,
            "footprint": fp,
            "cpu_ms_per_drop": base * n * k,
            "same_basin_vs_reference": agree * k2,
        }
        for p, n in (("gear", 9), ("crescent", 36))
        for c, k, k2 in (("a|b", 1.0, 1.0), ("c|d", 3.0, 0.5))
        for fp, base, agree in (("pieces", 50.0, 0.8), ("pads16", 10.0, 0.9), ("pads32", 20.0, 1.0))
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _decomposition(path):
    # two models, one part each way; a verdict row per model (the figure's right panel)
    rows = [
        {
            "kind": "decomposition",
            "part": p,
            "model": m,
            "median_dyaw_deg": d,
            "circular_w1_deg": 2 * d,
            "floor_median_dyaw_deg": f,
            "floor_circular_w1_deg": 2 * f,
            "passes": d <= 2 * f,
            "passes_paired": d <= 2 * f,
            "passes_label": True,
            "cpu_ms_per_drop": None,
            "rows": None,
            "rows_passed_paired": None,
            "rows_passed_label": None,
        }
        for p in ("rect", "ell")
        for m, d, f in (("pieces", 3.0, 0.1), ("pads8", 0.1, 0.1))
    ] + [
        {
            "kind": "verdict",
            "part": "all",
            "model": m,
            "passes": ok,
            "passes_paired": ok,
            "passes_label": True,
            "cpu_ms_per_drop": c,
            "rows": 2,
            "rows_passed_paired": int(ok) * 2,
            "rows_passed_label": 2,
        }
        for m, ok, c in (("pieces", False, 80.0), ("pads8", True, 95.0))
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _frontier(path):
    # two predictors (one a lookup at 0 s) and one budget, both sets of configurations
    rows = [
        {
            "configurations": subset,
            "answer": answer,
            "kind": kind,
            "n": 3,
            "cpu_s_mean": cpu,
            "circular_w1_deg": w1,
            "circular_w1_low": w1 - 1.0,
            "circular_w1_high": w1 + 2.0,
        }
        for subset in ("all", "unseen")
        for answer, kind, cpu, w1 in (
            ("mean_pmf", "predictor", 0.0, 29.0),
            ("analytic", "predictor", 0.1, 18.0),
            ("simulate8", "simulate", 3.0, 6.0),
        )
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _frontier_known(path):
    # two predictors (one a lookup at 0 s) and two budgets on the simulated set; predictors on Test
    rows = [
        {
            "configurations": subset,
            "answer": answer,
            "kind": kind,
            "budget": budget,
            "n": 3,
            "cpu_s_mean": cpu,
            "circular_w1_deg": w1,
            "circular_w1_low": w1 - 1.0,
            "circular_w1_high": w1 + 2.0,
        }
        for subset, answer, kind, budget, cpu, w1 in (
            ("all", "mean_pmf", "predictor", 0, 0.0, 29.0),
            ("all", "structured", "predictor", 0, 0.3, 9.0),
            ("all", "simulate8", "simulate", 8, 3.0, 4.0),
            ("all", "simulate40", "simulate", 40, 12.0, 1.5),
            ("test", "structured", "predictor", 0, 0.3, 10.0),
        )
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _step(path):
    # one part: the bare world (no configuration, no fit) and two configurations' drops
    rows = [
        {
            "part": "rect",
            "configuration": c,
            "world": w,
            "us_per_step": us,
            "us_per_step_low": us - 1.0,
            "us_per_step_high": us + 2.0,
            "us_per_step_all": us * 1.1 if w == "drop" else np.nan,
            "mean_contact_points": n,
            "us_at_no_contact": a,
            "us_per_contact_point": b,
        }
        for c, w, us, n, a, b in (
            ("straight:30|none", "drop", 16.0, 6.0, 4.0, 2.0),
            (np.nan, "bare", 7.0, 4.0, np.nan, np.nan),
            ("curved:40|curved:60", "drop", 30.0, 12.0, 6.0, 2.0),
        )
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _physics(path):
    # two factors, the floor and two model errors (rows of other kinds carry NaN in the others' columns)
    stats = ("circular_w1_deg", "same_basin", "circular_w1_to_floor")
    rows = [
        {"kind": "factor", "factor": name}
        | {f"{k}_median{s}": v * m for k in stats for s, m in (("", 1.0), ("_low", 0.5), ("_high", 1.5))}
        | {"circular_w1_deg_mean": v}
        for name, v in (("part_friction_x0.8", 4.0), ("restitution_0.1", 0.0))
    ]
    rows.append(
        {"kind": "floor", "factor": "floor"}
        | {f"{k}_median{s}": 0.5 * m for k in stats for s, m in (("", 1.0), ("_low", 0.5), ("_high", 1.5))}
        | {"circular_w1_deg_mean": 0.5}
    )
    rows += [{"kind": "model_error", "factor": n, "circular_w1_deg_mean": v} for n, v in (("m3", 24.0), ("pmf", 15.0))]
    rows.append({"kind": "configuration", "factor": "part_friction_x0.8", "circular_w1_deg_mean": np.nan})
    pd.DataFrame(rows).to_csv(path, index=False)


def _label_errors(path):
    rng = np.random.default_rng(0)
    n = 40
    pd.DataFrame(
        {
            "loc1": rng.choice(["straight", "curved"], n),
            "loc2": rng.choice(["none", "straight", "curved"], n),
            "kept": [True] * (n - 2) + [False] * 2,
            "est_circular_w1_deg": rng.uniform(2.0, 30.0, n),
            "est_sup_cdf": rng.uniform(0.03, 0.4, n),
        }
    ).to_csv(path, index=False)


CASES = {
    "label_error_estimate": ("label_errors.csv", _label_errors, []),
    "step_cost": ("step.csv", _step, []),
    "frontier": ("frontier.csv", _frontier, []),
    "frontier_known": ("frontier_known.csv", _frontier_known, []),
    "label_designs": ("label_designs_summary.csv", _label_designs, []),
    "label_emulation": ("label_emulation.csv", _label_emulation, []),
    "fig6_dft_reconstruction": ("fig6.npz", _fig6, []),
    "s1_dft_mse": ("s1.csv", _s1, ["--chosen", "15"]),
    "fig4_js_vs_drops": ("fig4.csv", _fig4, []),
    "fig5_js_hist": ("fig5.npz", _fig5, []),
    "fig9_example_pmfs": ("fig9.npz", _fig9, []),
    "convergence_dkw": ("dkw.npz", _dkw, []),
    "fig12_test_predictions": ("fig12.npz", _predictions, []),
    "fig13_parts_predictions": ("fig13.npz", _predictions, []),
    "fig14_cross_convergence": ("p2.csv", _p2, []),
    "s11_delta_sweep": ("table10.csv", _table10, []),
    "cost_by_stage": ("cost.csv", _cost, []),
    "sim_accuracy_vs_time": ("bench.csv", _bench, ["--reference", "faithful"]),
    "jam_rates": ("jams.csv", _jams, []),
    "yaw_sampling": ("yaws.csv", _yaws, []),
    "sim_cost": ("sim_cost.csv", _sim_cost, []),
    "contact_model": ("contact.csv", _contact, []),
    "contact_decomposition": ("decomposition.csv", _decomposition, []),
    "physics_sensitivity": ("physics.csv", _physics, []),
}


def test_every_figure_module_has_a_case():
    assert figures.figure_names() == sorted(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_draws_from_a_tiny_data_file(name, tmp_path):
    data_name, writer, extra = CASES[name]
    data = tmp_path / data_name
    writer(data)
    out = tmp_path / "out" / f"{name}.png"
    assert cli(["figure", name, "--data", str(data), "--out", str(out), *extra]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5_000
    assert not list(out.parent.glob("*.tmp")), "a temporary file was left behind"


@pytest.mark.parametrize("name", sorted(CASES))
def test_missing_data_is_one_line_error_and_writes_nothing(name, tmp_path, capsys):
    out = tmp_path / f"{name}.png"
    _, _, extra = CASES[name]
    assert cli(["figure", name, "--data", str(tmp_path / "missing.csv"), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("feeder figure: error: figure data") and "missing" in err and "\n" not in err
    assert not out.exists()


def test_wrong_columns_and_keys_are_named(tmp_path):
    csv = tmp_path / "fig4.csv"
    pd.DataFrame({"n_drops": [1], "mean_js": [0.1]}).to_csv(csv, index=False)
    with pytest.raises(FeederError, match="lacks the column\\(s\\) sd_js, configurations"):
        style.read_csv(csv, ("n_drops", "mean_js", "sd_js", "configurations"))
    npz = tmp_path / "fig5.npz"
    np.savez(npz, js=np.zeros(3))
    with pytest.raises(FeederError, match="lacks the array\\(s\\) noise_floor"):
        style.read_npz(npz, ("js", "noise_floor"))
    empty = tmp_path / "empty.csv"
    empty.write_text("n_drops,mean_js\n")
    with pytest.raises(FeederError, match="has no rows"):
        style.read_csv(empty, ("n_drops",))


def test_unknown_figure_is_refused(capsys):
    assert cli(["figure", "fig99_nothing"]) == 2
    assert "unknown figure 'fig99_nothing'" in capsys.readouterr().err
    assert cli(["figure", "style"]) == 2  # the shared style is not a figure
    assert cli(["figure"]) == 0 and "fig4_js_vs_drops" in capsys.readouterr().out


def test_style_is_applied(tmp_path):
    fig, ax = style.subplots()
    import matplotlib

    assert all(matplotlib.rcParams[k] == v for k, v in style.RC.items())
    style.save(fig, tmp_path / "x.png")
    assert (tmp_path / "x.png").is_file()


@pytest.mark.parametrize("name", sorted(CASES))
def test_figure_modules_import_no_stage_module(name):
    """A figure module reads data; importing a stage module would make its drawing job depend
    on that module's source (and a compute edit would have to rerun the figure)."""
    tree = ast.parse((ROOT / "src/feeder/figures" / f"{name}.py").read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
        elif isinstance(node, ast.Import):
            imported.update(a.name for a in node.names)
    feeder_modules = {m for m in imported if m == "feeder" or m.startswith("feeder.")}
    allowed = {"feeder.figures", "feeder.figures.style", "feeder.errors", "feeder.io"}
    shared = {m for m in feeder_modules if m.startswith("feeder.figures._")}
    assert feeder_modules - shared <= allowed, feeder_modules


def test_each_figure_module_has_one_drawing_rule_and_compute_rules_read_no_figure_module():
    """In the rules files, figure modules reach a job only through the figure table: each figure
    module under src/feeder/figures/ has its entry (so its draw_<name> rule), and no other rule
    names a drawing module."""
    report = (ROOT / "workflow/rules/report.smk").read_text()
    table = set(re.findall(r'^    "(\w+)": \(', report, flags=re.M))
    modules = {p.stem for p in (ROOT / "src/feeder/figures").glob("*.py") if not p.stem.startswith("_")}
    assert table == modules - {"__init__", "style"}
    assert table >= set(CASES)
    for smk in sorted((ROOT / "workflow/rules").glob("*.smk")):
        assert "feeder/figures" not in smk.read_text(), smk.name


@pytest.mark.slow
def test_style_edit_reruns_only_that_figure(tmp_path):
    """Build the two parts-stage figures in a scratch copy of the workflow, then edit drawing code
    and read the dry run's job list: a figure module edit redraws that figure only, a style.py
    edit redraws both, a compute module edit recomputes and redraws."""
    from workflow_helpers import planned_rules, scratch_copy, snakemake

    work = scratch_copy(tmp_path / "w")
    smoke = ("--configfile", "config/smoke.yaml")
    targets = ("results/smoke/figures/s1_dft_mse.png", "results/smoke/figures/fig6_dft_reconstruction.png")
    built = snakemake(work, *targets, *smoke)
    assert built.returncode == 0, built.stderr[-3000:]
    assert planned_rules(work, *targets, *smoke) == set()

    def edit(relpath):
        path = work / relpath
        path.write_text(path.read_text() + "\n# style tweak\n")

    edit("src/feeder/figures/s1_dft_mse.py")
    assert planned_rules(work, *targets, *smoke) == {"draw_s1_dft_mse"}
    edit("src/feeder/figures/style.py")
    assert planned_rules(work, *targets, *smoke) == {"draw_s1_dft_mse", "draw_fig6_dft_reconstruction"}
    edit("src/feeder/parts/features.py")
    assert planned_rules(work, *targets, *smoke) == {
        "parts_s1",
        "parts_fig6_data",
        "draw_s1_dft_mse",
        "draw_fig6_dft_reconstruction",
    }


def test_label_designs_plots_each_designs_means_against_its_simulations(tmp_path):
    """The figure's lines are the summary's numbers: one line per design (reference left out),
    x = simulations, y = the metric of each panel, in order of simulations."""
    from feeder.figures import label_designs

    csv = tmp_path / "s.csv"
    _label_designs(csv)
    df = pd.read_csv(csv)
    fig = label_designs.draw(df)
    for ax, col in zip(fig.axes, ("sup_cdf", "circular_w1_deg"), strict=True):
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert set(lines) == set(df.design)
        for design, sub in df.groupby("design"):
            sub = sub.sort_values("simulations")
            np.testing.assert_allclose(lines[design].get_xdata(), sub.simulations)
            np.testing.assert_allclose(lines[design].get_ydata(), sub[col])


# --- the plotted data read back from draw() -------------------------------------------------------
# Each test below draws a tiny data file with the figure's draw() and compares what the axes hold
# (lines, bars, error bars, bands, scatter points, histogram bars) with the input's numbers, so a
# dropped series, a wrong column or a rescaled value fails, not only a missing PNG.


def _xy(line):
    return np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)


def _lines_by_label(ax):
    return {line.get_label(): line for line in ax.get_lines()}


def _assert_line(line, x, y):
    lx, ly = _xy(line)
    np.testing.assert_allclose(lx, np.asarray(x, float))
    np.testing.assert_allclose(ly, np.asarray(y, float))


def _assert_band(collection, x, lo, hi):
    """A fill_between(x, lo, hi) polygon: its vertices run along (x, lo), then back along (x, hi)."""
    x, lo, hi = (np.asarray(v, float) for v in (x, lo, hi))
    (path,) = collection.get_paths()
    verts, n = path.vertices, len(x)
    np.testing.assert_allclose(verts[1 : n + 1], np.column_stack([x, lo]))
    np.testing.assert_allclose(verts[n + 2 : 2 * n + 2][::-1], np.column_stack([x, hi]))


def _assert_errorbar(container, x, y, err):
    """An errorbar container: its data line is (x, y) and its bars run from y - err to y + err at x."""
    x, y, err = (np.asarray(v, float) for v in (x, y, err))
    _assert_line(container.lines[0], x, y)
    segments = np.asarray(container.lines[2][0].get_segments(), float)  # (n, 2 ends, xy)
    np.testing.assert_allclose(segments[:, :, 0], np.column_stack([x, x]))
    np.testing.assert_allclose(segments[:, 0, 1], y - err)
    np.testing.assert_allclose(segments[:, 1, 1], y + err)


def _npz(path):
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("name", ["fig12_test_predictions", "fig13_parts_predictions"])
def test_cdf_predictions_plot_the_true_and_predicted_cdfs(name, tmp_path):
    """One panel per row: the simulated CDF and the predicted CDF against yaw_deg."""
    module = importlib.import_module(f"feeder.figures.{name}")
    _predictions(tmp_path / "p.npz")
    data = _npz(tmp_path / "p.npz")
    fig = module.draw(data)
    assert len(fig.axes) == len(data["cdf_true"]) == 4
    for ax, true, pred in zip(fig.axes, data["cdf_true"], data["cdf_pred"], strict=True):
        lines = _lines_by_label(ax)
        _assert_line(lines["simulation"], data["yaw_deg"], true)
        _assert_line(lines["prediction"], data["yaw_deg"], pred)


def test_fig4_plots_the_mean_js_with_sd_bars_against_drops(tmp_path):
    from feeder.figures import fig4_js_vs_drops

    _fig4(tmp_path / "f.csv")
    df = pd.read_csv(tmp_path / "f.csv")
    (bars,) = fig4_js_vs_drops.draw(df).axes[0].containers
    _assert_errorbar(bars, [100, 500, 1000], [0.2, 0.05, 0.0], [0.05, 0.01, 0.0])


def test_fig5_histogram_counts_the_js_values_and_marks_the_noise_floor(tmp_path):
    from feeder.figures import fig5_js_hist

    _fig5(tmp_path / "f.npz")
    data = _npz(tmp_path / "f.npz")
    ax = fig5_js_hist.draw(data).axes[0]
    counts, edges = np.histogram(data["js"], bins=30)
    (bars,) = ax.containers
    np.testing.assert_allclose([b.get_height() for b in bars], counts)
    np.testing.assert_allclose([b.get_x() for b in bars], edges[:-1])
    np.testing.assert_allclose([b.get_width() for b in bars], np.diff(edges))
    assert sum(b.get_height() for b in bars) == 50
    (floor,) = ax.get_lines()
    np.testing.assert_allclose(_xy(floor)[0], [0.03, 0.03])


def test_fig6_plots_each_parts_closed_outline_and_reconstruction(tmp_path):
    from feeder.figures import fig6_dft_reconstruction

    _fig6(tmp_path / "f.npz")
    data = _npz(tmp_path / "f.npz")
    fig = fig6_dft_reconstruction.draw(data)
    assert len(fig.axes) == 2
    for ax, name, z, rec in zip(fig.axes, data["name"], data["outline"], data["reconstruction"], strict=True):
        assert ax.get_title().startswith(str(name))
        outline, reconstruction = ax.get_lines()
        closed = np.append(z, z[0])  # the outline is drawn closed: back to its first sample
        _assert_line(outline, closed.real, closed.imag)
        closed = np.append(rec, rec[0])
        _assert_line(reconstruction, closed.real, closed.imag)


def test_fig9_plots_each_pmf_against_the_bin_centres(tmp_path):
    from feeder.figures import fig9_example_pmfs

    _fig9(tmp_path / "f.npz")
    data = _npz(tmp_path / "f.npz")
    fig = fig9_example_pmfs.draw(data)
    for ax, label, pmf in zip(fig.axes, data["label"], data["pmf"], strict=True):
        assert ax.get_title().endswith(str(label))
        (line,) = ax.get_lines()
        _assert_line(line, data["yaw_deg"], pmf)


def test_convergence_dkw_plots_the_sup_distance_band_and_share_inside(tmp_path):
    """Left: median, 10-90 % band and DKW ε of the partial levels (the full run, N = 1000, left
    out); right: the share inside the band at every level, and the 1 - α line."""
    from feeder.figures import convergence_dkw

    _dkw(tmp_path / "d.npz")
    data = _npz(tmp_path / "d.npz")
    left, right = convergence_dkw.draw(data).axes
    n = [100, 500]
    lines = _lines_by_label(left)
    _assert_line(lines["median"], n, [0.05, 0.02])
    (dkw,) = [line for label, line in lines.items() if label.startswith("DKW")]
    _assert_line(dkw, n, data["dkw_epsilon"][:2])
    (band,) = left.collections
    _assert_band(band, n, [0.02, 0.01], [0.1, 0.04])
    share, level = right.get_lines()
    _assert_line(share, [100, 500, 1000], [0.9, 0.97, 1.0])
    np.testing.assert_allclose(_xy(level)[1], [0.95, 0.95])


def test_fig14_plots_within_and_cross_r2_with_sd_bars_and_the_no_model_line(tmp_path):
    from feeder.figures import fig14_cross_convergence

    _p2(tmp_path / "p.csv")
    df = pd.read_csv(tmp_path / "p.csv")
    ax = fig14_cross_convergence.draw(df).axes[0]
    within, cross = ax.containers
    _assert_errorbar(within, LEVELS, [0.8, 0.9, 0.95], [0.1, 0.05, 0.02])
    _assert_errorbar(cross, LEVELS, [0.6, 0.85, 0.95], [0.2, 0.1, 0.02])
    (baseline,) = [line for line in ax.get_lines() if line.get_label().startswith("level-k CDF itself")]
    _assert_line(baseline, LEVELS, [0.3, 0.8, 1.0])


def test_s11_plots_each_splits_delta_and_baseline_means_with_sd_bands(tmp_path):
    from feeder.figures import s11_delta_sweep

    _table10(tmp_path / "t.csv")
    df = pd.read_csv(tmp_path / "t.csv")
    # make the two splits differ, so a panel drawn from the other split's columns shows
    df.loc[:, df.columns.str.startswith("config_")] *= 0.5
    fig = s11_delta_sweep.draw(df)
    for ax, mode in zip(fig.axes, ("part", "config"), strict=True):
        lines = _lines_by_label(ax)
        bands = ax.collections
        assert len(bands) == 2
        for key, label, band in zip(("r2", "baseline"), ("delta model", "partial PMF as answer"), bands, strict=True):
            mean, sd = df[f"{mode}_{key}_mean"], df[f"{mode}_{key}_sd"]
            _assert_line(lines[label], LEVELS, mean)
            _assert_band(band, LEVELS, mean - sd, mean + sd)


def test_s1_plots_mean_and_median_mse_the_iqr_band_and_the_chosen_count(tmp_path):
    from feeder.figures import s1_dft_mse

    _s1(tmp_path / "s.csv")
    df = pd.read_csv(tmp_path / "s.csv")
    ax = s1_dft_mse.draw(df, 15).axes[0]
    n = np.arange(1, 21)
    mse = 10.0 / n**2
    lines = _lines_by_label(ax)
    _assert_line(lines["mean over parts"], n, mse)
    _assert_line(lines["median"], n, 0.9 * mse)
    np.testing.assert_allclose(_xy(lines["15 coefficients"])[0], [15, 15])
    (band,) = ax.collections
    _assert_band(band, n, mse / 2, 1.5 * mse)


def test_jam_rates_plot_the_mean_ok_rate_per_location_and_each_parts_points(tmp_path):
    from feeder.figures import jam_rates

    _jams(tmp_path / "j.csv")
    df = pd.read_csv(tmp_path / "j.csv")
    fig = jam_rates.draw(df)
    for ax, kind in zip(fig.axes, ("curved", "straight"), strict=True):  # one panel per fence, sorted
        lines = ax.get_lines()
        assert len(lines) == 2 and len(ax.collections) == 2
        for line, points, loc in zip(lines, ax.collections, ("loc1", "loc2"), strict=True):
            at = df[(df.fence == kind) & (df.location == loc)]
            mean = at[at.part == "mean"].sort_values("angle_deg")
            _assert_line(line, mean.angle_deg, mean.ok_rate)
            parts = at[at.part != "mean"]
            np.testing.assert_allclose(points.get_offsets(), parts[["angle_deg", "ok_rate"]].to_numpy())
    straight = _lines_by_label(fig.axes[1])
    _assert_line(straight["Location 1 (mean of 2 parts)"], [30, 65], [0.75, 0.3])
    _assert_line(straight["Location 2 (mean of 2 parts)"], [30, 65], [0.6, 0.24])


def test_cost_by_stage_bars_are_wall_and_cpu_seconds(tmp_path):
    from feeder.figures import cost_by_stage

    _cost(tmp_path / "c.csv")
    df = pd.read_csv(tmp_path / "c.csv")
    ax = cost_by_stage.draw(df).axes[0]
    wall, cpu = ax.containers  # the TOTAL row is left out
    np.testing.assert_allclose([b.get_width() for b in wall], [120.0, 40.0, 9.0])
    np.testing.assert_allclose([b.get_width() for b in cpu], [110.0, 70.0, 8.0])
    for bars in (wall, cpu):
        np.testing.assert_allclose([b.get_y() + b.get_height() / 2 for b in bars], [0, 1, 2])
    assert [t.get_text() for t in ax.get_yticklabels()] == ["simulate (30 jobs)", "train (2 jobs)", "figures (9 jobs)"]


def test_sim_accuracy_vs_time_plots_each_setting_its_pareto_front_and_the_drops_curves(tmp_path):
    """Left/middle: one point per setting at (ms per drop, JS or W1) at the largest drop count,
    blue inside the floor and red outside, the floor band and the Pareto front; right: JS
    against drops of the fast setting and of the reference (the floor)."""
    import matplotlib.colors as mcolors

    from feeder.figures import sim_accuracy_vs_time

    _bench(tmp_path / "b.csv")
    df = pd.read_csv(tmp_path / "b.csv")
    slow = df[df.setting == "coarse"].assign(setting="slow", ms_per_drop=100.0, js=0.5, w1_deg=20.0)
    df = pd.concat([df, slow], ignore_index=True)  # dearer and further than all: off the front
    fig = sim_accuracy_vs_time.draw(df, "faithful")
    points = {
        "faithful": (40.0, 0.02, 1.0),
        "fast": (4.0, 0.03, 1.5),
        "coarse": (1.0, 0.2, 9.0),
        "slow": (100, 0.5, 20),
    }
    colour = {s: "C0" if s == "faithful" else "C3" for s in points}  # only faithful is within its floor
    for ax, col, floor, front in (
        (fig.axes[0], 1, 0.025, [(1.0, 0.2), (4.0, 0.03), (40.0, 0.02)]),
        (fig.axes[1], 2, 1.2, [(1.0, 9.0), (4.0, 1.5), (40.0, 1.0)]),
    ):
        drawn = {tuple(c.get_offsets()[0]): c for c in ax.collections}
        assert sorted(drawn) == sorted((p[0], p[col]) for p in points.values())
        for setting, p in points.items():
            np.testing.assert_allclose(drawn[(p[0], p[col])].get_facecolor()[0], mcolors.to_rgba(colour[setting]))
        (span,) = ax.patches
        np.testing.assert_allclose([span.get_y(), span.get_height()], [0.0, floor])
        _assert_line(_lines_by_label(ax)["Pareto front"], *zip(*front))
    lines = _lines_by_label(fig.axes[2])
    _assert_line(lines["fast vs reference"], [10, 50], [0.15, 0.03])
    _assert_line(lines["noise floor (reference, second seed)"], [10, 50], [0.1, 0.02])


def test_yaw_sampling_plots_each_designs_mean_and_configuration_lines(tmp_path):
    from feeder.figures import yaw_sampling

    _yaws(tmp_path / "y.csv")
    df = pd.read_csv(tmp_path / "y.csv")
    fig = yaw_sampling.draw(df)
    n = np.array([25, 50, 100])
    for ax, scale in zip(fig.axes, (0.5, 30.0), strict=True):  # js, then w1_deg
        lines = ax.get_lines()
        assert len(lines) == 4  # per design: one configuration line, then the mean line
        for (thin, mean), (design, e) in zip((lines[0:2], lines[2:4]), (("random", 0.5), ("golden", 0.8)), strict=True):
            assert mean.get_label() == f"{design} (mean)"
            _assert_line(mean, n, scale / n**e)
            _assert_line(thin, n, 1.5 * scale / n**e)


def test_sim_cost_plots_each_parts_jobs_per_design_and_each_designs_mean(tmp_path):
    """Parts in order of the first design's mean (rect 110 < crescent 1600 ms), each design's jobs
    shifted by ∓0.25 from the part's tick, and one dashed mean per design."""
    from feeder.figures import sim_cost

    _sim_cost(tmp_path / "s.csv")
    df = pd.read_csv(tmp_path / "s.csv")
    ax = sim_cost.draw(df).axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["rect", "crescent"]
    lines = ax.get_lines()
    points = [line for line in lines if line.get_linestyle() == "None"]
    means = [line for line in lines if line.get_linestyle() == "--"]
    expected = [(-0.25, [90.0, 130.0]), (0.75, [1600.0]), (0.25, [80.0, 120.0]), (1.25, [1500.0])]
    assert len(points) == len(expected)
    for line, (x, y) in zip(points, expected, strict=True):
        _assert_line(line, [x] * len(y), y)
    np.testing.assert_allclose([_xy(m)[1] for m in means], [[1820 / 3] * 2, [1700 / 3] * 2])


def test_label_emulation_plots_the_ecdfs_of_real_first_and_pooled_emulated_js(tmp_path):
    """Per N: the ECDF over usable configurations of the real JS, the first emulated realisation's
    and all realisations pooled; an unusable configuration and a NaN are left out, 0 is drawn at 1e-6."""
    from feeder.figures import label_emulation

    rows = []
    for n in (10, 100):
        for i, config in enumerate(("c0", "c1", "c2", "bad")):
            for source, repeats in (("real", 1), ("emulated", 2)):
                for r in range(repeats):
                    js = (i + 1) * (0.01 if source == "real" else 0.02 + 0.005 * r) * 10 / n
                    rows.append(
                        {
                            "config": config,
                            "n_drops": n,
                            "source": source,
                            "repeat": r,
                            "js": js,
                            "usable": config != "bad",
                        }
                    )
    df = pd.DataFrame(rows)
    df.loc[(df.config == "c0") & (df.source == "real") & (df.n_drops == 100), "js"] = 0.0
    df.loc[(df.config == "c1") & (df.repeat == 1) & (df.n_drops == 100), "js"] = np.nan
    fig = label_emulation.draw(df)
    assert len(fig.axes) == 2
    third = np.array([1, 2, 3]) / 3
    expected = {
        10: ([0.01, 0.02, 0.03], [0.02, 0.04, 0.06], [0.02, 0.025, 0.04, 0.05, 0.06, 0.075]),
        100: ([1e-6, 0.002, 0.003], [0.002, 0.004, 0.006], [0.002, 0.0025, 0.004, 0.006, 0.0075]),
    }
    for ax, (n, (real, first, pooled)) in zip(fig.axes, expected.items(), strict=True):
        assert ax.get_title() == f"N = {n}"
        lines = _lines_by_label(ax)
        _assert_line(lines["real (3)"], real, third)
        _assert_line(lines["emulated, first realisation"], first, third)
        _assert_line(lines["emulated, 2 realisations"], pooled, np.arange(1, len(pooled) + 1) / len(pooled))


def test_label_designs_bands_span_each_designs_interval(tmp_path):
    """The shaded band of each design runs from the _lo to the _hi column at its simulations."""
    from feeder.figures import label_designs

    _label_designs(tmp_path / "s.csv")
    df = pd.read_csv(tmp_path / "s.csv")
    fig = label_designs.draw(df)
    for ax, col in zip(fig.axes, ("sup_cdf", "circular_w1_deg"), strict=True):
        bands = ax.collections
        assert len(bands) == 3
        for band, design in zip(bands, ("adaptive", "grid", "random"), strict=True):  # sorted by design
            sub = df[df.design == design].sort_values("simulations")
            _assert_band(band, sub.simulations, sub[f"{col}_lo"], sub[f"{col}_hi"])


def test_contact_model_plots_each_footprints_mean_cost_and_agreement_against_pieces(tmp_path):
    from feeder.figures import contact_model

    _contact(tmp_path / "c.csv")
    cost, agree = contact_model.draw(pd.read_csv(tmp_path / "c.csv")).axes
    lines = _lines_by_label(cost)
    assert list(lines) == ["each convex piece", "16 pads", "32 pads"]  # pieces first, then by pad count
    # mean over the two configurations: base * pieces * (1 + 3) / 2
    _assert_line(lines["each convex piece"], [9, 36], [50 * 9 * 2, 50 * 36 * 2])
    _assert_line(lines["16 pads"], [9, 36], [10 * 9 * 2, 10 * 36 * 2])
    _assert_line(_lines_by_label(agree)["32 pads"], [9, 36], [0.75, 0.75])
    _assert_line(_lines_by_label(agree)["each convex piece"], [9, 36], [0.6, 0.6])
    assert cost.get_yscale() == "log"


def test_contact_decomposition_plots_each_models_distances_beside_its_floor_and_its_cost(tmp_path):
    from feeder.figures import contact_decomposition

    _decomposition(tmp_path / "d.csv")
    paired, label, cost = contact_decomposition.draw(pd.read_csv(tmp_path / "d.csv")).axes
    assert [t.get_text() for t in cost.get_xticklabels()] == ["pieces", "pads8"]  # pieces first
    assert [p.get_height() for p in cost.patches] == [80.0, 95.0]
    assert [t.get_text() for t in cost.texts] == [
        "paired fail (0/2 rows pass)\nlabel pass (2/2 rows pass)",
        "paired pass (2/2 rows pass)\nlabel pass (2/2 rows pass)",
    ]
    filled = sorted(
        float(y)
        for ln in paired.get_lines()
        if ln.get_marker() == "o" and ln.get_markerfacecolor() != "none"
        for y in ln.get_ydata()
    )
    assert filled == [0.1, 0.1, 3.0, 3.0]
    assert paired.get_yscale() == label.get_yscale() == "log"


def test_step_cost_plots_each_worlds_cost_with_its_interval_and_the_fitted_contact_lines(tmp_path):
    from feeder.figures import step_cost

    _step(tmp_path / "s.csv")
    bars, fit = step_cost.draw(pd.read_csv(tmp_path / "s.csv")).axes
    heights = [p.get_height() for p in bars.patches]
    assert heights == pytest.approx([7.0, 30.0, 16.0])  # bare first, then the configurations sorted
    labels = [t.get_text() for t in bars.get_xticklabels()]
    assert labels == ["rect\nbare box", "rect\ncurved:40|curved:60", "rect\nstraight:30|none"]
    (caps,) = [c for c in bars.collections]  # the error bars: low and high of each bar
    segs = [np.asarray(s) for s in caps.get_segments()]
    assert [(s[0][1], s[1][1]) for s in segs] == [(6.0, 9.0), (29.0, 32.0), (15.0, 18.0)]
    (python,) = [ln for ln in bars.lines if ln.get_label() == "with the Python loop"]
    assert list(python.get_ydata()) == pytest.approx([33.0, 17.6])
    lines = _lines_by_label(fit)
    # the fitted line of each configuration: a + b * points from 0 to twice its mean points
    _assert_line(lines["rect curved:40|curved:60"], [0.0, 24.0], [6.0, 54.0])
    _assert_line(lines["rect straight:30|none"], [0.0, 12.0], [4.0, 28.0])
    _assert_line(lines["bare box"], [4.0], [7.0])
