"""Does the analytic model agree better with a seam-free curved fence? (issue #39)

Joins the drops of ``internal_edges.py`` (``results/tables/internal_edges_hull_drops.csv.gz``:
the study's 16-box curved fence, and the fence as one convex piece at 64 and 128 chords) with the
analytic model's final yaw of each drop (``results/tables/arc_ride_drops.csv.gz``, column
``yaw_state``: the default model, NaN where it jams). A drop agrees when both end ok within 5°
modulo the period, or both jam, weighted by its share of the initial yaws (as ``arc_ride.py``).
Prints the share per configuration and build (and the configurations it leaves out: ``arc_ride.py``
keeps no rows where a fence rolls the part), and writes it to
``results/tables/internal_edges_model.csv``. Seconds; nothing simulated.

    python docs/experiments/internal_edges_model.py
"""

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import numpy as np
import pandas as pd

from feeder.io import write_csv

AGREE_DEG = 5.0
h = pd.read_csv("results/tables/internal_edges_hull_drops.csv.gz")
m = pd.read_csv("results/tables/arc_ride_drops.csv.gz")
m = m[["part", "config_id", "initial_yaw_deg", "weight", "yaw_state"]]
rows = []
for v in ("segments16", "hull64", "hull128"):
    d = h[h.variant == v].merge(m, on=["part", "config_id", "initial_yaw_deg"], how="inner")
    ok = d.status == "ok"
    gap = np.abs(np.mod(d.final_yaw_deg - d.yaw_state.fillna(0) + d.period / 2, d.period) - d.period / 2)
    agree = (ok & d.yaw_state.notna() & (gap <= AGREE_DEG)) | (~ok & d.yaw_state.isna())
    d = d.assign(agree=agree)
    per = d.groupby(["part", "config_id"]).apply(
        lambda g: float((g.weight * g.agree).sum() / g.weight.sum()), include_groups=False
    )
    rows.append(per.rename(v))
t = pd.concat(rows, axis=1)
missing = sorted(set(map(tuple, h[["part", "config_id"]].drop_duplicates().values)) - set(t.index))
if missing:  # arc_ride.py keeps no drop rows of a configuration where a fence rolls the part
    print("left out, no model rows (a fence rolls the part):", ", ".join(f"{p} {c}" for p, c in missing))
write_csv("results/tables/internal_edges_model.csv", t.reset_index())
print(t.round(2).to_string())
print(t.mean().round(3))
