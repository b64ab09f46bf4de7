"""``feeder evaluate``: the regression models on the 360-bin CDFs (paper §3.5.3, Tables 5–8,
Figs. 12–13) and the leave-parts-out GroupKFold study of one model.

Metrics compare post-processed predicted CDFs with the true CDFs row by row
(``feeder.labels.metrics``): R² over the bins of one configuration, W1 = Σ|ΔF| in degrees and the MSE
(the paper's), and beside them the rotation-invariant pair (``r2c``: R² at the best common cut of
the circle; ``cw1``: circular W1, the W1 minimised over cuts), which do not depend on where 0°
falls in the label frame; a table reports mean ± population SD (ddof = 0) over the configurations
of a split.

Two baselines sit beside the models in every table:

* ``baseline_mean_pmf``: the mean PMF of the training rows, for every configuration;
* ``baseline_nearest_part``: the PMF of the nearest training configuration in the scaled 53-d
  input space (Euclidean; the scaler is fit on the training rows). A training row is never its
  own neighbour (leave-one-out), so the Train table shows an honest baseline.

``train_s`` is the training wall time (from the model's ``metrics.json``); for the baselines it
is the measured time to build them.

Subcommands::

    feeder evaluate tables --dataset D --models results/models/m1 ... --out-dir results/tables
    feeder evaluate groupkfold --dataset D --out results/tables/groupkfold_m3.csv model=m3 [overrides]
    feeder evaluate figure-data --dataset D --model results/models/m3 --fig12-data F12.npz --fig13-data F13.npz
    feeder evaluate grid --dir results/models/grid/m3 --out results/tables/grid_m3.csv
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError

# split -> (table number, caption)
TABLES = {
    "train": (5, "Regression models on the training rows (CDF R², W1 in degrees)"),
    "test": (6, "Regression models on Test: known parts, unseen fence angles (P1)"),
    "fences": (7, "Regression models on Fences: unseen part-fence type combinations (P1)"),
    "parts": (8, "Regression models on Parts: unseen part geometries (P3)"),
}
METRIC_COLUMNS = ["r2_mean", "r2_sd", "w1_mean", "w1_sd", "mse_mean", "r2c_mean", "r2c_sd", "cw1_mean", "cw1_sd"]
COLUMNS = ["model", "n", *METRIC_COLUMNS, "train_s"]
BREAKDOWN_COLUMNS = ["model", "group", "n", *METRIC_COLUMNS]
BASELINE_MEAN = "baseline_mean_pmf"
BASELINE_NEAREST = "baseline_nearest_part"
# Figs. 12-13: the rows at these quantiles of the model's R² (best to worst) are shown.
FIGURE_QUANTILES = (0.9, 0.6, 0.3, 0.1)


# ----------------------------------------------------------------------------------------------
# Metrics and baselines (pure)
# ----------------------------------------------------------------------------------------------
def row_metrics(cdf_true: np.ndarray, cdf_pred: np.ndarray) -> dict[str, np.ndarray]:
    """Per-configuration R², W1 (degrees) and MSE of predicted against true CDF rows, and the
    rotation-invariant R² (best common cut) and circular W1 (degrees)."""
    from feeder.labels.metrics import circular_w1, mse, r2_cdf, r2_cdf_best_cut, w1

    return {
        "r2": r2_cdf(cdf_true, cdf_pred),
        "w1": w1(cdf_true, cdf_pred),
        "mse": mse(cdf_true, cdf_pred),
        "r2c": r2_cdf_best_cut(cdf_true, cdf_pred),
        "cw1": circular_w1(cdf_true, cdf_pred),
    }


_SPREAD = ("r2", "w1", "r2c", "cw1")  # reported as mean and population SD; mse as its mean


def summarise(m: dict[str, np.ndarray]) -> dict[str, float]:
    """n, mean and population SD (ddof = 0) of per-configuration metrics."""
    n = int(m["r2"].size)
    out: dict[str, float] = {"n": n}
    for k in _SPREAD:
        out[f"{k}_mean"] = float(np.mean(m[k])) if n else np.nan
        out[f"{k}_sd"] = float(np.std(m[k], ddof=0)) if n else np.nan
    out["mse_mean"] = float(np.mean(m["mse"])) if n else np.nan
    return out


def nearest_rows(query: np.ndarray, ref: np.ndarray, exclude_same: np.ndarray | None = None) -> np.ndarray:
    """Index into ``ref`` of the Euclidean-nearest row for every query row (first on ties).

    ``exclude_same[i]`` (an index into ``ref`` or −1) is a row query ``i`` may not pick
    (leave-one-out for queries that are themselves reference rows)."""
    query = np.asarray(query, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    exclude = np.full(len(query), -1) if exclude_same is None else np.asarray(exclude_same)
    out = np.empty(len(query), dtype=np.int64)
    chunk = 64  # rows per block of exact differences (bounded memory)
    for start in range(0, len(query), chunk):
        q = query[start : start + chunk]
        d2 = ((q[:, None, :] - ref[None, :, :]) ** 2).sum(axis=-1)
        ex = exclude[start : start + chunk]
        rows = np.flatnonzero(ex >= 0)
        d2[rows, ex[rows]] = np.inf
        out[start : start + chunk] = np.argmin(d2, axis=1)
    return out


def baseline_predictions(data: dict, train_mask: np.ndarray) -> dict[str, tuple[np.ndarray, float]]:
    """CDF predictions of both baselines for every row, with the seconds each took to build."""
    from feeder.labels.dataset import fit_scaler

    t0 = time.perf_counter()
    mean_pmf = data["pmf"][train_mask].mean(axis=0)
    mean_cdf = np.broadcast_to(np.cumsum(mean_pmf), data["cdf"].shape)
    t_mean = time.perf_counter() - t0

    t0 = time.perf_counter()
    scaler = fit_scaler(data["part_raw"], data["feeder_raw"], train_mask)
    x = scaler.transform(data["part_raw"], data["feeder_raw"])
    train_rows = np.flatnonzero(train_mask)
    position = np.full(len(x), -1)
    position[train_rows] = np.arange(train_rows.size)
    if train_rows.size < 2:
        raise FeederError("the nearest-configuration baseline needs at least 2 training rows")
    nearest = train_rows[nearest_rows(x, x[train_rows], exclude_same=position)]
    near_cdf = np.cumsum(data["pmf"][nearest], axis=1)
    t_near = time.perf_counter() - t0
    return {BASELINE_MEAN: (mean_cdf, t_mean), BASELINE_NEAREST: (near_cdf, t_near)}


def combo_label(config_id: str) -> str:
    """Fence-type combination of a configuration id: ``curved-1 + straight-2``, ``curved-2 only``."""
    from feeder.sim.fences import parse_config_id

    loc1, loc2 = parse_config_id(config_id)
    present = [f"{f.type}-{i}" for i, f in ((1, loc1), (2, loc2)) if f.present]
    if not present:
        return "no fence"
    return present[0] + " only" if len(present) == 1 else " + ".join(present)


# ----------------------------------------------------------------------------------------------
# Tables
# ----------------------------------------------------------------------------------------------
def _write_table(path: Path, df: pd.DataFrame, caption: str) -> None:
    from feeder.io import markdown_table, write_csv, write_text

    write_csv(path, df)
    write_text(path.with_suffix(".md"), markdown_table(df, caption))


def load_models(model_dirs) -> list[tuple[str, object, float]]:
    """(name, TrainedModel, train_s) of every model directory."""
    from feeder.learn.models import TrainedModel

    out = []
    for d in model_dirs:
        d = Path(d)
        metrics_path = d / "metrics.json"
        if not metrics_path.is_file():
            raise FeederError(f"{metrics_path}: missing (train the model first)")
        metrics = json.loads(metrics_path.read_text())
        out.append((str(metrics.get("model", d.name)), TrainedModel.load(d), float(metrics["train_s"])))
    return out


def evaluation_tables(data: dict, models: list[tuple[str, object, float]]):
    """Tables 5–8 (split -> DataFrame) and the Fences/Parts breakdowns."""
    train_mask = data["split"] == "train"
    preds: list[tuple[str, np.ndarray, float]] = []
    for name, model, train_s in models:
        _, cdf = model.predict(data["part_raw"], data["feeder_raw"])
        preds.append((name, cdf, train_s))
    for name, (cdf, secs) in baseline_predictions(data, train_mask).items():
        preds.append((name, cdf, secs))

    tables = {}
    per_row = {name: row_metrics(data["cdf"], cdf) for name, cdf, _ in preds}
    for split in TABLES:
        mask = data["split"] == split
        rows = [
            {"model": name, **summarise({k: v[mask] for k, v in per_row[name].items()}), "train_s": secs}
            for name, _, secs in preds
        ]
        tables[split] = pd.DataFrame(rows, columns=COLUMNS)

    def breakdown(split: str, groups: np.ndarray) -> pd.DataFrame:
        mask = data["split"] == split
        rows = []
        for name, _, _ in preds:
            for g in sorted(set(groups[mask])):
                sel = mask & (groups == g)
                rows.append({"model": name, "group": g, **summarise({k: v[sel] for k, v in per_row[name].items()})})
        return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS)

    combos = np.array([combo_label(c) for c in data["config_id"]])
    return tables, {"fences": breakdown("fences", combos), "parts": breakdown("parts", data["part"])}


def write_tables(dataset, model_dirs, out_dir) -> list[Path]:
    from feeder.labels.dataset import load_dataset

    data = load_dataset(dataset)
    models = load_models(model_dirs)
    tables, breakdowns = evaluation_tables(data, models)
    out_dir = Path(out_dir)
    written = []
    for split, (number, caption) in TABLES.items():
        n = int((data["split"] == split).sum())
        path = out_dir / f"table{number}.csv"
        _write_table(path, tables[split], f"Table {number}. {caption}; mean ± SD (ddof=0) over N = {n} configurations.")
        written.append(path)
    captions = {"fences": "Fences split by fence-type combination", "parts": "Parts split by part"}
    for split, df in breakdowns.items():
        path = out_dir / f"breakdown_{split}.csv"
        _write_table(path, df, f"{captions[split]} (CDF R², W1 in degrees; mean ± SD ddof=0).")
        written.append(path)
    return written


# ----------------------------------------------------------------------------------------------
# Leave-parts-out GroupKFold
# ----------------------------------------------------------------------------------------------
def groupkfold(data: dict, cfg, progress: bool | None = None) -> pd.DataFrame:
    """Train ``cfg.model`` once per ``group_fold`` on every row of the other folds and predict the
    held-out parts. Rows: per part, all held-out configurations, and the mean ± SD of the
    per-part means ("over parts"), for the model and both baselines (built per fold)."""
    from feeder.learn.train import fit

    folds = np.unique(data["group_fold"])
    if folds.size < 2:
        raise FeederError("GroupKFold needs at least 2 folds in group_fold")
    n_rows, bins = data["cdf"].shape
    name = str(cfg.model.name)
    names = [name, BASELINE_MEAN, BASELINE_NEAREST]
    preds = {k: np.full((n_rows, bins), np.nan) for k in names}
    secs = dict.fromkeys(names, 0.0)
    for fold in folds:
        test = data["group_fold"] == fold
        train = ~test
        fitted = fit(cfg, data, train, seed=int(cfg.seed) + int(fold), progress=progress)
        _, preds[name][test] = fitted.model.predict(data["part_raw"][test], data["feeder_raw"][test])
        secs[name] += fitted.train_s
        for b, (cdf, s) in baseline_predictions(data, train).items():
            preds[b][test] = cdf[test]
            secs[b] += s
    rows = []
    for model_name in names:
        m = row_metrics(data["cdf"], preds[model_name])
        part_means = []
        for part in sorted(set(data["part"])):
            sel = data["part"] == part
            s = summarise({k: v[sel] for k, v in m.items()})
            part_means.append(s)
            rows.append({"model": model_name, "group": part, **s, "train_s": np.nan})
        rows.append({"model": model_name, "group": "all configurations", **summarise(m), "train_s": secs[model_name]})
        over = {"model": model_name, "group": "over parts", "n": len(part_means)}
        for k in _SPREAD:
            means = np.array([s[f"{k}_mean"] for s in part_means])
            over[f"{k}_mean"], over[f"{k}_sd"] = means.mean(), means.std(ddof=0)
        over["mse_mean"] = float(np.mean([s["mse_mean"] for s in part_means]))
        rows.append({**over, "train_s": secs[model_name]})
    return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS + ["train_s"])


# ----------------------------------------------------------------------------------------------
# Figures 12-13: the data (drawn by feeder.figures.fig12_test_predictions / fig13_parts_predictions)
# ----------------------------------------------------------------------------------------------
def representative_rows(r2: np.ndarray, quantiles=FIGURE_QUANTILES) -> list[int]:
    """Indices of the rows whose R² sits at the given quantiles (distinct rows when possible)."""
    order = np.argsort(-np.asarray(r2), kind="stable")  # best first
    picks: list[int] = []
    for q in quantiles:
        pos = int(round((1.0 - q) * (order.size - 1)))
        free = [c for c in range(order.size) if int(order[c]) not in picks]
        if free:  # the unused rank closest to the quantile's rank
            picks.append(int(order[min(free, key=lambda c: (abs(c - pos), c))]))
    return picks


def prediction_data(dataset, model_dir) -> dict[str, dict[str, np.ndarray]]:
    """For the Test and Parts splits: the representative rows' true and predicted CDFs, their R²
    and labels, as the arrays feeder.figures._cdf_predictions reads."""
    from feeder.labels.dataset import load_dataset
    from feeder.labels.metrics import r2_cdf
    from feeder.learn.models import TrainedModel

    data = load_dataset(dataset)
    model = TrainedModel.load(model_dir)
    _, cdf = model.predict(data["part_raw"], data["feeder_raw"])
    r2 = r2_cdf(data["cdf"], cdf)
    bins = data["cdf"].shape[1]
    out = {}
    for split, label in (("test", "Test"), ("parts", "Parts")):
        idx = np.flatnonzero(data["split"] == split)
        if idx.size == 0:
            raise FeederError(f"{dataset}: no {split} rows to plot")
        rows = [int(idx[j]) for j in representative_rows(r2[idx])]
        out[split] = {
            "part": np.asarray(data["part"])[rows].astype(str),
            "config_id": np.asarray(data["config_id"])[rows].astype(str),
            "yaw_deg": np.arange(bins) * (360.0 / bins),
            "cdf_true": np.asarray(data["cdf"][rows], dtype=np.float64),
            "cdf_pred": np.asarray(cdf[rows], dtype=np.float64),
            "r2": np.asarray(r2[rows], dtype=np.float64),
            "model": np.array(str(model.spec.name)),
            "split": np.array(label),
        }
    return out


# ----------------------------------------------------------------------------------------------
# Grid-search summary
# ----------------------------------------------------------------------------------------------
def grid_table(grid_dir) -> pd.DataFrame:
    """One row per finished grid point (a directory with metrics.json + config.yaml)."""
    from omegaconf import OmegaConf

    rows = []
    for metrics_path in sorted(Path(grid_dir).glob("*/metrics.json")):
        cfg = OmegaConf.load(metrics_path.parent / "config.yaml")
        m = json.loads(metrics_path.read_text())
        rows.append(
            {
                "run": metrics_path.parent.name,
                "lr": cfg["model"]["lr"],
                "batch_size": cfg["trainer"]["batch_size"],
                "best_val_loss": m["best_val_loss"],
                "best_epoch": m["best_epoch"],
                "r2_train": m.get("r2_train"),
                "train_s": m["train_s"],
            }
        )
    if not rows:
        raise FeederError(f"{grid_dir}: no finished grid runs (*/metrics.json)")
    return pd.DataFrame(rows).sort_values(["best_val_loss", "run"], kind="stable").reset_index(drop=True)


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder evaluate", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)

    p = sub.add_parser("tables", help="Tables 5-8 (+ .md) and the Fences/Parts breakdowns")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--models", type=Path, nargs="+", required=True, help="trained model directories")
    p.add_argument("--out-dir", type=Path, required=True)

    p = sub.add_parser("groupkfold", help="leave-parts-out GroupKFold of one model (trains one per fold)")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="CSV (a .md twin is written beside it)")
    p.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. model=m3 trainer.max_epochs=50")

    p = sub.add_parser("figure-data", help="data of Figs. 12 (Test) and 13 (Parts): four representative CDFs each")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--model", type=Path, required=True)
    p.add_argument("--fig12-data", type=Path, required=True, help="Test rows (.npz)")
    p.add_argument("--fig13-data", type=Path, required=True, help="Parts rows (.npz)")

    p = sub.add_parser("grid", help="collect a grid-search multirun into one CSV")
    p.add_argument("--dir", type=Path, required=True, help="results/models/grid/<model>")
    p.add_argument("--out", type=Path, required=True)

    args = parser.parse_args(argv)
    if args.cmd == "tables":
        for path in write_tables(args.dataset, args.models, args.out_dir):
            print(path)
    elif args.cmd == "groupkfold":
        from feeder.config import compose_config
        from feeder.labels.dataset import load_dataset

        data = load_dataset(args.dataset)
        cfg = compose_config("train", args.overrides)
        df = groupkfold(data, cfg)
        name = str(cfg.model.name)
        _write_table(
            args.out,
            df,
            f"Leave-parts-out GroupKFold of {name} ({np.unique(data['group_fold']).size} folds): "
            "CDF R², W1 in degrees, mean ± SD (ddof=0) per part, over all held-out "
            "configurations, and over the per-part means.",
        )
        summary = df[df.group == "over parts"][["model", "r2_mean", "r2_sd", "w1_mean"]]
        print(summary.to_string(index=False), file=sys.stderr)
    elif args.cmd == "figure-data":
        from feeder.io import write_npz

        data = prediction_data(args.dataset, args.model)
        write_npz(args.fig12_data, **data["test"])
        write_npz(args.fig13_data, **data["parts"])
    elif args.cmd == "grid":
        from feeder.io import write_csv

        write_csv(args.out, grid_table(args.dir))
    return 0
