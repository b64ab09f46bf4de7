"""The eight regression networks of paper Table 2, their label PCA and output post-processing.

A model is described by its Hydra node ``model`` (``config/hydra/model/m1.yaml`` … ``m8.yaml``):

* ``label``: ``pmf`` or ``cdf`` — which distribution the network outputs;
* ``repr``: ``full`` (360 bins) or ``pca`` (``components`` principal-component scores);
* ``arch``: ``standard`` (53 → ``hidden`` → out) or ``branched`` (45 part features →
  ``part_hidden``, 8 feeder features → ``feeder_hidden``, concatenated → ``shared_hidden`` → out);
* ``inputs``: ``paper`` (the paper's 53 inputs; the default, and what a model saved without the
  key has) or ``paper+push``: the 53 and the analytic push block
  (:data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`, z-scored like the DFT values), appended after
  them. A branched network feeds the push block to its feeder branch (8 + P → ``feeder_hidden``):
  the block describes how the fences act on the part, the configuration-specific side of the
  input; the part branch keeps the 45 shape features alone. ``fence+push`` leaves the DFT out:
  the 8 feeder inputs and the push block only (the ablation of issue #20; standard networks only);
* ``output_activation``: ``softmax`` (full PMF), ``sigmoid`` or ``linear`` (full CDF),
  ``linear`` (PCA scores);
* ``base``: what the network starts from and corrects. ``mean`` (the default, and what a model
  saved without the key has): the training-mean label, as below. ``prior`` (softmax PMF models
  only): the analytic + mean-PMF prior of each row (:mod:`feeder.learn.prior`; its (σ, λ) fitted
  on the training rows from the grids of the training config's ``prior`` node, stored with the
  weights as buffers with the training-mean PMF). The softmax logits are the network's output plus
  log(prior), so the network learns a per-configuration correction of the prior, and with the
  output layer at zero it predicts the prior itself. Such a model needs the configuration's
  analytic PMF (the dataset's ``pmf_analytic``; for a new part :func:`feeder.mechanics.features.push_block`).

The network's forward pass returns the *raw* distribution in 360-bin space (PCA outputs are
reconstructed with the stored training mean and loadings inside the graph, so the losses of
Table 2 are always computed on 360-bin PMFs/CDFs): ``pmf``, ``cdf`` and, for softmax outputs,
``log_pmf``. PMFs of CDF models are first differences of the CDF; CDFs of PMF models cumulative
sums. The output layer starts with zero weights and the training-mean label as its bias (zero PCA
scores, the logarithm of the mean PMF for softmax, the logit of the mean CDF for sigmoid), so
training starts from the mean-distribution baseline.

Post-processing (§3.4.1, numpy, :func:`postprocess`) turns raw outputs into valid distributions
before any metric or plot: CDF outputs are projected onto non-decreasing sequences
(pool-adjacent-violators isotonic regression), clipped at 0 and divided by their last value;
PCA PMFs are clipped at 0 and renormalised; softmax PMFs are left alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from feeder.learn.spec import (  # noqa: F401 (re-exported: the torch-free part of a model, here as before)
    ACTIVATIONS,
    ARCHS,
    BASES,
    FEEDER_DIM,
    INPUT_DIM,
    INPUTS,
    LABELS,
    NO_DFT_INPUTS,
    PART_DIM,
    PRIOR_FLOOR,
    REPRS,
    SCALER_FILE,
    WEIGHTS_FILE,
    ModelSpec,
    Predictor,
    check_push_features,
    isotonic_increasing,
    postprocess,
    postprocess_cdf,
    postprocess_pmf,
)

# Floor for probabilities/CDF values turned into logits for the output bias.
_BIAS_FLOOR = 1e-6


# ----------------------------------------------------------------------------------------------
# Label PCA
# ----------------------------------------------------------------------------------------------
@dataclass
class LabelPCA:
    """PCA of label rows: ``scores = (Y − mean) @ components.T``, ``Y ≈ scores @ components + mean``."""

    mean: np.ndarray  # (B,)
    components: np.ndarray  # (K, B), orthonormal rows
    explained_variance_ratio: np.ndarray  # (K,)
    requested: int

    @property
    def n_components(self) -> int:
        return int(self.components.shape[0])

    @property
    def capped(self) -> bool:
        return self.n_components < self.requested

    def transform(self, y: np.ndarray) -> np.ndarray:
        return (np.asarray(y, dtype=np.float64) - self.mean) @ self.components.T

    def inverse(self, scores: np.ndarray) -> np.ndarray:
        return np.asarray(scores, dtype=np.float64) @ self.components + self.mean


def fit_pca(y: np.ndarray, n_components: int) -> LabelPCA:
    """PCA on zero-centred rows of ``y`` (training rows only) via SVD.

    The number of components is capped at what the rows support: min(requested, rows − 1, bins)
    (after centring, n rows span at most n − 1 directions). ``LabelPCA.capped`` tells. Signs are
    fixed so each component's largest-magnitude loading is positive (deterministic output).
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 2 or y.shape[0] < 2:
        raise ValueError(f"PCA needs at least 2 label rows, got shape {y.shape}")
    if n_components < 1:
        raise ValueError(f"PCA needs at least one component, got {n_components}")
    mean = y.mean(axis=0)
    centred = y - mean
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    k = int(min(n_components, y.shape[0] - 1, y.shape[1]))
    comps = vt[:k]
    flip = np.sign(comps[np.arange(k), np.abs(comps).argmax(axis=1)])
    comps = comps * np.where(flip == 0, 1.0, flip)[:, None]
    var = s**2
    total = var.sum()
    ratio = var[:k] / total if total > 0 else np.zeros(k)
    return LabelPCA(mean=mean, components=comps, explained_variance_ratio=ratio, requested=int(n_components))


# ----------------------------------------------------------------------------------------------
# Networks
# ----------------------------------------------------------------------------------------------
def _mlp(sizes: list[int], final_relu: bool) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if final_relu or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class StandardFC(nn.Module):
    """53 (+ push block, or 8 + push block without the DFT) → hidden (ReLU) → out (no activation)."""

    def __init__(self, hidden: list[int], out_dim: int, in_dim: int = INPUT_DIM):
        super().__init__()
        self.net = _mlp([in_dim, *hidden, out_dim], final_relu=False)

    @property
    def head(self) -> nn.Linear:
        return self.net[-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class BranchedFC(nn.Module):
    """Part branch (45 → part_hidden) and feeder branch (8 + push block → feeder_hidden),
    concatenated, then shared layers (→ shared_hidden → out). ReLU after every hidden layer."""

    def __init__(
        self,
        part_hidden: list[int],
        feeder_hidden: list[int],
        shared_hidden: list[int],
        out_dim: int,
        push_dim: int = 0,
    ):
        super().__init__()
        if not part_hidden or not feeder_hidden:
            raise ValueError("a branched network needs at least one layer in each branch")
        self.part = _mlp([PART_DIM, *part_hidden], final_relu=True)
        self.feeder = _mlp([FEEDER_DIM + push_dim, *feeder_hidden], final_relu=True)
        self.shared = _mlp([part_hidden[-1] + feeder_hidden[-1], *shared_hidden, out_dim], final_relu=False)

    @property
    def head(self) -> nn.Linear:
        return self.shared[-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.cat([self.part(x[:, :PART_DIM]), self.feeder(x[:, PART_DIM:])], dim=1)
        return self.shared(h)


class RegressionModel(nn.Module):
    """Body network + output head. ``forward(x)`` returns raw 360-bin ``pmf``, ``cdf`` and
    ``log_pmf`` (softmax outputs only; ``None`` otherwise)."""

    def __init__(
        self, spec: ModelSpec, n_out: int, pca_mean: np.ndarray | None = None, pca_components: np.ndarray | None = None
    ):
        super().__init__()
        self.spec = spec
        if spec.arch == "standard":
            if not spec.hidden:
                raise ValueError(f"model {spec.name}: a standard network needs hidden layers")
            self.body = StandardFC(list(spec.hidden), n_out, spec.input_dim)
        else:
            self.body = BranchedFC(
                list(spec.part_hidden), list(spec.feeder_hidden), list(spec.shared_hidden), n_out, spec.push_dim
            )
        if spec.repr == "pca":
            if pca_mean is None or pca_components is None or pca_components.shape[0] != n_out:
                raise ValueError(f"model {spec.name}: PCA output needs mean and {n_out} components")
            self.register_buffer("pca_mean", torch.as_tensor(pca_mean, dtype=torch.float32))
            self.register_buffer("pca_components", torch.as_tensor(pca_components, dtype=torch.float32))
        elif n_out != spec.bins:
            raise ValueError(f"model {spec.name}: full output must have {spec.bins} values, got {n_out}")
        if spec.base == "prior":  # the fitted prior (set_prior), saved with the weights
            self.register_buffer("prior_mean_pmf", torch.full((spec.bins,), 1.0 / spec.bins, dtype=torch.float64))
            self.register_buffer("prior_sigma_bins", torch.zeros((), dtype=torch.float64))
            self.register_buffer("prior_weight", torch.zeros((), dtype=torch.float64))

    def set_prior(self, mean_pmf: np.ndarray, sigma_bins: float, weight: float) -> None:
        """Store the prior fitted on the training rows (``base: prior`` models only)."""
        if self.spec.base != "prior":
            raise ValueError(f"model {self.spec.name}: only a base prior model holds a prior")
        with torch.no_grad():
            self.prior_mean_pmf.copy_(torch.as_tensor(np.asarray(mean_pmf, dtype=np.float64)))
            self.prior_sigma_bins.fill_(float(sigma_bins))
            self.prior_weight.fill_(float(weight))

    def prior_pmf(self, analytic: np.ndarray) -> np.ndarray:
        """The stored prior of rows of analytic PMFs (:func:`feeder.learn.prior.blend`)."""
        from feeder.learn.prior import blend

        return blend(analytic, self.prior_mean_pmf.numpy(), float(self.prior_sigma_bins), float(self.prior_weight))

    def log_prior(self, analytic: np.ndarray) -> torch.Tensor:
        """log(prior) of rows of analytic PMFs, floored at log(PRIOR_FLOOR), float32 for the logits."""
        prior = np.clip(self.prior_pmf(analytic), PRIOR_FLOOR, None)
        return torch.as_tensor(np.log(prior), dtype=torch.float32)

    def init_output_to_mean(self, mean_pmf: np.ndarray, mean_cdf: np.ndarray) -> None:
        """Zero the output layer's weights and set its bias to the training-mean label, so the
        untrained network predicts the mean-distribution baseline for every input (hidden
        layers still get gradients once the output weights move off zero). A ``base: prior``
        network gets a zero bias: it starts at its prior."""
        spec = self.spec
        head = self.body.head
        with torch.no_grad():
            head.weight.zero_()
            if spec.base == "prior":
                bias = np.zeros(head.bias.shape[0])
            elif spec.repr == "pca":
                bias = np.zeros(head.bias.shape[0])
            elif spec.label == "pmf":  # softmax
                bias = np.log(np.clip(mean_pmf, _BIAS_FLOOR, None))
                bias = bias - bias.mean()
            elif spec.output_activation == "sigmoid":
                c = np.clip(mean_cdf, _BIAS_FLOOR, 1.0 - _BIAS_FLOOR)
                bias = np.log(c) - np.log1p(-c)
            else:
                bias = np.asarray(mean_cdf, dtype=np.float64)
            head.bias.copy_(torch.as_tensor(bias, dtype=head.bias.dtype))

    def forward(self, x: torch.Tensor, log_prior: torch.Tensor | None = None) -> dict[str, torch.Tensor | None]:
        """Raw outputs of scaled inputs ``x``; a ``base: prior`` network also takes the rows'
        log(prior) (:meth:`log_prior`) and adds it to its logits."""
        out = self.body(x)
        spec = self.spec
        if spec.base == "prior":
            if log_prior is None:
                raise ValueError(f"model {spec.name}: base prior needs the rows' log(prior)")
            out = out + log_prior
        log_pmf = None
        if spec.repr == "pca":
            values = out @ self.pca_components + self.pca_mean
        elif spec.output_activation == "softmax":
            log_pmf = torch.log_softmax(out, dim=-1)
            values = torch.exp(log_pmf)
        elif spec.output_activation == "sigmoid":
            values = torch.sigmoid(out)
        else:
            values = out
        if spec.label == "pmf":
            pmf, cdf = values, torch.cumsum(values, dim=-1)
        else:
            cdf = values
            pmf = torch.diff(cdf, dim=-1, prepend=torch.zeros_like(cdf[..., :1]))
        return {"pmf": pmf, "cdf": cdf, "log_pmf": log_pmf}


# ----------------------------------------------------------------------------------------------
# A trained model on disk: weights + the input scaler (+ label PCA inside the weights)
# ----------------------------------------------------------------------------------------------


class TrainedModel(Predictor):
    """A fitted network with its input scaler: raw features in, valid distributions out
    (:class:`feeder.learn.spec.Predictor`; the network in torch, float32)."""

    def __init__(self, net: RegressionModel, scaler, label_frame: str = "part"):
        self.net = net.eval()
        super().__init__(net.spec, scaler, label_frame)

    def raw(self, x: np.ndarray, analytic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw (pmf, cdf) network outputs for scaled inputs ``x`` (N, 53 + push block), float64;
        ``analytic``: the rows' analytic PMFs (N, bins), for a ``base: prior`` model."""
        x = np.asarray(x)
        analytic = self.check_analytic(analytic, int(np.atleast_2d(x).shape[0]))
        log_prior = None if analytic is None else self.net.log_prior(analytic)
        with torch.no_grad():
            out = self.net(torch.as_tensor(x, dtype=torch.float32), log_prior)
        return out["pmf"].double().numpy(), out["cdf"].double().numpy()

    def save(self, out_dir) -> None:
        """Write ``model.pt`` (spec + weights) and ``scaler.json`` atomically into ``out_dir``.
        A ``paper+push`` model also records the names of its push features (``push_features``)."""
        import io as _io
        from pathlib import Path

        from feeder.io import write_bytes, write_json

        out_dir = Path(out_dir)
        buf = _io.BytesIO()
        blob = {
            "spec": self.spec.to_dict(),
            "n_out": int(self.net.body.head.out_features),
            "label_frame": self.label_frame,
            "state_dict": self.net.state_dict(),
        }
        if self.needs_push:
            from feeder.mechanics.features import PUSH_FEATURE_NAMES

            blob["push_features"] = list(PUSH_FEATURE_NAMES)
        torch.save(blob, buf)
        write_json(out_dir / SCALER_FILE, self.scaler.to_dict())
        write_bytes(out_dir / WEIGHTS_FILE, buf.getvalue())

    @classmethod
    def load(cls, model_dir) -> TrainedModel:
        """The model saved in ``model_dir``; one whose push features are not the ones this code
        computes (another :data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`) is a one-line FeederError."""
        from pathlib import Path

        from feeder.errors import FeederError

        model_dir = Path(model_dir)
        weights, scaler_path = model_dir / WEIGHTS_FILE, model_dir / SCALER_FILE
        for path in (weights, scaler_path):
            if not path.is_file():
                raise FeederError(f"{path}: missing (is {model_dir} a trained model directory?)")
        blob = torch.load(weights, map_location="cpu", weights_only=True)
        try:
            spec = ModelSpec.from_dict(blob["spec"])
        except ValueError as err:
            raise FeederError(f"{weights}: {err}") from None
        check_push_features(spec, blob, model_dir)
        state = blob["state_dict"]
        pca_mean = state["pca_mean"].numpy() if "pca_mean" in state else None
        pca_comp = state["pca_components"].numpy() if "pca_components" in state else None
        net = RegressionModel(spec, int(blob["n_out"]), pca_mean, pca_comp)
        net.load_state_dict(state)
        import json

        from feeder.labels.dataset import Scaler

        scaler = Scaler.from_dict(json.loads(scaler_path.read_text()))
        return cls(net, scaler, str(blob.get("label_frame", "part")))  # older models: the part frame
