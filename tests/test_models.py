"""Networks, label PCA and §3.4.1 post-processing."""

import numpy as np
import pytest
import torch
from sklearn.isotonic import IsotonicRegression

from feeder.learn import models
from feeder.learn.models import ModelSpec, RegressionModel

BINS = 360


def spec(**kw):
    base = dict(
        name="mx", label="pmf", repr="full", arch="standard", output_activation="softmax", bins=BINS, hidden=(16,)
    )
    base.update(kw)
    return ModelSpec(**base)


def test_isotonic_hand_values():
    # pooling 3,1 -> 2,2 ; then 2,2,2 <= 4 fine
    assert np.allclose(models.isotonic_increasing([1.0, 3.0, 1.0, 4.0]), [1, 2, 2, 4])
    assert np.allclose(models.isotonic_increasing([3.0, 2.0, 1.0]), [2, 2, 2])
    already = np.array([0.0, 0.5, 0.5, 1.0])
    assert np.array_equal(models.isotonic_increasing(already), already)


def test_isotonic_matches_sklearn():
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(0.01, 0.05, BINS))
    ref = IsotonicRegression().fit_transform(np.arange(BINS), y)
    assert np.allclose(models.isotonic_increasing(y), ref, atol=1e-12)


def test_postprocess_cdf_valid():
    rng = np.random.default_rng(0)
    raw = np.cumsum(rng.normal(1 / BINS, 0.01, (4, BINS)), axis=1) - 0.05
    cdf = models.postprocess_cdf(raw)
    assert (np.diff(cdf, axis=1) >= -1e-15).all()
    assert (cdf >= 0).all()
    assert np.allclose(cdf[:, -1], 1.0)
    # a CDF that is already valid is unchanged
    valid = np.cumsum(np.full(BINS, 1 / BINS))
    assert np.allclose(models.postprocess_cdf(valid)[0], valid)
    # no positive mass at all -> uniform
    assert np.allclose(models.postprocess_cdf(-np.ones(BINS))[0], valid)


def test_postprocess_pmf_clip_renormalise():
    raw = np.array([[0.5, -0.25, 0.5, 0.0]])
    assert np.allclose(models.postprocess_pmf(raw), [[0.5, 0.0, 0.5, 0.0]])
    assert np.allclose(models.postprocess_pmf(-np.ones((1, 4))), 0.25)


def test_fit_pca_reconstructs_and_caps():
    rng = np.random.default_rng(1)
    y = rng.dirichlet(np.ones(BINS), size=12)
    pca = models.fit_pca(y, 170)
    assert pca.n_components == 11 and pca.capped  # 12 centred rows span 11 directions
    assert np.allclose(pca.inverse(pca.transform(y)), y, atol=1e-12)
    assert np.allclose(pca.components @ pca.components.T, np.eye(11), atol=1e-10)
    small = models.fit_pca(y, 3)
    assert small.n_components == 3 and not small.capped
    assert np.all(np.diff(small.explained_variance_ratio) <= 0)


@pytest.mark.parametrize(
    "label,repr_,act",
    [
        ("pmf", "full", "softmax"),
        ("pmf", "pca", "linear"),
        ("cdf", "pca", "linear"),
        ("cdf", "full", "sigmoid"),
        ("cdf", "full", "linear"),
    ],
)
@pytest.mark.parametrize("arch", ["standard", "branched"])
def test_forward_shapes_and_mean_start(label, repr_, act, arch):
    rng = np.random.default_rng(2)
    y_pmf = rng.dirichlet(np.ones(BINS), size=20)
    y_cdf = np.cumsum(y_pmf, axis=1)
    kw = dict(
        label=label,
        repr=repr_,
        output_activation=act,
        arch=arch,
        components=5 if repr_ == "pca" else None,
        part_hidden=(8,),
        feeder_hidden=(4,),
        shared_hidden=(8,),
    )
    s = spec(**kw)
    pca = models.fit_pca(y_pmf if label == "pmf" else y_cdf, 5) if repr_ == "pca" else None
    torch.manual_seed(0)
    net = RegressionModel(s, 5 if pca else BINS, *((pca.mean, pca.components) if pca else (None, None)))
    net.init_output_to_mean(y_pmf.mean(0), y_cdf.mean(0))
    # all-zero scaled input: hidden activations are ReLU(bias) -> still finite outputs
    x = torch.zeros(3, models.INPUT_DIM)
    out = net(x)
    assert out["pmf"].shape == (3, BINS) and out["cdf"].shape == (3, BINS)
    assert (out["log_pmf"] is not None) == (act == "softmax")
    assert torch.isfinite(out["pmf"]).all() and torch.isfinite(out["cdf"]).all()
    # the untrained model predicts the training-mean label for any input
    out = net(torch.randn(3, models.INPUT_DIM))
    target = y_pmf.mean(0) if label == "pmf" else y_cdf.mean(0)
    got = (out["pmf"] if label == "pmf" else out["cdf"])[0].detach().double().numpy()
    assert np.allclose(got, target, atol=1e-5 if act != "sigmoid" else 1e-4)


def test_branched_branches_see_their_features_only():
    s = spec(arch="branched", part_hidden=(4,), feeder_hidden=(3,), shared_hidden=(5,))
    torch.manual_seed(0)
    net = RegressionModel(s, BINS)
    x = torch.randn(2, models.INPUT_DIM, requires_grad=True)
    h_part = net.body.part(x[:, : models.PART_DIM])
    h_part.sum().backward()
    assert x.grad[:, models.PART_DIM :].abs().sum() == 0
    assert net.body.part[0].in_features == 45 and net.body.feeder[0].in_features == 8


def test_push_inputs_widen_the_input_and_reach_the_feeder_branch():
    from feeder.mechanics.features import PUSH_FEATURE_NAMES

    n_push = len(PUSH_FEATURE_NAMES)
    std = spec(inputs="paper+push")
    assert std.push_dim == n_push and std.input_dim == models.INPUT_DIM + n_push
    assert RegressionModel(std, BINS).body.net[0].in_features == models.INPUT_DIM + n_push
    s = spec(arch="branched", part_hidden=(4,), feeder_hidden=(3,), shared_hidden=(5,), inputs="paper+push")
    torch.manual_seed(0)
    net = RegressionModel(s, BINS)
    assert net.body.part[0].in_features == 45 and net.body.feeder[0].in_features == 8 + n_push
    x = torch.randn(2, s.input_dim, requires_grad=True)
    net.body.feeder(x[:, models.PART_DIM :]).sum().backward()
    assert x.grad[:, : models.PART_DIM].abs().sum() == 0  # the feeder branch: fences and push block
    assert x.grad[:, models.INPUT_DIM :].abs().sum() > 0
    assert spec().push_dim == 0 and spec().input_dim == models.INPUT_DIM
    # the saved spec names the inputs only when they are not the paper's (old files have no key)
    assert "inputs" not in spec().to_dict() and s.to_dict()["inputs"] == "paper+push"
    assert ModelSpec.from_dict(s.to_dict()) == s and ModelSpec.from_dict(spec().to_dict()).inputs == "paper"
    with pytest.raises(ValueError, match="inputs"):
        spec(inputs="push")


def test_spec_validation():
    with pytest.raises(ValueError):
        spec(output_activation="linear")  # full PMF needs softmax
    with pytest.raises(ValueError):
        spec(label="cdf", output_activation="softmax")
    with pytest.raises(ValueError):
        spec(repr="pca", output_activation="linear", components=None)
    s = spec(arch="branched", part_hidden=(4,), feeder_hidden=(3,), shared_hidden=(5,))
    assert ModelSpec.from_dict(s.to_dict()) == s


def test_postprocess_dispatch():
    pmf = np.full((1, BINS), 1 / BINS)
    p, c = models.postprocess(spec(), pmf, np.cumsum(pmf, 1))
    assert np.allclose(p, pmf) and np.allclose(c[:, -1], 1)
    s_cdf = spec(label="cdf", output_activation="sigmoid")
    raw_cdf = np.linspace(-0.1, 0.9, BINS)[None]
    p, c = models.postprocess(s_cdf, None, raw_cdf)
    assert np.allclose(c[:, -1], 1) and (p >= 0).all() and np.allclose(p.sum(1), 1)
