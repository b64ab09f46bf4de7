"""feeder.fresh: a clone's committed results marked current (unit tests on a small git repository;
the workflow in a real clone: tests/test_fresh_clone.py)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
import yaml

from feeder import fresh
from feeder.errors import FeederError

ROOT = Path(__file__).resolve().parents[1]


def git(repo: Path, *args: str) -> None:
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args], cwd=repo, check=True)


def write(repo: Path, path: str, text: str, mtime: float) -> Path:
    f = repo / path
    f.parent.mkdir(parents=True, exist_ok=True)
    f.write_text(text)
    os.utime(f, (mtime, mtime))
    return f


@pytest.fixture
def repo(tmp_path) -> Path:
    """A checkout as git leaves it: committed results older than the code they were made from."""
    git(tmp_path, "init", "-q")
    write(tmp_path, "results/tables/t.csv", "a\n1\n", 1_000)
    write(tmp_path, "results/figures/t.png", "png", 1_000)
    write(tmp_path, "results/tables/edited.csv", "a\n1\n", 1_000)
    write(tmp_path, "models/m3/model.pt", "weights", 1_100)
    write(tmp_path, "src/feeder/stage.py", "x = 1\n", 2_000)
    write(tmp_path, "config/config.yaml", "results: results\n", 1_900)
    git(tmp_path, "add", ".")
    git(tmp_path, "commit", "-q", "-m", "study")
    write(tmp_path, "results/tables/edited.csv", "a\n2\n", 1_500)  # a local edit of a committed table
    write(tmp_path, "results/sim/p/c.npz", "not committed", 1_200)  # an untracked intermediate
    return tmp_path


def mtime(repo: Path, path: str) -> float:
    return os.lstat(repo / path).st_mtime


def test_committed_results_get_the_newest_time_of_the_checkout(repo):
    marked, stamp = fresh.mark_current(repo)
    assert stamp == 2_000  # src/feeder/stage.py, the newest file as committed
    assert sorted(marked) == ["models/m3/model.pt", "results/figures/t.png", "results/tables/t.csv"]
    for path in marked + ["results", "results/tables", "results/figures", "models", "models/m3"]:
        assert mtime(repo, path) == stamp, path


def test_edited_untracked_and_source_files_keep_their_times(repo):
    fresh.mark_current(repo)
    assert mtime(repo, "results/tables/edited.csv") == 1_500  # differs from HEAD: its edit stays newer
    assert mtime(repo, "results/sim/p/c.npz") == 1_200  # not committed: not declared current
    assert mtime(repo, "results/sim/p") != 2_000  # nor its folder
    assert mtime(repo, "src/feeder/stage.py") == 2_000
    assert mtime(repo, "config/config.yaml") == 1_900


def test_a_later_edit_is_newer_than_the_marked_results(repo):
    _, stamp = fresh.mark_current(repo)
    f = write(repo, "src/feeder/stage.py", "x = 2\n", stamp + 10)  # edited after marking
    assert f.stat().st_mtime > mtime(repo, "results/tables/t.csv")
    # marking again does not hide the edit: the edited file is not as committed
    _, again = fresh.mark_current(repo)
    assert again == stamp and mtime(repo, "results/tables/t.csv") < f.stat().st_mtime


def test_not_a_checkout_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "results").mkdir()
    with pytest.raises(FeederError, match="not a git checkout"):
        fresh.mark_current(tmp_path)
    assert fresh.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1


def test_main_reports_what_it_marked(repo, capsys):
    assert fresh.main([str(repo)]) == 0
    assert capsys.readouterr().out.startswith("3 committed results under results, models marked current")


def test_the_folders_are_where_the_default_study_writes():
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    assert set(fresh.COMMITTED_OUTPUTS) == {config["results"], config["models"]["export_dir"]}


def test_code_committed_after_the_results_is_said(repo, capsys):
    assert fresh.code_after_results(repo) == ""  # results and code in one commit
    git(repo, "commit", "-q", "--allow-empty", "-m", "nothing")
    assert fresh.code_after_results(repo) == ""  # a commit that touches no code
    write(repo, "src/feeder/stage.py", "x = 3\n", 3_000)
    git(repo, "add", "src/feeder/stage.py")
    git(repo, "commit", "-q", "-m", "change the stage", "--date=@3000")
    # the committer time of the second commit is now, after the results' commit: said
    assert fresh.code_after_results(repo).endswith("change the stage")
    assert fresh.main([str(repo)]) == 0
    assert "code was committed after the newest committed results" in capsys.readouterr().err


def test_a_checkout_marked_from_a_subfolder_keeps_its_edits(repo):
    """The study in a subfolder of a larger checkout: the local edit is still seen (paths relative)."""
    outer = repo.parent / "outer"
    (outer / "study").mkdir(parents=True)
    for p in ("results/tables/t.csv", "results/tables/edited.csv", "src/feeder/stage.py"):
        write(outer / "study", p, "a\n1\n", 1_000)
    git(outer, "init", "-q")
    git(outer, "add", ".")
    git(outer, "commit", "-q", "-m", "study")
    write(outer / "study", "results/tables/edited.csv", "a\n2\n", 500)
    marked, _ = fresh.mark_current(outer / "study")
    assert "results/tables/edited.csv" not in marked and "results/tables/t.csv" in marked
    assert mtime(outer / "study", "results/tables/edited.csv") == 500


def test_a_checkout_without_a_commit_is_a_one_line_error(tmp_path):
    git(tmp_path, "init", "-q")
    write(tmp_path, "results/t.csv", "a\n", 1_000)
    with pytest.raises(FeederError, match="not a git checkout with a commit") as err:
        fresh.mark_current(tmp_path)
    assert "[" not in str(err.value)
