"""Synthetic datasets and small model settings shared by the learner tests.

Plain functions (a test calls them with its own arguments); ``conftest.py`` wraps the default
datasets in session fixtures. Two dataset shapes, both in the docs/data.md layout:

* :func:`make_regression_dataset`: a few parts with random DFT-like triplets and fence
  configurations, PMFs from von Mises mixtures whose modes depend on the part features and fence
  angles, so a network can learn them (train, evaluate, predict); with ``push=True`` also a
  synthetic analytic push block (``push_raw``, ``push_feature_names``, ``pmf_analytic``:
  :func:`add_push_block`);
* :func:`make_level_dataset`: PMFs from simulated drops with every partial level ``LEVELS`` of
  the first k % of drops (VAE, delta model).
"""

from __future__ import annotations

import numpy as np

from feeder.config import compose_config
from feeder.io import write_npz
from feeder.labels.metrics import partial_pmfs

BINS = 360
LEVELS = np.arange(5, 105, 5)
FENCE_TYPES = ("none", "straight", "curved")
PUSH_SEED_OFFSET = 1000  # the synthetic push block's random stream, apart from the dataset's
PUSH_MAX_SHIFT_DEG = 20  # the synthetic analytic PMF: the label turned by up to this many degrees
PUSH_BLUR_BINS = 4.0  # and blurred by this wrapped-Gaussian sigma


def _vm_pmf(mus, kappas, weights):
    theta = np.deg2rad(np.arange(BINS) + 0.5)
    dens = sum(w * np.exp(k * np.cos(theta - np.deg2rad(m))) for m, k, w in zip(mus, kappas, weights, strict=True))
    return dens / dens.sum()


def add_push_block(arrays: dict, seed: int = 0) -> dict:
    """A synthetic analytic push block for a regression dataset's rows (in place, returned):
    ``pmf_analytic`` the label turned by a random whole number of degrees (up to
    ``PUSH_MAX_SHIFT_DEG``) and blurred, a rough but informative analytic prediction; ``push_raw``
    its Fourier coefficients (the block's layout: :data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`)
    and noise for the other features. Its own random stream: the paper arrays do not change."""
    from feeder.circular import wrapped_gaussian_smooth
    from feeder.mechanics.features import FOURIER_K, PUSH_FEATURE_NAMES, fourier_coefficients

    rng = np.random.default_rng(seed + PUSH_SEED_OFFSET)
    pmf = arrays["pmf"]
    shifts = rng.integers(-PUSH_MAX_SHIFT_DEG, PUSH_MAX_SHIFT_DEG + 1, size=len(pmf))
    analytic = wrapped_gaussian_smooth(np.stack([np.roll(p, k) for p, k in zip(pmf, shifts)]), PUSH_BLUR_BINS)
    coef = fourier_coefficients(analytic, FOURIER_K)
    push = rng.normal(size=(len(pmf), len(PUSH_FEATURE_NAMES)))
    push[:, : 2 * FOURIER_K] = np.stack([coef.real, coef.imag], axis=-1).reshape(len(pmf), -1)
    arrays.update(push_raw=push, push_feature_names=np.array(PUSH_FEATURE_NAMES), pmf_analytic=analytic)
    return arrays


def make_regression_dataset(
    path, n_parts=5, per_part=30, holdout=1, seed=0, one_hot=False, zero_features=False, push=False
):
    """Synthetic dataset.npz for the regression models; the last ``holdout`` parts form the Parts
    split, part 0 gets a reserved fence combination (curved_curved) as the Fences split. ``push``:
    add the synthetic push block of :func:`add_push_block` (the other arrays are the same)."""
    rng = np.random.default_rng(seed)
    rows = []
    w = rng.normal(size=45)
    for p in range(n_parts):
        k = np.sort(rng.choice(np.arange(1, 30), 15, replace=False)).astype(float)
        mag = np.abs(rng.normal(1, 0.5, 15))
        ph = rng.uniform(-np.pi, np.pi, 15)
        raw = np.stack([k, mag, ph], axis=1).ravel()
        if zero_features and p == 0:
            raw = np.zeros(45)
        u = np.tanh(w @ (raw - raw.mean()) / 20.0)
        combos = [("straight", "none"), ("none", "curved"), ("straight", "straight"), ("curved", "straight")]
        for i in range(per_part):
            if p == 0 and i % 6 == 5:
                t1, t2, split = "curved", "curved", "fences"
            else:
                t1, t2 = combos[i % len(combos)]
                split = "parts" if p >= n_parts - holdout else "main"
            a1 = 0.0 if t1 == "none" else float(rng.integers(10, 80))
            a2 = 0.0 if t2 == "none" else float(rng.integers(10, 80))
            feeder = np.zeros(8)
            feeder[FENCE_TYPES.index(t1)] = 1
            feeder[3] = a1
            feeder[4 + FENCE_TYPES.index(t2)] = 1
            feeder[7] = a2
            mu = 180 * u + 2 * a1 + a2 + 60 * FENCE_TYPES.index(t1)
            pmf = _vm_pmf([mu, mu + 180], [8.0, 4.0], [0.7, 0.3 + 0.2 * FENCE_TYPES.index(t2)])
            if one_hot:
                pmf = np.zeros(BINS)
                pmf[int(mu) % BINS] = 1.0
            rows.append((f"p{p}", f"{t1}{a1:g}_{t2}{a2:g}".replace("none0", "none"), split, p, raw, feeder, pmf))
    split = np.array([r[2] for r in rows], dtype="U6")
    main = np.flatnonzero(split == "main")
    test = rng.choice(main, size=int(round(0.15 * main.size)), replace=False)
    split[main] = "train"
    split[test] = "test"
    pmf = np.stack([r[6] for r in rows])
    arrays = dict(
        part=np.array([r[0] for r in rows]),
        config_id=np.array([r[1] for r in rows]),
        split=split,
        group_fold=np.array([r[3] % 3 for r in rows]),
        part_raw=np.stack([r[4] for r in rows]),
        feeder_raw=np.stack([r[5] for r in rows]),
        pmf=pmf,
        cdf=np.cumsum(pmf, axis=1),
        pmf_levels=np.repeat(pmf[:, None, :], 2, axis=1),
        levels_pct=np.array([50, 100]),
        n_ok=np.full(len(rows), 1000),
    )
    if push:
        add_push_block(arrays, seed)
    write_npz(path, **arrays)
    return arrays


def small_overrides(dataset, out, model="m3", epochs=3, extra=()):
    """Overrides shrinking a model so a test trains in about a second."""
    cfg = compose_config("train", [f"model={model}"])
    shrink = []
    for key in ("hidden", "shared_hidden"):
        if key in cfg.model:
            shrink.append(f"model.{key}=[32]")
    for key in ("part_hidden",):
        if key in cfg.model:
            shrink.append(f"model.{key}=[16]")
    return [
        f"model={model}",
        f"paths.dataset={dataset}",
        f"paths.out={out}",
        f"trainer.max_epochs={epochs}",
        *shrink,
        *extra,
    ]


def make_level_dataset(path, n_parts=6, n_configs=10, drops=200, seed=0):
    """A small dataset.npz with partial levels: PMFs drawn from von Mises mixtures that depend on
    the part and the fence configuration; partial levels from the first k % of drops."""
    rng = np.random.default_rng(seed)
    parts = [f"p{i}" for i in range(n_parts)]
    part_vec = {p: rng.normal(size=45) for p in parts}
    rows = {k: [] for k in ("part", "config_id", "split", "group_fold", "part_raw", "feeder_raw", "pmf_levels")}
    for pi, p in enumerate(parts):
        for c in range(n_configs):
            t1, t2 = rng.integers(0, 3, size=2)
            a1, a2 = (0.0 if t == 0 else float(rng.uniform(5, 85)) for t in (t1, t2))
            feeder = np.zeros(8)
            feeder[t1], feeder[3], feeder[4 + t2], feeder[7] = 1, a1, 1, a2
            centres = np.deg2rad([(40 * pi + a1) % 360, (40 * pi + 180 + a2) % 360])
            weight = 0.3 + 0.4 * (c % 3) / 2
            comp = rng.random(drops) < weight
            yaw = np.where(comp, rng.vonmises(centres[0], 8.0, drops), rng.vonmises(centres[1], 3.0, drops))
            pl, _ = partial_pmfs(np.rad2deg(yaw), LEVELS, BINS, 1.0)
            if pi >= n_parts - 2:
                split = "parts"
            else:
                split = ["train", "train", "train", "train", "train", "test", "fences"][c % 7]
            for key, val in (
                ("part", p),
                ("config_id", f"cfg{c}"),
                ("split", split),
                ("group_fold", pi % 3),
                ("part_raw", part_vec[p]),
                ("feeder_raw", feeder),
                ("pmf_levels", pl),
            ):
                rows[key].append(val)
    arrays = {k: np.asarray(v) for k, v in rows.items()}
    arrays["pmf"] = arrays["pmf_levels"][:, -1]
    arrays["cdf"] = np.cumsum(arrays["pmf"], axis=-1)
    arrays["levels_pct"] = LEVELS
    arrays["n_ok"] = np.full(len(arrays["part"]), drops)
    np.savez(path, **arrays)
    return arrays


def grid_map(finals, statuses=None):
    """A sampled drop map at 0, 90, 180 and 270 deg (a grid design, as a grid simulation record
    rebuilds it); every drop ok unless ``statuses`` says otherwise."""
    from feeder.sim.adaptive import design_from_samples

    statuses = statuses or ["ok"] * len(finals)
    return design_from_samples(
        np.array([0.0, 90.0, 180.0, 270.0]),
        np.array(finals, dtype=float),
        np.array(statuses),
        period_deg=360.0,
        offset_deg=0.0,
        tolerance_deg=2.0,
        min_width_deg=90.0,
        max_width_deg=90.0,
        band_gap_deg=0.0,
        edge_check_deg=0.0,
    )
