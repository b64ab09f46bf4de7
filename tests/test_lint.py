"""The code style checks of ``make lint``, so that a style failure fails ``make test`` too.

ruff (lint and format, configured in pyproject.toml [tool.ruff]) over the package and the tests,
snakefmt ([tool.snakefmt]) over the workflow. ``snakemake --lint`` is in tests/test_workflow.py.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent  # the venv's executables, next to its python

CHECKS = {
    "ruff check": ["ruff", "check", "src", "tests"],
    "ruff format": ["ruff", "format", "--check", "src", "tests"],
    "snakefmt": ["snakefmt", "--check", "--compact-diff", "Snakefile", "workflow"],  # the diff names the files
}


@pytest.mark.parametrize("name", list(CHECKS))
def test_code_style_is_clean(name):
    exe, *args = CHECKS[name]
    proc = subprocess.run([str(BIN / exe), *args], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{' '.join(CHECKS[name])} failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}"
