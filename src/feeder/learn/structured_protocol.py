"""``feeder structured``: train and score the structured predictor under a protocol a reviewer can trust.

The predictor is :mod:`feeder.learn.structured` (issue #39, items 2 and 3).

* **Locked parts**: ``protocol.locked_fraction`` of the library's parts, ranked by
  sha256(seed:locked:part), take part in no fit and no choice; one model trained on every other
  configuration scores them once, at the end (``unseen_locked``).
* **Unseen parts**: the dataset's GroupKFold folds over the other parts (``unseen_groupkfold``).
* **Known parts at new angles** (``test``) and **Fences** (``fences``): ``protocol.main_repeats``
  Main splits; repeat 0 is the dataset's own Test split, the others hold out
  ``protocol.test_fraction`` of the Main rows (seeded by repeat). Each repeat trains on every
  non-locked configuration outside its Test rows and the Fences rows and scores both.
* Inside every fit, ``protocol.val_part_fraction`` of its training *parts* are validation rows:
  early stopping (patience in optimiser steps) and the choice among the ``search`` settings, by
  circular W1 (the ok head by its mean absolute error). The chosen setting is then trained with
  ``seeds`` seeds, whose per-row metrics are averaged.
* Baselines on the same rows: the analytic PMF, the analytic prior (σ, λ fitted on the fit's
  training rows, grids of ``config/hydra/train.yaml``), the training-mean PMF, and Model 3 where
  its predictions are given; the ok mass against the analytic ok mass and the training-mean ok
  share. 95 % paired bootstrap intervals over parts (unseen) or configurations (Test, Fences)
  (:func:`feeder.learn.evaluate.paired_bootstrap`).

Writes ``<out-dir>/structured_rows.csv`` (one row per configuration, predictor and seed: every
later statistic needs no rerun), ``structured_protocol.csv`` / ``.md`` (the comparisons) and
``structured_choices.csv`` (per fit: the chosen setting, its steps and validation scores).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.learn.splits import derived_seed, pick_parts, resplit_rows

log = logging.getLogger(__name__)

STRUCTURED = "structured"
ENSEMBLE = "structured_ensemble"  # the seeds' PMFs averaged: what the shipped predictor answers
ANALYTIC = "analytic_pmf"
PRIOR = "analytic_prior"
MEAN = "mean_pmf"
M3 = "m3"
GATED = "neighbour_gated"  # the part's nearest labelled angle within a gate, else the analytic PMF
FIT_KINDS = ("groupkfold", "main", "locked")  # the protocol's fits (protocol.fits runs some of them)
COMPOSED = "composed"  # the part's one-fence maps composed (model.composed; else the analytic PMF)
DROPS = "drops"  # the label of the configuration's own few start-grid drops (model.drops > 0)
CALIBRATED = "analytic_calibrated"  # the analytic model calibrated on the part's training labels (calibration)
GATED_CALIBRATED = "neighbour_gated_calibrated"  # the gated neighbour, else the calibrated analytic PMF
UNBLENDED = "structured_unblended"  # the seeds' PMFs averaged before the blend (structured_blend; Main fits)


# ----------------------------------------------------------------------------------------------
# One fit: search, early stopping and seeds inside the training rows
# ----------------------------------------------------------------------------------------------
def _settings(cfg):
    from feeder.learn.structured import NetSettings, TrainSettings

    m, t = cfg.model, cfg.train

    def net(hp):
        return NetSettings(
            int(hp.hidden),
            float(m.max_offset_deg),
            float(m.sigma_min_deg),
            float(m.sigma_init_deg),
            float(m.sigma_max_deg),
            str(hp.get("kind", "candidates")),
            str(m.start),
            float(m.neighbour_start_logit),
        )

    def train(weight_decay):
        return TrainSettings(
            float(t.lr), float(weight_decay), int(t.max_steps), int(t.eval_every), int(t.patience_steps)
        )

    return net, train


def fit_protocol(arrays: dict, train: np.ndarray, cfg, key: str, known: bool = True) -> dict:
    """Fit the structured predictor on the configurations ``train`` (a boolean mask over
    ``arrays``; kept rows train the PMF, all of them the ok head): validation parts, the search
    and the seeds, all derived from ``cfg.seed`` and ``key``. Returns the fitted seeds and what
    predicting needs (input scaling ``x_mean``/``x_sd``, training-mean PMF, the chosen network's
    ``settings``) with the choice made.

    ``known``: the fit is scored on parts it has labels of (Test, Fences), so a validation row sees
    its part's other validation rows as neighbours; otherwise (unseen parts) validation rows see
    none, as the scored parts will not, and the choice and early stopping mirror that."""
    from feeder.learn.structured import fit
    from feeder.learn.structured_data import neighbour_rows, stack_rows

    refit_on(cfg)  # bad settings: an error before any training
    cross_only(cfg)
    fences_specialist(cfg)
    base = int(cfg.seed)
    val_parts = pick_parts(arrays["part"][train], float(cfg.protocol.val_part_fraction), derived_seed(base, key), "val")
    is_val = np.isin(arrays["part"], list(val_parts))
    pool = train  # the scored rows' neighbours: every training row, whatever the network trains on
    unused = unused_parts(arrays["part"][train & ~is_val], fit_part_fraction(cfg), derived_seed(base, key))
    train = train & ~np.isin(arrays["part"], list(unused))
    kept = arrays["kept"]
    fit_rows = np.flatnonzero(train & kept & ~is_val)
    val_rows = np.flatnonzero(train & kept & is_val)
    fit_ok = np.flatnonzero(train & ~is_val)
    val_ok = np.flatnonzero(train & is_val)
    # the part's neighbouring labels: a fit row sees the other fit rows, a validation row the other
    # rows of its own (validation) part, a scored row every training row (as a user's known part)
    k, cross = neighbour_count(cfg), neighbour_count(cfg, "cross_neighbours")
    nb_opts = neighbour_options(cfg)

    def inputs(pool, hide_same=False):
        return pool_inputs(arrays, pool, cfg, hide_same)

    a_fit = inputs(train & ~is_val)
    a_val = inputs(train & is_val & bool(known))
    x = a_fit["x"]
    mu, sd = x[fit_ok].mean(axis=0), x[fit_ok].std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    scaled, scaled_val = dict(a_fit, x=(x - mu) / sd), dict(a_val, x=(a_val["x"] - mu) / sd)
    a_eval = inputs(pool)
    scaled_eval = dict(a_eval, x=(a_eval["x"] - mu) / sd)
    # model.cross_only_copies: each fit row with labels of its own type combination and of its
    # downstream fence type in another trains twice, once as if it had only the latter (a Fences row)
    train_rows, copies = fit_rows, np.zeros(0, dtype=np.int64)
    if cross_only_copies(cfg) and known and k > 0 and cross > 0:
        idx, _ = neighbour_rows(arrays, train & ~is_val, k, cross)
        both = (idx[:, :k] >= 0).any(axis=1) & (idx[:, k:] >= 0).any(axis=1)
        copies = fit_rows[both[fit_rows]]
        a_hidden = inputs(train & ~is_val, hide_same=True)
        scaled = stack_rows(scaled, dict(a_hidden, x=(a_hidden["x"] - mu) / sd))
        train_rows = np.concatenate([fit_rows, copies + len(arrays["part"])])
    mean_pmf = arrays["pmf"][fit_rows].mean(axis=0)
    net, tr = _settings(cfg)
    ok_train = tr(float(cfg.train.ok_weight_decay))
    tried = []
    for i, hp in enumerate(cfg.search):
        seed = derived_seed(base, key, "seed", 0)
        f = fit(
            scaled,
            train_rows,
            val_rows,
            fit_ok,
            val_ok,
            mean_pmf,
            net(hp),
            tr(hp.weight_decay),
            seed,
            ok_train,
            scaled_val,
        )
        tried.append((f.val_cw1, i, f))
    best_cw1, best_i, first = min(tried, key=lambda t: (t[0], t[1]))
    hp = cfg.search[best_i]
    fits = [first]
    for s in range(1, int(cfg.seeds)):
        seed = derived_seed(base, key, "seed", s)
        fits.append(
            fit(
                scaled,
                train_rows,
                val_rows,
                fit_ok,
                val_ok,
                mean_pmf,
                net(hp),
                tr(hp.weight_decay),
                seed,
                ok_train,
                scaled_val,
            )
        )
    # train.refit: each seed trained again on the fit and validation rows for the steps early
    # stopping chose it, from the same initial weights (the validation parts then train too)
    n_refit, early = 0, {"fits": fits, "x_mean": mu, "x_sd": sd, "mean_pmf": mean_pmf}
    if refit_on(cfg):
        r = _refitted(arrays, train, fits, inputs, net(hp), tr(hp.weight_decay), ok_train, base, key)
        fits, scaled, train_rows, mean_pmf, mu, sd = r["fits"], r["scaled"], r["rows"], r["mean_pmf"], r["mu"], r["sd"]
        a_eval = inputs(pool)
        scaled_eval, n_refit = dict(a_eval, x=(a_eval["x"] - mu) / sd), int(train_rows.size)
    choice = {
        "fit": key,
        "kind": str(hp.get("kind", "candidates")),
        "hidden": int(hp.hidden),
        "weight_decay": float(hp.weight_decay),
        "train_parts": int(len(set(arrays["part"][train]))),
        "unused_parts": len(unused),
        "val_parts": len(val_parts),
        "fit_rows": int(fit_rows.size),
        "val_rows": int(val_rows.size),
        "cross_only_copies": int(copies.size),
        "cross_only": cross_only(cfg),
        "refit_rows": n_refit,
        **{f"search{i}_val_cw1": float(t[0]) for i, t in enumerate(sorted(tried, key=lambda t: t[1]))},
        "val_cw1": float(np.mean([f.val_cw1 for f in early["fits"]])),
        "val_ok_mae": float(np.mean([f.val_ok_mae for f in early["fits"]])),
        "steps": float(np.mean([f.steps for f in early["fits"]])),
        "ok_steps": float(np.mean([f.ok_steps for f in early["fits"]])),
        "neighbours": k,
        "cross_neighbours": cross,
        "neighbour_basins": int(nb_opts["basins"]),
        "neighbour_candidates": int(nb_opts["candidates"]),
        "drops": drop_count(cfg),
        "composed": composed_on(cfg),
        "val_neighbours": bool(known and (k + cross > 0 or composed_on(cfg))),
    }
    return {
        "fits": fits,
        "scaled": scaled_eval,
        "mean_pmf": mean_pmf,
        "choice": choice,
        "train": pool,
        "train_inputs": scaled,  # what the networks trained on (with cross-only copies: stacked after the rows)
        "train_rows": train_rows,
        "x_mean": mu,
        "x_sd": sd,
        "settings": net(hp),
        "early": early,  # the early-stopped seeds and their scaling and mean PMF (the same as above without a refit)
        "val_rows": val_rows,  # the validation rows (kept) and the early seeds' inputs of them
        "val_inputs": scaled_val,
        "val_pool": train & is_val if known else train & ~is_val,  # the labels a validation row sees
    }


def pool_inputs(arrays: dict, pool, cfg, hide_same: bool = False) -> dict:
    """``arrays`` with every row's inputs from the labels of the rows ``pool`` (a boolean mask):
    the part's neighbours there (``hide_same``, and always with ``model.cross_only``: none of its
    own fence-type combination, as a Fences row), their composition (``model.composed``) and the
    row's own drops (when ``arrays`` holds them)."""
    from feeder.learn.structured_data import with_composed, with_drops, with_neighbours

    k, cross = neighbour_count(cfg), neighbour_count(cfg, "cross_neighbours")
    near, nb_opts = float(cfg.model.neighbour_near_deg), neighbour_options(cfg)
    hide_same = bool(hide_same) or cross_only(cfg)
    a = with_neighbours(arrays, pool, k, near, cross, **nb_opts, hide_same=hide_same)
    if composed_on(cfg):
        a = with_composed(a, pool, near, float(cfg.model.get("composed_start_logit", 0.0)))
    if "drop_pmf" not in arrays:
        return a
    return with_drops(a, drop_count(cfg, "drop_candidates"), nb_opts["merge_deg"], nb_opts["window_deg"])


def _refitted(arrays: dict, train, fits, inputs, net, t, ok_train, base: int, key: str) -> dict:
    """``fits`` (early-stopped, one per seed) trained again by :func:`feeder.learn.structured.refit`
    on every kept row of ``train`` (the ok head on every row), each for its own step counts and
    from its own seed. The inputs (``inputs(pool)``), their scaling and the training-mean PMF are
    recomputed on those rows: every row sees the others as neighbours, as a scored row does.
    Returns the refitted seeds (``fits``), their scaled inputs and kept rows (``scaled``,
    ``rows``), ``mean_pmf`` and the scaling ``mu``, ``sd``."""
    from feeder.learn.structured import refit

    rows = np.flatnonzero(train & arrays["kept"])
    ok_rows = np.flatnonzero(train)
    a = inputs(train)
    mu, sd = a["x"][ok_rows].mean(axis=0), a["x"][ok_rows].std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    scaled = dict(a, x=(a["x"] - mu) / sd)
    mean_pmf = arrays["pmf"][rows].mean(axis=0)
    refits = [
        refit(
            scaled, rows, ok_rows, mean_pmf, net, t, derived_seed(base, key, "seed", s), f.steps, f.ok_steps, ok_train
        )
        for s, f in enumerate(fits)
    ]
    return {"fits": refits, "scaled": scaled, "rows": rows, "mean_pmf": mean_pmf, "mu": mu, "sd": sd}


def refit_on(cfg) -> bool:
    """``train.refit`` (default false) as a bool; a one-line FeederError if it is no bool or is
    combined with ``model.cross_only_copies`` (a refit trains no copies)."""
    value = config_flag(cfg, "train", "refit")
    if value and cross_only_copies(cfg):
        raise FeederError("train.refit and model.cross_only_copies cannot be combined")
    return value


def config_flag(cfg, group: str, key: str) -> bool:
    """``cfg.<group>.<key>`` (false when absent) as a bool; a one-line FeederError unless it is one."""
    value = cfg[group].get(key, False)
    if not isinstance(value, bool):
        raise FeederError(f"{group}.{key} must be true or false, got {value!r}")
    return value


def cross_only_copies(cfg) -> bool:
    """``model.cross_only_copies`` (default false) as a bool; a one-line FeederError otherwise."""
    return config_flag(cfg, "model", "cross_only_copies")


def cross_only(cfg) -> bool:
    """``model.cross_only`` (default false) as a bool: every row reads only its part's labels of other
    fence-type combinations (the cross neighbours), as a Fences row must, in training, validation
    and scoring. A one-line FeederError if it is no bool or is combined with
    ``model.cross_only_copies`` (whose copies would then be their rows)."""
    value = config_flag(cfg, "model", "cross_only")
    if value and cross_only_copies(cfg):
        raise FeederError("model.cross_only and model.cross_only_copies cannot be combined")
    return value


def fences_specialist(cfg) -> bool:
    """``model.fences_specialist`` (true in ``config/hydra/structured.yaml``) as a bool: a fit
    scored on known parts also fits the ``model.cross_only`` network, which answers the rows with
    no label of their own fence-type combination among the fit's training rows. Off under
    ``model.cross_only`` (every row is then the specialist's already). A one-line FeederError if it
    is no bool."""
    value = config_flag(cfg, "model", "fences_specialist")
    return value and not cross_only(cfg)


def specialist_cfg(cfg):
    """``cfg`` with ``model.cross_only`` on and ``model.fences_specialist`` and
    ``model.cross_only_copies`` off: the specialist's (its rows read only cross neighbours, so
    copies without their own combination would be their rows)."""
    from omegaconf import OmegaConf

    out = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    out.model.cross_only, out.model.fences_specialist, out.model.cross_only_copies = True, False, False
    return out


def without_own_label(arrays: dict, pool, rows) -> np.ndarray:
    """Of ``rows``: whether the kept rows of ``pool`` hold no label of the row's part and fence-type
    combination (a Fences row's situation; the rows the specialist answers)."""
    from feeder.learn.structured_data import nearest_rows, neighbour_source

    source, pool = neighbour_source(arrays, pool)  # with the mirrored labels (model.mirror_labels)
    _, dist = nearest_rows(source["part"], source["config_id"], pool, rows, 1)
    return ~np.isfinite(dist[:, 0])


def fit_part_fraction(cfg) -> float:
    """``protocol.fit_part_fraction`` (default 1): the share of a fit's non-validation parts its
    network trains on; the rest train nothing and stay its scored rows' neighbours. Below 1 it
    draws a learning curve on the same validation parts. A one-line FeederError outside (0, 1]."""
    value = cfg.protocol.get("fit_part_fraction", 1.0)
    try:
        fraction = float(value)
    except (TypeError, ValueError):
        raise FeederError(f"protocol.fit_part_fraction: {value!r} is not a number in (0, 1]") from None
    if not 0.0 < fraction <= 1.0:
        raise FeederError(f"protocol.fit_part_fraction: {value!r} is not a number in (0, 1]")
    return fraction


def unused_parts(parts, fraction: float, seed: int) -> set[str]:
    """The parts a fit leaves out of training at ``fraction`` (:func:`fit_part_fraction`): none at
    1, else the first ``1 - fraction`` of them in the seeded ranking of
    :func:`feeder.learn.splits.pick_parts`, so a smaller fraction leaves out a superset."""
    if fraction >= 1.0:
        return set()
    return pick_parts(parts, 1.0 - fraction, seed, "unused")


def neighbour_count(cfg, key: str = "neighbours") -> int:
    """``model.neighbours`` (or ``model.cross_neighbours``): how many of the part's nearest labelled
    configurations of the same fence types (or of other types under the same downstream fence) the
    predictor reads (:func:`feeder.learn.structured_data.neighbour_block`)."""
    k = cfg.model[key]
    if isinstance(k, bool) or not isinstance(k, int) or k < 0:
        raise FeederError(f"model.{key} must be an integer >= 0, got {k!r}")
    return int(k)


def drop_count(cfg, key: str = "drops") -> int:
    """An optional count of ``model`` (0 when absent; a one-line FeederError unless an integer
    >= 0): ``drops`` (the configuration's own start-grid drops read; 0: none), ``drop_candidates``
    (the largest basins of their label made candidates), ``neighbour_basins``,
    ``neighbour_candidates``."""
    return neighbour_count(cfg, key) if key in cfg.model else 0


def composed_on(cfg) -> bool:
    """``model.composed`` (false when absent): two-fence rows read the composition of their part's
    one-fence maps (:func:`feeder.learn.structured_data.with_composed`). A one-line FeederError
    unless it is a boolean."""
    return config_flag(cfg, "model", "composed")


def neighbour_options(cfg) -> dict:
    """The keyword arguments of :func:`feeder.learn.structured_data.with_neighbours` beyond the
    neighbour counts: ``model.neighbour_basins``, ``model.neighbour_candidates`` (each 0 when
    absent) and the candidates' ``merge_deg`` and ``window_deg``, and ``model.neighbour_signed``
    (absent: false; :func:`neighbour_signed`)."""
    return {
        "basins": drop_count(cfg, "neighbour_basins"),
        "candidates": drop_count(cfg, "neighbour_candidates"),
        "merge_deg": float(cfg.candidates.merge_deg),
        "window_deg": float(cfg.candidates.window_deg),
        "signed": neighbour_signed(cfg),
    }


def neighbour_signed(cfg) -> bool:
    """``model.neighbour_signed`` (absent: false), checked: whether each neighbour's signed angle
    steps are inputs (:func:`feeder.learn.structured_data.signed_steps`)."""
    value = cfg.model.get("neighbour_signed", False)
    if not isinstance(value, bool):
        raise FeederError(f"model.neighbour_signed must be true or false, got {value!r}")
    return value


def baseline_pmfs(arrays: dict, train: np.ndarray, rows, prior_grids) -> dict[str, np.ndarray]:
    """The analytic PMF, the analytic prior (σ, λ fitted on the kept ``train`` rows) and the
    training-mean PMF of ``rows``."""
    from feeder.learn.prior import blend, fit_blend
    from feeder.learn.structured_calibration import model_analytic

    kept_train = train & arrays["kept"]
    mean_pmf = arrays["pmf"][kept_train].mean(axis=0)
    analytic = model_analytic(arrays)  # the model's own, not the calibrated one
    kept = arrays["kept"]
    best = fit_blend(arrays["pmf"][kept], analytic[kept], train[kept], prior_grids.sigmas_bins, prior_grids.weights)
    return {
        ANALYTIC: analytic[rows],
        PRIOR: blend(analytic[rows], mean_pmf, best.sigma_bins, best.weight),
        MEAN: np.broadcast_to(mean_pmf, (len(rows), mean_pmf.size)),
    }


def score_rows(
    arrays: dict, fitted: dict, rows, experiment: str, repeat: int, prior_grids, extra=None, blend=None
) -> list[dict]:
    """Long rows (one per configuration, predictor and seed) of the structured predictor's seeds
    and the baselines on ``rows`` (kept and excluded; PMF metrics on kept rows only). ``blend``:
    ``(weight or one weight per row, fallback PMFs of rows)``
    (:mod:`feeder.learn.structured_blend`): each seed answers
    blended, and the seeds' mean unblended is scored too (the same as the ensemble at weight 1)."""
    from feeder.labels.metrics import circular_w1, r2_cdf
    from feeder.learn.structured import predict
    from feeder.learn.structured_blend import blended

    rows = np.asarray(rows)
    kept = arrays["kept"][rows]
    cdf = arrays["cdf"][rows]
    preds = []
    for s, f in enumerate(fitted["fits"]):
        pmf, ok = predict(f, fitted["scaled"], rows, fitted["mean_pmf"])
        preds.append((STRUCTURED, s, pmf, ok))
    if blend is not None:  # the seeds' mean alone is scored beside, whatever the weight
        extra = {**(extra or {}), UNBLENDED: np.mean([p[2] for p in preds], axis=0)}
        if np.any(np.asarray(blend[0], np.float64) != 1.0):
            preds = [(n, s, blended(pmf, blend[1], blend[0]), ok) for n, s, pmf, ok in preds]
    if len(preds) > 1:  # the shipped answer (feeder.learn.structured_shipped) averages its seeds' PMFs
        preds.append((ENSEMBLE, -1, np.mean([p[2] for p in preds], axis=0), np.mean([p[3] for p in preds], axis=0)))
    train = fitted["train"]
    ok_mean = float(arrays["ok"][train].mean())
    for name, pmf in baseline_pmfs(arrays, train, rows, prior_grids).items():
        ok = arrays["analytic_ok"][rows] if name == ANALYTIC else np.full(rows.size, ok_mean)
        preds.append((name, -1, pmf, ok if name != PRIOR else arrays["analytic_ok"][rows]))
    for name, pmf in (extra or {}).items():
        preds.append((name, -1, pmf, np.full(rows.size, np.nan)))
    out = []
    for name, seed, pmf, ok in preds:
        pc = np.cumsum(pmf, axis=1)
        cw1 = np.where(kept, circular_w1(cdf, pc), np.nan)
        r2 = np.where(kept, r2_cdf(cdf, pc), np.nan)
        for j, i in enumerate(rows):
            out.append(
                {
                    "experiment": experiment,
                    "repeat": repeat,
                    "part": arrays["part"][i],
                    "config_id": arrays["config_id"][i],
                    "split": arrays["split"][i],
                    "kept": bool(kept[j]),
                    "predictor": name,
                    "seed": seed,
                    "cw1": float(cw1[j]),
                    "r2": float(r2[j]),
                    "ok_true": float(arrays["ok"][i]),
                    "ok_pred": float(ok[j]),
                }
            )
    return out


# ----------------------------------------------------------------------------------------------
# The experiments
# ----------------------------------------------------------------------------------------------
def protocol_jobs(arrays: dict, cfg) -> tuple[list[tuple], set]:
    """The protocol's fits in their order (module doc): ``(kind, key, index, train, scored)`` per
    fit, with ``scored`` the rows it scores by experiment; and the locked parts."""
    base = int(cfg.seed)
    kinds = fit_kinds(cfg)
    parts = arrays["part"]
    locked = pick_parts(parts, float(cfg.protocol.locked_fraction), base, "locked")
    is_locked = np.isin(parts, list(locked))
    jobs = []
    # unseen parts: GroupKFold over the non-locked library
    for fold in np.unique(arrays["group_fold"]):
        held = (arrays["group_fold"] == fold) & ~is_locked
        train = (arrays["group_fold"] != fold) & ~is_locked
        jobs.append(("groupkfold", f"groupkfold:{fold}", int(fold), train, {"unseen_groupkfold": held}))
    # known parts at new angles, and Fences: repeated Main splits
    main = np.isin(arrays["split"], ["train", "test"]) & ~is_locked
    fences = (arrays["split"] == "fences") & ~is_locked
    for r in range(int(cfg.protocol.main_repeats)):
        if r == 0:
            test = main & (arrays["split"] == "test")
        else:
            test = np.zeros(len(parts), dtype=bool)
            test[
                resplit_rows(np.flatnonzero(main), float(cfg.protocol.test_fraction), derived_seed(base, "main", r))
            ] = True
        jobs.append(("main", f"main:{r}", r, ~is_locked & ~test & ~fences, {"test": test, "fences": fences}))
    # the locked parts, once
    jobs.append(("locked", "locked", 0, ~is_locked, {"unseen_locked": is_locked}))
    return [job for job in jobs if job[0] in kinds], locked


def fit_kinds(cfg) -> list[str]:
    """``protocol.fits`` (all of :data:`FIT_KINDS` when absent): the kinds of fit to run. A one-line
    FeederError unless it is a non-empty list of them."""
    kinds = list(cfg.protocol.get("fits", FIT_KINDS))
    if not kinds or set(kinds) - set(FIT_KINDS):
        raise FeederError(f"protocol.fits must be a non-empty list of {', '.join(FIT_KINDS)}, got {kinds}")
    return kinds


def check_count(value, key: str) -> int:
    """A count setting (``train.workers``, ``seeds``) checked: a one-line FeederError naming ``key``
    unless it is an integer >= 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise FeederError(f"{key} must be an integer >= 1, got {value!r}")
    return int(value)


def check_workers(workers) -> int:
    """``train.workers`` checked: a one-line FeederError unless it is an integer >= 1."""
    return check_count(workers, "train.workers")


_SHARED: dict = {}  # what a forked worker of run_protocol reads (arrays are not pickled per job)


def run_job(job: tuple, arrays: dict, cfg, prior_grids, m3_pmf: dict | None, locked: set) -> tuple[list, dict]:
    """One fit of :func:`protocol_jobs` and its scores: ``(long rows, choice)``. Every seed derives
    from ``cfg.seed`` and the fit's key, so the result does not depend on the process it runs in."""
    from feeder.learn.structured_blend import blend_choice, blend_weights, fallback_choice, fit_blend, row_weights
    from feeder.learn.structured_calibration import calibration_network, calibration_settings, with_calibration

    kind, key, index, train, scored = job
    t0 = time.perf_counter()
    base_arrays = calibrated = arrays
    if kind == "main":  # calibration.modes: the analytic PMF calibrated on each part's training labels
        calibrated = with_calibration(arrays, train, calibration_settings(cfg)[1])
        if calibration_network(cfg):  # the network's own component and start too
            arrays = calibrated
    fitted = fit_protocol(arrays, train, cfg, key, known=kind == "main")
    specialist = None
    if kind == "main" and fences_specialist(cfg):  # answers the rows with no label of their own combination
        specialist = fit_protocol(arrays, train, specialist_cfg(cfg), f"{key}:specialist", known=True)
    blends = {}  # blend.weights: each network's answer blended with its fallback (known parts; [1.0]: off)
    if kind == "main" and blend_weights(cfg) != [1.0]:
        blends[id(fitted)] = fit_blend(fitted, arrays, cfg, train, own_labels=not cross_only(cfg))
        if specialist is not None:
            blends[id(specialist)] = fit_blend(specialist, arrays, specialist_cfg(cfg), train, own_labels=False)

    def blend_of(f, idx):
        b = blends.get(id(f))
        if b is None:
            return None
        fallback, from_label = fallback_choice(arrays, train, idx, b["gate_deg"])
        return row_weights(b, from_label), fallback

    rows, n_calibrated = [], 0
    for experiment, mask in scored.items():
        idx = np.flatnonzero(mask)
        extra = {DROPS: arrays["drop_pmf"][idx]} if "drop_pmf" in arrays else {}
        if kind == "main":
            gates = list(cfg.neighbour.gates_deg)
            extra[GATED] = gated_neighbour(base_arrays, train, idx, gates)
            if "calibration_mode" in calibrated:
                extra[CALIBRATED] = calibrated["analytic"][idx]
                extra[GATED_CALIBRATED] = gated_neighbour(calibrated, train, idx, gates)
                n_calibrated += int((calibrated["calibration_mode"][idx] > 0).sum())
            if composed_on(cfg):  # the composition alone (else the analytic PMF)
                from feeder.learn.structured_data import composed_block

                extra[COMPOSED] = composed_block(arrays, train, float(cfg.model.neighbour_near_deg))[1][idx, 0]
            if m3_pmf is not None and index == 0:
                nan_row = np.full(arrays["pmf"].shape[1], np.nan)
                keys = zip(arrays["part"][idx], arrays["config_id"][idx], strict=True)
                extra[M3] = np.stack([m3_pmf.get((str(p), str(c)), nan_row) for p, c in keys])
        if specialist is None:
            rows += score_rows(arrays, fitted, idx, experiment, index, prior_grids, extra, blend_of(fitted, idx))
            continue
        theirs = without_own_label(arrays, train, idx)
        for mine, f in ((~theirs, fitted), (theirs, specialist)):
            if mine.any():
                part_extra = {name: pmf[mine] for name, pmf in extra.items()}
                blend = blend_of(f, idx[mine])
                rows += score_rows(arrays, f, idx[mine], experiment, index, prior_grids, part_extra, blend)
    choice = {**fitted["choice"], "seconds": time.perf_counter() - t0}
    if id(fitted) in blends:
        choice.update(blend_choice(blends[id(fitted)]))
    if "calibration_mode" in calibrated:  # how many scored rows a mode other than the base answers
        choice["calibrated_rows"] = n_calibrated
        choice["calibrated_network"] = calibration_network(cfg)
    if specialist is not None:
        choice.update({f"specialist_{k}": v for k, v in specialist["choice"].items() if k != "fit"})
        if id(specialist) in blends:
            choice.update({f"specialist_{k}": v for k, v in blend_choice(blends[id(specialist)]).items()})
    if kind == "locked":
        choice["locked_parts"] = " ".join(sorted(locked))
    return rows, choice


def _forked_job(job: tuple) -> tuple[list, dict]:
    import torch

    torch.set_num_threads(int(_SHARED["cfg"].train.threads))
    return run_job(job, **_SHARED)


def run_protocol(arrays: dict, cfg, prior_grids, m3_pmf: dict | None = None, progress=None, workers: int = 1) -> tuple:
    """All experiments of the module doc; returns (long rows, choices). ``m3_pmf``: Model 3's
    PMFs by (part, config_id) for the dataset's Test and Fences rows (trained on its Train rows),
    used in repeat 0 and for Fences. ``workers`` > 1 runs that many fits at once in forked
    processes; the rows and choices are the same, in the same order (only ``seconds`` differ)."""
    check_workers(workers)
    say = progress or (lambda msg: None)
    jobs, locked = protocol_jobs(arrays, cfg)
    state = {"arrays": arrays, "cfg": cfg, "prior_grids": prior_grids, "m3_pmf": m3_pmf, "locked": locked}
    workers = min(int(workers), len(jobs))
    rows, choices = [], []
    if workers == 1:
        results = (run_job(job, **state) for job in jobs)
    else:
        from multiprocessing import get_context

        _SHARED.clear()
        _SHARED.update(state)
        pool = get_context("fork").Pool(workers)
        results = pool.imap(_forked_job, jobs)
    try:
        for job, (job_rows, choice) in zip(jobs, results, strict=True):
            rows += job_rows
            choices.append(choice)
            say(f"{job[1]} ({len(choices)} of {len(jobs)} fits): {choice}")
    finally:
        if workers > 1:
            pool.terminate()
            _SHARED.clear()
    return pd.DataFrame(rows), pd.DataFrame(choices)


def gated_neighbour(arrays: dict, train, rows, gates) -> np.ndarray:
    """The gated neighbour of ``rows`` (:mod:`feeder.learn.neighbour`): the label of the nearest kept
    ``train`` row of the same part and fence types within the gate, else the analytic PMF; the gate
    of ``gates`` chosen on the training rows alone."""
    from feeder.learn.structured_blend import fit_gate, gated_pmfs

    return gated_pmfs(arrays, train, rows, fit_gate(arrays, train, gates))


UNITS = {"unseen_groupkfold": "part", "unseen_locked": "part", "test": "configuration", "fences": "configuration"}
METRICS = (("cw1", -1), ("r2", 1), ("ok_abs_err", -1))


def unit_scores(long: pd.DataFrame, experiment: str, predictor: str, metric: str) -> pd.Series:
    """Per unit (part, or configuration over repeats) the metric of ``predictor`` averaged over
    its seeds and repeats; PMF metrics over kept configurations, the ok error over all."""
    d = long[(long.experiment == experiment) & (long.predictor == predictor)].copy()
    d["ok_abs_err"] = (d.ok_pred - d.ok_true).abs()
    if metric != "ok_abs_err":
        d = d[d.kept]
    per_config = d.groupby(["part", "config_id"])[metric].mean()
    if UNITS[experiment] == "part":
        return per_config.groupby(level="part").mean()
    return per_config


def paired_runs(
    run: pd.DataFrame, base: pd.DataFrame, experiment: str, model: str, bootstrap: dict, by_part: bool = False
) -> dict | None:
    """Two runs' rows (``structured_rows.csv``) paired on ``experiment``'s units both scored with
    ``model``: ``n``, each run's mean circular W1 (``run``, ``base``) and the paired difference
    run − base with its bootstrap interval (``diff``, ``diff_low``, ``diff_high``); None where they
    share no unit. ``by_part``: configurations paired first, then each part's mean taken, so the
    interval resamples parts (a part's configurations are not independent of each other)."""
    mine, theirs = unit_scores(run, experiment, model, "cw1"), unit_scores(base, experiment, model, "cw1")
    if by_part and UNITS[experiment] != "part":
        both = pd.concat([mine, theirs], axis=1, keys=["m", "b"]).dropna()
        mine, theirs = (both[k].groupby(level="part").mean() for k in ("m", "b"))
    pair = _paired(mine, theirs, bootstrap)
    if pair is None:
        return None
    n, run_mean, base_mean, diff, lo, hi = pair
    return {"n": n, "run": run_mean, "base": base_mean, "diff": diff, "diff_low": lo, "diff_high": hi}


def _paired(model: pd.Series, base: pd.Series, bootstrap: dict) -> tuple | None:
    """Two per-unit score series on the units both have: (n, their means, the mean difference
    model − base and its bootstrap interval); None where they share no unit."""
    from feeder.learn.evaluate import paired_bootstrap

    both = pd.concat([model, base], axis=1, keys=["m", "b"]).dropna()
    if both.empty:
        return None
    diff, lo, hi = paired_bootstrap(
        (both.m - both.b).to_numpy(), bootstrap["resamples"], bootstrap["level"], bootstrap["seed"]
    )
    return len(both), float(both.m.mean()), float(both.b.mean()), diff, lo, hi


def comparison_table(long: pd.DataFrame, bootstrap: dict, m3_parts: pd.Series | None = None) -> pd.DataFrame:
    """Per experiment, model, metric and baseline: the model's mean, the baseline's, their paired
    difference with its bootstrap interval over the experiment's units. The models are the
    structured predictor scored seed by seed (``structured``, its seed SD beside it) and, where the
    run has several seeds, their PMFs averaged (``structured_ensemble``: the shipped answer)."""
    out = []
    for experiment in UNITS:
        if experiment not in set(long.experiment):
            continue
        present = set(long[long.experiment == experiment].predictor)
        for name in [m for m in (STRUCTURED, ENSEMBLE) if m in present]:
            for metric, sign in METRICS:
                out += _comparisons(long, experiment, name, metric, sign, present, bootstrap, m3_parts)
    return pd.DataFrame(out)


def _comparisons(long, experiment, name, metric, sign, present, bootstrap, m3_parts) -> list[dict]:
    from feeder.learn.evaluate import verdict

    model = unit_scores(long, experiment, name, metric)
    seeds = long[(long.experiment == experiment) & (long.predictor == name)]
    optional = (UNBLENDED, GATED, CALIBRATED, GATED_CALIBRATED, COMPOSED, M3, DROPS)
    baselines = [ANALYTIC, PRIOR, MEAN] + [b for b in optional if b in present]
    if metric == "ok_abs_err":
        baselines = [ANALYTIC, MEAN]
    series = {b: unit_scores(long, experiment, b, metric) for b in baselines}
    if m3_parts is not None and experiment == "unseen_groupkfold" and metric == "cw1":
        series[M3] = m3_parts
    out = []
    for b, base in series.items():
        pair = _paired(model, base, bootstrap)
        if pair is None:
            continue
        n, model_mean, base_mean, mean, lo, hi = pair
        sd = np.nan
        if metric != "ok_abs_err" and seeds.seed.nunique() > 1:
            per_seed = seeds[seeds.kept].groupby("seed")[metric].mean()
            sd = float(per_seed.std(ddof=1))
        out.append(
            {
                "experiment": experiment,
                "unit": UNITS[experiment],
                "model": name,
                "metric": metric,
                "baseline": b,
                "n": n,
                "structured": model_mean,
                "structured_seed_sd": sd,
                "baseline_value": base_mean,
                "diff": mean,
                "diff_low": lo,
                "diff_high": hi,
                "level": float(bootstrap["level"]),
                "verdict": verdict(lo, hi, sign),
            }
        )
    return out


def neighbour_distances(arrays: dict, cfg) -> pd.DataFrame:
    """For every row a Main fit scores (Test and Fences of each repeat): the angle distance
    (degrees, ``|Δθ1| + |Δθ2|``) of the nearest kept label of the same part and fence types among
    the fit's training rows (:func:`feeder.learn.structured_data.nearest_rows`, the rule of the
    shipped answer's :func:`~feeder.learn.structured_data.nearest_configuration`); inf where there is
    none. ``cross``: whether the part has a training label of the row's downstream (Location 1) fence
    type in another combination (:func:`~feeder.learn.structured_data.nearest_cross_rows`), the other
    neighbour the shipped answer needs (else it answers otherwise)."""
    from feeder.learn.structured_data import nearest_cross_rows, nearest_rows, neighbour_source

    out = []
    for kind, _key, index, train, scored in protocol_jobs(arrays, cfg)[0]:
        if kind != "main":
            continue
        source, pool = neighbour_source(arrays, train)  # with the mirrored labels (model.mirror_labels)
        for experiment, mask in scored.items():
            rows = np.flatnonzero(mask)
            _, dist = nearest_rows(source["part"], source["config_id"], pool, rows, 1)
            cross, _ = nearest_cross_rows(source["part"], source["config_id"], pool, rows, 1)
            out.append(
                pd.DataFrame(
                    {
                        "experiment": experiment,
                        "repeat": int(index),
                        "part": arrays["part"][rows].astype(str),
                        "config_id": arrays["config_id"][rows].astype(str),
                        "neighbour_deg": dist[:, 0],
                        "cross": cross[:, 0] >= 0,
                    }
                )
            )
    columns = ["experiment", "repeat", "part", "config_id", "neighbour_deg", "cross"]
    return pd.concat(out, ignore_index=True)[columns] if out else pd.DataFrame(columns=columns)


def check_edges(edges) -> list[float]:
    """``answer_errors.edges_deg``: increasing finite angles from 0; a one-line FeederError otherwise."""
    try:
        out = [float(e) for e in edges]
    except (TypeError, ValueError):
        raise FeederError(f"answer_errors.edges_deg: a list of angles in degrees, got {edges!r}") from None
    if len(out) < 2 or out[0] != 0.0 or not np.all(np.isfinite(out)) or np.any(np.diff(out) <= 0):
        raise FeederError(f"answer_errors.edges_deg: increasing finite angles from 0, got {edges!r}")
    return out


def error_by_distance(long: pd.DataFrame, distances: pd.DataFrame, edges) -> pd.DataFrame:
    """The structured predictor's circular W1 on the Main fits' scored rows (Test and Fences, kept,
    each row of each repeat once: its seeds' averaged PMF where the run scored it, else the mean over
    seeds) by the distance to its nearest label of the same fence types (:func:`neighbour_distances`),
    in the bins ``[edges[i], edges[i+1])`` (the last one closed) and one more for no such label but
    one of the downstream fence type (``low_deg`` inf; rows with neither are left out, the shipped
    answer is not this predictor's there): the
    error an answer of the shipped predictor may carry at that distance; ``rows`` counts each scored
    row of each repeat. A scored row without a distance (``distances`` from other settings than the
    run's) is a one-line FeederError (pure)."""
    edges = check_edges(edges)
    model = ENSEMBLE if (long.predictor == ENSEMBLE).any() else STRUCTURED
    key = ["experiment", "repeat", "part", "config_id"]
    d = long[(long.predictor == model) & long.kept & long.experiment.isin(["test", "fences"])]
    d = d.groupby(key, as_index=False).cw1.mean().merge(distances, on=key, how="left", validate="one_to_one")
    if d.neighbour_deg.isna().any():
        first = d[d.neighbour_deg.isna()].iloc[0]
        raise FeederError(
            f"{int(d.neighbour_deg.isna().sum())} scored rows have no neighbour distance (e.g. {first.experiment} "
            f"repeat {first.repeat} {first.part} {first.config_id}): the settings (seed, protocol) are not the run's"
        )
    bins = [(lo, hi) for lo, hi in zip(edges[:-1], edges[1:], strict=True)] + [(np.inf, np.inf)]
    out = []
    for lo, hi in bins:
        if np.isinf(lo):
            inside = np.isinf(d.neighbour_deg) & d.cross.astype(bool)
        else:  # the last bin is closed: its upper edge (180: the most |dtheta1| + |dtheta2| of 0-90 grids) is in
            inside = (d.neighbour_deg >= lo) & ((d.neighbour_deg < hi) | ((d.neighbour_deg == hi) & (hi == edges[-1])))
        w = d[inside].cw1
        out.append(
            {
                "low_deg": lo,
                "high_deg": hi,
                "model": model,
                "rows": int(w.size),
                "mean_circular_w1_deg": float(w.mean()) if w.size else np.nan,
                "median_circular_w1_deg": float(w.median()) if w.size else np.nan,
                "p90_circular_w1_deg": float(w.quantile(0.9)) if w.size else np.nan,
            }
        )
    return pd.DataFrame(out)


def m3_part_scores(path) -> pd.Series:
    """Model 3's per-part circular W1 from a GroupKFold table (``results/tables/groupkfold_m3.csv``)."""
    t = pd.read_csv(path)
    t = t[(t.model == "m3") & ~t.group.isin(["all configurations", "over parts"])]
    return t.set_index("group")["cw1_mean"].rename_axis("part")


def m3_predictions(data: dict, model_dirs) -> dict:
    """Model 3's PMFs (averaged over its seeds) of the dataset's Test and Fences rows, by (part,
    config_id)."""
    from feeder.learn.evaluate import load_models

    rows = np.flatnonzero(np.isin(data["split"], ["test", "fences"]))
    pmfs = [m.predict_rows(data, rows)[0] for _, _, m, _ in load_models(model_dirs)]
    mean = np.mean(pmfs, axis=0)
    return {(str(data["part"][i]), str(data["config_id"][i])): mean[j] for j, i in enumerate(rows)}


FIT_EXPERIMENTS = {"groupkfold": ("unseen_groupkfold",), "main": ("test", "fences"), "locked": ("unseen_locked",)}


def fit_kind(fit) -> str:
    """The kind of fit (:data:`FIT_KINDS`) of a choices row's ``fit`` name (``main:1`` -> ``main``)."""
    return str(fit).split(":")[0]


def merge_runs(runs: list[tuple[pd.DataFrame, pd.DataFrame]]) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Several runs' (rows, choices) as one run: each kind of fit (:data:`FIT_KINDS`) comes from the
    last run that holds it, rows and choices alike (a later run, e.g. ``protocol.fits=[main]`` with
    another setting, replaces those fits of an earlier one and keeps the rest). Returns (rows,
    choices, {kind: index of its run}), in the protocol's order of kinds. A one-line FeederError when
    a run's rows and choices disagree on which kinds they hold."""
    source = {}
    for n, (rows, choices) in enumerate(runs):
        row_kinds = {k for k, exps in FIT_EXPERIMENTS.items() if rows.experiment.isin(exps).any()}
        choice_kinds = {fit_kind(f) for f in choices["fit"]}
        if row_kinds != choice_kinds:
            raise FeederError(
                f"run {n + 1}: its rows hold the fits {sorted(row_kinds)} but its choices {sorted(choice_kinds)}"
            )
        source |= dict.fromkeys(row_kinds, n)
    picked = {k: source[k] for k in FIT_KINDS if k in source}  # the protocol's order of kinds
    rows = pd.concat(
        [runs[n][0][runs[n][0].experiment.isin(FIT_EXPERIMENTS[k])] for k, n in picked.items()], ignore_index=True
    )
    choices = pd.concat(
        [runs[n][1][runs[n][1]["fit"].map(fit_kind) == k] for k, n in picked.items()], ignore_index=True
    )
    return rows, choices, picked


def read_run(rows_path: Path) -> tuple[pd.DataFrame, Path]:
    """A run's rows and the path of the choices beside them (``structured_choices.csv`` in the same
    folder); a one-line FeederError when the rows are missing or not a run's."""
    if not rows_path.is_file():
        raise FeederError(f"--from-rows {rows_path}: no such file")
    long = pd.read_csv(rows_path)
    missing = {"experiment", "repeat", "part", "config_id", "kept", "predictor", "seed", "cw1"} - set(long.columns)
    if missing:
        raise FeederError(f"--from-rows {rows_path}: not a structured_rows.csv (no {sorted(missing)})")
    return long, rows_path.with_name("structured_choices.csv")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="feeder structured", description=__doc__.split("\n")[0])
    p.add_argument("--dataset", type=Path, default=Path("results/datasets/dataset.npz"))
    p.add_argument("--sim-dir", type=Path, default=Path("results/sim"), help="the simulation files (ok shares)")
    p.add_argument("--parts-dir", type=Path, default=Path("parts"))
    p.add_argument("--features-dir", type=Path, default=Path("results/features"), help="frames of excluded parts")
    p.add_argument("--out-dir", type=Path, default=Path("results/tables"))
    p.add_argument(
        "--cache",
        type=Path,
        default=None,
        help="candidates cache (.npz; default structured_candidates.npz beside the dataset)",
    )
    p.add_argument("--m3-groupkfold", type=Path, default=None, help="Model 3's GroupKFold table (per-part cW1)")
    p.add_argument("--m3-model", type=Path, nargs="*", default=None, help="Model 3's seed folders (Test, Fences)")
    p.add_argument(
        "--from-rows",
        type=Path,
        nargs="+",
        default=None,
        help="a run's structured_rows.csv: fit nothing, write the comparisons and the error by neighbour distance "
        "from it (default: run the protocol). Several runs: each kind of fit from the last run holding it, and the "
        "merged structured_rows.csv and structured_choices.csv (read beside each rows file) written too",
    )
    p.add_argument("overrides", nargs="*", help="Hydra overrides of config/hydra/structured.yaml")
    return p


def write_tables(out_dir: Path, table: pd.DataFrame, by_distance: pd.DataFrame) -> None:
    """The comparisons (``structured_protocol.csv`` / ``.md``) and the error by neighbour distance
    (``structured_by_distance.csv``), each written atomically."""
    from feeder import io

    io.write_csv(out_dir / "structured_protocol.csv", table)
    io.write_text(
        out_dir / "structured_protocol.md",
        io.markdown_table(table, "Structured predictor against the baselines (issue #39; 95 % paired bootstrap)"),
    )
    io.write_csv(out_dir / "structured_by_distance.csv", by_distance)


def main(argv: list[str]) -> int:
    from feeder import io
    from feeder.config import compose_config, pull_overrides
    from feeder.labels.dataset import load_dataset
    from feeder.learn.prior import grids
    from feeder.learn.structured_blend import blend_weights
    from feeder.learn.structured_calibration import calibration_settings
    from feeder.learn.structured_data import drop_arrays, one_fence_maps, structured_arrays
    from feeder.learn.structured_mirror import mirror_labels

    args = _parser().parse_args(argv)
    args.m3_model, args.overrides = pull_overrides(args.m3_model, args.overrides)  # list options take every word
    args.from_rows, args.overrides = pull_overrides(args.from_rows, args.overrides)
    if args.from_rows == []:
        raise FeederError("--from-rows needs a structured_rows.csv (it got only Hydra overrides)")
    cfg = compose_config("structured", args.overrides)
    edges = check_edges(cfg.answer_errors.edges_deg)
    if args.from_rows is not None:  # the tables of a run's rows: its splits from the dataset, no fit
        from feeder.learn.structured_data import row_mirror_degs, split_arrays

        runs = [read_run(path) for path in args.from_rows]
        long = runs[0][0]
        if len(runs) > 1:  # each kind of fit from the last run that holds it
            for path, (_, choices_path) in zip(args.from_rows, runs, strict=True):
                if not choices_path.is_file():
                    raise FeederError(f"--from-rows {path}: no {choices_path.name} beside it")
            long, choices, source = merge_runs([(r, pd.read_csv(c)) for r, c in runs])
            for kind, n in source.items():
                print(f"{kind}: from {args.from_rows[n]}", flush=True)
        m3_parts = m3_part_scores(args.m3_groupkfold) if args.m3_groupkfold else None
        table = comparison_table(long, dict(cfg.protocol.bootstrap), m3_parts)
        data = load_dataset(args.dataset)
        split = split_arrays(data)
        if mirror_labels(cfg) and "push_raw" in data:  # the mirrored labels too, as the run's (outlines known)
            split["mirror_deg"] = row_mirror_degs(data, split["part"], args.parts_dir, args.features_dir)
        by_distance = error_by_distance(long, neighbour_distances(split, cfg), edges)
        if len(runs) > 1:
            io.write_csv(args.out_dir / "structured_rows.csv", long)
            io.write_csv(args.out_dir / "structured_choices.csv", choices)
        write_tables(args.out_dir, table, by_distance)
        print(by_distance.to_string(index=False))
        return 0
    check_workers(cfg.train.workers)  # before the data and the candidates, not after
    # bad settings: a one-line error before any work
    neighbour_options(cfg), drop_count(cfg), drop_count(cfg, "drop_candidates"), composed_on(cfg), fit_kinds(cfg)
    fit_part_fraction(cfg), cross_only_copies(cfg), refit_on(cfg), calibration_settings(cfg), blend_weights(cfg)
    mirror_labels(cfg)
    prior_grids = grids(compose_config("train")["prior"])
    import torch

    torch.set_num_threads(int(cfg.train.threads))
    data = load_dataset(args.dataset)
    if "push_raw" not in data:
        raise FeederError(f"{args.dataset}: no push block (build the dataset with the part files)")
    cache = args.cache or args.dataset.with_name("structured_candidates.npz")
    say = lambda m: print(m, flush=True)  # noqa: E731
    arrays = structured_arrays(data, cfg, args.sim_dir, args.parts_dir, args.features_dir, cache, say, calibration=True)
    labels = json.loads(str(data["settings"]))["labels"]
    if composed_on(cfg):  # the one-fence configurations' drop maps, read from their simulation files
        arrays["composed_maps"] = one_fence_maps(arrays, args.sim_dir, float(labels["sigma_bins"]))
    if drop_count(cfg):  # each configuration's own first drops, read from its simulation file
        arrays = drop_arrays(arrays, args.sim_dir, drop_count(cfg), int(labels["bins"]), float(labels["sigma_bins"]))
    m3 = m3_predictions(data, args.m3_model) if args.m3_model else None
    long, choices = run_protocol(arrays, cfg, prior_grids, m3, progress=say, workers=cfg.train.workers)
    m3_parts = m3_part_scores(args.m3_groupkfold) if args.m3_groupkfold else None
    table = comparison_table(long, dict(cfg.protocol.bootstrap), m3_parts)
    io.write_csv(args.out_dir / "structured_rows.csv", long)
    io.write_csv(args.out_dir / "structured_choices.csv", choices)
    write_tables(args.out_dir, table, error_by_distance(long, neighbour_distances(arrays, cfg), edges))
    print(table.to_string(index=False))
    return 0
