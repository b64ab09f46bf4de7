"""What one simulation step costs, and what it is spent on (``feeder bench-step``).

Two worlds with the study's engine settings (``sim.step_bench.preset``), per one-piece part of
``sim.step_bench.parts`` and configuration of ``sim.step_bench.configurations``:

- ``bare``: the part's bounding box at rest on a static box floor, nothing else (the floor of
  what a step can cost in pybullet with these settings);
- ``drop``: real drops of the study's scene (belt, walls, fences; :func:`feeder.sim.drops.run_lanes`),
  run twice: once as the study runs them, for the CPU per internal step with everything the
  Python loop does, and once with every ``stepSimulation`` call timed on its own and the part's
  contact points counted after it, for what Bullet alone costs and what it is spent on.

Each is repeated (``repeats``, seeded initial yaws), so every figure carries an interval across
repeats. The raw calls are kept (``--out-raw``), so a new statistic needs no rerun.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.sim.body import World

BARE, DROP = "bare", "drop"


def mean_interval(values, confidence: float = 0.95) -> tuple[float, float, float]:
    """``(mean, low, high)``: the mean of ``values`` and its two-sided Student-t interval at
    ``confidence`` (NaN bounds for a single value)."""
    from scipy import stats

    x = np.asarray(values, float)
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise FeederError("an interval needs one or more finite values")
    mean = float(x.mean())
    if x.size < 2:
        return mean, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + 0.5 * confidence, x.size - 1)) * float(x.std(ddof=1)) / math.sqrt(x.size)
    return mean, mean - half, mean + half


def contact_fit(us_per_step, contact_points) -> tuple[float, float]:
    """``(intercept_us, us_per_point)``: least-squares line of the CPU of one internal step against
    the part's contact points after it."""
    x, y = np.asarray(contact_points, float), np.asarray(us_per_step, float)
    if x.size < 2 or np.ptp(x) == 0:
        return math.nan, math.nan
    slope, intercept = np.polyfit(x, y, 1)
    return float(intercept), float(slope)


class TimedWorld(World):
    """The study's world with every ``stepSimulation`` call timed (CPU) and the contact points
    counted after it (outside the timed span): ``calls`` holds ``(cpu_s, contact_points)``."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.calls: list[tuple[float, int]] = []

    def step(self) -> None:
        start = time.process_time()
        self.pb.stepSimulation(physicsClientId=self.cid)
        cpu = time.process_time() - start
        self.calls.append((cpu, len(self.pb.getContactPoints(physicsClientId=self.cid))))


def _drop_world(geom, loc1, loc2, scene, preset, world_class):
    from feeder.sim.body import part_model
    from feeder.sim.drops import make_plan

    model = part_model(geom, scene, float(preset["merge_tolerance"]))
    plan = make_plan(scene, loc1, loc2, model, bool(preset["full_path"]))
    if not plan.fences:
        raise FeederError(f"{loc1}|{loc2}: no fence in reach, so a drop never steps the world")
    return world_class(scene, preset, plan, 1, model)


def drop_steps(geom, loc1, loc2, yaws, scene, preset) -> tuple[float, int, list[tuple[float, int]]]:
    """The drops of ``yaws`` run twice: ``(cpu_s, calls, timed)``, the CPU of the plain run (all
    of it, Python included) over its ``stepSimulation`` calls, and the instrumented run's
    ``(cpu_s, contact_points)`` per call. The two runs take the same steps (deterministic)."""
    from feeder.sim.drops import Probes, drop_limits, empty_results, run_lanes, slideways

    lim = drop_limits(scene, preset)
    runs = []
    for world_class in (World, TimedWorld):
        world = _drop_world(geom, loc1, loc2, scene, preset, world_class)
        count = [0]
        step = world.step

        def counted(step=step, count=count):
            count[0] += 1
            step()

        world.step = counted
        try:
            start = time.process_time()
            run_lanes(world, yaws, lim, slideways(world.plan.fences), Probes(None, None), empty_results(len(yaws)))
            runs.append((time.process_time() - start, count[0], getattr(world, "calls", None)))
        finally:
            world.close()
    (cpu, calls, _), (_, timed_calls, timed) = runs
    if calls != timed_calls:
        raise FeederError(f"the timed run took {timed_calls} steps, the plain one {calls}: not deterministic")
    return cpu, calls, timed


def bare_steps(geom, scene, preset, yaw_deg: float, calls: int, settle: int) -> list[tuple[float, int]]:
    """The part's bounding box (its principal frame, the part's mass and inertia) at rest on a
    static box floor with the preset's engine settings: ``(cpu_s, contact_points)`` per call,
    after ``settle`` calls."""
    from feeder.sim.body import connect_world, part_model, quiet_pybullet

    pb = quiet_pybullet()
    model = part_model(geom, scene, float(preset["merge_tolerance"]))
    lo, hi = model.hull.min(axis=0), model.hull.max(axis=0)
    c = connect_world(pb, scene, preset)
    try:
        span = float(np.max(hi - lo))
        floor = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[2 * span, 2 * span, 0.005], physicsClientId=c)
        pb.createMultiBody(0, floor, basePosition=[0, 0, -0.005], physicsClientId=c)
        half = [*(0.5 * (hi - lo)), 0.5 * model.thickness]
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=c)
        yaw = math.radians(yaw_deg)
        body = pb.createMultiBody(
            model.mass,
            shape,
            basePosition=[0, 0, half[2]],
            baseOrientation=[0, 0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)],
            physicsClientId=c,
        )
        pb.changeDynamics(body, -1, localInertiaDiagonal=list(model.inertia), physicsClientId=c)
        for _ in range(settle):
            pb.stepSimulation(physicsClientId=c)
        out = []
        for _ in range(calls):
            start = time.process_time()
            pb.stepSimulation(physicsClientId=c)
            cpu = time.process_time() - start
            out.append((cpu, len(pb.getContactPoints(physicsClientId=c))))
        return out
    finally:
        pb.disconnect(physicsClientId=c)


def summarize(raw: pd.DataFrame, repeats: pd.DataFrame, substeps: int, confidence: float = 0.95) -> pd.DataFrame:
    """One row per (part, configuration, world) with intervals across repeats.

    ``raw``: one row per timed ``stepSimulation`` call (part, configuration, world, repeat,
    cpu_s, contact_points). ``repeats``: one row per drop repeat (part, configuration, repeat,
    cpu_s, calls) of the plain run. Columns: ``us_per_step`` (CPU per internal step of Bullet
    alone, mean and interval across repeats), ``us_per_step_all`` (the plain run's, Python
    included; drops only), ``bullet_share`` (Bullet's share of the plain run), the mean contact
    points, and the fitted cost of a contact point."""
    rows = []
    for (part, config, world), group in raw.groupby(["part", "configuration", "world"], sort=True):
        per_rep = group.groupby("repeat")
        bullet_us = 1e6 * per_rep["cpu_s"].sum() / (per_rep.size() * substeps)
        mean, low, high = mean_interval(bullet_us.to_numpy(), confidence)
        intercept, slope = contact_fit(1e6 * group["cpu_s"] / substeps, group["contact_points"])
        row = {
            "part": part,
            "configuration": config,
            "world": world,
            "repeats": int(bullet_us.size),
            "calls": int(len(group)),
            "us_per_step": mean,
            "us_per_step_low": low,
            "us_per_step_high": high,
            "mean_contact_points": float(group["contact_points"].mean()),
            "us_at_no_contact": intercept,
            "us_per_contact_point": slope,
            "us_per_step_all": math.nan,
            "us_per_step_all_low": math.nan,
            "us_per_step_all_high": math.nan,
            "bullet_share": math.nan,
        }
        if world == DROP:
            plain = repeats[(repeats["part"] == part) & (repeats["configuration"] == config)].set_index("repeat")
            all_us = 1e6 * plain["cpu_s"] / (plain["calls"] * substeps)
            row["us_per_step_all"], row["us_per_step_all_low"], row["us_per_step_all_high"] = mean_interval(
                all_us.to_numpy(), confidence
            )
            row["bullet_share"] = float(per_rep["cpu_s"].sum().sum() / plain["cpu_s"].sum())
        rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-step", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, parts} config sections")
    parser.add_argument("--out-csv", required=True)
    parser.add_argument("--out-raw", required=True, help="every timed stepSimulation call (CSV)")
    args = parser.parse_args(argv)
    from feeder.config import parse_settings

    cfg = parse_settings(args.settings, "scene", "sim", "parts")
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import drop_seed, get_preset, initial_yaws

    try:
        scene, sim_cfg, parts_dir = cfg["scene"], cfg["sim"], cfg["parts"]["dir"]
        bench, base_seed = sim_cfg["step_bench"], int(sim_cfg["base_seed"])
        preset = get_preset(sim_cfg["presets"], bench["preset"])
        parts, configurations = list(bench["parts"]), list(bench["configurations"])
        drops, repeats = int(bench["drops"]), int(bench["repeats"])
        bare_calls, settle = int(bench["bare_calls"]), int(bench["settle_calls"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    bad = [c for c in configurations if c.count("|") != 1]
    if bad:
        raise FeederError(f"sim.step_bench.configurations: LOC1|LOC2 specs, got {bad}")
    from feeder.parts.geometry import load_part

    geoms = {p: load_part(f"{parts_dir}/{p}.stl") for p in parts}
    substeps = int(preset["substeps"])
    calls, plain = [], []
    total = len(parts) * repeats * (len(configurations) + 1)
    done = 0
    for part, geom in geoms.items():
        for rep in range(repeats):
            yaws = initial_yaws(drop_seed(part, f"step-bench-{rep}", base_seed), max(drops, 1))
            for k, (cpu, n) in enumerate(bare_steps(geom, scene, preset, float(yaws[0]), bare_calls, settle)):
                calls.append((part, "", BARE, rep, k, cpu, n))
            done += 1
            for config in configurations:
                loc1, loc2 = (parse_location(s) for s in config.split("|"))
                cpu, n_calls, timed = drop_steps(geom, loc1, loc2, yaws, scene, preset)
                plain.append({"part": part, "configuration": config, "repeat": rep, "cpu_s": cpu, "calls": n_calls})
                calls += [(part, config, DROP, rep, k, c, n) for k, (c, n) in enumerate(timed)]
                done += 1
            print(f"bench-step: {done}/{total} runs", file=sys.stderr, flush=True)
    columns = ["part", "configuration", "world", "repeat", "call", "cpu_s", "contact_points"]
    raw = pd.DataFrame(calls, columns=columns)
    repeats_table = pd.DataFrame(plain, columns=["part", "configuration", "repeat", "cpu_s", "calls"])
    table = summarize(raw, repeats_table, substeps)
    raw = raw.merge(
        repeats_table.rename(columns={"cpu_s": "run_cpu_s", "calls": "run_calls"}),
        on=["part", "configuration", "repeat"],
        how="left",
    )
    from feeder.io import write_csv

    write_csv(args.out_raw, raw)
    write_csv(args.out_csv, table)
    for _, row in table.iterrows():
        extra = (
            "" if row["world"] == BARE else f", all {row['us_per_step_all']:.1f} us, Bullet {row['bullet_share']:.0%}"
        )
        print(
            f"{row['part']:>10} {row['configuration'] or '-':>22} {row['world']:>4}: "
            f"{row['us_per_step']:.1f} us [{row['us_per_step_low']:.1f}, {row['us_per_step_high']:.1f}] "
            f"per internal step, {row['mean_contact_points']:.1f} contact points{extra}",
            file=sys.stderr,
        )
    return 0
