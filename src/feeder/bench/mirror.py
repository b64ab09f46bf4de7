"""Is a fence at Location 2 the mirror image of the same fence at Location 1? (``feeder bench-mirror``).

Issue #38 item 3. Location 1 is on the right of the belt and Location 2 on the left, upstream. A
one-fence scene ``F | none`` seen by a part P from initial yaw β is, reflected x → −x, the scene
``none | F`` seen by P's mirror image (:func:`feeder.parts.shapes.mirror_part`) from −β: its
final yaw should be the negative of P's. Were it so, a part with a mirror axis (its mirror image
is itself, turned) would need one set of simulations for both locations, since the two
locations differ only in how far downstream the fence stands, and a part that rides the belt
does not change on the way.

For each part (``sim.mirror_bench.parts``; empty: the first part of each family of the library's
catalog) and fence (``fences``), four runs of the same grid of initial yaws, one drop per world so
that drop i pairs up: ``a`` (P, F | none, from β), ``mirror`` (mirror image, none | F, from −β,
its final yaws negated before comparing), ``nudged`` (``a`` with every yaw ``nudge_deg`` later:
the paired floor) and ``b`` (a second seeded offset: the label floor). A row passes when the
mirror's distances to ``a`` stay within ``floor_factor`` times the floors, as the decomposition
test rules (:func:`feeder.bench.decomposition_table.within_floor`, with the label's resolution as
the least floor). The raw drops are kept (``--out-raw``); the table comes from them.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from multiprocessing import get_context

import numpy as np
import pandas as pd

from feeder.errors import FeederError

RUNS = ("a", "mirror", "nudged", "b")


def bench_parts(bench: dict, catalog: pd.DataFrame) -> list[str]:
    """The parts of the bench: as listed, else the first id (sorted) of each catalog family (pure)."""
    listed = list(bench.get("parts") or [])
    if listed:
        return listed
    if not {"id", "family"} <= set(catalog.columns) or catalog.empty:
        raise FeederError("sim.mirror_bench.parts is empty and the catalog has no id and family columns")
    return sorted(catalog.sort_values("id").groupby("family")["id"].first().tolist())


def plan_runs(parts: list[str], bench: dict, base_seed: int) -> list[dict]:
    """Every run: per part and fence, the four runs of :data:`RUNS` (pure)."""
    from feeder.sim.drops import drop_seed, initial_yaws

    drops, sampling, nudge = int(bench["drops"]), str(bench["sampling"]), float(bench["nudge_deg"])
    runs = []
    for part in parts:
        for fence in bench["fences"]:
            config = f"{fence}|none"
            base = initial_yaws(drop_seed(part, config, base_seed), drops, sampling)
            other = initial_yaws(drop_seed(part, config, base_seed + int(bench["offset_b_seed"])), drops, sampling)
            yaws = {"a": base, "mirror": -base, "nudged": base + nudge, "b": other}
            runs += [{"part": part, "fence": fence, "run": r, "yaws": np.asarray(yaws[r], np.float64)} for r in RUNS]
    return runs


def _job(job):
    run, parts_dir, scene, preset = job
    from feeder.lane.fences import parse_location
    from feeder.parts.geometry import load_part
    from feeder.parts.shapes import mirror_part
    from feeder.sim.drops import run_each

    geom = load_part(f"{parts_dir}/{run['part']}.stl")
    fence, none = parse_location(run["fence"]), parse_location("none")
    loc1, loc2 = (none, fence) if run["run"] == "mirror" else (fence, none)
    if run["run"] == "mirror":
        geom = mirror_part(geom, f"{run['part']}-m")
    start = time.process_time()
    out = run_each(geom, loc1, loc2, run["yaws"], scene, preset)
    cpu = time.process_time() - start
    return run, out["final_yaw_deg"], np.asarray(out["status"]).astype(str), cpu


def simulate_all(parts, bench, base_seed, parts_dir, scene, preset) -> pd.DataFrame:
    """Every run of :func:`plan_runs` (``bench.workers`` processes): one row per drop."""
    jobs = [(run, parts_dir, scene, preset) for run in plan_runs(parts, bench, base_seed)]
    records = []
    with get_context("fork").Pool(max(1, int(bench["workers"]))) as pool:
        for k, (run, final, status, cpu) in enumerate(pool.imap_unordered(_job, jobs), 1):
            records += [
                {
                    "part": run["part"],
                    "fence": run["fence"],
                    "run": run["run"],
                    "drop": i,
                    "initial_yaw_deg": float(y0),
                    "final_yaw_deg": float(y),
                    "status": s,
                    "cpu_s": cpu,
                }
                for i, (y0, y, s) in enumerate(zip(run["yaws"], final, status))
            ]
            print(f"feeder bench-mirror: {k}/{len(jobs)} runs", file=sys.stderr)
    return pd.DataFrame(records).sort_values(["part", "fence", "run", "drop"], ignore_index=True)


def summarize(raw: pd.DataFrame, bins: int, sigma: float, factor: float) -> pd.DataFrame:
    """One row per part and fence: the mirror's distances to ``a`` (its final yaws negated), the
    floors, and the verdict; then one ``all`` row: rows passed (pure but for the metrics)."""
    from feeder.bench.decomposition_table import LABEL, PAIRED, compare, resolved_floor, within_floor

    rows = []
    for (part, fence), g in raw.groupby(["part", "fence"], sort=True):
        run = {r: g[g["run"] == r].sort_values("drop") for r in RUNS}
        mirrored = run["mirror"].assign(final_yaw_deg=np.mod(-run["mirror"]["final_yaw_deg"], 360.0))
        dist = compare(run["a"], mirrored, bins, sigma)
        paired, labels = compare(run["a"], run["nudged"], bins, sigma), compare(run["a"], run["b"], bins, sigma)
        own = {k: paired[k] for k in PAIRED} | {k: labels[k] for k in LABEL}
        drops = len(run["a"])
        floor = resolved_floor(own, bins, drops)
        rows.append(
            {"part": part, "fence": fence, "drops": drops, "ok_rate": float(np.mean(run["a"]["status"] == "ok"))}
            | dist
            | {f"own_floor_{k}": v for k, v in own.items()}
            | {f"floor_{k}": v for k, v in floor.items()}
            | {
                "passes_paired": within_floor(dist, floor, drops, factor, PAIRED),
                "passes_label": within_floor(dist, floor, drops, factor, LABEL),
                "passes": within_floor(dist, floor, drops, factor),
                "cpu_s_a": float(run["a"]["cpu_s"].iloc[0]),
            }
        )
    table = pd.DataFrame(rows)
    verdict = {
        "part": "all",
        "fence": "all",
        "drops": int(table["drops"].sum()),
        "same_basin": float(table["same_basin"].median()),
        "median_dyaw_deg": float(table["median_dyaw_deg"].median()),
        "rows": len(table),
        "rows_passed_paired": int(table["passes_paired"].sum()),
        "rows_passed_label": int(table["passes_label"].sum()),
        "rows_passed": int(table["passes"].sum()),
    }
    return pd.concat([table, pd.DataFrame([verdict])], ignore_index=True)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-mirror", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, labels, parts} config sections")
    parser.add_argument("--out-raw", required=True, help="every drop of every run (CSV)")
    parser.add_argument("--out-csv", required=True, help="per part and fence: the mirror against the floors (CSV)")
    args = parser.parse_args(argv)
    from feeder.config import parse_settings
    from feeder.io import write_csv
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import get_preset

    cfg = parse_settings(args.settings, "scene", "sim", "labels", "parts")
    try:
        scene, sim, parts_dir = cfg["scene"], cfg["sim"], cfg["parts"]["dir"]
        bench, base_seed = sim["mirror_bench"], int(sim["base_seed"])
        preset = get_preset(sim["presets"], bench["preset"])
        bins, sigma = int(cfg["labels"]["bins"]), float(cfg["labels"]["sigma_bins"])
        factor = float(bench["floor_factor"])
        fences = [parse_location(f) for f in bench["fences"]]
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    if not fences or any(not f.present for f in fences):
        raise FeederError("sim.mirror_bench.fences: one or more fences, none of them 'none'")
    if int(bench["drops"]) < 2 or not factor > 0 or math.isnan(factor):
        raise FeederError("sim.mirror_bench: drops >= 2 and floor_factor > 0")
    catalog = pd.read_csv(f"{parts_dir}/catalog.csv") if not bench.get("parts") else pd.DataFrame()
    parts = bench_parts(bench, catalog)
    raw = simulate_all(parts, bench, base_seed, parts_dir, scene, preset)
    table = summarize(raw, bins, sigma, factor)
    write_csv(args.out_raw, raw)
    write_csv(args.out_csv, table)
    v = table.iloc[-1]
    print(
        f"feeder bench-mirror: {v['rows_passed']:.0f}/{v['rows']:.0f} rows pass (paired {v['rows_passed_paired']:.0f}, "
        f"label {v['rows_passed_label']:.0f}); median same basin {v['same_basin']:.2f}, "
        f"|dyaw| {v['median_dyaw_deg']:.3f} deg",
        file=sys.stderr,
    )
    return 0
