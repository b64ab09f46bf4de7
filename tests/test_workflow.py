"""The smoke workflow end to end in a scratch copy, lint and dry runs, partial reruns, crash-resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from workflow_helpers import (
    ROOT,
    SMOKE_RESULTS,
    SNAKEMAKE,
    merged_config,
    planned_jobs,
    planned_rules,
    scratch_copy,
    snakemake,
)

pytestmark = pytest.mark.slow
# the study and the benchmarks (not part of the default target), at smoke scale
SMOKE = ("all", "bench", "--configfile", "config/smoke.yaml")


def committed_results() -> list[str]:
    """The results and the shipped model the repository commits (git ls-files results models)."""
    proc = subprocess.run(["git", "ls-files", "results", "models"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, f"not a git checkout: {proc.stderr}"
    return proc.stdout.split()


def digests(root: Path, files: list[str]) -> dict[str, str]:
    import hashlib

    return {f: hashlib.sha256((root / f).read_bytes()).hexdigest() for f in files if (root / f).is_file()}


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory) -> Path:
    """The smoke study and its benchmarks in a scratch copy that also holds every committed result,
    as a fresh clone does (their digests before the run: .committed.json)."""
    import shutil

    work = scratch_copy(tmp_path_factory.mktemp("smoke"))
    committed = committed_results()
    for f in committed:
        (work / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, work / f)
    (work / ".committed.json").write_text(json.dumps(digests(work, committed)))
    proc = snakemake(work, *SMOKE)
    assert proc.returncode == 0, proc.stderr[-4000:]
    # the onstart hook ran: no per-job re-scheduling timers in a local run (feeder.workflow)
    assert "job rate limiter switched off" in proc.stderr
    return work


def test_smoke_workflow_builds_every_table_and_figure(smoke_run):
    tables = smoke_run / SMOKE_RESULTS / "tables"
    for name in ["table1", "table4", "table5", "table6", "table7", "table8", "cost_by_stage"]:
        frame = pd.read_csv(tables / f"{name}.csv")
        assert len(frame) > 0, name
    for n in (5, 6, 7, 8):
        frame = pd.read_csv(tables / f"table{n}.csv").set_index("model")
        assert {"m3", "baseline_mean_pmf", "baseline_nearest_part"} <= set(frame.index)
        assert np.isfinite(frame[["r2_mean", "w1_mean", "mse_mean"]].to_numpy()).all()
        assert (frame.loc["m3", "train_s"] > 0) and (frame["w1_mean"] >= 0).all()
    paired = pd.read_csv(tables / "model_vs_baselines.csv")
    assert set(paired.split) == {"test", "fences", "parts"} and set(paired.verdict) <= {
        "better",
        "worse",
        "no clear difference",
    }
    card = json.loads((smoke_run / SMOKE_RESULTS / "shipped" / "m3" / "card.json").read_text())
    assert card["model"] == "m3" and card["seed"] == 0  # the smoke overlay exports beside its results
    cost = pd.read_csv(tables / "cost_by_stage.csv").set_index("stage")
    assert {"simulate", "models", "TOTAL"} <= set(cost.index)
    assert cost.loc["TOTAL", "jobs"] == cost.drop("TOTAL")["jobs"].sum()
    for png in (smoke_run / SMOKE_RESULTS / "figures").glob("*.png"):
        assert png.stat().st_size > 1000, png
    assert not list(smoke_run.rglob("*.tmp")), "a temporary file was left behind"


def test_a_smoke_run_changes_no_committed_file(smoke_run):
    """An overlay writes under its own results folder (config key `results`): the committed results
    of other runs and the shipped model (models/) stay byte for byte as they were."""
    before = json.loads((smoke_run / ".committed.json").read_text())
    assert before, "no committed result was copied in"
    after = digests(smoke_run, list(before))
    changed = sorted(f for f in before if after.get(f) != before[f])
    assert not changed, f"the smoke run rewrote committed files: {changed[:10]}"
    assert (smoke_run / SMOKE_RESULTS / "tables" / "table6.csv").is_file()  # it wrote its own


def test_report_holds_every_table_and_figure_with_its_caption(smoke_run, tmp_path):
    """snakemake --report: every file declared with report() is in the HTML with its caption."""
    html = tmp_path / "report.html"
    proc = snakemake(smoke_run, *SMOKE, "--report", str(html))
    assert proc.returncode == 0, proc.stderr[-3000:]
    text = html.read_text(errors="replace")
    captions = sorted((ROOT / "workflow" / "report").glob("*.rst"))  # none is left unused
    assert len(captions) >= 30
    for rst in captions:
        first = rst.read_text().split()[:4]
        assert " ".join(first) in text, f"caption {rst.name} is not in the report"
    # each figure and CSV table is a file entry of the report (a bare name also occurs in the rules'
    # inputs and outputs, so it would pass for a file left out of the report)
    out = smoke_run / SMOKE_RESULTS
    for path in [*out.glob("figures/*.png"), *out.glob("tables/*.csv")]:
        assert f'"filename": "{path.name}"' in text, f"{path.name} is not in the report"


def test_complete_run_has_nothing_left_to_do(smoke_run):
    assert planned_jobs(smoke_run, *SMOKE) == []


@pytest.mark.parametrize("configfile", [None, "config/smoke.yaml"], ids=["default", "smoke"])
def test_lint_and_dry_run_are_clean(tmp_path, configfile):
    work = scratch_copy(tmp_path / "w")
    extra = ("--configfile", configfile) if configfile else ()
    lint = snakemake(work, "--lint", *extra)
    assert lint.returncode == 0, lint.stdout[-3000:] + lint.stderr[-3000:]
    jobs = planned_jobs(work, *extra)
    assert jobs, "the dry run plans no jobs"
    if configfile is None:  # `make run` on a fresh checkout schedules the study, never a benchmark
        benches = sorted({rule for rule, _ in jobs if rule.startswith("bench")})
        assert not benches, f"the default target schedules benchmarks: {benches}"


def test_crash_midway_then_restart_gives_identical_outputs(smoke_run, tmp_path):
    """Kill the whole run hard while simulations are being written, start again, compare."""
    work = scratch_copy(tmp_path / "crash")
    proc = subprocess.Popen(
        [SNAKEMAKE, "--cores", "2", *SMOKE],
        cwd=work,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    sims = work / SMOKE_RESULTS / "sim"
    deadline = time.time() + 300
    while time.time() < deadline and len(list(sims.rglob("*.npz"))) < 3:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert snakemake(work, "--unlock").returncode == 0
    resumed = snakemake(work, *SMOKE)
    assert resumed.returncode == 0, resumed.stderr[-4000:]
    for ref in sorted((smoke_run / SMOKE_RESULTS / "sim").rglob("*.npz")):
        with np.load(ref) as a, np.load(work / ref.relative_to(smoke_run)) as b:
            for key in ("final_yaw_deg", "initial_yaw_deg", "status"):
                np.testing.assert_array_equal(a[key], b[key], err_msg=f"{ref.name}:{key}")
    with (
        np.load(smoke_run / SMOKE_RESULTS / "datasets/dataset.npz") as a,
        np.load(work / SMOKE_RESULTS / "datasets/dataset.npz") as b,
    ):
        for key in ("pmf", "part_raw", "feeder_raw"):
            np.testing.assert_array_equal(a[key], b[key])


# --- partial reruns: what a dry run plans after one edit in the finished smoke workspace ---------

# the bench target is planned only when a benchmark reruns; the cost table is the record of a whole
# run, built after every other result but not re-summed after a partial rerun (its inputs are
# ancient: `-f results/smoke/tables/cost_by_stage.csv` re-sums), so a clone's redraw of one figure
# does not send it back to the simulations (tests/test_fresh_clone.py); a changed setting of the
# Snakemake config rewrites results/run_config.json, and so the record
ALWAYS = {"all"}


@pytest.fixture
def edit(smoke_run):
    """Edit a file of the finished smoke workspace for one test, then put it back byte for byte."""
    saved: dict[Path, tuple[bytes, int]] = {}

    def apply(relpath: str, old: str, new: str) -> None:
        path = smoke_run / relpath
        text = path.read_text()
        assert old in text, f"{old!r} not in {relpath}"
        saved.setdefault(path, (path.read_bytes(), path.stat().st_mtime_ns))
        path.write_text(text.replace(old, new, 1))

    yield apply
    for path, (data, mtime) in saved.items():
        path.write_bytes(data)
        os.utime(path, ns=(mtime, mtime))


def _sim_outputs(config: dict) -> set[str]:
    from feeder.labels.grid import configurations
    from feeder.parts.library import list_parts

    parts = list_parts(str(ROOT / config["parts"]["dir"]), config["parts"]["include"])
    table = configurations(config, parts)
    return {f"{config['results']}/sim/{p}/{c}.npz" for p, c in zip(table["part"], table["config_id"])}


def test_editing_one_fence_angle_reruns_only_the_simulations_that_use_it(smoke_run, tmp_path):
    before = merged_config(smoke_run, "config/smoke.yaml")
    angles = before["fences"]["straight_angles"]
    used = {a for p in _sim_outputs(before) for a in angles if f"straight{a:g}" in p}
    old = sorted(used)[0]
    new = old + 1 if old + 1 not in angles else old - 1
    override = tmp_path / "edited.yaml"
    override.write_text(yaml.safe_dump({"fences": {"straight_angles": [new if a == old else a for a in angles]}}))
    after = merged_config(smoke_run, "config/smoke.yaml", str(override))

    jobs = planned_jobs(smoke_run, *SMOKE, str(override))
    planned_sims = {out for rule, out in jobs if rule == "simulate"}
    assert planned_sims == _sim_outputs(after) - _sim_outputs(before)
    assert planned_sims and all(f"straight{new:g}" in out for out in planned_sims)
    rules = {rule for rule, _ in jobs}
    assert not rules & {"part_features", "scene_table", "bench_sim", "parts_s1"}
    assert {"datasets_build", "train_model", "evaluate_models"} <= rules  # and what depends on them
    assert "bench_cost" in rules  # the jobs it projects changed
    # a changed setting is the run's record too, in the same pass as the jobs upstream of it (whose
    # inputs are ancient, so Snakemake would not look at its params: it took a second run)
    assert {"run_config", "cost_by_stage", "draw_cost_by_stage"} <= rules


def test_switching_the_yaw_design_reruns_every_simulation_and_no_benchmark(smoke_run, tmp_path):
    """The benchmarks take only the settings they read: sim.yaw_sampling is one only for the cost
    projection, which runs the study's own jobs."""
    before = merged_config(smoke_run, "config/smoke.yaml")
    override = tmp_path / "golden.yaml"
    override.write_text(yaml.safe_dump({"sim": {"yaw_sampling": "golden"}}))
    jobs = planned_jobs(smoke_run, *SMOKE, str(override))
    assert {out for rule, out in jobs if rule == "simulate"} == _sim_outputs(before)
    rules = {rule for rule, _ in jobs}
    assert not rules & {"bench_sim", "bench_yaws", "bench_jams", "scene_table", "part_features"}
    assert {"datasets_build", "train_model", "bench_cost"} <= rules


def _models_built_on(name: str) -> set[str]:
    """The model configs that inherit ``name``'s settings: whose Hydra defaults list it, or list a
    config that does (m3prior builds on m3pushonly, which builds on m3)."""
    parents = {
        path.stem: set(yaml.safe_load(path.read_text()).get("defaults") or [])
        for path in (ROOT / "config/hydra/model").glob("*.yaml")
    }
    built_on, frontier = set(), {name}
    while frontier:
        frontier = {m for m, p in parents.items() if p & frontier} - built_on
        built_on |= frontier
    return built_on


MODEL_JOB_RULES = {
    "train_model",
    "evaluate_models",
    "groupkfold_model",
    "generalisation",
    "generalisation_by_set",
    "prediction_figure_data",
    "draw_fig12_test_predictions",
    "draw_fig13_parts_predictions",
    "export_model",  # the shipped Model 3 (seed 0) and its card
    "bench_frontier",  # the frontier scores the shipped models (make bench) ...
    "draw_frontier",  # ... and its figure
    "bench_frontier_known",  # so does the known-part frontier ...
    "draw_frontier_known",  # ... and its figure
    "bench",  # the bench target, whose frontier moved
}


def test_editing_one_model_config_reruns_that_model_and_the_models_built_on_it(smoke_run, edit):
    """m3push inherits m3's settings (Hydra defaults), so a change to m3.yaml retrains both, and
    no other model."""
    assert "m3push" in _models_built_on("m3")
    edit("config/hydra/model/m3.yaml", "lr: 0.0004", "lr: 0.0005")
    jobs = planned_jobs(smoke_run, *SMOKE)
    trained = {out for rule, out in jobs if rule == "train_model"}
    models = merged_config(smoke_run, "config/smoke.yaml")["models"]
    smoke_models = {*models["regression"], *models["groupkfold"]}
    expected = {"m3"} | (_models_built_on("m3") & smoke_models)
    assert trained == {
        f"{SMOKE_RESULTS}/models/{m}/seed{seed}/model.pt" for m in expected for seed in (0, 1, 2)
    }  # every seed of m3 and of what inherits it, no other model
    rules = {rule for rule, _ in jobs}
    assert rules <= MODEL_JOB_RULES | ALWAYS
    assert "evaluate_models" in rules


def test_editing_a_derived_model_config_leaves_its_base_alone(smoke_run, edit):
    edit("config/hydra/model/m3push.yaml", "name: m3push", "name: m3push\nlr: 0.0003")
    jobs = planned_jobs(smoke_run, *SMOKE)
    trained = {out for rule, out in jobs if rule == "train_model"}
    assert trained == {f"{SMOKE_RESULTS}/models/m3push/seed{seed}/model.pt" for seed in (0, 1, 2)}
    assert {rule for rule, _ in jobs} <= MODEL_JOB_RULES | ALWAYS


def test_editing_one_figure_style_reruns_only_that_figure(smoke_run, edit):
    edit("src/feeder/figures/fig14_cross_convergence.py", "capsize=3", "capsize=5")
    assert planned_rules(smoke_run, *SMOKE) == {"draw_fig14_cross_convergence"} | ALWAYS
