"""The analytic model with a round fence tip: a corner or a disc? (issue #39, the round-tip re-baseline)

``docs/experiments/fence_tip.py`` simulated 121 configurations with a round fence tip (a
vertical cylinder of the fence's half thickness capping its free end), 16 evenly spaced initial
yaws each (raw rows ``results/tables/fence_tip.csv``, variant ``round``). Until now the analytic
model took a round tip as the face's corner. With the cap modelled
(``feeder.mechanics.fence.FenceModel.cap``), the exit turn pushes the outline grown by the cap's
radius with the cap's centre as the corner (``feeder.mechanics.hull.dilate``), while the face
still meets the outline itself. Nothing is fitted: the radius is the fence's half thickness.

Per drop, this script computes the analytic yaw both ways (``corner``: the cap removed from the
fence models; ``disc``: the library's round-tip model) from the simulated drop's initial yaw and
checks which agrees with the simulated round-tip drop (both ok within ``AGREE_DEG`` modulo the
symmetry period). Per group (one straight fence at ``STEEP_DEG`` or more, the other one-fence
configurations, two fences) it prints the share of drops that agree under each model, the
difference with a 95 % bootstrap interval over configurations, and the analytic PMF's circular
W1 to the 16-drop PMF under each model (paired, same interval). Rows: OUT_CSV (one per drop) and
OUT_CSV with ``_pmf`` before the suffix (one per configuration). About 5 minutes on one core.

    python docs/experiments/round_tip_model.py results/tables/fence_tip.csv parts OUT_CSV
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, analytic_final  # noqa: E402
from fence_tip import paired_interval, run_pmf  # noqa: E402

from feeder.io import write_csv  # noqa: E402
from feeder.labels.metrics import circular_w1  # noqa: E402
from feeder.lane.fences import parse_config_id  # noqa: E402
from feeder.mechanics.distribution import analytic_distribution  # noqa: E402
from feeder.mechanics.fence import default_scene, fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.mechanics.pmf import analytic_pmf  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402

STEEP_DEG = 45.0
MODELS = ("corner", "disc")


def group(config_id: str) -> str:
    loc1, loc2 = parse_config_id(config_id)
    if loc1.type != "none" and loc2.type != "none":
        return "two fences"
    one = loc1 if loc1.type != "none" else loc2
    return "one steep straight" if one.type == "straight" and one.angle >= STEEP_DEG else "one, other"


def round_tip_drops(csv: Path, parts_dir: Path):
    """The ``round`` rows of a ``fence_tip.csv``-style file, per configuration: ``(part, config_id,
    geom, loc1, loc2, initial yaws, period, ok, final yaws)``, with the round-tip scene and its
    part–fence friction as the first item."""
    raw = pd.read_csv(csv)
    raw = raw[raw.variant == "round"]
    scene = copy.deepcopy(default_scene())
    scene["fences"]["tip"] = "round"
    yield scene, fence_mu(scene)
    for (part, config_id), g in raw.groupby(["part", "config_id"], sort=True):
        geom = as_geometry(load_part(parts_dir / f"{part}.stl"))
        loc1, loc2 = parse_config_id(config_id)
        ok = (g.status == "ok").to_numpy()
        yield (
            part,
            config_id,
            geom,
            loc1,
            loc2,
            g.initial_yaw_deg.to_numpy(),
            float(g.period.iloc[0]),
            ok,
            g.final_yaw_deg.to_numpy(),
            list(g.status),
        )


def models(loc1, loc2, scene: dict) -> dict:
    disc = fence_models(loc1, loc2, scene)
    return {"corner": [dataclasses.replace(m, cap=None, cap_radius=0.0) for m in disc], "disc": disc}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fence_tip_csv", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    args = ap.parse_args(argv)
    configs = round_tip_drops(args.fence_tip_csv, args.parts_dir)
    scene, mu = next(configs)
    drops, pmfs = [], []
    for part, config_id, geom, loc1, loc2, y0, period, ok, final, status in configs:
        fences = models(loc1, loc2, scene)
        run = run_pmf(final, ok)
        rec = {"part": part, "config_id": config_id, "group": group(config_id)}
        per_drop = {}
        for name, fm in fences.items():
            memo: dict = {}
            try:
                ana, _ = analytic_final(geom, fm, y0, mu, memo)
            except ValueError:  # a fence rolls the part: no yaw per drop
                ana = None
            if ana is None:
                per_drop[name] = np.full(len(y0), np.nan)
            else:
                d = np.abs((final - ana + period / 2) % period - period / 2)
                per_drop[name] = np.where(ok & np.isfinite(ana) & (d < AGREE_DEG), 1.0, 0.0)
            if run is not None:
                dist = analytic_distribution(geom, loc1, loc2, scene, fences=fm)
                if dist.weights.sum() <= 0.0:  # every drop jams: the PMF without jams (as analytic_pmf)
                    dist = analytic_distribution(geom, loc1, loc2, scene, fences=fm, jams=False)
                cdf = np.cumsum(analytic_pmf(geom, None, None, distribution=dist))
                rec[f"{name}_cw1_deg"] = float(circular_w1(cdf, np.cumsum(run)))
        pmfs.append(rec)
        for i in range(len(y0)):
            drops.append(
                {
                    "part": part,
                    "config_id": config_id,
                    "group": rec["group"],
                    "initial_yaw_deg": y0[i],
                    "status": status[i],
                    "final_yaw_deg": final[i],
                    **{f"{name}_agrees": per_drop[name][i] for name in MODELS},
                }
            )
    drops_df, pmf_df = pd.DataFrame(drops), pd.DataFrame(pmfs)
    write_csv(args.out_csv, drops_df)
    write_csv(args.out_csv.with_name(args.out_csv.stem + "_pmf" + args.out_csv.suffix), pmf_df)
    per_config = drops_df.dropna(subset=["corner_agrees"]).groupby(["group", "part", "config_id"])
    agree = per_config[["corner_agrees", "disc_agrees"]].mean()
    for name, g in agree.groupby(level=0):
        diff = (g.disc_agrees - g.corner_agrees).to_numpy()
        lo, hi = paired_interval(diff)
        print(
            f"{name}: {len(g)} configurations, drops that agree: corner {g.corner_agrees.mean():.3f}, "
            f"disc {g.disc_agrees.mean():.3f}, difference {diff.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]"
        )
    for name, g in pmf_df.dropna(subset=["corner_cw1_deg"]).groupby("group"):
        diff = (g.disc_cw1_deg - g.corner_cw1_deg).to_numpy()
        lo, hi = paired_interval(diff)
        print(
            f"{name}: analytic PMF circular W1 to the 16-drop PMF: corner {g.corner_cw1_deg.mean():.1f}, "
            f"disc {g.disc_cw1_deg.mean():.1f} deg, difference {diff.mean():+.1f} [{lo:+.1f}, {hi:+.1f}]"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
