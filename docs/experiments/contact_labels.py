"""Experiment (issue #19, 2026-11-24): do pads change the *labels* of many-piece parts more than
the study's own label noise does? Not part of the workflow; run from the repository root:

    .venv/bin/python docs/experiments/contact_labels.py > results/tables/contact_labels.csv

``feeder bench-contact`` compares footprints drop by drop and finds the pieces below their own
paired floor (92 % same basin under a 0.01° nudge), so the issue's paired goal cannot decide
between them. This compares what the study keeps, the label: for every one of the 59 protocol parts
with at least ``sim.contact_bench.min_pieces`` convex pieces, three parts with holes of the wider
library, and each
``sim.contact_bench.configurations`` entry, the study's adaptive label (``sim.drops`` budget,
``sim.adaptive``, ``fast``) under the pieces and under ``scene.belt.footprint.pads`` pads, each at
two seeded offsets (a, b). Rows: circular W1 and sup|ΔCDF| of pieces a-b and pads a-b (each
footprint's label noise at the study's budget) and of pieces against pads at the same offset;
ok masses and CPU. One CSV row per (part, configuration, comparison).
"""

from __future__ import annotations

import sys
import time
from fnmatch import fnmatch
from multiprocessing import get_context

import pandas as pd

from feeder.bench.contact import PIECES, footprint_scene
from feeder.config import load_study_config
from feeder.labels import metrics as L
from feeder.labels.pmf import sim_label
from feeder.lane.fences import parse_location
from feeder.parts.geometry import load_part
from feeder.parts.library import list_parts
from feeder.sim.drops import drop_seed, get_preset
from feeder.sim.record import SimRecord
from feeder.sim.simulate import simulate

CFG = load_study_config("config/config.yaml")
SEEDS = {"a": 0, "b": 1}  # base seeds of the two offsets
HOLED = ("holed-washer", "holed-plate-1", "holed-bracket-1")  # of the wider library, as bench-contact leaves it out


def label(job):
    part, config, footprint, tag = job
    scene = footprint_scene(CFG["scene"], footprint, float(CFG["scene"]["belt"]["footprint"]["pad_radius"]))
    sim = CFG["sim"]
    geom = load_part(f"{CFG['parts']['dir']}/{part}.stl")
    loc1, loc2 = config.split("|")
    start = time.process_time()
    res = simulate(
        geom,
        parse_location(loc1),
        parse_location(loc2),
        int(sim["drops"]),
        drop_seed(part, config, SEEDS[tag]),
        scene,
        get_preset(sim["presets"], "fast"),
        "fast",
        yaw_sampling="adaptive",
        adaptive=dict(sim["adaptive"]),
    )
    cpu = time.process_time() - start
    import json

    meta = json.loads(str(res["meta"]))
    status = res["status"].astype(str)
    rec = SimRecord(
        yaws=res["final_yaw_deg"], ok=status == "ok", meta=meta, initial=res["initial_yaw_deg"], status=status
    )
    lab = sim_label(rec, int(CFG["labels"]["bins"]), float(CFG["labels"]["sigma_bins"])) if rec.ok.any() else None
    return part, config, footprint, tag, lab, cpu, int(res["initial_yaw_deg"].size)


def main() -> pd.DataFrame:
    bench = CFG["sim"]["contact_bench"]
    parts_dir = CFG["parts"]["dir"]
    pieces = {p: len(load_part(f"{parts_dir}/{p}.stl").convex_pieces) for p in list_parts(parts_dir, "all")}
    wide = [p for p in pieces if any(fnmatch(p, pat) for pat in CFG["datasets"]["wide"]["parts"])]
    parts = sorted(p for p, n in pieces.items() if n >= int(bench["min_pieces"]) and (p not in wide or p in HOLED))
    pads = f"pads{int(CFG['scene']['belt']['footprint']['pads'])}"
    jobs = [(p, c, fp, t) for p in parts for c in bench["configurations"] for fp in (PIECES, pads) for t in SEEDS]
    jobs.sort(key=lambda j: -pieces[j[0]])
    out = {}
    with get_context("fork").Pool(2) as pool:
        for part, config, fp, tag, lab, cpu, sims in pool.imap_unordered(label, jobs):
            out[(part, config, fp, tag)] = (lab, cpu, sims)
            print(part, config, fp, tag, f"{cpu:.0f} s", file=sys.stderr, flush=True)
    rows = []
    pairs = {
        "pieces_a_b": ((PIECES, "a"), (PIECES, "b")),
        "pads_a_b": ((pads, "a"), (pads, "b")),
        "pieces_pads_a": ((PIECES, "a"), (pads, "a")),
        "pieces_pads_b": ((PIECES, "b"), (pads, "b")),
    }
    for part in parts:
        for config in bench["configurations"]:
            for name, (x, y) in pairs.items():
                (lx, cx, nx), (ly, cy, ny) = out[(part, config, *x)], out[(part, config, *y)]
                row = {
                    "part": part,
                    "pieces": pieces[part],
                    "configuration": config,
                    "comparison": name,
                    "ok_mass_x": lx.ok_mass if lx else 0.0,
                    "ok_mass_y": ly.ok_mass if ly else 0.0,
                    "cpu_s_x": cx,
                    "cpu_s_y": cy,
                    "simulations_x": nx,
                    "simulations_y": ny,
                }
                if lx is not None and ly is not None:
                    a, b = L.cdf(lx.pmf), L.cdf(ly.pmf)
                    row |= {"circular_w1_deg": float(L.circular_w1(a, b)), "sup_cdf": float(abs(a - b).max())}
                rows.append(row)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    main().to_csv(sys.stdout, index=False, float_format="%.6g")
