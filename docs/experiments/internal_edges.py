"""Does a fence's face hold a part by the seams between its boxes? (issue #39, simulator side)

A fence is built in pybullet as a compound of boxes (``feeder.lane.geometry``). A straight fence
is one box, and a curved fence is ``scene.fences.curved.segments`` boxes whose outer faces are the
chords of the arc, so it has a seam at every joint. Drop by drop, this script runs the study's own
drops (the simulation file's initial yaws, scene and preset) through variants of the same fence
that differ only in how its face is cut into boxes:

* ``boxesN`` (straight fences): the one box cut into N collinear boxes. The face is the same plane,
  so any change is the seams'.
* ``segmentsN`` (curved fences): the arc built from N boxes (the study: 16). This also moves the
  face by the chords' sagitta (0.24 mm at 16 boxes, 0.015 mm at 64).
* ``hullN`` (curved fences): ``scene.fences.curved.build: hull`` at N chords, the fence as one
  convex piece, the hull of its outer face (the circular segment between the arc and its chord;
  no seam on the face, the space behind the arc filled; ``feeder.sim.body.World._add_hull``). Its
  round tip stays the separate cylinder it is in the study.

Each variant is compared with the study's build (``boxes1``, ``segments16``), and with every other
variant of its own kind, over the same initial yaws: the share of the drops that jam, the share
with the same status, and, over the drops ok in both, the share within ``AGREE_DEG`` of each other
(modulo the file's symmetry period) and the median |Δyaw|.

    python docs/experiments/internal_edges.py SIM_DIR PARTS_DIR OUT_RAW_CSV OUT_SUMMARY_CSV \\
        --runs star4-a/straight60_none:boxes1,boxes8,boxes32 ...

About 0.5 s a drop on one core.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import copy
import json
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

import feeder.lane.geometry as lane_geometry
from feeder.io import write_csv
from feeder.lane.fences import parse_location
from feeder.parts.geometry import load_part
from feeder.sim.drops import run_drops

AGREE_DEG = 5.0  # two ok drops agree within this (modulo the period), as analytic_dropwise.py
STUDY = {"boxes": 1, "segments": 16}  # the study's build of each fence type
KINDS = ("boxes", "segments", "hull")


def split_box(box, n: int) -> tuple:
    """The box ``(cx, cy, half_length, half_thickness, yaw)`` cut into ``n`` collinear boxes of
    equal length that cover it exactly."""
    cx, cy, hl, ht, yaw = box
    t = np.array([np.cos(yaw), np.sin(yaw)])
    step = hl / n
    centres = [(-hl + (2 * k + 1) * step) for k in range(n)]
    return tuple((float(cx + t[0] * s), float(cy + t[1] * s), step, ht, yaw) for s in centres)


@contextmanager
def straight_boxes(n: int):
    """While inside, every straight fence the simulator builds is cut into ``n`` boxes."""
    original = lane_geometry.fence_geometry

    def cut(scene, location, fence):
        g = original(scene, location, fence)
        if g is None or fence.type != "straight" or n == 1:
            return g
        boxes = tuple(b for box in g.boxes for b in split_box(box, n))
        return lane_geometry.FenceGeom(g.location, g.fence, g.side, boxes, g.round_tip)

    lane_geometry.fence_geometry = cut
    try:
        yield
    finally:
        lane_geometry.fence_geometry = original


def run_variant(geom, meta: dict, yaws, variant: str) -> dict:
    """The drops of ``yaws`` through the file's configuration, its scene and preset, with the
    fence built as ``variant`` (``boxesN``, ``segmentsN`` or ``hullN``)."""
    scene, preset = copy.deepcopy(meta["settings"]["scene"]), meta["settings"]["preset"]
    kind, n = variant.rstrip("0123456789"), int(variant[len(variant.rstrip("0123456789")) :])
    if kind not in KINDS:
        raise ValueError(f"variant {variant!r}: boxesN, segmentsN or hullN")
    loc1, loc2 = parse_location(meta["loc1"]), parse_location(meta["loc2"])
    if kind in ("segments", "hull"):
        scene["fences"]["curved"]["segments"] = n
        scene["fences"]["curved"]["build"] = "boxes" if kind == "segments" else "hull"
        return run_drops(geom, loc1, loc2, yaws, scene, preset)
    with straight_boxes(n):
        return run_drops(geom, loc1, loc2, yaws, scene, preset)


def raw_rows(sim_dir: Path, parts_dir: Path, runs: list[tuple[str, str, list[str]]]) -> pd.DataFrame:
    frames = []
    for part, config_id, variants in runs:
        with np.load(sim_dir / part / f"{config_id}.npz", allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            yaws = np.asarray(z["initial_yaw_deg"], dtype=np.float64)
        period = 360.0 / int(meta["design"].get("symmetry_order", 1))
        geom = load_part(parts_dir / f"{part}.stl")
        for variant in variants:
            out = run_variant(geom, meta, yaws, variant)
            frames.append(
                pd.DataFrame(
                    dict(
                        part=part,
                        config_id=config_id,
                        variant=variant,
                        period=period,
                        drop=np.arange(yaws.size),
                        initial_yaw_deg=yaws,
                        status=out["status"].astype(str),
                        final_yaw_deg=out["final_yaw_deg"],
                    )
                )
            )
            print(f"{part} {config_id} {variant}: jam {np.mean(out['status'] != 'ok'):.3f}", flush=True)
    return pd.concat(frames, ignore_index=True)


def paired(h: pd.DataFrame, base: pd.DataFrame) -> dict:
    """Drop by drop (indexed by drop): the share with the same status and, over the drops ok in
    both, the share within ``AGREE_DEG`` and the median |Δyaw|."""
    both = (h.status == "ok") & (base.status == "ok")
    period = h.period[both]
    gap = np.abs(np.mod(h.final_yaw_deg[both] - base.final_yaw_deg[both] + period / 2.0, period) - period / 2.0)
    return dict(
        same_status=float((h.status == base.status).mean()),
        ok_in_both=int(both.sum()),
        same_basin=float((gap <= AGREE_DEG).mean()) if both.any() else float("nan"),
        median_abs_dyaw_deg=float(np.median(gap)) if both.any() else float("nan"),
    )


def summary(raw: pd.DataFrame) -> pd.DataFrame:
    """Per part, configuration and variant: the jam share, and the drop-by-drop comparison with
    the study's build of the same fence and with every other variant of its own kind."""
    rows = []
    for (part, config_id), g in raw.groupby(["part", "config_id"], sort=False):
        variants = {v: h.set_index("drop") for v, h in g.groupby("variant", sort=False)}
        kind = {v: v.rstrip("0123456789") for v in variants}
        study = {f"{k}{n}" for k, n in STUDY.items()} & set(variants)
        for variant, h in variants.items():
            base = dict(part=part, config_id=config_id, variant=variant, drops=len(h))
            base["jam_share"] = float((h.status != "ok").mean())
            others = sorted(study | {v for v in variants if kind[v] == kind[variant]})
            for against in [v for v in others if v != variant] or [None]:
                row = dict(base, against=against)
                if against is not None:
                    row |= paired(h, variants[against])
                rows.append(row)
    return pd.DataFrame(rows)


def parse_runs(items: list[str]) -> list[tuple[str, str, list[str]]]:
    out = []
    for item in items:
        where, _, variants = item.partition(":")
        part, _, config_id = where.partition("/")
        if not (part and config_id and variants):
            raise SystemExit(f"--runs {item!r}: PART/CONFIG:VARIANT,VARIANT")
        out.append((part, config_id, variants.split(",")))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_raw", type=Path)
    ap.add_argument("out_summary", type=Path)
    ap.add_argument("--runs", nargs="+", required=True, help="PART/CONFIG:VARIANT,VARIANT,...")
    ap.add_argument("--from-raw", action="store_true", help="summarise OUT_RAW as it is (no simulation)")
    args = ap.parse_args(argv)
    raw = pd.read_csv(args.out_raw) if args.from_raw else raw_rows(args.sim_dir, args.parts_dir, parse_runs(args.runs))
    if not args.from_raw:
        raw.to_csv(args.out_raw, index=False)  # gzip by the name's suffix, as arc_ride.py
    table = summary(raw)
    write_csv(args.out_summary, table)
    print(table.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
