"""Does the analytic model say how a neighbour's basins change with the angle? (issue #39, untrained)

For each Test row of the dataset's own split that has a training neighbour (the part's nearest
training configuration of the same fence types, ``feeder.learn.neighbour.neighbour_index``):

* ``neighbour``: the neighbour's label as it is;
* ``reweighted``: each basin of the neighbour's label (the bins within ``WINDOW_DEG`` of one of its
  modes of >= ``MIN_BASIN`` mass) scaled by how much the analytic PMF's mass in those bins grows
  or shrinks from the neighbour's configuration to the row's, ``(A_row + EPS) / (A_nb + EPS)``,
  then normalised; no training, no label of the row read;
* ``analytic``: the row's analytic PMF.

Run from a results folder that holds the dataset and the structured predictor's candidates cache
(its analytic PMFs in the label frame):

    python docs/experiments/neighbour_reweighted.py results/datasets/dataset.npz \
        results/datasets/structured_candidates.npz results/tables/neighbour_reweighted.csv

Writes one row per configuration (raw) and prints the means with a 95 % paired bootstrap of
``reweighted`` against ``neighbour``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.circular import FULL_TURN_DEG, circular_distance
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1, resting_orientations
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.neighbour import neighbour_index

WINDOW_DEG = 5.0  # a basin's half-width around its mode (candidates.window_deg)
MIN_BASIN = 0.01  # a mode counts from this basin mass (candidates.min_mass)
EPS = 0.01  # added to both analytic masses: a basin the model gives nothing keeps a finite factor


def reweighted(label_nb: np.ndarray, analytic_row: np.ndarray, analytic_nb: np.ndarray) -> np.ndarray:
    """The neighbour's label with each basin scaled by the analytic model's change (module doc)."""
    bins = label_nb.size
    centres = (np.arange(bins) + 0.5) * FULL_TURN_DEG / bins
    factor = np.ones(bins)
    for yaw, mass in resting_orientations(label_nb):
        if mass < MIN_BASIN:
            continue
        inside = circular_distance(centres, yaw) <= WINDOW_DEG
        factor[inside] = (analytic_row[inside].sum() + EPS) / (analytic_nb[inside].sum() + EPS)
    out = label_nb * factor
    return out / out.sum()


def main(argv: list[str]) -> int:
    dataset, cache, out = Path(argv[0]), Path(argv[1]), Path(argv[2])
    data = load_dataset(dataset)
    with np.load(cache, allow_pickle=False) as z:
        analytic = np.asarray(z["analytic"][: len(data["part"])], dtype=np.float64)
    analytic = analytic / np.clip(analytic.sum(axis=1, keepdims=True), 1e-300, None)
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    parts, cids, split = (np.asarray(data[key]).astype(str) for key in ("part", "config_id", "split"))
    rows = np.flatnonzero(split == "test")
    idx = neighbour_index(parts, cids, split == "train", rows)
    records = []
    for i, j in zip(rows, idx, strict=True):
        if j < 0:
            continue
        truth = np.cumsum(pmf[i])
        answers = {
            "neighbour": pmf[j],
            "reweighted": reweighted(pmf[j], analytic[i], analytic[j]),
            "analytic": analytic[i],
        }
        rec = {"part": parts[i], "config_id": cids[i], "neighbour_config_id": cids[j]}
        rec.update({f"{k}_cw1_deg": float(circular_w1(truth, np.cumsum(v))) for k, v in answers.items()})
        records.append(rec)
    frame = pd.DataFrame(records)
    io.write_csv(out, frame)
    print(frame[[c for c in frame.columns if c.endswith("_cw1_deg")]].agg(["mean", "median"]).round(2).to_string())
    diff = (frame["reweighted_cw1_deg"] - frame["neighbour_cw1_deg"]).to_numpy()
    mean, lo, hi = paired_bootstrap(diff, 10000, 0.95, 0)
    print(f"reweighted - neighbour: {mean:+.2f} [{lo:+.2f}, {hi:+.2f}] deg over {len(frame)} Test configurations")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
