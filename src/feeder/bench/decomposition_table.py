"""The decomposition test's table from its raw drops (``feeder bench-decomposition-table``).

Issue #37, item 1: :mod:`feeder.bench.decomposition` simulates each part under each convex
decomposition and contact model and keeps every drop; this module compares the runs (pure) and
writes one row per comparison with its floors, then one verdict row per model (see that module's
docstring for the floors and the pass rule). Rebuilding the table simulates nothing.
"""

from __future__ import annotations

import argparse
import itertools
import math
import re
import sys

import numpy as np
import pandas as pd

from feeder.bench.decomposition import LIBRARY
from feeder.errors import FeederError


def label_cdf(final, status, bins: int, sigma: float) -> np.ndarray | None:
    """CDF of the label of a run's ok drops (None without one)."""
    from feeder.labels import metrics as L

    ok = np.asarray(status).astype(str) == "ok"
    if not ok.any():
        return None
    return L.cdf(L.pmf_from_yaws(np.asarray(final, np.float64)[ok], bins, sigma))


def compare(x: pd.DataFrame, y: pd.DataFrame, bins: int, sigma: float) -> dict:
    """Two runs of the same drops: same-basin fraction and median |Δ final yaw| (paired,
    :func:`feeder.bench.designs.paired_basins`), sup|ΔCDF| and circular W1 of their labels."""
    from feeder.bench.designs import paired_basins
    from feeder.labels import metrics as L

    x, y = x.sort_values("drop"), y.sort_values("drop")
    out = {}
    if len(x) == len(y):
        pair = paired_basins(x["final_yaw_deg"], x["status"], y["final_yaw_deg"], y["status"])
        out |= {"same_basin": pair["same_basin"], "median_dyaw_deg": pair["median_dyaw_deg"]}
    else:
        out |= {"same_basin": math.nan, "median_dyaw_deg": math.nan}
    a, b = (
        label_cdf(x["final_yaw_deg"], x["status"], bins, sigma),
        label_cdf(y["final_yaw_deg"], y["status"], bins, sigma),
    )
    if a is None or b is None:
        out |= {"sup_cdf": math.nan, "circular_w1_deg": math.nan}
    else:
        out |= {"sup_cdf": float(L.ks(a, b)), "circular_w1_deg": float(L.circular_w1(a, b))}
    return out


METRICS = ("same_basin", "median_dyaw_deg", "sup_cdf", "circular_w1_deg")


PAIRED, LABEL = METRICS[:2], METRICS[2:]


def within_floor(row: dict, floor: dict, drops: int, factor: float, metrics=METRICS) -> bool:
    """Every distance of ``metrics`` in ``row`` within ``factor`` times ``floor``'s: the missed-basin
    share (1 - same basin; its floor at least one drop in ``drops``), median |Δyaw|, sup|ΔCDF|,
    circular W1. A NaN distance passes only where its floor is NaN too (e.g. no ok drop in either)."""
    checks = []
    for k in metrics:
        if k == "same_basin":  # in missed drops (whole numbers: no round-off at the bound)
            missed = lambda share: float(round((1.0 - share) * drops)) if not math.isnan(share) else math.nan  # noqa: E731
            checks.append((missed(row[k]), max(missed(floor[k]), 1.0)))
        else:
            checks.append((row[k], floor[k]))
    for value, bound in checks:
        if math.isnan(value) or math.isnan(bound):
            if not (math.isnan(value) and math.isnan(bound)):
                return False
            continue
        if value > factor * bound:
            return False
    return True


def summarize(raw: pd.DataFrame, bins: int, sigma: float, factor: float) -> pd.DataFrame:
    """The table from the raw drops: per (part, configuration, model) its floor and one row per
    decomposition pair (``kind = decomposition``); per (part, configuration, decomposition) one row
    per pair of pad counts (``kind = convergence``); then one ``verdict`` row per model and per pad
    pair (``part = all``): rows passed out of rows, CPU per drop."""
    runs = {
        key: g for key, g in raw.groupby(["part", "configuration", "model", "decomposition", "offset", "yaw_shift_deg"])
    }
    floors, rows = {}, []
    for (part, config, model), g in raw.groupby(["part", "configuration", "model"], sort=True):
        plain = runs[(part, config, model, LIBRARY, "a", 0.0)]
        nudged = g[(g["decomposition"] == LIBRARY) & (g["yaw_shift_deg"] != 0)]
        other = runs[(part, config, model, LIBRARY, "b", 0.0)]
        paired, labels = compare(plain, nudged, bins, sigma), compare(plain, other, bins, sigma)
        floors[(part, config, model)] = floor = {
            "same_basin": paired["same_basin"],
            "median_dyaw_deg": paired["median_dyaw_deg"],
            "sup_cdf": labels["sup_cdf"],
            "circular_w1_deg": labels["circular_w1_deg"],
        }
        names = sorted(g.loc[g["offset"] == "a", "decomposition"].unique(), key=lambda n: (n != LIBRARY, n))
        for x, y in itertools.combinations(names, 2):
            rx, ry = runs[(part, config, model, x, "a", 0.0)], runs[(part, config, model, y, "a", 0.0)]
            rows.append(_row("decomposition", part, config, model, x, y, rx, ry, floor, bins, sigma, factor))
    pad_pairs = [pair for pads in pad_ladders(raw["model"].unique()) for pair in zip(pads, pads[1:])]
    for (part, config, name), _ in raw[raw["offset"] == "a"].groupby(["part", "configuration", "decomposition"]):
        for m1, m2 in pad_pairs:
            rx, ry = runs.get((part, config, m1, name, "a", 0.0)), runs.get((part, config, m2, name, "a", 0.0))
            if rx is None or ry is None:
                continue
            f1, f2 = floors[(part, config, m1)], floors[(part, config, m2)]
            floor = {"same_basin": min(f1["same_basin"], f2["same_basin"])} | {
                k: float(np.nanmax([f1[k], f2[k]])) if not (math.isnan(f1[k]) and math.isnan(f2[k])) else math.nan
                for k in METRICS[1:]
            }
            rows.append(_row("convergence", part, config, f"{m1}~{m2}", name, name, rx, ry, floor, bins, sigma, factor))
    table = pd.DataFrame(rows)
    cpu = {
        m: 1000.0
        * g.groupby(["part", "configuration", "decomposition", "offset", "yaw_shift_deg"])["cpu_s"].first().sum()
        / len(g)
        for m, g in raw.groupby("model")
    }
    verdicts = []
    for (kind, model), g in table.groupby(["kind", "model"], sort=False):
        verdicts.append(
            {
                "kind": "verdict",
                "part": "all",
                "configuration": "all",
                "model": model,
                "decomposition_a": kind,
                "rows": len(g),
                "rows_passed": int(g["passes"].sum()),
                "rows_passed_paired": int(g["passes_paired"].sum()),
                "rows_passed_label": int(g["passes_label"].sum()),
                "passes_paired": bool(g["passes_paired"].all()),
                "passes_label": bool(g["passes_label"].all()),
                "passes": bool(g["passes"].all()),
                "cpu_ms_per_drop": cpu.get(model, math.nan),
            }
            | {k: float(g[k].median()) for k in METRICS}
            | {f"floor_{k}": float(g[f"floor_{k}"].median()) for k in METRICS}
        )
    return pd.concat([table, pd.DataFrame(verdicts)], ignore_index=True)


def pad_ladders(models) -> list[list[str]]:
    """The pad models grouped by how walls and fences meet the part (the suffix after the pad
    count, e.g. ``+outline``), each ordered by pad count: the ladders whose neighbours the
    convergence test compares (pure; ``pieces`` and ``pieces+…`` have no pad count)."""
    ladders: dict[str, list[tuple[int, str]]] = {}
    for m in models:
        hit = re.fullmatch(r"pads([1-9][0-9]*)(.*)", str(m))
        if hit:
            ladders.setdefault(hit.group(2), []).append((int(hit.group(1)), str(m)))
    return [[m for _, m in sorted(ladders[suffix])] for suffix in sorted(ladders)]


def label_resolution(bins: int, drops: int) -> dict:
    """The least difference a label of ``drops`` drops over ``bins`` yaw bins can show (pure): half
    a bin of median |Δyaw| (a smaller shift need not move a drop to another bin), one drop's mass
    of sup|ΔCDF| and one drop moved by one bin of circular W1 (degrees)."""
    width = 360.0 / bins
    return {"median_dyaw_deg": width / 2.0, "sup_cdf": 1.0 / drops, "circular_w1_deg": width / drops}


def resolved_floor(floor: dict, bins: int, drops: int) -> dict:
    """``floor`` raised to :func:`label_resolution` where it is below it (a NaN floor stays NaN)."""
    least = label_resolution(bins, drops)
    return {k: v if k not in least or math.isnan(v) else max(v, least[k]) for k, v in floor.items()}


def _row(kind, part, config, model, x, y, rx, ry, own_floor, bins, sigma, factor) -> dict:
    dist = compare(rx, ry, bins, sigma)
    drops = len(rx)
    floor = resolved_floor(own_floor, bins, drops)
    return {
        "kind": kind,
        "part": part,
        "configuration": config,
        "model": model,
        "decomposition_a": x,
        "decomposition_b": y,
        "pieces_a": int(rx["pieces"].iloc[0]),
        "pieces_b": int(ry["pieces"].iloc[0]),
        "drops": drops,
        "ok_rate_a": float(np.mean(rx["status"] == "ok")),
        "ok_rate_b": float(np.mean(ry["status"] == "ok")),
        **dist,
        **{f"own_floor_{k}": v for k, v in own_floor.items()},
        **{f"floor_{k}": v for k, v in floor.items()},
        "passes_paired": within_floor(dist, floor, drops, factor, PAIRED),
        "passes_label": within_floor(dist, floor, drops, factor, LABEL),
        "passes": within_floor(dist, floor, drops, factor),
    }


def read_raw(path) -> pd.DataFrame:
    """The raw drops written by ``feeder bench-decomposition --out-raw`` (a status ``nan`` stays a
    string; an empty cell is NaN)."""
    try:
        return pd.read_csv(path, dtype={"status": str, "offset": str}, keep_default_na=False, na_values=[""])
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise FeederError(f"--raw {path}: {err}") from None


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-decomposition-table", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {sim, labels} config sections")
    parser.add_argument("--raw", required=True, help="the raw drops of feeder bench-decomposition (CSV)")
    parser.add_argument("--out-csv", required=True, help="the table: comparisons, floors and verdicts (CSV)")
    args = parser.parse_args(argv)
    from feeder.config import parse_settings
    from feeder.io import write_csv

    cfg = parse_settings(args.settings, "sim", "labels")
    try:
        factor = float(cfg["sim"]["decomposition_bench"]["floor_factor"])
        bins, sigma = int(cfg["labels"]["bins"]), float(cfg["labels"]["sigma_bins"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes {err}") from None
    table = summarize(read_raw(args.raw), bins, sigma, factor)
    write_csv(args.out_csv, table)
    for _, v in table[table["kind"] == "verdict"].iterrows():
        print(
            f"{v['decomposition_a']:>13} {v['model']:>13}: {'passes' if v['passes'] else 'FAILS '} "
            f"({v['rows_passed']:.0f}/{v['rows']:.0f} rows; paired {v['rows_passed_paired']:.0f}, label "
            f"{v['rows_passed_label']:.0f}), {v['cpu_ms_per_drop']:.0f} ms/drop; median "
            f"same basin {v['same_basin']:.2f} (floor {v['floor_same_basin']:.2f}), |dyaw| {v['median_dyaw_deg']:.2f} "
            f"deg ({v['floor_median_dyaw_deg']:.2f}), sup|dCDF| {v['sup_cdf']:.3f} ({v['floor_sup_cdf']:.3f}), "
            f"W1 {v['circular_w1_deg']:.2f} deg ({v['floor_circular_w1_deg']:.2f})",
            file=sys.stderr,
        )
    return 0
