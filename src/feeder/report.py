"""What the study cost: gather Snakemake ``benchmark:`` files into a per-stage table and write a
provenance record (git commit, config hash, machine, per-stage time). The figure is drawn from the
table by ``feeder figure cost_by_stage`` (:mod:`feeder.figures.cost_by_stage`).

Benchmarks are laid out ``benchmarks/<stage>/<job>.tsv`` (one file per job); a stage is the first
directory below ``benchmarks/``. Snakemake samples a job's CPU time every second for 30 s, then
every 30 s, so CPU seconds of jobs longer than 30 s miss up to their last 30 s (wall seconds are
exact; ``feeder bench-cost --check`` measured 6 % short on 1,000-drop simulation jobs).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import subprocess
from pathlib import Path

import pandas as pd

from feeder import io
from feeder.errors import FeederError

COLUMNS = ["stage", "jobs", "wall_s", "cpu_s", "max_rss_mb"]


def read_benchmarks(root: str | os.PathLike) -> pd.DataFrame:
    """One row per benchmark file: stage, job, wall_s, cpu_s, max_rss_mb (last repeat of each file)."""
    rows = []
    root = Path(root)
    for tsv in sorted(root.rglob("*.tsv")):
        try:
            frame = pd.read_csv(tsv, sep="\t")
        except (pd.errors.EmptyDataError, pd.errors.ParserError) as err:
            raise FeederError(f"{tsv}: not a Snakemake benchmark file ({err})") from None
        if frame.empty or "s" not in frame:
            raise FeederError(f"{tsv}: benchmark file without an 's' column")
        last = frame.iloc[-1]
        cpu = float(last["cpu_time"]) if "cpu_time" in frame and pd.notna(last["cpu_time"]) else float("nan")
        rss = float(last["max_rss"]) if "max_rss" in frame and pd.notna(last["max_rss"]) else float("nan")
        rows.append(
            {
                "stage": tsv.relative_to(root).parts[0],
                "job": str(tsv.relative_to(root)),
                "wall_s": float(last["s"]),
                "cpu_s": cpu,
                "max_rss_mb": rss,
            }
        )
    return pd.DataFrame(rows, columns=["stage", "job", "wall_s", "cpu_s", "max_rss_mb"])


def cost_by_stage(jobs: pd.DataFrame) -> pd.DataFrame:
    """Sum wall and CPU seconds per stage, keep the largest resident memory; a TOTAL row last."""
    if jobs.empty:
        return pd.DataFrame(columns=COLUMNS)
    grouped = jobs.groupby("stage", sort=True).agg(
        jobs=("job", "size"), wall_s=("wall_s", "sum"), cpu_s=("cpu_s", "sum"), max_rss_mb=("max_rss_mb", "max")
    )
    grouped = grouped.reset_index().sort_values("wall_s", ascending=False, kind="stable")
    total = pd.DataFrame(
        [
            {
                "stage": "TOTAL",
                "jobs": int(grouped["jobs"].sum()),
                "wall_s": grouped["wall_s"].sum(),
                "cpu_s": grouped["cpu_s"].sum(),
                "max_rss_mb": grouped["max_rss_mb"].max(),
            }
        ]
    )
    out = pd.concat([grouped, total], ignore_index=True)[COLUMNS]
    return out.round({"wall_s": 2, "cpu_s": 2, "max_rss_mb": 1})


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def provenance(config_json: str, table: pd.DataFrame) -> dict:
    return {
        "git_commit": _git_commit(),
        "config_sha256": hashlib.sha256(config_json.encode()).hexdigest(),
        "config": json.loads(config_json),
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "processor": platform.machine(),
            "cpus": os.cpu_count(),
        },
        "stage_wall_s": {r.stage: r.wall_s for r in table.itertuples()},
    }


def checked_json(text: str, source: str) -> str:
    """``text`` itself if it parses as JSON, else a one-line FeederError naming ``source``."""
    try:
        json.loads(text)
    except json.JSONDecodeError as err:
        raise FeederError(f"{source}: not JSON ({err.msg}, line {err.lineno} column {err.colno})") from None
    return text


def read_config_json(path: str | os.PathLike) -> str:
    """The run's resolved config as written by ``feeder cost --config-out`` (the text itself: its
    hash is the provenance's ``config_sha256``); a one-line FeederError if it is missing or not JSON."""
    path = Path(path)
    if not path.is_file():
        raise FeederError(f"config file {path} not found")
    return checked_json(path.read_text(), str(path))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder cost", description=__doc__)
    parser.add_argument("--benchmarks", default="benchmarks", help="root of the benchmark files")
    parser.add_argument("--out-csv", help="the per-stage table")
    parser.add_argument("--provenance", help="also write this provenance JSON")
    parser.add_argument("--config-json", help="the resolved workflow config (for its hash)")
    parser.add_argument("--config-file", help="... or the file --config-out wrote it to")
    parser.add_argument(
        "--config-out",
        help="write --config-json to this file, alone: the workflow's record of a run's settings, which a "
        "change of any setting rewrites (and so the run's provenance, which reads it)",
    )
    args = parser.parse_args(argv)
    if args.config_json is not None and args.config_file is not None:
        raise FeederError("give --config-json or --config-file, not both")
    config_json = read_config_json(args.config_file) if args.config_file is not None else (args.config_json or "{}")
    if args.config_out is not None:
        if args.config_json is None:
            raise FeederError("--config-out writes the config given as --config-json")
        io.write_text(args.config_out, checked_json(config_json, "--config-json"))
    if args.out_csv is None:
        if args.config_out is None:
            raise FeederError("give --out-csv (the per-stage table), --config-out, or both")
        return 0
    table = cost_by_stage(read_benchmarks(args.benchmarks))
    io.write_csv(args.out_csv, table)
    if args.provenance:
        io.write_json(args.provenance, provenance(config_json, table))
    return 0
