"""Every job's code inputs hold the feeder modules its command really loads.

The rules derive their code inputs from the commands' imports (``code()`` in common.smk,
:func:`feeder.workflow.code_inputs`). This test checks them independently: it imports each job's
command module in a fresh interpreter, as the job would, and reads which ``feeder`` modules were
loaded. A rule whose inputs miss one of them would not rerun after an edit there.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from workflow_helpers import ROOT, snakemake

_RULE = re.compile(r"^(?:local)?rule (\w+):$")


def dry_run_jobs(*args: str) -> list[dict]:
    """rule, inputs and shell command of every job of a forced dry run."""
    proc = snakemake(ROOT, "-n", "-p", "--forceall", *args, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs: list[dict] = []
    for line in proc.stdout.splitlines():
        if m := _RULE.match(line.strip()):
            jobs.append({"rule": m.group(1), "input": set(), "shell": ""})
        elif jobs and line.startswith("    input: "):
            jobs[-1]["input"] = set(line.removeprefix("    input: ").split(", "))
        elif jobs and line.startswith("Shell command: "):
            jobs[-1]["shell"] = line.removeprefix("Shell command: ")
    return jobs


def loaded_modules(command: str, *args: str) -> set[str]:
    """Source files of the feeder modules loaded by importing the command's module(s)."""
    figure = f"import feeder.figures.{args[0]}\n" if command == "figure" else ""
    code = (
        "import importlib, json, sys\nfrom feeder.cli import COMMANDS\n"
        f"importlib.import_module(COMMANDS[{command!r}][0])\n{figure}"
        "print(json.dumps(sorted(m.__file__ for n, m in sys.modules.items()"
        " if n.split('.')[0] == 'feeder' and getattr(m, '__file__', None))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    return {Path(f).resolve().relative_to(ROOT).as_posix() for f in json.loads(out.stdout)}


def missing_code(job: dict) -> set[str]:
    argv = shlex.split(job["shell"])
    command, rest = argv[1], [a for a in argv[2:] if not a.startswith("-")][:1]
    return loaded_modules(command, *rest) - job["input"]


# rules in neither `all` nor `bench` (they need the trained model)
EXTRA_TARGETS = ("results/smoke/tables/predict_speed.csv",)  # config/smoke.yaml's results folder


@pytest.fixture(scope="module")
def smoke_jobs():
    jobs = dry_run_jobs("all", "bench", *EXTRA_TARGETS, "--configfile", "config/smoke.yaml")
    by_command: dict[tuple, dict] = {}  # one job per rule and command (simulate x 20 is one)
    for job in jobs:
        if job["shell"].startswith("feeder "):
            argv = shlex.split(job["shell"])
            by_command.setdefault((job["rule"], argv[1], argv[2]), job)
    return by_command


def test_every_rule_runs_one_feeder_command(smoke_jobs):
    proc = snakemake(ROOT, "--list-rules", "all", "bench", "--configfile", "config/smoke.yaml")
    # one line a rule, "name (docstring...)"; a long docstring wraps onto lines of its own
    rules = {m.group(1) for line in proc.stdout.splitlines() if (m := re.match(r"([a-z]\w*)(?: \(|$)", line))}
    rules -= {"all", "bench"}
    assert rules == {job["rule"] for job in smoke_jobs.values()}


def test_every_job_declares_the_modules_its_command_loads(smoke_jobs):
    assert len(smoke_jobs) >= 30
    gaps = {job["rule"]: sorted(missing_code(job)) for job in smoke_jobs.values()}
    assert {rule: files for rule, files in gaps.items() if files} == {}


def test_a_job_missing_a_module_is_caught(smoke_jobs):
    """The check itself sees a gap: drop one imported module from a job's declared inputs."""
    job = dict(next(j for key, j in smoke_jobs.items() if key[0] == "simulate"))
    job["input"] = job["input"] - {"src/feeder/sim/scene.py"}
    assert missing_code(job) == {"src/feeder/sim/scene.py"}
