"""Is the part–fence friction of the analytic model the lever for a known part? (stop 76)

The analytic model reads the part–fence friction as pybullet combines it, 0.8 × 0.5 = 0.4
(``feeder.mechanics.fence.fence_mu``). For crescent-b at ``none | straight:40``-like scenes it is on
a knife edge: at μ = 0.35 it gives the simulator's two basins (60 % / 30 %), at μ = 0.4 one basin
for every initial yaw. The calibration modes (``calibration.modes``) already hold μ = 0.25, 0.3 and
0.5; this adds μ = 0.35 and 0.45 (the base model otherwise) and asks two questions:

1. **per row**: circular W1 of every kept dataset row under the base model, the ten cached modes
   and the two new ones (``friction_modes_rows.csv``, the raw data);
2. **calibrated**: the protocol's per-part choice (the mode with the least mean W1 on the part's
   Main rows outside each repeat's Test rows, where it beats the base by ``calibration.margin_deg``),
   scored on each repeat's Test rows, with and without the two new modes; and the per-part oracle
   (each part's best mode on all its rows) over the friction grid alone;
3. **mixture**: the untrained model averaged over μ = 0.35, 0.4 and 0.45, an answer for any part.

The new modes' PMFs are computed once (about 10 CPU-minutes, one process) into ``PMFS`` and read
from there on a rerun. The ten cached modes come from ``results/datasets/structured_calibration.npz``
(a protocol run writes it). The Test rows of each repeat come from the committed
``results/tables/structured_rows.csv``.

    python docs/experiments/friction_modes.py results/tables/friction_modes.csv
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import label_smooth_deg
from feeder.labels.metrics import circular_w1
from feeder.learn.structured_calibration import calibration_settings, compute_mode_pmfs

DATASET = Path("results/datasets/dataset.npz")
CACHE = Path("results/datasets/structured_calibration.npz")
ROWS = Path("results/tables/structured_rows.csv")
PMFS = Path("results/bench/friction_modes/mode_pmfs.npz")
NEW_MU = (0.35, 0.45)
RESAMPLES, SEED = 2000, 0


def new_mode_pmfs(d, modes) -> np.ndarray:
    """(rows, 2, bins) of the two new modes: the cached μ = 0.5 mode with μ changed."""
    if PMFS.is_file():
        return io.read_npz(PMFS, ("pmfs",), "friction modes' PMFs")["pmfs"]
    settings = json.loads(str(d["settings"]))
    base = next(m for m in modes if m.name == "mu0.5")
    new = tuple(dataclasses.replace(base, name=f"mu{mu}", mu=mu) for mu in NEW_MU)
    pmfs = compute_mode_pmfs(
        [str(p) for p in d["part"]],
        [str(c) for c in d["config_id"]],
        d["frame_deg"].tolist(),
        settings["scene"],
        new,
        label_smooth_deg(360, float(settings["labels"]["sigma_bins"])),
        settings["parts"]["dir"],
        360,
        settings["parts"]["units"],
        progress=lambda m: print(m, flush=True),
    )
    io.write_npz(PMFS, pmfs=pmfs)
    return pmfs


def calibrated_test(r: pd.DataFrame, rows: pd.DataFrame, modes: list[str], margin: float) -> pd.DataFrame:
    """Each repeat's Test rows scored with the mode each part's other Main rows choose."""
    out = []
    for rep in sorted(rows.repeat.unique()):
        t = rows[(rows.experiment == "test") & (rows.repeat == rep) & (rows.predictor == "analytic_calibrated")]
        test = set(zip(t.part[t.kept], t.config_id[t.kept], strict=True))
        is_test = np.array([(p, c) in test for p, c in zip(r.part, r.config_id, strict=True)])
        pool = r[(r.dataset == "main").to_numpy() & ~is_test].groupby("part")[["base", *modes]].mean()
        choice = {}
        for part, m in pool.iterrows():
            best = m[modes].idxmin()
            choice[part] = best if m[best] < m["base"] - margin else "base"
        te = r[is_test]
        w1 = [te.at[i, choice.get(p, "base")] for i, p in zip(te.index, te.part, strict=True)]
        out.append(pd.DataFrame({"repeat": rep, "part": te.part.to_numpy(), "w1": w1}))
    return pd.concat(out, ignore_index=True)


def main(out_csv: str) -> None:
    cfg = compose_config("structured", [])
    modes, margin = calibration_settings(cfg)
    d = io.read_npz(DATASET, ("part", "config_id", "dataset", "cdf", "pmf_analytic", "frame_deg"), "dataset")
    n = len(d["part"])
    cached = io.read_npz(CACHE, ("pmfs",), "calibration cache")["pmfs"][:n]  # kept rows first, as the dataset's
    new = new_mode_pmfs(d, modes)
    cdf = d["cdf"]
    r = pd.DataFrame({"part": d["part"], "config_id": d["config_id"], "dataset": d["dataset"]})
    r["base"] = circular_w1(cdf, np.cumsum(d["pmf_analytic"], axis=1))
    names = [m.name for m in modes]
    for k, name in enumerate(names):
        r[name] = circular_w1(cdf, np.cumsum(cached[:, k], axis=1))
    added = [f"mu{mu}" for mu in NEW_MU]
    for k, name in enumerate(added):
        r[name] = circular_w1(cdf, np.cumsum(new[:, k], axis=1))
    io.write_csv(Path(out_csv).with_name("friction_modes_rows.csv"), r)

    grid = ["mu0.25", "mu0.3", "mu0.35", "base", "mu0.45", "mu0.5"]
    by_part = r.groupby("part")[grid].mean()
    summary = [{"what": f"row mean, {g}", "value": float(r[g].mean()), "low": np.nan, "high": np.nan} for g in grid]
    summary += [
        {"what": "part mean, base (mu 0.4)", "value": float(by_part["base"].mean()), "low": np.nan, "high": np.nan},
        {
            "what": "part oracle over mu 0.3 / 0.4 / 0.5",
            "value": float(by_part[["mu0.3", "base", "mu0.5"]].min(axis=1).mean()),
            "low": np.nan,
            "high": np.nan,
        },
        {
            "what": "part oracle over the mu grid",
            "value": float(by_part.min(axis=1).mean()),
            "low": np.nan,
            "high": np.nan,
        },
    ]
    # an untrained answer for any part: the model averaged over mu 0.35 / 0.4 / 0.45
    mixture = (new[:, 0] + d["pmf_analytic"] + new[:, 1]) / 3.0
    r_mix = pd.Series(circular_w1(cdf, np.cumsum(mixture, axis=1)), index=r.index)
    summary += [
        {
            "what": "row mean, mixture of mu 0.35 / 0.4 / 0.45",
            "value": float(r_mix.mean()),
            "low": np.nan,
            "high": np.nan,
        },
        {
            "what": "part mean, mixture of mu 0.35 / 0.4 / 0.45",
            "value": float(r_mix.groupby(r.part).mean().mean()),
            "low": np.nan,
            "high": np.nan,
        },
    ]
    before = calibrated_test(r, pd.read_csv(ROWS), names, margin)
    after = calibrated_test(r, pd.read_csv(ROWS), names + added, margin)
    diff = after.w1.to_numpy() - before.w1.to_numpy()
    rng = np.random.default_rng(SEED)
    boot = [diff[rng.integers(0, diff.size, diff.size)].mean() for _ in range(RESAMPLES)]
    summary += [
        {"what": "Test, calibrated, the ten modes", "value": float(before.w1.mean()), "low": np.nan, "high": np.nan},
        {
            "what": "Test, calibrated, with mu 0.35 and 0.45",
            "value": float(after.w1.mean()),
            "low": np.nan,
            "high": np.nan,
        },
        {
            "what": "Test, calibrated, difference (rows, 95 % bootstrap)",
            "value": float(diff.mean()),
            "low": float(np.percentile(boot, 2.5)),
            "high": float(np.percentile(boot, 97.5)),
        },
    ]
    out = pd.DataFrame(summary)
    io.write_csv(out_csv, out)
    print(out.round(2).to_string(index=False))


if __name__ == "__main__":
    main(sys.argv[1])
