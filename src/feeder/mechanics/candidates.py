"""Candidate resting orientations of a configuration: the modes of the analytic push model and of
its variants (issue #39, item 2).

The simulated final yaw of a part falls in a few sharp basins, and the analytic model
(:func:`feeder.mechanics.distribution.analytic_distribution`) or one of its variants (another
friction, no exit turn, jams ignored, one fence alone) usually puts a mode where each basin is;
what it gets wrong is how much mass each one holds. This module lists those modes per
configuration, and per mode the mass each variant gives it, so that a learner
(:mod:`feeder.learn.structured`) only has to weigh them.

Everything is a pure function of its arguments on 360-bin circular PMFs in the label frame (bin
``b`` covers ``[b, b + 1)`` degrees times ``360 / bins``; a position in degrees is a bin centre):

* :func:`pmf_modes`: the local maxima of a circular PMF that hold at least ``min_mass`` within
  ``± window_deg`` (wrap-around at 0/360 included);
* :func:`merge_positions`: positions closer than ``merge_deg`` on the circle merged, the heavier
  one kept;
* :func:`basin_masses`: the mass of a PMF that lies within ``± window_deg`` of each position and
  closer to it than to any other (a Voronoi partition of the circle, cut at the window);
* :func:`variant_pmf`: one variant's analytic PMF; :func:`configuration_candidates` all of it for
  one configuration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeder.circular import FULL_TURN_DEG, wrap180, wrapped_gaussian_smooth
from feeder.errors import FeederError
from feeder.mechanics.distribution import (
    ARC_RIDE,
    ARC_RIDE_MODES,
    GRAZE,
    GRAZE_MODES,
    TURN_BUDGET_SCALE,
    TURN_RATE,
    TURN_RATE_MODES,
    analytic_distribution,
)
from feeder.mechanics.fence import fence_models, fence_mu
from feeder.mechanics.hull import as_geometry
from feeder.mechanics.pmf import bin_masses

FENCE_SETS = ("both", "loc1", "loc2")  # which fences of the configuration a variant keeps
# A mode must rise above its left neighbour by more than this (round-off of the smoothing makes a
# flat PMF ripple at ~1e-18)
PEAK_TOL = 1e-12


@dataclass(frozen=True)
class Variant:
    """One variant of the analytic push model: ``mu`` (None: the scene's part–fence friction),
    ``exit_turns``, ``jams`` (False: drops in the friction cone slide as if they did not jam),
    ``fences`` (``both``, or ``loc1``/``loc2`` alone) and the turn settings of
    :func:`~feeder.mechanics.distribution.analytic_distribution`: ``turn_rate``,
    ``turn_budget_scale``, ``arc_ride`` and ``graze`` (their defaults: the model's)."""

    name: str
    mu: float | None = None
    exit_turns: bool = True
    jams: bool = True
    fences: str = "both"
    turn_rate: str | None = TURN_RATE
    turn_budget_scale: float = TURN_BUDGET_SCALE
    arc_ride: str | None = ARC_RIDE
    graze: str = GRAZE

    def __post_init__(self) -> None:
        if self.fences not in FENCE_SETS:
            raise FeederError(f"variant {self.name}: fences must be one of {FENCE_SETS}, got {self.fences!r}")
        if self.mu is not None and not (math.isfinite(self.mu) and self.mu >= 0):
            raise FeederError(f"variant {self.name}: mu must be finite and >= 0, got {self.mu!r}")
        if not (math.isfinite(self.turn_budget_scale) and self.turn_budget_scale > 0):
            raise FeederError(
                f"variant {self.name}: turn_budget_scale must be finite and > 0, got {self.turn_budget_scale!r}"
            )
        for key, allowed in (("turn_rate", TURN_RATE_MODES), ("arc_ride", ARC_RIDE_MODES), ("graze", GRAZE_MODES)):
            if getattr(self, key) not in allowed:
                raise FeederError(f"variant {self.name}: {key} must be one of {allowed}, got {getattr(self, key)!r}")

    def spec(self) -> dict:
        """The variant as a plain mapping: its name, ``mu``, ``exit_turns``, ``jams`` and ``fences``,
        and each turn setting only where it is not the model's default (so a cache key of the
        variants above, written before the turn settings existed, stays the same)."""
        out = {k: getattr(self, k) for k in ("name", "mu", "exit_turns", "jams", "fences")}
        out.update({k: getattr(self, k) for k, default in TURN_DEFAULTS.items() if getattr(self, k) != default})
        return out


TURN_DEFAULTS = {"turn_rate": TURN_RATE, "turn_budget_scale": TURN_BUDGET_SCALE, "arc_ride": ARC_RIDE, "graze": GRAZE}


def variants_from_config(cfg) -> tuple[Variant, ...]:
    """The variants of a config list of mappings (``name``, optional ``mu``, ``exit_turns``,
    ``jams``, ``fences``, ``turn_rate``, ``turn_budget_scale``, ``arc_ride``, ``graze``; an absent
    setting is the model's default, ``arc_ride``/``turn_rate`` null is none); names must be unique
    and the first is the base model. An unknown key is a one-line FeederError."""
    known = {"name", "mu", "exit_turns", "jams", "fences", *TURN_DEFAULTS}
    out = []
    for item in cfg:
        get = item.get
        unknown = sorted(set(map(str, item.keys())) - known)
        if unknown:
            raise FeederError(f"variant {get('name')!r}: unknown settings {unknown} (known: {sorted(known)})")
        mu = get("mu")
        rate = get("turn_rate", TURN_RATE)
        ride = get("arc_ride", ARC_RIDE)
        out.append(
            Variant(
                name=str(get("name")),
                mu=None if mu is None else float(mu),
                exit_turns=bool(get("exit_turns", True)),
                jams=bool(get("jams", True)),
                fences=str(get("fences", "both")),
                turn_rate=None if rate is None else str(rate),
                turn_budget_scale=float(get("turn_budget_scale", TURN_BUDGET_SCALE)),
                arc_ride=None if ride is None else str(ride),
                graze=str(get("graze", GRAZE)),
            )
        )
    names = [v.name for v in out]
    if not out or len(set(names)) != len(names):
        raise FeederError(f"candidates.variants: need at least one variant with unique names, got {names}")
    return tuple(out)


# ----------------------------------------------------------------------------------------------
# Pure functions on circular PMFs
# ----------------------------------------------------------------------------------------------
def bin_centres_deg(bins: int) -> np.ndarray:
    """Centres of ``bins`` equal bins of [0, 360) in degrees."""
    return (np.arange(int(bins)) + 0.5) * (FULL_TURN_DEG / int(bins))


def _window_bins(window_deg: float, bins: int) -> int:
    if not (math.isfinite(window_deg) and window_deg >= 0):
        raise FeederError(f"window_deg must be finite and >= 0, got {window_deg!r}")
    return int(round(window_deg * bins / FULL_TURN_DEG))


def window_sums(pmf, window_deg: float) -> np.ndarray:
    """Per bin, the circular sum of ``pmf`` over the bins within ``± window_deg`` (rounded to
    whole bins) of it."""
    p = np.asarray(pmf, dtype=np.float64)
    w = _window_bins(window_deg, p.size)
    return sum(np.roll(p, s) for s in range(-w, w + 1))


def pmf_modes(pmf, min_mass: float, window_deg: float, peak_sigma_bins: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The modes of a circular PMF: the bins where the PMF smoothed by a wrapped Gaussian of
    ``peak_sigma_bins`` is a local maximum (above its left neighbour by more than :data:`PEAK_TOL`:
    the first bin of a flat top; a flat PMF has none) and whose
    window sum (:func:`window_sums` of the unsmoothed PMF) holds at least ``min_mass``. Returns
    (positions in degrees: bin centres, their window masses), heaviest first."""
    p = np.asarray(pmf, dtype=np.float64)
    if p.ndim != 1 or p.size < 3:
        raise FeederError(f"pmf_modes needs one PMF of at least 3 bins, got shape {p.shape}")
    q = wrapped_gaussian_smooth(p, float(peak_sigma_bins)) if peak_sigma_bins > 0 else p
    s = window_sums(p, window_deg)
    peak = (q > np.roll(q, 1) + PEAK_TOL) & (q >= np.roll(q, -1) - PEAK_TOL) & (s >= min_mass)
    idx = np.flatnonzero(peak)
    idx = idx[np.argsort(-s[idx], kind="stable")]
    return bin_centres_deg(p.size)[idx], s[idx]


def merge_positions(positions, weights, merge_deg: float) -> np.ndarray:
    """Positions (degrees) with those closer than ``merge_deg`` on the circle to a heavier one
    dropped (greedy, heaviest first; ties keep the first given). Returns the kept positions,
    heaviest first."""
    pos = np.asarray(positions, dtype=np.float64)
    wts = np.asarray(weights, dtype=np.float64)
    if pos.shape != wts.shape or pos.ndim != 1:
        raise FeederError("merge_positions needs 1-d positions and weights of one shape")
    kept: list[float] = []
    for i in np.argsort(-wts, kind="stable"):
        if all(abs(float(wrap180(pos[i] - k))) >= merge_deg for k in kept):
            kept.append(float(pos[i]))
    return np.asarray(kept, dtype=np.float64)


def basin_masses(pmf, positions, window_deg: float) -> np.ndarray:
    """The mass of ``pmf`` in each position's basin: the bins within ``± window_deg`` of it
    (bin-centre distance on the circle) that are closer to it than to any other position (ties
    to the first). The masses sum to at most 1; the rest lies outside every window."""
    p = np.asarray(pmf, dtype=np.float64)
    pos = np.asarray(positions, dtype=np.float64)
    if pos.size == 0:
        return np.zeros(0)
    dist = np.abs(wrap180(bin_centres_deg(p.size)[None, :] - pos[:, None]))  # (K, bins)
    nearest = np.argmin(dist, axis=0)
    inside = dist[nearest, np.arange(p.size)] <= window_deg
    return np.bincount(nearest[inside], weights=p[inside], minlength=pos.size).astype(np.float64)


# ----------------------------------------------------------------------------------------------
# Variants of the analytic model on one configuration
# ----------------------------------------------------------------------------------------------
def variant_pmf(
    part,
    loc1,
    loc2,
    scene: dict,
    variant: Variant,
    *,
    frame_deg: float = 0.0,
    bins: int = 360,
    smooth_deg: float = 0.0,
    responses: dict | None = None,
) -> tuple[np.ndarray, float]:
    """(the variant's PMF over the ok drops in the label frame, its ok mass). When every drop
    jams the PMF is the variant's with jams ignored (as :func:`feeder.mechanics.pmf.analytic_pmf`).
    ``responses``: the part's memo of :func:`analytic_distribution`."""
    geom = as_geometry(part)
    mu = fence_mu(scene) if variant.mu is None else variant.mu
    fences = fence_models(loc1, loc2, scene)
    if variant.fences != "both":
        fences = [m for m in fences if m.location == variant.fences]
    kwargs = dict(
        mu=mu,
        exit_turns=variant.exit_turns,
        fences=fences,
        responses=responses,
        turn_rate=variant.turn_rate,
        turn_budget_scale=variant.turn_budget_scale,
        arc_ride=variant.arc_ride,
        graze=variant.graze,
    )
    dist = analytic_distribution(geom, None, None, scene, jams=variant.jams, **kwargs)
    ok = float(dist.ok_mass)
    if dist.weights.sum() <= 0.0:
        dist = analytic_distribution(geom, None, None, scene, jams=False, **kwargs)
    hist = bin_masses(dist.yaws + frame_deg, dist.weights, int(bins))
    hist /= hist.sum()
    if smooth_deg > 0:
        hist = wrapped_gaussian_smooth(hist, smooth_deg * bins / FULL_TURN_DEG)
    return hist, ok


@dataclass(frozen=True)
class Candidates:
    """The candidates of one configuration: ``positions`` (K,) degrees in the label frame,
    heaviest first; ``masses`` (K, V) the basin mass each variant gives each candidate; ``ok``
    (V,) each variant's ok mass; ``pmfs`` (V, bins) the variants' PMFs."""

    positions: np.ndarray
    masses: np.ndarray
    ok: np.ndarray
    pmfs: np.ndarray


def candidates_from_pmfs(
    pmfs, min_mass: float, window_deg: float, merge_deg: float, max_candidates: int
) -> tuple[np.ndarray, np.ndarray]:
    """(positions, masses (K, V)) of the modes of every variant PMF (rows of ``pmfs``): each
    variant's modes (:func:`pmf_modes`), merged across variants by their largest window mass
    (:func:`merge_positions`), at most ``max_candidates`` of them (by the summed mass the variants
    give them), with each variant's basin masses (:func:`basin_masses`)."""
    pmfs = np.atleast_2d(np.asarray(pmfs, dtype=np.float64))
    if int(max_candidates) < 1:
        raise FeederError(f"max_candidates must be >= 1, got {max_candidates!r}")
    pos, wts = [], []
    for p in pmfs:
        a, b = pmf_modes(p, min_mass, window_deg)
        pos.append(a)
        wts.append(b)
    positions = merge_positions(np.concatenate(pos), np.concatenate(wts), merge_deg)
    masses = np.stack([basin_masses(p, positions, window_deg) for p in pmfs], axis=1)  # (K, V)
    order = np.argsort(-masses.sum(axis=1), kind="stable")[: int(max_candidates)]
    positions = positions[order]
    masses = np.stack([basin_masses(p, positions, window_deg) for p in pmfs], axis=1)
    return positions, masses


def configuration_candidates(
    part,
    loc1,
    loc2,
    scene: dict,
    variants: tuple[Variant, ...],
    *,
    frame_deg: float = 0.0,
    bins: int = 360,
    smooth_deg: float = 0.0,
    min_mass: float,
    window_deg: float,
    merge_deg: float,
    max_candidates: int,
    responses: dict | None = None,
) -> Candidates:
    """The :class:`Candidates` of a part (outline, PartGeometry or PushGeometry) in a
    configuration, from the PMFs of ``variants`` (:func:`variant_pmf`)."""
    geom = as_geometry(part)
    out = [
        variant_pmf(
            geom, loc1, loc2, scene, v, frame_deg=frame_deg, bins=bins, smooth_deg=smooth_deg, responses=responses
        )
        for v in variants
    ]
    pmfs = np.stack([p for p, _ in out])
    ok = np.array([o for _, o in out])
    positions, masses = candidates_from_pmfs(pmfs, min_mass, window_deg, merge_deg, max_candidates)
    return Candidates(positions, masses, ok, pmfs)
