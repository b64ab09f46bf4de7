"""Mark a clone's committed results current, so Snakemake reruns only what their inputs need.

Git writes a checkout's files in index order, not in the order the workflow made them: in a fresh
clone ``src/`` is written after ``results/``, so every committed table and figure looks older than
its code, and Snakemake plans the whole study (all simulations) to redraw one figure.

:func:`mark_current` gives every committed result (the tracked files under ``results/`` and
``models/`` whose content is as committed, and their folders) one modification time: the newest
of the checkout's unmodified tracked files. A committed output is then as new as its code, its
configuration and its committed inputs, so Snakemake reruns nothing for it; whatever is edited
afterwards (code, config, a committed table) is newer and reruns what depends on it, as usual. A
file that differs from ``HEAD`` keeps its time, so a local edit is never hidden. A commit is
trusted: results committed at ``HEAD`` count as current for ``HEAD``'s code. When code, config or
rules were committed after the newest committed result, the command says so (a result may then be
stale: force it).

Files that are not committed (``results/sim/``, the dataset, the trained models) are left alone:
Snakemake builds a missing intermediate only when a job that needs it runs, so a committed table
whose inputs are not committed (a table built from the simulations) is not rebuilt when only its
figure is asked for. Snakemake's other rerun triggers (params, code, the set of inputs) compare
with its own records in ``.snakemake/``, which a clone does not have; they count from a job's
first run in the clone.

Run it once after cloning or pulling: ``make fresh`` (``python -m feeder.fresh``).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path, PurePosixPath

from feeder.errors import FeederError

# Where the workflow writes what the repository commits: the study's results folder (config key
# `results`, overlays below it) and the shipped models (models.export_dir); tests/test_fresh.py
# checks these against config/config.yaml.
COMMITTED_OUTPUTS = ("results", "models")
# what a result depends on besides its committed inputs: the code, the settings and the rules
CODE_PATHS = ("src", "config", "workflow", "Snakefile")


def _git_paths(root: Path, *args: str) -> list[str]:
    """Paths (relative to ``root``) that ``git ARGS -z`` lists."""
    try:
        proc = subprocess.run(["git", *args, "-z"], cwd=root, capture_output=True, text=True)
    except FileNotFoundError as exc:
        raise FeederError("git not found on PATH: marking committed results needs a git checkout") from exc
    if proc.returncode != 0:
        said = (proc.stderr.strip().splitlines() or ["no commit"])[-1]
        raise FeederError(f"{root}: not a git checkout with a commit ({said})")
    return [p for p in proc.stdout.split("\0") if p]


def _git_out(root: Path, *args: str) -> str:
    """What ``git ARGS`` prints ('' when it fails)."""
    proc = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True)
    return proc.stdout.strip() if proc.returncode == 0 else ""


def code_after_results(root: str | os.PathLike = ".", folders=COMMITTED_OUTPUTS) -> str:
    """The newest commit (``hash summary``) that changed the code, config or workflow after the
    newest commit of the committed results, '' when there is none: the results trusted by
    :func:`mark_current` may then be stale for that code (a refactor that changes no output also
    counts). Commits are ordered by history, not by time."""
    root = Path(root)
    results = _git_out(root, "log", "-1", "--format=%H", "--", *folders)
    if not results:
        return ""
    return _git_out(root, "log", "-1", "--format=%h %s", f"{results}..HEAD", "--", *CODE_PATHS)


def clean_tracked(root: str | os.PathLike = ".") -> list[str]:
    """The tracked files of the checkout at ``root`` whose working copy is as committed in ``HEAD``."""
    root = Path(root)
    _git_paths(root, "rev-parse", "--verify", "--quiet", "HEAD")  # a checkout with a commit, or a one-line error
    changed = set(_git_paths(root, "diff", "--name-only", "--relative", "HEAD"))  # paths as ls-files gives them
    return [p for p in _git_paths(root, "ls-files") if p not in changed and os.path.lexists(root / p)]


def in_folders(path: str, folders=COMMITTED_OUTPUTS) -> bool:
    """Whether the relative POSIX ``path`` lies below one of ``folders``."""
    return any(PurePosixPath(path).is_relative_to(f) for f in folders)


def mark_current(root: str | os.PathLike = ".", folders=COMMITTED_OUTPUTS) -> tuple[list[str], float]:
    """Give the committed outputs under ``folders`` (and their folders) the modification time of the
    newest unmodified tracked file of the checkout at ``root``. Returns the files marked and the
    time (seconds since the epoch)."""
    root = Path(root)
    clean = clean_tracked(root)
    if not clean:
        raise FeederError(f"{root}: no tracked file as committed")
    stamp = max((root / p).lstat().st_mtime for p in clean)
    marked = [p for p in clean if in_folders(p, folders) and not (root / p).is_symlink()]
    dirs = {str(d) for p in marked for d in PurePosixPath(p).parents if in_folders(str(d), folders)}
    for p in [*marked, *sorted(dirs)]:
        os.utime(root / p, (stamp, stamp), follow_symlinks=False)
    return marked, stamp


def main(argv: list[str] | None = None) -> int:
    """``python -m feeder.fresh [ROOT]``: mark the committed results of the checkout at ROOT current."""
    import argparse
    import time

    parser = argparse.ArgumentParser(prog="python -m feeder.fresh", description=__doc__.split("\n\n")[0])
    parser.add_argument("root", nargs="?", default=".", help="the checkout (default: the current folder)")
    args = parser.parse_args(argv)
    try:
        marked, stamp = mark_current(args.root)
    except FeederError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(stamp))
    print(f"{len(marked)} committed results under {', '.join(COMMITTED_OUTPUTS)} marked current ({when})")
    later = code_after_results(args.root)
    if later:
        print(
            f"note: code was committed after the newest committed results ({later}); a result that "
            "depends on it may be stale: rebuild it with snakemake -f TARGET (or -R RULE)",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
