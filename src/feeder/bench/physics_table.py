"""The physics sensitivity table from its raw drops (``feeder bench-physics-table``).

Issue #37, item 3: :mod:`feeder.bench.physics` runs every configuration under the baseline and
under each factor with the same initial yaws and keeps every drop; this module compares the runs
(pure) and writes

* one ``configuration`` row per configuration and factor: the label shift against the baseline
  (same-basin fraction and median |Δ final yaw|, paired drop by drop; sup|ΔCDF| and circular W1 of
  the labels; :func:`feeder.bench.decomposition_table.compare`), beside that configuration's noise
  floor (``floor_*``: the baseline nudged for the paired metrics, the baseline at offset ``b`` for
  the label's), the circular W1 shift over that floor (``circular_w1_to_floor``; the floor taken
  at least at the label's resolution, one drop moved one bin), the ok rates and how many ok drops
  had no final yaw (``ok_nan``, never expected);
* one ``factor`` row per factor: each metric's median and mean over the configurations with a
  95 % percentile bootstrap interval (configurations resampled, ``bootstrap`` times), the floor's
  medians beside it;
* one ``floor`` row: the floor's own median and mean with intervals;
* one ``model_error`` row per entry of ``model_errors``: the circular W1 (degrees) of a model's
  predictions, read from a committed table (named in ``source``).

Rebuilding the table simulates nothing.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.bench.decomposition_table import METRICS, compare, label_resolution
from feeder.bench.physics import BASELINE
from feeder.errors import FeederError

STATS = ("median", "mean")
RATIO = "circular_w1_to_floor"  # a configuration's circular W1 shift over its floor (at least the label's resolution)
SUMMED = (*METRICS, RATIO)
CONFIDENCE = 0.95  # the intervals' coverage (percentile bootstrap)


def bootstrap_interval(values, stat: str, resamples: int, seed: int) -> tuple[float, float, float]:
    """``stat`` (median or mean) of the finite ``values`` and its 95 % percentile bootstrap interval
    (the values resampled with replacement ``resamples`` times, seeded): ``(estimate, low, high)``,
    NaN without a finite value (pure)."""
    if stat not in STATS:
        raise FeederError(f"statistic {stat!r}: one of {', '.join(STATS)}")
    x = np.asarray(values, np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan
    f = np.median if stat == "median" else np.mean
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(int(resamples), x.size))
    boot = f(x[idx], axis=1)
    tail = 100.0 * (1.0 - CONFIDENCE) / 2.0
    low, high = np.percentile(boot, [tail, 100.0 - tail])
    return float(f(x)), float(low), float(high)


def _stat_seed(seed: int, *names: str) -> int:
    from feeder.sim.drops import drop_seed

    return drop_seed("physics-bench", "|".join(names), seed)


def status_counts(run: pd.DataFrame) -> dict:
    """A run's ok rate and how many ok drops carry no finite final yaw (pure)."""
    ok = run["status"].astype(str).to_numpy() == "ok"
    final = run["final_yaw_deg"].to_numpy(np.float64)
    return {"ok_rate": float(ok.mean()) if ok.size else math.nan, "ok_nan": int((ok & ~np.isfinite(final)).sum())}


def _as_nan_status(raw: pd.DataFrame) -> pd.DataFrame:
    """``raw`` with an ok drop that has no finite final yaw given the status ``nan`` (it is counted
    in ``ok_nan`` and compared as a failed drop, never labelled)."""
    bad = (raw["status"].astype(str) == "ok") & ~np.isfinite(raw["final_yaw_deg"].to_numpy(np.float64))
    if not bad.any():
        return raw
    out = raw.copy()
    out.loc[bad, "status"] = "nan"
    return out


def configuration_rows(raw: pd.DataFrame, bins: int, sigma: float) -> pd.DataFrame:
    """One row per configuration and factor: the shift against the baseline beside the floor (an
    ok drop without a final yaw counts in ``ok_nan`` and is compared as status ``nan``)."""
    rows = []
    counted = raw
    raw = _as_nan_status(raw)
    for (part, config), g in raw.groupby(["part", "configuration"], sort=True):
        c = counted.loc[g.index]
        base = g[g["factor"] == BASELINE]
        plain = base[(base["offset"] == "a") & (base["yaw_shift_deg"] == 0)]
        nudged = base[(base["offset"] == "a") & (base["yaw_shift_deg"] != 0)]
        other = base[base["offset"] == "b"]
        if plain.empty or nudged.empty or other.empty:
            raise FeederError(f"{part} {config}: the raw drops lack a baseline run (plain, nudged or offset b)")
        paired, labels = compare(plain, nudged, bins, sigma), compare(plain, other, bins, sigma)
        floor = {
            "same_basin": paired["same_basin"],
            "median_dyaw_deg": paired["median_dyaw_deg"],
            "sup_cdf": labels["sup_cdf"],
            "circular_w1_deg": labels["circular_w1_deg"],
        }
        base_counts = status_counts(c.loc[plain.index])
        floor_nan = sum(status_counts(c.loc[r.index])["ok_nan"] for r in (plain, nudged, other))
        least = label_resolution(bins, len(plain))["circular_w1_deg"]
        for factor, f in g[g["factor"] != BASELINE].groupby("factor", sort=True):
            counts = status_counts(c.loc[f.index])
            shift = compare(plain, f, bins, sigma)
            rows.append(
                {
                    "kind": "configuration",
                    "part": part,
                    "configuration": config,
                    "factor": factor,
                    "path": str(f["path"].iloc[0]),
                    "level": str(f["level"].iloc[0]),
                    "drops": len(f),
                    "ok_rate_baseline": base_counts["ok_rate"],
                    "ok_rate": counts["ok_rate"],
                    "ok_nan": counts["ok_nan"] + floor_nan,
                    **shift,
                    **{f"floor_{k}": v for k, v in floor.items()},
                    RATIO: shift["circular_w1_deg"] / max(floor["circular_w1_deg"], least)
                    if not math.isnan(floor["circular_w1_deg"])
                    else math.nan,
                    "cpu_s": float(f["cpu_s"].iloc[0]),
                    "cpu_s_baseline": float(plain["cpu_s"].iloc[0]),
                }
            )
    return pd.DataFrame(rows)


def _summary(kind: str, factor: str, path: str, level: str, values: dict, resamples: int, seed: int) -> dict:
    row = {"kind": kind, "part": "all", "configuration": "all", "factor": factor, "path": path, "level": level}
    for k in [m for m in SUMMED if m in values]:
        x = np.asarray(values[k], np.float64)
        row[f"n_{k}"] = int(np.isfinite(x).sum())
        for stat in STATS:
            est, low, high = bootstrap_interval(x, stat, resamples, _stat_seed(seed, factor, k, stat))
            row[f"{k}_{stat}"], row[f"{k}_{stat}_low"], row[f"{k}_{stat}_high"] = est, low, high
    return row


def summarize(
    raw: pd.DataFrame, bins: int, sigma: float, resamples: int, seed: int, errors=(), order=()
) -> pd.DataFrame:
    """The table (see the module's docstring) from the raw drops and the models' errors
    (``errors``: dicts of ``name``, ``value`` and ``source``): the factor rows in ``order`` (factor
    names; any other after them, by name), the floor, the model errors, then the configuration rows."""
    per = configuration_rows(raw, bins, sigma)
    rank = {name: k for k, name in enumerate(order)}
    per = per.sort_values(
        ["factor", "part", "configuration"],
        key=lambda s: s.map(lambda f: (rank.get(f, len(rank)), f)) if s.name == "factor" else s,
    ).reset_index(drop=True)
    summary = []
    for factor, g in per.groupby("factor", sort=False):
        row = _summary("factor", factor, g["path"].iloc[0], g["level"].iloc[0], g, resamples, seed)
        row |= {f"floor_{k}_median": float(np.nanmedian(g[f"floor_{k}"])) for k in METRICS}
        row |= {
            "configurations": int(g["configuration"].size),
            "ok_rate": float(g["ok_rate"].mean()),
            "ok_rate_baseline": float(g["ok_rate_baseline"].mean()),
            "ok_nan": int(g["ok_nan"].sum()),
            "cpu_ratio": float(g["cpu_s"].sum() / g["cpu_s_baseline"].sum()),
        }
        summary.append(row)
    first = per.drop_duplicates(["part", "configuration"])
    floor = _summary("floor", "floor", "", "", {k: first[f"floor_{k}"] for k in METRICS}, resamples, seed)
    floor["configurations"] = len(first)
    summary.append(floor)
    for e in errors:
        summary.append(
            {
                "kind": "model_error",
                "part": "all",
                "configuration": "all",
                "factor": e["name"],
                "circular_w1_deg_mean": float(e["value"]),
                "source": e["source"],
            }
        )
    return pd.concat([pd.DataFrame(summary), per], ignore_index=True)


def model_errors(entries) -> list[dict]:
    """Each ``{name, table, row, column}``: the number in ``column`` of the row whose first column
    is ``row`` in the CSV ``table``. A table that is not there (a workspace without the default
    run's committed tables) leaves its entry out, said on stderr: the factor rows do not need it.
    A row or column missing from a table that is there is a one-line FeederError."""
    out = []
    for e in entries:
        try:
            name, path, key, column = str(e["name"]), str(e["table"]), str(e["row"]), str(e["column"])
        except (KeyError, TypeError):
            raise FeederError(f"model_errors entry {e!r}: needs name, table, row and column") from None
        if not Path(path).is_file():
            print(f"feeder bench-physics-table: model error {name!r} left out: {path} is not there", file=sys.stderr)
            continue
        try:
            t = pd.read_csv(path)
        except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
            raise FeederError(f"model error {name!r}: {path}: {err}") from None
        hit = t[t.iloc[:, 0].astype(str) == key]
        if hit.empty or column not in t.columns:
            raise FeederError(f"model error {name!r}: {path} has no row {key!r} with a column {column!r}")
        out.append(
            {"name": name, "value": float(hit[column].iloc[0]), "source": f"{path}: {t.columns[0]}={key}, {column}"}
        )
    return out


def read_raw(path) -> pd.DataFrame:
    """The raw drops written by ``feeder bench-physics --out-raw``."""
    try:
        raw = pd.read_csv(
            path,
            dtype={"status": str, "offset": str, "path": str, "level": str, "factor": str},
            keep_default_na=False,
            na_values={"final_yaw_deg": [""], "initial_yaw_deg": [""]},
        )
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise FeederError(f"--raw {path}: {err}") from None
    need = {
        "part",
        "configuration",
        "factor",
        "path",
        "level",
        "offset",
        "yaw_shift_deg",
        "drop",
        "final_yaw_deg",
        "status",
        "cpu_s",
    }
    missing = sorted(need - set(raw.columns))
    if missing:
        raise FeederError(f"--raw {path}: lacks the column(s) {', '.join(missing)}")
    return raw


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-physics-table", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {sim, labels} config sections")
    parser.add_argument("--raw", required=True, help="the raw drops of feeder bench-physics (CSV)")
    parser.add_argument(
        "--out-csv", required=True, help="the table: per configuration, per factor, floor, model errors (CSV)"
    )
    args = parser.parse_args(argv)
    from feeder.config import parse_settings
    from feeder.io import write_csv

    cfg = parse_settings(args.settings, "sim", "labels")
    try:
        bench = cfg["sim"]["physics_bench"]
        resamples, seed = int(bench["bootstrap"]), int(bench["seed"])
        bins, sigma = int(cfg["labels"]["bins"]), float(cfg["labels"]["sigma_bins"])
        entries = list(bench["model_errors"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    if resamples < 1:
        raise FeederError(f"sim.physics_bench.bootstrap must be positive, got {resamples}")
    errors = model_errors(entries)
    order = [f.get("name") for f in bench.get("factors", []) if isinstance(f, dict)]
    table = summarize(read_raw(args.raw), bins, sigma, resamples, seed, errors, order)
    write_csv(args.out_csv, table)
    for _, v in table[table["kind"].isin(["factor", "floor"])].iterrows():
        print(
            f"{v['factor']:>24}: circular W1 median {v['circular_w1_deg_median']:.2f} deg "
            f"[{v['circular_w1_deg_median_low']:.2f}, {v['circular_w1_deg_median_high']:.2f}], sup|dCDF| "
            f"{v['sup_cdf_median']:.3f}, same basin {v['same_basin_median']:.2f}, "
            f"|dyaw| {v['median_dyaw_deg_median']:.2f} deg",
            file=sys.stderr,
        )
    for e in errors:
        print(f"{e['name']:>24}: circular W1 {e['value']:.2f} deg ({e['source']})", file=sys.stderr)
    return 0
