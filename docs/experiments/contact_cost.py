"""Check (issue #37 item 2, 2026-11-25): what does a contact model cost per drop over the whole
library? Not part of the workflow. From the repository root:

    .venv/bin/python docs/experiments/contact_cost.py OUT.csv [DROPS] [MODEL ...]

Every part of ``parts/catalog.csv`` under each contact model (names as in
``feeder bench-decomposition``: ``pieces``, ``padsK``, ``padsK+outline``; ``MODEL@PRESET`` runs it at
another preset of the config, e.g. ``pads16+outline@fast1ms``), on one one-fence and one two-fence
configuration, ``DROPS`` evenly spaced initial yaws each (default 2), the ``fast`` preset unless
named, one drop per world. Writes one row per part, configuration and model:
the process CPU seconds per drop and the statuses. Two worker processes; the CPU is the worker's
own (``time.process_time``), so a busy machine changes it less than the wall time.
"""

from __future__ import annotations

import sys
import time
from multiprocessing import get_context

import numpy as np
import pandas as pd

CONFIGURATIONS = ("straight:30|none", "straight:45|curved:40")
DEFAULT_MODELS = ("pieces", "pads8+outline", "pads16+outline")


def _job(job):
    part, config, model, drops = job
    model_name, _, preset_name = model.partition("@")
    from feeder.bench.decomposition import model_scene
    from feeder.config import load_study_config
    from feeder.lane.fences import parse_location
    from feeder.parts.geometry import load_part
    from feeder.sim.drops import get_preset, run_each

    cfg = load_study_config("config/config.yaml")
    preset = get_preset(cfg["sim"]["presets"], preset_name or "fast")
    scene = model_scene(cfg["scene"], model_name)
    geom = load_part(f"parts/{part}.stl")
    yaws = np.linspace(0.0, 360.0, drops, endpoint=False) + 7.0
    loc1, loc2 = config.split("|")
    start = time.process_time()
    out = run_each(geom, parse_location(loc1), parse_location(loc2), yaws, scene, preset)
    cpu = time.process_time() - start
    status = pd.Series(out["status"].astype(str)).value_counts().to_dict()
    return {
        "part": part,
        "configuration": config,
        "model": model,
        "pieces": len(geom.convex_pieces),
        "outline_vertices": len(geom.outline),
        "drops": drops,
        "cpu_ms_per_drop": 1000.0 * cpu / drops,
        "statuses": " ".join(f"{k} {v}" for k, v in sorted(status.items())),
    }


def main(argv: list[str]) -> int:
    out = argv[0]
    drops = int(argv[1]) if len(argv) > 1 else 2
    models = tuple(argv[2:]) or DEFAULT_MODELS
    parts = pd.read_csv("parts/catalog.csv")["id"].tolist()
    jobs = [(p, c, m, drops) for p in parts for c in CONFIGURATIONS for m in models]
    with get_context("fork").Pool(2) as pool:
        rows = list(pool.imap_unordered(_job, jobs))
    table = pd.DataFrame(rows).sort_values(["part", "configuration", "model"], ignore_index=True)
    table.to_csv(out, index=False)
    print(table.groupby("model")["cpu_ms_per_drop"].describe().to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
