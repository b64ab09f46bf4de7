"""The user-facing commands work from any folder: the project is found from the package, the
working directory or ``$FEEDER_PROJECT`` (issue 36, item 1)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from feeder import config as C
from feeder.errors import FeederError
from feeder.learn.export import MODEL_DIR_ENV

ROOT = Path(__file__).resolve().parents[1]
PART = ROOT / "parts" / "rect-a2.stl"
needs_library = pytest.mark.skipif(not PART.is_file(), reason="no part library in parts/")
SIM_DROPS = "2"  # the fewest drops that still make a simulation file


def run_in(folder: Path, *args: str, **env_extra: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in {MODEL_DIR_ENV, C.PROJECT_ENV}}
    env.update(env_extra)
    return subprocess.run(
        [sys.executable, "-m", "feeder", *args], cwd=folder, capture_output=True, text=True, env=env, timeout=300
    )


@needs_library
def test_predict_recommend_and_simulate_run_outside_the_project(tmp_path):
    assert not (tmp_path / C.STUDY_CONFIG).exists()
    fences = ["--loc1", "straight:30", "--loc2", "none"]
    for model in ([], ["--model", "models/m3prior"]):  # the shipped model; a push model, as the README names it
        proc = run_in(tmp_path, "predict", *model, "--part", str(PART), *fences, "--out", "pmf.csv")
        assert proc.returncode == 0, proc.stderr
        assert len(pd.read_csv(tmp_path / "pmf.csv")) == 360
    proc = run_in(tmp_path, "recommend", "--part", str(PART), "--target", "0", "--tolerance", "10", "--top", "2")
    assert proc.returncode == 0, proc.stderr
    assert "configurations:" in proc.stdout
    proc = run_in(tmp_path, "simulate", "--part", str(PART), *fences, "--drops", SIM_DROPS, "--out", "sim.npz")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "sim.npz").is_file()


def test_a_project_that_does_not_exist_is_a_one_line_error(tmp_path):
    proc = run_in(
        tmp_path,
        "recommend",
        "--features",
        "x.json",
        "--target",
        "0",
        "--tolerance",
        "10",
        **{C.PROJECT_ENV: str(tmp_path / "nowhere")},
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert C.PROJECT_ENV in proc.stderr and "Traceback" not in proc.stderr


def make_project(root: Path) -> Path:
    (root / C.STUDY_CONFIG).parent.mkdir(parents=True)
    (root / C.STUDY_CONFIG).write_text("labels: {bins: 360}\n")
    return root


def test_study_root_is_found_as_git_finds_its_repository(tmp_path, monkeypatch):
    monkeypatch.delenv(C.PROJECT_ENV, raising=False)
    project = make_project(tmp_path / "study")
    deep = project / "results" / "tables"
    deep.mkdir(parents=True)
    assert C.study_root(deep) == project.resolve()  # a folder inside the project
    assert C.study_root(tmp_path) == ROOT  # outside any project: the package's own
    other = make_project(tmp_path / "other")
    monkeypatch.setenv(C.PROJECT_ENV, str(other))
    assert C.study_root(deep) == other.resolve()  # the environment variable overrides
    assert C.load_study_config(root=C.study_root())["labels"] == {"bins": 360}
    monkeypatch.setenv(C.PROJECT_ENV, str(tmp_path / "missing"))
    with pytest.raises(FeederError, match=C.PROJECT_ENV):
        C.study_root()


def test_project_path_prefers_the_working_directory_then_the_project(tmp_path, monkeypatch):
    monkeypatch.delenv(C.PROJECT_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    assert C.project_path("models/m3") == ROOT / "models" / "m3"  # not here: the project's
    (tmp_path / "models" / "m3").mkdir(parents=True)
    assert C.project_path("models/m3") == Path("models/m3")  # here: as given
    assert C.project_path("no/such/dir") == Path("no/such/dir")  # nowhere: as given, for the error
