"""A fresh clone redraws one figure or one table from the committed data alone, in seconds.

Git writes src/ after results/, so in a clone every committed result looks older than its code and
Snakemake planned the whole study for one figure (629 jobs for Fig. 9, 44 for label_designs). This
test clones the repository's HEAD, leaves every committed result older than the code (the worst
checkout order), checks that this is the problem, applies `make fresh` (python -m feeder.fresh)
and asks Snakemake for figures and tables: nothing to do until something is forced or edited, and
then only the job itself, not the simulations behind it (which a clone does not have). And every
committed figure is drawn from one committed data file, but the figures listed in AWAITING_DATA.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from workflow_helpers import ROOT, planned_jobs, snakemake

pytestmark = pytest.mark.slow

# figures whose data is committed (a table, or results/figdata/), and a committed table whose raw
# inputs are committed too (results/bench/designs/)
FIGURES = ("results/figures/label_designs.png", "results/figures/fig6_dft_reconstruction.png")
TABLE = "results/tables/label_designs_summary.csv"
# the cost of the whole run, built after every table and figure
COST = ("results/tables/cost_by_stage.csv", "results/figures/cost_by_stage.png")
COST_FIGURE = "cost_by_stage"
# figures whose data file is made only by a full run and not yet committed (from the dataset and the
# models, which a clone does not have): none since the run of 083830f committed theirs
AWAITING_DATA: set[str] = set()
# committed results built from simulations that no clone has
FROM_SIMULATIONS = ("results/figures/fig9_example_pmfs.png", "results/tables/table5.csv", "results/tables/table4.csv")


def git(repo: Path, *args: str) -> str:
    proc = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True)
    assert proc.returncode == 0, f"git {' '.join(args)}: {proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def clone(tmp_path_factory) -> Path:
    """HEAD cloned, its committed results an hour older than everything else (as when git writes
    results/ first), with the clone's own package on the path of every job."""
    dest = tmp_path_factory.mktemp("fresh") / "clone"
    proc = subprocess.run(["git", "clone", "--quiet", str(ROOT), str(dest)], capture_output=True, text=True)
    assert proc.returncode == 0, f"cannot clone {ROOT}: {proc.stderr}"
    old = time.time() - 3600
    for f in git(dest, "ls-files", "-z", "results", "models").split("\0"):
        if f:
            os.utime(dest / f, (old, old))
    saved = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = str(dest / "src")
    yield dest
    if saved is None:
        os.environ.pop("PYTHONPATH")
    else:
        os.environ["PYTHONPATH"] = saved


def mark_current(clone: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "feeder.fresh"], cwd=clone, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "committed results under results, models marked current" in proc.stdout


def test_a_clone_redraws_a_figure_and_rebuilds_a_table_alone(clone):
    # without the step: the committed figure looks older than its code and its table's code
    before = planned_jobs(clone, FIGURES[0])
    assert len(before) > 2 and ("bench_designs", TABLE.replace("_summary", "")) in before, before

    mark_current(clone)
    # current: nothing to do, even where the inputs (the simulations) are not in the clone
    assert planned_jobs(clone, *FIGURES, TABLE, *FROM_SIMULATIONS) == []
    # forced: the drawing jobs only, from the committed data
    assert sorted(planned_jobs(clone, "--force", *FIGURES)) == sorted((f"draw_{Path(f).stem}", f) for f in FIGURES)

    stamp = {f: (clone / f).stat().st_mtime for f in FIGURES}
    start = time.monotonic()
    proc = snakemake(clone, "--force", *FIGURES, timeout=300)
    seconds = time.monotonic() - start
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert seconds < 120, f"redrawing two figures took {seconds:.0f} s"
    for f in FIGURES:
        assert (clone / f).stat().st_mtime > stamp[f], f"{f} not redrawn"
        assert (clone / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f
    changed = {line[3:] for line in git(clone, "status", "--porcelain").splitlines()}
    assert changed <= set(FIGURES), f"a redraw wrote more than its figure: {sorted(changed - set(FIGURES))}"

    # a table from its committed inputs: its own job, then its figure is the only thing out of date
    assert planned_jobs(clone, "--force", TABLE) == [("bench_designs", TABLE.replace("_summary", ""))]
    proc = snakemake(clone, "--force", TABLE, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # nor did the redraw of Fig. 6 outdate the record of the whole run (cost_by_stage, which is
    # built after every figure and would need the simulations again)
    assert planned_jobs(clone, *FIGURES, *FROM_SIMULATIONS, *COST) == [("draw_label_designs", FIGURES[0])]


def drawing_inputs(clone: Path, *args: str) -> dict[str, list[str]]:
    """The inputs of every drawing job (draw_<figure>) of a dry run, by figure."""
    proc = snakemake(clone, "-n", *args, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    found, rule = {}, None
    for line in proc.stdout.splitlines():
        if line.strip().startswith(("rule ", "localrule ")):
            rule = line.strip().split()[1].rstrip(":")
        elif rule and rule.startswith("draw_") and line.startswith("    input: "):
            found[rule.removeprefix("draw_")] = line.removeprefix("    input: ").split(", ")
    return found


def test_every_figure_draws_from_one_committed_data_file(clone):
    mark_current(clone)
    listed = snakemake(clone, "--list-rules", timeout=300).stdout.split()
    drawn = {r.removeprefix("draw_") for r in listed if r.startswith("draw_")}
    committed = set(git(clone, "ls-files", "results").split())
    pngs = {Path(f).stem for f in committed if f.startswith("results/figures/") and f.endswith(".png")}
    # every committed figure of the study is drawn by the workflow, but the rigid contact's bench,
    # drawn by hand from its committed table (config/rigid.yaml)
    assert pngs - drawn == {"sim_accuracy_vs_time_rigid"}
    figures = sorted(drawn & pngs)
    assert len(figures) >= 19, figures
    # the cost figure alone: its table comes after every study result (order only), and forced together
    # with a study figure Snakemake leaves its drawing out of the plan
    inputs = drawing_inputs(clone, "--force", *[f"results/figures/{f}.png" for f in figures if f != COST_FIGURE])
    inputs |= drawing_inputs(clone, "--force", f"results/figures/{COST_FIGURE}.png")
    assert sorted(inputs) == figures
    data = {f: [i for i in files if not i.startswith("src/")] for f, files in inputs.items()}
    assert all(len(d) == 1 for d in data.values()), data  # one data file each, besides the code
    missing = {f for f, (d,) in data.items() if d not in committed}
    assert missing == AWAITING_DATA, (
        f"figure data not committed: {sorted(missing - AWAITING_DATA)}; "
        f"committed now, so drop from AWAITING_DATA: {sorted(AWAITING_DATA - missing)}"
    )
