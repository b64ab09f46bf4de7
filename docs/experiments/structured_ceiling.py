"""How low can a predictor built on candidate orientations go? (issue #39, the structured predictor)

An oracle, not a predictor: for each configuration it keeps the label's own mass within
``WINDOW_DEG`` of a set of candidate orientations (so masses, offsets and widths are perfect
there) and puts the rest of the mass on the analytic PMF. Its circular W1 to the label is the
floor of any predictor that places mass only near those orientations and otherwise falls back on
the analytic model. Three candidate sets:

* ``candidates``: the modes of the analytic push model and its variants
  (``feeder.mechanics.candidates``; the structured predictor's candidates);
* ``neighbour``: the modes (basins of >= ``MIN_BASIN`` mass) of the label of the part's nearest
  training configuration of the same fence types (``feeder.learn.neighbour.neighbour_index``);
* ``union``: both.

Rows: the dataset's own Test and Fences rows (training rows: its Train split), and every kept row
for ``candidates`` alone (what an unseen part can have). Run from a results folder that holds the
dataset and the structured predictor's candidates cache (written by ``feeder structured``):

    python docs/experiments/structured_ceiling.py results/datasets/dataset.npz \
        results/datasets/structured_candidates.npz results/tables/structured_ceiling.csv

Writes one row per configuration and candidate set (raw, so a new statistic needs no rerun) and
prints the means.
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
from feeder.learn.neighbour import neighbour_index

WINDOW_DEG = 5.0  # the candidates' basin half-width (config/hydra/structured.yaml candidates.window_deg)
MIN_BASIN = 0.01  # a neighbour's basin counts from this mass (candidates.min_mass)


def oracle_pmf(label: np.ndarray, analytic: np.ndarray, positions) -> tuple[np.ndarray, float]:
    """The label on the bins within WINDOW_DEG of a position, the rest of the mass on the analytic
    PMF's other bins (on all bins if it has none there); also the covered share of the label."""
    bins = label.size
    centres = (np.arange(bins) + 0.5) * FULL_TURN_DEG / bins
    covered = np.zeros(bins, dtype=bool)
    for p in np.atleast_1d(positions):
        covered |= circular_distance(centres, float(p)) <= WINDOW_DEG
    share = float(label[covered].sum())
    rest = np.where(covered, 0.0, analytic)
    if rest.sum() <= 0:
        rest = analytic if analytic.sum() > 0 else np.full(bins, 1.0 / bins)
    return label * covered + (1.0 - share) * rest / rest.sum(), share


def main(argv: list[str]) -> int:
    dataset, cache, out = Path(argv[0]), Path(argv[1]), Path(argv[2])
    data = load_dataset(dataset)
    with np.load(cache, allow_pickle=False) as z:
        k, pos, analytic = z["k"], z["pos"], z["analytic"]
    n = len(data["part"])  # kept rows come first in the cache
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    ana = np.asarray(analytic[:n], dtype=np.float64)
    parts, cids, split = (np.asarray(data[key]).astype(str) for key in ("part", "config_id", "split"))
    train = split == "train"
    known = np.flatnonzero(np.isin(split, ["test", "fences"]))
    neigh = dict(zip(known, neighbour_index(parts, cids, train, known), strict=True))
    rows = []
    for i in range(n):
        cand = pos[i, : k[i]]
        sets = {"candidates": cand}
        j = neigh.get(i, -1)
        if j >= 0:
            modes = [yaw for yaw, mass in resting_orientations(pmf[j]) if mass >= MIN_BASIN]
            sets["neighbour"] = np.array(modes)
            sets["union"] = np.concatenate([cand, modes])
        label_cdf = np.cumsum(pmf[i])
        base = float(circular_w1(label_cdf, np.cumsum(ana[i] / max(ana[i].sum(), 1e-300))))
        for name, positions in sets.items():
            q, share = oracle_pmf(pmf[i], ana[i], positions)
            rows.append(
                {
                    "part": parts[i],
                    "config_id": cids[i],
                    "split": split[i],
                    "has_neighbour": j >= 0,
                    "candidate_set": name,
                    "positions": int(np.size(positions)),
                    "covered_mass": share,
                    "oracle_cw1_deg": float(circular_w1(label_cdf, np.cumsum(q))),
                    "analytic_cw1_deg": base,
                }
            )
    frame = pd.DataFrame(rows)
    io.write_csv(out, frame)
    summary = frame.groupby(["split", "has_neighbour", "candidate_set"]).agg(
        n=("oracle_cw1_deg", "size"),
        oracle_cw1_deg=("oracle_cw1_deg", "mean"),
        analytic_cw1_deg=("analytic_cw1_deg", "mean"),
        covered_median=("covered_mass", "median"),
        covered_mean=("covered_mass", "mean"),
        positions=("positions", "mean"),
    )
    print(summary.to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
