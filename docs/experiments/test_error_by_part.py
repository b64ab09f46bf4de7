"""Where the shipped predictor's Test error sits, part by part (stop 74).

From the committed protocol rows (``results/tables/structured_rows.csv``): each part's mean circular
W1 of the seed ensemble over its kept Test rows (every repeat), its row count and its share of the
summed error, largest share first; then the mean without the parts that carry the most:

    python docs/experiments/test_error_by_part.py results/tables/structured_test_by_part.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from feeder import io

TOP = 5  # parts left out in the printed "without" mean


def by_part(rows: pd.DataFrame) -> pd.DataFrame:
    """Per part: ``rows`` (scored rows), ``mean_cw1``, ``share`` of the summed error (largest first)."""
    test = rows[(rows.experiment == "test") & (rows.predictor == "structured_ensemble") & rows.kept]
    out = test.groupby("part").cw1.agg(rows="count", mean_cw1="mean", total="sum")
    out["share"] = out.total / out.total.sum()
    return out.drop(columns="total").sort_values("share", ascending=False).reset_index()


def main(argv: list[str]) -> int:
    rows = pd.read_csv("results/tables/structured_rows.csv")
    table = by_part(rows)
    io.write_csv(Path(argv[0]), table)
    test = rows[(rows.experiment == "test") & (rows.predictor == "structured_ensemble") & rows.kept]
    top = table.part[:TOP]
    print(table.head(12).round(2).to_string(index=False))
    print(
        f"all {len(table)} parts: {test.cw1.mean():.2f} deg over {len(test)} rows; the top {TOP} carry "
        f"{table.share[:TOP].sum():.0%}; without them {test[~test.part.isin(top)].cw1.mean():.2f} deg"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
