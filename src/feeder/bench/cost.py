"""What the simulation stage of a study will cost, measured on a sample of its own jobs
(``feeder bench-cost``).

A study's simulation stage is one ``feeder simulate`` job per part × fence configuration, and a
job's cost depends mostly on the part (its convex pieces) and the fences (how long the part turns
and slides). Before committing a machine for a day, this draws a seeded simple random sample of
``sim.cost_bench.configurations`` of the study's configurations (:func:`feeder.labels.dataset.configurations`),
runs each through the very command the workflow runs (``feeder simulate``, the study's preset,
scene and seed) under two initial-yaw designs, paired on the same configurations: the study's own
(``sim.yaw_sampling``, ``sim.drops``) and a baseline (``sim.cost_bench.baseline``, the paper's
1,000 independent drops; run once when it is the study's design). It measures per job:

* ``job_cpu_s``: CPU seconds of the whole process (``os.wait4`` resource usage), as Snakemake's
  ``benchmark:`` files count it;
* ``sim_s``: the simulation's own CPU seconds (``cpu_s`` in its output);
* ``overhead_s = job_cpu_s - sim_s``: interpreter start, imports, reading the part.

How a job is projected depends on its design (:func:`projected_job_cpu`). ``random``, ``golden``
and ``grid`` simulate a fixed number D of drops at a steady cost per drop: the sampled job runs
``sim.cost_bench.drops`` drops and is projected at ``overhead_s + D · sim_s / drops``. ``adaptive``
simulates a data-dependent number of drops (at most its budget ``sim.drops``): the sampled job runs
the real design at the full budget with the options of ``sim.adaptive``, and its measured CPU is
its projected cost (``drops`` is then the simulations it ran). The stage total is the population
size N times the sample mean, with a t-interval from the sample spread and the finite-population
correction (:func:`project_total`); the ratio of two designs' totals is a paired ratio estimator
over the sampled configurations (:func:`paired_ratio`). Wall time on ``cores`` cores is the CPU
total divided by the cores, never less than the longest projected job: the jobs are single-core
and many, so the workflow keeps every core busy (``feeder bench-scheduler`` measures what
scheduling adds).

Writes the sample (one row per configuration and design, the study's design first) to
``--out-csv`` and the projection (one row per design, with ``cpu_ratio_to_baseline``) to
``--out-summary``; the figure (``feeder figure sim_cost``) draws the sample by part and design. Once some of
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
    "yaw_sampling",
    "design_drops",
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


def paired_ratio(x, y, population: int, confidence: float = 0.95) -> tuple[float, float, float]:
    """Ratio of two designs' totals, ``sum(x) / sum(y)``, from the same sampled configurations.

    ``x[i]`` and ``y[i]`` are one configuration's projected job cost under the two designs. Returns
    ``(ratio, low, high)``: the ratio estimator ``R = mean(x) / mean(y)`` and its two-sided
    t-interval at ``confidence`` (n - 1 degrees of freedom) from the linearised variance
    ``(1 - n/N) · s_d² / (n · mean(y)²)`` of the residuals ``d = x - R·y`` (Cochran, Sampling
    Techniques, 6.3): the pairing removes the spread the two designs share across configurations,
    and a census, or costs exactly proportional, has no error.
    """
    from scipy import stats

    x, y = np.asarray(x, float), np.asarray(y, float)
    n = x.size
    if y.size != n:
        raise FeederError(f"paired costs differ in length ({n} against {y.size})")
    if n < 2:
        raise FeederError("a ratio needs at least two paired jobs")
    if population < n:
        raise FeederError(f"sample of {n} is larger than the population of {population}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))) or y.mean() <= 0:
        raise FeederError("paired job costs must be finite, the baseline's positive")
    ratio = float(x.mean() / y.mean())
    d = x - ratio * y
    se = math.sqrt((1.0 - n / population) * float(d.var(ddof=1)) / n) / float(y.mean())
    half = float(stats.t.ppf(0.5 + 0.5 * confidence, n - 1)) * se
    return ratio, ratio - half, ratio + half


def designs(sim: dict, cost_bench: dict) -> list[dict]:
    """The designs projected: the study's (``sim``) first, then ``cost_bench.baseline`` unless equal."""
    base = cost_bench.get("baseline")
    if not isinstance(base, dict) or not {"yaw_sampling", "drops"} <= set(base):
        raise FeederError("sim.cost_bench.baseline needs yaw_sampling and drops")
    out = []
    for d in (sim, base):
        design = {"yaw_sampling": str(d["yaw_sampling"]), "drops": int(d["drops"])}
        if design["drops"] < 1:
            raise FeederError(f"design drops must be positive, got {design['drops']}")
        if design not in out:
            out.append(design)
    return out


def sample_drops(design: dict, bench_drops: int) -> int:
    """Drops a sampled job of ``design`` runs: the full budget for adaptive, else ``bench_drops``."""
    return design["drops"] if design["yaw_sampling"] == "adaptive" else int(bench_drops)


def design_options(design: dict, adaptive: dict | None) -> list[str]:
    """``feeder simulate`` options of ``design`` (``--yaw-sampling``, and ``sim.adaptive`` for adaptive)."""
    opts = ["--yaw-sampling", design["yaw_sampling"]]
    if design["yaw_sampling"] == "adaptive":
        if not adaptive:
            raise FeederError("the adaptive design needs sim.adaptive")
        for key, value in adaptive.items():
            opts += [f"--{key.replace('_', '-')}", str(value)]
    return opts


def projected_job_cpu(job_cpu_s, sim_s, drops, design_drops, yaw_sampling: str):
    """A sampled job's projected CPU seconds under its design: the measured job for adaptive (it ran
    the real design at the full budget), else its overhead plus ``design_drops`` times its CPU per drop."""
    job_cpu_s, sim_s = np.asarray(job_cpu_s, float), np.asarray(sim_s, float)
    if yaw_sampling == "adaptive":
        return job_cpu_s
    return job_cpu_s - sim_s + design_drops * sim_s / np.asarray(drops, float)


def _run_job(job):
    """One ``feeder simulate`` process → (index, job CPU seconds, simulation seconds, simulations)."""
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
        sim_s, simulations = float(data["cpu_s"]), int(data["final_yaw_deg"].size)
    return idx, usage.ru_utime + usage.ru_stime, sim_s, simulations


def job_command(feeder, part_path, loc1, loc2, design, bench_drops, sim, settings, out) -> list[str]:
    """The ``feeder simulate`` command of one sampled job of ``design`` (see :func:`sample_drops`,
    :func:`design_options`): the study's seed and preset, the given ``--settings`` JSON."""
    return [
        *feeder,
        "simulate",
        "--part",
        str(part_path),
        "--loc1",
        str(loc1),
        "--loc2",
        str(loc2),
        "--drops",
        str(sample_drops(design, bench_drops)),
        "--seed",
        str(int(sim["base_seed"])),
        *design_options(design, sim.get("adaptive")),
        "--preset",
        sim["preset"],
        "--settings",
        settings,
        "--out",
        str(out),
    ]


def run_bench(cfg: dict, progress: bool = False):
    """Sample, run and project (see the module docstring) → (sample frame, summary frame)."""
    from feeder.labels.grid import configurations
    from feeder.parts.library import list_parts

    sim, cb = cfg["sim"], cfg["sim"]["cost_bench"]
    preset_name = sim["preset"]
    if preset_name not in sim["presets"]:
        raise FeederError(f"sim.preset {preset_name!r} is not a preset")
    parts_dir = Path(cfg["parts"]["dir"])
    configs = configurations(cfg, list_parts(parts_dir, cfg["parts"]["include"], cfg["parts"].get("exclude", [])))
    take = sample_rows(len(configs), int(cb["configurations"]), int(cb["seed"]))
    sample = configs.iloc[take].reset_index(drop=True)
    drops = int(cb["drops"])
    if drops < 1:
        raise FeederError(f"sim.cost_bench.drops must be positive, got {drops}")
    plan = designs(sim, cb)
    settings = json.dumps(
        {"scene": cfg["scene"], "presets": {preset_name: sim["presets"][preset_name]}},
        sort_keys=True,
        separators=(",", ":"),
    )
    feeder = [sys.executable, "-m", "feeder"]
    results = {}
    with tempfile.TemporaryDirectory(prefix="feeder-bench-cost-") as tmp:
        jobs = []
        for k, design in enumerate(plan):
            for i, r in sample.iterrows():
                out = Path(tmp) / f"{k}-{i}.npz"
                part = parts_dir / f"{r['part']}.stl"
                jobs.append(
                    ((k, i), job_command(feeder, part, r["loc1"], r["loc2"], design, drops, sim, settings, out), out)
                )
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(jobs), unit="job", file=sys.stderr)
        with ThreadPoolExecutor(max(1, int(cb["workers"]))) as pool:
            for idx, job_cpu, sim_s, simulations in pool.map(_run_job, jobs):
                results[idx] = (job_cpu, sim_s, simulations)
                if bar is not None:
                    bar.update(1)
        if bar is not None:
            bar.close()
    frames = []
    for k, design in enumerate(plan):
        f = sample[["part", "config_id", "dataset"]].copy()
        f["yaw_sampling"] = design["yaw_sampling"]
        f["design_drops"] = design["drops"]
        f["drops"] = [results[(k, i)][2] for i in range(len(sample))]
        f["job_cpu_s"] = [results[(k, i)][0] for i in range(len(sample))]
        f["sim_s"] = [results[(k, i)][1] for i in range(len(sample))]
        frames.append(f)
    import pandas as pd

    out = project_sample(pd.concat(frames, ignore_index=True))
    summary = summarize(out, len(configs), int(cb["cores"]), preset_name, plan[-1], drops)
    return out[SAMPLE_COLUMNS], summary


def project_sample(sample):
    """Add ``overhead_s``, ``ms_per_drop`` and ``projected_job_cpu_s`` (:func:`projected_job_cpu`) to
    sampled jobs with ``yaw_sampling``, ``design_drops``, ``drops``, ``job_cpu_s`` and ``sim_s``."""
    sample = sample.copy()
    sample["overhead_s"] = sample["job_cpu_s"] - sample["sim_s"]
    sample["ms_per_drop"] = 1e3 * sample["sim_s"] / sample["drops"]
    sample["projected_job_cpu_s"] = np.nan
    for ys, rows in sample.groupby("yaw_sampling", sort=False):
        sample.loc[rows.index, "projected_job_cpu_s"] = projected_job_cpu(
            rows["job_cpu_s"], rows["sim_s"], rows["drops"], rows["design_drops"].to_numpy(float), ys
        )
    return sample


def summarize(sample, population: int, cores: int, preset: str, baseline: dict, bench_drops: int):
    """The projection of the simulation stage, one row per design of ``sample`` (in its order).

    ``sample`` is :func:`project_sample`'s table: the same configurations, in the same order, under
    each design (``yaw_sampling``, ``design_drops``). ``simulations_per_job`` is the mean
    simulations per projected job (``design_drops`` for a fixed design, the measured mean for
    adaptive); ``cpu_ratio_to_baseline`` is :func:`paired_ratio` of the design's projected jobs
    against ``baseline``'s (``{yaw_sampling, drops}``), with its 95 % t-interval.
    """
    import pandas as pd

    groups = [
        (key, g.reset_index(drop=True)) for key, g in sample.groupby(["yaw_sampling", "design_drops"], sort=False)
    ]
    base_key = (baseline["yaw_sampling"], int(baseline["drops"]))
    base = dict(groups).get(base_key)
    if base is None:
        raise FeederError(f"the sample has no jobs of the baseline design {base_key}")
    rows = []
    for (ys, design_drops), g in groups:
        if list(zip(g["part"], g["config_id"])) != list(zip(base["part"], base["config_id"])):
            raise FeederError(f"design {ys} ({design_drops}) was not sampled on the baseline's configurations")
        projected = g["projected_job_cpu_s"]
        cpu, lo, hi = project_total(projected, population)
        ratio = paired_ratio(projected, base["projected_job_cpu_s"], population)
        longest = float(projected.max())
        per_drop = project_total(g["ms_per_drop"], population)
        adaptive = ys == "adaptive"
        rows.append(
            dict(
                configurations=population,
                drops=int(design_drops),
                preset=preset,
                yaw_sampling=ys,
                sampled=len(g),
                sample_drops=sample_drops({"yaw_sampling": ys, "drops": int(design_drops)}, bench_drops),
                simulations_per_job=float(g["drops"].mean()) if adaptive else float(design_drops),
                ms_per_drop=per_drop[0] / population,
                ms_per_drop_lo=per_drop[1] / population,
                ms_per_drop_hi=per_drop[2] / population,
                overhead_s_per_job=float(g["overhead_s"].mean()),
                cpu_s=cpu,
                cpu_s_lo=lo,
                cpu_s_hi=hi,
                cpu_ratio_to_baseline=ratio[0],
                cpu_ratio_to_baseline_lo=ratio[1],
                cpu_ratio_to_baseline_hi=ratio[2],
                cores=cores,
                wall_h=wall_hours(cpu, cores, longest),
                wall_h_lo=wall_hours(lo, cores, longest),
                wall_h_hi=wall_hours(hi, cores, longest),
            )
        )
    return pd.DataFrame(rows)


def check_projection(sample, sim_dir, bench_dir=None):
    """The sampled jobs that have since run for real: projected against measured CPU.

    For each row of ``sample`` (``feeder bench-cost``'s sample table) whose simulation output
    ``<sim_dir>/<part>/<config_id>.npz`` exists: ``drops`` of that run, ``projected_sim_cpu_s``
    (its drops × the sampled CPU per drop), ``sim_cpu_s`` (``cpu_s`` of the run) and their
    ``ratio``; with ``bench_dir``, also Snakemake's ``benchmark_cpu_s`` / ``benchmark_wall_s``
    (``<bench_dir>/<part>/<config_id>.tsv``, NaN where absent). A last row ``part == "total"``
    sums each column over the rows that have it (ratio of the sums). A sample of several designs
    (``yaw_sampling``, ``design_drops``) is matched to the design each run records in its meta
    (the rows of other designs, e.g. the baseline, are left out; a run without meta is taken as
    ``random``).
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
            meta = json.loads(str(data["meta"])) if "meta" in data else {}
        if "yaw_sampling" in r and r["yaw_sampling"] != meta.get("yaw_sampling", "random"):
            continue
        if "design_drops" in r and "drops" in meta and int(r["design_drops"]) != int(meta["drops"]):
            continue
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

    parser = argparse.ArgumentParser(prog="feeder bench-cost", description=__doc__.split("\n\n")[0])
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
    for _, s in summary.iterrows():
        print(
            f"{int(s['configurations'])} configurations x {s['yaw_sampling']} {int(s['drops'])} drops "
            f"({s['simulations_per_job']:.1f} simulations/job, {s['preset']}): "
            f"{s['ms_per_drop']:.0f} ms/drop [{s['ms_per_drop_lo']:.0f}, {s['ms_per_drop_hi']:.0f}], "
            f"{s['cpu_s'] / 3600:.2f} CPU-h [{s['cpu_s_lo'] / 3600:.2f}, {s['cpu_s_hi'] / 3600:.2f}], "
            f"x{s['cpu_ratio_to_baseline']:.3f} [{s['cpu_ratio_to_baseline_lo']:.3f}, "
            f"{s['cpu_ratio_to_baseline_hi']:.3f}] of the baseline, "
            f"{s['wall_h']:.1f} h on {int(s['cores'])} cores (from {int(s['sampled'])} jobs of "
            f"{int(s['sample_drops'])} drops)",
            file=sys.stderr,
        )
    return 0
