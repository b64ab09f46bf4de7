"""A trained network's answers in numpy, without torch: what ``feeder predict`` and ``feeder
recommend`` run (:func:`load`).

Importing torch costs a fresh ``feeder predict`` most of its time (about 0.8 of its 1.7 s on the
development machine), while one configuration costs the network well under a millisecond. The
networks are small multilayer perceptrons (:mod:`feeder.learn.models`), so their forward pass is
a few matrix products:

* the weights are read from ``model.pt`` without torch (:func:`read_weights`): the file is a zip
  archive of a pickle and one raw buffer per tensor, and the pickle is read by an unpickler that
  knows only what a saved state dict holds (:data:`_GLOBALS`: an ordered dict, tensors and their
  storages), so a file with anything else is refused rather than run;
* the forward pass (:class:`NumpyNetwork`) is :class:`feeder.learn.models.RegressionModel`'s,
  layer for layer (standard or branched body, the analytic prior's logits, PCA reconstruction,
  softmax, sigmoid or linear outputs), in float64 on the float32 weights;
* :class:`NumpyModel` has :class:`feeder.learn.models.TrainedModel`'s prediction interface (the
  input scaler, the label frame, post-processing).

Torch evaluates the same network in float32, so the two answers differ by float32 rounding (about
1e-6 relative); evaluated in float64 (``net.double()``) torch and this module agree to 1e-8
relative (``tests/test_inference.py``). ``feeder predict`` therefore answers what the model's
weights compute, more exactly than in float32; training, evaluation and the tables use torch.
"""

from __future__ import annotations

import json
import pickle
import zipfile
from collections import OrderedDict
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.learn.spec import PART_DIM, PRIOR_FLOOR, SCALER_FILE, WEIGHTS_FILE, ModelSpec, Predictor

_LITTLE_ENDIAN = "little"  # the byte order torch.save records, and the only one read here


class _Storage:
    """A tensor storage type of a torch file (``torch.FloatStorage`` …): its numpy dtype."""

    def __init__(self, dtype: str):
        self.dtype = np.dtype(dtype)


def _rebuild_tensor(storage: np.ndarray, offset: int, size, stride, *_rest) -> np.ndarray:
    """``torch._utils._rebuild_tensor_v2`` in numpy: the strided view of a storage, copied. A view
    that would reach outside the storage (negative or too large offset, sizes or strides) is a
    ValueError, which :func:`read_weights` reports as a file that is not a saved model."""
    size, stride = tuple(int(n) for n in size), tuple(int(s) for s in stride)
    if len(size) != len(stride) or offset < 0 or any(n < 0 for n in size) or any(s < 0 for s in stride):
        raise ValueError("a tensor record with a negative or mismatched offset, size or stride")
    last = offset + sum((n - 1) * s for n, s in zip(size, stride, strict=True)) if all(size) else offset - 1
    if last >= storage.size or (not size and offset >= storage.size):
        raise ValueError("a tensor record that reaches outside its storage")
    if not size:
        return np.array(storage[offset])
    strides = [s * storage.itemsize for s in stride]
    return np.lib.stride_tricks.as_strided(storage[offset:], shape=size, strides=strides).copy()


# what a saved model.pt may name: the state dict's container, tensors and their storages
_GLOBALS = {
    ("collections", "OrderedDict"): OrderedDict,
    ("torch._utils", "_rebuild_tensor_v2"): _rebuild_tensor,
    ("torch", "FloatStorage"): _Storage("<f4"),
    ("torch", "DoubleStorage"): _Storage("<f8"),
    ("torch", "HalfStorage"): _Storage("<f2"),
    ("torch", "LongStorage"): _Storage("<i8"),
    ("torch", "IntStorage"): _Storage("<i4"),
    ("torch", "ShortStorage"): _Storage("<i2"),
    ("torch", "CharStorage"): _Storage("i1"),
    ("torch", "ByteStorage"): _Storage("u1"),
    ("torch", "BoolStorage"): _Storage("?"),
}


class _WeightsUnpickler(pickle.Unpickler):
    def __init__(self, archive: zipfile.ZipFile, prefix: str, path: Path):
        super().__init__(archive.open(f"{prefix}/data.pkl"))
        self.archive, self.prefix, self.path = archive, prefix, path

    def find_class(self, module: str, name: str):
        try:
            return _GLOBALS[(module, name)]
        except KeyError:
            raise FeederError(f"{self.path}: holds {module}.{name}, not a model's weights") from None

    def persistent_load(self, pid):
        kind, storage, key = pid[0], pid[1], pid[2]
        if kind != "storage" or not isinstance(storage, _Storage):
            raise FeederError(f"{self.path}: an unknown record {kind!r}, not a model's weights")
        return np.frombuffer(self.archive.read(f"{self.prefix}/data/{key}"), dtype=storage.dtype)


def read_weights(path: str | Path) -> dict:
    """The object ``torch.save`` wrote to ``path`` (a dict of plain values and state dicts),
    tensors as numpy arrays, without torch. A file that is not a torch zip archive, or that holds
    anything but plain values and tensors, is a one-line :class:`FeederError`."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
            prefix = names[0].split("/")[0] if names else ""
            order = f"{prefix}/byteorder"
            if order in names and archive.read(order).decode().strip() != _LITTLE_ENDIAN:
                raise FeederError(f"{path}: weights in big-endian byte order")
            return _WeightsUnpickler(archive, prefix, path).load()
    except (
        zipfile.BadZipFile,
        KeyError,
        pickle.UnpicklingError,
        EOFError,
        ValueError,
        TypeError,
        AttributeError,
        IndexError,
    ) as err:
        raise FeederError(f"{path}: not a saved model ({type(err).__name__})") from None


def _layers(state: dict, prefix: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (weight, bias) of every linear layer of the ``nn.Sequential`` at ``prefix``, in order."""
    index = sorted({int(k[len(prefix) :].split(".")[0]) for k in state if k.startswith(prefix)})
    layers = [(state[f"{prefix}{i}.weight"], state[f"{prefix}{i}.bias"]) for i in index]
    if not layers:
        raise FeederError(f"the weights lack the layers {prefix}*")
    return [(np.asarray(w, dtype=np.float64), np.asarray(b, dtype=np.float64)) for w, b in layers]


def _mlp(x: np.ndarray, layers, final_relu: bool) -> np.ndarray:
    """:func:`feeder.learn.models._mlp`'s forward pass: linear layers with ReLU between them (and
    after the last one when ``final_relu``)."""
    for i, (weight, bias) in enumerate(layers):
        x = x @ weight.T + bias
        if final_relu or i < len(layers) - 1:
            x = np.maximum(x, 0.0)
    return x


def _log_softmax(z: np.ndarray) -> np.ndarray:
    z = z - z.max(axis=-1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=-1, keepdims=True))


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * z))  # = 1 / (1 + exp(-z)), without overflow


class NumpyNetwork:
    """:class:`feeder.learn.models.RegressionModel`'s forward pass on its state dict, float64."""

    def __init__(self, spec: ModelSpec, state: dict):
        self.spec = spec
        if spec.arch == "standard":
            self.body = {"net": _layers(state, "body.net.")}
        else:
            self.body = {name: _layers(state, f"body.{name}.") for name in ("part", "feeder", "shared")}
        self.pca = None
        if spec.repr == "pca":
            self.pca = (
                np.asarray(state["pca_components"], dtype=np.float64),
                np.asarray(state["pca_mean"], dtype=np.float64),
            )
        self.prior = None
        if spec.base == "prior":
            self.prior = (
                np.asarray(state["prior_mean_pmf"], dtype=np.float64),
                float(state["prior_sigma_bins"]),
                float(state["prior_weight"]),
            )

    def log_prior(self, analytic: np.ndarray) -> np.ndarray:
        """log(prior) of rows of analytic PMFs (:meth:`RegressionModel.log_prior`, float64)."""
        from feeder.learn.prior import blend

        mean_pmf, sigma, weight = self.prior
        return np.log(np.clip(blend(analytic, mean_pmf, sigma, weight), PRIOR_FLOOR, None))

    def logits(self, x: np.ndarray) -> np.ndarray:
        if self.spec.arch == "standard":
            return _mlp(x, self.body["net"], final_relu=False)
        part = _mlp(x[:, :PART_DIM], self.body["part"], final_relu=True)
        feeder = _mlp(x[:, PART_DIM:], self.body["feeder"], final_relu=True)
        return _mlp(np.concatenate([part, feeder], axis=1), self.body["shared"], final_relu=False)

    def __call__(self, x: np.ndarray, analytic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw (pmf, cdf) of scaled inputs ``x`` (N, inputs); ``analytic`` for a prior model."""
        spec = self.spec
        out = self.logits(np.atleast_2d(np.asarray(x, dtype=np.float64)))
        if spec.base == "prior":
            out = out + self.log_prior(analytic)
        if spec.repr == "pca":
            components, mean = self.pca
            values = out @ components + mean
        elif spec.output_activation == "softmax":
            values = np.exp(_log_softmax(out))
        elif spec.output_activation == "sigmoid":
            values = _sigmoid(out)
        else:
            values = out
        if spec.label == "pmf":
            return values, np.cumsum(values, axis=-1)
        return np.diff(values, axis=-1, prepend=0.0), values


class NumpyModel(Predictor):
    """A trained model answered in numpy: :class:`feeder.learn.models.TrainedModel`'s
    ``predict`` without torch (:mod:`feeder.learn.inference`)."""

    def __init__(self, net: NumpyNetwork, scaler, label_frame: str = "part"):
        self.net = net
        super().__init__(net.spec, scaler, label_frame)

    def raw(self, x: np.ndarray, analytic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw (pmf, cdf) network outputs for scaled inputs ``x``, float64 throughout."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        return self.net(x, self.check_analytic(analytic, x.shape[0]))


def load(model_dir: str | Path) -> NumpyModel:
    """The model saved in ``model_dir`` (``model.pt`` and ``scaler.json``, as
    :meth:`feeder.learn.models.TrainedModel.save` writes them), with the checks of
    :meth:`~feeder.learn.models.TrainedModel.load`, for :class:`NumpyModel`."""
    from feeder.labels.dataset import Scaler
    from feeder.learn.spec import check_push_features

    model_dir = Path(model_dir)
    weights, scaler_path = model_dir / WEIGHTS_FILE, model_dir / SCALER_FILE
    for path in (weights, scaler_path):
        if not path.is_file():
            raise FeederError(f"{path}: missing (is {model_dir} a trained model directory?)")
    blob = read_weights(weights)
    try:
        spec = ModelSpec.from_dict(blob["spec"])
        check_push_features(spec, blob, model_dir)
        net = NumpyNetwork(spec, blob["state_dict"])
    except (KeyError, TypeError) as err:
        raise FeederError(f"{weights}: not a saved model ({type(err).__name__}: {err})") from None
    except ValueError as err:
        raise FeederError(f"{weights}: {err}") from None
    scaler = Scaler.from_dict(json.loads(scaler_path.read_text()))
    return NumpyModel(net, scaler, str(blob.get("label_frame", "part")))
