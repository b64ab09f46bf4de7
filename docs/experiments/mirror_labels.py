"""A one-fence label read at the other location (stop 75, ``model.mirror_labels``).

Location 1 stands on the right of the belt, Location 2 on the left; ``feeder bench-mirror`` showed
drop by drop that ``F | none`` for a part is ``none | F`` for its mirror image with every final
yaw negated. A part with a mirror axis is its own mirror image turned, so its label at one
location is its label at the other, reflected (``feeder.learn.structured_mirror``). Two checks,
on the study's own labels, nothing simulated:

1. **pairs**: every pair of one-fence labels of one part, ``F | none`` against ``none | F`` of the
   same fence type within 5°: circular W1 between the first and the second reflected with the
   constant from the part's outline (``label_mirror_deg``, label frame), against the second
   unreflected, and against the best constant on a 1° grid (which reads both labels).
2. **gated**: the untrained gated neighbour of the protocol's Main fits (``fit_gate`` then
   ``gated_pmfs`` on each repeat's training rows; the analytic PMF where no label is within the
   gate) with and without the mirrored labels in its pool, scored on the Test and Fences rows.

    python docs/experiments/mirror_labels.py results/tables/mirror_labels.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.config import compose_config
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.learn.structured_blend import fit_gate, gated_pmfs
from feeder.learn.structured_data import fence_key, row_mirror_degs, split_arrays
from feeder.learn.structured_mirror import reflect_pmf
from feeder.learn.structured_protocol import protocol_jobs

NEAR_DEG = 5.0  # a pair's largest angle difference
GRID_DEG = np.arange(0.0, 360.0, 1.0)  # the constants tried for the best one


def label_arrays(data: dict, parts_dir, features_dir) -> dict:
    """The kept and excluded rows of the dataset (split_arrays) with labels, analytic PMFs and
    each row's mirror constant."""
    a = split_arrays(data)
    n, n_kept = len(a["part"]), len(data["part"])
    bins = data["pmf"].shape[1]
    pmf, analytic = np.zeros((n, bins)), np.zeros((n, bins))
    pmf[:n_kept], analytic[:n_kept] = data["pmf"], data["pmf_analytic"]
    a.update(pmf=pmf, cdf=np.cumsum(pmf, axis=1), analytic=analytic, ok=np.ones(n), analytic_ok=np.ones(n))
    a["mirror_deg"] = row_mirror_degs(data, a["part"], parts_dir, features_dir)
    return a


def pairs(a: dict) -> list[dict]:
    rows = []
    kept = np.flatnonzero(a["kept"])
    for i in kept:
        (t1, t2), (x1, _) = fence_key(a["config_id"][i])
        if t1 == "none" or t2 != "none":
            continue
        for j in kept:
            (u1, u2), (_, y2) = fence_key(a["config_id"][j])
            if a["part"][j] != a["part"][i] or u1 != "none" or u2 != t1 or abs(y2 - x1) > NEAR_DEG:
                continue
            c = float(a["mirror_deg"][i])
            grid = [float(circular_w1(a["cdf"][i], np.cumsum(reflect_pmf(a["pmf"][j], g)))) for g in GRID_DEG]
            rows.append(
                {
                    "check": "pairs",
                    "part": str(a["part"][i]),
                    "config_id": str(a["config_id"][i]),
                    "other": str(a["config_id"][j]),
                    "angle_diff_deg": abs(y2 - x1),
                    "mirror_deg": c,
                    "cw1_reflected": float(circular_w1(a["cdf"][i], np.cumsum(reflect_pmf(a["pmf"][j], c))))
                    if np.isfinite(c)
                    else np.nan,
                    "cw1_unreflected": float(circular_w1(a["cdf"][i], a["cdf"][j])),
                    "best_deg": float(GRID_DEG[int(np.argmin(grid))]),
                    "cw1_best": float(min(grid)),
                }
            )
    return rows


def gated(a: dict, cfg) -> list[dict]:
    rows = []
    plain = {k: v for k, v in a.items() if k != "mirror_deg"}
    for kind, _key, repeat, train, scored in protocol_jobs(a, cfg)[0]:
        if kind != "main":
            continue
        for experiment, mask in scored.items():
            idx = np.flatnonzero(mask & a["kept"])
            for mirror, arrays in (("off", plain), ("on", a)):
                gate = fit_gate(arrays, train, cfg.neighbour.gates_deg)
                w1 = circular_w1(a["cdf"][idx], np.cumsum(gated_pmfs(arrays, train, idx, gate), axis=1))
                rows += [
                    {
                        "check": "gated",
                        "experiment": experiment,
                        "repeat": int(repeat),
                        "mirror": mirror,
                        "gate_deg": gate,
                        "part": str(a["part"][i]),
                        "config_id": str(a["config_id"][i]),
                        "cw1": float(w),
                    }
                    for i, w in zip(idx, w1, strict=True)
                ]
    return rows


def summary(df: pd.DataFrame) -> pd.DataFrame:
    p = df[df.check == "pairs"]
    sym = p[p.mirror_deg.notna()]
    out = [
        {"what": "pairs, symmetric parts: reflected", "n": len(sym), "mean": sym.cw1_reflected.mean()},
        {"what": "pairs, symmetric parts: unreflected", "n": len(sym), "mean": sym.cw1_unreflected.mean()},
        {"what": "pairs, symmetric parts: best constant", "n": len(sym), "mean": sym.cw1_best.mean()},
        {
            "what": "pairs, asymmetric parts: best constant",
            "n": int(p.mirror_deg.isna().sum()),
            "mean": p[p.mirror_deg.isna()].cw1_best.mean(),
        },
    ]
    g = df[df.check == "gated"]
    for (experiment, mirror), part in g.groupby(["experiment", "mirror"]):
        out.append({"what": f"gated neighbour, {experiment}, mirror {mirror}", "n": len(part), "mean": part.cw1.mean()})
    return pd.DataFrame(out)


def main(argv: list[str]) -> int:
    out_csv = Path(argv[0]) if argv else Path("results/tables/mirror_labels.csv")
    cfg = compose_config("structured", [])
    a = label_arrays(load_dataset(Path("results/datasets/dataset.npz")), "parts", "results/features")
    df = pd.DataFrame(pairs(a) + gated(a, cfg))
    io.write_csv(out_csv, df)
    print(summary(df).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
