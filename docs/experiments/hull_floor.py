"""Is the seam-free curved fence's change more than the simulator's own chaos? (issue #39)

``config/hull.yaml`` rebuilds every curved fence as one convex piece over 64 chords, where the study
builds 16 boxes. ``rebaseline_pairs.py`` pairs the two runs drop by drop: the share of initial yaws
with the same outcome. That share is below 1 even for a change that does nothing, because an
initial yaw near a basin boundary flips under any perturbation. This script measures that floor on
a seeded sample of the curved-fence configurations, stratified by the part's concavity
(``curved_jams.CONCAVE_BELOW``), with the same drops run four ways:

* ``segments16`` and ``hull64``: the study's build and the overlay's, at the file's initial yaws;
* ``segments16+nudge`` and ``hull64+nudge``: the same, every initial yaw ``NUDGE_DEG`` later;
* ``file``: the simulation file's own outcomes (``reproduced``: ``segments16`` must give them back).

Per configuration, the share of same outcomes (both ok within ``SAME_DEG`` modulo the symmetry
period, or the same non-ok status) of: hull against boxes (the change), and each build against
itself nudged (its floor). Per group, the mean over configurations with a 95 % bootstrap
interval, and the paired difference change minus floor (boxes' floor) with its interval. A change
that does nothing sits at the floor.

    python docs/experiments/hull_floor.py SIM_DIR PARTS_DIR OUT_RAW_CSV_GZ OUT_SUMMARY_CSV \\
        [--per-group 20 --drops 12 --seed 0] [--from-raw]

About 0.5 s a drop on one core: 2 groups x 20 configurations x 12 drops x 4 runs, about 16 minutes.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.io import write_csv
from feeder.parts.geometry import load_part

sys.path.insert(0, str(Path(__file__).resolve().parent))
from curved_jams import CONCAVE_BELOW, solidity  # noqa: E402 - this folder's scripts
from internal_edges import run_variant  # noqa: E402
from rebaseline_pairs import SAME_DEG, boot_mean  # noqa: E402

NUDGE_DEG = 0.01  # as the decomposition bench's floor (config: benches.decomposition_bench.nudge_deg)
# internal_edges names the study's curved build segments16 (its boxesN cut a straight fence into N boxes)
RUNS = (("segments16", 0.0), ("hull64", 0.0), ("segments16", NUDGE_DEG), ("hull64", NUDGE_DEG))


def sample(sim_dir: Path, parts_dir: Path, per_group: int, seed: int) -> pd.DataFrame:
    """``per_group`` curved-fence configurations of convex and of concave parts, drawn with ``seed``."""
    files = sorted(sim_dir.glob("*/*curved*.npz"))
    sol = {p: solidity(parts_dir / f"{p}.stl") for p in sorted({f.parent.name for f in files})}
    df = pd.DataFrame(dict(part=[f.parent.name for f in files], config_id=[f.stem for f in files]))
    df["concave"] = df.part.map(sol) < CONCAVE_BELOW
    rng = np.random.default_rng(seed)
    picks = [
        g.iloc[np.sort(rng.choice(len(g), size=min(per_group, len(g)), replace=False))]
        for _, g in df.groupby("concave")
    ]
    return pd.concat(picks, ignore_index=True)


def raw_rows(sim_dir: Path, parts_dir: Path, picks: pd.DataFrame, drops: int) -> pd.DataFrame:
    frames = []
    for k, (part, config_id, concave) in enumerate(picks[["part", "config_id", "concave"]].itertuples(index=False)):
        with np.load(sim_dir / part / f"{config_id}.npz", allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            yaws = np.asarray(z["initial_yaw_deg"], dtype=np.float64)[:drops]  # the start grid first
            recorded = {"status": z["status"][:drops].astype(str), "final_yaw_deg": z["final_yaw_deg"][:drops]}
        period = 360.0 / int(meta["design"].get("symmetry_order", 1))
        geom = load_part(parts_dir / f"{part}.stl")
        for variant, nudge in (("file", 0.0), *RUNS):
            out = recorded if variant == "file" else run_variant(geom, meta, yaws + nudge, variant)
            frames.append(
                pd.DataFrame(
                    dict(
                        part=part,
                        config_id=config_id,
                        concave=bool(concave),
                        run=variant + ("+nudge" if nudge else ""),
                        period=period,
                        drop=np.arange(yaws.size),
                        initial_yaw_deg=yaws,
                        status=out["status"].astype(str),
                        final_yaw_deg=out["final_yaw_deg"],
                    )
                )
            )
        print(f"{k + 1}/{len(picks)} {part} {config_id}", flush=True)
    return pd.concat(frames, ignore_index=True)


def same_outcome(a: pd.DataFrame, b: pd.DataFrame) -> np.ndarray:
    """Drop by drop (rows aligned): both ok within ``SAME_DEG`` modulo the period, or the same non-ok status."""
    both_ok = (a.status.to_numpy() == "ok") & (b.status.to_numpy() == "ok")
    p = a.period.to_numpy()
    gap = np.abs(np.mod(a.final_yaw_deg.to_numpy() - b.final_yaw_deg.to_numpy() + p / 2.0, p) - p / 2.0)
    return np.where(both_ok, gap < SAME_DEG, (a.status.to_numpy() == b.status.to_numpy()) & ~both_ok)


def per_config(raw: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (part, config_id, concave), g in raw.groupby(["part", "config_id", "concave"], sort=False):
        runs = {r: h.sort_values("drop").reset_index(drop=True) for r, h in g.groupby("run")}
        rows.append(
            dict(
                part=part,
                config_id=config_id,
                concave=concave,
                reproduced=same_outcome(runs["segments16"], runs["file"]).mean(),
                change=same_outcome(runs["hull64"], runs["segments16"]).mean(),
                floor_boxes=same_outcome(runs["segments16+nudge"], runs["segments16"]).mean(),
                floor_hull=same_outcome(runs["hull64+nudge"], runs["hull64"]).mean(),
                jam_boxes=float((runs["segments16"].status != "ok").mean()),
                jam_hull=float((runs["hull64"].status != "ok").mean()),
            )
        )
    return pd.DataFrame(rows)


def summary(cfg: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    out = []
    for concave, g in cfg.groupby("concave"):
        rec = dict(concave=bool(concave), configurations=len(g))
        for col in ("reproduced", "change", "floor_boxes", "floor_hull", "jam_boxes", "jam_hull"):
            rec[col], rec[col + "_lo"], rec[col + "_hi"] = boot_mean(g[col].to_numpy(dtype=float), rng)
        d = (g.change - g.floor_boxes).to_numpy(dtype=float)
        rec["change_minus_floor"], rec["change_minus_floor_lo"], rec["change_minus_floor_hi"] = boot_mean(d, rng)
        out.append(rec)
    return pd.DataFrame(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path, help="the study's simulation files (boxes)")
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_raw", type=Path)
    ap.add_argument("out_summary", type=Path)
    ap.add_argument("--per-group", type=int, default=20)
    ap.add_argument("--drops", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--from-raw", action="store_true", help="summarise OUT_RAW as it is (no simulation)")
    args = ap.parse_args(argv)
    if args.from_raw:
        raw = pd.read_csv(args.out_raw)
    else:
        raw = raw_rows(
            args.sim_dir, args.parts_dir, sample(args.sim_dir, args.parts_dir, args.per_group, args.seed), args.drops
        )
        raw.to_csv(args.out_raw, index=False)  # gzip by the name's suffix
    cfg = per_config(raw)
    table = summary(cfg)
    write_csv(args.out_summary, table)
    pd.set_option("display.width", 200)
    print(table.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
