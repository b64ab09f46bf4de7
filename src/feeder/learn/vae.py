"""Variational autoencoder of part+feeder features and orientation CDFs (paper §3.4.2, Table 3),
its reconstruction table (Table 9) and the partial-iteration study P2 (§4.7.2, Fig. 14).

Model (all sizes from ``config/hydra/vae.yaml``)
    Two encoders, each Linear -> LayerNorm -> ReLU per layer: the 53 scaled part+feeder values
    (53 -> 128 -> 64 -> 45) and the 360-bin CDF (360 -> 256 -> 128). Their outputs are concatenated
    (173) and two linear heads give the mean and the log-variance of a 35-dimensional Gaussian
    latent; the log-variance is clamped to ``[logvar_min, logvar_max]`` so ``exp`` and the KL stay
    finite. The decoder (35 -> 300, LeakyReLU, -> 413) is split into 53 feature outputs (sigmoid
    on the six fence-type one-hot columns, identity elsewhere) and 360 CDF outputs that go through
    softplus (+ ``cdf_eps``), a cumulative sum and a division by the total: every reconstructed CDF
    is non-decreasing and ends at exactly 1 without post-processing.

Loss
    ``alpha1 * (Huber(continuous) + BCE(one-hots) + delta * gradient) + alpha2 * MSE(CDF)
    + beta * KL + gamma * KS``. The gradient term is the mean squared difference between the first
    differences (along the feature axis) of the reconstructed and true DFT columns, our reading of
    the paper's "smoothness" term. The BCE is computed from the pre-sigmoid outputs (log-sum-exp
    form) so saturated one-hots give finite losses. MSE is the mean over bins; KS is the per-row
    max |F^ - F| averaged over the batch; the KL is summed over latent dimensions and averaged
    over the batch. ``beta`` grows linearly from 0 at epoch 0 to ``beta_max`` at
    ``beta_anneal_epochs``.

Training
    Adam (weight decay), global gradient-norm clipping, a seeded 10 % validation split of the
    training rows. The kept model is the epoch of lowest validation loss, where the validation
    loss uses the latent mean (no sampling noise) and the *final* KL weight ``beta_max`` so epochs
    with different annealing weights are compared on one scale; training stops after ``patience``
    epochs without improvement. Reconstructions for metrics also use the latent mean.

Metrics
    R² per configuration (``feeder.labels.metrics.r2_cdf``: 1 - SS_res / SS_tot along the row) of the
    53 scaled features and of the 360-bin CDF; tables give mean and population SD (ddof = 0).

P2
    One seeded split (``p2.holdout_fraction``) of the ``p2.splits`` rows is shared by every
    level. At level k the VAE is trained from scratch on the level-k CDFs (cumulative sums of
    ``pmf_levels``) of the shared training rows. On the holdout it is fed the level-k CDF and
    scored against the level-k CDF ("within-level") and against the 100 % CDF ("cross-
    convergence"); the R² of the raw level-k CDF against the 100 % CDF is reported beside them.

CLI: ``feeder vae train|table9|p2-level|p2-gather`` (see ``feeder vae <cmd> -h``); every command
that trains takes Hydra overrides of ``config/hydra/vae.yaml`` as trailing arguments.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import io as _io
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from feeder import io
from feeder.config import compose_config, resolved_yaml
from feeder.errors import FeederError
from feeder.labels.dataset import DATASET_KEYS, LEVEL_KEYS, load_dataset
from feeder.labels.metrics import r2_cdf
from feeder.learn.data import level_index, scaled_features, split_mask, validation_split

P2_COLUMNS = [
    "level_pct",
    "n_train",
    "n_val",
    "n_holdout",
    "within_r2_mean",
    "within_r2_sd",
    "cross_r2_mean",
    "cross_r2_sd",
    "features_r2_mean",
    "features_r2_sd",
    "partial_baseline_r2_mean",
    "partial_baseline_r2_sd",
    "best_epoch",
    "epochs_run",
    "train_wall_s",
]
TABLE9_COLUMNS = ["dataset", "n", "r2_features_mean", "r2_features_sd", "r2_cdf_mean", "r2_cdf_sd"]


# ----------------------------------------------------------------------------------------------
# Hydra configuration
# ----------------------------------------------------------------------------------------------
def rule_params(name: str, overrides: Sequence[str] = ()) -> dict[str, str]:
    """``params:`` for a rule that runs a Hydra-configured command: the shell-quoted overrides to
    append to the command and the resolved config (so a changed setting reruns the job)."""
    overrides = [str(o) for o in overrides]
    return {"overrides": " ".join(shlex.quote(o) for o in overrides), "resolved": resolved_yaml(name, overrides)}


def select_levels(setting, available: Sequence[int], what: str) -> list[int]:
    """Workflow helper: ``"all"`` -> every available level, else the listed levels (each must be
    available), sorted."""
    levels = list(available) if setting == "all" else list(setting)
    unknown = sorted(set(int(v) for v in levels) - set(int(v) for v in available))
    if unknown:
        raise FeederError(f"{what}: levels {unknown} are not in labels.levels_pct {list(available)}")
    return sorted(int(v) for v in levels)


def config_digest(cfg) -> str:
    from omegaconf import OmegaConf

    return hashlib.sha256(OmegaConf.to_yaml(cfg, resolve=True).encode()).hexdigest()[:12]


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------
def summarize(values: np.ndarray) -> tuple[float, float]:
    """Mean and population SD (ddof = 0)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return float("nan"), float("nan")
    return float(values.mean()), float(values.std(ddof=0))


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------
def build_vae(mcfg, n_features: int, n_bins: int):
    """The VAE as an ``nn.ModuleDict`` (enc_x, enc_f, mu, logvar, dec); see :func:`vae_forward`."""
    from torch import nn

    def encoder(sizes):
        layers = []
        for a, b in zip(sizes[:-1], sizes[1:]):
            layers += [nn.Linear(a, b), nn.LayerNorm(b), nn.ReLU()]
        return nn.Sequential(*layers)

    if max(mcfg.onehot_columns) >= n_features or mcfg.smooth_columns > n_features:
        raise FeederError(f"vae model: feature columns exceed the {n_features} inputs")
    joint = int(mcfg.part_encoder[-1]) + int(mcfg.dist_encoder[-1])
    latent = int(mcfg.latent_dim)
    return nn.ModuleDict(
        {
            "enc_x": encoder([n_features, *mcfg.part_encoder]),
            "enc_f": encoder([n_bins, *mcfg.dist_encoder]),
            "mu": nn.Linear(joint, latent),
            "logvar": nn.Linear(joint, latent),
            "dec": nn.Sequential(
                nn.Linear(latent, int(mcfg.decoder_hidden)),
                nn.LeakyReLU(float(mcfg.leaky_relu_slope)),
                nn.Linear(int(mcfg.decoder_hidden), n_features + n_bins),
            ),
        }
    )


def onehot_mask(mcfg, n_features: int):
    import torch

    mask = torch.zeros(n_features, dtype=torch.bool)
    mask[list(mcfg.onehot_columns)] = True
    return mask


def vae_forward(net, mcfg, x, cdf, noise=None) -> dict[str, Any]:
    """Encode, sample ``z = mu + noise * sigma`` (``noise=None``: z = mu) and decode.

    Returns features (sigmoid on one-hots), feature_logits (pre-sigmoid), cdf, mu, logvar.
    """
    import torch
    from torch.nn import functional as F

    h = torch.cat([net["enc_x"](x), net["enc_f"](cdf)], dim=-1)
    mu = net["mu"](h)
    logvar = torch.clamp(net["logvar"](h), float(mcfg.logvar_min), float(mcfg.logvar_max))
    z = mu if noise is None else mu + noise * torch.exp(0.5 * logvar)
    out = net["dec"](z)
    n_features = x.shape[-1]
    logits, cdf_raw = out[:, :n_features], out[:, n_features:]
    mask = onehot_mask(mcfg, n_features)
    features = torch.where(mask, torch.sigmoid(logits), logits)
    inc = F.softplus(cdf_raw) + float(mcfg.cdf_eps)
    cdf_hat = torch.cumsum(inc, dim=-1) / inc.sum(dim=-1, keepdim=True)
    return {"features": features, "feature_logits": logits, "cdf": cdf_hat, "mu": mu, "logvar": logvar}


def kl_standard_normal(mu, logvar):
    """Mean over rows of KL(N(mu, exp(logvar)) || N(0, I)), summed over latent dimensions."""
    import torch

    return (-0.5 * (1.0 + logvar - mu.pow(2) - torch.exp(logvar))).sum(dim=-1).mean()


def vae_loss(out, x, cdf, cfg, beta: float):
    """Total loss and its unweighted parts (see the module docstring)."""
    import torch
    from torch.nn import functional as F

    from feeder.learn import losses

    mcfg, lcfg = cfg.model, cfg.loss
    mask = onehot_mask(mcfg, x.shape[-1])
    logits = out["feature_logits"]
    huber = F.huber_loss(logits[:, ~mask], x[:, ~mask], delta=float(lcfg.huber_delta))
    bce = F.binary_cross_entropy_with_logits(logits[:, mask], x[:, mask])
    s = int(mcfg.smooth_columns)
    grad = losses.mse(torch.diff(out["features"][:, :s], dim=-1), torch.diff(x[:, :s], dim=-1))
    part1 = huber + bce + float(lcfg.delta) * grad
    cdf_mse = losses.mse(out["cdf"], cdf)
    ks = losses.ks(out["cdf"], cdf)
    kl = kl_standard_normal(out["mu"], out["logvar"])
    total = float(lcfg.alpha1) * part1 + float(lcfg.alpha2) * cdf_mse + beta * kl + float(lcfg.gamma) * ks
    parts = {"huber": huber, "bce": bce, "grad": grad, "cdf_mse": cdf_mse, "ks": ks, "kl": kl}
    return total, parts


def kl_weight(lcfg, epoch: int) -> float:
    """Linear KL annealing: 0 at epoch 0, ``beta_max`` from ``beta_anneal_epochs`` on."""
    n = int(lcfg.beta_anneal_epochs)
    return float(lcfg.beta_max) if n <= 0 else float(lcfg.beta_max) * min(1.0, epoch / n)


# ----------------------------------------------------------------------------------------------
# Training
# ----------------------------------------------------------------------------------------------
@dataclass
class VaeFit:
    net: Any
    n_features: int
    n_bins: int
    best_epoch: int
    epochs_run: int
    wall_s: float
    n_train: int
    n_val: int
    history: list[dict[str, float]] = field(default_factory=list)


def seeded_run(tcfg, n: int, seed: int):
    """What makes one training run reproducible: the seeded (train, validation) row split, torch's
    thread count and seed, and the generator that orders its batches. Shared by the VAE and the
    delta model."""
    import torch

    tr, va = validation_split(np.arange(n), float(tcfg.val_fraction), seed, "train.val_fraction")
    torch.set_num_threads(int(tcfg.threads))
    torch.manual_seed(seed)
    return tr, va, torch.Generator().manual_seed(seed)


def _fit_inputs(x: np.ndarray, cdf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x`` and ``cdf`` as float64 matrices with one row per configuration, finite."""
    x = np.asarray(x, dtype=np.float64)
    cdf = np.asarray(cdf, dtype=np.float64)
    if x.ndim != 2 or cdf.ndim != 2 or x.shape[0] != cdf.shape[0]:
        raise FeederError(f"fit_vae: features {x.shape} and CDFs {cdf.shape} do not pair up")
    if not (np.isfinite(x).all() and np.isfinite(cdf).all()):
        raise FeederError("fit_vae: non-finite features or CDFs")
    return x, cdf


def _vae_epoch(net, opt, cfg, x_tr, f_tr, gen, beta: float, epoch: int) -> float:
    """One pass over the training rows (seeded batch order and latent noise, gradient clipping);
    the mean training loss."""
    import torch

    batch, latent = int(cfg.train.batch_size), int(cfg.model.latent_dim)
    net.train()
    order = torch.randperm(len(x_tr), generator=gen)
    total, count = 0.0, 0
    for i in range(0, len(x_tr), batch):
        idx = order[i : i + batch]
        noise = torch.randn(len(idx), latent, generator=gen)
        out = vae_forward(net, cfg.model, x_tr[idx], f_tr[idx], noise)
        loss, _ = vae_loss(out, x_tr[idx], f_tr[idx], cfg, beta)
        if not torch.isfinite(loss):
            raise FeederError(f"VAE training diverged: non-finite loss at epoch {epoch}")
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), float(cfg.train.grad_clip))
        opt.step()
        total += float(loss.detach()) * len(idx)
        count += len(idx)
    return total / count


def _vae_validation(net, cfg, x_va, f_va, epoch: int) -> tuple[float, dict]:
    """Validation loss (latent mean, final KL weight ``beta_max``) and its parts."""
    import torch

    net.eval()
    with torch.no_grad():
        out = vae_forward(net, cfg.model, x_va, f_va)
        val, parts = vae_loss(out, x_va, f_va, cfg, float(cfg.loss.beta_max))
    val = float(val)
    if not np.isfinite(val):
        raise FeederError(f"VAE training diverged: non-finite validation loss at epoch {epoch}")
    return val, parts


def fit_vae(cfg, x: np.ndarray, cdf: np.ndarray, seed: int | None = None) -> VaeFit:
    """Train one VAE on rows ``x`` (N, 53) scaled features and ``cdf`` (N, bins)."""
    import torch
    from tqdm import tqdm

    seed = int(cfg.seed if seed is None else seed)
    x, cdf = _fit_inputs(x, cdf)
    tcfg = cfg.train
    tr, va, gen = seeded_run(tcfg, x.shape[0], seed)
    net = build_vae(cfg.model, x.shape[1], cdf.shape[1])
    xt, ft = torch.as_tensor(x, dtype=torch.float32), torch.as_tensor(cdf, dtype=torch.float32)
    x_tr, f_tr, x_va, f_va = xt[tr], ft[tr], xt[va], ft[va]
    opt = torch.optim.Adam(net.parameters(), lr=float(tcfg.lr), weight_decay=float(tcfg.weight_decay))
    patience = None if tcfg.patience is None else int(tcfg.patience)
    best, best_state, best_epoch, stale = float("inf"), None, -1, 0
    history: list[dict[str, float]] = []
    start = time.perf_counter()
    epochs = tqdm(
        range(int(tcfg.epochs)), desc="vae", unit="epoch", file=sys.stderr, disable=not sys.stderr.isatty(), leave=False
    )
    for epoch in epochs:
        beta = kl_weight(cfg.loss, epoch)
        train_loss = _vae_epoch(net, opt, cfg, x_tr, f_tr, gen, beta, epoch)
        val, parts = _vae_validation(net, cfg, x_va, f_va, epoch)
        history.append(
            {
                "epoch": epoch,
                "beta": beta,
                "train_loss": train_loss,
                "val_loss": val,
                **{f"val_{k}": float(v) for k, v in parts.items()},
            }
        )
        if val < best:
            best, best_epoch, stale = val, epoch, 0
            best_state = copy.deepcopy(net.state_dict())
        else:
            stale += 1
            if patience is not None and stale >= patience:
                break
    wall = time.perf_counter() - start
    if best_state is None:
        raise FeederError("VAE training ran no epoch (train.epochs must be >= 1)")
    net.load_state_dict(best_state)
    net.eval()
    return VaeFit(net, x.shape[1], cdf.shape[1], best_epoch, len(history), wall, len(tr), len(va), history)


def reconstruct(net, mcfg, x: np.ndarray, cdf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deterministic reconstruction (latent mean) of features and CDFs, float64 arrays."""
    import torch

    with torch.no_grad():
        out = vae_forward(net, mcfg, torch.as_tensor(x, dtype=torch.float32), torch.as_tensor(cdf, dtype=torch.float32))
    return out["features"].double().numpy(), out["cdf"].double().numpy()


# ----------------------------------------------------------------------------------------------
# Checkpoints
# ----------------------------------------------------------------------------------------------
def save_checkpoint(path: str | Path, fit: VaeFit, cfg, extra: dict | None = None) -> None:
    import torch
    from omegaconf import OmegaConf

    blob = {
        "state_dict": fit.net.state_dict(),
        "config_yaml": OmegaConf.to_yaml(cfg, resolve=True),
        "n_features": fit.n_features,
        "n_bins": fit.n_bins,
        "best_epoch": fit.best_epoch,
        "epochs_run": fit.epochs_run,
        "wall_s": fit.wall_s,
        "n_train": fit.n_train,
        "n_val": fit.n_val,
        "history": fit.history,
        **(extra or {}),
    }
    buf = _io.BytesIO()
    torch.save(blob, buf)
    io.write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | Path):
    """Return (net, cfg, blob) of a checkpoint written by :func:`save_checkpoint`."""
    import torch
    from omegaconf import OmegaConf

    path = Path(path)
    if not path.is_file():
        raise FeederError(f"{path}: VAE checkpoint not found")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        cfg = OmegaConf.create(blob["config_yaml"])
        net = build_vae(cfg.model, int(blob["n_features"]), int(blob["n_bins"]))
        net.load_state_dict(blob["state_dict"])
    except (OSError, RuntimeError, KeyError, ValueError) as err:
        raise FeederError(f"{path}: not a VAE checkpoint ({str(err).splitlines()[0]})") from None
    net.eval()
    return net, cfg, blob


# ----------------------------------------------------------------------------------------------
# Table 9: VAE on Main, reconstruction of Fences and Parts
# ----------------------------------------------------------------------------------------------
def train_vae(cfg) -> tuple[VaeFit, dict[str, np.ndarray]]:
    """Train the Table 9 VAE on the ``table9.train_splits`` rows of ``cfg.dataset``.

    Returns the fit and the dataset (with its ``features`` key added: scaled on the training rows).
    """
    data = load_dataset(cfg.dataset, DATASET_KEYS + LEVEL_KEYS)
    mask = split_mask(data, cfg.table9.train_splits, "table9.train_splits")
    if mask.sum() < 2:
        raise FeederError(f"{cfg.dataset}: fewer than 2 rows in splits {list(cfg.table9.train_splits)}")
    data["features"] = scaled_features(data, mask)
    fit = fit_vae(cfg, data["features"][mask], data["cdf"][mask])
    return fit, data


def reconstruction_scores(net, mcfg, x: np.ndarray, cdf_in: np.ndarray, cdf_target: np.ndarray | None = None):
    """Per-row R² of the reconstructed features (vs ``x``) and CDFs (vs ``cdf_target``, default
    the input CDF)."""
    feat_hat, cdf_hat = reconstruct(net, mcfg, x, cdf_in)
    target = cdf_in if cdf_target is None else cdf_target
    return r2_cdf(x, feat_hat), r2_cdf(target, cdf_hat)


def table9(net, cfg, data: dict[str, np.ndarray]) -> pd.DataFrame:  # noqa: F821
    """One row per evaluation split: n and R² mean/SD of features and CDF."""
    import pandas as pd

    rows = []
    for name in cfg.table9.eval_splits:
        mask = split_mask(data, [name], "table9.eval_splits")
        if not mask.any():
            raise FeederError(f"{cfg.dataset}: no rows in split {name!r} to evaluate")
        r2_x, r2_f = reconstruction_scores(net, cfg.model, data["features"][mask], data["cdf"][mask])
        fm, fs = summarize(r2_x)
        cm, cs = summarize(r2_f)
        rows.append(
            {
                "dataset": name,
                "n": int(mask.sum()),
                "r2_features_mean": fm,
                "r2_features_sd": fs,
                "r2_cdf_mean": cm,
                "r2_cdf_sd": cs,
            }
        )
    return pd.DataFrame(rows, columns=TABLE9_COLUMNS)


def table9_markdown(frame, blob: dict, cfg) -> str:
    lines = [
        "# Table 9: VAE reconstruction R² (mean ± population SD per configuration)",
        "",
        f"VAE trained on splits {list(cfg.table9.train_splits)} only ({blob['n_train']} training + "
        f"{blob['n_val']} validation rows); the rows below were never seen in training. This is "
        "autoencoding: the VAE receives the CDF it reconstructs.",
        "",
        "| Dataset | N | R² (Part+Feeder) | R² (CDF) |",
        "|---|---|---|---|",
    ]
    for r in frame.itertuples():
        lines.append(
            f"| {r.dataset.capitalize()} | {r.n} | {r.r2_features_mean:.2f} ± {r.r2_features_sd:.2f} | "
            f"{r.r2_cdf_mean:.2f} ± {r.r2_cdf_sd:.2f} |"
        )
    lines += [
        "",
        "Provenance:",
        f"- training wall time {blob['wall_s']:.1f} s, {blob['epochs_run']} epochs run, "
        f"best epoch {blob['best_epoch']} (lowest validation loss)",
        f"- config digest {config_digest(cfg)} (config/hydra/vae.yaml + overrides), dataset {cfg.dataset}",
    ]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# P2: partial-iteration study
# ----------------------------------------------------------------------------------------------
def p2_split(data: dict[str, np.ndarray], cfg) -> tuple[np.ndarray, np.ndarray]:
    """Shared (train, holdout) row indices of the P2 study, the same for every level."""
    rows = np.flatnonzero(split_mask(data, cfg.p2.splits, "p2.splits"))
    frac = float(cfg.p2.holdout_fraction)
    if not 0 < frac < 1:
        raise FeederError(f"p2.holdout_fraction must be in (0, 1), got {frac}")
    if rows.size < 4:
        raise FeederError(f"{cfg.dataset}: P2 needs at least 4 rows in splits {list(cfg.p2.splits)}")
    perm = np.random.default_rng(int(cfg.p2.split_seed)).permutation(rows)
    n_hold = min(max(1, int(round(frac * rows.size))), rows.size - 2)
    return np.sort(perm[n_hold:]), np.sort(perm[:n_hold])


def p2_level(cfg, level: int) -> dict[str, Any]:
    """Train a VAE from scratch on level-``level`` CDFs and score it on the shared holdout."""
    data = load_dataset(cfg.dataset, DATASET_KEYS + LEVEL_KEYS)
    li = level_index(data["levels_pct"], level)
    train, hold = p2_split(data, cfg)
    fit_mask = np.zeros(len(data["split"]), dtype=bool)
    fit_mask[train] = True
    x = scaled_features(data, fit_mask)
    cdf_k = np.cumsum(data["pmf_levels"][:, li, :], axis=-1)
    fit = fit_vae(cfg, x[train], cdf_k[train])
    feat_hat, cdf_hat = reconstruct(fit.net, cfg.model, x[hold], cdf_k[hold])
    within = r2_cdf(cdf_k[hold], cdf_hat)
    cross = r2_cdf(data["cdf"][hold], cdf_hat)
    feats = r2_cdf(x[hold], feat_hat)
    base = r2_cdf(data["cdf"][hold], cdf_k[hold])
    for name, arr in (("within", within), ("cross", cross), ("features", feats)):
        if not np.isfinite(arr).all():
            raise FeederError(f"P2 level {level}: non-finite {name} R²")
    result: dict[str, Any] = {
        "level_pct": int(level),
        "n_train": fit.n_train,
        "n_val": fit.n_val,
        "n_holdout": int(hold.size),
    }
    for name, arr in (
        ("within_r2", within),
        ("cross_r2", cross),
        ("features_r2", feats),
        ("partial_baseline_r2", base),
    ):
        result[f"{name}_mean"], result[f"{name}_sd"] = summarize(arr)
    result.update(
        {
            "best_epoch": fit.best_epoch,
            "epochs_run": fit.epochs_run,
            "train_wall_s": fit.wall_s,
            "config_digest": config_digest(cfg),
            "holdout_rows": {
                "part": data["part"][hold].tolist(),
                "config_id": data["config_id"][hold].astype(str).tolist(),
            },
            "per_row": {
                "within_r2": within.tolist(),
                "cross_r2": cross.tolist(),
                "features_r2": feats.tolist(),
                "partial_baseline_r2": base.tolist(),
            },
        }
    )
    return result


def p2_gather(results: Sequence[dict]) -> pd.DataFrame:  # noqa: F821
    import pandas as pd

    if not results:
        raise FeederError("p2-gather: no level results given")
    frame = pd.DataFrame([{k: r[k] for k in P2_COLUMNS} for r in results], columns=P2_COLUMNS)
    if frame["level_pct"].duplicated().any():
        raise FeederError("p2-gather: a level appears twice")
    return frame.sort_values("level_pct", kind="stable").reset_index(drop=True)


def p2_markdown(frame) -> str:
    lines = [
        "# P2: VAE per iteration level, shared holdout (R² mean ± population SD)",
        "",
        "| Level | N train | N holdout | Within-level | Cross-convergence | Partial CDF vs 100 % | "
        "Features | Train wall [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in frame.itertuples():
        lines.append(
            f"| {r.level_pct}% | {r.n_train} | {r.n_holdout} | {r.within_r2_mean:.2f} ± {r.within_r2_sd:.2f} | "
            f"{r.cross_r2_mean:.2f} ± {r.cross_r2_sd:.2f} | "
            f"{r.partial_baseline_r2_mean:.2f} ± {r.partial_baseline_r2_sd:.2f} | "
            f"{r.features_r2_mean:.2f} ± {r.features_r2_sd:.2f} | {r.train_wall_s:.1f} |"
        )
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def _read_json(path: Path) -> dict:
    import json

    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as err:
        raise FeederError(f"{path}: unreadable result JSON ({err})") from None


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder vae", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("train", help="train the Table 9 VAE on the Main rows")
    p.add_argument("--out", type=Path, required=True, help="checkpoint (.pt)")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/vae.yaml")
    p = sub.add_parser("table9", help="Table 9 from a trained checkpoint")
    p.add_argument("--model", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="table9.csv (a .md is written beside it)")
    p = sub.add_parser("p2-level", help="train and score one P2 iteration level")
    p.add_argument("--level", type=int, required=True, help="percentage, one of the dataset's levels")
    p.add_argument("--out", type=Path, required=True, help="level result (.json)")
    p.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/vae.yaml")
    p = sub.add_parser("p2-gather", help="P2 table (the data of Fig. 14) from level results")
    p.add_argument("--table", type=Path, required=True, help="p2_levels.csv (a .md is written beside it)")
    p.add_argument("results", nargs="+", type=Path, help="level JSONs from p2-level")
    args = parser.parse_args(argv)

    if args.cmd == "train":
        cfg = compose_config("vae", args.overrides)
        fit, _ = train_vae(cfg)
        save_checkpoint(args.out, fit, cfg)
        print(
            f"vae: {fit.n_train}+{fit.n_val} rows, {fit.epochs_run} epochs, best {fit.best_epoch}, "
            f"{fit.wall_s:.1f} s -> {args.out}",
            file=sys.stderr,
        )
    elif args.cmd == "table9":
        net, cfg, blob = load_checkpoint(args.model)
        data = load_dataset(cfg.dataset, DATASET_KEYS + LEVEL_KEYS)
        data["features"] = scaled_features(data, split_mask(data, cfg.table9.train_splits, "table9.train_splits"))
        frame = table9(net, cfg, data)
        md = table9_markdown(frame, blob, cfg)
        io.write_csv(args.out, frame)
        io.write_text(args.out.with_suffix(".md"), md)
    elif args.cmd == "p2-level":
        cfg = compose_config("vae", args.overrides)
        io.write_json(args.out, p2_level(cfg, args.level))
    elif args.cmd == "p2-gather":
        frame = p2_gather([_read_json(p) for p in args.results])
        io.write_csv(args.table, frame)
        io.write_text(args.table.with_suffix(".md"), p2_markdown(frame))
    return 0
