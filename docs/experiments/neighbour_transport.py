"""Does moving a neighbour's label as the analytic model moves help? (issue #39, untrained)

For each Test row of the dataset's own split with a training neighbour (the part's two nearest
training configurations of the same fence types, ``feeder.learn.structured_data.nearest_rows``):

* ``neighbour``: the nearest neighbour's label as it is;
* ``transport``: that label pushed through the circular monotone (W1-optimal) map that carries the
  neighbour's analytic PMF onto the row's, so a basin moves as the analytic model's basin moves and
  mass shifts between basins as the analytic masses do (no training, no label of the row read);
* ``mix2``: the two nearest labels mixed by inverse angle distance; ``transport2``: the same mix of
  their transported labels;
* ``analytic``: the row's analytic PMF.

Run from a results folder that holds the dataset and the structured predictor's candidates cache:

    python docs/experiments/neighbour_transport.py results/datasets/dataset.npz \
        results/datasets/structured_candidates.npz results/tables/neighbour_transport.csv

Writes one row per configuration (raw) and prints the means, the per-row oracle of choosing the
best of some answers (a bound on what a learned choice could gain), and a 95 % paired bootstrap of
``transport`` against ``neighbour``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.structured_data import nearest_rows

FLOOR = 1e-3  # total mass spread evenly over an analytic PMF, so the map is defined where it has none
SUB = 8  # sub-bins per bin when the label's mass is carried through the map


def transport(label, analytic_from, analytic_to):
    """``label`` pushed through the circular monotone map of ``analytic_from`` onto ``analytic_to``."""
    bins = label.size
    a = (analytic_from + FLOOR / bins) / (analytic_from.sum() + FLOOR)
    b = (analytic_to + FLOOR / bins) / (analytic_to.sum() + FLOOR)
    fa, fb = np.cumsum(a), np.cumsum(b)
    cut = np.median(fa - fb)  # the optimal cut of the circle (as circular W1 takes it)
    x = (np.arange(bins * SUB) + 0.5) / SUB
    level = np.mod(np.interp(x, np.arange(bins + 1), np.concatenate([[0.0], fa])) - cut, 1.0)
    y = np.interp(level, np.concatenate([[0.0], fb]), np.arange(bins + 1))
    out = np.bincount(np.floor(y).astype(int) % bins, weights=np.repeat(label / SUB, SUB), minlength=bins)
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
    idx, dist = nearest_rows(parts, cids, split == "train", rows, 2)
    records = []
    for n, i in enumerate(rows):
        j, j2 = idx[n]
        if j < 0:
            continue
        moved = transport(pmf[j], analytic[j], analytic[i])
        answers = {"neighbour": pmf[j], "transport": moved, "analytic": analytic[i]}
        answers["mix2"], answers["transport2"] = pmf[j], moved
        if j2 >= 0:
            w = 1.0 / (dist[n] + 1.0)
            w = w / w.sum()
            answers["mix2"] = w[0] * pmf[j] + w[1] * pmf[j2]
            answers["transport2"] = w[0] * moved + w[1] * transport(pmf[j2], analytic[j2], analytic[i])
        truth = np.cumsum(pmf[i])
        rec = {"part": parts[i], "config_id": cids[i], "neighbour_config_id": cids[j]}
        rec.update({f"{k}_cw1_deg": float(circular_w1(truth, np.cumsum(v))) for k, v in answers.items()})
        records.append(rec)
    frame = pd.DataFrame(records)
    io.write_csv(out, frame)
    cols = [c for c in frame.columns if c.endswith("_cw1_deg")]
    print(frame[cols].agg(["mean", "median"]).round(2).to_string())
    for names in (("neighbour", "analytic"), ("neighbour", "analytic", "transport")):
        best = frame[[f"{k}_cw1_deg" for k in names]].min(axis=1).mean()
        print(f"per-row best of {', '.join(names)}: {best:.2f} deg")
    diff = (frame["transport_cw1_deg"] - frame["neighbour_cw1_deg"]).to_numpy()
    mean, lo, hi = paired_bootstrap(diff, 10000, 0.95, 0)
    print(f"transport - neighbour: {mean:+.2f} [{lo:+.2f}, {hi:+.2f}] deg over {len(frame)} Test configurations")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
