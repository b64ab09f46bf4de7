"""The analytic prior as a baseline (``baseline_analytic_prior``) and as the base of a network
(``model.base: prior``, m3prior): grids from the training config, the row's prior, training,
saving and loading, predict and recommend on a real part, and the errors for what is missing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from factories import small_overrides

from feeder.config import compose_config
from feeder.errors import FeederError
from feeder.labels import dataset as D
from feeder.lane.fences import parse_config_id, parse_location
from feeder.learn import evaluate as E
from feeder.learn import predict as P
from feeder.learn import prior as PR
from feeder.learn import recommend as R
from feeder.learn import train as T
from feeder.learn.models import ModelSpec, TrainedModel
from feeder.mechanics.features import push_block
from feeder.mechanics.fence import default_scene
from feeder.parts.geometry import load_outline

ROOT = Path(__file__).resolve().parents[1]
STL = ROOT / "parts" / "rect-a2.stl"


def test_grids_come_from_the_training_config_and_bad_ones_are_one_line_errors():
    g = PR.grids(compose_config("train").prior)
    assert 0.0 in g.sigmas_bins and g.weights[0] == 0.0 and g.weights[-1] == 1.0
    for bad, match in (
        ({"sigmas_bins": [], "weights": [0.5]}, "at least one"),
        ({"sigmas_bins": [-1], "weights": [0.5]}, ">= 0"),
        ({"sigmas_bins": [1], "weights": [1.5]}, r"\[0, 1\]"),
        ({"weights": [0.5]}, "sigmas_bins"),
        ({"sigmas_bins": ["x"], "weights": [0.5]}, "numbers"),
    ):
        with pytest.raises(FeederError, match=match) as err:
            PR.grids(bad)
        assert "\n" not in str(err.value)


def test_prior_baseline_takes_the_analytic_pmf_when_it_is_exact_on_the_training_rows():
    pmf = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.0]])
    analytic = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.2, 0.2, 0.6]])
    data = {
        "pmf": pmf,
        "cdf": np.cumsum(pmf, 1),
        "part_raw": np.arange(180.0).reshape(4, 45),
        "feeder_raw": np.tile([0, 1, 0, 30, 1, 0, 0, 0], (4, 1)).astype(float),
        "pmf_analytic": analytic,
    }
    train = np.array([True, True, True, False])
    assert E.BASELINE_PRIOR not in E.baseline_predictions(data, train)  # no grids: no prior row
    grids = PR.Grids(sigmas_bins=(0.0,), weights=(0.0, 0.5, 1.0))
    out = E.baseline_predictions(data, train, grids)
    assert (
        list(out)
        == E.baseline_names(data, grids)
        == [
            E.BASELINE_MEAN,
            E.BASELINE_NEAREST,
            E.BASELINE_ANALYTIC,
            E.BASELINE_PRIOR,
        ]
    )
    # the analytic PMF is every training label: lambda = 1, and the held-out row is its analytic PMF
    np.testing.assert_allclose(out[E.BASELINE_PRIOR][0][3], [0.2, 0.4, 1.0])
    # an analytic PMF that is always wrong (the next bin): the mean PMF's share is chosen
    wrong = {**data, "pmf_analytic": np.roll(pmf, 1, axis=1)}
    best = PR.fit_blend(pmf, wrong["pmf_analytic"], train, grids.sigmas_bins, grids.weights)
    assert best.weight < 1.0
    want = np.cumsum(PR.blend(wrong["pmf_analytic"], pmf[train].mean(axis=0), 0.0, best.weight), axis=1)
    np.testing.assert_allclose(E.baseline_predictions(wrong, train, grids)[E.BASELINE_PRIOR][0], want)


def test_base_prior_needs_a_softmax_pmf_and_a_mean_model_saves_without_the_key():
    with pytest.raises(ValueError, match="base prior"):
        ModelSpec("x", "cdf", "full", "standard", "sigmoid", 360, hidden=(8,), base="prior")
    with pytest.raises(ValueError, match="base must be one of"):
        ModelSpec("x", "pmf", "full", "standard", "softmax", 360, hidden=(8,), base="median")
    spec = ModelSpec("x", "pmf", "full", "standard", "softmax", 360, hidden=(8,))
    assert "base" not in spec.to_dict() and ModelSpec.from_dict(spec.to_dict()).base == "mean"
    prior = ModelSpec("x", "pmf", "full", "standard", "softmax", 360, hidden=(8,), base="prior")
    assert ModelSpec.from_dict(prior.to_dict()).base == "prior"


@pytest.fixture(scope="module")
def prior_model(tmp_path_factory, push_regression_dataset):
    root = tmp_path_factory.mktemp("prior_model")
    ds = push_regression_dataset
    T.train(compose_config("train", small_overrides(ds, root / "m3prior", "m3prior", 3)))
    return root / "m3prior", ds


def test_an_untrained_prior_network_predicts_its_prior(push_regression_dataset):
    data = D.load_dataset(push_regression_dataset)
    cfg = compose_config("train", small_overrides(push_regression_dataset, "unused", "m3prior", 1))
    spec, _ = T._model_spec(cfg, 360)
    train = data["split"] == "train"
    rows = np.flatnonzero(train)
    scaler, x_all, _ = T._model_inputs(spec, data, train, rows)
    net = T._init_net(spec, None, data, rows, 0, cfg.prior)
    g = PR.grids(cfg.prior)
    best = PR.fit_blend(data["pmf"], data["pmf_analytic"], train, g.sigmas_bins, g.weights)
    want = PR.blend(data["pmf_analytic"], data["pmf"][rows].mean(axis=0), best.sigma_bins, best.weight)
    got, _ = TrainedModel(net, scaler).raw(x_all, data["pmf_analytic"])
    np.testing.assert_allclose(got, want, atol=1e-6)
    # the synthetic analytic PMF is the label turned and blurred: the prior leans on it
    assert best.weight > 0.0


def test_a_prior_model_trains_saves_loads_and_needs_the_analytic_pmf(prior_model):
    model_dir, ds = prior_model
    data = D.load_dataset(ds)
    tm = TrainedModel.load(model_dir)
    assert tm.needs_analytic and tm.needs_push and tm.spec.base == "prior" and tm.spec.name == "m3prior"
    pmf, cdf = tm.predict_rows(data)
    np.testing.assert_allclose(pmf.sum(axis=1), 1.0, atol=1e-6)
    assert np.isfinite(cdf).all()
    # the prior is stored with the weights: a loaded model predicts what the prior and the net give
    g = PR.grids(compose_config("train").prior)
    train = data["split"] == "train"
    best = PR.fit_blend(data["pmf"], data["pmf_analytic"], train, g.sigmas_bins, g.weights)
    assert float(tm.net.prior_weight) == best.weight and float(tm.net.prior_sigma_bins) == best.sigma_bins
    # a different analytic PMF moves the prediction: the model reads it
    other, _ = tm.predict_rows({**data, "pmf_analytic": np.roll(data["pmf_analytic"], 90, axis=1)})
    assert np.abs(other - pmf).max() > 1e-3
    without = {k: v for k, v in data.items() if k != "pmf_analytic"}
    with pytest.raises(FeederError, match="pmf_analytic"):
        tm.predict_rows(without)
    with pytest.raises(FeederError, match=r"model.base: prior"):
        tm.predict(*D.raw_inputs(data, tm.inputs))
    cfg = compose_config("train", small_overrides(ds, "unused", "m3prior", 1))
    with pytest.raises(FeederError, match="pmf_analytic") as err:
        T.fit(cfg, without, train)
    assert "\n" not in str(err.value)


def test_groupkfold_and_tables_with_a_prior_model(prior_model, tmp_path):
    model_dir, ds = prior_model
    data = D.load_dataset(ds)
    E.write_tables(
        ds, [model_dir], tmp_path, {"resamples": 20, "level": 0.9, "seed": 0}, PR.grids(compose_config("train").prior)
    )
    t8 = pd.read_csv(tmp_path / "table8.csv").set_index("model")
    assert {"m3prior", E.BASELINE_PRIOR} <= set(t8.index)
    cfg = compose_config("train", small_overrides(ds, "unused", "m3prior", 1))
    table, paired = E.groupkfold(
        data, cfg, seeds=[0], progress=False, bootstrap={"resamples": 20, "level": 0.9, "seed": 0}
    )
    over = table[table.group == "over parts"].set_index("model")
    assert {"m3prior", E.BASELINE_PRIOR} <= set(over.index)
    assert E.BASELINE_PRIOR in set(paired.baseline)


@pytest.mark.skipif(not STL.is_file(), reason="no part library in parts/")
def test_predict_and_recommend_with_a_prior_model_read_the_parts_analytic_pmf(prior_model, tmp_path):
    from feeder.config import load_study_config
    from feeder.parts.features import as_vector, features_of_file

    model_dir, _ = prior_model
    tm = P.load_model(model_dir)  # what the commands answer with: the network in numpy
    out = tmp_path / "pmf.csv"
    argv = ["--model", str(model_dir), "--part", str(STL), "--loc1", "straight:30", "--loc2", "curved:40"]
    assert P.main([*argv, "--out", str(out)]) == 0
    scene = default_scene()
    smooth = D.label_smooth_deg(360, float(load_study_config()["labels"]["sigma_bins"]))
    outline = load_outline(STL, "auto")

    def direct(loc1, loc2):
        push, analytic = push_block(outline, loc1, loc2, scene, pmf_smooth_deg=smooth)
        feeder = D.feeder_vector(
            parse_location(loc1) if isinstance(loc1, str) else loc1,
            parse_location(loc2) if isinstance(loc2, str) else loc2,
        )
        return tm.predict(as_vector(features_of_file(STL)), feeder, push, analytic)[0][0]

    np.testing.assert_allclose(pd.read_csv(out).pmf, direct("straight:30", "curved:40"), atol=1e-12)
    configs = ["straight30_none", "none_straight45"]
    ranked_csv = tmp_path / "rank.csv"
    rec = ["--model", str(model_dir), "--part", str(STL), "--target", "90", "--tolerance", "10"]
    assert R.main([*rec, "--symmetry", "1", "--configs", ",".join(configs), "--out", str(ranked_csv)]) == 0
    ranked = pd.read_csv(ranked_csv).set_index("config_id")
    for cid in configs:
        loc1, loc2 = parse_config_id(cid)
        want = R.window_probability(direct(loc1, loc2), 90.0, 10.0)[()]
        assert ranked.loc[cid, "probability"] == pytest.approx(want)
