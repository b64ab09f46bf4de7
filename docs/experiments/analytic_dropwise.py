"""Where does the analytic push model part from the simulator, drop by drop? (issue #39, unseen parts)

For an unseen part the answer is the analytic PMF (20.6 deg circular W1 on GroupKFold), and the
structured predictor's candidates are its modes. Pooled PMFs hide where it goes wrong; this
compares it with the simulator drop by drop. Every simulated drop of the study (the simulation
files of a run, ``results/sim/<part>/<config>.npz``) is pushed through the analytic model
(``feeder.mechanics.distribution``: the same fence models, friction, push functions, turn budget
and exit turns as ``analytic_distribution``) from the same initial yaw, centred as the
simulator drops it, under the scene each file was simulated with (its settings: a round tip's cap
included). A drop agrees when both end ok and their final yaws lie within ``AGREE_DEG``
of each other modulo the part's symmetry period (the design's ``symmetry_order``). Each drop is
weighted by its share of the initial yaws (half the gap to each neighbour within the period), as
the adaptive design refines near basin edges and would otherwise over-count the hard drops.
Configurations where a fence rolls the part (no stable edge: the model gives a density, not a yaw
per drop) are left out and counted. For one-fence configurations each drop also gets why the
modelled exit turn of its basin stopped (``released``: the complete model; ``notch``, ``wedged``,
``end face``, ``hooked``, ``phases``: where it gives up), and the summary splits the agreement by it.

Optionally (``--budget-scales``) it also scores the analytic PMF of every kept configuration of a
dataset against its label with the turn budget (the ``overlap / (2c)`` bound on how far a fence can
turn a part) multiplied by each scale (``analytic_distribution``'s ``turn_budget_scale``), and
writes beside BUDGET_CSV a ``_summary.csv`` per split: the mean and the difference from scale 1,
paired by configuration, with a 95 % bootstrap interval over parts (choose on ``train`` alone).

    python docs/experiments/analytic_dropwise.py SIM_DIR PARTS_DIR OUT_CSV_GZ \
        [--one-fence-csv CSV] [--from-rows] [--dataset DATASET --budget-scales 1,1.5,2,3 --budget-csv BUDGET_CSV]

``--from-rows`` reads OUT_CSV_GZ as written before and only summarises it (seconds).

About 3 minutes for the 60,000 drops of the default study on one core; each budget scale about
2.5 minutes more.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import gzip
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import feeder.mechanics.distribution as D
from feeder.io import write_bytes, write_csv
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.lane.fences import parse_config_id
from feeder.learn.evaluate import fence_types
from feeder.mechanics.exitturn import exit_turn
from feeder.mechanics.fence import default_scene, fence_models, fence_mu, fence_normal_deg
from feeder.mechanics.hull import as_geometry
from feeder.mechanics.pmf import analytic_pmf
from feeder.parts.geometry import load_part

STEEP_DEG = 45.0  # a straight fence at least this steep counts as steep in the summary
AGREE_DEG = 5.0  # two final yaws this close (modulo the symmetry period) are the same outcome
YAW_SAME_DEG = 1e-6  # a modelled final yaw this close to the initial one: the model left the drop untouched


def cell_weights(y0: np.ndarray, period: float) -> np.ndarray:
    """Each initial yaw's share of the period: half the gap to each neighbour on the circle."""
    order = np.argsort(y0)
    ys = y0[order]
    nxt = np.roll(ys, -1)
    nxt[-1] += period
    prv = np.roll(ys, 1)
    prv[0] -= period
    w = np.empty(len(y0))
    w[order] = (nxt - prv) / (2.0 * period)
    return w


def analytic_final(geom, fences, yaws, mu, memo) -> tuple[np.ndarray, list[float]]:
    """Final yaw of each drop (NaN: jammed) through ``fences`` in order, and each fence's touched
    share; the drops are tracked through ``_apply`` by their weights (index + 1), under the hard
    jam rule (each drop's likeliest end). ValueError when a fence rolls the part (its drops leave
    at a density, not one yaw each)."""
    yaw = np.asarray(yaws, dtype=np.float64).copy()
    x = np.zeros_like(yaw)
    tag = np.arange(1.0, yaw.size + 1.0)
    touched = []
    for m in fences:
        if m not in memo:
            memo[m] = D.fence_response(geom, m, mu, True)
        if memo[m].push.rolls:
            raise ValueError("a fence rolls the part: no yaw per drop")
        yaw, x, tag, (t, _, _) = D._apply(geom, memo[m], mu, yaw, x, tag, True, 0.0)  # hard: a drop's likeliest end
        touched.append(t)
    out = np.full(len(yaws), np.nan)
    out[np.rint(tag).astype(int) - 1] = yaw
    return out, touched


def exit_reasons(geom, model, yaws, mu, memo) -> list[str]:
    """Why the modelled exit turn of each drop's basin on one fence stopped
    (:class:`feeder.mechanics.exitturn.ExitTurn`: ``released`` is the complete model; ``notch``
    is where it gives up for a square tip and hooks for a round one; ``wedged``, ``end face``,
    ``hooked``, ``phases``, ``travel``, ``stuck`` are where it gives up),
    for drops whose centred start reaches the fence (else ``missed``)."""
    if model not in memo:
        memo[model] = D.fence_response(geom, model, mu, True)
    resp = memo[model]
    key = ("reasons", model)
    if key not in memo:  # the response's own (around a round tip's cap if it has one) ...
        memo[key] = [  # ... or, where the exit face holds the part and it has none, the turn it would take
            why or exit_turn(geom, int(e), model.exit_deg, model.side, mu).reason
            for why, e in zip(resp.exit_reason, resp.push.edges)
        ]
    phi = fence_normal_deg(model.exit_deg, model.side) - np.asarray(yaws, dtype=np.float64)
    idx = resp.push.basin_index(phi)
    reach = D._support_towards(geom, np.asarray(yaws, dtype=np.float64), model.side)
    return [memo[key][int(i)] if r > model.inner else "missed" for i, r in zip(idx, reach)]


def file_scene(meta: dict) -> dict:
    """The scene a simulation file was run with (its settings), else the study's default."""
    return meta.get("settings", {}).get("scene") or default_scene()


def sim_files(sim_dir: Path, parts_dir: Path):
    """Every simulation file of ``sim_dir`` (parts, then files, in name order) with what the drop
    comparisons read: ``(part, geometry, path, scene, period, initial yaws, final yaws, statuses)``;
    the scene is the file's own (:func:`file_scene`), the period its design's symmetry period."""
    for part_dir in sorted(p for p in sim_dir.iterdir() if p.is_dir()):
        geom = as_geometry(load_part(parts_dir / f"{part_dir.name}.stl"))
        for path in sorted(part_dir.glob("*.npz")):
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                y0, yf, status = z["initial_yaw_deg"], z["final_yaw_deg"], z["status"]
            period = 360.0 / int(meta["design"].get("symmetry_order", 1))
            yield part_dir.name, geom, path, meta, file_scene(meta), period, y0, yf, status


def dropwise(sim_dir: Path, parts_dir: Path) -> tuple[pd.DataFrame, list[str], list[dict]]:
    """The drop rows, the configurations left out (a fence rolls the part) and the distinct
    scenes of the files (each file is modelled with its own scene: a round tip's cap included)."""
    rows, rolling, scenes = [], [], []
    for part_dir in sorted(p for p in sim_dir.iterdir() if p.is_dir()):
        part = part_dir.name
        geom = as_geometry(load_part(parts_dir / f"{part}.stl"))
        memos: dict = {}
        for path in sorted(part_dir.glob("*.npz")):
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                y0, yf, status = z["initial_yaw_deg"], z["final_yaw_deg"], z["status"]
            scene = file_scene(meta)
            if scene not in scenes:
                scenes.append(scene)
            mu = fence_mu(scene)
            memo = memos.setdefault(mu, {})
            period = 360.0 / int(meta["design"].get("symmetry_order", 1))
            fences = fence_models(meta["loc1"], meta["loc2"], scene)
            for m in fences:
                if m not in memo:
                    memo[m] = D.fence_response(geom, m, mu, True)
            if any(memo[m].push.rolls for m in fences):
                rolling.append(f"{part} {path.stem}")
                continue
            ana, _ = analytic_final(geom, fences, y0, mu, memo)
            w = cell_weights(y0, period)
            why = exit_reasons(geom, fences[0], y0, mu, memo) if len(fences) == 1 else [""] * len(y0)
            for i in range(len(y0)):
                rows.append(
                    (part, path.stem, meta["loc1"], meta["loc2"], period, y0[i], w[i], status[i], yf[i], ana[i], why[i])
                )
    cols = ["part", "config_id", "loc1", "loc2", "period", "initial_yaw_deg", "weight", "status", "final_yaw_deg"]
    return pd.DataFrame(rows, columns=cols + ["analytic_yaw_deg", "exit_reason"]), rolling, scenes


def agreement(df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Per group: configurations, and the weighted share of initial yaws whose drops agree (both
    ok, within ``AGREE_DEG``), both jam, or where exactly one of the two jams."""
    sim_ok = df.status == "ok"
    ana_ok = df.analytic_yaw_deg.notna()
    p = df.period
    d = np.abs((df.final_yaw_deg - df.analytic_yaw_deg + p / 2) % p - p / 2)
    flags = pd.DataFrame(
        {"agree": sim_ok & ana_ok & (d < AGREE_DEG), "both_jam": ~sim_ok & ~ana_ok, "one_jams": sim_ok != ana_ok}
    )
    w = df.weight
    grouped = flags.mul(w, axis=0).groupby([df[k] for k in keys]).sum()
    out = grouped.div(w.groupby([df[k] for k in keys]).sum(), axis=0)
    out.insert(0, "configs", df.groupby(keys).apply(lambda g: g.groupby(["part", "config_id"]).ngroups))
    return out


def _one_fence(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of one fence alone, at either location, with its ``location``, ``fence`` type
    and ``angle``, and the yaw gap between the two final yaws where both end ok (``gap_deg``)."""
    one = df[(df.loc1 == "none") != (df.loc2 == "none")]
    at2 = one.loc1 == "none"
    where = one.loc2.where(at2, one.loc1)
    p = one.period
    ok = (one.status == "ok") & one.analytic_yaw_deg.notna()
    gap = np.abs((one.final_yaw_deg - one.analytic_yaw_deg + p / 2) % p - p / 2)
    return one.assign(
        location=np.where(at2, "loc2", "loc1"),
        fence=where.str.split(":").str[0],
        angle=where.str.split(":").str[1].astype(int),
        gap_deg=gap.where(ok),
    )


def one_fence_table(df: pd.DataFrame) -> pd.DataFrame:
    """One fence alone (at either location), by its type and angle: the weighted share of initial
    yaws that agree, that the model leaves untouched (final = initial: it says the part misses
    the fence, or only grazes a curved fence's tip), that it leaves untouched while the simulator
    turns them by at least ``AGREE_DEG``, and where exactly one of the two jams (either way); and
    the weighted quartiles of the yaw gap where both end ok."""
    one = _one_fence(df)
    p = one.period
    sim_ok, ana_ok = one.status == "ok", one.analytic_yaw_deg.notna()
    untouched = ana_ok & (np.abs((one.analytic_yaw_deg - one.initial_yaw_deg + p / 2) % p - p / 2) < YAW_SAME_DEG)
    moved = sim_ok & (np.abs((one.final_yaw_deg - one.initial_yaw_deg + p / 2) % p - p / 2) >= AGREE_DEG)
    flags = pd.DataFrame(
        {
            "agree": sim_ok & ana_ok & (one.gap_deg < AGREE_DEG),
            "untouched": untouched,
            "untouched_but_moved": untouched & moved,
            "model_jams_only": sim_ok & ~ana_ok,
            "sim_jams_only": ~sim_ok & ana_ok,
        }
    ).astype(float)
    keys = [one.fence, one.angle]
    w = one.weight
    out = flags.mul(w, axis=0).groupby(keys).sum().div(w.groupby(keys).sum(), axis=0)
    out.insert(0, "configs", one.groupby(keys).apply(lambda g: len(g.groupby(["part", "config_id"]))))
    gaps = one.groupby(keys).apply(lambda g: weighted_quantiles(g.gap_deg, g.weight, (0.25, 0.5, 0.75)))
    out[["gap_q25_deg", "gap_median_deg", "gap_q75_deg"]] = np.vstack(gaps.to_numpy())
    return out.reset_index()


def weighted_quantiles(values: pd.Series, weights: pd.Series, qs) -> np.ndarray:
    """Quantiles of ``values`` (NaN left out) under ``weights``: the smallest value whose
    cumulative weight share reaches each q."""
    keep = values.notna().to_numpy()
    v, w = values.to_numpy()[keep], weights.to_numpy()[keep]
    if v.size == 0:
        return np.full(len(qs), np.nan)
    order = np.argsort(v, kind="stable")
    share = np.cumsum(w[order]) / w.sum()
    return np.array([v[order][np.searchsorted(share, q)] for q in qs])


def one_curved_by_reason(df: pd.DataFrame, angles: tuple[int, int]) -> pd.DataFrame:
    """One curved fence alone at ``angles[0]``..``angles[1]`` degrees, by why the modelled exit
    turn of each drop's basin stopped: weighted share, agreement and gap quartiles."""
    one = _one_fence(df)
    one = one[(one.fence == "curved") & one.angle.between(*angles)]
    ok = (one.status == "ok") & one.analytic_yaw_deg.notna()
    one = one.assign(agree=(ok & (one.gap_deg < AGREE_DEG)).astype(float))
    rows = []
    for why, g in one.groupby("exit_reason"):
        q = weighted_quantiles(g.gap_deg, g.weight, (0.25, 0.5, 0.75))
        rows.append((why, g.weight.sum() / one.weight.sum(), np.average(g.agree, weights=g.weight), *q))
    return pd.DataFrame(rows, columns=["exit_reason", "share", "agree", "gap_q25_deg", "gap_median_deg", "gap_q75_deg"])


def summarise(df: pd.DataFrame) -> None:
    df = df.assign(fences=[fence_types(c) for c in df.config_id])
    print(f"drops {len(df)}, configurations {df.groupby(['part', 'config_id']).ngroups}")
    print("share of the initial yaws (weighted) by fence types (Location 1 + Location 2):")
    print(agreement(df, ["fences"]).round(3).to_string())
    one = df[(df.loc2 == "none") & df.loc1.str.startswith("straight")]
    one = one.assign(angle=one.loc1.str.split(":").str[1].astype(int))
    print("one straight fence, by its angle:")
    print(agreement(one, ["angle"]).round(3).to_string())
    one = one.assign(steep=one.angle >= STEEP_DEG)
    share = one.groupby(["steep", "exit_reason"]).weight.sum()
    table = agreement(one, ["steep", "exit_reason"]).assign(share=share / share.groupby(level=0).transform("sum"))
    print(f"one straight fence, by why the modelled exit turn stopped (steep: >= {STEEP_DEG:g} deg):")
    print(table.round(3).to_string())
    print("one fence alone (either location), by its type and angle (untouched: the model leaves the yaw as it was):")
    print(one_fence_table(df).round(3).to_string(index=False))
    print("one curved fence alone at 10-40 deg, by why the modelled exit turn stopped:")
    print(one_curved_by_reason(df, (10, 40)).round(3).to_string(index=False))


def budget_scores(dataset: Path, parts_dir: Path, scales: list[float], scene: dict) -> pd.DataFrame:
    """The analytic PMF's circular W1 to the label of every kept configuration of ``dataset`` with
    the turn budget multiplied by each scale (``analytic_distribution``'s ``turn_budget_scale``); a
    configuration where every drop jams is scored with its PMF without jams, as ``analytic_pmf``
    gives it."""
    data = load_dataset(dataset)
    geoms: dict = {}
    rows = []
    memos: dict = {}  # the exit turns do not depend on the budget: one memo per part for every scale
    for scale in scales:
        for i, (part, config_id) in enumerate(zip(data["part"], data["config_id"])):
            part = str(part)
            if part not in geoms:
                geoms[part] = as_geometry(load_part(parts_dir / f"{part}.stl"))
            loc1, loc2 = parse_config_id(str(config_id))
            memo = memos.setdefault(part, {})
            dist = D.analytic_distribution(geoms[part], loc1, loc2, scene, responses=memo, turn_budget_scale=scale)
            if dist.weights.sum() <= 0.0:  # every drop jams: the PMF without jams
                dist = D.analytic_distribution(
                    geoms[part], loc1, loc2, scene, responses=memo, turn_budget_scale=scale, jams=False
                )
            pmf = analytic_pmf(geoms[part], None, None, frame_deg=float(data["frame_deg"][i]), distribution=dist)
            cw1 = float(circular_w1(np.cumsum(pmf), data["cdf"][i]))
            rows.append((scale, part, str(config_id), str(data["split"][i]), cw1))
        print(f"turn budget x {scale:g}: mean circular W1 {np.mean([r[-1] for r in rows if r[0] == scale]):.2f} deg")
    return pd.DataFrame(rows, columns=["budget_scale", "part", "config_id", "split", "circular_w1_deg"])


def budget_summary(raw: pd.DataFrame) -> pd.DataFrame:
    """Per split (and pooled: all but ``train``, ``held_out``; ``parts`` and ``wide``, the parts no
    Main fit trains on, ``parts_and_wide``) and scale: the mean circular
    W1 and its difference from scale 1, paired by configuration, with a 95 % bootstrap interval
    over parts. The scale is to be chosen on ``train`` alone."""
    from soft_jams import paired_interval

    rng = np.random.default_rng(0)
    raw = raw.rename(columns={"circular_w1_deg": "cw1"})
    groups = [(split, raw[raw.split == split]) for split in sorted(raw.split.unique())]
    groups.append(("held_out", raw[raw.split != "train"]))
    groups.append(("parts_and_wide", raw[raw.split.isin(["parts", "wide"])]))  # parts no Main fit trains on
    rows = []
    for name, g in groups:
        base = g[g.budget_scale == 1.0]
        for scale, h in g.groupby("budget_scale"):
            diff = paired_interval(base, h, "cw1", rng) if scale != 1.0 else (0.0, 0.0, 0.0)
            rows.append((name, scale, h.part.nunique(), len(h), h.cw1.mean(), *diff))
    cols = ["split", "budget_scale", "parts", "configs", "cw1_mean", "diff_vs_1", "diff_lo", "diff_hi"]
    return pd.DataFrame(rows, columns=cols)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sim_dir", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    ap.add_argument("--dataset", type=Path)
    ap.add_argument("--budget-scales", default="")
    ap.add_argument("--budget-csv", type=Path)
    ap.add_argument("--one-fence-csv", type=Path, help="also write the one-fence table here")
    ap.add_argument("--from-rows", action="store_true", help="OUT_CSV_GZ exists: summarise its rows, simulate nothing")
    args = ap.parse_args(argv)
    if args.from_rows and args.budget_scales:
        sys.exit("--budget-scales needs the simulation files' scene: run without --from-rows")
    if args.from_rows:
        df, scenes = pd.read_csv(args.out_csv), []
    else:
        df, rolling, scenes = dropwise(args.sim_dir, args.parts_dir)
        write_bytes(args.out_csv, gzip.compress(df.to_csv(index=False, lineterminator="\n").encode(), mtime=0))
        parts = sorted({r.split()[0] for r in rolling})
        print(
            f"left out: {len(rolling)} configurations where a fence rolls the part (no stable edge), "
            f"of {', '.join(parts) or 'none'}"
        )
    summarise(df)
    if args.one_fence_csv:
        write_csv(args.one_fence_csv, one_fence_table(df))
    if args.budget_scales:
        if args.dataset is None or args.budget_csv is None:
            sys.exit("--budget-scales needs --dataset and --budget-csv")
        if len(scenes) != 1:
            sys.exit(f"--budget-scales needs simulation files of one scene, got {len(scenes)}")
        scales = [float(s) for s in args.budget_scales.split(",")]
        if 1.0 not in scales:
            sys.exit("--budget-scales must include 1 (the derived bound, the reference of every comparison)")
        raw = budget_scores(args.dataset, args.parts_dir, scales, scenes[0])
        write_csv(args.budget_csv, raw)
        summary = budget_summary(raw)
        write_csv(args.budget_csv.with_name(args.budget_csv.stem + "_summary.csv"), summary)
        print(summary.round(3).to_string(index=False))
        raw["fences"] = [fence_types(c) for c in raw.config_id]
        for key in ("split", "fences"):
            print(raw.pivot_table(index=key, columns="budget_scale", values="circular_w1_deg").round(2).to_string())
        per_part = raw.groupby(["budget_scale", "part"]).circular_w1_deg.mean().unstack(0)
        print("per part (what GroupKFold averages):", per_part.mean().round(2).to_dict())
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
