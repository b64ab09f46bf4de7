"""Does the arc a part rides pick its basin on a curved fence? (issue #39, unseen parts)

The analytic model takes a curved fence as the straight fence of its last chord: the push
function at the exit angle picks each drop's basin from the yaw it arrives with. Drop by drop
that agrees with the simulator on about half the initial yaws at one curved fence of 10-40 deg
(``results/tables/analytic_dropwise_round_one_fence.csv``): the part meets the arc where it is
steeper and turns as the arc flattens under it. ``analytic_distribution(..., arc_ride=MODE)``
integrates that ride (``feeder.mechanics.arcride.arc_yaw``) and picks the basin from the yaw the
part has turned to at the tip; ``basin`` counts the turn budget from the arriving yaw as before,
``state`` from the ridden one. Jams, grazes and the exit turn are unchanged.

Two measurements, each against the default (mode ``none``):

``drops``: every simulated drop of a configuration with a curved fence, pushed through the model
from its own initial yaw (centred), as ``analytic_dropwise.py`` does (hard jams; a drop agrees
when both end ok within ``AGREE_DEG`` modulo the period, or both jam; weighted by its share of
the initial yaws); summary by fence types and, for one curved fence, by its angle.

``pmf``: the analytic PMF's circular W1 to the label of every kept configuration of a dataset
with a curved fence, per split, paired by configuration with a 95 % bootstrap over parts (the
mode is to be chosen on ``train`` alone; configurations without a curved fence do not change).

    python docs/experiments/arc_ride.py drops SIM_DIR PARTS_DIR OUT_CSV_GZ --modes none,basin,state
    python docs/experiments/arc_ride.py pmf DATASET PARTS_DIR OUT_CSV_GZ --modes none,basin,state
    python docs/experiments/arc_ride.py summary DROPS_CSV_GZ PMF_CSV_GZ OUT_PREFIX

Nothing is fitted. About 0.4 s a configuration and mode.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, cell_weights, sim_files  # noqa: E402
from soft_jams import paired_interval  # noqa: E402

import feeder.mechanics.distribution as D  # noqa: E402
from feeder.io import write_csv  # noqa: E402
from feeder.labels.dataset import load_dataset  # noqa: E402
from feeder.labels.metrics import circular_w1  # noqa: E402
from feeder.lane.fences import parse_config_id  # noqa: E402
from feeder.learn.evaluate import fence_types  # noqa: E402
from feeder.mechanics.fence import fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.mechanics.pmf import analytic_pmf  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402


def _mode(name: str):
    return None if name == "none" else name


def final_yaws(geom, fences, yaws, mu, memo, mode) -> np.ndarray:
    """Final yaw of each drop (NaN: jammed) through ``fences`` in order, hard jams, the drops
    tracked through ``_apply`` by their weights (index + 1); ValueError where a fence rolls it."""
    yaw = np.asarray(yaws, dtype=np.float64).copy()
    x = np.zeros_like(yaw)
    tag = np.arange(1.0, yaw.size + 1.0)
    for m in fences:
        if m not in memo:
            memo[m] = D.fence_response(geom, m, mu, True)
        if memo[m].push.rolls:
            raise ValueError("a fence rolls the part: no yaw per drop")
        yaw, x, tag, _ = D._apply(geom, memo[m], mu, yaw, x, tag, True, 0.0, D.TURN_BUDGET_SCALE, _mode(mode))
    out = np.full(len(yaws), np.nan)
    out[np.rint(tag).astype(int) - 1] = yaw
    return out


def drops(sim_dir: Path, parts_dir: Path, modes: list[str]) -> pd.DataFrame:
    rows = []
    for part, geom, path, meta, scene, period, y0, yf, status in sim_files(sim_dir, parts_dir):
        loc1, loc2 = meta["loc1"], meta["loc2"]
        if not (loc1.startswith("curved") or loc2.startswith("curved")):
            continue
        fences = fence_models(loc1, loc2, scene)
        mu = fence_mu(scene)
        memo: dict = {}
        try:
            out = {m: final_yaws(geom, fences, y0, mu, memo, m) for m in modes}
        except ValueError:
            continue
        w = cell_weights(np.mod(y0, period), period)
        frame = pd.DataFrame(
            dict(
                part=part,
                config_id=path.stem,
                loc1=loc1,
                loc2=loc2,
                period=period,
                initial_yaw_deg=y0,
                weight=w,
                status=status.astype(str),
                final_yaw_deg=yf,
                **{f"yaw_{m}": out[m] for m in modes},
            )
        )
        rows.append(frame)
    return pd.concat(rows, ignore_index=True)


def pmfs(dataset: Path, parts_dir: Path, modes: list[str]) -> pd.DataFrame:
    data = load_dataset(dataset)
    geoms: dict = {}
    memos: dict = {}
    rows = []
    for i, (part, config_id) in enumerate(zip(data["part"], data["config_id"])):
        part, config_id = str(part), str(config_id)
        if "curved" not in config_id:
            continue
        if part not in geoms:
            geoms[part] = as_geometry(load_part(parts_dir / f"{part}.stl"))
        loc1, loc2 = parse_config_id(config_id)
        memo = memos.setdefault(part, {})
        for m in modes:
            dist = D.analytic_distribution(geoms[part], loc1, loc2, responses=memo, arc_ride=_mode(m))
            if dist.weights.sum() <= 0.0:  # every drop jams: the PMF without jams
                dist = D.analytic_distribution(geoms[part], loc1, loc2, responses=memo, arc_ride=_mode(m), jams=False)
            pmf = analytic_pmf(geoms[part], loc1, loc2, frame_deg=float(data["frame_deg"][i]), distribution=dist)
            cw1 = float(circular_w1(np.cumsum(pmf), data["cdf"][i]))
            rows.append((m, part, config_id, str(data["split"][i]), cw1))
    return pd.DataFrame(rows, columns=["mode", "part", "config_id", "split", "circular_w1_deg"])


def _gap(a, b, period):
    return np.abs(np.mod(a - b + period / 2.0, period) - period / 2.0)


def drop_summary(d: pd.DataFrame, modes: list[str]) -> pd.DataFrame:
    """Weighted share of the initial yaws that agree, per configuration, averaged over the
    configurations of each fence-type combination and of each one-curved-fence angle."""
    ok = d.status == "ok"
    agree = {}
    for m in modes:
        y = d[f"yaw_{m}"]
        agree[m] = (ok & y.notna() & (_gap(d.final_yaw_deg, y.fillna(0.0), d.period) <= AGREE_DEG)) | (~ok & y.isna())
    d = d.assign(**{f"agree_{m}": agree[m] for m in modes})
    d["wn"] = d.weight / d.groupby(["part", "config_id"]).weight.transform("sum")
    one = (d.loc1 == "none") | (d.loc2 == "none")
    present = pd.Series(np.where(d.loc1 == "none", d.loc2, d.loc1), index=d.index)
    d["group"] = np.where(
        one, "one curved:" + present.str.split(":").str[1].str.zfill(2), [fence_types(c) for c in d.config_id]
    )
    per = d.groupby(["group", "part", "config_id"]).apply(
        lambda g: pd.Series({m: float((g.wn * g[f"agree_{m}"]).sum()) for m in modes}), include_groups=False
    )
    per = per.reset_index()
    out = per.groupby("group")[modes].mean()
    out.insert(0, "configs", per.groupby("group").size())
    tot = per[modes].mean().to_frame().T
    tot.insert(0, "configs", len(per))
    tot.index = ["all with a curved fence"]
    return pd.concat([out, tot]).reset_index(names="fences")


def pmf_summary(raw: pd.DataFrame, modes: list[str], base: str = "none") -> pd.DataFrame:
    """Per split (and the held-out splits pooled): mean circular W1 per mode and its difference
    from mode ``base``, paired by configuration, 95 % bootstrap over parts."""
    rng = np.random.default_rng(0)
    raw = raw.rename(columns={"circular_w1_deg": "cw1"})
    groups = [(s, raw[raw.split == s]) for s in sorted(raw.split.unique())]
    groups.append(("held_out", raw[raw.split != "train"]))
    rows = []
    for name, g in groups:
        ref = g[g["mode"] == base]
        for m in modes:
            h = g[g["mode"] == m]
            diff = paired_interval(ref, h, "cw1", rng) if m != base else (0.0, 0.0, 0.0)
            rows.append((name, m, h.part.nunique(), len(h), h.cw1.mean(), *diff))
    cols = ["split", "mode", "parts", "configs", "cw1_mean", f"diff_vs_{base}", "diff_lo", "diff_hi"]
    return pd.DataFrame(rows, columns=cols)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["drops", "pmf", "summary"])
    ap.add_argument("a", type=Path)
    ap.add_argument("b", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--modes", default="none,basin,state")
    args = ap.parse_args(argv)
    modes = args.modes.split(",")
    if args.what == "drops":
        d = drops(args.a, args.b, modes)
        d.to_csv(args.out, index=False)
        print(drop_summary(d, modes).to_string(index=False))
    elif args.what == "pmf":
        raw = pmfs(args.a, args.b, modes)
        raw.to_csv(args.out, index=False)
        print(pmf_summary(raw, [m for m in modes]).to_string(index=False))
    elif args.b.name == "-":  # drops only
        d = pd.read_csv(args.a)
        print(drop_summary(d, [c[4:] for c in d.columns if c.startswith("yaw_")]).to_string(index=False))
    else:
        d, raw = pd.read_csv(args.a), pd.read_csv(args.b)
        dm = [c[4:] for c in d.columns if c.startswith("yaw_")]
        pm = list(raw["mode"].unique())
        a, b = drop_summary(d, dm), pmf_summary(raw, pm)
        write_csv(f"{args.out}_drops.csv", a)
        write_csv(f"{args.out}_pmf.csv", b)
        print(a.to_string(index=False))
        print(b.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
