"""A model's description and the post-processing of its outputs, without torch.

:class:`ModelSpec` (the architecture part of a model config, stored with the weights), the
post-processing of raw outputs into valid distributions (§3.4.1, :func:`postprocess`) and
:class:`Predictor`, what answering with a trained model takes besides its network. The networks
themselves are in :mod:`feeder.learn.models` (torch: training, evaluation) and
:mod:`feeder.learn.inference` (numpy: ``feeder predict`` and ``feeder recommend``, which so never
import torch). :mod:`feeder.learn.models` re-exports every name defined here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeder.errors import FeederError

PART_DIM = 45
FEEDER_DIM = 8
INPUT_DIM = PART_DIM + FEEDER_DIM
INPUTS = ("paper", "paper+push", "fence+push")  # model.inputs (feeder.labels.dataset.INPUTS)
NO_DFT_INPUTS = "fence+push"  # the inputs without the part's DFT: the 8 fence inputs and the push block

LABELS = ("pmf", "cdf")
REPRS = ("full", "pca")
ARCHS = ("standard", "branched")
ACTIVATIONS = ("softmax", "sigmoid", "linear")
BASES = ("mean", "prior")  # model.base: the training-mean label, or the analytic prior of each row
# Floor of the prior's bins before the log (a bin the prior leaves empty can still be reached).
PRIOR_FLOOR = 1e-9


@dataclass(frozen=True)
class ModelSpec:
    """The architecture part of a model config (plain values, stored with the weights)."""

    name: str
    label: str
    repr: str
    arch: str
    output_activation: str
    bins: int
    components: int | None = None
    hidden: tuple[int, ...] = ()
    part_hidden: tuple[int, ...] = ()
    feeder_hidden: tuple[int, ...] = ()
    shared_hidden: tuple[int, ...] = ()
    inputs: str = "paper"
    base: str = "mean"

    def __post_init__(self) -> None:
        if self.inputs not in INPUTS:
            raise ValueError(f"model {self.name}: inputs must be one of {INPUTS}, got {self.inputs!r}")
        if self.inputs == NO_DFT_INPUTS and self.arch != "standard":
            raise ValueError(
                f"model {self.name}: inputs {NO_DFT_INPUTS} has no DFT for a part branch: it needs arch standard"
            )
        if self.label not in LABELS:
            raise ValueError(f"model {self.name}: label must be one of {LABELS}, got {self.label!r}")
        if self.repr not in REPRS:
            raise ValueError(f"model {self.name}: repr must be one of {REPRS}, got {self.repr!r}")
        if self.arch not in ARCHS:
            raise ValueError(f"model {self.name}: arch must be one of {ARCHS}, got {self.arch!r}")
        if self.output_activation not in ACTIVATIONS:
            raise ValueError(f"model {self.name}: output_activation must be one of {ACTIVATIONS}")
        if self.output_activation == "softmax" and not (self.label == "pmf" and self.repr == "full"):
            raise ValueError(f"model {self.name}: softmax output is only for full PMF labels")
        if self.label == "pmf" and self.repr == "full" and self.output_activation != "softmax":
            raise ValueError(f"model {self.name}: a full PMF output needs softmax")
        if self.repr == "pca" and self.output_activation != "linear":
            raise ValueError(f"model {self.name}: PCA scores need a linear output")
        if self.repr == "pca" and not (self.components and self.components > 0):
            raise ValueError(f"model {self.name}: PCA labels need a positive number of components")
        if self.base not in BASES:
            raise ValueError(f"model {self.name}: base must be one of {BASES}, got {self.base!r}")
        if self.base == "prior" and self.output_activation != "softmax":
            raise ValueError(f"model {self.name}: base prior adds log(prior) to softmax logits: it needs a full PMF")

    @classmethod
    def from_config(cls, model_cfg, bins: int) -> ModelSpec:
        get = model_cfg.get  # a dict or an OmegaConf DictConfig

        def tup(key: str) -> tuple[int, ...]:
            return tuple(int(v) for v in (get(key) or ()))

        return cls(
            name=str(get("name")),
            label=str(get("label")),
            repr=str(get("repr")),
            arch=str(get("arch")),
            output_activation=str(get("output_activation")),
            bins=int(bins),
            components=None if get("components") is None else int(get("components")),
            hidden=tup("hidden"),
            part_hidden=tup("part_hidden"),
            feeder_hidden=tup("feeder_hidden"),
            shared_hidden=tup("shared_hidden"),
            inputs=str(get("inputs") or "paper"),
            base=str(get("base") or "mean"),
        )

    @property
    def push_dim(self) -> int:
        """Width of the push block in the network input (0 for the paper's inputs)."""
        if self.inputs == "paper":
            return 0
        from feeder.mechanics.features import PUSH_FEATURE_NAMES

        return len(PUSH_FEATURE_NAMES)

    @property
    def part_dim(self) -> int:
        """Width of the part's DFT block in the network input (0 for ``fence+push``)."""
        return 0 if self.inputs == NO_DFT_INPUTS else PART_DIM

    @property
    def input_dim(self) -> int:
        return self.part_dim + FEEDER_DIM + self.push_dim

    def to_dict(self) -> dict:
        """Plain values; ``inputs`` only when it is not ``paper`` and ``base`` only when it is not
        ``mean``, so an older model's saved spec (and its model.pt, byte for byte) is what it was
        before the keys existed."""
        out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}
        if out["inputs"] == "paper":
            del out["inputs"]
        if out["base"] == "mean":
            del out["base"]
        return out

    @classmethod
    def from_dict(cls, d: dict) -> ModelSpec:
        d = dict(d)
        for k in ("hidden", "part_hidden", "feeder_hidden", "shared_hidden"):
            d[k] = tuple(d.get(k) or ())
        return cls(**d)


# ----------------------------------------------------------------------------------------------
# Post-processing (§3.4.1)
# ----------------------------------------------------------------------------------------------
def isotonic_increasing(y: np.ndarray) -> np.ndarray:
    """Least-squares projection of a 1-D sequence onto non-decreasing sequences
    (pool adjacent violators, equal weights)."""
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError("isotonic_increasing takes one sequence")
    vals: list[float] = []
    wts: list[int] = []
    for v in y.tolist():
        val, w = v, 1
        while vals and vals[-1] > val:
            pv, pw = vals.pop(), wts.pop()
            val = (pv * pw + val * w) / (pw + w)
            w += pw
        vals.append(val)
        wts.append(w)
    return np.repeat(np.asarray(vals), wts)


def postprocess_cdf(cdf: np.ndarray) -> np.ndarray:
    """Isotonic projection of every row, clipped at 0, divided by its last value.
    A row whose projected last value is not positive becomes the uniform CDF."""
    cdf = np.atleast_2d(np.asarray(cdf, dtype=np.float64))
    out = np.empty_like(cdf)
    bins = cdf.shape[1]
    uniform = np.arange(1, bins + 1) / bins
    for i, row in enumerate(cdf):
        iso = np.clip(isotonic_increasing(row), 0.0, None)
        last = iso[-1]
        out[i] = iso / last if last > 0 and np.isfinite(last) else uniform
    return out


def postprocess_pmf(pmf: np.ndarray) -> np.ndarray:
    """Clip rows at 0 and renormalise to sum 1 (an all-zero row becomes uniform)."""
    pmf = np.clip(np.atleast_2d(np.asarray(pmf, dtype=np.float64)), 0.0, None)
    total = pmf.sum(axis=1, keepdims=True)
    uniform = np.full(pmf.shape[1], 1.0 / pmf.shape[1])
    return np.where(total > 0, pmf / np.where(total > 0, total, 1.0), uniform)


def postprocess(spec: ModelSpec, raw_pmf: np.ndarray, raw_cdf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Valid (pmf, cdf) rows from raw network outputs, per §3.4.1."""
    if spec.label == "cdf":
        cdf = postprocess_cdf(raw_cdf)
        pmf = np.diff(cdf, axis=1, prepend=0.0)
        return pmf, cdf
    if spec.repr == "pca":
        pmf = postprocess_pmf(raw_pmf)
    else:  # softmax: valid by construction
        pmf = np.atleast_2d(np.asarray(raw_pmf, dtype=np.float64))
        pmf = pmf / pmf.sum(axis=1, keepdims=True)  # float32 -> float64 round-off only
    return pmf, np.cumsum(pmf, axis=1)


# ----------------------------------------------------------------------------------------------
# A trained model's prediction interface (torch or numpy underneath)
# ----------------------------------------------------------------------------------------------
WEIGHTS_FILE = "model.pt"
SCALER_FILE = "scaler.json"  # feeder.labels.dataset.Scaler.to_dict()


def check_push_features(spec: ModelSpec, blob: dict, model_dir) -> None:
    """Refuse a saved model whose push features are not the ones this code computes (another
    :data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`): a one-line FeederError."""
    if not spec.push_dim:
        return
    from feeder.mechanics.features import PUSH_FEATURE_NAMES

    if tuple(blob.get("push_features") or ()) != PUSH_FEATURE_NAMES:
        raise FeederError(
            f"{model_dir}: the model was trained on other push features than this code computes: retrain it"
        )


class Predictor:
    """What answering with a trained model takes besides its network: the spec, the input scaler,
    the label frame and the post-processing. A subclass gives :meth:`raw`, the network's raw
    outputs (:class:`feeder.learn.models.TrainedModel` in torch, :class:`feeder.learn.inference.NumpyModel`
    in numpy)."""

    def __init__(self, spec: ModelSpec, scaler, label_frame: str = "part"):
        self.spec = spec
        self.scaler = scaler
        self.label_frame = label_frame  # labels.frame of the training data (feeder.labels.metrics)
        if scaler.inputs != spec.inputs:
            raise FeederError(
                f"model {spec.name}: its scaler is for inputs {scaler.inputs}, the network takes {spec.inputs}"
            )

    @property
    def inputs(self) -> str:
        """``model.inputs``: ``paper``, ``paper+push`` or ``fence+push``."""
        return self.spec.inputs

    @property
    def needs_push(self) -> bool:
        """Whether predictions need the analytic push block (``model.inputs``: ``paper+push``,
        ``fence+push``)."""
        return self.spec.inputs != "paper"

    @property
    def needs_analytic(self) -> bool:
        """Whether predictions need each configuration's analytic PMF (``model.base: prior``)."""
        return self.spec.base == "prior"

    def check_analytic(self, analytic, n: int) -> np.ndarray | None:
        """The rows' analytic PMFs (n, bins) as float64 for a ``base: prior`` model (a one-line
        FeederError when they are missing or of another shape); None for any other model."""
        if not self.needs_analytic:
            return None
        if analytic is None:
            raise FeederError(
                f"model {self.spec.name} starts from the analytic prior (model.base: prior): it needs the "
                "configurations' analytic PMFs (the dataset's pmf_analytic, or the part's outline)"
            )
        analytic = np.atleast_2d(np.asarray(analytic, dtype=np.float64))
        if analytic.shape != (n, self.spec.bins):
            raise FeederError(
                f"model {self.spec.name}: analytic PMFs of shape {analytic.shape}, need ({n}, {self.spec.bins})"
            )
        return analytic

    def raw(self, x: np.ndarray, analytic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def predict_scaled(self, x: np.ndarray, analytic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Post-processed (pmf, cdf) for scaled inputs."""
        return postprocess(self.spec, *self.raw(x, analytic))

    def predict(
        self,
        part_raw: np.ndarray,
        feeder_raw: np.ndarray,
        push_raw: np.ndarray | None = None,
        analytic: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Post-processed (pmf, cdf) for raw DFT triplets (N, 45) and feeder vectors (N, 8), and
        for a ``paper+push`` model the raw push features (N, P) (a one-line FeederError without
        them; a paper model ignores them); for a ``base: prior`` model also the analytic PMFs
        (N, bins) in the label frame."""
        push = None if push_raw is None or not self.needs_push else np.atleast_2d(push_raw)
        x = self.scaler.transform(np.atleast_2d(part_raw), np.atleast_2d(feeder_raw), push)
        return self.predict_scaled(x, analytic)

    def predict_rows(self, data: dict, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`predict` on the rows ``rows`` (default all) of a dataset dict
        (:func:`feeder.labels.dataset.load_dataset`), with the inputs the model takes."""
        from feeder.labels.dataset import raw_inputs

        analytic = None
        if self.needs_analytic:
            if "pmf_analytic" not in data:
                raise FeederError(f"model {self.spec.name}: the dataset has no pmf_analytic (rebuild it)")
            analytic = np.asarray(data["pmf_analytic"])[slice(None) if rows is None else rows]
        return self.predict(*raw_inputs(data, self.spec.inputs, rows), analytic=analytic)
