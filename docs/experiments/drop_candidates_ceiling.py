"""Would a few simulated drops give an unseen part its candidates? (issue #39, unseen parts)

The candidates of the analytic push model and its variants cap a predictor for unseen parts at
12.6 deg per part (``structured_ceiling.py``), and scaled exit turns do not lift that cap
(``exit_scale_ceiling.py``). The other source the ceiling section names is a few simulated drops.
This script reads the study's simulation files and, for each kept configuration, takes ``k`` drops
of its start grid spread evenly over the turn (every ``n0 / k``-th start yaw, the study's first
drops; no new simulation), and scores:

* ``drops_k`` (the oracle of ``structured_ceiling.py`` on the final yaws of those drops that did
  not jam or fall): the floor of any predictor that places its mass near where k drops ended;
* ``candidates+drops_k``: the same with the analytic candidates added;
* ``empirical_k``: the k drops' own label (their final yaws, equal weights, smoothed as the
  labels are), what simulating those k drops alone answers.

    python docs/experiments/drop_candidates_ceiling.py results/datasets/dataset.npz \
        results/datasets/structured_candidates.npz results/sim results/tables/drop_candidates_ceiling.csv

Writes one row per configuration, k and candidate set (raw) and prints the per-part means (what
GroupKFold averages).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from structured_ceiling import oracle_pmf

from feeder import io
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.learn.structured_data import drops_label, start_grid_drops

KS = (4, 8)  # drops per configuration
OK = "ok"  # the status of a drop that left the fences


def main(argv: list[str]) -> int:
    dataset, cache, sim_dir, out = Path(argv[0]), Path(argv[1]), Path(argv[2]), Path(argv[3])
    data = load_dataset(dataset)
    with np.load(cache, allow_pickle=False) as z:
        kc, pos, analytic = z["k"], z["pos"], z["analytic"]
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    bins = pmf.shape[1]
    sigma_bins = float(json.loads(str(data["settings"]))["labels"]["sigma_bins"])
    parts, cids = (np.asarray(data[key]).astype(str) for key in ("part", "config_id"))
    frames = np.asarray(data["frame_deg"], dtype=np.float64)
    rows = []
    for i in range(len(parts)):
        with np.load(Path(sim_dir) / parts[i] / f"{cids[i]}.npz", allow_pickle=False) as z:
            initial, final, status = z["initial_yaw_deg"], z["final_yaw_deg"], z["status"].astype(str)
            design = json.loads(str(z["meta"]))["design"]
        period = float(design["period_deg"])
        copies = np.arange(int(round(360.0 / period))) * period  # a symmetric part's equivalent yaws
        label_cdf = np.cumsum(pmf[i])
        cand = pos[i, : kc[i]]
        for k in KS:
            pick = start_grid_drops(initial, design, k)
            good = pick[status[pick] == OK]
            yaws = np.mod((final[good] + frames[i])[:, None] + copies[None, :], 360.0).ravel()
            sets = {"drops": yaws, "candidates+drops": np.concatenate([cand, yaws])}
            for name, positions in sets.items():
                q, share = oracle_pmf(pmf[i], analytic[i], positions)
                rows.append(_row(parts[i], cids[i], data["split"][i], k, name, good.size, share, label_cdf, q))
            if good.size:
                emp = drops_label(final[good], period, frames[i], bins, sigma_bins)
            else:
                emp = analytic[i]
            rows.append(_row(parts[i], cids[i], data["split"][i], k, "empirical", good.size, np.nan, label_cdf, emp))
        if i % 200 == 0:
            print(f"{i} of {len(parts)}", file=sys.stderr, flush=True)
    frame = pd.DataFrame(rows)
    io.write_csv(out, frame)
    per_part = frame.groupby(["k", "candidate_set", "part"]).oracle_cw1_deg.mean().groupby(["k", "candidate_set"])
    print("per-part mean cW1 (deg):")
    print(per_part.mean().round(2).to_string())
    return 0


def _row(part, cid, split, k, name, ok_drops, share, label_cdf, q) -> dict:
    return {
        "part": part,
        "config_id": cid,
        "split": str(split),
        "k": int(k),
        "candidate_set": name,
        "ok_drops": int(ok_drops),
        "covered_mass": share,
        "oracle_cw1_deg": float(circular_w1(label_cdf, np.cumsum(q))),
    }


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
