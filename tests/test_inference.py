"""The numpy forward pass of `feeder predict` (feeder.learn.inference) against the torch network
it replaces (issue 36, item 6): the shipped models' weights, several parts and configurations."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from feeder.errors import FeederError
from feeder.learn import inference
from feeder.learn.models import TrainedModel
from feeder.learn.predict import part_vector, push_inputs

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = [ROOT / "models" / name for name in ("m3", "m3prior", "m3pushonly")]
PARTS = [ROOT / "parts" / f"{name}.stl" for name in ("rect-a2", "gear20-a", "keyhole-a")]
CONFIGS = [("straight:30", "none"), ("curved:40", "straight:20"), ("none", "curved:10"), ("none", "none")]
SAME_NETWORK_RTOL = 1e-8  # float64 numpy against float64 torch: the same function, round-off apart
FLOAT32_RTOL = 1e-4  # against torch's own float32 pass: float32 rounding of inputs, weights and sums
needs_models = pytest.mark.skipif(
    not all((d / "model.pt").is_file() for d in SHIPPED) or not all(p.is_file() for p in PARTS),
    reason="no shipped models or part library",
)


def torch_raw(model: TrainedModel, x: np.ndarray, analytic, double: bool) -> np.ndarray:
    """The torch network's raw PMF of scaled inputs, in float64 (``double``: a copy of the network)
    or as trained."""
    import copy

    net = copy.deepcopy(model.net).double() if double else model.net
    dtype = torch.float64 if double else torch.float32
    log_prior = None
    if analytic is not None:
        prior = np.clip(net.prior_pmf(np.atleast_2d(analytic)), inference.PRIOR_FLOOR, None)
        log_prior = torch.as_tensor(np.log(prior), dtype=dtype)
    with torch.no_grad():
        return net(torch.as_tensor(x, dtype=dtype), log_prior)["pmf"].double().numpy()


@needs_models
@pytest.mark.parametrize("model_dir", SHIPPED, ids=lambda d: d.name)
def test_the_numpy_pass_is_the_torch_network(model_dir):
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_location

    ours, theirs = inference.load(model_dir), TrainedModel.load(model_dir)
    assert ours.spec == theirs.spec and ours.label_frame == theirs.label_frame
    for part in PARTS:
        part_raw, frame_deg = part_vector(part, None)
        push, analytic = push_inputs(ours, part, CONFIGS, frame_deg)
        feeder = np.stack([feeder_vector(parse_location(a), parse_location(b)) for a, b in CONFIGS])
        parts = np.repeat(part_raw[None, :], len(CONFIGS), axis=0)
        x = ours.scaler.transform(parts, feeder, push if ours.needs_push else None)
        raw, _ = ours.raw(x, analytic)
        np.testing.assert_allclose(raw, torch_raw(theirs, x, analytic, double=True), rtol=SAME_NETWORK_RTOL, atol=0)
        np.testing.assert_allclose(raw, torch_raw(theirs, x, analytic, double=False), rtol=FLOAT32_RTOL, atol=0)
        pmf, cdf = ours.predict(parts, feeder, push, analytic)  # post-processed: valid distributions
        np.testing.assert_allclose(pmf.sum(axis=1), 1.0, rtol=1e-12)
        np.testing.assert_allclose(cdf, np.cumsum(pmf, axis=1), rtol=1e-12)


def test_the_numpy_pass_of_every_architecture_matches_torch(tmp_path):
    """Branched bodies, PCA outputs and CDF labels (not among the shipped models): a network
    built by models.RegressionModel with random weights, saved, read back without torch."""
    from factories import make_regression_dataset, small_overrides

    from feeder.config import compose_config
    from feeder.labels.dataset import load_dataset
    from feeder.learn import train as T

    make_regression_dataset(tmp_path / "ds.npz")
    data = load_dataset(tmp_path / "ds.npz")
    rows = np.arange(6)
    for name in ("m1", "m2", "m4", "m6", "m7"):
        out = tmp_path / name
        T.train(compose_config("train", small_overrides(tmp_path / "ds.npz", out, name, epochs=1)))
        theirs = TrainedModel.load(out)
        with torch.no_grad():  # off the mean-label start: every weight counts
            for param in theirs.net.parameters():
                param.add_(0.05 * torch.randn_like(param))
        theirs.save(out)
        ours, theirs = inference.load(out), TrainedModel.load(out)
        x = ours.scaler.transform(data["part_raw"][rows], data["feeder_raw"][rows])
        raw_pmf, raw_cdf = ours.raw(x)
        with torch.no_grad():
            want = theirs.net.double()(torch.as_tensor(x, dtype=torch.float64))
        np.testing.assert_allclose(raw_cdf, want["cdf"].numpy(), rtol=SAME_NETWORK_RTOL, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(raw_pmf, want["pmf"].numpy(), rtol=SAME_NETWORK_RTOL, atol=1e-12, err_msg=name)


def test_a_file_that_is_not_a_model_is_refused(tmp_path):
    import pickle
    import zipfile

    (tmp_path / "text.pt").write_text("not a zip")
    with pytest.raises(FeederError, match="not a saved model"):
        inference.read_weights(tmp_path / "text.pt")
    with zipfile.ZipFile(tmp_path / "evil.pt", "w") as archive:  # a pickle that would run code
        archive.writestr("archive/data.pkl", pickle.dumps(print))
    with pytest.raises(FeederError, match="builtins.print"):
        inference.read_weights(tmp_path / "evil.pt")


def test_predict_does_not_import_torch(tmp_path):
    """A fresh `feeder predict` imports only what the model needs: never torch."""
    import subprocess

    if not all(p.is_file() for p in PARTS):
        pytest.skip("no part library")
    code = (
        "import sys\nfrom feeder.cli import main\n"
        f"rc = main(['predict', '--part', {str(PARTS[0])!r}, '--loc1', 'straight:30', '--loc2', 'none',"
        f" '--out', {str(tmp_path / 'pmf.csv')!r}])\n"
        "assert rc == 0, rc\nprint('torch' in sys.modules)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "False"


def test_a_tensor_record_outside_its_storage_is_refused():
    from feeder.learn.inference import _rebuild_tensor

    storage = np.arange(6, dtype=np.float32)
    np.testing.assert_array_equal(_rebuild_tensor(storage, 0, (2, 3), (3, 1)), storage.reshape(2, 3))
    np.testing.assert_array_equal(_rebuild_tensor(storage, 1, (2, 2), (3, 1)), [[1, 2], [4, 5]])
    assert _rebuild_tensor(storage, 5, (), ()) == 5
    for offset, size, stride in [
        (1, (2, 3), (3, 1)),
        (0, (2, 3), (4, 1)),
        (-1, (2,), (1,)),
        (0, (2,), (-1,)),
        (6, (), ()),
    ]:
        with pytest.raises(ValueError):
            _rebuild_tensor(storage, offset, size, stride)
