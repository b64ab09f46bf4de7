"""Training through Hydra's compose API on a small synthetic dataset.

``make_dataset`` (also used by test_evaluate / test_predict) writes a dataset.npz in the format of
docs/data.md: a few parts with random DFT-like triplets, fence configurations, and PMFs from
von Mises mixtures whose mode positions depend on the part features and fence angles, so a
network can learn them.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from feeder.learn import train as T
from feeder.errors import FeederError
from feeder.io import write_npz

BINS = 360
TYPES = ("none", "straight", "curved")


def _vm_pmf(mus, kappas, weights):
    theta = np.deg2rad(np.arange(BINS) + 0.5)
    dens = sum(w * np.exp(k * np.cos(theta - np.deg2rad(m))) for m, k, w in zip(mus, kappas, weights))
    return dens / dens.sum()


def make_dataset(path, n_parts=5, per_part=30, holdout=1, seed=0, one_hot=False, zero_features=False):
    """Synthetic dataset.npz; the last ``holdout`` parts form the Parts split, part 0 gets a
    reserved fence combination (curved_curved) as the Fences split."""
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
            feeder[TYPES.index(t1)] = 1
            feeder[3] = a1
            feeder[4 + TYPES.index(t2)] = 1
            feeder[7] = a2
            mu = 180 * u + 2 * a1 + a2 + 60 * TYPES.index(t1)
            pmf = _vm_pmf([mu, mu + 180], [8.0, 4.0], [0.7, 0.3 + 0.2 * TYPES.index(t2)])
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
    write_npz(path, **arrays)
    return arrays


def small_overrides(dataset, out, model="m3", epochs=3, extra=()):
    """Overrides shrinking a model so a test trains in about a second."""
    from omegaconf import OmegaConf

    cfg = T.compose_config([f"model={model}"])
    shrink = []
    for key in ("hidden", "shared_hidden"):
        if key in cfg.model:
            shrink.append(f"model.{key}=[32]")
    for key in ("part_hidden",):
        if key in cfg.model:
            shrink.append(f"model.{key}=[16]")
    del OmegaConf
    return [f"model={model}", f"paths.dataset={dataset}", f"paths.out={out}",
            f"trainer.max_epochs={epochs}", *shrink, *extra]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("ds") / "dataset.npz"
    make_dataset(path)
    return path


def test_every_model_composes_with_paper_settings():
    lrs = {"m1": 1e-4, "m2": 1e-4, "m3": 4e-4, "m4": 4e-4, "m5": 3e-4, "m6": 3e-4, "m7": 4e-4, "m8": 1e-3}
    for name, lr in lrs.items():
        cfg = T.compose_config([f"model={name}"])
        assert cfg.model.name == name and cfg.model.lr == lr
        assert cfg.trainer.batch_size == 64 and cfg.trainer.max_epochs == 400
        assert cfg.trainer.patience == 20 and cfg.trainer.val_fraction == 0.1
    assert T.compose_config(["model=m1"]).model.components == 170
    assert T.compose_config(["model=m5"]).model.components == 85
    assert dict(T.compose_config(["model=m3"]).model.loss) == {"cdf_mse": 1.0, "pmf_kl_fwd": 1.0, "cdf_ks": 1.0}
    assert dict(T.compose_config(["model=m6"]).model.loss) == {"cdf_mse": 1.0}


def test_resolved_config_yaml_changes_only_with_the_model():
    a = T.resolved_config_yaml("m3")
    assert "pmf_kl_fwd" in a and "paths" not in a
    assert T.resolved_config_yaml("m3") == a
    assert T.resolved_config_yaml("m4") != a
    assert "max_epochs: 7" in T.resolved_config_yaml("m3", ["trainer.max_epochs=7"])


@pytest.mark.parametrize("model", ["m1", "m2", "m3", "m4", "m5", "m6", "m7", "m8"])
def test_each_model_trains_and_saves(dataset, tmp_path, model):
    from feeder.learn.models import TrainedModel

    cfg = T.compose_config(small_overrides(dataset, tmp_path / model, model, epochs=2))
    metrics = T.train(cfg)
    out = tmp_path / model
    for name in ("model.pt", "scaler.json", "config.yaml", "history.csv", "metrics.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "metrics.json").read_text()) == pytest.approx(metrics)
    assert metrics["epochs_run"] == 2 and metrics["train_s"] > 0
    assert np.isfinite(metrics["r2_test"]) and np.isfinite(metrics["best_val_loss"])
    if model in ("m1", "m2", "m5", "m6"):
        # 98 training rows support at most 97 components: 170 is capped (and said so), 85 is not
        n_train = int((T.load_dataset(dataset)["split"] == "train").sum())
        assert metrics["pca_components"] == min(cfg.model.components, n_train - 1)
        assert metrics["pca_capped"] == (cfg.model.components > n_train - 1)
    tm = TrainedModel.load(out)
    data = T.load_dataset(dataset)
    pmf, cdf = tm.predict(data["part_raw"][:5], data["feeder_raw"][:5])
    assert (pmf >= 0).all() and np.allclose(pmf.sum(1), 1) and np.allclose(cdf[:, -1], 1)
    assert (np.diff(cdf, axis=1) >= -1e-12).all()


def test_same_seed_same_metrics_different_seed_differs(dataset, tmp_path):
    runs = []
    for i, seed in enumerate((0, 0, 1)):
        cfg = T.compose_config(small_overrides(dataset, tmp_path / f"r{i}", "m3", epochs=4, extra=[f"seed={seed}"]))
        runs.append(T.train(cfg))
    keys = [k for k in runs[0] if k.startswith(("r2_", "w1_")) or k == "best_val_loss"]
    for k in keys:
        assert runs[0][k] == pytest.approx(runs[1][k], abs=1e-6)
    assert any(abs(runs[0][k] - runs[2][k]) > 1e-6 for k in keys)


def test_m3_learns_beyond_the_mean(dataset, tmp_path):
    """A few hundred steps on the synthetic data beat the training-mean distribution on Test."""
    from feeder.labels.metrics import r2_cdf

    cfg = T.compose_config(small_overrides(dataset, tmp_path / "m3", "m3", epochs=150,
                                           extra=["model.hidden=[64,64]", "trainer.batch_size=16",
                                                  "model.lr=0.003"]))
    metrics = T.train(cfg)
    data = T.load_dataset(dataset)
    tr, te = data["split"] == "train", data["split"] == "test"
    mean_cdf = data["cdf"][tr].mean(axis=0)
    baseline = r2_cdf(data["cdf"][te], mean_cdf[None]).mean()
    assert metrics["r2_test"] > baseline + 0.1
    assert metrics["r2_train"] > 0.9


def test_early_stopping_restores_best_epoch(dataset, tmp_path):
    import pandas as pd

    cfg = T.compose_config(small_overrides(dataset, tmp_path / "m7", "m7", epochs=60,
                                           extra=["trainer.patience=2", "model.lr=0.05"]))
    metrics = T.train(cfg)
    hist = pd.read_csv(tmp_path / "m7" / "history.csv")
    assert metrics["epochs_run"] == len(hist)
    assert metrics["best_epoch"] == int(hist.loc[hist.val_loss.idxmin(), "epoch"])
    assert metrics["best_val_loss"] == pytest.approx(hist.val_loss.min())
    if metrics["epochs_run"] < 60:
        assert metrics["epochs_run"] - metrics["best_epoch"] == 2


@pytest.mark.parametrize("model", ["m3", "m4", "m5", "m7"])
def test_one_hot_pmfs_and_zero_feature_rows_train_finite(tmp_path, model):
    path = tmp_path / "ds.npz"
    make_dataset(path, n_parts=3, per_part=20, one_hot=True, zero_features=True)
    cfg = T.compose_config(small_overrides(path, tmp_path / "out", model, epochs=3, extra=["model.lr=0.01"]))
    metrics = T.train(cfg)
    assert all(np.isfinite(v) for v in metrics.values() if isinstance(v, float))


def test_validation_split_is_seeded_and_disjoint():
    rows = np.arange(10, 60)
    fit_a, val_a = T.validation_split(rows, 0.1, 3)
    fit_b, val_b = T.validation_split(rows, 0.1, 3)
    assert np.array_equal(val_a, val_b) and val_a.size == 5
    assert np.array_equal(np.sort(np.concatenate([fit_a, val_a])), rows)
    with pytest.raises(FeederError):
        T.validation_split(rows[:1], 0.1, 0)


def test_bad_inputs_are_one_line_errors(tmp_path, dataset):
    cfg = T.compose_config(small_overrides(tmp_path / "missing.npz", tmp_path / "o", "m3"))
    with pytest.raises(FeederError):
        T.train(cfg)
    cfg = T.compose_config(small_overrides(dataset, tmp_path / "o", "m3", extra=["+model.loss.nope=1.0"]))
    with pytest.raises(FeederError, match="unknown loss term"):
        T.train(cfg)
    assert not (tmp_path / "o").exists()


def test_cli_main_runs_hydra_and_saves_resolved_config(dataset, tmp_path):
    out = tmp_path / "cli"
    args = small_overrides(dataset, out, "m8", epochs=1) + [f"hydra.run.dir={out}/hydra"]
    assert T.main(args) == 0
    assert (out / "model.pt").is_file()
    assert (out / "hydra" / ".hydra" / "config.yaml").is_file()
    saved = (out / "config.yaml").read_text()
    assert "name: m8" in saved and "${" not in saved


def test_grid_search_config_matches_paper():
    from hydra import compose, initialize_config_dir

    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(version_base="1.3", config_dir=str(T.CONFIG_DIR)):
        cfg = compose("train", overrides=["hparams_search=grid", "model=m5"], return_hydra_config=True)
    params = cfg.hydra.sweeper.params
    assert [float(v) for v in params["model.lr"].split(",")] == [0.0001, 0.0003, 0.0004, 0.001]
    assert [int(v) for v in params["trainer.batch_size"].split(",")] == [16, 32, 64]
    assert str(cfg.hydra.mode) == "RunMode.MULTIRUN"
    assert cfg.paths.out == "results/models/grid/m5/lr0.0003_bs64"


def test_grid_search_multirun_from_the_cli(dataset, tmp_path, monkeypatch):
    from feeder.learn.evaluate import grid_table

    monkeypatch.chdir(tmp_path)
    args = small_overrides(dataset, "unused", "m3", epochs=1)
    args = [a for a in args if not a.startswith("paths.out")]
    assert T.main(["-m", "hparams_search=grid", *args, "model.lr=0.01", "trainer.batch_size=32,64"]) == 0
    df = grid_table(tmp_path / "results/models/grid/m3")
    assert sorted(df.run) == ["lr0.01_bs32", "lr0.01_bs64"]
