"""How far do the labels move with the physics? (``feeder bench-physics``).

Issue #37, item 3. On every configuration of ``sim.physics_bench.configurations`` (a part id and
a ``LOC1|LOC2`` fence scene) the same drops run under the default scene (``scene``, preset
``sim.physics_bench.preset``: the **baseline**) and under each **factor**, one factor moved at a
time. A factor is data (``sim.physics_bench.factors``): a ``name``, a ``path`` and either a
``scale`` (the default value times it) or a ``value`` (set). Paths:

* ``scene.<key>...``: any number of the scene, e.g. ``scene.part.friction`` (Bullet multiplies
  coefficients: part–belt friction is part × belt, part–fence part × fence), ``scene.belt.speed``,
  ``scene.restitution``, ``scene.part.density`` (the mass alone);
* ``preset.<key>``: a number of the preset, e.g. ``preset.substeps`` scaled by 2 halves the step
  at the same ``time_step`` (an integer key must stay an integer);
* ``part.thickness``: the part's thickness (:func:`dataclasses.replace` on the loaded part; the mass
  follows), checked against the scene (:func:`feeder.sim.body.check_fit`) before anything runs;
* ``contact_model``: a ``value`` naming a contact model of
  :func:`feeder.bench.decomposition.model_scene` (``pieces``, ``padsK``, either ``+outline``).

Every run of a configuration starts drop ``i`` from the same initial yaw (offset ``a`` of the
``sampling`` design, seeded from the part, the configuration and ``seed``), one drop per world
(:func:`feeder.sim.drops.run_each`), the preset as it is (its own ``merge_tolerance``), so drop
``i`` of two runs is paired. The label's **noise floor** is the baseline twice more: every initial
yaw ``nudge_deg`` later (paired: same-basin fraction, median |Δ final yaw|) and at a second seeded
offset of the design, ``b`` (seed + ``offset_b_seed``; the label: sup|ΔCDF|, circular W1).

This command simulates and writes the raw drops (``--out-raw``, one row per drop), which are kept;
``feeder bench-physics-table`` (:mod:`feeder.bench.physics_table`) makes the table from them.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import numbers
import sys
import time
from multiprocessing import get_context

import numpy as np
import pandas as pd

from feeder.errors import FeederError

BASELINE = "baseline"
CONTACT_MODEL = "contact_model"
PART_FIELDS = ("thickness",)  # part.<field>: the geometry's numbers a factor may scale
RAW_KEYS = ["part", "configuration", "factor", "offset", "yaw_shift_deg", "drop"]


# ----------------------------------------------------------------------------------------------
# Factors (pure)
# ----------------------------------------------------------------------------------------------
def factor_level(factor: dict) -> str:
    """How a factor moves its parameter, as text: ``x0.8`` (scale) or ``=0.1`` (value)."""
    return f"x{factor['scale']:g}" if "scale" in factor else f"={factor['value']}"


def _moved(old, factor: dict, what: str):
    """The new value of a number ``old`` under ``factor`` (scale or value)."""
    if isinstance(old, bool) or not isinstance(old, numbers.Real):
        raise FeederError(f"factor {factor['name']!r}: {what} is {old!r}, not a number")
    if "scale" in factor:
        new = float(old) * float(factor["scale"])
    else:
        value = factor["value"]
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise FeederError(f"factor {factor['name']!r}: value {value!r} of {what} is not a number")
        new = float(value)
    if isinstance(old, numbers.Integral):
        if abs(new - round(new)) > 1e-9:
            raise FeederError(f"factor {factor['name']!r}: {what} is an integer, {new:g} is not")
        return int(round(new))
    return new


def check_factor(factor) -> dict:
    """A factor's shape: a mapping with a ``name``, a ``path`` and exactly one of ``scale`` (a
    positive number) and ``value``; a one-line FeederError otherwise. Returns the factor."""
    if not isinstance(factor, dict) or not isinstance(factor.get("name"), str) or not factor.get("name"):
        raise FeederError(f"factor {factor!r}: needs a name, a path and a scale or a value")
    name, path = factor["name"], factor.get("path")
    if name == BASELINE:
        raise FeederError(f"factor {name!r}: the name is the unmoved scene's")
    if not isinstance(path, str) or not path:
        raise FeederError(
            f"factor {name!r}: needs a path (scene.<key>, preset.<key>, part.thickness or {CONTACT_MODEL})"
        )
    if ("scale" in factor) == ("value" in factor):
        raise FeederError(f"factor {name!r}: give a scale or a value, not {'both' if 'scale' in factor else 'neither'}")
    if "scale" in factor:
        scale = factor["scale"]
        if isinstance(scale, bool) or not isinstance(scale, numbers.Real) or not math.isfinite(scale) or scale <= 0:
            raise FeederError(f"factor {name!r}: scale must be a positive number, got {scale!r}")
    head = path.split(".")[0]
    if path == CONTACT_MODEL:
        if not isinstance(factor.get("value"), str):
            raise FeederError(f"factor {name!r}: {CONTACT_MODEL} takes a value naming a contact model")
    elif head not in ("scene", "preset", "part") or "." not in path:
        raise FeederError(
            f"factor {name!r}: unknown path {path!r} (scene.<key>, preset.<key>, part.thickness or {CONTACT_MODEL})"
        )
    elif head == "part" and path[5:] not in PART_FIELDS:
        raise FeederError(
            f"factor {name!r}: unknown path {path!r} (the part's: {', '.join('part.' + f for f in PART_FIELDS)})"
        )
    return factor


def apply_factor(factor: dict, geom, scene: dict, preset: dict):
    """``(geom, scene, preset)`` with ``factor`` applied (copies; the arguments are not changed).
    An unknown key, a value that is not a number or an integer key scaled to a fraction is a
    one-line FeederError."""
    from feeder.bench.decomposition import model_scene

    check_factor(factor)
    path = factor["path"]
    if path == CONTACT_MODEL:
        return geom, model_scene(scene, factor["value"]), dict(preset)
    head, *keys = path.split(".")
    if head == "part":
        return dataclasses.replace(geom, **{keys[0]: _moved(getattr(geom, keys[0]), factor, path)}), scene, dict(preset)
    root = copy.deepcopy(scene) if head == "scene" else dict(preset)
    node = root
    for k in keys[:-1]:
        if not isinstance(node, dict) or not isinstance(node.get(k), dict):
            raise FeederError(f"factor {factor['name']!r}: unknown path {path!r}")
        node = node[k]
    if not isinstance(node, dict) or keys[-1] not in node:
        raise FeederError(f"factor {factor['name']!r}: unknown path {path!r}")
    node[keys[-1]] = _moved(node[keys[-1]], factor, path)
    return (geom, root, dict(preset)) if head == "scene" else (geom, scene, root)


def check_factors(factors, parts: dict, scene: dict, preset: dict) -> None:
    """Every factor applies to every part (``parts``: id -> geometry) and the part it gives still
    fits the scene (:func:`feeder.sim.body.check_fit`); names are unique. FeederError otherwise."""
    from feeder.sim.body import check_fit

    if not isinstance(factors, list) or not factors:
        raise FeederError("sim.physics_bench.factors: a list of at least one factor")
    names = [check_factor(f)["name"] for f in factors]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise FeederError(f"factors named twice: {', '.join(twice)}")
    for f in factors:
        for part, geom in parts.items():
            g, s, _ = apply_factor(f, geom, scene, preset)
            check_fit(part, g.outline, g.centroid, g.thickness, s)


# ----------------------------------------------------------------------------------------------
# Runs (simulation)
# ----------------------------------------------------------------------------------------------
def parse_configurations(entries) -> list[tuple[str, str]]:
    """``[[part, "LOC1|LOC2"], ...]`` as tuples, each fence spec parsed (FeederError otherwise)."""
    from feeder.lane.fences import parse_location

    out = []
    for e in entries:
        if not (isinstance(e, (list, tuple)) and len(e) == 2 and all(isinstance(x, str) for x in e)) or "|" not in e[1]:
            raise FeederError(f"configuration {e!r}: [part id, 'LOC1|LOC2']")
        loc1, loc2 = e[1].split("|", 1)
        parse_location(loc1), parse_location(loc2)
        out.append((e[0], e[1]))
    if len(set(out)) != len(out):
        raise FeederError("sim.physics_bench.configurations: a configuration is listed twice")
    return out


def plan_runs(bench: dict) -> list[dict]:
    """Every run of the bench: per configuration the baseline at offset ``a``, nudged by
    ``nudge_deg`` and at offset ``b``, then each factor at offset ``a``."""
    from feeder.sim.drops import drop_seed, initial_yaws

    drops, sampling, nudge, seed = (
        int(bench["drops"]),
        str(bench["sampling"]),
        float(bench["nudge_deg"]),
        int(bench["seed"]),
    )
    runs = []
    for part, config in parse_configurations(bench["configurations"]):
        yaws = {
            tag: initial_yaws(drop_seed(part, config, seed + offset), drops, sampling)
            for tag, offset in (("a", 0), ("b", int(bench["offset_b_seed"])))
        }
        plan = [(None, "a", 0.0), (None, "a", nudge), (None, "b", 0.0)] + [(f, "a", 0.0) for f in bench["factors"]]
        runs += [
            {
                "part": part,
                "configuration": config,
                "factor": BASELINE if f is None else f["name"],
                "path": "" if f is None else f["path"],
                "level": "" if f is None else factor_level(f),
                "offset": tag,
                "yaw_shift_deg": shift,
                "yaws": yaws[tag] + shift,
                "spec": f,
            }
            for f, tag, shift in plan
        ]
    return runs


def run_one(geom, config: str, yaws, scene: dict, preset: dict) -> dict:
    """The drops of one run, one drop per world: final yaws, statuses, process CPU seconds."""
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import run_each

    loc1, loc2 = config.split("|")
    start = time.process_time()
    out = run_each(geom, parse_location(loc1), parse_location(loc2), np.asarray(yaws, np.float64), scene, preset)
    cpu = time.process_time() - start
    return {"final_yaw_deg": out["final_yaw_deg"], "status": out["status"].astype(str), "cpu_s": cpu}


def _job(job):
    run, parts_dir, scene, preset = job
    from feeder.parts.geometry import load_part

    geom = load_part(f"{parts_dir}/{run['part']}.stl")
    if run["spec"] is not None:
        geom, scene, preset = apply_factor(run["spec"], geom, scene, preset)
    return run, run_one(geom, run["configuration"], run["yaws"], scene, preset)


def run_cost_weight(run: dict) -> float:
    """A run's expected cost relative to a baseline run (dearest first): the step factor's substeps."""
    spec = run["spec"]
    if spec is not None and spec["path"] == "preset.substeps" and "scale" in spec:
        return float(spec["scale"])
    return 1.0


def simulate_all(bench, parts_dir, scene, preset, workers) -> pd.DataFrame:
    """Every run of :func:`plan_runs` (``workers`` processes): the raw drops."""
    runs = plan_runs(bench)
    jobs = [(run, parts_dir, copy.deepcopy(scene), dict(preset)) for run in runs]
    jobs.sort(key=lambda j: -run_cost_weight(j[0]))
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), unit="run", file=sys.stderr)
    records = []
    with get_context("fork").Pool(workers) as pool:
        for run, out in pool.imap_unordered(_job, jobs):
            keys = {k: v for k, v in run.items() if k not in ("yaws", "spec")}
            records += [
                keys
                | {
                    "drop": i,
                    "initial_yaw_deg": float(y0),
                    "final_yaw_deg": float(y),
                    "status": s,
                    "cpu_s": out["cpu_s"],
                }
                for i, (y0, y, s) in enumerate(zip(run["yaws"], out["final_yaw_deg"], out["status"]))
            ]
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    return pd.DataFrame(records).sort_values(RAW_KEYS, ignore_index=True)


def check_bench(bench: dict, parts_dir: str, scene: dict, preset: dict) -> None:
    """Everything the bench needs, before anything runs: the configurations, every part file,
    every factor on every part (FeederError otherwise)."""
    from feeder.parts.geometry import load_part

    configs = parse_configurations(bench["configurations"])
    if not configs:
        raise FeederError("sim.physics_bench.configurations: at least one")
    if int(bench["drops"]) < 1:
        raise FeederError(f"sim.physics_bench.drops must be positive, got {bench['drops']!r}")
    if float(bench["nudge_deg"]) <= 0:
        raise FeederError(f"sim.physics_bench.nudge_deg must be positive, got {bench['nudge_deg']!r}")
    parts = {p: load_part(f"{parts_dir}/{p}.stl") for p in sorted({p for p, _ in configs})}
    check_factors(bench["factors"], parts, scene, preset)


# ----------------------------------------------------------------------------------------------
# Command
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-physics", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, parts} config sections")
    parser.add_argument(
        "--out-raw", required=True, help="every drop (CSV): factor, initial and final yaw, status, CPU of its run"
    )
    args = parser.parse_args(argv)
    from feeder.config import parse_settings
    from feeder.io import write_csv
    from feeder.sim.drops import get_preset

    cfg = parse_settings(args.settings, "scene", "sim", "parts")
    try:
        scene, sim_cfg, parts_dir = cfg["scene"], cfg["sim"], cfg["parts"]["dir"]
        bench = sim_cfg["physics_bench"]
        preset = get_preset(sim_cfg["presets"], bench["preset"])
        workers = max(1, int(bench["workers"]))
        check_bench(bench, parts_dir, scene, preset)
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    raw = simulate_all(bench, parts_dir, scene, preset, workers)
    write_csv(args.out_raw, raw)
    cpu = raw.groupby(["part", "configuration", "factor", "offset", "yaw_shift_deg"])["cpu_s"].first().sum()
    print(f"feeder bench-physics: {len(raw)} drops, {cpu / 60:.1f} CPU min, {args.out_raw}", file=sys.stderr)
    return 0
