"""feeder.figures: every figure drawn from a tiny synthetic data file, the dispatcher, the data
readers' one-line errors, and the workflow property the split exists for (a figure module is an
input of its own drawing job only)."""

from __future__ import annotations

import ast
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
    rows = [
        {"fence": f, "angle_deg": a, "location": loc, "part": p, "ok_rate": r}
        for f, a, r in (("straight", 30.0, 1.0), ("straight", 65.0, 0.4), ("curved", 60.0, 0.2))
        for loc in ("loc1", "loc2")
        for p in ("a", "b", "mean")
    ]
    pd.DataFrame(rows).to_csv(path, index=False)


def _yaws(path):
    rows = [
        {
            "design": d,
            "drops": n,
            "config": c,
            "js": 0.5 / n**e,
            "w1_deg": 30.0 / n**e,
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


CASES = {
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
    targets = ("results/figures/s1_dft_mse.png", "results/figures/fig6_dft_reconstruction.png")
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
