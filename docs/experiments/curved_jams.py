"""Which parts jam on a curved fence, in the simulator and in the analytic model (issue #39)?

Reads the drop rows of ``arc_ride.py drops`` (``results/tables/arc_ride_drops.csv.gz``: every
simulated drop of a configuration with a curved fence, its status, and the model's final yaw
for it, NaN where the model jams it). Per configuration it takes the share of the initial yaws
that jam (weighted by each drop's share of the yaws, as ``arc_ride.py`` does). Then it averages
that share over the configurations of each fence group: one curved fence by its angle, or two
fences. The configurations are split by the part's solidity (area over its convex hull's area,
holes taken out). Nothing is simulated or fitted.

What a jam rule could be worth: per configuration, the circular W1 between the simulator's ok
drops and the model's passing drops, each as a 1° histogram weighted by the drops' shares of the
initial yaws. Then the same with the drops the simulator jams left out of the model's too (an
oracle that knows which drops jam, and still cannot pass the ones the model jams). These are
drop-level PMFs of the adaptive design's 40 drops, unsmoothed, so they run higher than the
label-level analytic W1. Compare them with each other only.

    python docs/experiments/curved_jams.py results/tables/arc_ride_drops.csv.gz parts \\
        results/tables/curved_jams_by_concavity.csv

Seconds.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.io import write_csv
from feeder.labels.metrics import circular_w1
from feeder.mechanics.hull import push_geometry
from feeder.parts.geometry import load_profile

CONCAVE_BELOW = 0.9  # a part whose solidity is below this counts as concave
MODEL_YAW = "yaw_state"  # the default model's final yaw column (the arc ride ``state``)


def polygon_area(v: np.ndarray) -> float:
    """Area of the simple polygon ``v`` (V, 2), by the shoelace formula."""
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def solidity(stl: Path) -> float:
    """The part's area (holes taken out) over its convex hull's area."""
    outline, holes, _ = load_profile(stl, "auto")
    area = polygon_area(np.asarray(outline)) - sum(polygon_area(np.asarray(h)) for h in holes)
    return area / polygon_area(np.asarray(push_geometry(outline, holes).hull))


def fence_group(loc1: str, loc2: str) -> str:
    """``one curved:NN`` for one curved fence at NN degrees, else ``two fences``."""
    if loc1 == "none" or loc2 == "none":
        present = loc2 if loc1 == "none" else loc1
        return "one curved:" + present.split(":")[1].zfill(2)
    return "two fences"


def drop_pmf(yaw_deg, weight) -> np.ndarray | None:
    """The 1° histogram (360 bins) of ``yaw_deg`` weighted by ``weight``, normalised; None if empty."""
    h = np.bincount(np.floor(np.mod(np.asarray(yaw_deg), 360.0)).astype(int) % 360, weights=weight, minlength=360)
    return h / h.sum() if h.sum() > 0 else None


def oracle_w1(g: pd.DataFrame) -> tuple[float, float]:
    """(model, model without the simulator's jammed drops): circular W1 to the simulator's ok
    drops of one configuration (NaN where a side has no drop)."""
    ok, passes = (g.status == "ok").to_numpy(), g[MODEL_YAW].notna().to_numpy()
    sim = drop_pmf(g.final_yaw_deg[ok], g.weight[ok])
    out = []
    for keep in (passes, passes & ok):
        model = drop_pmf(g[MODEL_YAW][keep], g.weight[keep])
        missing = sim is None or model is None
        out.append(float("nan") if missing else float(circular_w1(np.cumsum(model), np.cumsum(sim))))
    return out[0], out[1]


def per_configuration(drops: pd.DataFrame, parts_dir: Path) -> pd.DataFrame:
    """One row per configuration: its group, the part's solidity, the weighted share of the
    initial yaws that jam in the simulator and in the model, and :func:`oracle_w1`."""
    d = drops.assign(sim_jam=(drops.status != "ok").astype(float), model_jam=drops[MODEL_YAW].isna().astype(float))
    rows = []
    for (part, config_id, loc1, loc2), g in d.groupby(["part", "config_id", "loc1", "loc2"]):
        w = g.weight / g.weight.sum()
        shares = (float((w * g.sim_jam).sum()), float((w * g.model_jam).sum()))
        rows.append((part, config_id, fence_group(loc1, loc2), *shares, *oracle_w1(g)))
    cols = ["part", "config_id", "fences", "sim_jam", "model_jam", "w1_model", "w1_without_sim_jams"]
    out = pd.DataFrame(rows, columns=cols)
    sol = {p: solidity(parts_dir / f"{p}.stl") for p in out.part.unique()}
    return out.assign(solidity=out.part.map(sol), concave=out.part.map(sol) < CONCAVE_BELOW)


def summary(per: pd.DataFrame) -> pd.DataFrame:
    """Mean jam shares per fence group and concavity, and the correlation over configurations
    between the part's solidity and the simulator's jam share."""
    rows = []
    for fences, g in per.groupby("fences"):
        r = np.corrcoef(g.solidity, g.sim_jam)[0, 1] if g.sim_jam.std() > 0 else float("nan")
        for concave, h in g.groupby("concave"):
            w1 = (h.w1_model.mean(), h.w1_without_sim_jams.mean())
            rows.append((fences, bool(concave), len(h), h.sim_jam.mean(), h.model_jam.mean(), r, *w1))
    cols = ["fences", "concave", "configurations", "sim_jam_share", "model_jam_share", "corr_solidity_sim_jam"]
    cols += ["drop_w1_model", "drop_w1_without_sim_jams"]
    return pd.DataFrame(rows, columns=cols)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("drops", type=Path, help="arc_ride.py drops rows (csv.gz)")
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out", type=Path)
    args = ap.parse_args(argv)
    per = per_configuration(pd.read_csv(args.drops), args.parts_dir)
    table = summary(per)
    write_csv(args.out, table)
    print(table.round(3).to_string(index=False))
    both = per.dropna(subset=["w1_model", "w1_without_sim_jams"])
    for name, g in (("all", both), ("simulator jams > 0.2", both[both.sim_jam > 0.2])):
        print(f"{name}: {len(g)} configurations, drop W1 {g.w1_model.mean():.2f} -> {g.w1_without_sim_jams.mean():.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
