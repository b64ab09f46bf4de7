"""Check (issue #39 item 1, 2026-11-24): on unseen parts, is any predictor better than the untrained
analytic push PMF by circular W1? Not part of the workflow; it reads committed tables only and
simulates or trains nothing. From the repository root:

    .venv/bin/python docs/experiments/analytic_against_networks.py

Per predictor of the leave-parts-out GroupKFold tables (``results/tables/groupkfold_<model>.csv``,
one row per part: the mean circular W1 over its configurations, averaged over training seeds), the
difference to the analytic PMF paired over parts with the evaluation's percentile bootstrap
(:func:`feeder.learn.evaluate.paired_bootstrap`, 2,000 resamples, 95 %, seed 0). The networks'
rows equal those of ``groupkfold_<model>_paired.csv``; the analytic prior's is computed here.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from feeder.learn.evaluate import BASELINE_ANALYTIC, paired_bootstrap

TABLES = Path("results/tables")
SUMMARY_GROUPS = ("all configurations", "over parts")  # rows of a GroupKFold table that are not a part
RESAMPLES, LEVEL, SEED = 2000, 0.95, 0


def per_part(path: Path) -> pd.DataFrame:
    t = pd.read_csv(path)
    return t[~t["group"].isin(SUMMARY_GROUPS)].pivot(index="group", columns="model", values="cw1_mean")


def main() -> None:
    frames = [per_part(p) for p in sorted(TABLES.glob("groupkfold_*.csv")) if not p.stem.endswith("_paired")]
    table = pd.concat(frames, axis=1)
    table = table.loc[:, ~table.columns.duplicated()]
    analytic = table[BASELINE_ANALYTIC]
    print("predictor,parts,cw1_mean,diff_vs_analytic,low,high")
    for name in table.columns:
        diff = (table[name] - analytic).dropna().to_numpy()
        mean, low, high = paired_bootstrap(diff, RESAMPLES, LEVEL, SEED)
        print(f"{name},{diff.size},{table[name].mean():.2f},{mean:+.2f},{low:+.2f},{high:+.2f}")


if __name__ == "__main__":
    main()
