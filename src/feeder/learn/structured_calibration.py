"""The analytic model calibrated on a known part's own labels (issue #39; docs/structured.md, "The
analytic model calibrated on the part's own labels").

The analytic push model has settings it cannot know for a given part: the part–fence friction it
meets, how far a fence turns it, what a steep curved fence does to a drop its arc misses. A few
*modes* (:class:`feeder.mechanics.candidates.Variant`, ``calibration.modes`` of
``config/hydra/structured.yaml``) change one of them each. For a part with labels, the mode with the
least mean circular W1 on the part's training labels answers its other configurations, if it beats
the base model there by at least ``calibration.margin_deg``; else the base model does. Measured on
tables at stop 72 (docs/experiments/part_calibration.py), the rule and its margin chosen on training
rows only.

* :func:`mode_w1`: each mode's circular W1 on every labelled row;
* :func:`calibrated_modes`: the mode each row answers with, chosen on its part's rows of a pool;
  a row of the pool is answered from its part's *other* pool rows (leave one out), as a row the pool
  does not hold is from all of them, so no row's answer was chosen on its own label;
* :func:`compute_mode_pmfs` / :func:`cached_mode_pmfs`: the modes' PMFs of every configuration, in
  the labels' frame and smoothing, cached beside the dataset.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

log = logging.getLogger(__name__)

CALIBRATION_VERSION = 1  # bump when the mode PMFs change for the same inputs


# ----------------------------------------------------------------------------------------------
# Pure functions
# ----------------------------------------------------------------------------------------------
def mode_w1(cdf, mode_pmfs, kept) -> np.ndarray:
    """(N, M): circular W1 (degrees) of each mode's PMF ``mode_pmfs`` (N, M, bins) against the
    label CDFs ``cdf`` (N, bins) on the ``kept`` rows; NaN on the others (no label)."""
    from feeder.labels.metrics import circular_w1

    pmfs = np.asarray(mode_pmfs, dtype=np.float64)
    cdf = np.asarray(cdf, dtype=np.float64)
    if pmfs.ndim != 3 or pmfs.shape[0] != cdf.shape[0] or pmfs.shape[2] != cdf.shape[1]:
        raise FeederError(f"mode_w1: mode PMFs of shape {pmfs.shape} do not match label CDFs of {cdf.shape}")
    out = np.stack([circular_w1(cdf, np.cumsum(pmfs[:, m], axis=1)) for m in range(pmfs.shape[1])], axis=1)
    return np.where(np.asarray(kept, dtype=bool)[:, None], out, np.nan)


def base_and_mode_w1(cdf, base_pmfs, mode_pmfs, kept) -> np.ndarray:
    """(N, M + 1): :func:`mode_w1` of the base model's PMFs ``base_pmfs`` (N, bins), then of each
    mode's (``mode_pmfs``, (N, M, bins)): the ``w1`` of :func:`calibrated_modes`."""
    base = mode_w1(cdf, np.asarray(base_pmfs)[:, None], kept)
    return np.concatenate([base, mode_w1(cdf, mode_pmfs, kept)], axis=1)


def model_analytic(arrays: dict) -> np.ndarray:
    """The analytic model's own PMFs of ``arrays``: ``base_analytic`` where the rows' ``analytic`` was
    calibrated on the part's labels (:func:`with_calibration`), else ``analytic``. What every input
    built from other rows' labels reads (a neighbour's miss and move, the composition's and the
    drops' fallback), and the baselines: a training row's calibrated PMF is chosen on its part's
    other rows, so a neighbour's would carry the row's own label into its inputs."""
    return arrays.get("base_analytic", arrays["analytic"])


def calibrated_modes(w1, parts, pool, margin_deg: float) -> np.ndarray:
    """(N,) the mode (column of ``w1``, (N, M); column 0 the base model) every row answers with.

    Per part, each mode's mean W1 over the part's rows in ``pool`` (a boolean mask; rows with a
    NaN W1 never count): for a row in the pool over the part's other pool rows, for any other row
    over all of them. The least mean answers where it beats the base's by at least ``margin_deg``
    (ties: the first column); a row whose part has no (other) pool row answers with the base (0)."""
    w1 = np.asarray(w1, dtype=np.float64)
    parts = np.asarray(parts)
    pool = np.asarray(pool, dtype=bool) & np.isfinite(w1).all(axis=1)
    if not (np.isfinite(margin_deg) and margin_deg >= 0):
        raise FeederError(f"calibration.margin_deg must be finite and >= 0, got {margin_deg!r}")
    out = np.zeros(len(parts), dtype=np.int64)
    for part in np.unique(parts):
        mine = parts == part
        rows = np.flatnonzero(mine & pool)
        total, n = w1[rows].sum(axis=0), rows.size
        for i in np.flatnonzero(mine):
            own = pool[i]
            count = n - 1 if own else n
            if count >= 1:
                out[i] = _choose((total - w1[i]) / count if own else total / count, margin_deg)
    return out


def _choose(mean, margin_deg: float) -> int:
    """The column of the least ``mean`` where it beats column 0's by at least ``margin_deg`` (ties:
    the first), else 0."""
    best = int(np.argmin(mean))
    return best if mean[0] - mean[best] >= margin_deg else 0


def part_modes(w1, parts, pool, margin_deg: float) -> dict[str, int]:
    """Per part with a row in ``pool``: the mode (column of ``w1``) chosen on all its pool rows, as
    :func:`calibrated_modes` chooses for a row outside the pool (a new configuration of the part)."""
    w1 = np.asarray(w1, dtype=np.float64)
    parts = np.asarray(parts)
    pool = np.asarray(pool, dtype=bool) & np.isfinite(w1).all(axis=1)
    out = {}
    for part in np.unique(parts[pool]):
        out[str(part)] = _choose(w1[pool & (parts == part)].mean(axis=0), margin_deg)
    return out


def calibrated_pmfs(base_pmfs, mode_pmfs, choice) -> np.ndarray:
    """(N, bins): each row's PMF under its chosen mode (``choice`` from :func:`calibrated_modes`;
    0: ``base_pmfs``, m >= 1: ``mode_pmfs[:, m - 1]``)."""
    stack = np.concatenate([np.asarray(base_pmfs)[:, None], np.asarray(mode_pmfs)], axis=1)
    return stack[np.arange(stack.shape[0]), np.asarray(choice)]


def calibration_network(cfg) -> bool:
    """``calibration.network`` (false when absent): the network of a Main fit starts from, and reads
    as its own component, the calibrated PMF (else the model's own, as the shipped predictor; the
    calibrated PMF is then scored beside it only). A one-line FeederError unless a boolean."""
    value = (cfg.get("calibration") or {}).get("network", False)
    if not isinstance(value, bool):
        raise FeederError(f"calibration.network must be true or false, got {value!r}")
    return value


def calibration_settings(cfg) -> tuple[tuple, float]:
    """(the modes, the margin) of ``cfg.calibration`` (no modes: none, calibration off); a one-line
    FeederError on a bad mode, margin or ``network`` flag."""
    calibration_network(cfg)
    from feeder.mechanics.candidates import Variant, variants_from_config

    section = cfg.get("calibration") or {}
    items = list(section.get("modes") or [])
    margin = section.get("margin_deg", 0.0)
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not np.isfinite(margin) or margin < 0:
        raise FeederError(f"calibration.margin_deg must be a number >= 0, got {margin!r}")
    if not items:
        return (), float(margin)
    modes = variants_from_config(items)
    if any(v == Variant(v.name) for v in modes):
        same = [v.name for v in modes if v == Variant(v.name)]
        raise FeederError(f"calibration.modes: {same} change nothing of the base model")
    return modes, float(margin)


# ----------------------------------------------------------------------------------------------
# The modes' PMFs of every configuration, cached
# ----------------------------------------------------------------------------------------------
def _part_mode_pmfs(job: tuple) -> np.ndarray:
    """(rows, M, bins) of one part's configurations (``job``: part path, units, config ids, frames,
    scene, modes, bins, smoothing), the part's push responses shared by its modes."""
    from feeder.lane.fences import parse_config_id
    from feeder.mechanics.candidates import variant_pmf
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    path, units, cids, frames, scene, modes, bins, smooth_deg = job
    outline, holes, _ = load_profile(path, units)
    geom, memo = push_geometry(outline, holes), {}
    out = np.zeros((len(cids), len(modes), bins))
    for i, (cid, frame) in enumerate(zip(cids, frames, strict=True)):
        loc1, loc2 = parse_config_id(cid)
        for m, mode in enumerate(modes):
            out[i, m] = variant_pmf(
                geom, loc1, loc2, scene, mode, frame_deg=float(frame), bins=bins, smooth_deg=smooth_deg, responses=memo
            )[0]
    return out


def compute_mode_pmfs(
    parts,
    config_ids,
    frames,
    scene,
    modes,
    smooth_deg: float,
    parts_dir,
    bins: int,
    units: str,
    workers=1,
    progress=None,
) -> np.ndarray:
    """(N, M, bins): every configuration's PMF under each mode (:func:`variant_pmf`, smoothed by
    ``smooth_deg``: the labels'), computed part by part, ``workers`` parts at once in forked
    processes (no value depends on it). ``progress(message)`` hears of every tenth part done."""
    parts = [str(p) for p in parts]
    order = list(dict.fromkeys(parts))
    jobs = []
    for part in order:
        path = Path(parts_dir) / f"{part}.stl"
        if not path.is_file():
            raise FeederError(f"part file {path} is missing (the calibration modes need every part's outline)")
        idx = [i for i, p in enumerate(parts) if p == part]
        jobs.append(
            (
                path,
                units,
                [config_ids[i] for i in idx],
                [frames[i] for i in idx],
                scene,
                tuple(modes),
                int(bins),
                float(smooth_deg),
            )
        )
    out = np.zeros((len(parts), len(modes), int(bins)))
    workers = max(1, min(int(workers), len(jobs)))
    if workers == 1:
        results = map(_part_mode_pmfs, jobs)
    else:
        from multiprocessing import get_context

        pool = get_context("fork").Pool(workers)
        results = pool.imap(_part_mode_pmfs, jobs)
    try:
        for n, (part, res) in enumerate(zip(order, results, strict=True), start=1):
            out[[i for i, p in enumerate(parts) if p == part]] = res
            if progress is not None and (n % 10 == 0 or n == len(order)):
                progress(f"calibration modes: {n} of {len(order)} parts")
    finally:
        if workers > 1:
            pool.terminate()
    return out


def cached_mode_pmfs(cache_path, key: str, n_rows: int, compute) -> np.ndarray:
    """:func:`compute_mode_pmfs` (called as ``compute()``), read from ``cache_path`` when it holds
    ``key``, else computed and written there atomically (:func:`feeder.io.write_npz`)."""
    from feeder import io

    if cache_path is not None and Path(cache_path).is_file():
        with np.load(cache_path, allow_pickle=False) as z:
            if str(z["key"]) == key and z["pmfs"].shape[0] == n_rows:  # the key holds the modes and bins too
                return z["pmfs"]
        log.info("calibration cache %s holds another key: recomputing", cache_path)
    pmfs = compute()
    if cache_path is not None:
        io.write_npz(Path(cache_path), key=np.array(key), pmfs=pmfs)
    return pmfs


def with_calibration(arrays: dict, pool, margin_deg: float) -> dict:
    """``arrays`` (holding ``mode_pmfs`` (N, M, bins) and ``mode_w1`` (N, M + 1): the base model's
    W1, then the modes') for a fit whose training rows are ``pool``: ``analytic`` becomes each
    row's calibrated PMF (:func:`calibrated_modes` on the kept pool rows), the model's own kept as
    ``base_analytic``, and ``calibration_mode`` the chosen column (0: base). Without
    ``mode_pmfs``: ``arrays`` unchanged."""
    if "mode_pmfs" not in arrays:
        return arrays
    base = model_analytic(arrays)
    pool = np.asarray(pool, dtype=bool) & np.asarray(arrays["kept"], dtype=bool)
    choice = calibrated_modes(arrays["mode_w1"], arrays["part"], pool, margin_deg)
    return dict(
        arrays, analytic=calibrated_pmfs(base, arrays["mode_pmfs"], choice), base_analytic=base, calibration_mode=choice
    )
