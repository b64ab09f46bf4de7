"""``feeder evaluate``: the regression models on the 360-bin CDFs (paper §3.5.3, Tables 5–8,
Figs. 12–13) and the leave-parts-out GroupKFold study of one model.

Metrics compare post-processed predicted CDFs with the true CDFs row by row
(``feeder.labels.metrics``): R² over the bins of one configuration, W1 = Σ|ΔF| in degrees and the MSE
(the paper's), and beside them the rotation-invariant pair (``r2c``: R² at the best common cut of
the circle, an oracle envelope since the cut is chosen with the truth; ``cw1``: circular W1, the
W1 minimised over cuts, the headline metric), which do not depend on where 0° falls in the label
frame; a table reports mean ± population SD (ddof = 0) over the configurations
of a split.

Two baselines sit beside the models in every table, and two more when the dataset has the
analytic push block (:func:`baseline_names`):

* ``baseline_mean_pmf``: the mean PMF of the training rows, for every configuration;
* ``baseline_nearest_part``: the PMF of the nearest training configuration in the scaled 53-d
  input space (Euclidean; the scaler is fit on the training rows). A training row is never its
  own neighbour (leave-one-out), so the Train table shows an honest baseline;
* ``baseline_analytic_pmf``: the analytic PMF of the configuration itself (the dataset's
  ``pmf_analytic``: quasi-static pushing of the part's outline, :mod:`feeder.mechanics`, in the
  label frame with the labels' smoothing), no training row read. Only with ``pmf_analytic``;
* ``baseline_analytic_prior``: the analytic PMF widened and blended with the training-mean PMF,
  ``λ · widen(analytic, σ) + (1 − λ) · mean`` (:mod:`feeder.learn.prior`), with (σ, λ) chosen on
  the training rows from the grids of the Hydra config's ``prior`` node. With ``pmf_analytic``
  and those grids (``prior_grids``; the CLI reads them from the training config).

``train_s`` is the training wall time (from the model's ``metrics.json``, the mean over seeds);
for the baselines it is the measured time to build them from the dataset (for the analytic one,
its cumulative sums: the analytic PMFs themselves are computed by ``feeder datasets build``,
which logs their time).

**Seeds.** Every model is trained once per seed (``models.seeds``). A table's metric columns are
the mean over seeds of each seed's statistic over configurations; ``seeds`` counts them and the
``*_seed_sd`` columns give the sample SD (ddof = 1) of the per-seed means across seeds (empty for
one seed and for the baselines, which have no seed).

**Model against baseline** (``model_vs_baselines.csv``): for every model, baseline, split and metric,
the mean per-configuration difference (model minus baseline; each configuration's model score is its
mean over seeds) with a paired percentile bootstrap interval over configurations
(:func:`paired_bootstrap`), and a verdict: ``better`` or ``worse`` only when the interval excludes
zero. GroupKFold does the same over parts (each part's mean over its held-out configurations).

Subcommands::

    feeder evaluate tables --dataset D --models results/models/m1/seed0 ... --out-dir results/tables \
        [--resamples 2000 --level 0.95 --bootstrap-seed 0] [Hydra overrides of the training config]
    feeder evaluate groupkfold --dataset D --out results/tables/groupkfold_m3.csv \
        --paired-out results/tables/groupkfold_m3_paired.csv --seeds 0 1 2 model=m3 [overrides]
    feeder evaluate figure-data --dataset D --model results/models/m3/seed0 --fig12-data F12.npz --fig13-data F13.npz
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
SEED_COLUMNS = ["seeds", "r2_seed_sd", "w1_seed_sd", "r2c_seed_sd", "cw1_seed_sd"]
COLUMNS = ["model", "n", *METRIC_COLUMNS, *SEED_COLUMNS, "train_s"]
BREAKDOWN_COLUMNS = ["model", "group", "n", *METRIC_COLUMNS, *SEED_COLUMNS]
PAIRED_COLUMNS = [
    "split",
    "model",
    "baseline",
    "metric",
    "n",
    "model_mean",
    "baseline_mean",
    "diff_mean",
    "diff_low",
    "diff_high",
    "level",
    "resamples",
    "verdict",
]
# paired comparisons: metric -> +1 when higher is better, -1 when lower is better
PAIRED_METRICS = {"r2": 1, "r2c": 1, "w1": -1, "cw1": -1}
PAIRED_SPLITS = ("test", "fences", "parts")
BASELINE_MEAN = "baseline_mean_pmf"
BASELINE_NEAREST = "baseline_nearest_part"
BASELINE_ANALYTIC = "baseline_analytic_pmf"
BASELINE_PRIOR = "baseline_analytic_prior"
ANALYTIC_KEY = "pmf_analytic"  # the dataset array the analytic baseline reads
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


def seed_summary(per_seed: list[dict[str, np.ndarray]], mask: np.ndarray) -> dict[str, float]:
    """Columns of one table row from per-seed per-configuration metrics: each statistic of
    :func:`summarise` averaged over seeds, the seed count and the sample SD (ddof = 1) of the
    per-seed means across seeds (NaN with one seed)."""
    sums = [summarise({k: v[mask] for k, v in m.items()}) for m in per_seed]
    out: dict[str, float] = {"n": sums[0]["n"], "seeds": len(sums)}
    for col in METRIC_COLUMNS:
        out[col] = float(np.mean([s[col] for s in sums]))
    for k in _SPREAD:
        means = [s[f"{k}_mean"] for s in sums]
        out[f"{k}_seed_sd"] = float(np.std(means, ddof=1)) if len(means) > 1 else np.nan
    return out


def paired_bootstrap(diff: np.ndarray, resamples: int, level: float, seed: int) -> tuple[float, float, float]:
    """Mean of paired differences and its percentile bootstrap interval at ``level``.

    ``diff[i]`` is one unit's difference (a configuration, or a part); units are resampled with
    replacement ``resamples`` times from ``numpy.random.default_rng(seed)``. The interval is the
    ((1 − level)/2, (1 + level)/2) quantile pair of the resampled means (linear interpolation)."""
    diff = np.asarray(diff, dtype=np.float64)
    if diff.ndim != 1 or diff.size == 0:
        raise FeederError("paired_bootstrap needs a non-empty 1-d array of differences")
    if not np.all(np.isfinite(diff)):
        raise FeederError("paired_bootstrap: differences must be finite")
    if int(resamples) < 1:
        raise FeederError(f"paired_bootstrap: resamples {resamples} must be >= 1")
    if not 0.0 < float(level) < 1.0:
        raise FeederError(f"paired_bootstrap: level {level} must lie in (0, 1)")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, diff.size, size=(int(resamples), diff.size))
    means = diff[idx].mean(axis=1)
    tail = (1.0 - float(level)) / 2.0
    lo, hi = np.quantile(means, [tail, 1.0 - tail])
    return float(diff.mean()), float(lo), float(hi)


def verdict(diff_low: float, diff_high: float, sign: int) -> str:
    """``better`` / ``worse`` when the interval of (model − baseline) excludes zero (``sign`` +1:
    higher is better, −1: lower is better), else ``no clear difference``."""
    if diff_low > 0.0 or diff_high < 0.0:
        return "better" if (diff_low > 0.0) == (sign > 0) else "worse"
    return "no clear difference"


def paired_rows(
    split: str,
    model: str,
    model_scores: dict[str, np.ndarray],
    baselines: dict[str, dict[str, np.ndarray]],
    bootstrap: dict,
) -> list[dict]:
    """Rows of the paired comparison of one model (per-unit scores, already averaged over seeds)
    against each baseline (per-unit scores over the same units, in the same order)."""
    rows = []
    for base, base_scores in baselines.items():
        for metric, sign in PAIRED_METRICS.items():
            a = np.asarray(model_scores[metric], dtype=np.float64)
            b = np.asarray(base_scores[metric], dtype=np.float64)
            mean, lo, hi = paired_bootstrap(a - b, bootstrap["resamples"], bootstrap["level"], bootstrap["seed"])
            rows.append(
                {
                    "split": split,
                    "model": model,
                    "baseline": base,
                    "metric": metric,
                    "n": int(a.size),
                    "model_mean": float(a.mean()),
                    "baseline_mean": float(b.mean()),
                    "diff_mean": mean,
                    "diff_low": lo,
                    "diff_high": hi,
                    "level": float(bootstrap["level"]),
                    "resamples": int(bootstrap["resamples"]),
                    "verdict": verdict(lo, hi, sign),
                }
            )
    return rows


def seed_mean(per_seed: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Per-configuration metrics averaged over seeds."""
    return {k: np.mean([m[k] for m in per_seed], axis=0) for k in per_seed[0]}


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


def baseline_names(data: dict, prior_grids=None) -> list[str]:
    """The baselines a dataset supports, in table order: the mean PMF, the nearest configuration,
    and when the dataset has ``pmf_analytic`` the analytic PMF and (given ``prior_grids``,
    :class:`feeder.learn.prior.Grids`) the analytic prior."""
    names = [BASELINE_MEAN, BASELINE_NEAREST]
    if ANALYTIC_KEY in data:
        names += [BASELINE_ANALYTIC] + ([BASELINE_PRIOR] if prior_grids is not None else [])
    return names


def baseline_predictions(data: dict, train_mask: np.ndarray, prior_grids=None) -> dict[str, tuple[np.ndarray, float]]:
    """CDF predictions of every baseline of :func:`baseline_names` for every row, with the
    seconds each took to build (the prior's include fitting its (σ, λ) on the training rows)."""
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
    out = {BASELINE_MEAN: (mean_cdf, t_mean), BASELINE_NEAREST: (near_cdf, t_near)}
    if ANALYTIC_KEY in data:
        t0 = time.perf_counter()
        analytic_cdf = np.cumsum(np.asarray(data[ANALYTIC_KEY], dtype=np.float64), axis=1)
        out[BASELINE_ANALYTIC] = (analytic_cdf, time.perf_counter() - t0)
        if prior_grids is not None:
            from feeder.learn.prior import blend, fit_blend

            t0 = time.perf_counter()
            analytic = np.asarray(data[ANALYTIC_KEY], dtype=np.float64)
            best = fit_blend(data["pmf"], analytic, train_mask, prior_grids.sigmas_bins, prior_grids.weights)
            prior = blend(analytic, mean_pmf, best.sigma_bins, best.weight)
            out[BASELINE_PRIOR] = (np.cumsum(prior, axis=1), time.perf_counter() - t0)
    return out


def combo_label(config_id: str) -> str:
    """Fence-type combination of a configuration id: ``curved-1 + straight-2``, ``curved-2 only``."""
    from feeder.lane.fences import parse_config_id

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


def load_models(model_dirs) -> list[tuple[str, int, object, float]]:
    """(name, seed, TrainedModel, train_s) of every model directory (one per model and seed)."""
    from feeder.learn.models import TrainedModel

    out = []
    seen: set[tuple[str, int]] = set()
    for d in model_dirs:
        d = Path(d)
        metrics_path = d / "metrics.json"
        if not metrics_path.is_file():
            raise FeederError(f"{metrics_path}: missing (train the model first)")
        metrics = json.loads(metrics_path.read_text())
        key = (str(metrics.get("model", d.name)), int(metrics.get("seed", 0)))
        if key in seen:
            raise FeederError(f"{d}: model {key[0]} with seed {key[1]} is given twice")
        seen.add(key)
        out.append((*key, TrainedModel.load(d), float(metrics["train_s"])))
    return out


def _per_seed_predictions(data: dict, models, prior_grids=None) -> dict[str, list[tuple[np.ndarray, float]]]:
    """name -> [(predicted CDFs, train_s) per seed, in seed order] for the models, then the
    baselines (one entry each: they have no seed)."""
    train_mask = data["split"] == "train"
    preds: dict[str, list[tuple[int, np.ndarray, float]]] = {}
    for name, seed, model, train_s in models:
        _, cdf = model.predict_rows(data)
        preds.setdefault(name, []).append((seed, cdf, train_s))
    out = {name: [(cdf, s) for _, cdf, s in sorted(runs, key=lambda r: r[0])] for name, runs in preds.items()}
    for name, (cdf, secs) in baseline_predictions(data, train_mask, prior_grids).items():
        out[name] = [(cdf, secs)]
    return out


def evaluation_tables(data: dict, models, bootstrap: dict | None = None, prior_grids=None):
    """Tables 5–8 (split -> DataFrame), the Fences/Parts breakdowns and the paired comparison of
    every model with every baseline (:func:`baseline_names`; None when ``bootstrap`` is None)."""
    preds = _per_seed_predictions(data, models, prior_grids)
    per_row = {name: [row_metrics(data["cdf"], cdf) for cdf, _ in runs] for name, runs in preds.items()}
    train_s = {name: float(np.mean([s for _, s in runs])) for name, runs in preds.items()}

    tables = {}
    for split in TABLES:
        mask = data["split"] == split
        rows = [{"model": name, **seed_summary(per_row[name], mask), "train_s": train_s[name]} for name in preds]
        tables[split] = pd.DataFrame(rows, columns=COLUMNS)

    def breakdown(split: str, groups: np.ndarray) -> pd.DataFrame:
        mask = data["split"] == split
        rows = []
        for name in preds:
            for g in sorted(set(groups[mask])):
                rows.append({"model": name, "group": g, **seed_summary(per_row[name], mask & (groups == g))})
        return pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS)

    combos = np.array([combo_label(c) for c in data["config_id"]])
    breakdowns = {"fences": breakdown("fences", combos), "parts": breakdown("parts", data["part"])}
    if bootstrap is None:
        return tables, breakdowns, None
    baselines = baseline_names(data, prior_grids)
    paired = []
    for split in PAIRED_SPLITS:
        mask = data["split"] == split
        if not mask.any():
            continue
        base_scores = {b: {k: v[mask] for k, v in per_row[b][0].items()} for b in baselines}
        for name in preds:
            if name in baselines:
                continue
            scores = {k: v[mask] for k, v in seed_mean(per_row[name]).items()}
            paired += paired_rows(split, name, scores, base_scores, bootstrap)
    return tables, breakdowns, pd.DataFrame(paired, columns=PAIRED_COLUMNS)


def fence_types(config_id: str) -> str:
    """The fence-type combination of a configuration id, e.g. ``straight+none`` (angles dropped)."""
    from feeder.lane.fences import parse_config_id

    loc1, loc2 = parse_config_id(config_id)
    return f"{loc1.type}+{loc2.type}"


def rows_with_a_neighbour(data: dict, split: str, of: str = "train") -> tuple[int, int]:
    """(rows of ``split`` that have a row of ``of`` with the same part and fence-type combination,
    rows of ``split``): how far "known parts at new fence angles" holds on the grid (pure)."""
    keys = [(p, fence_types(c)) for p, c in zip(data["part"], data["config_id"], strict=True)]
    split_of = np.asarray(data["split"])
    known = {k for k, s in zip(keys, split_of, strict=True) if s == of}
    mine = [k for k, s in zip(keys, split_of, strict=True) if s == split]
    return sum(k in known for k in mine), len(mine)


def _split_note(data: dict, split: str) -> str:
    """What the grid makes of the Test split, for its caption ('' for the other splits)."""
    if split != "test":
        return ""
    near, n = rows_with_a_neighbour(data, split)
    return f"; {near} of {n} Test rows have a training row of the same part and fence-type combination"


def write_tables(dataset, model_dirs, out_dir, bootstrap: dict | None = None, prior_grids=None) -> list[Path]:
    from feeder.labels.dataset import load_dataset

    data = load_dataset(dataset)
    models = load_models(model_dirs)
    tables, breakdowns, paired = evaluation_tables(data, models, bootstrap, prior_grids)
    seeds = sorted({seed for _, seed, _, _ in models})
    seed_note = f"{len(seeds)} training seed{'s' if len(seeds) > 1 else ''} ({', '.join(map(str, seeds))})"
    out_dir = Path(out_dir)
    written = []
    for split, (number, caption) in TABLES.items():
        n = int((data["split"] == split).sum())
        path = out_dir / f"table{number}.csv"
        _write_table(
            path,
            tables[split],
            f"Table {number}. {caption}{_split_note(data, split)}; mean ± SD (ddof=0) over N = {n} "
            "configurations, averaged over "
            f"{seed_note}; *_seed_sd: SD (ddof=1) of the mean across seeds.",
        )
        written.append(path)
    captions = {"fences": "Fences split by fence-type combination", "parts": "Parts split by part"}
    for split, df in breakdowns.items():
        path = out_dir / f"breakdown_{split}.csv"
        _write_table(path, df, f"{captions[split]} (CDF R², W1 in degrees; mean ± SD ddof=0; {seed_note}).")
        written.append(path)
    if paired is not None:
        path = out_dir / "model_vs_baselines.csv"
        _write_table(
            path,
            paired,
            "Each model against each baseline, paired over the configurations of a split: mean difference "
            f"(model − baseline; model scores averaged over {seed_note}) with a "
            f"{bootstrap['level']:.0%} percentile bootstrap interval ({bootstrap['resamples']} resamples); "
            "better/worse only when the interval excludes 0.",
        )
        written.append(path)
    return written


# ----------------------------------------------------------------------------------------------
# Leave-parts-out GroupKFold
# ----------------------------------------------------------------------------------------------
def _part_means(m: dict[str, np.ndarray], parts: np.ndarray, names: list[str]) -> dict[str, np.ndarray]:
    """Per-part means of per-configuration metrics (parts in the order of ``names``)."""
    return {k: np.array([v[parts == p].mean() for p in names]) for k, v in m.items()}


def _prior_grids(cfg):
    """The grids of the composed training config's ``prior`` node (None when it has none)."""
    from feeder.learn.prior import grids

    return grids(cfg["prior"]) if "prior" in cfg else None


def groupkfold(data: dict, cfg, seeds=None, progress: bool | None = None, bootstrap: dict | None = None):
    """Train ``cfg.model`` once per ``group_fold`` and seed on every row of the other folds and
    predict the held-out parts. Rows: per part, all held-out configurations, and the mean ± SD of
    the per-part means ("over parts"), for the model (averaged over ``seeds``, default
    ``[cfg.seed]``, with the spread across seeds) and every baseline of :func:`baseline_names`
    (built per fold).

    Returns the table, and with ``bootstrap`` also the paired comparison over parts (else None)."""
    from feeder.learn.train import fit

    folds = np.unique(data["group_fold"])
    if folds.size < 2:
        raise FeederError("GroupKFold needs at least 2 folds in group_fold")
    seeds = [int(cfg.seed)] if seeds is None else [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise FeederError(f"GroupKFold seeds {seeds}: give at least one, without repeats")
    n_rows, bins = data["cdf"].shape
    name = str(cfg.model.name)
    prior_grids = _prior_grids(cfg)
    baselines = baseline_names(data, prior_grids)
    runs = {
        name: [np.full((n_rows, bins), np.nan) for _ in seeds],
        **{b: [np.full((n_rows, bins), np.nan)] for b in baselines},
    }
    secs = dict.fromkeys(runs, 0.0)
    for fold in folds:
        test = data["group_fold"] == fold
        train = ~test
        for i, seed in enumerate(seeds):
            fitted = fit(cfg, data, train, seed=seed + int(fold), progress=progress)
            _, runs[name][i][test] = fitted.model.predict_rows(data, test)
            secs[name] += fitted.train_s / len(seeds)
        for b, (cdf, s) in baseline_predictions(data, train, prior_grids).items():
            runs[b][0][test] = cdf[test]
            secs[b] += s
    per_row = {k: [row_metrics(data["cdf"], cdf) for cdf in v] for k, v in runs.items()}
    parts = np.asarray(data["part"])
    part_names = sorted(set(parts))
    rows = []
    for model_name, per_seed in per_row.items():
        everything = np.ones(n_rows, dtype=bool)
        for part in part_names:
            rows.append(
                {"model": model_name, "group": part, **seed_summary(per_seed, parts == part), "train_s": np.nan}
            )
        rows.append(
            {
                "model": model_name,
                "group": "all configurations",
                **seed_summary(per_seed, everything),
                "train_s": secs[model_name],
            }
        )
        part_level = [_part_means(m, parts, part_names) for m in per_seed]
        over = {
            "model": model_name,
            "group": "over parts",
            **seed_summary(part_level, np.ones(len(part_names), dtype=bool)),
        }
        rows.append({**over, "train_s": secs[model_name]})
    table = pd.DataFrame(rows, columns=BREAKDOWN_COLUMNS + ["train_s"])
    if bootstrap is None:
        return table, None
    model_parts = seed_mean([_part_means(m, parts, part_names) for m in per_row[name]])
    base_parts = {b: _part_means(per_row[b][0], parts, part_names) for b in baselines}
    paired = pd.DataFrame(
        paired_rows("groupkfold over parts", name, model_parts, base_parts, bootstrap), columns=PAIRED_COLUMNS
    )
    return table, paired


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
    _, cdf = model.predict_rows(data)
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
# ----------------------------------------------------------------------------------------------
# Generalisation: every predictor on unseen parts, side by side (issue #20)
# ----------------------------------------------------------------------------------------------
OVER_PARTS = "over parts"  # the GroupKFold table's row of per-part means
GENERALISATION_METRICS = (("r2", 1), ("r2c", 1), ("cw1", -1))  # (metric, +1 higher is better / -1 lower)


def _read_table(path: Path, what: str, columns: list[str]) -> pd.DataFrame:
    """A CSV table with ``columns``; a missing, unreadable or incomplete file is a one-line FeederError."""
    if not Path(path).is_file():
        raise FeederError(f"{what} {path} is missing")
    try:
        df = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise FeederError(f"{what} {path} is not a readable CSV ({err})".replace("\n", " ")) from None
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise FeederError(f"{what} {path} lacks the column(s) {', '.join(missing)}")
    return df


def generalisation_table(groupkfold: list[pd.DataFrame], parts: pd.DataFrame, bootstrap: dict) -> pd.DataFrame:
    """One row per predictor on unseen parts, from the leave-parts-out GroupKFold tables of one or
    more models (the same dataset and folds, so their baseline rows agree) and the Parts split's
    table (Table 8).

    Per predictor: its GroupKFold mean over parts and SD across parts of each metric of
    :data:`GENERALISATION_METRICS` (the paper's CDF R², the R² at the best common cut, the circular
    W1), the SD across training seeds (models), the difference to the mean-PMF baseline paired
    over parts with its percentile bootstrap interval, and the Parts split's means. A predictor
    missing from Table 8 has NaN there."""
    per_part: dict[str, pd.DataFrame] = {}
    summary: dict[str, pd.Series] = {}
    for table in groupkfold:
        for name, rows in table.groupby("model", sort=False):
            over = rows[rows["group"] == OVER_PARTS]
            parts_rows = rows[~rows["group"].isin([OVER_PARTS, "all configurations"])]
            if len(over) != 1 or parts_rows.empty:
                raise FeederError(f"GroupKFold table: {name} lacks its '{OVER_PARTS}' row or its per-part rows")
            if name in per_part:
                continue  # a baseline repeated by a second model's table
            per_part[name] = parts_rows.set_index("group")
            summary[name] = over.iloc[0]
    if BASELINE_MEAN not in per_part:
        raise FeederError(f"GroupKFold tables lack the {BASELINE_MEAN} rows")
    mean_parts = per_part[BASELINE_MEAN]
    parts_split = parts.set_index("model")
    rows = []
    for name, over in summary.items():
        row = {"predictor": name, "parts": int(over["n"])}
        for metric, sign in GENERALISATION_METRICS:
            row[f"groupkfold_{metric}_mean"] = float(over[f"{metric}_mean"])
            row[f"groupkfold_{metric}_sd_parts"] = float(np.std(per_part[name][f"{metric}_mean"], ddof=0))
            seed_sd = over.get(f"{metric}_seed_sd")
            row[f"groupkfold_{metric}_sd_seeds"] = float(seed_sd) if pd.notna(seed_sd) else np.nan
            common = per_part[name].index.intersection(mean_parts.index)
            if len(common) != len(per_part[name]):
                raise FeederError(f"GroupKFold tables: {name} and {BASELINE_MEAN} cover different parts")
            diff = per_part[name].loc[common, f"{metric}_mean"] - mean_parts.loc[common, f"{metric}_mean"]
            mean, low, high = paired_bootstrap(diff.to_numpy(), **bootstrap)
            row[f"{metric}_vs_mean_pmf"], row[f"{metric}_vs_mean_pmf_low"] = mean, low
            row[f"{metric}_vs_mean_pmf_high"] = high
            row[f"{metric}_verdict"] = "" if name == BASELINE_MEAN else verdict(low, high, sign)
            row[f"parts_split_{metric}_mean"] = (
                float(parts_split.loc[name, f"{metric}_mean"]) if name in parts_split.index else np.nan
            )
        rows.append(row)
    return pd.DataFrame(rows)


def _bootstrap_options(p: argparse.ArgumentParser) -> None:
    """The paired bootstrap's settings (models.bootstrap in the study config)."""
    p.add_argument("--resamples", type=int, default=2000, help="bootstrap resamples (default 2000)")
    p.add_argument("--level", type=float, default=0.95, help="interval level in (0, 1) (default 0.95)")
    p.add_argument("--bootstrap-seed", type=int, default=0, help="seed of the resampling (default 0)")


def _bootstrap_settings(args) -> dict:
    if args.resamples < 1:
        raise FeederError(f"--resamples {args.resamples}: must be >= 1")
    if not 0.0 < args.level < 1.0:
        raise FeederError(f"--level {args.level}: must lie in (0, 1)")
    return {"resamples": args.resamples, "level": args.level, "seed": args.bootstrap_seed}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="feeder evaluate", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)

    p = sub.add_parser("tables", help="Tables 5-8 (+ .md), the Fences/Parts breakdowns and model_vs_baselines.csv")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument(
        "--models", type=Path, nargs="+", required=True, help="trained model directories (one per model and seed)"
    )
    p.add_argument("--out-dir", type=Path, required=True)
    _bootstrap_options(p)
    p.add_argument("overrides", nargs="*", help="Hydra overrides of the training config (its prior node)")

    p = sub.add_parser("groupkfold", help="leave-parts-out GroupKFold of one model (trains one per fold and seed)")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="CSV (a .md twin is written beside it)")
    p.add_argument("--paired-out", type=Path, help="CSV of the model against each baseline, paired over parts")
    p.add_argument("--seeds", type=int, nargs="+", help="training seeds (default: the Hydra config's seed)")
    _bootstrap_options(p)
    p.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. model=m3 trainer.max_epochs=50")

    p = sub.add_parser(
        "generalisation", help="every predictor on unseen parts: GroupKFold tables and Table 8 side by side"
    )
    p.add_argument("--groupkfold", type=Path, nargs="+", required=True, help="groupkfold_<model>.csv of each model")
    p.add_argument("--parts-table", type=Path, required=True, help="Table 8 (the Parts split), table8.csv")
    p.add_argument("--out", type=Path, required=True, help="CSV (a .md twin is written beside it)")
    _bootstrap_options(p)

    p = sub.add_parser("figure-data", help="data of Figs. 12 (Test) and 13 (Parts): four representative CDFs each")
    p.add_argument("--dataset", type=Path, required=True)
    p.add_argument("--model", type=Path, required=True)
    p.add_argument("--fig12-data", type=Path, required=True, help="Test rows (.npz)")
    p.add_argument("--fig13-data", type=Path, required=True, help="Parts rows (.npz)")

    p = sub.add_parser("grid", help="collect a grid-search multirun into one CSV")
    p.add_argument("--dir", type=Path, required=True, help="results/models/grid/<model>")
    p.add_argument("--out", type=Path, required=True)

    return parser


def _groupkfold_tables(args) -> None:
    """``feeder evaluate groupkfold``: the GroupKFold table of one model (and its paired table)."""
    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset

    data = load_dataset(args.dataset)
    cfg = compose_config("train", args.overrides)
    bootstrap = _bootstrap_settings(args) if args.paired_out else None
    df, paired = groupkfold(data, cfg, seeds=args.seeds, bootstrap=bootstrap)
    name = str(cfg.model.name)
    seeds = args.seeds or [int(cfg.seed)]
    _write_table(
        args.out,
        df,
        f"Leave-parts-out GroupKFold of {name} ({np.unique(data['group_fold']).size} folds, "
        f"{len(seeds)} training seed{'s' if len(seeds) > 1 else ''}): "
        "CDF R², W1 in degrees, mean ± SD (ddof=0) per part, over all held-out "
        "configurations, and over the per-part means; averaged over seeds, *_seed_sd across them.",
    )
    if paired is not None:
        _write_table(
            args.paired_out,
            paired,
            f"{name} against each baseline on unseen parts (GroupKFold), paired over parts: mean "
            f"difference of per-part means with a {bootstrap['level']:.0%} percentile bootstrap "
            f"interval ({bootstrap['resamples']} resamples); better/worse only when it excludes 0.",
        )
    summary = df[df.group == "over parts"][["model", "r2_mean", "r2_sd", "w1_mean"]]
    print(summary.to_string(index=False), file=sys.stderr)


def _generalisation_table(args) -> None:
    """``feeder evaluate generalisation``: every predictor on unseen parts, side by side."""
    metrics = [f"{m}_mean" for m, _ in GENERALISATION_METRICS]
    tables = [_read_table(path, "GroupKFold table", ["model", "group", "n", *metrics]) for path in args.groupkfold]
    bootstrap = _bootstrap_settings(args)
    df = generalisation_table(tables, _read_table(args.parts_table, "Table 8", ["model", *metrics]), bootstrap)
    _write_table(
        args.out,
        df,
        "Every predictor on unseen parts: leave-parts-out GroupKFold (mean over parts, SD across parts "
        "and across training seeds) and the Parts split (Table 8); the difference to the mean-PMF "
        f"baseline paired over parts with a {bootstrap['level']:.0%} percentile bootstrap interval "
        f"({bootstrap['resamples']} resamples). r2: the paper's CDF R²; r2c: at the best common cut, "
        "an oracle envelope (the cut is chosen with the truth); cw1: circular W1 (degrees, lower is "
        "better), the headline metric.",
    )
    print(
        df[["predictor", "groupkfold_r2_mean", "groupkfold_r2c_mean", "groupkfold_cw1_mean"]].to_string(),
        file=sys.stderr,
    )


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.cmd == "tables":
        from feeder.config import compose_config, pull_overrides

        args.models, args.overrides = pull_overrides(args.models, args.overrides)  # --models takes every word
        if not args.models:
            raise FeederError("--models needs a trained model directory (it got only Hydra overrides)")
        prior_grids = _prior_grids(compose_config("train", args.overrides))
        for path in write_tables(args.dataset, args.models, args.out_dir, _bootstrap_settings(args), prior_grids):
            print(path)
    elif args.cmd == "groupkfold":
        _groupkfold_tables(args)
    elif args.cmd == "generalisation":
        _generalisation_table(args)
    elif args.cmd == "figure-data":
        from feeder.io import write_npz

        data = prediction_data(args.dataset, args.model)
        write_npz(args.fig12_data, **data["test"])
        write_npz(args.fig13_data, **data["parts"])
    elif args.cmd == "grid":
        from feeder.io import write_csv

        write_csv(args.out, grid_table(args.dir))
    return 0
