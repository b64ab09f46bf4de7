"""What scheduling the simulation jobs costs: ``feeder bench-scheduler``.

Runs the workflow's ``simulate`` jobs for a spread of configurations in a scratch copy of the
study, once with Snakemake's job rate limiter left on (its command-line default) and once with it
switched off by the ``onstart`` hook (``scheduling.local_rate_limit: false``, the default), and
measures the CPU the snakemake process itself spends (its own threads, from /proc, children
excluded) against the CPU of the jobs (everything it waited for, from wait4). Few drops per job make the jobs
short so that scheduling is a large, measurable share; the per-job figure carries over to
longer jobs. The jobs draw ``--drops`` independent random drops whatever the study's design
(an adaptive job's length is not set by its budget).

    feeder bench-scheduler --configfile config/paper50.yaml --jobs 300 --drops 2 \\
        --out results/tables/bench_scheduler.csv
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from feeder.errors import FeederError


def proc_cpu_seconds(stat_line: str, ticks_per_s: float) -> float:
    """User + system CPU of one process's own threads from a /proc/<pid>/stat line (children,
    fields 16-17, excluded). The command name (field 2) may hold spaces: split after its ')'."""
    fields = stat_line[stat_line.rindex(")") + 2 :].split()
    # fields[0] is field 3 (state): utime and stime are fields 14 and 15
    return (int(fields[11]) + int(fields[12])) / ticks_per_s


def spread(items: list, n: int) -> list:
    """n items evenly spread over the list (all of them when n >= len)."""
    if n >= len(items):
        return list(items)
    step = len(items) / n
    return [items[int(i * step)] for i in range(n)]


def sim_targets(study: Path, configfiles: list[str], n_jobs: int) -> list[str]:
    """Simulation outputs of n configurations spread over the configured grid."""
    from feeder.config import load_study_config
    from feeder.labels.grid import configurations
    from feeder.parts.library import list_parts

    cfg = load_study_config(*configfiles, root=study)
    parts = list_parts(str(study / cfg["parts"]["dir"]), cfg["parts"]["include"], cfg["parts"].get("exclude", []))
    grid = configurations(cfg, parts)
    rows = spread(list(zip(grid["part"], grid["config_id"])), n_jobs)
    return [f"{cfg['results']}/sim/{part}/{config_id}.npz" for part, config_id in rows]


def run_variant(
    study: Path,
    work: Path,
    configfiles: list[str],
    targets: list[str],
    drops: int,
    local_rate_limit: bool,
    poll_s: float = 0.5,
) -> dict:
    """One snakemake run of the targets in a fresh copy of the study; what it cost."""
    from feeder.workflow import copy_study

    if work.exists():
        shutil.rmtree(work)
    copy_study(study, work)
    overlay = work / "config" / "_bench_scheduler.yaml"
    overlay.write_text(
        # a fixed design of `drops` drops (an adaptive budget below its start grid is refused)
        f"sim:\n  drops: {drops}\n  yaw_sampling: random\n  min_ok_mass: 0.001\n"
        f"scheduling:\n  local_rate_limit: {str(local_rate_limit).lower()}\n"
    )
    snakemake = str(Path(sys.executable).parent / "snakemake")
    cmd = [snakemake, "--cores", "2", *targets, "--configfile", *configfiles, str(overlay.relative_to(work))]
    ticks = os.sysconf("SC_CLK_TCK")
    log = open(work / "bench_scheduler.log", "w")
    start = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=work, stdout=log, stderr=subprocess.STDOUT)
    cpu, threads = 0.0, 0
    stat = Path(f"/proc/{proc.pid}/stat")
    while True:
        # wait4, not Popen.poll: it hands back the CPU of snakemake and every job it waited for
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        try:
            cpu = proc_cpu_seconds(stat.read_text(), ticks)
            threads = max(threads, len(os.listdir(f"/proc/{proc.pid}/task")))
        except (FileNotFoundError, ProcessLookupError):
            pass
        time.sleep(poll_s)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.monotonic() - start
    log.close()
    if proc.returncode != 0:
        raise FeederError(f"snakemake failed (local_rate_limit={local_rate_limit}); see {work}/bench_scheduler.log")
    # the jobs: everything snakemake's children used (the last poll of its own CPU is at most
    # poll_s old, so a sliver of snakemake's final CPU may count as jobs')
    jobs_cpu = usage.ru_utime + usage.ru_stime - cpu
    return {
        "local_rate_limit": local_rate_limit,
        "jobs": len(targets),
        "drops_per_job": drops,
        "wall_s": round(wall, 1),
        "jobs_cpu_s": round(jobs_cpu, 1),
        "snakemake_cpu_s": round(cpu, 1),
        "snakemake_cpu_per_job_s": round(cpu / len(targets), 3),
        "snakemake_share_pct": round(100 * cpu / (cpu + jobs_cpu), 1) if cpu + jobs_cpu > 0 else 0.0,
        "max_threads": threads,
    }


def main(argv: list[str]) -> int:
    from feeder.io import write_csv

    ap = argparse.ArgumentParser(
        prog="feeder bench-scheduler", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--study", default=".", help="study directory (Snakefile, config/, parts/)")
    ap.add_argument("--configfile", nargs="*", default=[], help="config overlays, as for snakemake")
    ap.add_argument("--jobs", type=int, default=300, help="simulation jobs per run")
    ap.add_argument("--drops", type=int, default=2, help="drops per job (few: short jobs)")
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    if args.jobs < 1 or args.drops < 1:
        raise FeederError("--jobs and --drops must be positive")
    if not Path(f"/proc/{os.getpid()}/stat").exists():
        raise FeederError("needs /proc (Linux) to read the snakemake process's own CPU time")
    study = Path(args.study).resolve()
    if not (study / "Snakefile").is_file():
        raise FeederError(f"no Snakefile in {study}")
    targets = sim_targets(study, args.configfile, args.jobs)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_scheduler_") as tmp:
        for limit in (True, False):
            row = run_variant(study, Path(tmp) / f"limit_{limit}", args.configfile, targets, args.drops, limit)
            print(
                f"rate limit {'on ' if limit else 'off'}: snakemake {row['snakemake_cpu_s']} CPU-s "
                f"({row['snakemake_cpu_per_job_s']} per job, {row['snakemake_share_pct']} % of all CPU), "
                f"{row['max_threads']} threads, wall {row['wall_s']} s",
                file=sys.stderr,
            )
            rows.append(row)
    write_csv(args.out, pd.DataFrame(rows))
    return 0
