"""How the part rests on the belt, and what it costs (``feeder bench-contact``).

Runs the same drops (the same random initial yaws, seeded from the part and the configuration)
of every library part with many convex pieces under each belt footprint of
``scene.belt.footprint``: the pieces (each convex piece touches the belt) and pads (a uniform
pressure over the footprint, :func:`feeder.sim.body.footprint_pads`) at several pad counts. Each
row is one (part, configuration, footprint): CPU per drop, the ok rate, and the drops compared
pair by pair (:func:`feeder.bench.designs.paired_basins`) with the pieces, with the largest pad
count, and with the same footprint's drops started ``nudge_deg`` later (the footprint's own floor:
how far a drop moves when nothing but a hundredth of a degree changes). The raw final yaws and
statuses are kept (``--out-raw``), so a new statistic needs no rerun.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from multiprocessing import get_context

import numpy as np
import pandas as pd

from feeder.errors import FeederError

PIECES = "pieces"


def footprint_scene(scene: dict, footprint: str, pad_radius: float) -> dict:
    """The scene with ``scene.belt.footprint`` set to ``pieces`` or ``padsK``, walls and fences met
    through the convex pieces (the bench compares belt footprints alone; the outline needs pads)."""
    scene = copy.deepcopy(scene)
    scene["part"]["wall_contact"] = dict(scene["part"]["wall_contact"], model="pieces")
    if footprint == PIECES:
        scene["belt"]["footprint"] = {"model": "pieces", "pads": 1, "pad_radius": pad_radius}
    else:
        scene["belt"]["footprint"] = {"model": "pads", "pads": int(footprint[4:]), "pad_radius": pad_radius}
    return scene


def _run(job):
    part, parts_dir, config, footprint, shift, yaws, scene, preset = job
    from feeder.lane.fences import parse_location
    from feeder.parts.geometry import load_part
    from feeder.sim.drops import run_drops

    geom = load_part(f"{parts_dir}/{part}.stl")
    loc1, loc2 = config.split("|")
    start = time.process_time()
    out = run_drops(geom, parse_location(loc1), parse_location(loc2), yaws + shift, scene, preset)
    cpu = time.process_time() - start
    return part, config, footprint, shift, out["final_yaw_deg"], out["status"].astype(str), cpu


def summarize(raw: pd.DataFrame, pieces: dict[str, int], reference: str) -> pd.DataFrame:
    """One row per (part, configuration, footprint) from the raw drops (one row per drop: part,
    configuration, footprint, yaw_shift_deg, drop, final_yaw_deg, status, cpu_s of its run); the
    drops with a nonzero ``yaw_shift_deg`` are each footprint's nudged twins (the floor columns)."""
    from feeder.bench.designs import paired_basins

    rows = []
    for (part, config), group in raw.groupby(["part", "configuration"], sort=True):
        plain, nudged = group[group["yaw_shift_deg"] == 0], group[group["yaw_shift_deg"] != 0]
        runs = {fp: g.sort_values("drop") for fp, g in plain.groupby("footprint")}
        twins = {fp: g.sort_values("drop") for fp, g in nudged.groupby("footprint")}
        for fp, g in runs.items():
            row = {
                "part": part,
                "pieces": pieces[part],
                "configuration": config,
                "footprint": fp,
                "drops": len(g),
                "cpu_ms_per_drop": 1000.0 * float(g["cpu_s"].iloc[0]) / len(g),
                "ok_rate": float(np.mean(g["status"] == "ok")),
            }
            for name, other in (
                (PIECES, runs.get(PIECES)),
                ("reference", runs.get(reference)),
                ("nudged", twins.get(fp)),
            ):
                if other is None:
                    row[f"same_basin_vs_{name}"] = row[f"median_dyaw_vs_{name}_deg"] = np.nan
                    continue
                pair = paired_basins(g["final_yaw_deg"], g["status"], other["final_yaw_deg"], other["status"])
                row[f"same_basin_vs_{name}"] = pair["same_basin"]
                row[f"median_dyaw_vs_{name}_deg"] = pair["median_dyaw_deg"]
            rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-contact", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, parts} config sections")
    parser.add_argument(
        "--parts",
        help="comma-separated candidate part ids (default: every part in parts.dir); those with "
        "sim.contact_bench.min_pieces convex pieces or more are benched",
    )
    parser.add_argument("--out-csv", required=True)
    parser.add_argument("--out-raw", required=True, help="every drop (CSV): final yaw, status, CPU of its run")
    args = parser.parse_args(argv)
    from feeder.config import parse_settings

    cfg = parse_settings(args.settings, "scene", "sim", "parts")
    from feeder.sim.drops import drop_seed, get_preset, initial_yaws

    try:
        scene, sim_cfg, parts_dir = cfg["scene"], cfg["sim"], cfg["parts"]["dir"]
        bench, base_seed = sim_cfg["contact_bench"], int(sim_cfg["base_seed"])
        pad_radius = float(scene["belt"]["footprint"]["pad_radius"])
        preset = get_preset(sim_cfg["presets"], bench["preset"])
        min_pieces, drops, nudge = int(bench["min_pieces"]), int(bench["drops"]), float(bench["nudge_deg"])
        configurations, counts = list(bench["configurations"]), sorted({int(k) for k in bench["pads"]})
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    bad = [c for c in configurations if c.count("|") != 1]
    if bad:
        raise FeederError(f"sim.contact_bench.configurations: LOC1|LOC2 specs, got {bad}")
    from feeder.parts.geometry import load_part
    from feeder.parts.library import list_parts

    candidates = list_parts(parts_dir, [p for p in args.parts.split(",") if p] if args.parts else "all")
    pieces = {p: len(load_part(f"{parts_dir}/{p}.stl").convex_pieces) for p in candidates}
    parts = sorted(p for p, n in pieces.items() if n >= min_pieces)
    if not parts:
        raise FeederError(f"no part in {parts_dir} has {min_pieces} convex pieces or more")
    footprints = [PIECES] + [f"pads{k}" for k in counts]
    shifts = [0.0, nudge]
    jobs = []
    for part in parts:
        for config in configurations:
            yaws = initial_yaws(drop_seed(part, config, base_seed), drops)
            jobs += [
                (part, parts_dir, config, fp, shift, yaws, footprint_scene(scene, fp, pad_radius), preset)
                for fp in footprints
                for shift in shifts
            ]
    jobs.sort(key=lambda j: -pieces[j[0]])  # the dearest first
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    records = []
    with get_context("fork").Pool(max(1, int(bench["workers"]))) as pool:
        for part, config, fp, shift, final, status, cpu in pool.imap_unordered(_run, jobs):
            records += [
                {
                    "part": part,
                    "configuration": config,
                    "footprint": fp,
                    "yaw_shift_deg": shift,
                    "drop": i,
                    "final_yaw_deg": y,
                    "status": s,
                    "cpu_s": cpu,
                }
                for i, (y, s) in enumerate(zip(final, status))
            ]
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    keys = ["part", "configuration", "footprint", "yaw_shift_deg", "drop"]
    raw = pd.DataFrame(records).sort_values(keys, ignore_index=True)
    table = summarize(raw, pieces, footprints[-1])
    from feeder.io import write_csv

    write_csv(args.out_raw, raw)
    write_csv(args.out_csv, table)
    for fp, g in table.groupby("footprint", sort=False):
        print(
            f"{fp:>8}: {g['cpu_ms_per_drop'].mean():6.0f} ms/drop, same basin as pieces "
            f"{g['same_basin_vs_pieces'].mean():.2f}, as {footprints[-1]} {g['same_basin_vs_reference'].mean():.2f}, "
            f"as itself nudged {g['same_basin_vs_nudged'].mean():.2f} "
            f"(median {g['median_dyaw_vs_nudged_deg'].median():.2f} deg)",
            file=sys.stderr,
        )
    return 0
