"""Does a two-fence label compose from the part's one-fence labels? (issue #39, untrained)

A part leaves the upstream fence (Location 2) at rest on the belt and is carried without turning to
the downstream fence (Location 1). If the downstream stage depends on the arriving yaw alone, the
label of ``F1 | F2`` is the push-forward of the uniform initial yaw through the upstream drop map of
``none | F2`` and then through the downstream drop map of ``F1 | none``. Both maps are the sampled
maps of the simulation files (``feeder.sim.pushforward.map_yaws``), so the composition reads no
label of the row, only the part's own one-fence simulations.

For every kept two-fence configuration of the dataset, the upstream map is taken from the part's
labelled ``none | F2'`` nearest in angle to F2 among the training rows (the dataset's own split,
repeat 0), the downstream one from its ``F1' | none`` nearest to F1, both of the same fence types.
Composed in the dataset's label frame (``feeder.learn.structured_data.compose_maps``, as the
predictor's ``model.composed`` reads it) and scored by circular W1 against the row's label, beside
the analytic PMF and, where the protocol scored the row in repeat 0, the structured predictor
(mean over its seeds) from ``structured_rows.csv``. Rows whose two one-fence configurations are
at exactly the row's angles measure the composition's physics error alone.

    python docs/experiments/composed_neighbour.py RESULTS_DIR results/tables/structured_rows.csv \
        results/tables/composed_neighbour.csv

RESULTS_DIR holds ``datasets/dataset.npz``, ``datasets/structured_candidates.npz`` and ``sim/``.
Writes one row per configuration (raw) and prints means by split, angle distance and fence types, and 95 % paired
bootstraps of the composition against the analytic PMF and the structured predictor.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.labels.pmf import record_design
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.structured_data import compose_maps, one_fence_rows
from feeder.sim.record import load_sim


def main(argv: list[str]) -> int:
    results, rows_csv, out = Path(argv[0]), Path(argv[1]), Path(argv[2])
    data = load_dataset(results / "datasets" / "dataset.npz")
    parts, cids, split = (np.asarray(data[key]).astype(str) for key in ("part", "config_id", "split"))
    sigma = float(json.loads(str(data["settings"]))["labels"]["sigma_bins"])
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    with np.load(results / "datasets" / "structured_candidates.npz", allow_pickle=False) as z:
        analytic = np.asarray(z["analytic"][: parts.size], dtype=np.float64)
    analytic = analytic / analytic.sum(axis=1, keepdims=True)
    scored = pd.read_csv(rows_csv)
    scored = scored[(scored.repeat == 0) & scored.kept & (scored.predictor == "structured")]
    structured = scored[scored.experiment.isin(["test", "fences"])].groupby(["part", "config_id"]).cw1.mean()
    up, d_up, down, d_down = one_fence_rows(parts, cids, split == "train", np.arange(parts.size))
    designs = {}

    def design(j):
        if j not in designs:
            designs[j] = record_design(load_sim(results / "sim" / parts[j] / f"{cids[j]}.npz"))
        return designs[j]

    records = []
    for i in np.flatnonzero((up >= 0) & (down >= 0)):
        frame = float(data["frame_deg"][i])
        composed, share = compose_maps(design(up[i]), design(down[i]), frame, pmf.shape[1], sigma)
        truth = np.cumsum(pmf[i])
        records.append(
            {
                "part": parts[i],
                "config_id": cids[i],
                "split": split[i],
                "upstream": cids[up[i]],
                "downstream": cids[down[i]],
                "upstream_dist_deg": d_up[i],
                "downstream_dist_deg": d_down[i],
                "ok_composed": share,
                "composed_cw1_deg": float(circular_w1(truth, np.cumsum(composed))) if composed is not None else np.nan,
                "analytic_cw1_deg": float(circular_w1(truth, np.cumsum(analytic[i]))),
                "structured_cw1_deg": structured.get((parts[i], cids[i]), np.nan),
            }
        )
    frame = pd.DataFrame(records)
    io.write_csv(out, frame)
    frame["dist"] = frame[["upstream_dist_deg", "downstream_dist_deg"]].max(axis=1)
    frame["types"] = frame.config_id.str.replace(r"[0-9.]", "", regex=True)
    cols = ["composed_cw1_deg", "analytic_cw1_deg", "structured_cw1_deg"]
    for by in ("split", pd.cut(frame.dist, [-0.1, 0, 5, 10, 20, 90]), "types"):
        print(frame.groupby(by, observed=True)[cols].agg(["mean", "median", "count"]).round(2).to_string())
    for s in ("test", "fences", "train"):
        f = frame[(frame.split == s) & frame.composed_cw1_deg.notna()]
        for base in ("analytic", "structured"):
            g = f[f[f"{base}_cw1_deg"].notna()]
            if len(g) < 2:
                continue
            diff = (g.composed_cw1_deg - g[f"{base}_cw1_deg"]).to_numpy()
            mean, lo, hi = paired_bootstrap(diff, 10000, 0.95, 0)
            print(f"{s}: composed - {base}: {mean:+.2f} [{lo:+.2f}, {hi:+.2f}] deg over {len(g)} configurations")
    both = frame[frame.structured_cw1_deg.notna()]
    best = both[["composed_cw1_deg", "structured_cw1_deg"]].min(axis=1).mean()
    print(f"per-row best of composed and structured over {len(both)} scored rows: {best:.2f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
