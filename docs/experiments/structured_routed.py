"""What the protocol would report with the Fences specialist wired in (issue #39), from two runs' rows.

The specialist (``model.cross_only``) would answer the rows with no label of their own fence-type
combination among their fit's training rows (every Fences row and a few Test rows), the default
network every other row. This script builds those routed rows from a default run's rows and a
specialist run's rows (the three Main fits of each), fitting nothing, and pairs them with the
default run's rows as ``structured_paired.py`` does (per configuration, seeds one by one and
averaged; 95 % bootstrap):

    python docs/experiments/structured_routed.py results/datasets/dataset.npz \\
        results/tables/structured_rows.csv results/tables/structured_crossonly_rows.csv \\
        results/tables/structured_routed.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.learn.structured_data import split_arrays
from feeder.learn.structured_protocol import ENSEMBLE, STRUCTURED, neighbour_distances, paired_runs

BOOTSTRAP = {"resamples": 10000, "level": 0.95, "seed": 0}
KEY = ["experiment", "repeat", "part", "config_id"]
SETS = ("test", "fences")


def routed(default: pd.DataFrame, specialist: pd.DataFrame, no_own: pd.DataFrame) -> pd.DataFrame:
    """``default``'s rows, but those of ``no_own`` (KEY columns) taken from ``specialist``."""

    def flagged(rows):
        return rows.merge(no_own.assign(_route=True), on=KEY, how="left")._route.eq(True).to_numpy()

    return pd.concat([default[~flagged(default)], specialist[flagged(specialist)]], ignore_index=True)


def main(argv: list[str]) -> int:
    if len(argv) != 4:
        raise SystemExit(__doc__)
    dataset, default_rows, specialist_rows, out = (Path(a) for a in argv)
    dist = neighbour_distances(split_arrays(load_dataset(dataset)), compose_config("structured", []))
    no_own = dist.loc[~np.isfinite(dist.neighbour_deg), KEY]
    default = pd.read_csv(default_rows)
    default = default[default.experiment.isin(SETS)]
    specialist = pd.read_csv(specialist_rows)
    both = routed(default, specialist[specialist.experiment.isin(SETS)], no_own)
    table = []
    for experiment in SETS:
        n_routed = int((no_own.experiment == experiment).sum())
        for model in (STRUCTURED, ENSEMBLE):
            pair = paired_runs(both, default, experiment, model, BOOTSTRAP)
            table.append({"what": experiment, "model": model, "routed_row_repeats": n_routed, **pair})
    frame = pd.DataFrame(table)
    io.write_csv(out, frame)
    print(frame.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
