"""Two runs of the study, paired drop by drop and label by label (issue #39: the round-tip re-baseline).

A re-baseline changes the simulator (here ``scene.fences.tip: square`` to ``round``) and
re-simulates every configuration. Seeds derive from the part and configuration ids, so both runs
start the adaptive design from the same grid of initial yaws (``sim.adaptive.n0`` per symmetry
period) and share every later yaw where their refinements coincide. This script pairs those drops:

* **Drops** (``OUT_CSV_GZ``, one row per initial yaw both runs simulated): a pair is the *same
  outcome* when both end ok within ``SAME_DEG`` of each other (modulo the part's symmetry period)
  or both end with the same non-ok status. Per group of configurations: the mean over
  configurations of the share of same outcomes, with a 95 % bootstrap interval over
  configurations, and the median |Δyaw| of the pairs that are both ok.
* **Labels** (``--old-dataset`` / ``--new-dataset``, the runs' ``results/datasets/dataset.npz``):
  per configuration kept in both, the circular W1 between the two labels; per configuration in
  either, whether it was kept (excluded ones jammed); and, if ``--analytic`` is given, the
  analytic PMF's circular W1 to each run's label, paired, with a 95 % bootstrap interval over
  configurations: the old run's model (its scene) against both labels (``diff``: the analytic
  model reads no label, so the difference is the labels' alone), and the new run's model (its
  scene: a round tip's cap) against the new labels (``diff_own``: what the re-baseline gives).
  Each run's scene is read from its simulation files (their settings).
  Rows: ``OUT_CSV_GZ`` with ``_labels.csv`` in place of ``.csv.gz``.

    python docs/experiments/rebaseline_pairs.py OLD_SIM_DIR NEW_SIM_DIR PARTS_DIR OUT_CSV_GZ \
        [--old-dataset OLD.npz --new-dataset NEW.npz --analytic] [--new-scene-glob '*/*curved*.npz']

A re-baseline that changes only some configurations (the seam-free curved fences of
``config/hull.yaml``) copies the others from the old run; ``--new-scene-glob`` names the files
whose settings are the new run's scene; only those are paired drop by drop. Drops are also
grouped by the part's concavity (``concave``: solidity below ``curved_jams.CONCAVE_BELOW``), the
decomposition test's question: a contact change meant for sharp and concave parts must leave convex
ones where they were.

Reading 2 x 1,578 simulation files takes seconds; ``--analytic`` about 3 minutes more.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.io import write_csv
from feeder.labels.dataset import load_dataset
from feeder.labels.metrics import circular_w1
from feeder.lane.fences import parse_config_id
from feeder.learn.evaluate import fence_types

sys.path.insert(0, str(Path(__file__).resolve().parent))
from curved_jams import CONCAVE_BELOW, solidity  # noqa: E402 - this folder's scripts

SAME_DEG = 5.0  # two final yaws this close (modulo the symmetry period) are the same outcome
STEEP_DEG = 45.0  # a straight fence at least this steep makes a configuration steep
YAW_MATCH_DEG = 1e-9  # initial yaws this close are the same drop
RESAMPLES = 10_000
SEED = 0


def read_sim(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        out = {k: z[k].copy() for k in ("initial_yaw_deg", "final_yaw_deg", "status")}
    out["period"] = 360.0 / int(meta["design"].get("symmetry_order", 1))
    out["loc1"], out["loc2"] = meta["loc1"], meta["loc2"]
    return out


def steep(loc1: str, loc2: str) -> bool:
    return any(s.startswith("straight:") and float(s.split(":")[1]) >= STEEP_DEG for s in (loc1, loc2))


def pair_drops(old_dir: Path, new_dir: Path, pattern: str = "*/*.npz") -> pd.DataFrame:
    rows = []
    for new_path in sorted(new_dir.glob(pattern)):
        old_path = old_dir / new_path.parent.name / new_path.name
        if not old_path.is_file():
            continue
        a, b = read_sim(old_path), read_sim(new_path)
        ia = np.argsort(a["initial_yaw_deg"])
        ya = a["initial_yaw_deg"][ia]
        for j, y in enumerate(b["initial_yaw_deg"]):
            k = int(np.searchsorted(ya, y))
            hit = [i for i in (k - 1, k) if 0 <= i < ya.size and abs(ya[i] - y) <= YAW_MATCH_DEG]
            if not hit:
                continue
            i = ia[hit[0]]
            rows.append(
                (
                    new_path.parent.name,
                    new_path.stem,
                    b["loc1"],
                    b["loc2"],
                    b["period"],
                    float(y),
                    str(a["status"][i]),
                    float(a["final_yaw_deg"][i]),
                    str(b["status"][j]),
                    float(b["final_yaw_deg"][j]),
                )
            )
    cols = ["part", "config_id", "loc1", "loc2", "period", "initial_yaw_deg"]
    return pd.DataFrame(rows, columns=cols + ["old_status", "old_yaw_deg", "new_status", "new_yaw_deg"])


def with_outcomes(df: pd.DataFrame) -> pd.DataFrame:
    p = df.period
    both_ok = (df.old_status == "ok") & (df.new_status == "ok")
    d = np.abs((df.new_yaw_deg - df.old_yaw_deg + p / 2) % p - p / 2)
    same = np.where(both_ok, d < SAME_DEG, (df.old_status == df.new_status) & ~both_ok)
    return df.assign(
        fences=[fence_types(c) for c in df.config_id],
        steep=[steep(a, b) for a, b in zip(df.loc1, df.loc2)],
        both_ok=both_ok,
        abs_dyaw_deg=np.where(both_ok, d, np.nan),
        same=same,
    )


def boot_mean(values: np.ndarray, rng: np.random.Generator) -> tuple[float, float, float]:
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return float("nan"), float("nan"), float("nan")
    idx = rng.integers(0, values.size, size=(RESAMPLES, values.size))
    means = values[idx].mean(axis=1)
    return float(values.mean()), float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))


def drop_summary(df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    rng = np.random.default_rng(SEED)
    per_config = df.groupby(keys + ["part", "config_id"]).agg(same=("same", "mean"), drops=("same", "size"))
    median = df.groupby(keys).abs_dyaw_deg.median()
    out = []
    for key, g in per_config.groupby(level=list(range(len(keys)))):
        m, lo, hi = boot_mean(g.same.to_numpy(), rng)
        key = key if isinstance(key, tuple) else (key,)
        med = float(median.loc[key if len(keys) > 1 else key[0]])
        out.append((*key, len(g), int(g.drops.sum()), m, lo, hi, med))
    return pd.DataFrame(out, columns=keys + ["configs", "drops", "same", "same_lo", "same_hi", "median_abs_dyaw_deg"])


def run_scene(sim_dir: Path, pattern: str = "*/*.npz") -> dict:
    """The one scene every simulation file of a run (those matching ``pattern``) was simulated with."""
    scenes: list[dict] = []
    for path in sorted(sim_dir.glob(pattern)):
        with np.load(path, allow_pickle=False) as z:
            scene = json.loads(str(z["meta"]))["settings"]["scene"]
        if scene not in scenes:
            scenes.append(scene)
    if len(scenes) != 1:
        raise SystemExit(f"{sim_dir}: simulation files of {len(scenes)} scenes, not one")
    return scenes[0]


def label_rows(old_npz: Path, new_npz: Path, parts_dir: Path | None, scenes: tuple = (None, None)) -> pd.DataFrame:
    old, new = load_dataset(old_npz), load_dataset(new_npz)

    def index(d):
        return {(str(p), str(c)): i for i, (p, c) in enumerate(zip(d["part"], d["config_id"]))}

    io, inew = index(old), index(new)
    memos: dict = {}
    geoms: dict = {}
    rows = []
    for key in sorted(set(io) | set(inew)):
        part, config_id = key
        loc1, loc2 = parse_config_id(config_id)
        row = {
            "part": part,
            "config_id": config_id,
            "fences": fence_types(config_id),
            "steep": any(f.type == "straight" and f.angle >= STEEP_DEG for f in (loc1, loc2)),
            "old_kept": key in io,
            "new_kept": key in inew,
        }
        if key in io and key in inew:
            ca, cb = old["cdf"][io[key]], new["cdf"][inew[key]]
            row["label_cw1_deg"] = float(circular_w1(ca, cb))
            row["split"] = str(new["split"][inew[key]])
            if parts_dir is not None:
                from feeder.mechanics.distribution import analytic_distribution
                from feeder.mechanics.hull import as_geometry
                from feeder.mechanics.pmf import analytic_pmf
                from feeder.parts.geometry import load_part

                if part not in geoms:
                    geoms[part] = as_geometry(load_part(parts_dir / f"{part}.stl"))
                frame = float(new["frame_deg"][inew[key]])
                if frame != float(old["frame_deg"][io[key]]):
                    raise SystemExit(f"{part} {config_id}: the label frames differ between the runs")
                cdfs = []
                for run, scene in enumerate(scenes):
                    memo = memos.setdefault((run, part), {})
                    dist = analytic_distribution(geoms[part], loc1, loc2, scene, responses=memo)
                    pmf = analytic_pmf(geoms[part], loc1, loc2, scene, frame_deg=frame, distribution=dist)
                    cdfs.append(np.cumsum(pmf))
                row["analytic_old_cw1_deg"] = float(circular_w1(cdfs[0], ca))
                row["analytic_new_cw1_deg"] = float(circular_w1(cdfs[0], cb))
                row["analytic_own_new_cw1_deg"] = float(circular_w1(cdfs[1], cb))
        rows.append(row)
    return pd.DataFrame(rows)


def label_summary(df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    rng = np.random.default_rng(SEED)
    out = []
    for key, g in df.groupby(keys):
        both = g[g.old_kept & g.new_kept]
        rec = dict(zip(keys, key if isinstance(key, tuple) else (key,)))
        rec.update(
            configs=len(g),
            kept_old=int(g.old_kept.sum()),
            kept_new=int(g.new_kept.sum()),
            label_cw1_deg=float(both.label_cw1_deg.mean()),
        )
        if "analytic_new_cw1_deg" in both:
            diff = (both.analytic_new_cw1_deg - both.analytic_old_cw1_deg).to_numpy()
            m, lo, hi = boot_mean(diff, rng)
            own = (both.analytic_own_new_cw1_deg - both.analytic_old_cw1_deg).to_numpy()
            m2, lo2, hi2 = boot_mean(own, rng)
            rec.update(
                analytic_old=float(both.analytic_old_cw1_deg.mean()),
                analytic_new=float(both.analytic_new_cw1_deg.mean()),
                diff=m,
                diff_lo=lo,
                diff_hi=hi,
                analytic_own_new=float(both.analytic_own_new_cw1_deg.mean()),
                diff_own=m2,
                diff_own_lo=lo2,
                diff_own_hi=hi2,
            )
        out.append(rec)
    return pd.DataFrame(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old_sim", type=Path)
    ap.add_argument("new_sim", type=Path)
    ap.add_argument("parts", type=Path)
    ap.add_argument("out", type=Path, help="drop pairs, .csv.gz")
    ap.add_argument("--old-dataset", type=Path)
    ap.add_argument("--new-dataset", type=Path)
    ap.add_argument("--analytic", action="store_true", help="score the analytic PMF against both labels")
    ap.add_argument("--new-scene-glob", default="*/*.npz", help="the new run's files that carry its scene")
    args = ap.parse_args()
    pd.set_option("display.width", 200)
    drops = with_outcomes(pair_drops(args.old_sim, args.new_sim, args.new_scene_glob))
    sol = {p: solidity(args.parts / f"{p}.stl") for p in drops.part.unique()}
    drops = drops.assign(solidity=drops.part.map(sol), concave=drops.part.map(sol) < CONCAVE_BELOW)
    drops.to_csv(args.out, index=False)  # gzip by the name's suffix (write_csv writes plain text)
    print(f"paired drops {len(drops)} over {drops.groupby(['part', 'config_id']).ngroups} configurations")
    for keys in (["fences"], ["steep"], ["fences", "steep"], ["concave"], ["fences", "concave"]):
        print(drop_summary(drops, keys).round(3).to_string(index=False))
    if args.old_dataset and args.new_dataset:
        scenes = (
            (run_scene(args.old_sim), run_scene(args.new_sim, args.new_scene_glob)) if args.analytic else (None, None)
        )
        labels = label_rows(args.old_dataset, args.new_dataset, args.parts if args.analytic else None, scenes)
        write_csv(Path(str(args.out).replace(".csv.gz", "_labels.csv")), labels)
        all_rows = labels.assign(all="all")
        for keys in (["all"], ["fences"], ["steep"], ["split"]):
            print(label_summary(all_rows, keys).round(3).to_string(index=False))


if __name__ == "__main__":
    main()
