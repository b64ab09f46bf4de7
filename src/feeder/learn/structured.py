"""A predictor with the truth's structure (issue #39, item 2): weights over candidate resting
orientations, small offsets and widths, diffuse components, and the ok mass as its own head.

Per configuration the predicted PMF over ``bins`` yaw bins (label frame) is the mixture

    p = Σ_k π_k · g(μ_k + δ_k, σ_k) + Σ_d π_d · D_d,

with ``μ_k`` the candidates of :mod:`feeder.mechanics.candidates` (modes of the analytic push
model and its variants), ``g`` a wrapped Gaussian normalised over the bins, ``δ_k`` an offset of at
most ``max_offset_deg`` and ``σ_k ≥ sigma_min_deg``, and ``D_d`` the diffuse components (the
analytic PMF, the analytic PMF widened, the uniform PMF and the training-mean PMF:
:func:`diffuse_components`). The weights are one softmax over candidates and diffuse components,
started (``model.start``, :func:`prior_logits`) either on the analytic PMF itself or on the base
variant's masses over the candidates, so an untrained network is (close to) the analytic PMF.
A small network reads the configuration's push and fence inputs and each candidate's masses
under the variants. It is trained by circular W1 on the CDF (:func:`circular_w1_loss`), full
batch, early-stopped on validation rows (patience counted in optimiser steps).

The ok mass (the share of drops that neither jam nor fall off) is a separate small network
(:class:`OkNet`, binary cross-entropy on the ok share) trained on every configuration, those the
dataset excludes as jammed included.

Inputs are built once per dataset by :func:`feeder.learn.structured_data.structured_arrays`; this
module holds the pure array helpers and the torch model.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from feeder.circular import FULL_TURN_DEG
from feeder.errors import FeederError

OK_FLOOR = 1e-3  # the analytic ok mass is clipped to [OK_FLOOR, 1 - OK_FLOOR] before its logit
LOGIT_FLOOR = 1e-3  # mass added before the log of the analytic masses (an empty candidate stays reachable)
DIFFUSE = ("analytic", "analytic_wide", "uniform", "mean")  # the diffuse components, in order
# candidates: a logit, an offset and a width per candidate from its own masses and the configuration;
# variants: one weight per variant (and diffuse component) from the configuration, each candidate
# getting the variants' masses so weighed, one shared width and no offset (far fewer outputs)
KINDS = ("candidates", "variants")
# where the weights start: the analytic PMF itself (candidates and other components at a floor), or
# the base variant's masses on the candidates (their Gaussians at bin centres cost ~0.5 deg cW1)
STARTS = ("analytic", "candidates")
VARIANT_START_LOGIT = -4.0  # starting logit of every variant but the base, and of the diffuse components


# ----------------------------------------------------------------------------------------------
# Pure helpers (numpy)
# ----------------------------------------------------------------------------------------------
def wrapped_gaussian_bins(centre_deg, sigma_deg, bins: int) -> np.ndarray:
    """A wrapped Gaussian of mean ``centre_deg`` and SD ``sigma_deg`` evaluated at the ``bins``
    bin centres and normalised to sum 1 over them (broadcast over leading axes)."""
    centres = (np.arange(int(bins)) + 0.5) * (FULL_TURN_DEG / int(bins))
    c = np.asarray(centre_deg, dtype=np.float64)[..., None]
    s = np.asarray(sigma_deg, dtype=np.float64)[..., None]
    d = np.mod(centres - c + FULL_TURN_DEG / 2, FULL_TURN_DEG) - FULL_TURN_DEG / 2
    g = np.exp(-0.5 * (d / s) ** 2)
    return g / g.sum(axis=-1, keepdims=True)


def mixture_pmf(weights_cand, centres_deg, sigmas_deg, weights_diffuse, diffuse) -> np.ndarray:
    """``Σ_k w_k g(c_k, σ_k) + Σ_d v_d D_d`` per row: ``weights_cand``, ``centres_deg``,
    ``sigmas_deg`` (N, K); ``weights_diffuse`` (N, C); ``diffuse`` (N, C, bins)."""
    diffuse = np.asarray(diffuse, dtype=np.float64)
    g = wrapped_gaussian_bins(centres_deg, sigmas_deg, diffuse.shape[-1])
    return np.einsum("nk,nkb->nb", np.asarray(weights_cand), g) + np.einsum(
        "nc,ncb->nb", np.asarray(weights_diffuse), diffuse
    )


def prior_logits(
    base_masses,
    mask,
    start: str = "candidates",
    floor: float = LOGIT_FLOOR,
    diffuse_floor: float = LOGIT_FLOOR,
    n_extra: int = 0,
) -> tuple:
    """Starting logits (``-inf`` where ``mask`` is False) per candidate and per diffuse component
    (in the order of :data:`DIFFUSE`). ``start`` ``candidates``: ``log(m_k + floor)`` of the base
    variant's basin masses ``base_masses`` (N, K), the analytic PMF's mass left outside the
    candidates for ``analytic`` and ``diffuse_floor`` for the other components; ``analytic``:
    every candidate ``log(floor)``, the analytic component ``log(1)`` and the others
    ``log(diffuse_floor)`` (the untrained network is the analytic PMF up to those floors).
    ``n_extra`` further diffuse components (the part's neighbouring labels) start at ``diffuse_floor``."""
    if start not in STARTS:
        raise FeederError(f"model.start must be one of {STARTS}, got {start!r}")
    m = np.asarray(base_masses, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    diff = np.full((m.shape[0], len(DIFFUSE) + int(n_extra)), math.log(diffuse_floor))
    if start == "analytic":
        diff[:, 0] = 0.0
        return np.where(mask, math.log(floor), -np.inf), diff
    cand = np.where(mask, np.log(np.where(mask, m, 0.0) + floor), -np.inf)
    rest = np.clip(1.0 - np.where(mask, m, 0.0).sum(axis=1), 0.0, 1.0)
    diff[:, 0] = np.log(rest + floor)
    return cand, diff


def ok_logit(analytic_ok) -> np.ndarray:
    """The logit of the analytic ok mass clipped to [:data:`OK_FLOOR`, 1 − :data:`OK_FLOOR`]."""
    a = np.clip(np.asarray(analytic_ok, dtype=np.float64), OK_FLOOR, 1.0 - OK_FLOOR)
    return np.log(a / (1.0 - a))


def diffuse_components(analytic, mean_pmf, wide_sigma_bins: float, extra=None) -> np.ndarray:
    """(N, 4 + J, bins) diffuse components of :data:`DIFFUSE`: the rows' analytic PMFs, the same
    widened by a wrapped Gaussian of ``wide_sigma_bins``, the uniform PMF and ``mean_pmf``; then
    the J PMFs of ``extra`` (N, J, bins) per row (the part's neighbouring labels), if given."""
    from feeder.circular import wrapped_gaussian_smooth

    a = np.atleast_2d(np.asarray(analytic, dtype=np.float64))
    n, bins = a.shape
    wide = wrapped_gaussian_smooth(a, float(wide_sigma_bins))
    uni = np.full((n, bins), 1.0 / bins)
    mean = np.broadcast_to(np.asarray(mean_pmf, dtype=np.float64), (n, bins))
    out = np.stack([a, wide, uni, mean], axis=1)
    if extra is not None and np.asarray(extra).shape[1]:
        out = np.concatenate([out, np.asarray(extra, dtype=np.float64)], axis=1)
    return out


def row_diffuse(arrays: dict, rows, mean_pmf) -> np.ndarray:
    """:func:`diffuse_components` of ``rows``, with ``arrays["neighbour_pmf"]`` where present."""
    extra = arrays.get("neighbour_pmf")
    return diffuse_components(
        arrays["analytic"][rows], mean_pmf, float(arrays["wide_sigma_bins"]), None if extra is None else extra[rows]
    )


# ----------------------------------------------------------------------------------------------
# Torch model
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class NetSettings:
    hidden: int
    max_offset_deg: float
    sigma_min_deg: float
    sigma_init_deg: float
    sigma_max_deg: float
    kind: str = "candidates"  # one of KINDS
    start: str = "candidates"  # one of STARTS
    neighbour_start_logit: float = math.log(LOGIT_FLOOR)  # starting logit of each neighbour component

    def __post_init__(self) -> None:
        if self.start not in STARTS:
            raise FeederError(f"model: start must be one of {STARTS}, got {self.start!r}")
        if self.kind not in KINDS:
            raise FeederError(f"model: kind must be one of {KINDS}, got {self.kind!r}")
        if not 0 < self.sigma_min_deg < self.sigma_init_deg < self.sigma_max_deg:
            raise FeederError(
                f"model: need 0 < sigma_min_deg < sigma_init_deg < sigma_max_deg, got "
                f"{self.sigma_min_deg}, {self.sigma_init_deg}, {self.sigma_max_deg}"
            )
        if self.hidden < 1 or self.max_offset_deg < 0:
            raise FeederError(f"model: hidden {self.hidden} must be >= 1 and max_offset_deg {self.max_offset_deg} >= 0")


TAIL_SIGMAS = 4.0  # a candidate's Gaussian is evaluated out to this many of its widest SD past its largest offset


def window_half_bins(s: NetSettings, bins: int) -> int:
    """Half-width (bins) of the window a candidate's Gaussian is evaluated on."""
    return int(math.ceil((TAIL_SIGMAS * s.sigma_max_deg + s.max_offset_deg) * bins / FULL_TURN_DEG)) + 1


def circular_w1_loss(pmf_pred, cdf_true):
    """Mean circular W1 (degrees per bin × bins) between predicted PMF rows and true CDF rows, as
    :func:`feeder.labels.metrics.circular_w1` (torch, differentiable almost everywhere)."""
    bins = cdf_true.shape[-1]
    d = pmf_pred.cumsum(dim=-1) - cdf_true
    med = d.median(dim=-1, keepdim=True).values
    return ((d - med).abs().sum(dim=-1) * (FULL_TURN_DEG / bins)).mean()


def _torch():
    import torch

    return torch


def _gaussians(torch, s, pos, delta, sigma, weights, bins: int):
    """(N, bins): Σ_k weights_k · g(pos_k + delta_k, sigma_k), each Gaussian evaluated on the bins
    within ±:func:`window_half_bins` of the bin holding ``pos_k`` and renormalised there."""
    n = pos.shape[0]
    width = FULL_TURN_DEG / bins
    half = window_half_bins(s, bins)
    steps = torch.arange(-half, half + 1)
    home = torch.floor(pos / width).long()  # (N, K) bin of the candidate
    d = (home[..., None] + steps + 0.5).to(pos.dtype) * width - (pos + delta)[..., None]
    g = torch.exp(-0.5 * (d / sigma[..., None]) ** 2)
    g = g / g.sum(dim=-1, keepdim=True)
    idx = torch.remainder(home[..., None] + steps, bins).reshape(n, -1)
    return torch.zeros(n, bins, dtype=pos.dtype).scatter_add(1, idx, (weights[..., None] * g).reshape(n, -1))


def sigma_shift(s: NetSettings) -> float:
    """The shift that makes ``sigma_min + (sigma_max − sigma_min) sigmoid(raw + shift)`` equal
    ``sigma_init`` at ``raw = 0``."""
    frac = (s.sigma_init_deg - s.sigma_min_deg) / (s.sigma_max_deg - s.sigma_min_deg)
    return math.log(frac / (1.0 - frac))


def make_nets(d_cfg: int, d_cand: int, n_diffuse: int, s: NetSettings, n_variants: int = 0):
    """(PMF network of ``s.kind``, OkNet) as torch modules (:func:`forward_numpy` answers the PMF
    network's state in numpy)."""
    torch = _torch()
    nn = torch.nn

    def width(raw):
        return s.sigma_min_deg + (s.sigma_max_deg - s.sigma_min_deg) * torch.sigmoid(raw + sigma_shift(s))

    class VariantNet(nn.Module):
        def __init__(self):
            super().__init__()
            h = int(s.hidden)
            self.net = nn.Sequential(nn.Linear(d_cfg, h), nn.ReLU(), nn.Linear(h, n_variants + n_diffuse))
            nn.init.zeros_(self.net[-1].weight)
            nn.init.zeros_(self.net[-1].bias)
            # the base variant (others at VARIANT_START_LOGIT), or the analytic PMF (others at the floor)
            rest = VARIANT_START_LOGIT if s.start == "candidates" else math.log(LOGIT_FLOOR)
            start = torch.full((n_variants + n_diffuse,), rest)
            start[0 if s.start == "candidates" else n_variants] = 0.0
            start[n_variants + len(DIFFUSE) :] = s.neighbour_start_logit  # the part's neighbouring labels
            self.register_buffer("start", start)
            self.sigma_raw = nn.Parameter(torch.zeros(()))

        def forward(self, x, cf, mask, pos, logit_c, logit_d, diffuse, masses, offset_d):
            logits = self.net(x) + self.start
            logits = torch.cat([logits[:, :n_variants], logits[:, n_variants:] + offset_d], dim=1)
            a = torch.softmax(logits, dim=1)
            av, ad = a[:, :n_variants], a[:, n_variants:]
            m = masses * mask[..., None]
            wc = (m * av[:, None, :]).sum(dim=-1)  # (N, K)
            rest = (av * (1.0 - m.sum(dim=1)).clamp(min=0.0)).sum(dim=1)  # the variants' mass off the candidates
            wd = torch.cat([ad[:, :1] + rest[:, None], ad[:, 1:]], dim=1)
            sigma = width(self.sigma_raw).expand_as(pos)
            cand = _gaussians(torch, s, pos, torch.zeros_like(pos), sigma, wc, diffuse.shape[-1])
            return cand + (wd[..., None] * diffuse).sum(dim=1)

    class StructuredNet(nn.Module):
        def __init__(self):
            super().__init__()
            h = int(s.hidden)
            self.cfg = nn.Sequential(nn.Linear(d_cfg, h), nn.ReLU())
            self.cand = nn.Sequential(nn.Linear(d_cand + h, h), nn.ReLU(), nn.Linear(h, 3))
            self.diff = nn.Linear(h, n_diffuse)
            for layer in (self.cand[-1], self.diff):  # start at the analytic masses
                nn.init.zeros_(layer.weight)
                nn.init.zeros_(layer.bias)

        def forward(self, x, cf, mask, pos, logit_c, logit_d, diffuse, masses, offset_d):
            h = self.cfg(x)
            k = cf.shape[1]
            out = self.cand(torch.cat([cf, h[:, None, :].expand(-1, k, -1)], dim=-1))
            lc = torch.where(mask, logit_c + out[..., 0], torch.full_like(logit_c, -1e9))
            ld = logit_d + offset_d + self.diff(h)
            w = torch.softmax(torch.cat([lc, ld], dim=1), dim=1)
            wc, wd = w[:, :k], w[:, k:]
            delta = s.max_offset_deg * torch.tanh(out[..., 1])
            cand = _gaussians(torch, s, pos, delta, width(out[..., 2]), wc, diffuse.shape[-1])
            return cand + (wd[..., None] * diffuse).sum(dim=1)

    class OkNet(nn.Module):
        """The ok share's logit: the analytic ok mass's plus a correction from the inputs (zero
        at the start)."""

        def __init__(self):
            super().__init__()
            h = int(s.hidden)
            self.net = nn.Sequential(nn.Linear(d_cfg, h), nn.ReLU(), nn.Linear(h, 1))
            nn.init.zeros_(self.net[-1].weight)
            nn.init.zeros_(self.net[-1].bias)

        def forward(self, x, base_logit):
            return base_logit + self.net(x)[:, 0]

    return (StructuredNet() if s.kind == "candidates" else VariantNet()), OkNet()


BATCH_INPUTS = ("x", "cf", "mask", "pos", "logit_c", "logit_d", "diffuse", "masses", "offset_d")


def batch_inputs(arrays: dict, rows, diffuse: np.ndarray, start: str = "candidates") -> dict:
    """The networks' inputs of ``rows`` (:data:`BATCH_INPUTS`, numpy): the starting logits of
    :func:`prior_logits` (``-1e9`` for a masked candidate) and, per diffuse component, the offset of
    its starting logit (``arrays["neighbour_offset"]`` for the neighbours' components, else 0)."""
    rows = np.asarray(rows)
    n_extra = np.asarray(diffuse).shape[1] - len(DIFFUSE)
    lc, ld = prior_logits(arrays["base_mass"][rows], arrays["mask"][rows], start, n_extra=n_extra)
    offset = np.zeros(ld.shape)
    if "neighbour_offset" in arrays:
        offset[:, len(DIFFUSE) :] = arrays["neighbour_offset"][rows]
    return {
        "x": arrays["x"][rows],
        "cf": arrays["cf"][rows],
        "mask": arrays["mask"][rows],
        "pos": arrays["pos"][rows],
        "logit_c": np.where(np.isfinite(lc), lc, -1e9),
        "logit_d": ld,
        "diffuse": np.asarray(diffuse),
        "masses": arrays["masses"][rows],
        "offset_d": offset,
    }


# ----------------------------------------------------------------------------------------------
# The PMF network in numpy (feeder predict never imports torch)
# ----------------------------------------------------------------------------------------------
def _linear(params: dict, name: str, a: np.ndarray) -> np.ndarray:
    return a @ params[f"{name}.weight"].T + params[f"{name}.bias"]


def _softmax(z: np.ndarray) -> np.ndarray:
    e = np.exp(z - z.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


def _width_np(raw, s: NetSettings) -> np.ndarray:
    return s.sigma_min_deg + (s.sigma_max_deg - s.sigma_min_deg) / (1.0 + np.exp(-(np.asarray(raw) + sigma_shift(s))))


def gaussians_np(s: NetSettings, pos, delta, sigma, weights, bins: int) -> np.ndarray:
    """(N, bins): the torch networks' windowed sum of weighted Gaussians (``_gaussians``) in numpy."""
    pos = np.asarray(pos, dtype=np.float64)
    n = pos.shape[0]
    width = FULL_TURN_DEG / bins
    half = window_half_bins(s, bins)
    steps = np.arange(-half, half + 1)
    home = np.floor(pos / width).astype(np.int64)
    d = (home[..., None] + steps + 0.5) * width - (pos + delta)[..., None]
    g = np.exp(-0.5 * (d / np.asarray(sigma)[..., None]) ** 2)
    g = g / g.sum(axis=-1, keepdims=True)
    idx = np.mod(home[..., None] + steps, bins).reshape(n, -1)
    out = np.zeros((n, bins))
    np.add.at(
        out, (np.repeat(np.arange(n), idx.shape[1]), idx.ravel()), (np.asarray(weights)[..., None] * g).reshape(-1)
    )
    return out


def forward_numpy(params: dict, s: NetSettings, n_variants: int, b: dict) -> np.ndarray:
    """The PMF network of ``s.kind`` (:func:`make_nets`) with the state ``params`` (its
    ``state_dict`` as numpy arrays) on the inputs ``b`` of :func:`batch_inputs`, in float64: (N, bins)."""
    x, mask, pos, diffuse = b["x"], np.asarray(b["mask"], dtype=bool), b["pos"], b["diffuse"]
    bins = diffuse.shape[-1]
    if s.kind == "variants":
        logits = _linear(params, "net.2", np.maximum(_linear(params, "net.0", x), 0.0)) + params["start"]
        logits = np.concatenate([logits[:, :n_variants], logits[:, n_variants:] + b["offset_d"]], axis=1)
        a = _softmax(logits)
        av, ad = a[:, :n_variants], a[:, n_variants:]
        m = b["masses"] * mask[..., None]
        wc = (m * av[:, None, :]).sum(axis=-1)
        rest = (av * np.clip(1.0 - m.sum(axis=1), 0.0, None)).sum(axis=1)
        wd = np.concatenate([ad[:, :1] + rest[:, None], ad[:, 1:]], axis=1)
        sigma = np.broadcast_to(_width_np(params["sigma_raw"], s), pos.shape)
        cand = gaussians_np(s, pos, np.zeros_like(pos), sigma, wc, bins)
    else:
        h = np.maximum(_linear(params, "cfg.0", x), 0.0)
        k = b["cf"].shape[1]
        z = np.concatenate([b["cf"], np.broadcast_to(h[:, None, :], (h.shape[0], k, h.shape[1]))], axis=-1)
        out = _linear(params, "cand.2", np.maximum(_linear(params, "cand.0", z), 0.0))
        lc = np.where(mask, b["logit_c"] + out[..., 0], -1e9)
        ld = b["logit_d"] + b["offset_d"] + _linear(params, "diff", h)
        w = _softmax(np.concatenate([lc, ld], axis=1))
        wc, wd = w[:, :k], w[:, k:]
        delta = s.max_offset_deg * np.tanh(out[..., 1])
        cand = gaussians_np(s, pos, delta, _width_np(out[..., 2], s), wc, bins)
    return cand + (wd[..., None] * diffuse).sum(axis=1)


@dataclass
class Batch:
    """Model inputs of a set of rows as torch tensors (float32)."""

    x: object
    cf: object
    mask: object
    pos: object
    logit_c: object
    logit_d: object
    diffuse: object
    masses: object
    offset_d: object  # per row and diffuse component: added to its starting logit (the neighbours' basins)

    @classmethod
    def of(cls, arrays: dict, rows, diffuse: np.ndarray, start: str = "candidates"):
        torch = _torch()
        b = batch_inputs(arrays, rows, diffuse, start)
        t = lambda a: torch.as_tensor(np.ascontiguousarray(a), dtype=torch.float32)  # noqa: E731
        return cls(**{k: torch.as_tensor(v) if k == "mask" else t(v) for k, v in b.items()})

    def args(self):
        return (
            self.x,
            self.cf,
            self.mask,
            self.pos,
            self.logit_c,
            self.logit_d,
            self.diffuse,
            self.masses,
            self.offset_d,
        )


@dataclass(frozen=True)
class TrainSettings:
    lr: float
    weight_decay: float
    max_steps: int
    eval_every: int
    patience_steps: int
    ok_loss: str = "bce"


@dataclass
class Fitted:
    net: object
    ok_net: object
    steps: int  # optimiser steps of the kept PMF state
    ok_steps: int
    val_cw1: float  # validation circular W1 of the kept state (degrees)
    val_ok_mae: float
    start: str = "candidates"  # NetSettings.start of the network


def _early_stopped(module, loss_fn, val_fn, t: TrainSettings, seed: int):
    """Train ``module`` full batch with Adam on ``loss_fn()``, evaluating ``val_fn()`` every
    ``eval_every`` steps; stop after ``patience_steps`` steps without a better validation score
    and return (best step, best score) with the best state loaded."""
    torch = _torch()
    torch.manual_seed(int(seed))
    opt = torch.optim.Adam(module.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    with torch.no_grad():
        best, best_step = float(val_fn()), 0
    state = copy.deepcopy(module.state_dict())
    for step in range(1, int(t.max_steps) + 1):
        opt.zero_grad()
        loss = loss_fn()
        loss.backward()
        opt.step()
        if step % int(t.eval_every) == 0:
            with torch.no_grad():
                score = float(val_fn())
            if score < best:
                best, best_step, state = score, step, copy.deepcopy(module.state_dict())
            elif step - best_step >= int(t.patience_steps):
                break
    module.load_state_dict(state)
    return best_step, best


def _seeded_nets(arrays: dict, n_diffuse: int, net: NetSettings, seed: int):
    """The untrained (PMF, ok) networks for ``arrays``' inputs, their weights drawn from ``seed``."""
    torch = _torch()
    torch.manual_seed(int(seed))
    pmf_net, ok_net = make_nets(arrays["x"].shape[1], arrays["cf"].shape[2], n_diffuse, net, arrays["masses"].shape[2])
    return pmf_net.float(), ok_net.float()


def _trained(module, loss_fn, t: TrainSettings, seed: int, steps: int) -> None:
    """Train ``module`` full batch with Adam on ``loss_fn()`` for exactly ``steps`` steps: the
    optimiser of :func:`_early_stopped` without a validation set (a refit for a step count that
    early stopping chose)."""
    torch = _torch()
    torch.manual_seed(int(seed))
    opt = torch.optim.Adam(module.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    for _ in range(int(steps)):
        opt.zero_grad()
        loss_fn().backward()
        opt.step()


def refit(
    arrays: dict,
    rows,
    ok_rows,
    mean_pmf,
    net: NetSettings,
    t: TrainSettings,
    seed: int,
    steps: int,
    ok_steps: int,
    ok_train=None,
) -> Fitted:
    """Train both networks as :func:`fit` does, from the same ``seed``'s initial weights, on the
    kept rows ``rows`` (the PMF network) and ``ok_rows`` (the ok network) for the given step
    counts, with no validation rows: early stopping on a fit's validation parts chose the counts,
    and the refit trains on those parts too. Its validation scores are NaN (nothing is held out)."""
    torch = _torch()
    ok_train = t if ok_train is None else ok_train
    rows, ok_rows = np.asarray(rows), np.asarray(ok_rows)
    if rows.size == 0 or ok_rows.size == 0:
        raise FeederError("a structured refit needs rows to train on")
    if int(steps) < 0 or int(ok_steps) < 0:
        raise FeederError(f"a structured refit needs step counts >= 0, got {steps} and {ok_steps}")
    df = row_diffuse(arrays, rows, mean_pmf)
    pmf_net, ok_net = _seeded_nets(arrays, df.shape[1], net, seed)
    b = Batch.of(arrays, rows, df, net.start)
    cdf = torch.as_tensor(arrays["cdf"][rows], dtype=torch.float32)
    _trained(pmf_net, lambda: circular_w1_loss(pmf_net(*b.args()), cdf), t, seed, steps)
    f32 = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    xo, bo, yo = f32(arrays["x"][ok_rows]), f32(ok_logit(arrays["analytic_ok"][ok_rows])), f32(arrays["ok"][ok_rows])
    bce = torch.nn.functional.binary_cross_entropy_with_logits
    _trained(ok_net, lambda: bce(ok_net(xo, bo), yo), ok_train, seed + 1, ok_steps)
    return Fitted(pmf_net, ok_net, int(steps), int(ok_steps), float("nan"), float("nan"), net.start)


def fit(
    arrays: dict,
    fit_rows,
    val_rows,
    fit_ok,
    val_ok,
    mean_pmf,
    net: NetSettings,
    t: TrainSettings,
    seed: int,
    ok_train=None,
    val_arrays: dict | None = None,
) -> Fitted:
    """Train the PMF network on the kept rows ``fit_rows`` (early-stopped by circular W1 on
    ``val_rows``) and the ok network on ``fit_ok`` (early-stopped by the mean absolute error of
    the ok share on ``val_ok``); the rows index ``arrays`` (:func:`feeder.learn.structured_data`),
    the validation rows ``val_arrays`` (default ``arrays``: they differ where the inputs depend on
    which labels a row may see, the part's neighbours). ``seed`` sets the initial weights;
    ``ok_train`` (default ``t``) the ok network's training."""
    torch = _torch()
    ok_train = t if ok_train is None else ok_train
    fit_rows, val_rows = np.asarray(fit_rows), np.asarray(val_rows)
    if fit_rows.size == 0 or val_rows.size == 0:
        raise FeederError("the structured predictor needs fit and validation rows")
    va = arrays if val_arrays is None else val_arrays
    df = row_diffuse(arrays, fit_rows, mean_pmf)
    pmf_net, ok_net = _seeded_nets(arrays, df.shape[1], net, seed)
    bf = Batch.of(arrays, fit_rows, df, net.start)
    bv = Batch.of(va, val_rows, row_diffuse(va, val_rows, mean_pmf), net.start)
    cdf_f = torch.as_tensor(arrays["cdf"][fit_rows], dtype=torch.float32)
    cdf_v = torch.as_tensor(va["cdf"][val_rows], dtype=torch.float32)
    steps, val_cw1 = _early_stopped(
        pmf_net,
        lambda: circular_w1_loss(pmf_net(*bf.args()), cdf_f),
        lambda: circular_w1_loss(pmf_net(*bv.args()), cdf_v),
        t,
        seed,
    )
    f32 = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
    xo_f, xo_v = f32(arrays["x"][fit_ok]), f32(va["x"][val_ok])
    bo_f, bo_v = f32(ok_logit(arrays["analytic_ok"][fit_ok])), f32(ok_logit(arrays["analytic_ok"][val_ok]))
    yo_f, yo_v = f32(arrays["ok"][fit_ok]), f32(arrays["ok"][val_ok])
    bce = torch.nn.functional.binary_cross_entropy_with_logits
    ok_steps, val_mae = _early_stopped(
        ok_net,
        lambda: bce(ok_net(xo_f, bo_f), yo_f),
        lambda: (torch.sigmoid(ok_net(xo_v, bo_v)) - yo_v).abs().mean(),
        ok_train,
        seed + 1,
    )
    return Fitted(pmf_net, ok_net, steps, ok_steps, val_cw1, float(val_mae), net.start)


def predict(fitted: Fitted, arrays: dict, rows, mean_pmf) -> tuple[np.ndarray, np.ndarray]:
    """(PMFs (n, bins), ok shares (n,)) of ``rows``."""
    torch = _torch()
    rows = np.asarray(rows)
    b = Batch.of(arrays, rows, row_diffuse(arrays, rows, mean_pmf), fitted.start)
    with torch.no_grad():
        pmf = fitted.net(*b.args()).numpy().astype(np.float64)
        base = torch.as_tensor(ok_logit(arrays["analytic_ok"][rows]), dtype=torch.float32)
        ok = torch.sigmoid(fitted.ok_net(b.x, base)).numpy().astype(np.float64)
    pmf = np.clip(pmf, 0.0, None)
    return pmf / pmf.sum(axis=1, keepdims=True), ok
