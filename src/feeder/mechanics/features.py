"""The push feature block of a part in a fence configuration.

Features (:func:`push_features`, :data:`PUSH_FEATURE_NAMES`)
    ``2·FOURIER_K`` values ``Re c_k, Im c_k`` (k = 1..K) of the smoothed analytic PMF in the label
    frame, ``c_k = Σ_b p_b e^{−i k θ_b}`` at bin centres ``θ_b``; then per location (loc1, loc2):
    present, touch (share of the drops reaching it that touch it), jam (share of them jammed),
    friction margin (degrees; ``90° − atan(mu)`` for an absent fence, i.e. a fence along the
    travel direction); then ok mass, peak mass (largest share of ok drops at one resting yaw),
    entropy (bits) of the unsmoothed analytic PMF, the number of stable edges and the largest basin
    measure of the frictionless push function. When every drop jams, the PMF, peak mass and
    entropy describe the same configuration with jams ignored (ok mass is then 0).
    :func:`push_block` gives the block and the analytic PMF from one pass of the drops (the
    dataset's ``push_raw`` and ``pmf_analytic``, :mod:`feeder.labels.dataset`); a hand-bumped
    :data:`PUSH_FEATURES_VERSION` marks changed values.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.circular import FULL_TURN_DEG
from feeder.mechanics.distribution import Distribution, analytic_distribution
from feeder.mechanics.fence import as_fence, default_scene, fence_models, fence_mu, friction_margin_deg
from feeder.mechanics.hull import as_geometry
from feeder.mechanics.pmf import DEFAULT_SMOOTH_DEG, PMF_BINS, analytic_pmf, bin_masses
from feeder.mechanics.pushfunction import push_function

FOURIER_K = 8  # leading complex Fourier coefficients of the PMF kept as features (k = 1..K)


# Two drops closer than this (degrees) count as one resting yaw for ``peak_mass`` (pushed drops
# of one basin share their yaw exactly).
MODE_MERGE_DEG = 1e-6


def fourier_coefficients(pmf, k: int = FOURIER_K) -> np.ndarray:
    """``c_1..c_k`` (complex) of a circular PMF, ``c_k = Σ_b p_b exp(−i k θ_b)`` at bin centres."""
    p = np.asarray(pmf, dtype=np.float64)
    bins = p.shape[-1]
    centres = (np.arange(bins) + 0.5) * (2.0 * math.pi / bins)
    ks = np.arange(1, int(k) + 1)
    return p @ np.exp(-1j * np.outer(centres, ks))


LOCATIONS = ("loc1", "loc2")
_PER_LOCATION = ("present", "touch", "jam", "margin_deg")
_SCALARS = ("ok_mass", "peak_mass", "entropy_bits", "stable_edges", "largest_basin")
# Bump by hand when the feature block's values change for the same names (a model trained on
# the old values would read the new ones wrongly): part of feeder.labels.dataset.features_version.
PUSH_FEATURES_VERSION = 3  # 2: the turn budget x1.5 (feeder.mechanics.distribution.TURN_BUDGET_SCALE);
# 3: a curved fence's basin from the ridden arc (feeder.mechanics.distribution.ARC_RIDE)
PUSH_FEATURE_NAMES: tuple[str, ...] = (
    *(f"{part}_c{k}" for k in range(1, FOURIER_K + 1) for part in ("re", "im")),
    *(f"{loc}_{name}" for loc in LOCATIONS for name in _PER_LOCATION),
    *_SCALARS,
)


def _peak_mass(yaws, weights) -> float:
    """Largest share of the ok weight at one resting yaw (yaws within MODE_MERGE_DEG merged)."""
    order = np.argsort(yaws)
    y, w = yaws[order], weights[order] / weights.sum()
    if y.size == 0:
        return 0.0
    new = np.concatenate([[True], np.diff(y) > MODE_MERGE_DEG])
    groups = np.cumsum(new) - 1
    sums = np.bincount(groups, weights=w)
    if groups[-1] > 0 and (y[0] + FULL_TURN_DEG - y[-1]) <= MODE_MERGE_DEG:  # wrap-around
        sums[0] += sums[-1]
        sums = sums[:-1]
    return float(sums.max())


def _shape_of(geom, scene, mu_f, exit_turns, fences, responses) -> tuple[Distribution, Distribution]:
    """(the distribution of the ok drops, the distribution its PMF describes): the latter is the
    same configuration with jams ignored when every drop jams."""
    dist = analytic_distribution(
        geom, None, None, scene, mu=mu_f, exit_turns=exit_turns, fences=fences, responses=responses
    )
    shape = dist
    if dist.weights.sum() <= 0.0:
        shape = analytic_distribution(
            geom, None, None, scene, mu=mu_f, exit_turns=exit_turns, fences=fences, jams=False, responses=responses
        )
    return dist, shape


def _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, smooth_deg, bins) -> np.ndarray:
    """The feature block of :func:`push_features` from the configuration's distributions."""
    pmf = analytic_pmf(
        geom, None, None, scene, frame_deg=frame_deg, smooth_deg=smooth_deg, bins=bins, distribution=shape
    )
    coef = fourier_coefficients(pmf, FOURIER_K)
    out = [v for c in coef for v in (c.real, c.imag)]
    present = {"loc1": as_fence(loc1).present, "loc2": as_fence(loc2).present}
    no_fence_margin = float(friction_margin_deg(0.0, mu_f))
    for loc in LOCATIONS:
        out += [
            1.0 if present[loc] else 0.0,
            dist.touch.get(loc, 0.0),
            dist.jam.get(loc, 0.0),
            dist.margin.get(loc, no_fence_margin),
        ]
    raw = bin_masses(shape.yaws + frame_deg, shape.weights, int(bins))
    raw /= raw.sum()
    nz = raw[raw > 0]
    frictionless = push_function(geom)
    out += [
        dist.ok_mass,
        _peak_mass(shape.yaws, shape.weights),
        float(-np.sum(nz * np.log2(nz))),
        float(len(frictionless.edges)),
        float(frictionless.measures.max()),
    ]
    vec = np.asarray(out, dtype=np.float64)
    assert vec.shape == (len(PUSH_FEATURE_NAMES),)
    return vec


def push_features(
    part,
    loc1,
    loc2,
    scene: dict | None = None,
    *,
    frame_deg: float = 0.0,
    smooth_deg: float = DEFAULT_SMOOTH_DEG,
    bins: int = PMF_BINS,
    mu: float | None = None,
    exit_turns: bool = True,
    responses: dict | None = None,
) -> np.ndarray:
    """The fixed-size feature block (:data:`PUSH_FEATURE_NAMES`, layout in the module doc) of a
    part (outline array, PartGeometry or PushGeometry) in a configuration (``none``,
    ``straight:θ``, ``curved:θ`` or :class:`~feeder.lane.fences.Fence`). ``responses``: the
    per-part memo of :func:`analytic_distribution`."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu_f = fence_mu(scene) if mu is None else float(mu)
    fences = fence_models(loc1, loc2, scene)
    dist, shape = _shape_of(geom, scene, mu_f, exit_turns, fences, responses)
    return _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, smooth_deg, bins)


def push_block(
    part,
    loc1,
    loc2,
    scene: dict | None = None,
    *,
    frame_deg: float = 0.0,
    bins: int = PMF_BINS,
    pmf_smooth_deg: float = DEFAULT_SMOOTH_DEG,
    responses: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(push_features(...), analytic_pmf(...))`` of one configuration from a single pass of the
    drops: the feature block with its default smoothing and the PMF smoothed by
    ``pmf_smooth_deg`` (a dataset uses its labels' smoothing), both in the frame ``frame_deg``
    over ``bins`` bins. Equal to the two calls (the scene's friction, exit turns on)."""
    geom = as_geometry(part)
    scene = default_scene() if scene is None else scene
    mu_f = fence_mu(scene)
    fences = fence_models(loc1, loc2, scene)
    dist, shape = _shape_of(geom, scene, mu_f, True, fences, responses)
    features = _feature_vector(geom, loc1, loc2, scene, mu_f, dist, shape, frame_deg, DEFAULT_SMOOTH_DEG, bins)
    pmf = analytic_pmf(
        geom, None, None, scene, frame_deg=frame_deg, smooth_deg=pmf_smooth_deg, bins=bins, distribution=shape
    )
    return features, pmf
