"""Would more labelled parts carry the structured predictor to the targets? (issue #39)

A learning curve of the protocol's three Main fits. ``feeder structured protocol.fits=[main]
protocol.fit_part_fraction=F`` trains each fit's network on a share F of its non-validation parts;
the validation parts (early stopping, the search), the scored rows' neighbours and every baseline
stay as at F = 1 (``tests/test_structured.py``). This script reads each run's choices and rows
and writes, per fraction:

- per Main fit: the parts and rows the network trained on and its validation circular W1 (the
  protocol's own criterion: rows of parts no fit trained on);
- per reported set (Test, Fences), the structured predictor's mean circular W1 (seeds scored one
  by one, and their averaged PMF) and its paired difference from the same rows at the largest
  fraction (95 % bootstrap over configurations, as the protocol);

the slope of each against log2 of the rows trained on (least squares over the fractions: degrees
gained per doubling of the training parts, ``<out>`` with ``_slopes`` before its suffix), and a
figure of both against the rows trained on:

    python docs/experiments/structured_learning_curve.py results/tables/structured_learning_curve.csv \
        docs/figures/structured_learning_curve.png \
        0.5 CHOICES_50.csv ROWS_50.csv 0.75 CHOICES_75.csv ROWS_75.csv 1 CHOICES.csv ROWS.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.learn.structured_protocol import ENSEMBLE, STRUCTURED, paired_runs

BOOTSTRAP = {"resamples": 10000, "level": 0.95, "seed": 0}
SETS = ("test", "fences")


def read_runs(args: list[str]) -> list[tuple[float, pd.DataFrame, pd.DataFrame]]:
    if len(args) % 3 or not args:
        raise SystemExit("give FRACTION CHOICES.csv ROWS.csv triples")
    runs = []
    for i in range(0, len(args), 3):
        choices = pd.read_csv(args[i + 1])
        rows = pd.read_csv(args[i + 2])
        runs.append((float(args[i]), choices[choices.fit.str.startswith("main")], rows))
    return sorted(runs, key=lambda r: r[0])


def curve(runs) -> pd.DataFrame:
    top = runs[-1]
    out = []
    for fraction, choices, rows in runs:
        for _, c in choices.iterrows():
            out.append(
                {
                    "fraction": fraction,
                    "what": "validation",
                    "fit": c.fit,
                    "model": STRUCTURED,
                    "train_parts": int(c.train_parts - c.val_parts),
                    "fit_rows": int(c.fit_rows),
                    "n": int(c.val_rows),
                    "cw1": float(c.val_cw1),
                }
            )
        for experiment in SETS:
            for model in (STRUCTURED, ENSEMBLE):
                pair = paired_runs(rows, top[2], experiment, model, BOOTSTRAP)
                if pair is None:
                    continue
                out.append(
                    {
                        "fraction": fraction,
                        "what": experiment,
                        "fit": "main (3 splits)",
                        "model": model,
                        "train_parts": int((choices.train_parts - choices.val_parts).mean()),
                        "fit_rows": int(round(choices.fit_rows.mean())),
                        "n": pair["n"],
                        "cw1": pair["run"],
                        "diff_from_largest": pair["diff"],
                        "diff_low": pair["diff_low"],
                        "diff_high": pair["diff_high"],
                    }
                )
    return pd.DataFrame(out)


def slopes(table: pd.DataFrame) -> pd.DataFrame:
    """Circular W1 against log2(rows trained on): the least-squares slope (degrees per doubling)
    of the validation mean of the Main fits and of each reported set's averaged seeds."""
    val = table[table.what == "validation"].groupby("fraction").agg(fit_rows=("fit_rows", "mean"), cw1=("cw1", "mean"))
    series = {"validation": val}
    for experiment in SETS:
        t = table[(table.what == experiment) & (table.model == ENSEMBLE)].set_index("fraction")
        if not t.empty:
            series[experiment] = t[["fit_rows", "cw1"]]
    out = []
    for what, t in series.items():
        slope, intercept = np.polyfit(np.log2(t.fit_rows.to_numpy(float)), t.cw1.to_numpy(float), 1)
        out.append(
            {
                "what": what,
                "points": len(t),
                "slope_deg_per_doubling": float(slope),
                "cw1_at_largest": float(t.cw1.iloc[-1]),
                "fit_rows_at_largest": float(t.fit_rows.iloc[-1]),
            }
        )
    return pd.DataFrame(out)


def figure(table: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    val = table[table.what == "validation"].groupby("fraction").agg(rows=("fit_rows", "mean"), cw1=("cw1", "mean"))
    ax.plot(val.rows, val.cw1, "o-", label="validation parts (mean of the 3 Main fits)")
    for experiment, marker in zip(SETS, ("s", "^"), strict=True):
        t = table[(table.what == experiment) & (table.model == ENSEMBLE)].sort_values("fit_rows")
        if t.empty:
            continue
        err = np.vstack([t.diff_from_largest - t.diff_low, t.diff_high - t.diff_from_largest])
        err = np.where(t.fraction.to_numpy() == t.fraction.max(), 0.0, err)
        ax.errorbar(t.fit_rows, t.cw1, yerr=err, fmt=marker + "--", capsize=3, label=f"{experiment} (seeds averaged)")
    targets = {"test": 6.0, "fences": 12.0}
    for experiment, y in targets.items():
        ax.axhline(y, color="grey", lw=0.8, ls=":")
        ax.text(ax.get_xlim()[0], y, f" target {experiment} ≤ {y:g}°", va="bottom", fontsize=8, color="grey")
    ax.set_xscale("log", base=2)
    ax.set_xticks(val.rows.to_numpy(), [f"{r:.0f}" for r in val.rows], minor=False)
    ax.minorticks_off()
    ax.set_xlabel("configurations the network trains on (per Main fit; log scale)")
    ax.set_ylabel("circular W1 (deg)")
    ax.set_title(
        "Structured predictor: error against training rows\n"
        "(bars: 95 % paired interval of the difference from the largest)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=120)
    tmp.replace(path)


def main(argv: list[str]) -> int:
    out, fig_path = Path(argv[0]), Path(argv[1])
    table = curve(read_runs(argv[2:]))
    io.write_csv(out, table)
    slope_table = slopes(table)
    io.write_csv(out.with_name(out.stem + "_slopes" + out.suffix), slope_table)
    figure(table, fig_path)
    print(table.to_string(index=False))
    print(slope_table.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
