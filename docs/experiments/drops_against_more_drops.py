"""Is the structured predictor reading k drops better than simulating more drops? (issue #39)

``feeder structured model.drops=K`` compares the predictor with the label of the same K drops
(baseline ``drops``). The next question on the frontier is the simulator with more drops. This
script pairs the protocol's rows (``structured_rows.csv`` of that run) with the label of the first
``M`` start-grid drops of each configuration (``empirical`` rows of
``drop_candidates_ceiling.py``'s CSV) and writes, per experiment, the mean circular W1 of each and
their paired difference with a 95 % bootstrap interval over the experiment's units (parts for
unseen parts, configurations for Test and Fences, as the protocol):

    python docs/experiments/drops_against_more_drops.py results/tables/structured_drops4_rows.csv \
        results/tables/drop_candidates_ceiling.csv 8 results/tables/structured_drops4_against_drops8.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from feeder import io
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.structured_protocol import STRUCTURED, UNITS

RESAMPLES, LEVEL, SEED = 10000, 0.95, 0


def main(argv: list[str]) -> int:
    rows_path, ceiling_path, m, out = Path(argv[0]), Path(argv[1]), int(argv[2]), Path(argv[3])
    rows = pd.read_csv(rows_path)
    rows = rows[rows.kept & (rows.predictor == STRUCTURED)]
    ceiling = pd.read_csv(ceiling_path)
    more = ceiling[(ceiling.k == m) & (ceiling.candidate_set == "empirical")]
    more = more.set_index(["part", "config_id"]).oracle_cw1_deg.rename("more")
    table = []
    for experiment, unit in UNITS.items():
        r = rows[rows.experiment == experiment]
        if r.empty:
            continue
        per = r.groupby(["repeat", "part", "config_id"]).cw1.mean().rename("model").reset_index()
        per = per.join(more, on=["part", "config_id"]).dropna()
        # a unit's score averaged over its seeds and repeats, as the protocol's unit_scores
        per = per.groupby("part" if unit == "part" else ["part", "config_id"])[["model", "more"]].mean()
        mean, lo, hi = paired_bootstrap((per.model - per.more).to_numpy(), RESAMPLES, LEVEL, SEED)
        table.append(
            {
                "experiment": experiment,
                "unit": unit,
                "n": len(per),
                "structured": per.model.mean(),
                f"drops{m}": per.more.mean(),
                "diff": mean,
                "diff_low": lo,
                "diff_high": hi,
            }
        )
    frame = pd.DataFrame(table)
    io.write_csv(out, frame)
    print(frame.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
