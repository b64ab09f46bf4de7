"""Two runs of ``feeder structured`` paired on the same rows (issue #39).

A change to the structured predictor (a setting fixed beforehand) is judged by the protocol's own
criterion, the validation circular W1 of each fit (``structured_choices.csv``); the reported sets
then say whether it carries over. This script pairs a run's rows with a base run's, per experiment
both runs scored: the structured predictor's circular W1 per unit (parts for unseen parts,
configurations for Test and Fences, each averaged over its seeds and repeats, as the protocol),
for the seeds one by one and their averaged PMF, the mean of each and the paired difference (run
minus base) with a 95 % bootstrap interval, for Test and Fences also with the configurations'
differences averaged per part and the interval over parts (unit ``part``); and the fits'
validation scores side by side:

    python docs/experiments/structured_paired.py results/tables/structured_coc_rows.csv \
        results/tables/structured_rows.csv results/tables/structured_coc_choices.csv \
        results/tables/structured_choices.csv results/tables/structured_coc_paired.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from feeder import io
from feeder.learn.structured_protocol import ENSEMBLE, STRUCTURED, UNITS, paired_runs

BOOTSTRAP = {"resamples": 10000, "level": 0.95, "seed": 0}


def paired(run: pd.DataFrame, base: pd.DataFrame) -> pd.DataFrame:
    out = []
    for experiment in UNITS:
        for model in (STRUCTURED, ENSEMBLE):
            for by_part in (False, True) if UNITS[experiment] == "configuration" else (False,):
                pair = paired_runs(run, base, experiment, model, BOOTSTRAP, by_part=by_part)
                unit = "part" if by_part else UNITS[experiment]
                if pair is not None:
                    out.append({"what": experiment, "model": model, "unit": unit, **pair})
    return pd.DataFrame(out)


def validation(run: pd.DataFrame, base: pd.DataFrame) -> pd.DataFrame:
    both = run[["fit", "val_cw1"]].merge(base[["fit", "val_cw1"]], on="fit", suffixes=("", "_base")).set_index("fit")
    return pd.DataFrame(
        [
            {
                "what": f"validation {fit}",
                "model": STRUCTURED,
                "unit": "fit",
                "n": 1,
                "run": r.val_cw1,
                "base": r.val_cw1_base,
            }
            for fit, r in both.iterrows()
        ]
    )


def main(argv: list[str]) -> int:
    run_rows, base_rows, run_choices, base_choices, out = map(Path, argv[:5])
    table = pd.concat(
        [
            validation(pd.read_csv(run_choices), pd.read_csv(base_choices)),
            paired(pd.read_csv(run_rows), pd.read_csv(base_rows)),
        ],
        ignore_index=True,
    )
    io.write_csv(out, table)
    print(table.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
