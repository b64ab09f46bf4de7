"""Experiment (issue #38 item 3, 2026-11-27): can a two-fence drop be finished from the state in which it
leaves the upstream fence, in a world that holds the downstream fence alone?

If it can, one set of upstream outcomes serves every configuration that shares the part and its
upstream fence (Location 2), and the downstream fence is simulated from those exit states: the reuse
or composition of issue #38. Not part of the workflow. From the repository root:

    .venv/bin/python docs/experiments/exit_state_continuation.py OUT_RAW.csv [N] [SEED] [DROPS]
    .venv/bin/python docs/experiments/exit_state_continuation.py --summary OUT_RAW.csv

Draws a seeded sample of N (default 40) of the default study's two-fence configurations
(config/config.yaml, :func:`feeder.labels.grid.configurations`) and runs, per configuration, DROPS
(default 16) evenly spaced initial yaws with a seeded offset, one world per drop, the study's preset
and scene:

* ``end2end``: the drops as the study simulates them. At every free-transport shortcut (a part
  resting on the belt with a fence ahead is moved to just before it: ``feeder.sim.drops.arrived``)
  the part's pose is recorded; the last such move of a drop is its hand-over to the downstream fence.
* ``nudge``: the same drops from initial yaws 0.01 deg later (the paired floor).
* ``offset_b``: another seeded offset (the label floor: two end-to-end labels of the same design).
* ``continued``: each drop that was handed over, restarted from its recorded pose (position and full
  orientation, moving with the belt, as the shortcut leaves it) in a new world built for the
  downstream fence alone (``LOC1|none``, built whether or not a centred part's lane reaches it);
  a drop that ended before any hand-over keeps its end-to-end outcome (its upstream result is all
  there is). Its ``handed_over`` column says which.

Writes one raw row per drop and run; ``--summary`` prints, per configuration and pooled, the paired
comparison of ``continued`` and ``nudge`` against ``end2end`` (same-basin fraction, median |dyaw|;
feeder.bench.designs.paired_basins) and of ``continued`` and ``offset_b`` labels against ``end2end``
(sup|dCDF|, circular W1), and the CPU of the downstream part against the whole drop.
"""

from __future__ import annotations

import random
import sys
import time
from collections import deque
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[2]
NUDGE_DEG = 0.01


def _study():
    from feeder.labels.grid import configurations
    from feeder.parts.library import list_parts

    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    table = configurations(cfg, list_parts(str(ROOT / "parts"), "all", []))
    return cfg, table


def _runner(cfg):
    import feeder.sim.drops as D
    from feeder.lane.settings import load_settings

    scene, presets = load_settings(None)
    preset = D.get_preset(presets, cfg["sim"]["preset"])
    return D, scene, preset


def run_end2end(D, geom, loc1, loc2, yaws, scene, preset):
    """Every drop in its own world; per drop: final yaw, status, the pose after its last hand-over
    (or None) and the CPU seconds of the drop and of its part after the hand-over."""
    orig = D.arrived
    handover = {}

    def arrived(world, ln, s, lim):
        moves = ln.teleports
        done = orig(world, ln, s, lim)
        if ln.teleports > moves:
            pos, q, _, _ = world.part_motion(ln.body)
            handover["pose"] = (tuple(pos), tuple(q))
            handover["cpu"] = time.process_time()
        return done

    D.arrived = arrived
    rows = []
    try:
        for yaw in yaws:
            handover.clear()
            c0 = time.process_time()
            out = D.run_each(geom, loc1, loc2, np.array([yaw]), scene, preset)
            c1 = time.process_time()
            rows.append(
                {
                    "final_yaw_deg": float(out["final_yaw_deg"][0]),
                    "status": str(out["status"][0]),
                    "pose": handover.get("pose"),
                    "cpu_s": c1 - c0,
                    "downstream_cpu_s": (c1 - handover["cpu"]) if "cpu" in handover else 0.0,
                }
            )
    finally:
        D.arrived = orig
    return rows


def run_continued(D, geom, loc1, pose, scene, preset):
    """One drop restarted from ``pose`` in a world with the downstream fence alone."""
    from feeder.lane.fences import parse_location

    setup = D.prepare_drops(geom, loc1, parse_location("none"), scene, preset, prune=False)
    orig = D.start_drop

    def start_at(world, lane, queue, yaws0, t, lim):
        i = queue.popleft()
        world.reset_belt(lane)
        pos, q = pose
        body = world.add_part(lane, pos[0] - world.lane_x[lane], pos[1], 0.0)
        world.pb.resetBasePositionAndOrientation(body, pos, q, physicsClientId=world.cid)
        world.pb.resetBaseVelocity(body, world.belt_vel, [0.0, 0.0, 0.0], physicsClientId=world.cid)
        return D._Lane(i, body, t, deque())

    D.start_drop = start_at
    try:
        c0 = time.process_time()
        out = D.drops_in_world(setup, np.array([0.0]))
        cpu = time.process_time() - c0
    finally:
        D.start_drop = orig
    return float(out["final_yaw_deg"][0]), str(out["status"][0]), cpu


def same_downstream_fence(D, geom, loc1, loc2, scene, preset) -> bool:
    """The downstream fence is built the same with and without the upstream one (the upstream is
    the one cut short to keep the gap)."""
    from feeder.lane.fences import parse_location

    a = D.prepare_drops(geom, loc1, loc2, scene, preset).plan.fences
    b = D.prepare_drops(geom, loc1, parse_location("none"), scene, preset, prune=False).plan.fences
    fa = [f for f in a if f.location == "loc1"]
    fb = [f for f in b if f.location == "loc1"]
    return len(fa) == len(fb) == 1 and np.array_equal(np.asarray(fa[0].boxes), np.asarray(fb[0].boxes))


def main(argv: list[str]) -> int:
    if argv and argv[0] == "--summary":
        print(summary(pd.read_csv(argv[1])))
        return 0
    from feeder.lane.fences import parse_config_id
    from feeder.parts.geometry import load_part_units
    from feeder.sim.drops import drop_seed, initial_yaws

    out_csv = Path(argv[0])
    n = int(argv[1]) if len(argv) > 1 else 40
    seed = int(argv[2]) if len(argv) > 2 else 0
    drops = int(argv[3]) if len(argv) > 3 else 16
    cfg, table = _study()
    two = table[~table["config_id"].str.contains("none")].reset_index(drop=True)
    pick = random.Random(seed).sample(range(len(two)), min(n, len(two)))
    D, scene, preset = _runner(cfg)
    rows = []
    for k, j in enumerate(pick):
        part, cid = two.loc[j, "part"], two.loc[j, "config_id"]
        loc1, loc2 = parse_config_id(cid)
        geom, _ = load_part_units(ROOT / "parts" / f"{part}.stl", "auto")
        if not same_downstream_fence(D, geom, loc1, loc2, scene, preset):
            raise SystemExit(f"{part} {cid}: the downstream fence differs without the upstream one")
        s = drop_seed(part, cid, int(cfg["sim"]["base_seed"]))
        ya = initial_yaws(s, drops, "grid")
        yb = initial_yaws(s + 1, drops, "grid")
        runs = {
            "end2end": (ya, run_end2end(D, geom, loc1, loc2, ya, scene, preset)),
            "nudge": (ya + NUDGE_DEG, run_end2end(D, geom, loc1, loc2, ya + NUDGE_DEG, scene, preset)),
            "offset_b": (yb, run_end2end(D, geom, loc1, loc2, yb, scene, preset)),
        }
        cont = []
        for r in runs["end2end"][1]:
            if r["pose"] is None:
                cont.append(dict(r, handed_over=False, cpu_s=0.0, downstream_cpu_s=0.0))
            else:
                final, status, cpu = run_continued(D, geom, loc1, r["pose"], scene, preset)
                cont.append(
                    {
                        "final_yaw_deg": final,
                        "status": status,
                        "handed_over": True,
                        "cpu_s": cpu,
                        "downstream_cpu_s": cpu,
                    }
                )
        runs["continued"] = (ya, cont)
        for run, (yaws, res) in runs.items():
            for i, (y0, r) in enumerate(zip(yaws, res)):
                rows.append(
                    {
                        "part": part,
                        "config_id": cid,
                        "run": run,
                        "drop": i,
                        "initial_yaw_deg": float(y0),
                        "final_yaw_deg": r["final_yaw_deg"],
                        "status": r["status"],
                        "handed_over": bool(r.get("handed_over", r.get("pose") is not None)),
                        "cpu_s": r["cpu_s"],
                        "downstream_cpu_s": r["downstream_cpu_s"],
                    }
                )
        pd.DataFrame(rows).to_csv(out_csv, index=False)  # after every configuration: an interrupted run keeps its rows
        print(f"[{k + 1}/{len(pick)}] {part} {cid}", file=sys.stderr, flush=True)
    print(summary(pd.DataFrame(rows)))
    return 0


def summary(raw: pd.DataFrame) -> str:
    from feeder.bench.decomposition_table import compare
    from feeder.circular import LABEL_BINS, LABEL_SIGMA_BINS

    lines, table = [], []
    for (part, cid), g in raw.groupby(["part", "config_id"], sort=False):
        runs = {r: x.sort_values("drop") for r, x in g.groupby("run")}
        e = runs["end2end"]
        row = {"part": part, "config_id": cid, "handed_over": float(e["handed_over"].mean())}
        for other in ("continued", "nudge", "offset_b"):
            c = compare(e, runs[other], LABEL_BINS, LABEL_SIGMA_BINS)
            row |= {f"{other}_{k}": v for k, v in c.items()}
        row["downstream_cpu_share"] = float(e["downstream_cpu_s"].sum() / e["cpu_s"].sum())
        table.append(row)
    t = pd.DataFrame(table)
    drops = raw.groupby(["part", "config_id", "run"]).size().max()
    missed_c = ((1 - t["continued_same_basin"]) * drops).round()
    missed_n = ((1 - t["nudge_same_basin"]) * drops).round()
    lines.append(t.round(3).to_string(index=False))
    lines.append("")
    lines.append(
        f"{len(t)} configurations x {drops} drops; handed over between the fences: "
        f"{t['handed_over'].mean():.3f} of the drops"
    )
    for other in ("continued", "nudge"):
        lines.append(
            f"{other:9s} vs end2end: same basin {t[f'{other}_same_basin'].mean():.3f} (pooled drops), "
            f"median |dyaw| {t[f'{other}_median_dyaw_deg'].median():.3f} deg (median over configurations)"
        )
    for other in ("continued", "offset_b"):
        lines.append(
            f"{other:9s} label vs end2end: circular W1 mean {t[f'{other}_circular_w1_deg'].mean():.2f} deg, "
            f"median {t[f'{other}_circular_w1_deg'].median():.2f}; sup|dCDF| mean {t[f'{other}_sup_cdf'].mean():.3f}"
        )
    worse = int((missed_c > 2 * np.maximum(missed_n, 1)).sum())
    lines.append(f"configurations whose continued drops miss > 2x the nudge floor's basins: {worse} of {len(t)}")
    lab = int((t["continued_circular_w1_deg"] > t["offset_b_circular_w1_deg"]).sum())
    lines.append(f"configurations whose continued label is further from end2end than offset b's: {lab} of {len(t)}")
    share = t["downstream_cpu_share"].mean()
    lines.append(f"downstream share of a two-fence drop's CPU (after the hand-over): {share:.3f}")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
