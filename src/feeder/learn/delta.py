"""Delta-to-full correction model, protocol P4 (paper §3.5.1, §4.7.3, Table 10, Supplementary S11).

Given the PMF after the first k % of drops, predict the correction ΔPMF such that
``PMF_k + ΔPMF`` approximates the 100 % PMF.

Inputs (one row per configuration, built by :func:`delta_inputs`)
    * the 53 scaled part+feeder values (``feeder.labels.dataset`` scaler fitted on the fold's training rows);
    * the PMFs at k, k-5 and k-10 (``checkpoint_offsets``), multiplied by the bin count so a uniform
      PMF is 1 in every bin; a checkpoint at or below 0 % is all zeros (zero padding);
    * their differences (PMF_k - PMF_{k-5}, PMF_{k-5} - PMF_{k-10}), same scale;
    * stability features: for each consecutive checkpoint pair a presence flag, the JS divergence
      (bits), half the L1 distance (total variation) and W1 / 360°; for each checkpoint its entropy
      divided by log2(bins) and its peak bin mass (all 0 for a padded checkpoint).

Output head: valid by construction
    The network gives 360 logits ``z`` and one gate logit ``g``. With ``w = sigmoid(g)`` in (0, 1)
    the corrected PMF is the convex mixture ``q = (1 - w) · PMF_k + w · softmax(z)`` and the
    correction is ``ΔPMF = q - PMF_k = w · (softmax(z) - PMF_k)``. A convex combination of two PMFs
    is non-negative and sums to 1, so ``PMF_k + ΔPMF`` is a valid PMF for any weights; ``w -> 0``
    is the baseline "the partial PMF is the answer". ``log q`` is formed with log-sum-exp from
    ``log_softmax(z)`` and ``log max(PMF_k, floor)`` so the KL term stays finite on sparse PMFs.
    The loss is a ``feeder.learn.losses`` composite (``loss:`` weights) against the 100 % PMF/CDF.

Evaluation
    One model per (level, split mode, fold). Split modes: ``part`` = the dataset's leave-parts-out
    ``group_fold`` (unseen parts), ``config`` = seeded KFold over configurations (parts seen in
    training). Every row is a test row exactly once per mode; R² per configuration on the
    360-bin CDF against the 100 % CDF, mean and population SD over all rows; the baseline scores
    the partial CDF itself.

CLI: ``feeder delta sweep --level K --out level.json [overrides]`` and
``feeder delta table --table table10.csv --figure s11.png level.json...``.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from feeder import io
from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels.dataset import DATASET_KEYS, LEVEL_KEYS, load_dataset
from feeder.labels.metrics import cdf as cdf_of
from feeder.labels.metrics import js_divergence, r2_cdf, w1
from feeder.learn.data import level_index, scaled_features, split_mask
from feeder.learn.vae import _read_json, config_digest, seeded_run, summarize

MODES = ("part", "config")
LOG_FLOOR = 1e-12
TABLE10_COLUMNS = [
    "level_pct",
    "cost_saved_pct",
    "part_r2_mean",
    "part_r2_sd",
    "part_baseline_mean",
    "part_baseline_sd",
    "config_r2_mean",
    "config_r2_sd",
    "config_baseline_mean",
    "config_baseline_sd",
]


# ----------------------------------------------------------------------------------------------
# Inputs (pure numpy)
# ----------------------------------------------------------------------------------------------
def checkpoints(
    pmf_levels: np.ndarray, levels_pct: Sequence[int], level: int, offsets: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """PMFs at ``level`` and ``level - offset`` for each offset: ``(N, 1 + len(offsets), bins)``
    and a presence flag per checkpoint. Checkpoints at or below 0 % are zero rows (absent); a
    positive checkpoint missing from ``levels_pct`` is an error."""
    levels = np.asarray(levels_pct)
    wanted = [int(level)] + [int(level) - int(o) for o in offsets]
    n, _, bins = pmf_levels.shape
    out = np.zeros((n, len(wanted), bins))
    present = np.zeros(len(wanted), dtype=bool)
    for j, k in enumerate(wanted):
        if k <= 0 and j > 0:
            continue
        out[:, j] = pmf_levels[:, level_index(levels, k)]
        present[j] = True
    return out, present


def entropy_bits(pmf: np.ndarray) -> np.ndarray:
    """Shannon entropy in bits along the last axis (0 log 0 = 0)."""
    p = np.asarray(pmf, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    return terms.sum(axis=-1)


def stability_features(ckpts: np.ndarray, present: np.ndarray) -> np.ndarray:
    """(N, 4 · pairs + 2 · checkpoints): per consecutive pair [present, JS, L1 / 2, W1 / 360°],
    per checkpoint [entropy / log2(bins), peak mass]; zeros where a checkpoint is absent."""
    n, c, bins = ckpts.shape
    cols = []
    for j in range(c - 1):
        a, b = ckpts[:, j], ckpts[:, j + 1]
        ok = bool(present[j] and present[j + 1])
        if ok:
            cols += [
                np.ones(n),
                js_divergence(a, b),
                0.5 * np.abs(a - b).sum(axis=-1),
                w1(cdf_of(a), cdf_of(b)) / 360.0,
            ]
        else:
            cols += [np.zeros(n)] * 4
    for j in range(c):
        if present[j]:
            cols += [entropy_bits(ckpts[:, j]) / np.log2(bins), ckpts[:, j].max(axis=-1)]
        else:
            cols += [np.zeros(n)] * 2
    return np.stack(cols, axis=1)


def delta_inputs(features: np.ndarray, ckpts: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Model input rows: features, bin-scaled checkpoint PMFs, their differences, stability."""
    bins = ckpts.shape[-1]
    diffs = ckpts[:, :-1] - ckpts[:, 1:]
    n = ckpts.shape[0]
    return np.concatenate(
        [features, bins * ckpts.reshape(n, -1), bins * diffs.reshape(n, -1), stability_features(ckpts, present)], axis=1
    )


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------
def build_delta(mcfg, n_in: int, bins: int):
    """MLP (Linear, ReLU, Dropout per hidden layer) -> ``bins`` logits + 1 gate logit."""
    import torch
    from torch import nn

    layers, width = [], n_in
    for h in mcfg.hidden:
        layers += [nn.Linear(width, int(h)), nn.ReLU(), nn.Dropout(float(mcfg.dropout))]
        width = int(h)
    head = nn.Linear(width, bins + 1)
    with torch.no_grad():
        head.bias[-1] = float(mcfg.gate_bias)
    return nn.Sequential(*layers, head)


def corrected_pmf(out, pmf_k):
    """Convex-mixture head: returns (q, log q, w) with q = (1 - w) pmf_k + w softmax(z)."""
    import torch
    from torch.nn import functional as F

    logits, gate = out[:, :-1], out[:, -1:]
    log_soft = F.log_softmax(logits, dim=-1)
    log_w, log_1mw = F.logsigmoid(gate), F.logsigmoid(-gate)
    log_q = torch.logaddexp(log_1mw + torch.log(torch.clamp(pmf_k, min=LOG_FLOOR)), log_w + log_soft)
    w = torch.exp(log_w)
    q = (1.0 - w) * pmf_k + w * torch.exp(log_soft)
    return q, log_q, w.squeeze(-1)


@dataclass
class DeltaFit:
    net: Any
    best_epoch: int
    epochs_run: int
    wall_s: float
    history: list[dict[str, float]] = field(default_factory=list)


def fit_delta(cfg, x: np.ndarray, pmf_k: np.ndarray, pmf_full: np.ndarray, seed: int) -> DeltaFit:
    """Train one delta model on input rows ``x`` towards ``pmf_full`` from ``pmf_k``."""
    import torch

    from feeder.learn import losses

    weights = {str(k): float(v) for k, v in cfg.loss.items()}
    try:
        losses.check_terms(weights, has_log_pmf=True)
    except ValueError as err:
        raise FeederError(f"config/hydra/delta.yaml loss: {err}") from None
    tcfg = cfg.train
    tr, va, gen = seeded_run(tcfg, x.shape[0], seed)
    net = build_delta(cfg.model, x.shape[1], pmf_k.shape[1])
    f32 = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    X, P, T = f32(x), f32(pmf_k), f32(pmf_full)
    C = torch.cumsum(T, dim=-1)
    opt = torch.optim.Adam(net.parameters(), lr=float(tcfg.lr), weight_decay=float(tcfg.weight_decay))
    batch, patience, max_epochs = int(tcfg.batch_size), int(tcfg.patience), int(tcfg.max_epochs)
    if batch < 1 or patience < 1 or max_epochs < 1:
        raise FeederError("delta train.batch_size, patience and max_epochs must be >= 1")

    def loss_of(idx):
        q, log_q, _ = corrected_pmf(net(X[idx]), P[idx])
        return losses.composite(weights, q, log_q, torch.cumsum(q, dim=-1), T[idx], C[idx])

    tr_t, va_t = torch.as_tensor(tr), torch.as_tensor(va)
    best, best_epoch, best_state, history = float("inf"), -1, None, []
    start = time.perf_counter()
    for epoch in range(max_epochs):
        net.train()
        order = tr_t[torch.randperm(len(tr), generator=gen)]
        total = 0.0
        for i in range(0, len(tr), batch):
            idx = order[i : i + batch]
            loss, _ = loss_of(idx)
            if not torch.isfinite(loss):
                raise FeederError(f"delta model diverged: non-finite loss at epoch {epoch}")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), float(tcfg.grad_clip))
            opt.step()
            total += float(loss.detach()) * len(idx)
        net.eval()
        with torch.no_grad():
            val = float(loss_of(va_t)[0])
        if not np.isfinite(val):
            raise FeederError(f"delta model diverged: non-finite validation loss at epoch {epoch}")
        history.append({"epoch": epoch, "train_loss": total / len(tr), "val_loss": val})
        if val < best:
            best, best_epoch, best_state = val, epoch, copy.deepcopy(net.state_dict())
        elif epoch - best_epoch >= patience:
            break
    net.load_state_dict(best_state)
    net.eval()
    return DeltaFit(net, best_epoch, len(history), time.perf_counter() - start, history)


def predict_pmf(net, x: np.ndarray, pmf_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corrected PMFs (float64, renormalised against float32 round-off) and mixing weights."""
    import torch

    with torch.no_grad():
        q, _, w = corrected_pmf(
            net(torch.as_tensor(x, dtype=torch.float32)), torch.as_tensor(pmf_k, dtype=torch.float32)
        )
    q = q.double().numpy()
    return q / q.sum(axis=-1, keepdims=True), w.double().numpy()


# ----------------------------------------------------------------------------------------------
# Sweep
# ----------------------------------------------------------------------------------------------
def derive_seed(base: int, *keys: Any) -> int:
    digest = hashlib.sha256(":".join(map(str, (base, *keys))).encode()).digest()
    return int.from_bytes(digest[:4], "little")


def folds(data: dict[str, np.ndarray], rows: np.ndarray, mode: str, cfg) -> np.ndarray:
    """Fold label of each of ``rows`` for a split mode."""
    if mode == "part":
        labels = np.asarray(data["group_fold"])[rows].astype(int)
    elif mode == "config":
        n_folds = int(cfg.random_folds)
        if n_folds < 2 or n_folds > rows.size:
            raise FeederError(f"random_folds must be in 2..{rows.size}, got {n_folds}")
        perm = np.random.default_rng(derive_seed(int(cfg.seed), "config-folds")).permutation(rows.size)
        labels = np.empty(rows.size, dtype=int)
        labels[perm] = np.arange(rows.size) % n_folds
    else:
        raise FeederError(f"unknown split mode {mode!r}")
    if np.unique(labels).size < 2:
        raise FeederError(f"split mode {mode!r}: need at least 2 folds, got {np.unique(labels).size}")
    return labels


def sweep_level(cfg, level: int) -> dict[str, Any]:
    """Train and score the delta model at one level under both split modes."""
    data = load_dataset(cfg.dataset, DATASET_KEYS + LEVEL_KEYS)
    rows = np.flatnonzero(split_mask(data, cfg.splits, "splits"))
    if rows.size < 4:
        raise FeederError(f"{cfg.dataset}: the delta sweep needs at least 4 rows in {list(cfg.splits)}")
    ckpts, present = checkpoints(data["pmf_levels"], data["levels_pct"], level, cfg.checkpoint_offsets)
    pmf_k, pmf_full, cdf_full = ckpts[:, 0], data["pmf"], data["cdf"]
    baseline = r2_cdf(cdf_full, cdf_of(pmf_k))
    result: dict[str, Any] = {
        "level_pct": int(level),
        "cost_saved_pct": 100.0 - float(level),
        "n_rows": int(rows.size),
        "checkpoints_present": present.tolist(),
        "config_digest": config_digest(cfg),
        "train_wall_s": 0.0,
        "modes": {},
    }
    for mode in MODES:
        fold_of = folds(data, rows, mode, cfg)
        r2 = np.full(rows.size, np.nan)
        gates = np.full(rows.size, np.nan)
        fold_info = []
        for f in np.unique(fold_of):
            test, train = rows[fold_of == f], rows[fold_of != f]
            if train.size < 2:
                raise FeederError(f"split mode {mode!r} fold {f}: fewer than 2 training rows")
            fit_mask = np.zeros(len(data["split"]), dtype=bool)
            fit_mask[train] = True
            x = delta_inputs(scaled_features(data, fit_mask), ckpts, present)
            fit = fit_delta(cfg, x[train], pmf_k[train], pmf_full[train], derive_seed(int(cfg.seed), level, mode, f))
            q, w = predict_pmf(fit.net, x[test], pmf_k[test])
            r2[fold_of == f] = r2_cdf(cdf_full[test], cdf_of(q))
            gates[fold_of == f] = w
            fold_info.append(
                {
                    "fold": int(f),
                    "n_train": int(train.size),
                    "n_test": int(test.size),
                    "best_epoch": fit.best_epoch,
                    "epochs_run": fit.epochs_run,
                    "wall_s": fit.wall_s,
                }
            )
            result["train_wall_s"] += fit.wall_s
        if not np.isfinite(r2).all():
            raise FeederError(f"delta level {level} mode {mode}: non-finite R²")
        base = baseline[rows]
        m, s = summarize(r2)
        bm, bs = summarize(base)
        result["modes"][mode] = {
            "r2_mean": m,
            "r2_sd": s,
            "baseline_mean": bm,
            "baseline_sd": bs,
            "gate_mean": float(gates.mean()),
            "folds": fold_info,
            "per_row": {"r2": r2.tolist(), "baseline": base.tolist()},
        }
    result["rows"] = {"part": data["part"][rows].tolist(), "config_id": data["config_id"][rows].astype(str).tolist()}
    return result


def table10(results: Sequence[dict]):
    import pandas as pd

    if not results:
        raise FeederError("delta table: no level results given")
    recs = []
    for r in results:
        rec = {"level_pct": int(r["level_pct"]), "cost_saved_pct": float(r["cost_saved_pct"])}
        for mode in MODES:
            mres = r["modes"][mode]
            rec.update(
                {
                    f"{mode}_r2_mean": mres["r2_mean"],
                    f"{mode}_r2_sd": mres["r2_sd"],
                    f"{mode}_baseline_mean": mres["baseline_mean"],
                    f"{mode}_baseline_sd": mres["baseline_sd"],
                }
            )
        recs.append(rec)
    frame = pd.DataFrame(recs, columns=TABLE10_COLUMNS)
    if frame["level_pct"].duplicated().any():
        raise FeederError("delta table: a level appears twice")
    return frame.sort_values("level_pct", kind="stable").reset_index(drop=True)


def table10_markdown(frame, results: Sequence[dict], representative: Sequence[int]) -> str:
    shown = frame[frame["level_pct"].isin([int(v) for v in representative])]
    missing = sorted(set(int(v) for v in representative) - set(frame["level_pct"]))
    fmt = lambda m, s: f"{m:.2f} ± {s:.2f}"  # noqa: E731
    lines = [
        "# Table 10: delta-to-full correction, CDF R² (mean ± population SD per configuration)",
        "",
        "Part split = leave-parts-out GroupKFold (unseen parts); config split = random KFold over "
        "configurations (parts seen in training). Baseline = the partial PMF taken as the answer. "
        "Cost saved = 100 − level. The corrected PMF is the convex mixture "
        "(1 − w)·PMF_k + w·softmax(z) with w = sigmoid(gate) in (0, 1), so PMF_k + ΔPMF is a valid "
        "PMF by construction (ΔPMF = w·(softmax(z) − PMF_k)). All levels: table10.csv.",
        "",
        "| Level | Cost saved (%) | Part split | Part baseline | Config split | Config baseline |",
        "|---|---|---|---|---|---|",
    ]
    for r in shown.itertuples():
        lines.append(
            f"| {r.level_pct}% | {r.cost_saved_pct:.1f} | {fmt(r.part_r2_mean, r.part_r2_sd)} | "
            f"{fmt(r.part_baseline_mean, r.part_baseline_sd)} | {fmt(r.config_r2_mean, r.config_r2_sd)} | "
            f"{fmt(r.config_baseline_mean, r.config_baseline_sd)} |"
        )
    if missing:
        lines += ["", f"Levels not in this sweep: {', '.join(f'{m}%' for m in missing)}."]
    wall = sum(float(r["train_wall_s"]) for r in results)
    n_models = sum(len(r["modes"][m]["folds"]) for r in results for m in MODES)
    lines += [
        "",
        "Provenance:",
        f"- {n_models} models trained over {len(results)} levels, training wall time {wall:.1f} s in total",
        "- training wall time per level: "
        + ", ".join(
            f"{int(r['level_pct'])}%: {float(r['train_wall_s']):.1f} s"
            for r in sorted(results, key=lambda r: int(r["level_pct"]))
        ),
        f"- rows per level: {sorted({int(r['n_rows']) for r in results})}; "
        f"config digests: {sorted({r['config_digest'] for r in results})}",
    ]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder delta", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("sweep", help="train and score the delta model at one level (both split modes)")
    p.add_argument("--level", type=int, required=True, help="percentage, one of the dataset's levels")
    p.add_argument("--out", type=Path, required=True, help="level result (.json)")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/delta.yaml")
    p = sub.add_parser("table", help="Table 10 (+ .md; also the data of Fig. S11) from level results")
    p.add_argument("--table", type=Path, required=True, help="table10.csv (a .md is written beside it)")
    p.add_argument(
        "--override",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="Hydra override of config/hydra/delta.yaml (repeatable; representative_levels is read)",
    )
    p.add_argument("results", nargs="+", type=Path, help="level JSONs from `feeder delta sweep`")
    args = parser.parse_args(argv)
    if args.cmd == "sweep":
        cfg = compose_config("delta", args.overrides)
        io.write_json(args.out, sweep_level(cfg, args.level))
    else:
        results = [_read_json(p) for p in args.results]
        rep = list(compose_config("delta", args.override).representative_levels)
        frame = table10(results)
        md = table10_markdown(frame, results, rep)
        io.write_csv(args.table, frame)
        io.write_text(args.table.with_suffix(".md"), md)
    return 0
