"""Every predictor on unseen parts, by library set: the paper's protocol parts and the wider library.

The leave-parts-out GroupKFold runs over every part (``datasets.wide`` adds the wider library to
it). Its tables keep one row per part, so this split needs no retraining: per predictor and set
(``all``, ``protocol``: the parts of Main/Fences/Parts, ``wide``: the wider library), the mean over
the set's parts of each metric of :data:`feeder.learn.evaluate.GENERALISATION_METRICS` and the
difference to the mean-PMF baseline paired over those parts, with its percentile bootstrap
interval (``models.bootstrap``)::

    feeder generalisation-sets --groupkfold results/tables/groupkfold_*.csv \\
        --configurations results/datasets/configurations.csv \\
        --out results/tables/generalisation_by_set.csv --resamples 2000 --level 0.95 --bootstrap-seed 0
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from feeder.errors import FeederError

SETS = ("all", "protocol", "wide")


def part_sets(configurations: pd.DataFrame) -> dict[str, str]:
    """``protocol`` or ``wide`` for every part of the configuration table (by its ``dataset``)."""
    from feeder.labels.grid import WIDE

    sets: dict[str, str] = {}
    for part, dataset in zip(configurations["part"], configurations["dataset"], strict=True):
        name = "wide" if dataset == WIDE else "protocol"
        if sets.setdefault(str(part), name) != name:
            raise FeederError(f"configuration table: part {part} is in the wide library and in the protocol")
    return sets


def per_part_tables(groupkfold: list[pd.DataFrame]) -> dict[str, pd.DataFrame]:
    """Each predictor's per-part rows (indexed by part) from GroupKFold tables of one or more models."""
    from feeder.learn.evaluate import OVER_PARTS

    out: dict[str, pd.DataFrame] = {}
    for table in groupkfold:
        for name, rows in table.groupby("model", sort=False):
            parts_rows = rows[~rows["group"].isin([OVER_PARTS, "all configurations"])]
            if parts_rows.empty:
                raise FeederError(f"GroupKFold table: {name} has no per-part rows")
            out.setdefault(str(name), parts_rows.set_index("group"))
    return out


def sets_table(groupkfold: list[pd.DataFrame], configurations: pd.DataFrame, bootstrap: dict) -> pd.DataFrame:
    """One row per predictor and set (see the module doc)."""
    from feeder.learn.evaluate import BASELINE_MEAN, GENERALISATION_METRICS, paired_bootstrap, verdict

    per_part = per_part_tables(groupkfold)
    if BASELINE_MEAN not in per_part:
        raise FeederError(f"GroupKFold tables lack the {BASELINE_MEAN} rows")
    sets = part_sets(configurations)
    base = per_part[BASELINE_MEAN]
    unknown = sorted(set(base.index) - set(sets))
    if unknown:
        raise FeederError(f"GroupKFold parts missing from the configuration table: {', '.join(unknown[:5])}")
    rows = []
    for name, table in per_part.items():
        if set(table.index) != set(base.index):
            raise FeederError(f"GroupKFold tables: {name} and {BASELINE_MEAN} cover different parts")
        for set_name in SETS:
            parts = sorted(p for p in table.index if set_name == "all" or sets[p] == set_name)
            if not parts:
                continue
            row = {"predictor": name, "set": set_name, "parts": len(parts)}
            for metric, sign in GENERALISATION_METRICS:
                col = f"{metric}_mean"
                row[col] = float(table.loc[parts, col].mean())
                diff = (table.loc[parts, col] - base.loc[parts, col]).to_numpy()
                mean, low, high = paired_bootstrap(diff, **bootstrap)
                row[f"{metric}_vs_mean_pmf"], row[f"{metric}_vs_mean_pmf_low"] = mean, low
                row[f"{metric}_vs_mean_pmf_high"] = high
                row[f"{metric}_verdict"] = "" if name == BASELINE_MEAN else verdict(low, high, sign)
            rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str]) -> int:
    from feeder import io as fio
    from feeder.learn.evaluate import _bootstrap_options, _bootstrap_settings, _read_table

    parser = argparse.ArgumentParser(prog="feeder generalisation-sets", description=__doc__.split("\n")[0])
    parser.add_argument(
        "--groupkfold", type=Path, nargs="+", required=True, help="groupkfold_<model>.csv of each model"
    )
    parser.add_argument("--configurations", type=Path, required=True, help="results/datasets/configurations.csv")
    parser.add_argument("--out", type=Path, required=True, help="CSV (a Markdown copy goes beside it)")
    _bootstrap_options(parser)
    args = parser.parse_args(argv)
    bootstrap = _bootstrap_settings(args)
    need = ["model", "group", "r2_mean", "r2c_mean", "cw1_mean"]
    tables = [_read_table(p, "GroupKFold table", need) for p in args.groupkfold]
    configurations = _read_table(args.configurations, "configuration table", ["part", "dataset"])
    df = sets_table(tables, configurations, bootstrap)
    fio.write_csv(args.out, df)
    fio.write_text(
        args.out.with_suffix(".md"),
        fio.markdown_table(
            df,
            "Every predictor on unseen parts (leave-parts-out GroupKFold) by library set: all parts, the "
            "paper's protocol parts, the wider library; each against the mean PMF paired over the set's parts",
        ),
    )
    cols = ["predictor", "set", "parts", "r2_mean", "r2_vs_mean_pmf", "r2_vs_mean_pmf_low", "r2_vs_mean_pmf_high"]
    print(df[cols].to_string(index=False), file=sys.stderr)
    return 0
