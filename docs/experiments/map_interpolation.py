"""A known part at a new angle: its neighbours' drop maps interpolated yaw by yaw (issue #39, untrained)

For a part the study has labelled, a Test configuration usually has labelled neighbours of the same
fence types at other angles. The protocol's predictor mixes their *labels*; where a basin drifts with
the fence angle, a mix of two labels puts two half-peaks where the truth has one peak in between.
This experiment interpolates the neighbours' sampled *drop maps* instead: for every initial yaw β
the two nearest neighbours' final yaws f1(β), f2(β) (``feeder.sim.pushforward.map_yaws``) are moved
along the line through the two neighbours' angles to the row's angles,

    f(β) = f1(β) + t · wrap_P(f2(β) − f1(β)),   t = projection of θ − θ1 on θ2 − θ1 (clipped),

wrapped to the part's symmetry period P, as long as the two agree (|Δ| ≤ ``AGREE_DEG``); where they
do not (a basin flip, or one fails), β goes to each neighbour's outcome with weight 1 − t and t
(clipped to [0, 1]). The label is the push-forward of 36,000 even yaws, binned in the label frame and
smoothed as labels are. No label of the row is read.

    python docs/experiments/map_interpolation.py RESULTS_DIR results/tables/structured_rows.csv \
        results/tables/map_interpolation.csv

RESULTS_DIR holds ``datasets/dataset.npz``, ``datasets/structured_candidates.npz`` and ``sim/``.
Scored by circular W1 on the dataset's Test split (repeat 0 of the protocol, neighbours from the
training split only), beside the nearest neighbour's label, the two neighbours' labels mixed by
inverse distance, the analytic PMF and the structured predictor (its mean over seeds in
``structured_rows.csv``); one row per configuration is written raw, and 95 % paired bootstraps are
printed.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.circular import FULL_TURN_DEG, normalize_yaw, wrapped_gaussian_smooth
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.labels.pmf import record_design
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.structured_data import fence_key, nearest_rows
from feeder.mechanics.pmf import bin_masses
from feeder.sim.pushforward import map_yaws
from feeder.sim.record import load_sim

YAWS = 36_000
AGREE_DEG = 15.0  # two neighbours' final yaws further apart than this are different basins
T_RANGE = (-0.5, 1.5)  # how far beyond the two neighbours the line may be followed


def interpolated_label(d1, d2, t: float, period: float, frame: float, bins: int, sigma: float):
    """The interpolated map's label (see the module docstring), or None when nothing ends ok."""
    beta = (np.arange(YAWS) + 0.5) * (FULL_TURN_DEG / YAWS)
    f1, _ = map_yaws(d1, beta)
    f2, _ = map_yaws(d2, beta)
    delta = np.mod(f2 - f1 + 0.5 * period, period) - 0.5 * period
    agree = np.isfinite(delta) & (np.abs(delta) <= AGREE_DEG)
    w = float(np.clip(t, 0.0, 1.0))
    yaws = [f1[agree] + float(np.clip(t, *T_RANGE)) * delta[agree]]
    weights = [np.ones(int(agree.sum()))]
    for f, wt in ((f1, 1.0 - w), (f2, w)):
        keep = ~agree & np.isfinite(f)
        yaws.append(f[keep])
        weights.append(np.full(int(keep.sum()), wt))
    yaws, weights = np.concatenate(yaws), np.concatenate(weights)
    if weights.sum() <= 0:
        return None
    hist = bin_masses(normalize_yaw(yaws + frame), weights, bins)
    return wrapped_gaussian_smooth(hist / hist.sum(), sigma)


def projection(theta, theta1, theta2) -> float:
    """Where ``theta`` projects on the line from ``theta1`` (t = 0) to ``theta2`` (t = 1)."""
    d = np.asarray(theta2) - np.asarray(theta1)
    n = float(d @ d)
    return 0.5 if n == 0 else float((np.asarray(theta) - np.asarray(theta1)) @ d / n)


def main(argv: list[str]) -> int:
    results, rows_csv, out = Path(argv[0]), Path(argv[1]), Path(argv[2])
    data = load_dataset(results / "datasets" / "dataset.npz")
    parts, cids, split = (np.asarray(data[key]).astype(str) for key in ("part", "config_id", "split"))
    sigma = float(json.loads(str(data["settings"]))["labels"]["sigma_bins"])
    pmf = np.asarray(data["pmf"], dtype=np.float64)
    pmf = pmf / pmf.sum(axis=1, keepdims=True)
    bins = pmf.shape[1]
    with np.load(results / "datasets" / "structured_candidates.npz", allow_pickle=False) as z:
        analytic = np.asarray(z["analytic"][: parts.size], dtype=np.float64)
    analytic = analytic / analytic.sum(axis=1, keepdims=True)
    scored = pd.read_csv(rows_csv)
    scored = scored[(scored.repeat == 0) & scored.kept & (scored.predictor == "structured")]
    structured = scored[scored.experiment == "test"].groupby(["part", "config_id"]).cw1.mean()
    rows = np.flatnonzero(split == "test")
    idx, dist = nearest_rows(parts, cids, split == "train", rows, 2)
    records = []
    for n, i in enumerate(rows):
        j1, j2 = idx[n]
        if j1 < 0:
            continue
        truth = np.cumsum(pmf[i])
        rec = {"part": parts[i], "config_id": cids[i], "near1": cids[j1], "dist1_deg": dist[n, 0]}
        rec["neighbour_cw1_deg"] = float(circular_w1(truth, np.cumsum(pmf[j1])))
        rec["analytic_cw1_deg"] = float(circular_w1(truth, np.cumsum(analytic[i])))
        rec["structured_cw1_deg"] = structured.get((parts[i], cids[i]), np.nan)
        if j2 >= 0:
            w1, w2 = 1.0 / max(dist[n, 0], 1e-9), 1.0 / max(dist[n, 1], 1e-9)
            mix = (w1 * pmf[j1] + w2 * pmf[j2]) / (w1 + w2)
            rec["near2"], rec["dist2_deg"] = cids[j2], dist[n, 1]
            rec["mix2_cw1_deg"] = float(circular_w1(truth, np.cumsum(mix)))
            d1 = record_design(load_sim(results / "sim" / parts[i] / f"{cids[j1]}.npz"))
            d2 = record_design(load_sim(results / "sim" / parts[i] / f"{cids[j2]}.npz"))
            t = projection(fence_key(cids[i])[1], fence_key(cids[j1])[1], fence_key(cids[j2])[1])
            rec["t"] = t
            label = interpolated_label(d1, d2, t, d1.period_deg, float(data["frame_deg"][i]), bins, sigma)
            if label is not None:
                rec["interp_cw1_deg"] = float(circular_w1(truth, np.cumsum(label)))
        records.append(rec)
    frame = pd.DataFrame(records)
    io.write_csv(out, frame)
    cols = [c for c in frame.columns if c.endswith("_cw1_deg")]
    frame["fences"] = [2 - sum(a == "none" for a in fence_key(c)[0]) for c in frame.config_id]
    frame["bracketed"] = frame.t.between(0, 1)
    for by in ("fences", "bracketed"):
        print(frame.groupby(by)[cols].agg(["mean", "median", "count"]).round(2).to_string())
    g = frame.dropna(subset=["interp_cw1_deg", "structured_cw1_deg"])
    print(f"{len(g)} rows with two neighbours, an interpolated label and a structured score:")
    print(g[cols].mean().round(2).to_string())
    for base in ("neighbour", "mix2", "analytic", "structured"):
        diff = (g.interp_cw1_deg - g[f"{base}_cw1_deg"]).to_numpy()
        mean, lo, hi = paired_bootstrap(diff, 10000, 0.95, 0)
        print(f"interp - {base}: {mean:+.2f} [{lo:+.2f}, {hi:+.2f}] deg")
    best = g[["interp_cw1_deg", "structured_cw1_deg"]].min(axis=1).mean()
    print(f"per-row best of interp and structured: {best:.2f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
