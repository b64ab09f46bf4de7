"""Run the Snakemake workflow in a scratch copy of the repository and read its job lists."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
SMOKE_RESULTS = "results/smoke"  # config/smoke.yaml's results folder (config key `results`)


def scratch_copy(dest: Path) -> Path:
    from feeder.workflow import copy_study

    return copy_study(ROOT, dest)


def snakemake(work: Path, *args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run([SNAKEMAKE, "--cores", "2", *args], cwd=work, capture_output=True, text=True, timeout=timeout)


_RULE = re.compile(r"^(?:local)?rule (\w+):$")
_OUTPUT = re.compile(r"^\s+output: (.*)$")


def planned_jobs(work: Path, *args: str) -> list[tuple[str, str]]:
    """(rule, first output) of every job a dry run would execute."""
    proc = snakemake(work, "-n", *args)
    if proc.returncode != 0:
        raise AssertionError(f"dry run failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    jobs, rule = [], None
    for line in proc.stdout.splitlines():
        if m := _RULE.match(line.strip()):
            rule = m.group(1)
            jobs.append([rule, ""])
        elif (m := _OUTPUT.match(line)) and jobs and not jobs[-1][1]:
            jobs[-1][1] = m.group(1).split(", ")[0]
    return [tuple(j) for j in jobs]


def planned_rules(work: Path, *args: str) -> set[str]:
    return {rule for rule, _ in planned_jobs(work, *args)}


def merged_config(root: Path, *files: str) -> dict:
    """config/config.yaml overlaid by ``files`` the way Snakemake merges ``--configfile``."""
    from feeder.config import load_study_config

    return load_study_config(*files, root=root)
