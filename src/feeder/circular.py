"""Angles on the circle: yaws reduced to ``[0, 360)``, differences of yaws, and the wrapped Gaussian
that smooths a circular histogram.

Pure numpy functions in degrees, shared by the labels (:mod:`feeder.labels.metrics`), the
adaptive design of the simulator (:mod:`feeder.sim.adaptive`) and the analytic mechanics
(:mod:`feeder.mechanics`). Conventions as in :mod:`feeder.labels.metrics`: ``θ = (β + 360) mod 360``;
the kernel weights ``exp(-d² / 2σ²)`` over the circular bin distance ``d`` (every image around the
circle summed), normalised to sum 1; ``sigma = 0`` is no smoothing.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.errors import FeederError

FULL_TURN_DEG = 360.0
HALF_TURN_DEG = 180.0
QUARTER_TURN_DEG = 90.0
LABEL_BINS = 360  # a label's yaw bins over a full turn, where no setting says (the workflow's labels.bins)
LABEL_SIGMA_BINS = 1.0  # its wrapped Gaussian smoothing in bins (labels.sigma_bins)


def normalize_yaw(beta) -> np.ndarray:
    """Map yaw angles (degrees, any real value) to ``[0, 360)``: θ = (β + 360) mod 360.

    Non-finite inputs stay NaN. The result is strictly below 360 even where floating-point
    rounding of a tiny negative angle would give 360.
    """
    beta = np.asarray(beta, dtype=np.float64)
    finite = np.isfinite(beta)
    theta = np.mod(np.where(finite, beta, 0.0) + FULL_TURN_DEG, FULL_TURN_DEG)
    theta = np.where(theta >= FULL_TURN_DEG, 0.0, theta)
    return np.where(finite, theta, np.nan)


def wrap360(angle_deg):
    """Angles (degrees) modulo 360: ``[0, 360)`` for finite angles (no guards: see
    :func:`normalize_yaw` for NaN and the rounding of tiny negative angles)."""
    return np.mod(angle_deg, FULL_TURN_DEG)


def wrap180(x) -> np.ndarray:
    """Angle differences (degrees) reduced to ``[-180, 180)``."""
    return np.mod(np.asarray(x, dtype=np.float64) + 180.0, FULL_TURN_DEG) - 180.0


def circular_distance(a, b) -> np.ndarray:
    """Circular distance of yaws in degrees, in [0, 180]; NaN if either is NaN."""
    return np.abs(wrap180(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)))


def check_bins(bins: int) -> int:
    """``bins`` as an int; FeederError unless it is a positive integer."""
    if int(bins) != bins or bins < 1:
        raise FeederError(f"bins must be a positive integer, got {bins!r}")
    return int(bins)


def wrapped_gaussian_kernel(bins: int, sigma: float) -> np.ndarray:
    """Circular Gaussian kernel indexed by offset 0..bins-1 (offset ``bins-1`` is −1), sums to 1."""
    bins = check_bins(bins)
    if not (sigma >= 0 and math.isfinite(sigma)):
        raise FeederError(f"sigma must be a finite non-negative number of bins, got {sigma!r}")
    kernel = np.zeros(bins)
    if sigma == 0:
        kernel[0] = 1.0
        return kernel
    offsets = np.arange(bins, dtype=np.float64)
    # Sum every image of the Gaussian that is not negligible (at least ±8σ, at least one turn).
    turns = int(math.ceil(8 * sigma / bins)) + 1
    for t in range(-turns, turns + 1):
        kernel += np.exp(-0.5 * ((offsets + t * bins) / sigma) ** 2)
    return kernel / kernel.sum()


def wrapped_gaussian_smooth(hist, sigma: float) -> np.ndarray:
    """Circular convolution of histogram rows (last axis = bins) with the wrapped Gaussian,
    renormalised so every row sums to 1. An all-zero row is an error (no mass to spread)."""
    hist = np.asarray(hist, dtype=np.float64)
    if hist.ndim == 0 or hist.shape[-1] < 1:
        raise FeederError("wrapped_gaussian_smooth: need at least one bin")
    if (hist < 0).any() or not np.isfinite(hist).all():
        raise FeederError("wrapped_gaussian_smooth: histogram values must be finite and >= 0")
    bins = hist.shape[-1]
    kernel = wrapped_gaussian_kernel(bins, sigma)
    out = np.fft.irfft(np.fft.rfft(hist, axis=-1) * np.fft.rfft(kernel), n=bins, axis=-1)
    if (hist.sum(axis=-1) <= 0).any():
        raise FeederError("wrapped_gaussian_smooth: a histogram row has no mass")
    out = np.clip(out, 0.0, None)  # FFT round-off can give -1e-18 in empty bins
    return out / out.sum(axis=-1, keepdims=True)
