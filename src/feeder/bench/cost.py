"""What the simulation stage of a study will cost, measured on a sample of its own jobs
(``feeder bench-cost``).

A study's simulation stage is one ``feeder simulate`` job per part × fence configuration, and a
job's cost depends mostly on the part (its convex pieces) and the fences (how long the part turns
and slides). Before committing a machine for a day, this draws a seeded simple random sample of
``sim.cost_bench.configurations`` of the study's configurations (:func:`feeder.labels.dataset.configurations`),
runs each through the very command the workflow runs (``feeder simulate``, the study's preset,
scene, seed and yaw design) with ``sim.cost_bench.drops`` drops, and measures per job:

* ``job_cpu_s``: CPU seconds of the whole process (``os.wait4`` resource usage), as Snakemake's
  ``benchmark:`` files count it;
* ``sim_s``: the simulation's own CPU seconds (``cpu_s`` in its output);
* ``overhead_s = job_cpu_s - sim_s``: interpreter start, imports, reading the part.

A job with D drops is projected at ``overhead_s + D · sim_s / drops``; the stage total is the
population size N times the sample mean of that, with a t-interval from the sample spread and
the finite-population correction (:func:`project_total`). Wall time on ``cores`` cores is the CPU
total divided by the cores, never less than the longest projected job: the jobs are single-core
and many, so the workflow keeps every core busy (``feeder bench-scheduler`` measures what
scheduling adds).

Writes the sample (one row per configuration) to ``--out-csv`` and the projection (one row) to
``--out-summary``; the figure (``feeder figure sim_cost``) draws the sample by part. Once some of
the sampled jobs have run for real, ``--check SAMPLE_CSV`` compares their projection with what
they cost (:func:`check_projection`). Snakemake's own ``benchmark:`` CPU times are polled every
second for a job's first 30 s and every 30 s after that, so for longer jobs they miss up to the
last 30 s; the simulation's ``cpu_s`` is exact.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

SAMPLE_COLUMNS = [
    "part",
    "config_id",
    "dataset",
    "drops",
    "job_cpu_s",
    "sim_s",
    "overhead_s",
    "ms_per_drop",
    "projected_job_cpu_s",
]


def sample_rows(n_rows: int, k: int, seed: int) -> np.ndarray:
    """Sorted indices of a simple random sample of ``min(k, n_rows)`` of ``n_rows`` rows (seeded)."""
    if n_rows < 1:
        raise FeederError("the study has no configurations to sample")
    if k < 2:
        raise FeederError(f"sim.cost_bench.configurations must be at least 2 (a spread needs two), got {k}")
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(n_rows, size=min(k, n_rows), replace=False))


def project_total(values, population: int, confidence: float = 0.95) -> tuple[float, float, float]:
    """Total of ``population`` values estimated from a simple random sample without replacement.

    Returns ``(total, low, high)``: ``population · mean`` and its two-sided t-interval at
    ``confidence``, with the finite-population correction ``1 - n/N`` (a census has no error).
    """
    from scipy import stats

    x = np.asarray(values, float)
    n = x.size
    if n < 2:
        raise FeederError("a projection needs at least two sampled jobs")
    if population < n:
        raise FeederError(f"sample of {n} is larger than the population of {population}")
    if not np.all(np.isfinite(x)):
        raise FeederError("sampled job costs must be finite")
    total = population * float(x.mean())
    se = population * float(x.std(ddof=1)) / math.sqrt(n) * math.sqrt(1.0 - n / population)
    half = float(stats.t.ppf(0.5 + 0.5 * confidence, n - 1)) * se
    return total, total - half, total + half


def wall_hours(cpu_s: float, cores: int, longest_job_s: float) -> float:
    """Wall hours of ``cpu_s`` single-core CPU seconds on ``cores`` cores (at least the longest job)."""
    if cores < 1:
        raise FeederError(f"cores must be positive, got {cores}")
    return max(cpu_s / cores, longest_job_s) / 3600.0


def _run_job(job):
    """One ``feeder simulate`` process → (index, job CPU seconds, simulation seconds)."""
    idx, cmd, out = job
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            tail = err.read().decode(errors="replace").strip().splitlines()[-1:]
            raise FeederError(f"feeder simulate failed ({proc.returncode}): {' '.join(cmd)}: {' '.join(tail)}")
    with np.load(out) as data:
        sim_s = float(data["cpu_s"])
    return idx, usage.ru_utime + usage.ru_stime, sim_s


def run_bench(cfg: dict, progress: bool = False):
    """Sample, run and project (see the module docstring) → (sample frame, summary frame)."""
    from feeder.labels.grid import configurations
    from feeder.parts.library import list_parts

    sim, cb = cfg["sim"], cfg["sim"]["cost_bench"]
    preset_name = sim["preset"]
    if preset_name not in sim["presets"]:
        raise FeederError(f"sim.preset {preset_name!r} is not a preset")
    parts_dir = Path(cfg["parts"]["dir"])
    configs = configurations(cfg, list_parts(parts_dir, cfg["parts"]["include"]))
    take = sample_rows(len(configs), int(cb["configurations"]), int(cb["seed"]))
    sample = configs.iloc[take].reset_index(drop=True)
    drops, full_drops = int(cb["drops"]), int(sim["drops"])
    if drops < 1:
        raise FeederError(f"sim.cost_bench.drops must be positive, got {drops}")
    settings = json.dumps(
        {"scene": cfg["scene"], "presets": {preset_name: sim["presets"][preset_name]}},
        sort_keys=True,
        separators=(",", ":"),
    )
    feeder = [sys.executable, "-m", "feeder"]
    results = {}
    with tempfile.TemporaryDirectory(prefix="feeder-bench-cost-") as tmp:
        jobs = []
        for i, r in sample.iterrows():
            out = str(Path(tmp) / f"{i}.npz")
            cmd = feeder + [
                "simulate",
                "--part",
                str(parts_dir / f"{r['part']}.stl"),
                "--loc1",
                r["loc1"],
                "--loc2",
                r["loc2"],
                "--drops",
                str(drops),
                "--seed",
                str(int(sim["base_seed"])),
                "--yaw-sampling",
                sim["yaw_sampling"],
                "--preset",
                preset_name,
                "--settings",
                settings,
                "--out",
                out,
            ]
            jobs.append((i, cmd, out))
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(jobs), unit="job", file=sys.stderr)
        with ThreadPoolExecutor(max(1, int(cb["workers"]))) as pool:
            for idx, job_cpu, sim_s in pool.map(_run_job, jobs):
                results[idx] = (job_cpu, sim_s)
                if bar is not None:
                    bar.update(1)
        if bar is not None:
            bar.close()
    sample = sample[["part", "config_id", "dataset"]].copy()
    sample["drops"] = drops
    sample["job_cpu_s"] = [results[i][0] for i in range(len(sample))]
    sample["sim_s"] = [results[i][1] for i in range(len(sample))]
    sample["overhead_s"] = sample["job_cpu_s"] - sample["sim_s"]
    sample["ms_per_drop"] = 1e3 * sample["sim_s"] / drops
    sample["projected_job_cpu_s"] = sample["overhead_s"] + full_drops * sample["sim_s"] / drops
    summary = summarize(sample, len(configs), full_drops, int(cb["cores"]), preset_name, sim["yaw_sampling"])
    return sample[SAMPLE_COLUMNS], summary


def summarize(sample, population: int, full_drops: int, cores: int, preset: str, yaw_sampling: str):
    """The one-row projection of the simulation stage from the sampled jobs."""
    import pandas as pd

    cpu, lo, hi = project_total(sample["projected_job_cpu_s"], population)
    longest = float(sample["projected_job_cpu_s"].max())
    per_drop = project_total(sample["ms_per_drop"], population)
    return pd.DataFrame(
        [
            dict(
                configurations=population,
                drops=full_drops,
                preset=preset,
                yaw_sampling=yaw_sampling,
                sampled=len(sample),
                sample_drops=int(sample["drops"].iloc[0]),
                ms_per_drop=per_drop[0] / population,
                ms_per_drop_lo=per_drop[1] / population,
                ms_per_drop_hi=per_drop[2] / population,
                overhead_s_per_job=float(sample["overhead_s"].mean()),
                cpu_s=cpu,
                cpu_s_lo=lo,
                cpu_s_hi=hi,
                cores=cores,
                wall_h=wall_hours(cpu, cores, longest),
                wall_h_lo=wall_hours(lo, cores, longest),
                wall_h_hi=wall_hours(hi, cores, longest),
            )
        ]
    )


def check_projection(sample, sim_dir, bench_dir=None):
    """The sampled jobs that have since run for real: projected against measured CPU.

    For each row of ``sample`` (``feeder bench-cost``'s sample table) whose simulation output
    ``<sim_dir>/<part>/<config_id>.npz`` exists: ``drops`` of that run, ``projected_sim_cpu_s``
    (its drops × the sampled CPU per drop), ``sim_cpu_s`` (``cpu_s`` of the run) and their
    ``ratio``; with ``bench_dir``, also Snakemake's ``benchmark_cpu_s`` / ``benchmark_wall_s``
    (``<bench_dir>/<part>/<config_id>.tsv``, NaN where absent). A last row ``part == "total"``
    sums each column over the rows that have it (ratio of the sums).
    """
    import pandas as pd

    rows = []
    for _, r in sample.iterrows():
        npz = Path(sim_dir) / r["part"] / f"{r['config_id']}.npz"
        if not npz.is_file():
            continue
        with np.load(npz) as data:
            if "cpu_s" not in data:
                raise FeederError(f"{npz} has no cpu_s (written before feeder simulate recorded it)")
            drops, cpu = int(data["final_yaw_deg"].size), float(data["cpu_s"])
        row = dict(
            part=r["part"],
            config_id=r["config_id"],
            drops=drops,
            projected_sim_cpu_s=drops * float(r["ms_per_drop"]) / 1e3,
            sim_cpu_s=cpu,
            benchmark_cpu_s=math.nan,
            benchmark_wall_s=math.nan,
        )
        tsv = Path(bench_dir) / r["part"] / f"{r['config_id']}.tsv" if bench_dir is not None else None
        if tsv is not None and tsv.is_file():
            last = pd.read_csv(tsv, sep="\t").iloc[-1]
            row.update(benchmark_cpu_s=float(last["cpu_time"]), benchmark_wall_s=float(last["s"]))
        rows.append(row)
    if not rows:
        raise FeederError(f"none of the {len(sample)} sampled jobs has an output in {sim_dir}")
    out = pd.DataFrame(rows)
    total = out.drop(columns=["part", "config_id"]).sum(min_count=1)
    out = pd.concat([out, pd.DataFrame([dict(part="total", config_id="", **total)])], ignore_index=True)
    out["drops"] = out["drops"].astype(np.int64)
    out["ratio"] = out["sim_cpu_s"] / out["projected_sim_cpu_s"]
    return out


def main(argv: list[str]) -> int:
    from feeder.bench.accuracy import add_config_source, config_from_args

    parser = argparse.ArgumentParser(prog="feeder bench-cost", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out-csv", required=True, help="the sampled jobs, one row each (with --check: the comparison)"
    )
    parser.add_argument("--out-summary", help="the projection, one row (required unless --check)")
    parser.add_argument(
        "--check",
        metavar="SAMPLE_CSV",
        help="instead of sampling: compare this sample's projection with the jobs of it that have run",
    )
    parser.add_argument("--sim-dir", default="results/sim", help="with --check: simulation outputs")
    parser.add_argument("--benchmarks", default="benchmarks/simulate", help="with --check: Snakemake benchmark files")
    add_config_source(parser, "parts, fences, datasets, scene, sim")
    args = parser.parse_args(argv)
    from feeder.io import write_csv

    if args.check is not None:
        import pandas as pd

        if not Path(args.check).is_file():
            raise FeederError(f"sample table {args.check} not found")
        out = check_projection(pd.read_csv(args.check), args.sim_dir, args.benchmarks)
        write_csv(args.out_csv, out)
        t = out.iloc[-1]
        print(
            f"{len(out) - 1} sampled jobs have run: simulation CPU {t['sim_cpu_s']:.0f} s against "
            f"{t['projected_sim_cpu_s']:.0f} s projected (ratio {t['ratio']:.2f})",
            file=sys.stderr,
        )
        return 0
    if args.out_summary is None:
        raise FeederError("--out-summary is required (unless --check)")
    cfg = config_from_args(args)
    missing = [k for k in ("parts", "fences", "datasets", "scene", "sim") if k not in cfg]
    if missing or "cost_bench" not in cfg.get("sim", {}):
        raise FeederError(f"settings lack section(s) {', '.join(missing or ['sim.cost_bench'])}")
    sample, summary = run_bench(cfg, progress=sys.stderr.isatty())
    write_csv(args.out_csv, sample)
    write_csv(args.out_summary, summary)
    s = summary.iloc[0]
    print(
        f"{int(s['configurations'])} configurations x {int(s['drops'])} drops ({s['preset']}): "
        f"{s['ms_per_drop']:.0f} ms/drop [{s['ms_per_drop_lo']:.0f}, {s['ms_per_drop_hi']:.0f}], "
        f"{s['cpu_s'] / 3600:.1f} CPU-h [{s['cpu_s_lo'] / 3600:.1f}, {s['cpu_s_hi'] / 3600:.1f}], "
        f"{s['wall_h']:.1f} h on {int(s['cores'])} cores (from {int(s['sampled'])} jobs of "
        f"{int(s['sample_drops'])} drops)",
        file=sys.stderr,
    )
    return 0
