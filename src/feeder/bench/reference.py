"""The dense reference of the design bench (``feeder bench-reference``): one file per configuration.

A configuration's reference samples its drop map on an evenly spaced grid of
``sim.design_bench.reference_yaws`` initial yaws per full turn (0.125° apart at 2,880), over one
period of the part's rotational symmetry, and simulates ``paired_drops`` independent initial yaws
for real, so that the map can be checked drop by drop against the simulator
(:mod:`feeder.bench.designs`). The configurations are the simulation bench's panel
(``sim.bench.panel``, shape specs) and ``sim.design_bench.library`` (part ids). This module needs
only the simulator: a change to how designs are refined or labelled reruns no reference.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import time
from pathlib import Path

import numpy as np

from feeder.errors import FeederError


def entries(settings: dict) -> list[dict]:
    """The bench's configurations: the simulation bench's panel (shape specs) and
    ``sim.design_bench.library`` (part ids of ``parts.dir``), each with a file-safe key."""
    sim = settings["sim"]
    out = [{"kind": "shape", "part": e[0], "loc1": e[1], "loc2": e[2]} for e in sim["bench"]["panel"]]
    out += [{"kind": "part", "part": e[0], "loc1": e[1], "loc2": e[2]} for e in sim["design_bench"]["library"]]
    for e in out:
        e["key"] = entry_key(e)
    keys = [e["key"] for e in out]
    if len(set(keys)) != len(keys):
        raise FeederError("sim.design_bench: a configuration is listed twice")
    return out


def entry_key(entry: dict) -> str:
    """``rect-40x20__straight45_none``: part and fence configuration, file-safe."""
    fences = "_".join(str(entry[k]).replace(":", "") for k in ("loc1", "loc2"))
    return re.sub(r"[^A-Za-z0-9._-]", "-", f"{entry['part']}__{fences}")


def entry_geometry(entry: dict, settings: dict):
    if entry["kind"] == "shape":
        from feeder.parts.shapes import shape_part

        return shape_part(entry["part"], float(settings["sim"]["bench"]["thickness"]))
    from feeder.parts.geometry import load_part

    path = Path(settings["parts"]["dir"]) / f"{entry['part']}.stl"
    if not path.is_file():
        raise FeederError(f"sim.design_bench.library: part file {path} not found")
    return load_part(path)


def seed_of(*tokens) -> int:
    return int.from_bytes(hashlib.sha256("|".join(map(str, tokens)).encode()).digest()[:8], "little")


# ----------------------------------------------------------------------------------------------
# One configuration (simulation)
# ----------------------------------------------------------------------------------------------
def reference_grid(order: int, reference_yaws: int, seed: int) -> tuple[np.ndarray, float, float]:
    """Initial yaws of the reference over one symmetry period: ``reference_yaws / order`` evenly
    spaced yaws with a seeded offset. Returns (yaws, period, offset)."""
    period = 360.0 / order
    n = max(2, int(round(reference_yaws / order)))
    offset = float(np.random.default_rng(seed).uniform(0.0, period / n))
    return offset + period * np.arange(n) / n, period, offset


def entry_by_key(settings: dict, key: str) -> dict:
    entry = {e["key"]: e for e in entries(settings)}.get(key)
    if entry is None:
        raise FeederError(f"no configuration {key!r} in the design bench (feeder bench-reference list)")
    return entry


def run_reference(entry: dict, settings: dict) -> dict:
    """One configuration's reference over one symmetry period and its paired drops: the arrays
    of its reference file (docs/data.md)."""
    from feeder.parts.symmetry import rotational_order
    from feeder.sim.drops import get_preset, run_each
    from feeder.sim.fences import parse_location

    db, scene = settings["sim"]["design_bench"], settings["scene"]
    preset = get_preset(settings["sim"]["presets"], db["preset"])
    geom = entry_geometry(entry, settings)
    loc1, loc2 = parse_location(entry["loc1"]), parse_location(entry["loc2"])
    order = rotational_order(geom.outline)
    yaws, period, offset = reference_grid(order, int(db["reference_yaws"]), seed_of(entry["key"], "reference"))
    c0 = time.process_time()
    ref = run_each(geom, loc1, loc2, yaws, scene, preset)  # a world each: the map of the yaw alone
    cpu = time.process_time() - c0
    beta = np.random.default_rng(seed_of(entry["key"], "paired")).uniform(0.0, 360.0, int(db["paired_drops"]))
    real = run_each(geom, loc1, loc2, beta, scene, preset)
    meta = {"entry": entry, "symmetry_order": order, "period_deg": period, "offset_deg": offset, "preset": db["preset"]}
    return {
        "ref_initial": yaws,
        "ref_final": ref["final_yaw_deg"],
        "ref_status": ref["status"].astype(str),
        "ref_cpu_s": np.float64(cpu),
        "paired_initial": beta,
        "paired_final": real["final_yaw_deg"],
        "paired_status": real["status"].astype(str),
        "meta": np.array(json.dumps(meta, sort_keys=True)),
    }


def main(argv: list[str]) -> int:
    from feeder.config import add_settings_options, study_settings
    from feeder.io import write_npz

    parser = argparse.ArgumentParser(prog="feeder bench-reference", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    add_settings_options(sub.add_parser("list", help="the configuration keys"))
    run = add_settings_options(sub.add_parser("run", help="simulate one configuration's reference"))
    run.add_argument("--key", required=True, help="configuration key (feeder bench-reference list)")
    run.add_argument("--out", required=True, type=Path)
    args = parser.parse_args(argv)
    settings = study_settings(args)
    if args.cmd == "list":
        print("\n".join(e["key"] for e in entries(settings)))
        return 0
    write_npz(args.out, **run_reference(entry_by_key(settings, args.key), settings))
    return 0
