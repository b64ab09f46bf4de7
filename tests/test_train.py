"""Training through Hydra's compose API on a small synthetic dataset (``factories.make_regression_dataset``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from factories import make_regression_dataset, small_overrides

from feeder.config import compose_config, hydra_config_dir
from feeder.errors import FeederError
from feeder.labels.dataset import load_dataset
from feeder.learn import train as T
from feeder.learn.data import validation_split


@pytest.fixture(scope="module")
def dataset(regression_dataset):
    return regression_dataset


def test_every_model_composes_with_paper_settings():
    lrs = {"m1": 1e-4, "m2": 1e-4, "m3": 4e-4, "m4": 4e-4, "m5": 3e-4, "m6": 3e-4, "m7": 4e-4, "m8": 1e-3}
    for name, lr in lrs.items():
        cfg = compose_config("train", [f"model={name}"])
        assert cfg.model.name == name and cfg.model.lr == lr
        assert cfg.trainer.batch_size == 64 and cfg.trainer.max_epochs == 400
        assert cfg.trainer.patience == 20 and cfg.trainer.val_fraction == 0.1
        assert cfg.model.inputs == "paper"  # the paper's 53 inputs unless model.inputs=paper+push
    assert compose_config("train", ["model=m1"]).model.components == 170
    assert compose_config("train", ["model=m5"]).model.components == 85
    assert dict(compose_config("train", ["model=m3"]).model.loss) == {"cdf_mse": 1.0, "pmf_kl_fwd": 1.0, "cdf_ks": 1.0}
    assert dict(compose_config("train", ["model=m6"]).model.loss) == {"cdf_mse": 1.0}


def test_resolved_config_yaml_changes_only_with_the_model():
    a = T.resolved_config_yaml("m3")
    assert "pmf_kl_fwd" in a and "paths" not in a
    assert T.resolved_config_yaml("m3") == a
    assert T.resolved_config_yaml("m4") != a
    assert "max_epochs: 7" in T.resolved_config_yaml("m3", ["trainer.max_epochs=7"])


@pytest.mark.parametrize("model", ["m1", "m2", "m3", "m4", "m5", "m6", "m7", "m8"])
def test_each_model_trains_and_saves(dataset, tmp_path, model):
    from feeder.learn.models import TrainedModel

    cfg = compose_config("train", small_overrides(dataset, tmp_path / model, model, epochs=2))
    metrics = T.train(cfg)
    out = tmp_path / model
    for name in ("model.pt", "scaler.json", "config.yaml", "history.csv", "metrics.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "metrics.json").read_text()) == pytest.approx(metrics)
    assert metrics["epochs_run"] == 2 and metrics["train_s"] > 0
    assert np.isfinite(metrics["r2_test"]) and np.isfinite(metrics["best_val_loss"])
    if model in ("m1", "m2", "m5", "m6"):
        # 98 training rows support at most 97 components: 170 is capped (and said so), 85 is not
        n_train = int((load_dataset(dataset)["split"] == "train").sum())
        assert metrics["pca_components"] == min(cfg.model.components, n_train - 1)
        assert metrics["pca_capped"] == (cfg.model.components > n_train - 1)
    tm = TrainedModel.load(out)
    data = load_dataset(dataset)
    pmf, cdf = tm.predict(data["part_raw"][:5], data["feeder_raw"][:5])
    assert (pmf >= 0).all() and np.allclose(pmf.sum(1), 1) and np.allclose(cdf[:, -1], 1)
    assert (np.diff(cdf, axis=1) >= -1e-12).all()


@pytest.mark.parametrize("model", ["m1", "m2", "m5", "m8"])
def test_every_architecture_trains_with_the_push_block(push_regression_dataset, tmp_path, model):
    """PCA and full outputs, standard and branched: model.inputs=paper+push trains and predicts."""
    from feeder.learn.models import TrainedModel

    extra = ["model.inputs=paper+push"]
    metrics = T.train(compose_config("train", small_overrides(push_regression_dataset, tmp_path, model, 2, extra)))
    assert np.isfinite(metrics["r2_test"])
    tm = TrainedModel.load(tmp_path)
    assert tm.inputs == "paper+push"
    pmf, cdf = tm.predict_rows(load_dataset(push_regression_dataset), np.arange(5))
    assert np.allclose(pmf.sum(1), 1) and np.allclose(cdf[:, -1], 1)


def test_same_seed_same_metrics_different_seed_differs(dataset, tmp_path):
    runs = []
    for i, seed in enumerate((0, 0, 1)):
        overrides = small_overrides(dataset, tmp_path / f"r{i}", "m3", epochs=4, extra=[f"seed={seed}"])
        cfg = compose_config("train", overrides)
        runs.append(T.train(cfg))
    keys = [k for k in runs[0] if k.startswith(("r2_", "w1_")) or k == "best_val_loss"]
    for k in keys:
        assert runs[0][k] == pytest.approx(runs[1][k], abs=1e-6)
    assert any(abs(runs[0][k] - runs[2][k]) > 1e-6 for k in keys)


def test_m3_learns_beyond_the_mean(dataset, tmp_path):
    """A few hundred steps on the synthetic data beat the training-mean distribution on Test."""
    from feeder.labels.metrics import r2_cdf

    cfg = compose_config(
        "train",
        small_overrides(
            dataset,
            tmp_path / "m3",
            "m3",
            epochs=150,
            extra=["model.hidden=[64,64]", "trainer.batch_size=16", "model.lr=0.003"],
        ),
    )
    metrics = T.train(cfg)
    data = load_dataset(dataset)
    tr, te = data["split"] == "train", data["split"] == "test"
    mean_cdf = data["cdf"][tr].mean(axis=0)
    baseline = r2_cdf(data["cdf"][te], mean_cdf[None]).mean()
    assert metrics["r2_test"] > baseline + 0.1
    assert metrics["r2_train"] > 0.9


def test_early_stopping_restores_best_epoch(dataset, tmp_path):
    import pandas as pd

    cfg = compose_config(
        "train",
        small_overrides(dataset, tmp_path / "m7", "m7", epochs=60, extra=["trainer.patience=2", "model.lr=0.05"]),
    )
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
    make_regression_dataset(path, n_parts=3, per_part=20, one_hot=True, zero_features=True)
    cfg = compose_config("train", small_overrides(path, tmp_path / "out", model, epochs=3, extra=["model.lr=0.01"]))
    metrics = T.train(cfg)
    assert all(np.isfinite(v) for v in metrics.values() if isinstance(v, float))


def test_validation_split_is_seeded_and_disjoint():
    rows = np.arange(10, 60)
    fit_a, val_a = validation_split(rows, 0.1, 3)
    fit_b, val_b = validation_split(rows, 0.1, 3)
    assert np.array_equal(val_a, val_b) and val_a.size == 5
    assert np.array_equal(np.sort(np.concatenate([fit_a, val_a])), rows)
    with pytest.raises(FeederError):
        validation_split(rows[:1], 0.1, 0)


def test_bad_inputs_are_one_line_errors(tmp_path, dataset):
    cfg = compose_config("train", small_overrides(tmp_path / "missing.npz", tmp_path / "o", "m3"))
    with pytest.raises(FeederError):
        T.train(cfg)
    cfg = compose_config("train", small_overrides(dataset, tmp_path / "o", "m3", extra=["+model.loss.nope=1.0"]))
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
    with initialize_config_dir(version_base="1.3", config_dir=hydra_config_dir()):
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
