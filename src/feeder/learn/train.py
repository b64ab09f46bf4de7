"""``feeder train``: train one regression model of paper Table 2 from its Hydra config.

The config is ``config/hydra/train.yaml`` (defaults: ``model: m3``, ``trainer: default``); the
model group ``config/hydra/model/m1.yaml`` … ``m8.yaml`` holds each model's label, architecture,
learning rate and loss terms, ``config/hydra/trainer/default.yaml`` the shared settings (Adam, batch 64, at most
400 epochs, early stopping with patience 20 on a 10 % validation carve-out of the training rows).
``model.inputs`` chooses the network inputs: the paper's 53 (``paper``, m1-m8), with
``paper+push`` also the analytic push block of the dataset (``push_raw``,
:mod:`feeder.labels.dataset`; m3push), or with ``fence+push`` the push block and the 8 fence
inputs without the DFT (m3pushonly); every block scaled on the training rows.

    feeder train model=m3 paths.dataset=results/datasets/dataset.npz \\
        paths.out=results/models/m3 hydra.run.dir=results/models/m3/hydra
    feeder train -m hparams_search=grid model=m3          # the §3.4.1 grid search (multirun)

:func:`train` is a plain function of a composed config (:func:`feeder.config.compose_config`
with ``"train"``; tests call it that way); :func:`fit` trains on any row mask (the GroupKFold
study reuses it). A model directory holds ``model.pt`` (spec + weights, PCA loadings as
buffers), ``scaler.json`` (input scaler), ``config.yaml`` (the resolved config), ``history.csv``
(per-epoch losses) and ``metrics.json`` (``train_s`` = training wall seconds, best epoch,
validation loss, PCA components kept, and the CDF R² per split).

Reproducibility: the seed fixes network initialisation, the validation carve-out and the batch
order; torch runs single-threaded (``trainer.threads``) with deterministic algorithms, so the
same inputs and seed give the same metrics on CPU.
"""

from __future__ import annotations

import copy
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from feeder.config import hydra_config_dir, resolved_yaml
from feeder.errors import FeederError
from feeder.learn.data import validation_split

CONFIG_NAME = "train"


def resolved_config_yaml(model: str, overrides=(), config_dir=None) -> str:
    """The resolved settings that determine a trained model (``model``, ``trainer``, ``seed``;
    not the ``paths``) as YAML. The workflow passes it as a rule param, so editing one model's
    Hydra file reruns only that model."""
    return resolved_yaml(CONFIG_NAME, [f"model={model}", *overrides], drop=("paths",), config_dir=config_dir)


# ----------------------------------------------------------------------------------------------
# Training
# ----------------------------------------------------------------------------------------------
@dataclass
class Fitted:
    model: object  # feeder.learn.models.TrainedModel
    history: list[dict] = field(default_factory=list)
    best_epoch: int = 0
    best_val_loss: float = float("nan")
    train_s: float = 0.0
    n_fit: int = 0
    n_val: int = 0
    pca_components: int | None = None
    pca_requested: int | None = None


def setup_torch(threads: int) -> None:
    import torch

    torch.set_num_threads(int(threads))
    torch.use_deterministic_algorithms(True)


def _model_spec(cfg, bins: int):
    """The model's spec and its loss weights, checked."""
    from feeder.learn import losses
    from feeder.learn.models import ModelSpec

    try:
        spec = ModelSpec.from_config(cfg.model, bins)
        weights = {str(k): float(v) for k, v in cfg.model.loss.items()}
        losses.check_terms(weights, has_log_pmf=spec.output_activation == "softmax")
    except ValueError as err:
        raise FeederError(str(err)) from None
    return spec, weights


def _model_inputs(spec, data: dict[str, np.ndarray], train_mask: np.ndarray, rows: np.ndarray):
    """The input scaler and the PCA of the label (for PCA models), both fit on the training rows,
    and the scaled inputs of every row (those of ``spec.inputs``)."""
    from feeder.labels.dataset import fit_scaler, raw_inputs, uses_dft
    from feeder.learn.models import fit_pca

    raw = raw_inputs(data, spec.inputs)
    scaler = fit_scaler(*raw[:2], train_mask, *raw[2:], dft=uses_dft(spec.inputs))
    x_all = np.asarray(scaler.transform(*raw), dtype=np.float64)
    pca = None
    if spec.repr == "pca":
        pca = fit_pca(data[spec.label][rows], spec.components)
        if pca.capped:
            print(
                f"feeder train: {spec.name}: PCA capped at {pca.n_components} components "
                f"(requested {spec.components}; {rows.size} training rows)",
                file=sys.stderr,
            )
    return scaler, x_all, pca


def _init_net(spec, pca, data: dict[str, np.ndarray], rows: np.ndarray, seed: int, prior_cfg=None):
    """The seeded network, its output initialised to the training rows' mean label; for
    ``model.base: prior`` with the prior fitted on those rows from the grids of ``prior_cfg``
    (the training config's ``prior`` node), its output at the prior."""
    import torch

    from feeder.learn.models import RegressionModel

    n_out = pca.n_components if pca is not None else data["pmf"].shape[1]
    torch.manual_seed(seed)
    net = RegressionModel(spec, n_out, None if pca is None else pca.mean, None if pca is None else pca.components)
    net.init_output_to_mean(data["pmf"][rows].mean(axis=0), data["cdf"][rows].mean(axis=0))
    if spec.base == "prior":
        from feeder.learn.prior import fit_blend, grids

        if "pmf_analytic" not in data:
            raise FeederError(
                f"model {spec.name} starts from the analytic prior (model.base: prior): the dataset has no "
                "pmf_analytic; rebuild it with `feeder datasets build --parts-dir DIR`"
            )
        if prior_cfg is None:
            raise FeederError(f"model {spec.name}: model.base prior needs the training config's prior node")
        g = grids(prior_cfg)
        train = np.zeros(len(data["pmf"]), dtype=bool)
        train[rows] = True
        best = fit_blend(data["pmf"], data["pmf_analytic"], train, g.sigmas_bins, g.weights)
        net.set_prior(data["pmf"][rows].mean(axis=0), best.sigma_bins, best.weight)
    return net


def _train_epoch(net, opt, loss_of, tensors, batch: int, gen, name: str, epoch: int) -> float:
    """One pass over the fit rows in a seeded batch order; the mean training loss."""
    import torch

    x, p, c, lp = tensors
    net.train()
    order = torch.randperm(x.shape[0], generator=gen)
    total, seen = 0.0, 0
    for start in range(0, x.shape[0], batch):
        idx = order[start : start + batch]
        loss, _ = loss_of(x[idx], p[idx], c[idx], None if lp is None else lp[idx])
        if not torch.isfinite(loss):
            raise FeederError(f"{name}: non-finite training loss at epoch {epoch}")
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        total += loss.item() * idx.numel()
        seen += idx.numel()
    return total / seen


def _train_epochs(
    cfg,
    net,
    spec,
    weights: dict,
    x_all: np.ndarray,
    data: dict[str, np.ndarray],
    fit_rows: np.ndarray,
    val_rows: np.ndarray,
    seed: int,
    progress: bool | None,
):
    """Adam with early stopping on the validation rows; leaves ``net`` at its best epoch.
    Returns (history, best epoch, best validation loss)."""
    import torch
    from tqdm import tqdm

    from feeder.learn import losses

    tr = cfg.trainer
    opt = torch.optim.Adam(net.parameters(), lr=float(cfg.model.lr))
    gen = torch.Generator().manual_seed(seed)
    f32 = lambda a: torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
    # log(prior) of every row for a base prior network (fixed: the prior is not trained)
    lp_all = net.log_prior(np.asarray(data["pmf_analytic"])) if spec.base == "prior" else None
    sub = lambda rows: None if lp_all is None else lp_all[rows]  # noqa: E731
    fit_t = f32(x_all[fit_rows]), f32(data["pmf"][fit_rows]), f32(data["cdf"][fit_rows]), sub(fit_rows)
    xv, pv, cv, lpv = f32(x_all[val_rows]), f32(data["pmf"][val_rows]), f32(data["cdf"][val_rows]), sub(val_rows)

    def loss_of(x, p, c, lp):
        out = net(x, lp)
        return losses.composite(weights, out["pmf"], out["log_pmf"], out["cdf"], p, c)

    batch, patience, max_epochs = int(tr.batch_size), int(tr.patience), int(tr.max_epochs)
    if batch < 1 or max_epochs < 1 or patience < 1:
        raise FeederError("trainer.batch_size, max_epochs and patience must be >= 1")
    best_val, best_epoch, best_state = float("inf"), 0, copy.deepcopy(net.state_dict())
    history: list[dict] = []
    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(range(1, max_epochs + 1), desc=f"train {spec.name}", disable=not show, file=sys.stderr)
    for epoch in bar:
        train_loss = _train_epoch(net, opt, loss_of, fit_t, batch, gen, spec.name, epoch)
        net.eval()
        with torch.no_grad():
            val_loss, parts = loss_of(xv, pv, cv, lpv)
        val_loss = float(val_loss)
        if not np.isfinite(val_loss):
            raise FeederError(f"{spec.name}: non-finite validation loss at epoch {epoch}")
        history.append(
            {
                "epoch": epoch,
                "train_loss": train_loss,
                "val_loss": val_loss,
                **{f"val_{k}": float(v) for k, v in parts.items()},
            }
        )
        bar.set_postfix(val=f"{val_loss:.4g}")
        if val_loss < best_val:
            best_val, best_epoch, best_state = val_loss, epoch, copy.deepcopy(net.state_dict())
        elif epoch - best_epoch >= patience:
            break
    net.load_state_dict(best_state)
    return history, best_epoch, best_val


def fit(
    cfg, data: dict[str, np.ndarray], train_mask: np.ndarray, seed: int | None = None, progress: bool | None = None
) -> Fitted:
    """Train the model of ``cfg.model`` on the rows in ``train_mask`` (scaler and PCA fit on
    them, a ``trainer.val_fraction`` carve-out of them for early stopping)."""
    from feeder.learn.models import TrainedModel

    t0 = time.perf_counter()
    tr = cfg.trainer
    seed = int(cfg.seed if seed is None else seed)
    setup_torch(tr.threads)
    if str(tr.optimizer).lower() != "adam":
        raise FeederError(f"trainer.optimizer {tr.optimizer!r}: only adam is implemented")
    train_mask = np.asarray(train_mask, dtype=bool)
    rows = np.flatnonzero(train_mask)
    fit_rows, val_rows = validation_split(rows, float(tr.val_fraction), seed, "trainer.val_fraction")
    spec, weights = _model_spec(cfg, data["pmf"].shape[1])
    scaler, x_all, pca = _model_inputs(spec, data, train_mask, rows)
    net = _init_net(spec, pca, data, rows, seed, cfg.get("prior"))
    history, best_epoch, best_val = _train_epochs(
        cfg, net, spec, weights, x_all, data, fit_rows, val_rows, seed, progress
    )
    return Fitted(
        model=TrainedModel(net, scaler, str(data.get("label_frame", "part"))),
        history=history,
        best_epoch=best_epoch,
        best_val_loss=best_val,
        train_s=time.perf_counter() - t0,
        n_fit=int(fit_rows.size),
        n_val=int(val_rows.size),
        pca_components=None if pca is None else pca.n_components,
        pca_requested=None if pca is None else pca.requested,
    )


def split_metrics(model, data: dict[str, np.ndarray]) -> dict[str, float]:
    """Mean CDF R² and W1 of the post-processed predictions on every split present."""
    from feeder.labels.grid import SPLITS
    from feeder.labels.metrics import r2_cdf, w1

    _, cdf = model.predict_rows(data)
    out: dict[str, float] = {}
    for split in SPLITS:
        mask = data["split"] == split
        if mask.any():
            out[f"r2_{split}"] = float(r2_cdf(data["cdf"][mask], cdf[mask]).mean())
            out[f"w1_{split}"] = float(w1(data["cdf"][mask], cdf[mask]).mean())
    return out


def train(cfg) -> dict:
    """Train ``cfg.model`` on the ``train`` rows of ``cfg.paths.dataset`` and write the model
    directory ``cfg.paths.out``. Returns the metrics written to ``metrics.json``."""
    import pandas as pd
    from omegaconf import OmegaConf

    from feeder.io import write_csv, write_json, write_text
    from feeder.labels.dataset import load_dataset

    data = load_dataset(cfg.paths.dataset)
    train_mask = data["split"] == "train"
    if not train_mask.any():
        raise FeederError(f"{cfg.paths.dataset}: no rows with split 'train'")
    fitted = fit(cfg, data, train_mask)
    metrics = {
        "model": str(cfg.model.name),
        "seed": int(cfg.seed),
        "train_s": fitted.train_s,
        "best_epoch": fitted.best_epoch,
        "epochs_run": len(fitted.history),
        "best_val_loss": fitted.best_val_loss,
        "n_fit": fitted.n_fit,
        "n_val": fitted.n_val,
        "pca_components": fitted.pca_components,
        "pca_capped": bool(fitted.pca_components is not None and fitted.pca_components < fitted.pca_requested),
        **split_metrics(fitted.model, data),
    }
    out = Path(cfg.paths.out)
    write_text(out / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))
    write_csv(out / "history.csv", pd.DataFrame(fitted.history))
    write_json(out / "metrics.json", metrics)
    fitted.model.save(out)  # model.pt last: it is the workflow's completion marker
    return metrics


# ----------------------------------------------------------------------------------------------
# CLI (Hydra)
# ----------------------------------------------------------------------------------------------
def check_overrides(argv: list[str]) -> None:
    """The arguments of ``feeder train`` that are neither options (``--help``, ``-m``, ``--cfg job``
    …) nor option values, parsed as Hydra overrides first: a bad one is a one-line
    :class:`FeederError` (Hydra's own command line prints its traceback for it)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    takes_value = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name", "-cn"}
    takes_value |= {"--config-dir", "-cd", "--info", "-i", "--experimental-rerun"}
    words = [a for i, a in enumerate(argv) if not a.startswith("-") and (i == 0 or argv[i - 1] not in takes_value)]
    parser = OverridesParser.create()
    for word in words:
        try:
            parser.parse_overrides([word])
        except OverrideParseException:
            raise FeederError(
                f"{word!r} is not an override of the form key=value (e.g. model=m3); "
                "`feeder train --help` lists the groups and settings"
            ) from None


def main(argv: list[str]) -> int:
    """Run Hydra's command line on ``argv`` (overrides, ``-m`` for multiruns, ``--cfg job`` …)."""
    import hydra

    errors: list[FeederError] = []

    @hydra.main(version_base="1.3", config_path=hydra_config_dir(), config_name=CONFIG_NAME)
    def _app(cfg) -> None:
        try:
            metrics = train(cfg)
        except FeederError as err:  # reported after Hydra returns, as one line
            errors.append(err)
            return
        print(json.dumps(metrics, sort_keys=True))

    check_overrides(argv)
    saved = sys.argv
    sys.argv = ["feeder-train", *argv]
    try:
        _app()
    finally:
        sys.argv = saved
    if errors:
        raise errors[0]
    return 0
