"""The start-grid drops of a run's simulation files, as the rows of ``fence_tip.csv`` (issue #39).

The adaptive design starts from ``n0`` evenly spaced initial yaws per symmetry period (offset
``design.offset_deg``) and refines where outcomes jump; the refinements over-count hard drops, the
start grid does not. This writes, for every simulation file of SIM_DIR whose configuration is not
in ``--exclude`` (a ``fence_tip.csv``: configurations some rule was chosen on), its start-grid
drops with ``variant`` VARIANT, so that ``round_tip_model.py`` and ``notch_hook.py`` can score
them. Files whose start grid cannot be found (another design) are skipped and counted.

    python docs/experiments/start_grid_drops.py SIM_DIR OUT_CSV [--variant round] [--exclude CSV]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.io import write_csv

GRID_TOL_DEG = 1e-6  # an initial yaw this close to a grid yaw is that start drop


def start_grid(path: Path) -> tuple[float, np.ndarray, np.ndarray, np.ndarray] | None:
    with np.load(path, allow_pickle=False) as z:
        design = json.loads(str(z["meta"]))["design"]
        y0, yf, status = z["initial_yaw_deg"], z["final_yaw_deg"], z["status"]
        if not isinstance(design, dict) or "n0" not in design or "offset_deg" not in design:
            return None
        n0 = int(design["n0"])
        period = 360.0 / int(design.get("symmetry_order", 1))
        grid = float(design["offset_deg"]) + np.arange(n0) * period / n0
        gap = np.abs((y0[None, :] - grid[:, None] + period / 2) % period - period / 2)
        idx = np.argmin(gap, axis=1)
        if np.any(gap[np.arange(n0), idx] > GRID_TOL_DEG):
            return None
        return period, y0[idx], yf[idx], status[idx]


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    ap.add_argument("--variant", default="round")
    ap.add_argument("--exclude", type=Path)
    args = ap.parse_args(argv)
    skip = set()
    if args.exclude:
        ex = pd.read_csv(args.exclude)
        skip = set(zip(ex.part, ex.config_id))
    rows, missing = [], 0
    for path in sorted(args.sim_dir.glob("*/*.npz")):
        part, config_id = path.parent.name, path.stem
        if (part, config_id) in skip:
            continue
        got = start_grid(path)
        if got is None:
            missing += 1
            continue
        period, y0, yf, status = got
        for i in range(len(y0)):
            rows.append((part, config_id, args.variant, period, i, float(y0[i]), str(status[i]), float(yf[i])))
    cols = ["part", "config_id", "variant", "period", "drop", "initial_yaw_deg", "status", "final_yaw_deg"]
    out = pd.DataFrame(rows, columns=cols)
    write_csv(args.out_csv, out)
    configs = out.groupby(["part", "config_id"]).ngroups
    print(f"{configs} configurations, {len(out)} drops; {missing} files without a start grid")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
