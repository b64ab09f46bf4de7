"""DFT shape features of a part's planar face (paper §3.2.1), 45 raw values.

Pipeline (:func:`outline_samples` then :func:`dft_features`):

1. **Points.** An ``.xyz`` file is read as ``x y z`` lines (spaces or commas; blank lines and
   ``#`` comments allowed). The axis with (nearly) no spread is dropped; the others must span a
   plane (not a line). For an ``.stl`` the exact top face is recovered, outline and through-holes
   (:func:`feeder.parts.geometry.read_profile`), and sampled into a point cloud exactly like
   the library's exports (:func:`feeder.parts.geometry.face_cloud`, ``DFT.stl_cloud_points`` points,
   none in a hole).
   **Units:** millimetres and metres both work and need no detection: step 3 scales the shape
   uniformly to the canvas, so every later quantity is in canvas pixels and the features do not
   depend on the unit (nor on the part's absolute size). All tolerances are relative.
2. **Principal axes.** Centre on the mean and rotate onto the covariance eigenvectors, largest
   eigenvalue first (x axis). Deterministic tie-breakers (the paper left them open): the first
   axis points along positive skewness of the projections (if the skewness is negligible, its
   largest-magnitude component is made positive) and the second axis is the first turned by
   +90°. The alignment is therefore a proper rotation: a part and its mirror image stay
   distinguishable. When the eigenvalues are (nearly) tied (ratio < ``DFT.tie_ratio`` = 1.05,
   the paper's near-tie criterion: squares, circles, regular polygons, stars, gears) their
   eigenvectors are arbitrary, and because step 3 scales the larger aligned extent to the
   canvas, an arbitrary in-plane angle would even change the magnitudes (by up to √2 for a
   square). For those shapes the first axis is instead the long side of the points' minimum-area
   bounding rectangle (either side of a square), which follows the shape when it is rotated or
   resampled. Everything stays finite and identical for identical input.
3. **Silhouette.** The aligned points are scaled uniformly so that the larger extent spans the
   500 px canvas minus the 10 px margins, centred, and rounded to integer pixels. A face cloud
   drawn as single pixels is a dotted pattern, not a shape, so the dots are closed into a solid
   silhouette: morphological closing with a disc whose radius follows the cloud's largest
   nearest-neighbour gap (``ceil(closing_gap_factor * gap) + 1`` px, computed on a padded canvas
   so the margins stay white), then interior holes are filled. Closing rounds concave corners by
   about that radius (about 1 % of the part size for the library's clouds) and leaves convex
   corners and straight edges where the points are. The part is black on a white canvas.
4. **Outline.** Canny with thresholds 100/200 on the canvas (no blur); ``findContours`` with
   ``RETR_EXTERNAL`` and ``CHAIN_APPROX_NONE``; the contour of largest area. Pixel rows are
   flipped so y points up (a right-handed frame like the part's). One addition: on a binary
   silhouette Canny's non-maximum suppression leaves one-pixel breaks in the edge ring (at
   corners, where the edge hops between the dark and the light side of the step; measured on 35
   of 59 library parts), and ``findContours`` then walks both sides of an open line, giving a
   contour of nearly zero area. The edge map is therefore dilated with a 3 x 3 square before
   ``findContours``, so the outer contour runs one pixel outside the edge ring. A contour that
   encloses less than 90 % of the silhouette is an error, never a silent feature vector.
5. **Spline.** Cubic B-spline through the contour points (``splprep``, s = 0, parameter = contour
   order on [0, 1], open curve as in the paper), sampled at 100 uniformly spaced parameters
   (scipy's FITPACK ``splprep``/``splev``, replayed bit for bit by :mod:`feeder.parts.fitpack`).
6. **Recentre** on the mean of the 100 samples; **DFT** ``numpy.fft.fft(x + j y)`` (unnormalised,
   pixel units).
7. **Select** the 15 largest-magnitude coefficients, sorted by decreasing magnitude (ties keep the
   lower FFT index first). ``k`` is the *signed* frequency ``numpy.fft.fftfreq(100) * 100`` in
   [-50, 49]; the phase is ``numpy.angle`` in (-π, π].

CLI: ``feeder features PATH [--out FILE]`` prints / atomically writes
``{"k": [15 ints], "magnitude": [15 floats], "phase": [15 floats]}``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeder.errors import FeederError


@dataclass(frozen=True)
class DFTSettings:
    """The method's settings: the paper's values (§3.2.1) plus our silhouette/STL choices."""

    canvas_px: int = 500  # square canvas side
    margin_px: int = 10  # white margin on every side
    canny_low: int = 100
    canny_high: int = 200
    samples: int = 100  # spline samples = DFT length
    spline_degree: int = 3
    coefficients: int = 15  # kept coefficients (triplets)
    closing_gap_factor: float = 0.75  # closing disc radius per px of largest nearest-neighbour gap
    edge_bridge_px: int = 3  # square dilation of the Canny edges (bridges 1-px breaks)
    min_outline_fill: float = 0.9  # the chosen contour must enclose this share of the silhouette
    stl_cloud_points: int = 4000  # face cloud size sampled from an STL's top face
    tie_ratio: float = 1.05  # eigenvalue ratio below which the axes count as tied
    planar_rel_tol: float = 1e-3  # spread of the constant axis / in-plane extent
    collinear_rel_tol: float = 1e-6  # smallest / largest singular value of the 2D points


DFT = DFTSettings()

# The version of the model inputs the feature code computes. Bump it by hand whenever a change
# alters the values of the features of a part (the method above, a default of DFTSettings, the
# order or meaning of a triplet): a model trained on the old values must not read the new ones.
# :func:`feeder.labels.dataset.features_version` combines it with the ordered input names and the
# settings; a shipped model whose card records another version is refused (feeder.learn.export).
FEATURES_VERSION = 1
# The 45 raw values in the order of :func:`as_vector`: k1, magnitude1, phase1, k2, ...
TRIPLET_KEYS = ("k", "magnitude", "phase")
DFT_FEATURE_NAMES = tuple(f"{key}{i}" for i in range(1, DFT.coefficients + 1) for key in TRIPLET_KEYS)

# Nearest-neighbour gap of the silhouette's pixels (:func:`largest_gap`): first search radius (px;
# a 4,000-point face cloud on the canvas has gaps of about 3-8 px) and offsets looked up per pass.
GAP_SEARCH_START_PX = 8
GAP_SEARCH_BLOCK = 32
_OUTSIDE = 2  # flood-fill label of the background reached from the border (:func:`fill_holes`)

_SPLIT = re.compile(r"[,\s;]+")


# --------------------------------------------------------------------------------------------
# Input
# --------------------------------------------------------------------------------------------
def read_xyz(path: str | os.PathLike) -> np.ndarray:
    """(N, 3) float64 points of an ``.xyz`` file; one-line FeederError naming file and problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError as err:
        raise FeederError(f"{path}: not a text point cloud (undecodable bytes)") from err
    except OSError as err:
        raise FeederError(f"{path}: cannot read ({err.strerror})") from err
    rows: list[list[float]] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f for f in _SPLIT.split(line) if f]
        if len(fields) != 3:
            raise FeederError(f"{path}: line {lineno} has {len(fields)} values, expected 'x y z'")
        try:
            vals = [float(f) for f in fields]
        except ValueError as err:
            raise FeederError(f"{path}: line {lineno} is not numbers: {line[:40]!r}") from err
        if not all(math.isfinite(v) for v in vals):
            raise FeederError(f"{path}: line {lineno} has a NaN or infinite coordinate")
        rows.append(vals)
    if not rows:
        raise FeederError(f"{path}: empty point cloud (no points)")
    return np.asarray(rows, dtype=np.float64)


def planar_points(points: np.ndarray, source: str, settings: DFTSettings = DFT) -> np.ndarray:
    """Drop the constant axis of a planar (N, 3) cloud -> (N, 2); reject degenerate clouds."""
    pts = np.asarray(points, dtype=np.float64)
    if not np.all(np.isfinite(pts)):
        raise FeederError(f"{source}: NaN or infinite coordinates")
    distinct = np.unique(pts, axis=0)
    if len(distinct) < 3:
        raise FeederError(f"{source}: fewer than 3 distinct points ({len(distinct)})")
    spread = np.ptp(pts, axis=0)
    flat, big = _flat_axis(pts), int(np.argmax(spread))
    if spread[flat] > settings.planar_rel_tol * spread[big]:
        raise FeederError(
            f"{source}: points are not planar with one constant coordinate (spreads x/y/z = "
            f"{spread[0]:.4g}/{spread[1]:.4g}/{spread[2]:.4g})"
        )
    keep = [a for a in range(3) if a != flat]
    xy = pts[:, keep]
    centred = xy - xy.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[-1] <= settings.collinear_rel_tol * sv[0]:
        raise FeederError(f"{source}: points are collinear (the face has no area)")
    return xy


def _flat_axis(pts: np.ndarray) -> int:
    """Index of the coordinate with the least spread (the dropped one of a planar cloud)."""
    return int(np.argsort(np.ptp(np.asarray(pts, dtype=np.float64), axis=0), kind="stable")[0])


def load_points(path: str | os.PathLike, settings: DFTSettings = DFT) -> np.ndarray:
    """The 2D face point set of an ``.xyz`` or ``.stl`` file."""
    return load_face(path, settings)[0]


def load_face(path: str | os.PathLike, settings: DFTSettings = DFT) -> tuple[np.ndarray, bool]:
    """(2D face points, whether they are the part's x-y coordinates) of an ``.xyz`` or ``.stl``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".stl":
        from feeder.parts.geometry import clean_holes, clean_outline, face_cloud, read_profile

        outline, holes, _ = read_profile(path)  # metres or millimetres: the features are unit-free
        try:
            outline, holes = clean_outline(outline), clean_holes(holes)
        except FeederError as err:
            raise FeederError(f"{path}: {err}") from err
        # the face as `feeder parts xyz` exports it, holes left out: the outline the features
        # describe is the outer one either way (holes are filled, as in the paper), and the
        # principal frame is the face's own
        return face_cloud(outline, settings.stl_cloud_points, holes), True
    if suffix == ".xyz":
        pts = read_xyz(path)
        xy = planar_points(pts, str(path), settings)
        return xy, _flat_axis(pts) == 2
    raise FeederError(f"{path}: unknown file type {suffix!r} (expected .xyz or .stl)")


# --------------------------------------------------------------------------------------------
# The method (pure functions)
# --------------------------------------------------------------------------------------------
def principal_align(xy: np.ndarray, settings: DFTSettings = DFT, axis: np.ndarray | None = None) -> np.ndarray:
    """Centre and rotate onto the principal axes (largest variance along x); see module doc.
    ``axis``: :func:`principal_axis` of ``xy`` when the caller has it already."""
    c = xy - xy.mean(axis=0)
    e1 = principal_axis(xy, settings) if axis is None else axis
    e2 = np.array([-e1[1], e1[0]])
    return np.column_stack([c @ e1, c @ e2])


def principal_axis(xy: np.ndarray, settings: DFTSettings = DFT) -> np.ndarray:
    """Unit first axis of the feature frame (step 2 of the module doc) in the points' frame."""
    c = xy - xy.mean(axis=0)
    cov = c.T @ c / len(c)
    evals, evecs = np.linalg.eigh(cov)  # ascending
    e1 = evecs[:, 1].copy()
    if evals[1] < settings.tie_ratio * evals[0]:
        e1 = _tie_axis(c)
    proj = c @ e1
    skew = float(np.mean(proj**3))
    sigma = math.sqrt(max(float(evals[1]), 0.0))
    if abs(skew) > 1e-6 * sigma**3:
        if skew < 0:
            e1 = -e1
    else:
        if e1[int(np.argmax(np.abs(e1)))] < 0:
            e1 = -e1
    return e1


def frame_deg(xy: np.ndarray, settings: DFTSettings = DFT) -> float:
    """Angle (degrees, [0, 360)) of the feature frame's x axis in the points' x-y frame.

    A part whose own frame is at yaw ψ has its feature frame at ψ + frame_deg: the labels'
    ``principal`` frame (:mod:`feeder.labels.metrics`) measures yaws there, so the same shape gives the
    same label whatever frame its CAD file was drawn in.
    """
    return axis_deg(principal_axis(xy, settings))


def axis_deg(e1: np.ndarray) -> float:
    """Angle (degrees, [0, 360)) of a unit axis, e.g. :func:`principal_axis` (:func:`frame_deg`)."""
    return float(math.degrees(math.atan2(e1[1], e1[0])) % 360.0)


def _tie_axis(c: np.ndarray) -> np.ndarray:
    """First axis for (near-)tied eigenvalues: the long side of the minimum-area bounding
    rectangle of the points (either side for a square); a rotation-covariant choice."""
    import shapely

    rect = np.asarray(shapely.minimum_rotated_rectangle(shapely.MultiPoint(c)).exterior.coords)[:3]
    sides = [rect[1] - rect[0], rect[2] - rect[1]]
    side = max(sides, key=lambda v: float(np.hypot(*v)))
    return side / np.hypot(*side)


def silhouette(aligned: np.ndarray, settings: DFTSettings = DFT) -> np.ndarray:
    """White (255) canvas with the part's filled silhouette in black (0), uint8 (H, W)."""
    import cv2

    size, margin = settings.canvas_px, settings.margin_px
    lo, hi = aligned.min(axis=0), aligned.max(axis=0)
    extent = float(np.max(hi - lo))
    scale = (size - 1 - 2 * margin) / extent
    mid = (lo + hi) / 2.0
    px = np.rint((aligned - mid) * scale + (size - 1) / 2.0).astype(np.int64)
    px = np.clip(px, margin, size - 1 - margin)
    cols, rows = px[:, 0], (size - 1) - px[:, 1]
    gap = largest_gap(np.column_stack([cols, rows]))
    radius = int(math.ceil(settings.closing_gap_factor * gap)) + 1
    pad = radius + 1
    mask = np.zeros((size + 2 * pad, size + 2 * pad), dtype=np.uint8)
    mask[rows + pad, cols + pad] = 255
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel)
    mask = fill_holes(mask[pad:-pad, pad:-pad] > 0)
    canvas = np.full((size, size), 255, dtype=np.uint8)
    canvas[mask] = 0
    return canvas


def largest_gap(pixels: np.ndarray) -> float:
    """Largest distance (px) from a pixel of ``pixels`` (N, 2 integers; repeats count once) to
    its nearest other pixel; 1.0 when there are fewer than two distinct pixels.

    Exact: the squared distances are integers, searched on an occupancy grid over pixel offsets
    in increasing distance (``GAP_SEARCH_START_PX``, then doubling the radius for the pixels
    still without a neighbour), and the square root of the largest is the value a k-d tree query
    (``scipy.spatial.cKDTree``, the previous implementation) returns, without importing scipy.
    """
    pts = np.asarray(pixels, dtype=np.int64)
    pts = pts - pts.min(axis=0)
    width = int(pts[:, 1].max()) + 1
    keys = np.unique(pts[:, 0] * width + pts[:, 1])
    if len(keys) < 2:
        return 1.0
    col, row = np.divmod(keys, width)
    span = max(int(col.max()), int(row.max())) + 1
    limit = int(math.ceil(math.sqrt(2.0) * span))  # no nearest neighbour is farther
    best = np.zeros(len(keys), dtype=np.int64)  # squared distance to the nearest other pixel
    todo = np.arange(len(keys))
    radius = GAP_SEARCH_START_PX
    while todo.size:
        radius = min(radius, limit)
        side = span + 2 * radius
        occupied = np.zeros(side * side, dtype=bool)
        flat = (col + radius) * side + (row + radius)
        occupied[flat] = True
        d = np.arange(-radius, radius + 1)
        dc, dr = (v.ravel() for v in np.meshgrid(d, d, indexing="ij"))
        d2 = dc * dc + dr * dr
        near = (d2 > 0) & (d2 <= radius * radius)
        order = np.argsort(d2[near], kind="stable")
        offsets, off_d2 = (dc[near] * side + dr[near])[order], d2[near][order]
        for start in range(0, len(offsets), GAP_SEARCH_BLOCK):
            block = slice(start, start + GAP_SEARCH_BLOCK)
            hits = occupied[flat[todo, None] + offsets[None, block]]
            found = hits.any(axis=1)
            best[todo[found]] = off_d2[block][hits[found].argmax(axis=1)]
            todo = todo[~found]
            if not todo.size:
                break
        if radius == limit:
            break
        radius *= 2
    return float(np.sqrt(np.float64(best.max())))


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """``mask`` (bool) with its holes filled: background pixels not 4-connected to the image
    border become foreground (``scipy.ndimage.binary_fill_holes`` with its default structure,
    by a flood fill of the background from a one-pixel frame)."""
    import cv2

    work = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), dtype=np.uint8)
    work[1:-1, 1:-1] = mask
    cv2.floodFill(work, None, (0, 0), _OUTSIDE, flags=4)
    return work[1:-1, 1:-1] != _OUTSIDE


def contour_of(canvas: np.ndarray, source: str, settings: DFTSettings = DFT) -> np.ndarray:
    """Largest external contour of the Canny edges, (M, 2) pixel coordinates with y up."""
    import cv2

    edges = cv2.Canny(canvas, settings.canny_low, settings.canny_high)
    k = settings.edge_bridge_px
    edges = cv2.dilate(edges, np.ones((k, k), np.uint8))
    contours, _ = cv2.findContours(edges, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise FeederError(f"{source}: no outline found on the canvas")
    areas = [cv2.contourArea(c) for c in contours]
    filled = float(np.count_nonzero(canvas == 0))
    if max(areas) < settings.min_outline_fill * filled:
        raise FeederError(
            f"{source}: outline extraction failed (contour encloses {max(areas):.0f} of {filled:.0f} silhouette pixels)"
        )
    best = contours[int(np.argmax(areas))].reshape(-1, 2).astype(np.float64)
    if len(best) <= settings.spline_degree:
        raise FeederError(f"{source}: outline too small to interpolate ({len(best)} pixels)")
    return np.column_stack([best[:, 0], (canvas.shape[0] - 1) - best[:, 1]])


def spline_samples(contour: np.ndarray, settings: DFTSettings = DFT) -> np.ndarray:
    """Cubic B-spline (s = 0, parameter = contour order) sampled at ``samples`` points, recentred.

    Returns complex (samples,) ``x + j y`` in pixel units. The spline is scipy's ``splprep`` /
    ``splev`` (FITPACK) through :mod:`feeder.parts.fitpack`, a bit-identical port that spares
    the import of ``scipy.interpolate``."""
    from feeder.parts.fitpack import evaluate, fit_interpolating

    u = np.linspace(0.0, 1.0, len(contour))
    t, c = fit_interpolating(np.asarray(contour, dtype=np.float64).T, u, settings.spline_degree)
    x, y = evaluate(t, c, settings.spline_degree, np.linspace(0.0, 1.0, settings.samples))
    z = np.asarray(x) + 1j * np.asarray(y)
    return z - z.mean()


def outline_samples(
    xy: np.ndarray, source: str = "points", settings: DFTSettings = DFT, axis: np.ndarray | None = None
) -> np.ndarray:
    """Steps 2-5 for a 2D face point set: the recentred complex outline (samples,). ``axis``: as
    for :func:`principal_align`."""
    aligned = principal_align(np.asarray(xy, dtype=np.float64), settings, axis)
    canvas = silhouette(aligned, settings)
    return spline_samples(contour_of(canvas, source, settings), settings)


def frequencies(n: int) -> np.ndarray:
    """Signed frequency index of each FFT bin: ``fftfreq(n) * n`` as ints."""
    return np.rint(np.fft.fftfreq(n) * n).astype(np.int64)


def top_indices(spectrum: np.ndarray, count: int) -> np.ndarray:
    """FFT bin indices of the ``count`` largest magnitudes, by decreasing magnitude (stable)."""
    return np.argsort(-np.abs(spectrum), kind="stable")[:count]


def dft_features(z: np.ndarray, count: int = DFT.coefficients) -> dict[str, list]:
    """The feature triplets of a recentred complex outline."""
    spec = np.fft.fft(z)
    idx = top_indices(spec, count)
    k = frequencies(len(z))[idx]
    return {
        "k": [int(v) for v in k],
        "magnitude": [float(v) for v in np.abs(spec[idx])],
        "phase": [float(v) for v in np.angle(spec[idx])],
    }


def reconstruct(z: np.ndarray, count: int) -> np.ndarray:
    """Inverse DFT keeping only the ``count`` largest-magnitude coefficients of ``z``."""
    spec = np.fft.fft(z)
    kept = np.zeros_like(spec)
    idx = top_indices(spec, count)
    kept[idx] = spec[idx]
    return np.fft.ifft(kept)


def reconstruction_mse(z: np.ndarray, count: int) -> float:
    """Mean squared point distance between an outline and its ``count``-coefficient
    reconstruction, in units of the canvas fit extent (the part's longest aligned extent = 1)."""
    unit = DFT.canvas_px - 1 - 2 * DFT.margin_px
    return float(np.mean(np.abs(z - reconstruct(z, count)) ** 2) / unit**2)


def features_of_file(path: str | os.PathLike, settings: DFTSettings = DFT) -> dict[str, list]:
    """The DFT features of a part file plus ``frame_deg`` (:func:`frame_deg`; None when an
    ``.xyz`` face does not lie in the x-y plane, the plane of the part's yaw)."""
    path = Path(path)
    xy, in_xy_plane = load_face(path, settings)
    axis = principal_axis(xy, settings)  # once: the alignment and frame_deg share it
    z = outline_samples(xy, str(path), settings, axis)
    out = dft_features(z, settings.coefficients)
    out["frame_deg"] = axis_deg(axis) if in_xy_plane else None
    return out


def load_frame_deg(path) -> float:
    """``frame_deg`` of a features JSON: where the part's feature frame lies in its own frame."""
    path = Path(path)
    try:
        value = json.loads(path.read_text()).get("frame_deg")
    except FileNotFoundError:
        raise FeederError(f"feature file {path} is missing") from None
    except OSError as err:
        raise FeederError(f"feature file {path}: cannot read ({err.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError) as err:
        raise FeederError(f"feature file {path} is not a features JSON ({err})") from None
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FeederError(
            f"feature file {path} has no frame_deg (its face cloud does not lie in the part's x-y plane, "
            "or the file predates it: rerun `feeder features`); labels.frame: principal needs it"
        )
    return float(value)


def as_vector(features: dict[str, list]) -> np.ndarray:
    """The 45 raw values as triplets ``k1, |a1|, arg a1, k2, ...`` (docs/data.md)."""
    return np.column_stack([features[key] for key in TRIPLET_KEYS]).ravel()


# --------------------------------------------------------------------------------------------
# Figure data (Fig. 6 panel b, Supplementary Fig. S1) - called by `feeder parts fig6-data|s1`;
# the drawing is in feeder.figures.fig6_dft_reconstruction / feeder.figures.s1_dft_mse
# --------------------------------------------------------------------------------------------
def reconstruction_data(paths: list[str], count: int) -> dict[str, np.ndarray]:
    """Fig. 6 data: per part its outline samples and their reconstruction from the ``count``
    largest coefficients, normalised so the canvas's drawable extent is 1, and the
    reconstruction MSE in those units² (the arrays of feeder.figures.fig6_dft_reconstruction)."""
    if not 1 <= count <= DFT.samples:
        raise FeederError(f"--coefficients {count} outside 1..{DFT.samples} (the DFT length)")
    if not paths:
        raise FeederError("no part files given")
    unit = DFT.canvas_px - 1 - 2 * DFT.margin_px
    outlines, recs, errs = [], [], []
    for path in paths:
        z = outline_samples(load_points(path), str(path)) / unit
        outlines.append(z)
        recs.append(reconstruct(z, count))
        errs.append(reconstruction_mse(z * unit, count))
    return {
        "name": np.array([Path(p).stem for p in paths]),
        "outline": np.asarray(outlines),
        "reconstruction": np.asarray(recs),
        "mse": np.asarray(errs, dtype=np.float64),
        "coefficients": np.int64(count),
    }


def study_mse(paths: list[str], max_count: int):
    """Supplementary Fig. S1 table: reconstruction MSE (normalised units²) over the parts for 1 ..
    ``max_count`` kept coefficients (mean, SD, quartiles, median, max)."""
    import pandas as pd
    from tqdm import tqdm

    if not 1 <= max_count <= DFT.samples:
        raise FeederError(f"--max-coefficients {max_count} outside 1..{DFT.samples} (the DFT length)")
    if not paths:
        raise FeederError("no part files given")
    counts = np.arange(1, max_count + 1)
    errs = []
    for path in tqdm(paths, desc="s1", disable=not sys.stderr.isatty()):
        z = outline_samples(load_points(path), str(path))
        errs.append([reconstruction_mse(z, int(c)) for c in counts])
    e = np.asarray(errs)
    return pd.DataFrame(
        {
            "n_coefficients": counts,
            "mean_mse": e.mean(axis=0),
            "std_mse": e.std(axis=0),
            "q25_mse": np.quantile(e, 0.25, axis=0),
            "median_mse": np.median(e, axis=0),
            "q75_mse": np.quantile(e, 0.75, axis=0),
            "max_mse": e.max(axis=0),
            "n_parts": len(paths),
        }
    )


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(
        prog="feeder features",
        description="Print the 45 raw DFT shape features of a part face (.xyz) or solid (.stl).",
    )
    ap.add_argument("path", help="a .xyz face point cloud (mm or m) or an extruded .stl")
    ap.add_argument("--out", help="write the JSON here (atomically) instead of stdout")
    args = ap.parse_args(argv)
    feats = features_of_file(args.path)
    if args.out:
        from feeder.io import write_json

        write_json(args.out, feats)
    else:
        print(json.dumps(feats))
    return 0
