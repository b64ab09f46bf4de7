"""Helpers the Snakemake workflow uses at parse time (kept here so they are importable and tested)."""

from __future__ import annotations

import functools
import json
import os
import sys


def module_file(module: str, root: str | os.PathLike = "src") -> str | None:
    """Source file of a dotted module under ``root`` (``feeder.sim.drops`` ->
    ``src/feeder/sim/drops.py``; a package -> its ``__init__.py``), or None if there is none."""
    from pathlib import Path

    base = Path(root, *module.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path.as_posix()
    return None


def feeder_imports(module: str, root: str | os.PathLike = "src") -> set[str]:
    """The ``feeder`` modules that ``module``'s source imports anywhere (function-local imports
    included), read from its syntax tree without importing it. ``from feeder.x import y`` counts
    ``feeder.x.y`` when that is a module, else ``feeder.x``."""
    from feeder.errors import FeederError

    path = module_file(module, root)
    if path is None:
        raise FeederError(f"no source for module {module} under {root}")
    stat = os.stat(path)
    found: set[str] = set()
    for imported, names in _feeder_import_statements(path, stat.st_mtime_ns, stat.st_size):
        if names is None:
            found.add(imported)
            continue
        for name in names:
            sub = f"{imported}.{name}"
            found.add(sub if module_file(sub, root) else imported)
    return found


@functools.cache
def _feeder_import_statements(path: str, mtime_ns: int, size: int) -> tuple[tuple[str, tuple[str, ...] | None], ...]:
    """The ``feeder`` imports of the file at ``path`` as (module, None) for ``import module`` and
    (module, names) for ``from module import names``. Parsed once per file version (its
    modification time and size are part of the key): a Snakefile parse asks for the same modules
    about 1,800 times, and parsing each time cost most of every Snakemake start (about 15 of 22 s)."""
    import ast
    from pathlib import Path

    statements: list[tuple[str, tuple[str, ...] | None]] = []
    for node in ast.walk(ast.parse(Path(path).read_text(), filename=path)):
        if isinstance(node, ast.Import):
            statements.extend((a.name, None) for a in node.names if a.name.split(".")[0] == "feeder")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] == "feeder":
                statements.append((node.module, tuple(a.name for a in node.names)))
    return tuple(statements)


def code_modules(*modules: str, root: str | os.PathLike = "src") -> list[str]:
    """``modules`` with everything they import from ``feeder``, transitively, and the packages
    they sit in (whose ``__init__`` runs first), sorted."""
    seen: set[str] = set()
    todo = list(modules)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        parts = name.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))
        todo.extend(feeder_imports(name, root))
    return sorted(seen)


def command_modules(command: str, *args: str) -> tuple[str, ...]:
    """The modules that ``feeder COMMAND ARGS…`` runs first: the command's own module, and for
    ``feeder figure NAME`` the figure's module, which the dispatcher loads by name."""
    from feeder.cli import COMMANDS
    from feeder.errors import FeederError

    if command not in COMMANDS:
        raise FeederError(f"no feeder command {command!r}")
    modules = ("feeder.cli", COMMANDS[command][0])
    if command == "figure" and args:
        modules += (f"feeder.figures.{args[0]}",)
    return modules


def code_inputs(command: str, *args: str, root: str | os.PathLike = "src") -> list[str]:
    """Source files a ``feeder COMMAND`` job runs, derived from its imports: a rule's code inputs.
    Snakemake does not track imported Python modules, so listing them is what reruns a stage after
    a code edit; deriving them means no list can drift from the code."""
    return [module_file(m, root) for m in code_modules(*command_modules(command, *args), root=root)]


def select_settings(config: dict, *keys: str) -> str:
    """Compact JSON of the named config sections (``labels``) or single settings
    (``sim.min_ok_drops``), nesting kept. As a rule param, editing exactly these reruns the rule."""
    picked: dict = {}
    for key in keys:
        *path, last = key.split(".")
        src, dst = config, picked
        for name in path:
            src, dst = src[name], dst.setdefault(name, {})
        dst[last] = src[last]
    return json.dumps(picked, sort_keys=True, separators=(",", ":"))


def cli_options(options: dict) -> str:
    """Command-line options from a dict, for one string param: ``{"chosen": 15, "ids": [1, 2]}``
    -> ``--chosen 15 --ids 1,2`` (a list or tuple joined by commas)."""
    return " ".join(
        f"--{key} {','.join(map(str, value)) if isinstance(value, (list, tuple)) else value}"
        for key, value in options.items()
    )


def put_interpreter_on_path(environ=os.environ) -> None:
    """Jobs call ``feeder``: take it from the environment Snakemake runs in (e.g. ``.venv/bin``),
    even when that environment is not activated."""
    here = os.path.dirname(sys.executable)
    parts = environ.get("PATH", "").split(os.pathsep)
    if parts[:1] != [here]:
        environ["PATH"] = os.pathsep.join([here, *[p for p in parts if p]])


def drop_local_job_rate_limit(workflow, log=print) -> bool:
    """Switch off Snakemake's job-submission rate limiter for a local run (call from ``onstart``).

    The limiter (``--max-jobs-per-timespan``, default 100/1s, always on from the command line)
    exists to spare cluster schedulers. In Snakemake 9 every scheduling round it triggers arms a
    ``threading.Timer`` that triggers another round, so each finished job leaves a perpetual
    once-a-timespan re-scheduling behind it (snakemake/snakemake#3744). With ~1,250 simulation
    jobs that cost the snakemake process itself a growing share of a core (measured 0.8 CPU-s per
    job early in the paper-scale run, more later). Locally nothing needs the limit; remote
    executors keep it. Returns whether the limiter was removed.
    """
    scheduler = getattr(workflow, "scheduler", None)
    if scheduler is None or not getattr(workflow, "local_exec", False):
        return False
    if getattr(scheduler, "job_rate_limiter", None) is None:
        return False
    scheduler.job_rate_limiter = None
    log("feeder: local run, Snakemake's job rate limiter switched off (snakemake#3744)")
    return True


def simulations_notice(jobs, targets=(), rule: str = "simulate") -> str | None:
    """What a run that is about to simulate says first (call from ``onstart`` with the DAG's
    needrun jobs and the requested files), or None when it simulates nothing. The simulations are
    not committed, so in a clone any table built from them (the dataset, the models, Tables 4-10)
    needs all of them again: say so before the hours start, not after."""
    n = sum(1 for job in jobs if job.rule.name == rule)
    if not n:
        return None
    wanted = f" for {', '.join(sorted(map(str, targets)))}" if targets else ""
    return (
        f"feeder: this run simulates {n} configurations{wanted}. Simulations are never committed, "
        "and what is built from them (the dataset, the models, their tables and figure data) needs "
        "every one (Ctrl-C stops the run). To redraw a committed figure or table instead: `make fresh` "
        "once after cloning, then `snakemake -n -r TARGET` shows which jobs would run and why."
    )


# What a workflow run reads from a study directory (the package itself is installed; src/ is
# there because rules declare its modules as inputs).
STUDY_FILES = ("Snakefile", "workflow", "profiles", "config", "parts", "src")


def copy_study(study: str | os.PathLike, dest: str | os.PathLike):
    """A fresh copy of what a workflow run of ``study`` reads, at ``dest`` (created); returns it."""
    import shutil
    from pathlib import Path

    study, dest = Path(study), Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    for name in STUDY_FILES:
        src = study / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        elif src.is_file():
            shutil.copy2(src, dest / name)
    return dest
