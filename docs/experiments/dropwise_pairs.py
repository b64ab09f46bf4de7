"""Two drop-by-drop comparisons of the analytic model with the simulator, paired by configuration
(issue #39: the round-tip re-baseline).

``analytic_dropwise.py`` writes, for one run's simulation files, each drop's simulated and
modelled final yaw (the model under the scene the files were simulated with). Given two such row
files (OLD: the square-tip run with its model; NEW: the round-tip run with the round tip's model,
cap and notch hook), this script takes the configurations present in both and compares the share
of initial yaws (weighted) where model and simulator agree (both ok within ``AGREE_DEG`` modulo
the symmetry period), per configuration, by one or two fences and by fence types: the mean of
each, and the mean difference with a 95 % bootstrap interval over configurations. Both the model
and the simulator differ between the two; the difference is how much closer they have come.

    python docs/experiments/dropwise_pairs.py OLD_ROWS_CSV_GZ NEW_ROWS_CSV_GZ OUT_CSV
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG  # noqa: E402
from fence_tip import paired_interval  # noqa: E402

from feeder.io import write_csv  # noqa: E402
from feeder.learn.evaluate import fence_types  # noqa: E402


def per_config(rows: pd.DataFrame) -> pd.Series:
    """Weighted share of each configuration's initial yaws where model and simulator agree."""
    p = rows.period
    ok = (rows.status == "ok") & rows.analytic_yaw_deg.notna()
    gap = np.abs((rows.final_yaw_deg - rows.analytic_yaw_deg + p / 2) % p - p / 2)
    rows = rows.assign(agree=(ok & (gap < AGREE_DEG)).astype(float))
    return rows.groupby(["part", "config_id"]).apply(lambda g: np.average(g.agree, weights=g.weight))


def paired(old: pd.DataFrame, new: pd.DataFrame) -> pd.DataFrame:
    both = pd.concat([per_config(old).rename("old"), per_config(new).rename("new")], axis=1, join="inner")
    both = both.reset_index()
    both["fences"] = [fence_types(c) for c in both.config_id]
    both["group"] = np.where(both.fences.str.contains("none"), "one fence", "two fences")
    out = []
    for key, g in [*both.groupby("group"), *both.groupby("fences"), ("all", both)]:
        diff = (g.new - g.old).to_numpy()
        lo, hi = paired_interval(diff)
        out.append((key, len(g), g.old.mean(), g.new.mean(), diff.mean(), lo, hi))
    return pd.DataFrame(out, columns=["group", "configs", "agree_old", "agree_new", "diff", "diff_lo", "diff_hi"])


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old_rows", type=Path)
    ap.add_argument("new_rows", type=Path)
    ap.add_argument("out_csv", type=Path)
    args = ap.parse_args(argv)
    table = paired(pd.read_csv(args.old_rows), pd.read_csv(args.new_rows))
    write_csv(args.out_csv, table)
    print(table.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
