"""The dense reference of the design bench (``feeder bench-reference``): one file per configuration.

A configuration's reference samples its drop map on an evenly spaced grid of
``sim.design_bench.reference_yaws`` initial yaws per full turn (0.125° apart at 2,880), over one
period of the part's rotational symmetry, and simulates ``paired_drops`` independent initial yaws
for real, so that the map can be checked drop by drop against the simulator
(:mod:`feeder.bench.designs`). The configurations are the simulation bench's panel
(``sim.bench.panel``, shape specs) and ``sim.design_bench.library`` (part ids). This module needs
only the simulator: a change to how designs are refined or labelled reruns no reference.

A reference of a many-piece part takes hours (crescent-a: 2,880 drops of ~2.4 s), longer than a
session may last, so a run saves its progress every ``CHECKPOINT_DROPS`` drops beside its output
(``<out>.partial.npz``, removed when the output is written) and a rerun of the same job goes on
from there with the same result (:func:`run_resumable`).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
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
    return keyed_entries(out, "sim.design_bench")


def keyed_entries(entries: list[dict], where: str) -> list[dict]:
    """``entries`` (``kind``, ``part``, ``loc1``, ``loc2``) each with its file-safe ``key``
    (:func:`entry_key`); a configuration listed twice is a FeederError naming ``where``."""
    for e in entries:
        e["key"] = entry_key(e)
    keys = [e["key"] for e in entries]
    if len(set(keys)) != len(keys):
        raise FeederError(f"{where}: a configuration is listed twice")
    return entries


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


CHECKPOINT_DROPS = 64  # reference drops between two checkpoints (a few minutes of the dearest part)


def checkpoint_path(out: Path) -> Path:
    """Where a reference run keeps its progress: beside its output, removed once it is written."""
    out = Path(out)
    return out.with_name(out.name + ".partial.npz")


def run_resumable(run_chunk, yaws, checkpoint: Path | None, fingerprint: str, every: int = CHECKPOINT_DROPS, log=None):
    """Simulate ``yaws`` in consecutive chunks of ``every`` with ``run_chunk(yaws) -> (final,
    status)``, saving the results so far to ``checkpoint`` (atomically) after each chunk. A run
    that finds a checkpoint with the same ``fingerprint`` (what the run depends on) goes on from
    where it stopped; one with another fingerprint is ignored and overwritten. Drops in worlds
    of their own depend on their yaw alone, so a resumed run equals an uninterrupted one.
    Returns ``(final, status, cpu_s)``, the CPU seconds summed over every run that contributed.
    ``log(done, total)`` is called after each chunk."""
    from feeder.io import read_npz, write_npz

    yaws = np.asarray(yaws, dtype=np.float64)
    final, status, cpu, done = np.full(yaws.size, np.nan), np.full(yaws.size, "", dtype="<U16"), 0.0, 0
    if checkpoint is not None and Path(checkpoint).is_file():
        try:
            saved = read_npz(checkpoint, ("fingerprint", "done", "final", "status", "cpu_s"), "checkpoint")
        except FeederError:  # unreadable: start over (it is rewritten after the first chunk)
            saved = {"fingerprint": np.array("")}
        if str(saved["fingerprint"]) == fingerprint:
            done = int(saved["done"])
            final[:done], status[:done], cpu = saved["final"], saved["status"], float(saved["cpu_s"])
    while done < yaws.size:
        c0 = time.process_time()
        f, st = run_chunk(yaws[done : done + every])
        cpu += time.process_time() - c0
        final[done : done + len(f)], status[done : done + len(f)] = f, st
        done += len(f)
        if checkpoint is not None and done < yaws.size:
            write_npz(
                checkpoint,
                fingerprint=np.array(fingerprint),
                done=np.int64(done),
                final=final[:done],
                status=status[:done],
                cpu_s=np.float64(cpu),
            )
        if log is not None:
            log(done, yaws.size)
    return final, status, cpu


def entry_by_key(settings: dict, key: str) -> dict:
    entry = {e["key"]: e for e in entries(settings)}.get(key)
    if entry is None:
        raise FeederError(f"no configuration {key!r} in the design bench (feeder bench-reference list)")
    return entry


def run_reference(entry: dict, settings: dict, checkpoint: Path | None = None) -> dict:
    """One configuration's reference over one symmetry period and its paired drops: the arrays
    of its reference file (docs/data.md). With ``checkpoint``, progress is saved there and a
    killed run goes on from it (:func:`run_resumable`); progress is logged to stderr."""
    from feeder.lane.fences import parse_location
    from feeder.parts.symmetry import rotational_order
    from feeder.sim.drops import get_preset, run_each

    db, scene = settings["sim"]["design_bench"], settings["scene"]
    preset = get_preset(settings["sim"]["presets"], db["preset"])
    geom = entry_geometry(entry, settings)
    loc1, loc2 = parse_location(entry["loc1"]), parse_location(entry["loc2"])
    order = rotational_order(geom.outline, holes=geom.holes)
    yaws, period, offset = reference_grid(order, int(db["reference_yaws"]), seed_of(entry["key"], "reference"))

    def run_chunk(chunk):  # a world each: the map of the yaw alone
        res = run_each(geom, loc1, loc2, chunk, scene, preset)
        return res["final_yaw_deg"], res["status"].astype(str)

    fingerprint = json.dumps({"entry": entry, "preset": preset, "scene": scene, "yaws": yaws.tolist()}, sort_keys=True)
    final, status, cpu = run_resumable(
        run_chunk,
        yaws,
        checkpoint,
        hashlib.sha256(fingerprint.encode()).hexdigest(),
        log=lambda done, total: print(f"{entry['key']}: {done}/{total} reference drops", file=sys.stderr, flush=True),
    )
    beta = np.random.default_rng(seed_of(entry["key"], "paired")).uniform(0.0, 360.0, int(db["paired_drops"]))
    real = run_each(geom, loc1, loc2, beta, scene, preset)
    meta = {"entry": entry, "symmetry_order": order, "period_deg": period, "offset_deg": offset, "preset": db["preset"]}
    return {
        "ref_initial": yaws,
        "ref_final": final,
        "ref_status": status,
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
    checkpoint = checkpoint_path(args.out)
    write_npz(args.out, **run_reference(entry_by_key(settings, args.key), settings, checkpoint))
    checkpoint.unlink(missing_ok=True)
    return 0
