"""feeder bench-scheduler: reading a process's own CPU time, spreading targets, and one small run."""

from __future__ import annotations

import os
import subprocess
import sys

import pandas as pd
import pytest
from workflow_helpers import ROOT

from feeder.bench.scheduler import proc_cpu_seconds, spread


def test_proc_cpu_seconds_reads_own_utime_and_stime_not_childrens():
    # fields: pid (comm) state ppid ... utime=14 stime=15 cutime=16 cstime=17; comm holds a space and ')'
    fields = ["S"] + [str(i) for i in range(4, 14)] + ["250", "50", "9999", "9999"] + ["0"] * 10
    line = "1234 (snake make) x) " + " ".join(fields)
    assert proc_cpu_seconds(line, 100.0) == pytest.approx(3.0)


def test_proc_cpu_seconds_of_this_process_grows_with_work():
    stat = f"/proc/{os.getpid()}/stat"
    before = proc_cpu_seconds(open(stat).read(), os.sysconf("SC_CLK_TCK"))
    sum(i * i for i in range(3_000_000))
    assert proc_cpu_seconds(open(stat).read(), os.sysconf("SC_CLK_TCK")) > before


def test_spread_is_even_and_keeps_all_when_few():
    assert spread(list(range(10)), 5) == [0, 2, 4, 6, 8]
    assert spread([1, 2], 5) == [1, 2]


@pytest.mark.slow
def test_bench_runs_both_variants_and_the_hook_removes_the_timer_threads(tmp_path):
    out = tmp_path / "bench.csv"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "feeder",
            "bench-scheduler",
            "--study",
            str(ROOT),
            "--configfile",
            "config/smoke.yaml",
            "--jobs",
            "4",
            "--drops",
            "2",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    frame = pd.read_csv(out).set_index("local_rate_limit")
    assert list(frame["jobs"]) == [4, 4]
    assert (frame["jobs_cpu_s"] > 0).all() and (frame["snakemake_cpu_s"] >= 0).all()
    # with the limiter each finished job leaves a live timer thread behind; without it none
    assert frame.loc[True, "max_threads"] > frame.loc[False, "max_threads"]


def test_bad_arguments_are_one_line_errors(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "feeder", "bench-scheduler", "--jobs", "0", "--out", str(tmp_path / "x.csv")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "must be positive" in proc.stderr and not (tmp_path / "x.csv").exists()
