"""The inputs of the structured predictor (:mod:`feeder.learn.structured`) for every configuration
of a dataset, those it excludes as jammed included.

Per configuration (rows: the dataset's rows, then its ``excluded_*`` rows):

* ``ok``: the ok share of its drops (:func:`feeder.labels.pmf.sim_label` of its simulation file;
  0 for a file without an ok drop), the target of the ok head;
* ``x``: the configuration inputs: the analytic push block (``push_raw``), the 8 fence inputs
  (angles in units of 90°) and each variant's ok mass;
* ``pos``, ``mask``, ``cf``, ``base_mass``: the candidates of
  :func:`feeder.mechanics.candidates.configuration_candidates` padded to ``max_candidates``, the
  candidate features (each variant's basin mass, their mean, maximum and the share of variants
  giving at least ``present_mass``) and the base variant's basin masses;
* ``pmf``, ``cdf``, ``analytic`` (kept rows; zeros for excluded ones), ``kept``, ``part``,
  ``config_id``, ``split``, ``group_fold``.

The analytic variants are the costly part (about 0.3 s a configuration): they are cached in an
``.npz`` keyed by a hash of everything they depend on (:func:`candidates_key`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.learn.structured_calibration import (  # model_analytic: read here, and from here by structured_shipped
    CALIBRATION_VERSION,
    base_and_mode_w1,
    cached_mode_pmfs,
    calibration_settings,
    compute_mode_pmfs,
    model_analytic,
)
from feeder.learn.structured_mirror import mirror_labels, part_mirror_degs

log = logging.getLogger(__name__)

CANDIDATES_VERSION = 1  # bump when the candidate arrays change for the same inputs
CALIBRATION_CACHE = "structured_calibration.npz"  # the calibration modes' PMFs, beside the candidates cache
RIGHT_ANGLE_DEG = 90.0  # the fence inputs' angle unit


def candidates_key(parts, config_ids, frames, scene: dict, variants, cand_cfg: dict, parts_dir) -> str:
    """sha256 of what the cached candidates depend on: the configurations, their frames, the
    scene, the variants, the candidate settings, the part files' bytes and the versions."""
    from feeder.mechanics.features import PUSH_FEATURES_VERSION

    h = hashlib.sha256()
    h.update(json.dumps([list(map(str, parts)), list(map(str, config_ids)), [float(f) for f in frames]]).encode())
    h.update(json.dumps(scene, sort_keys=True).encode())
    h.update(json.dumps([v.spec() for v in variants], sort_keys=True).encode())
    h.update(json.dumps(cand_cfg, sort_keys=True).encode())
    h.update(f"{CANDIDATES_VERSION}:{PUSH_FEATURES_VERSION}".encode())
    for part in sorted(set(map(str, parts))):
        path = Path(parts_dir) / f"{part}.stl"
        if not path.is_file():
            raise FeederError(f"part file {path} is missing (the candidates need every part's outline)")
        h.update(path.read_bytes())
    return h.hexdigest()


def _ok_share(sim_path: Path, bins: int, sigma: float) -> float:
    from feeder.labels.pmf import sim_label
    from feeder.sim.record import load_sim

    rec = load_sim(sim_path, min_ok_drops=0)
    if not rec.ok.any():
        return 0.0
    return float(sim_label(rec, bins, sigma).ok_mass)


def _frames(data: dict, parts, features_dir) -> dict[str, float]:
    """frame_deg of every part: the dataset's, else its feature file's (principal labels)."""
    from feeder.parts.features import load_frame_deg

    frames = {str(p): float(f) for p, f in zip(data["part"], data["frame_deg"], strict=True)}
    principal = str(data["label_frame"]) == "principal"
    for part in parts:
        if part not in frames:
            frames[part] = load_frame_deg(Path(features_dir) / f"{part}.json") if principal else 0.0
    return frames


def row_mirror_degs(data: dict, parts, parts_dir, features_dir) -> np.ndarray:
    """Per row of ``parts``: :func:`feeder.learn.structured_mirror.label_mirror_deg` of its part
    in the label frame of ``data`` (:func:`feeder.labels.dataset.load_dataset`), its STL read in
    the dataset's ``parts.units`` (``model.mirror_labels``)."""
    units = str((json.loads(str(data["settings"])).get("parts") or {}).get("units", "auto"))
    frames = _frames(data, sorted(set(map(str, parts))), features_dir)
    return part_mirror_degs([str(p) for p in parts], [frames[str(p)] for p in parts], parts_dir, units)


def configuration_inputs(
    geom, memo: dict, config_id: str, frame_deg: float, scene, variants, cand_cfg: dict, bins: int
):
    """One configuration's (candidate positions (K,), their masses under each variant (K, V), each
    variant's ok mass (V,), push block (P,), analytic PMF (bins,)) for a part's push geometry
    ``geom`` (:func:`feeder.mechanics.hull.push_geometry`) in the label frame ``frame_deg``;
    ``memo`` caches the part's push responses across its configurations."""
    from feeder.lane.fences import parse_config_id
    from feeder.mechanics.candidates import configuration_candidates
    from feeder.mechanics.features import push_block

    loc1, loc2 = parse_config_id(config_id)
    c = configuration_candidates(
        geom,
        loc1,
        loc2,
        scene,
        variants,
        frame_deg=float(frame_deg),
        bins=bins,
        min_mass=float(cand_cfg["min_mass"]),
        window_deg=float(cand_cfg["window_deg"]),
        merge_deg=float(cand_cfg["merge_deg"]),
        max_candidates=int(cand_cfg["max_candidates"]),
        responses=memo,
    )
    push, analytic = push_block(
        geom,
        loc1,
        loc2,
        scene,
        frame_deg=float(frame_deg),
        bins=bins,
        pmf_smooth_deg=float(cand_cfg["label_smooth_deg"]),
        responses=memo,
    )
    return c.positions, c.masses, c.ok, push, analytic


def compute_candidates(
    parts, config_ids, frames, scene, variants, cand_cfg: dict, parts_dir, bins: int, units: str, progress=None
):
    """:func:`configuration_inputs` of every configuration (label smoothing ``cand_cfg``'s
    ``label_smooth_deg``). ``progress(message)`` hears of every tenth part begun."""
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    geoms, memos, out = {}, {}, []
    for part, cid, frame in zip(parts, config_ids, frames, strict=True):
        if part not in geoms:
            if progress is not None and len(geoms) % 10 == 0:
                progress(f"candidates: part {len(geoms) + 1} of {len(set(parts))} ({part})")
            path = Path(parts_dir) / f"{part}.stl"
            if not path.is_file():
                raise FeederError(f"part file {path} is missing (the candidates need every part's outline)")
            outline, holes, _ = load_profile(path, units)
            geoms[part], memos[part] = push_geometry(outline, holes), {}
        out.append(configuration_inputs(geoms[part], memos[part], cid, frame, scene, variants, cand_cfg, bins))
    return out


def _pad(cands, k_max: int, n_var: int):
    n = len(cands)
    pos = np.zeros((n, k_max))
    masses = np.zeros((n, k_max, n_var))
    mask = np.zeros((n, k_max), dtype=bool)
    for i, (p, m, *_rest) in enumerate(cands):
        k = p.size
        pos[i, :k], masses[i, :k], mask[i, :k] = p, m, True
    return pos, masses, mask


CACHE_ARRAYS = ("k", "pos", "masses", "ok_var", "push", "analytic")


def write_candidates_cache(path, key: str, cands, n_variants: int) -> None:
    """Write :func:`compute_candidates`' output under ``key`` (atomically, :func:`feeder.io.write_npz`)."""
    from feeder import io

    k_max = max(max(c[0].size for c in cands), 1)
    pos, masses, _ = _pad(cands, k_max, n_variants)
    io.write_npz(
        Path(path),
        key=np.array(key),
        k=np.array([c[0].size for c in cands]),
        pos=pos,
        masses=masses,
        ok_var=np.stack([c[2] for c in cands]),
        push=np.stack([c[3] for c in cands]),
        analytic=np.stack([c[4] for c in cands]),
    )


def read_candidates_cache(path, key: str):
    """The cached candidates of :func:`write_candidates_cache`, or None when ``path`` is missing or
    holds another key. Each array is read once: every ``z[name]`` decompresses the whole array, so
    reading it per row kept a full copy per row alive (~17 GB for the default study's 1,578)."""
    if not Path(path).is_file():
        return None
    with np.load(path, allow_pickle=False) as z:
        if str(z["key"]) != key:
            return None
        k, pos, masses, ok_var, push, analytic = (z[name] for name in CACHE_ARRAYS)
    return [(pos[i, : k[i]], masses[i, : k[i]], ok_var[i], push[i], analytic[i]) for i in range(k.size)]


def candidate_features(masses, mask, present_mass: float) -> np.ndarray:
    """(N, K, V + 3): each variant's basin mass, their mean, their maximum and the share of
    variants giving the candidate at least ``present_mass`` (zeros where ``mask`` is False)."""
    m = np.asarray(masses, dtype=np.float64)
    feats = np.concatenate(
        [
            m,
            m.mean(axis=2, keepdims=True),
            m.max(axis=2, keepdims=True),
            (m >= present_mass).mean(axis=2, keepdims=True),
        ],
        axis=2,
    )
    return np.where(np.asarray(mask)[..., None], feats, 0.0)


def row_inputs(cands, config_ids, n_variants: int, max_candidates: int, present_mass: float) -> dict:
    """The model inputs of rows from their :func:`configuration_inputs` ``cands``: ``x`` (push block,
    the 8 fence inputs with angles over 90°, each variant's ok mass), the candidates padded to
    ``max_candidates`` (``pos``, ``masses``, ``mask``), their features ``cf``
    (:func:`candidate_features`), ``base_mass``, ``analytic`` and ``analytic_ok``."""
    from feeder.labels.dataset import feeder_vector
    from feeder.lane.fences import parse_config_id

    pos, masses, mask = _pad(cands, int(max_candidates), int(n_variants))
    ok_var = np.stack([c[2] for c in cands])
    push = np.stack([c[3] for c in cands])
    fences = np.stack([feeder_vector(*parse_config_id(c)) for c in config_ids])
    fences[:, [3, 7]] /= RIGHT_ANGLE_DEG
    return {
        "x": np.concatenate([push, fences, ok_var], axis=1),
        "pos": pos,
        "mask": mask,
        "masses": masses,
        "cf": candidate_features(masses, mask, float(present_mass)),
        "base_mass": masses[:, :, 0],
        "analytic": np.stack([c[4] for c in cands]),
        "analytic_ok": ok_var[:, 0],
    }


def candidate_settings(candidates, bins: int, sigma_bins: float) -> dict:
    """The settings the candidates depend on: ``candidates``' (``config/hydra/structured.yaml``)
    ``min_mass``, ``window_deg``, ``merge_deg``, ``max_candidates``, ``present_mass`` and the labels'
    smoothing in degrees (``label_smooth_deg``), as plain numbers."""
    from feeder.labels.dataset import label_smooth_deg

    out = {k: candidates[k] for k in ("min_mass", "window_deg", "merge_deg", "max_candidates", "present_mass")}
    out = {k: (int(v) if k == "max_candidates" else float(v)) for k, v in out.items()}
    out["label_smooth_deg"] = label_smooth_deg(int(bins), float(sigma_bins))
    return out


def cached_candidates(cache_path, key: str, push_raw, compute, n_variants: int, progress=None) -> list:
    """The candidates of every configuration (:func:`compute_candidates`, called as ``compute()``),
    read from ``cache_path`` when it holds ``key`` and its push block agrees with the dataset's
    ``push_raw`` (its first rows: the kept configurations), else computed and cached. The key
    hashes every input but not the arithmetic: a cache written under other BLAS kernels can differ
    where an exit turn sits on a knife edge (docs/testing.md), so such a cache is recomputed, not
    blamed on the dataset. Computed candidates that still disagree are a one-line FeederError."""

    def agrees(cands) -> bool:
        if push_raw is None:
            return True
        push = np.stack([c[3] for c in cands])[: len(push_raw)]
        return push.shape == np.shape(push_raw) and bool(np.allclose(push, push_raw))

    cands = read_candidates_cache(cache_path, key) if cache_path is not None else None
    if cands is not None and not agrees(cands):
        said = f"candidates: the cache {cache_path} disagrees with the dataset's push block; recomputing it"
        log.warning(said)
        if progress is not None:
            progress(said)
        cands = None
    if cands is None:
        log.info("computing candidates")
        cands = compute()
        if not agrees(cands):
            raise FeederError("the dataset's push_raw differs from this code's push block: rebuild the dataset")
        if cache_path is not None:
            write_candidates_cache(cache_path, key, cands, n_variants)
    return cands


def split_arrays(data: dict) -> dict:
    """Of every configuration of ``data`` (:func:`feeder.labels.dataset.load_dataset`), kept ones
    first, then those excluded as jammed (the order of :func:`structured_arrays`): ``part``,
    ``config_id``, ``split``, ``kept`` and ``group_fold`` (an excluded part no kept row has gets a
    fold from its id's hash). What the protocol's splits need, without the candidates."""

    def both(key):  # the kept rows', then the excluded ones' (none in a dataset without that block)
        return [*map(str, data[key]), *map(str, data[f"excluded_{key}"] if f"excluded_{key}" in data else [])]

    parts = both("part")
    n_kept = len(data["part"])
    fold_of = {str(p): int(f) for p, f in zip(data["part"], data["group_fold"], strict=True)}
    n_folds = int(np.max(data["group_fold"])) + 1
    return {
        "part": np.array(parts),
        "config_id": np.array(both("config_id")),
        "split": np.array(both("split")),
        "kept": np.arange(len(parts)) < n_kept,
        "group_fold": np.array(
            [fold_of.get(p, int(hashlib.sha256(p.encode()).hexdigest(), 16) % n_folds) for p in parts]
        ),
    }


def structured_arrays(
    data: dict, cfg, sim_dir, parts_dir, features_dir, cache_path=None, progress=None, calibration: bool = False
) -> dict:
    """The arrays of the module doc for ``data`` (:func:`feeder.labels.dataset.load_dataset`),
    with the candidate settings ``cfg.candidates`` of ``config/hydra/structured.yaml``.
    ``calibration``: also every configuration's PMF under each of ``cfg.calibration.modes``
    (``mode_pmfs``) and the circular W1 of the base model and of each mode on the kept rows
    (``mode_w1``), for :func:`feeder.learn.structured_calibration.with_calibration`; cached in
    :data:`CALIBRATION_CACHE` beside ``cache_path``."""
    from feeder.mechanics.candidates import variants_from_config
    from feeder.mechanics.fence import default_scene

    settings = json.loads(str(data["settings"]))
    scene = settings.get("scene") or default_scene()
    labels = settings["labels"]
    bins = int(labels["bins"])
    units = str((settings.get("parts") or {}).get("units", "auto"))
    n_kept = len(data["part"])
    parts = [*map(str, data["part"]), *map(str, data["excluded_part"])]
    cids = [*map(str, data["config_id"]), *map(str, data["excluded_config_id"])]
    frames_of = _frames(data, sorted(set(parts)), features_dir)
    frames = [frames_of[p] for p in parts]
    variants = variants_from_config(cfg.candidates.variants)
    cand_cfg = candidate_settings(cfg.candidates, bins, float(labels["sigma_bins"]))
    sim_dir = Path(sim_dir)
    ok = np.array(  # first: a missing or broken simulation file stops the run before the candidates' minutes
        [
            _ok_share(sim_dir / p / f"{c}.npz", bins, float(labels["sigma_bins"]))
            for p, c in zip(parts, cids, strict=True)
        ]
    )
    key = candidates_key(parts, cids, frames, scene, variants, cand_cfg, parts_dir)
    push_raw = data["push_raw"] if "push_raw" in data else None
    cands = cached_candidates(
        cache_path,
        key,
        push_raw,
        lambda: compute_candidates(parts, cids, frames, scene, variants, cand_cfg, parts_dir, bins, units, progress),
        len(variants),
        progress,
    )
    inputs = row_inputs(
        cands, cids, len(variants), int(cfg.candidates.max_candidates), float(cfg.candidates.present_mass)
    )
    n = len(parts)
    pmf = np.zeros((n, bins))
    pmf[:n_kept] = data["pmf"]
    out = {
        **split_arrays(data),
        "frame_deg": np.array(frames, dtype=np.float64),
        "ok": ok,
        **inputs,
        "pmf": pmf,
        "cdf": np.cumsum(pmf, axis=1),
        "wide_sigma_bins": float(cfg.model.wide_sigma_bins),
    }
    if mirror_labels(cfg):  # a one-fence label read at the other location too (structured_mirror)
        out["mirror_deg"] = row_mirror_degs(data, parts, parts_dir, features_dir)
    if not calibration:
        return out
    modes, _ = calibration_settings(cfg)
    if not modes:
        return out
    # calibration.modes: every configuration's PMF under each mode, cached beside the candidates
    smooth = float(cand_cfg["label_smooth_deg"])
    mode_key = candidates_key(
        parts, cids, frames, scene, modes, {"calibration": CALIBRATION_VERSION, "smooth_deg": smooth}, parts_dir
    )
    mode_cache = None if cache_path is None else Path(cache_path).with_name(CALIBRATION_CACHE)
    workers = int(cfg.train.get("workers", 1))
    out["mode_pmfs"] = cached_mode_pmfs(
        mode_cache,
        mode_key,
        n,
        lambda: compute_mode_pmfs(parts, cids, frames, scene, modes, smooth, parts_dir, bins, units, workers, progress),
    )
    out["mode_w1"] = base_and_mode_w1(out["cdf"], out["analytic"], out["mode_pmfs"], out["kept"])
    return out


# ----------------------------------------------------------------------------------------------
# The part's own neighbouring labels (known parts at new angles)
# ----------------------------------------------------------------------------------------------
FAR_DEG = 180.0  # the angle distance input of a missing neighbour: beyond any |Δθ1| + |Δθ2| of the grid
# the inputs of each neighbour, followed by the part's "part_miss" and "has_part" (neighbour_block)
NEIGHBOUR_FEATURES = ("has", "distance", "closeness", "analytic_move", "analytic_miss", "ok")


def fence_key(config_id: str) -> tuple[tuple[str, str], tuple[float, float]]:
    """(the type combination, the two angles) of a configuration id; ``none`` has angle 0. Here, below
    :mod:`feeder.learn.neighbour` and :mod:`feeder.learn.structured_protocol`, which both read it."""
    from feeder.lane.fences import parse_config_id

    a, b = parse_config_id(str(config_id))
    return (a.type, b.type), (float(a.angle), float(b.angle))


def nearest_configuration(config_id: str, pool: list[str]) -> tuple[int, float]:
    """The position in ``pool`` of the configuration of ``config_id``'s fence types nearest to it by
    ``|Δθ1| + |Δθ2|`` (ties to the earlier one; :func:`feeder.learn.neighbour.neighbour_index`'s rule)
    and that distance in degrees; ``(-1, inf)`` when no configuration of ``pool`` has its types."""
    types, angles = fence_key(config_id)
    best, dist = -1, float("inf")
    for k, other in enumerate(pool):
        t, a = fence_key(other)
        if t != types:
            continue
        d = float(np.abs(np.subtract(a, angles)).sum())
        if d < dist:
            best, dist = k, d
    return best, dist


def nearest_rows(parts, config_ids, pool, rows, k: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``rows``: the ``k`` nearest rows of ``pool`` (a boolean mask) of the same part
    and fence-type combination by ``|Δθ1| + |Δθ2|`` (degrees), nearest first, ties to the lower
    index; never the row itself. Returns (indices (n, k), −1 where fewer; distances (n, k), inf)."""
    parts = np.asarray(parts).astype(str)
    keys = [fence_key(c) for c in config_ids]
    by_group: dict[tuple, list[int]] = {}
    for j in np.flatnonzero(np.asarray(pool, dtype=bool)):
        by_group.setdefault((parts[j], keys[j][0]), []).append(int(j))
    rows = np.asarray(rows, dtype=np.int64)
    idx = np.full((rows.size, int(k)), -1, dtype=np.int64)
    dist = np.full((rows.size, int(k)), np.inf)
    for n, i in enumerate(rows):
        group = [j for j in by_group.get((parts[i], keys[i][0]), []) if j != i]
        if not group:
            continue
        d = np.abs(np.array([keys[j][1] for j in group]) - np.array(keys[i][1])).sum(axis=1)
        order = np.argsort(d, kind="stable")[: int(k)]  # stable: ties keep index order
        idx[n, : order.size] = np.asarray(group)[order]
        dist[n, : order.size] = d[order]
    return idx, dist


def nearest_cross_rows(parts, config_ids, pool, rows, k: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``rows`` with a downstream (Location 1) fence: the ``k`` nearest rows of ``pool``
    of the same part whose Location 1 fence has the same type but whose type combination differs
    (the same last fence after another upstream one, or none), by ``|Δθ1|`` (degrees), nearest
    first, ties to the lower index. The downstream fence sets most of where a part comes to rest.
    Returns (indices (n, k), −1 where fewer or no Location 1 fence; distances (n, k), inf)."""
    parts = np.asarray(parts).astype(str)
    keys = [fence_key(c) for c in config_ids]
    by_loc1: dict[tuple, list[int]] = {}
    for j in np.flatnonzero(np.asarray(pool, dtype=bool)):
        by_loc1.setdefault((parts[j], keys[j][0][0]), []).append(int(j))
    rows = np.asarray(rows, dtype=np.int64)
    idx = np.full((rows.size, int(k)), -1, dtype=np.int64)
    dist = np.full((rows.size, int(k)), np.inf)
    for n, i in enumerate(rows):
        (loc1, _), (angle1, _) = keys[i]
        if loc1 == "none":
            continue
        group = [j for j in by_loc1.get((parts[i], loc1), []) if keys[j][0] != keys[i][0]]
        if not group:
            continue
        d = np.abs(np.array([keys[j][1][0] for j in group]) - angle1)
        order = np.argsort(d, kind="stable")[: int(k)]
        idx[n, : order.size] = np.asarray(group)[order]
        dist[n, : order.size] = d[order]
    return idx, dist


def neighbour_source(arrays: dict, pool) -> tuple[dict, np.ndarray]:
    """The rows a neighbour is read from: ``arrays``' kept rows of ``pool``, with each one-fence
    label of a part with a mirror axis read at the other location appended
    (:func:`feeder.learn.structured_mirror.with_mirrors`; only where ``arrays`` holds
    ``mirror_deg``, ``model.mirror_labels``). Returns (their fields, the pool over them); row ``i``
    of ``arrays`` is row ``i`` of the source."""
    from feeder.learn.structured_mirror import with_mirrors

    source, pool, _ = with_mirrors(arrays, np.asarray(pool, dtype=bool) & np.asarray(arrays["kept"], dtype=bool))
    return source, pool


def neighbour_rows(
    arrays: dict, pool, k: int, cross: int = 0, hide_same: bool = False, source: tuple | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Every row's ``k`` nearest kept rows of ``pool`` of its part and fence types
    (:func:`nearest_rows`), then its ``cross`` nearest under the same downstream fence
    (:func:`nearest_cross_rows`): (indices (N, k + cross), −1 where missing; distances).
    The indices are rows of :func:`neighbour_source` (``arrays``' own, then the mirrored labels).
    ``hide_same``: the first ``k`` missing for every row, as for a configuration of a type
    combination the part has no label of (the Fences rows). ``source``: that function's answer
    for ``arrays`` and ``pool`` when the caller has it already (it is not built again)."""
    source, pool = neighbour_source(arrays, pool) if source is None else source
    rows = np.arange(len(arrays["part"]))
    if hide_same:
        idx, dist = np.full((rows.size, int(k)), -1, dtype=np.int64), np.full((rows.size, int(k)), np.inf)
    else:
        idx, dist = nearest_rows(source["part"], source["config_id"], pool, rows, k)
    if int(cross) > 0:  # then the nearest of other type combinations under the same downstream fence
        c_idx, c_dist = nearest_cross_rows(source["part"], source["config_id"], pool, rows, cross)
        idx, dist = np.concatenate([idx, c_idx], axis=1), np.concatenate([dist, c_dist], axis=1)
    return idx, dist


def basin_components(pmfs, analytic, idx, basins: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each neighbour's label split into its ``basins`` largest basins and the rest
    (:func:`feeder.labels.metrics.basin_owners`), each normalised, as separate mixture components:
    (inputs (N, 3 J basins), components (N, J (basins + 1), bins), starting logit offsets (N, J
    (basins + 1))). ``pmfs`` (N, J, bins): the neighbours' labels (:func:`neighbour_block`);
    ``idx`` (N, J) their rows (−1: missing). The offsets are log(basin mass), so that a network
    that starts each neighbour at one weight starts its basins at that weight times their masses:
    together the whole label again. A missing basin or neighbour, or an empty rest, is the row's
    analytic PMF with a floor offset. Per basin the inputs are its mass in the neighbour's label,
    the row's analytic mass in its bins and the neighbour's analytic mass in them (zeros where
    missing)."""
    from feeder.labels.metrics import basin_owners
    from feeder.learn.structured import LOGIT_FLOOR

    pmfs, analytic = np.asarray(pmfs, np.float64), np.asarray(analytic, np.float64)
    n, j_count, bins = pmfs.shape
    b_count = int(basins)
    comps = np.repeat(analytic[:, None, :], j_count * (b_count + 1), axis=1)
    offsets = np.full((n, j_count * (b_count + 1)), math.log(LOGIT_FLOOR))
    feats = np.zeros((n, j_count * 3 * b_count))
    split: dict[int, tuple] = {}  # by neighbour row: its top basins' masks and masses
    for r in range(n):
        for j in range(j_count):
            nb = int(idx[r, j])
            first = j * (b_count + 1)
            if nb < 0:
                continue
            if nb not in split:
                owner = basin_owners(pmfs[r, j])
                ids, inverse = np.unique(owner, return_inverse=True)
                mass = np.bincount(inverse, weights=pmfs[r, j], minlength=ids.size)
                top = np.argsort(-mass, kind="stable")[:b_count]
                split[nb] = ([inverse == t for t in top], mass[top])
            masks, masses = split[nb]
            taken = np.zeros(bins, dtype=bool)
            for b, (inside, m) in enumerate(zip(masks, masses, strict=True)):
                if m <= 0:
                    continue
                comps[r, first + b] = np.where(inside, pmfs[r, j], 0.0) / m
                offsets[r, first + b] = math.log(m)
                feats[r, 3 * (j * b_count + b) : 3 * (j * b_count + b) + 3] = (
                    m,
                    analytic[r, inside].sum(),
                    analytic[nb, inside].sum(),
                )
                taken |= inside
            rest = float(pmfs[r, j][~taken].sum())
            if rest > LOGIT_FLOOR:
                comps[r, first + b_count] = np.where(taken, 0.0, pmfs[r, j]) / rest
                offsets[r, first + b_count] = math.log(rest)
    return feats, comps, offsets


def label_miss(pmf, analytic) -> np.ndarray:
    """Per row: the circular W1 between its label and its analytic PMF, over 90° (a neighbour input)."""
    from feeder.labels.metrics import circular_w1

    a = np.atleast_2d(np.asarray(analytic, np.float64))
    return circular_w1(np.cumsum(np.atleast_2d(np.asarray(pmf, np.float64)), axis=1), np.cumsum(a, axis=1)) / (
        RIGHT_ANGLE_DEG
    )


def signed_steps(config_ids, source_ids, idx) -> np.ndarray:
    """Each neighbour's signed angle steps from its row, over 90°: (N, 2 J) of ``(θ1 − θ1 of the
    row, θ2 − θ2 of the row)`` per neighbour ``idx`` (N, J; rows of ``source_ids``, −1: none, then
    both 0). The Location 2 step is 0 where the neighbour's fence types differ from the row's (a
    cross neighbour: only its Location 1 fence is the row's type). The distances alone do not say
    on which side of the row a neighbour lies, nor whether two neighbours bracket it."""
    keys = [fence_key(c) for c in np.asarray(config_ids).astype(str)]
    source_ids = np.asarray(source_ids).astype(str)
    idx = np.asarray(idx, dtype=np.int64)
    out = np.zeros((idx.shape[0], 2 * idx.shape[1]))
    for i, j in zip(*np.nonzero(idx >= 0), strict=True):
        (types, angles), (nb_types, nb_angles) = keys[i], fence_key(source_ids[idx[i, j]])
        out[i, 2 * j] = (nb_angles[0] - angles[0]) / RIGHT_ANGLE_DEG
        if nb_types == types:
            out[i, 2 * j + 1] = (nb_angles[1] - angles[1]) / RIGHT_ANGLE_DEG
    return out


def neighbour_block(
    arrays: dict,
    pool,
    k: int,
    near_deg: float,
    cross: int = 0,
    miss=None,
    hide_same: bool = False,
    signed: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Every row's ``k`` nearest labelled rows of ``pool`` (kept rows of the same part and fence
    types, :func:`nearest_rows`), then its ``cross`` nearest under the same downstream fence in
    other type combinations (:func:`nearest_cross_rows`, distance ``|Δθ1|``), as inputs of the
    structured predictor: (features (N, 6(k + cross) + 2, + 2(k + cross) with ``signed``), PMFs
    (N, k + cross, bins)).

    Per neighbour (:data:`NEIGHBOUR_FEATURES`): present (0/1); its angle distance over 90°
    (:data:`FAR_DEG` when missing); its closeness ``exp(−distance / near_deg)`` (0 when missing);
    the circular W1 between the row's and its analytic PMFs, and between its label and its
    analytic PMF (over 90°; 0 when missing); its ok share (the row's analytic ok mass when
    missing). Then the mean W1 between label and analytic PMF over the part's other pool rows
    (over 90°) and whether there are any. A missing neighbour's PMF is the
    row's analytic PMF, so its component changes nothing. No label of the row itself is read.
    ``miss``: each pool row's :func:`label_miss`, when known (then only the neighbours' analytic
    PMFs are read: the others may be anything). ``hide_same``: :func:`neighbour_rows`'.
    ``signed`` (``model.neighbour_signed``): then, per neighbour, :func:`signed_steps`."""
    from feeder.labels.metrics import circular_w1
    from feeder.learn.structured_mirror import with_mirrors

    pool = np.asarray(pool, dtype=bool) & np.asarray(arrays["kept"], dtype=bool)
    n = len(arrays["part"])
    source, source_pool, mirrored = with_mirrors(arrays, pool)  # neighbour_source: the rows idx indexes
    idx, dist = neighbour_rows(arrays, pool, k, cross, hide_same, source=(source, source_pool))
    k = idx.shape[1]
    analytic, pmf = np.asarray(model_analytic(arrays), np.float64), np.asarray(arrays["pmf"], np.float64)
    s_analytic, s_pmf = np.asarray(model_analytic(source), np.float64), np.asarray(source["pmf"], np.float64)
    a_cdf, s_cdf = np.cumsum(analytic, axis=1), np.cumsum(s_analytic, axis=1)
    if miss is None:  # each pool row's label against its analytic PMF
        miss = np.zeros(n)
        miss[pool] = label_miss(pmf[pool], analytic[pool])
    miss = np.where(pool, np.asarray(miss, dtype=np.float64), 0.0)
    s_miss = np.concatenate([miss, miss[mirrored]])  # a reflection moves label and analytic PMF alike
    s_ok = np.asarray(source["ok"])
    feats, pmfs = [], np.repeat(analytic[:, None, :], int(k), axis=1)
    for j in range(int(k)):
        has = idx[:, j] >= 0
        nb = np.where(has, idx[:, j], 0)
        move = np.where(has, circular_w1(a_cdf, s_cdf[nb]) / RIGHT_ANGLE_DEG, 0.0)
        feats += [
            has.astype(float),
            np.where(has, dist[:, j], FAR_DEG) / RIGHT_ANGLE_DEG,
            np.where(has, np.exp(-dist[:, j] / near_deg), 0.0),
            move,
            np.where(has, s_miss[nb], 0.0),
            np.where(has, s_ok[nb], np.asarray(arrays["analytic_ok"])),
        ]
        pmfs[has, j] = s_pmf[nb[has]]
    if signed:
        feats += list(signed_steps(arrays["config_id"], source["config_id"], idx).T)
    parts = np.asarray(arrays["part"]).astype(str)
    part_miss, has_part = np.zeros(n), np.zeros(n)
    for p in np.unique(parts):
        of = np.flatnonzero(parts == p)
        in_pool = of[pool[of]]
        total, count = miss[in_pool].sum(), in_pool.size
        for i in of:  # leave the row itself out
            c = count - int(pool[i])
            if c > 0:
                part_miss[i] = (total - (miss[i] if pool[i] else 0.0)) / c
                has_part[i] = 1.0
    return np.column_stack([*feats, part_miss, has_part]), pmfs


def window_mass(pmfs, centres_deg, half_deg: float) -> np.ndarray:
    """The mass of each PMF row of ``pmfs`` (N, bins) whose bin centres lie within ±``half_deg``
    (circular) of each of ``centres_deg`` (N, K): (N, K)."""
    pmfs = np.atleast_2d(np.asarray(pmfs, dtype=np.float64))
    bins = pmfs.shape[-1]
    centres = (np.arange(bins) + 0.5) * (360.0 / bins)
    c = np.asarray(centres_deg, dtype=np.float64)
    d = np.abs(np.mod(centres[None, None, :] - c[..., None] + 180.0, 360.0) - 180.0)
    return np.einsum("nkb,nb->nk", (d <= float(half_deg)).astype(np.float64), pmfs)


def neighbour_modes(pmf, top: int) -> list[tuple[float, float]]:
    """The ``top`` largest basins of a label (:func:`feeder.labels.metrics.resting_orientations`)
    as (mode in degrees, mass)."""
    from feeder.labels.metrics import resting_orientations

    return resting_orientations(pmf, top=int(top))


def neighbour_candidates(arrays: dict, pmfs, idx, top: int, merge_deg: float, window_deg: float) -> dict:
    """``arrays`` with the modes of each row's neighbouring labels added to its candidates.

    ``pmfs`` (N, J, bins) and ``idx`` (N, J) are the neighbours' labels and rows (−1: missing,
    :func:`neighbour_block`, :func:`neighbour_rows`). Per row, each present neighbour's ``top``
    largest basins' modes (:func:`neighbour_modes`) join the candidates unless one lies within
    ``merge_deg`` of a candidate already there (circular); a new candidate has no variant masses
    (``masses`` and ``base_mass`` 0, so the ``variants`` network gives it no weight). The candidate
    features ``cf`` of every candidate, old and new, gain J + 2 columns: each neighbour's label mass
    within ±``window_deg`` of it (0 for a missing neighbour), the row's analytic mass there, and
    whether the candidate came from a neighbour. The candidate axis is padded to its old width
    plus J · ``top`` for every row alike. A neighbour's modes are computed once per row index in
    ``idx``: every row that reads row j must be given row j's label (as :func:`neighbour_block`
    does; the drops pass each row's own index)."""
    if isinstance(top, bool) or int(top) != top or top < 0:
        raise FeederError(f"model.neighbour_candidates must be an integer >= 0, got {top!r}")
    if int(top) == 0:
        return arrays
    pmfs, idx = np.asarray(pmfs, dtype=np.float64), np.asarray(idx)
    n, j_count, _ = pmfs.shape
    pos, mask = np.asarray(arrays["pos"], dtype=np.float64), np.asarray(arrays["mask"], dtype=bool)
    k_old = pos.shape[1]
    k_new = k_old + j_count * int(top)
    new_pos = np.zeros((n, k_new))
    new_mask = np.zeros((n, k_new), dtype=bool)
    from_nb = np.zeros((n, k_new))
    new_pos[:, :k_old], new_mask[:, :k_old] = pos, mask
    modes_of: dict[int, list] = {}
    for r in range(n):
        taken = list(pos[r, mask[r]])
        slot = k_old
        for j in range(j_count):
            nb = int(idx[r, j])
            if nb < 0:
                continue
            if nb not in modes_of:
                modes_of[nb] = neighbour_modes(pmfs[r, j], int(top))
            for yaw, _mass in modes_of[nb]:
                gaps = np.abs(np.mod(np.asarray(taken) - yaw + 180.0, 360.0) - 180.0)
                if gaps.size and gaps.min() <= float(merge_deg):
                    continue
                new_pos[r, slot], new_mask[r, slot], from_nb[r, slot] = yaw, True, 1.0
                taken.append(yaw)
                slot += 1
    extra = [window_mass(pmfs[:, j], new_pos, window_deg) * (idx[:, j] >= 0)[:, None] for j in range(j_count)]
    extra += [window_mass(model_analytic(arrays), new_pos, window_deg), from_nb]
    pad = lambda a: np.concatenate([a, np.zeros((n, k_new - k_old, *a.shape[2:]))], axis=1)  # noqa: E731
    cf = np.concatenate([pad(np.asarray(arrays["cf"], dtype=np.float64)), np.stack(extra, axis=2)], axis=2)
    return dict(
        arrays,
        pos=new_pos,
        mask=new_mask,
        masses=pad(np.asarray(arrays["masses"], dtype=np.float64)),
        base_mass=pad(np.asarray(arrays["base_mass"], dtype=np.float64)),
        cf=np.where(new_mask[..., None], cf, 0.0),
    )


def stack_rows(first: dict, second: dict) -> dict:
    """The per-row arrays of two versions of the same configurations (the same keys, ``N`` rows
    each) one after the other: row ``i`` of ``second`` becomes row ``N + i``; what is not a per-row
    array (a setting) is ``first``'s. A one-line FeederError where they do not match."""
    n = len(first["part"])
    if set(first) != set(second) or len(second["part"]) != n:
        raise FeederError("stack_rows: two versions of different configurations")
    out = {}
    for key, a in first.items():
        b = second[key]
        if isinstance(a, np.ndarray) and a.ndim and a.shape[0] == n:
            if not isinstance(b, np.ndarray) or b.shape[1:] != a.shape[1:]:
                raise FeederError(f"stack_rows: {key} differs in shape")
            out[key] = np.concatenate([a, b], axis=0)
        else:
            out[key] = a
    return out


def with_neighbours(
    arrays: dict,
    pool,
    k: int,
    near_deg: float,
    cross: int = 0,
    basins: int = 0,
    candidates: int = 0,
    merge_deg: float | None = None,
    window_deg: float | None = None,
    hide_same: bool = False,
    signed: bool = False,
) -> dict:
    """``arrays`` with the neighbour inputs of :func:`neighbour_block` appended to ``x`` and their
    PMFs as ``neighbour_pmf`` (unchanged when ``k`` and ``cross`` are 0). With ``basins`` > 0 each
    neighbour's PMF is split into its largest basins and the rest (:func:`basin_components`):
    their inputs are appended too, and ``neighbour_offset`` holds their starting logit offsets.
    With ``candidates`` > 0 the modes of each neighbour's largest basins join the row's candidates
    (:func:`neighbour_candidates`, with ``merge_deg`` and ``window_deg``: the settings of
    ``candidates`` in ``config/hydra/structured.yaml``, needed then). ``hide_same``: every row as if
    its part had no label of its type combination (:func:`neighbour_rows`). ``signed``: the
    neighbours' signed angle steps too (:func:`signed_steps`)."""
    if int(k) + int(cross) <= 0:
        return arrays
    if not near_deg > 0:
        raise FeederError(f"model.neighbour_near_deg must be > 0, got {near_deg}")
    if isinstance(basins, bool) or int(basins) != basins or basins < 0:
        raise FeederError(f"model.neighbour_basins must be an integer >= 0, got {basins!r}")
    feats, pmfs = neighbour_block(arrays, pool, int(k), float(near_deg), int(cross), hide_same=hide_same, signed=signed)
    out = dict(arrays, x=np.concatenate([arrays["x"], feats], axis=1), neighbour_pmf=pmfs)
    if int(basins) > 0 or int(candidates) > 0:
        idx, _ = neighbour_rows(arrays, pool, int(k), int(cross), hide_same)
    if int(candidates) > 0:
        if merge_deg is None or window_deg is None:
            raise FeederError("neighbour candidates need candidates.merge_deg and candidates.window_deg")
        out = neighbour_candidates(out, pmfs, idx, int(candidates), float(merge_deg), float(window_deg))
    if int(basins) > 0:  # a neighbour's analytic masses: read from the rows idx indexes
        source, _ = neighbour_source(arrays, pool)
        b_feats, comps, offsets = basin_components(pmfs, model_analytic(source), idx, int(basins))
        out.update(x=np.concatenate([out["x"], b_feats], axis=1), neighbour_pmf=comps, neighbour_offset=offsets)
    return out


# ----------------------------------------------------------------------------------------------
# A few simulated drops of the configuration itself (a predictor between the model and the simulator)
# ----------------------------------------------------------------------------------------------
DROP_FEATURES = ("drops_ok_share", "drops_have_ok")  # appended to x by with_drops
START_YAW_TOL_DEG = 1e-6  # a drop's initial yaw within this of a start-grid yaw is that yaw's drop (float noise)


def start_grid_drops(initial_deg, design: dict, k: int) -> np.ndarray:
    """Indices of the drops at ``k`` start-grid yaws of an adaptive design spread evenly over its
    period: its ``n0`` start yaws are ``offset_deg + j · period_deg / n0`` and the picks are
    j = 0, n0/k, 2 n0/k, ... (rounded down), the drops a user's budget of k would begin with. A
    one-line FeederError when ``design`` is not an adaptive design's or a start yaw has no drop."""
    try:
        n0, period, offset = int(design["n0"]), float(design["period_deg"]), float(design["offset_deg"])
    except (KeyError, TypeError, ValueError):
        n0 = None
    if n0 is None or initial_deg is None:
        raise FeederError("model.drops reads the adaptive design's start grid and initial yaws: the file has none")
    if int(k) < 1 or int(k) > n0:
        raise FeederError(f"model.drops must be an integer in 1..n0 ({n0}), got {k!r}")
    initial = np.asarray(initial_deg, dtype=np.float64)
    out = []
    for j in np.unique(np.linspace(0, n0, int(k), endpoint=False).astype(int)):
        target = offset + j * period / n0
        gap = np.abs(np.mod(initial - target + 180.0, 360.0) - 180.0)
        if not gap.size or gap.min() >= START_YAW_TOL_DEG:
            raise FeederError(f"the start-grid yaw {target:.6f} deg has no drop")
        out.append(int(np.argmin(gap)))
    return np.asarray(out, dtype=np.int64)


def drops_label(final_deg, period_deg: float, frame_deg: float, bins: int, sigma_bins: float) -> np.ndarray:
    """The label of a few drops' final yaws (part frame; equal weights), in the label frame
    ``frame_deg`` and copied over the ``360 / period_deg`` symmetric turns, smoothed by
    ``sigma_bins`` as the labels are."""
    from feeder.circular import FULL_TURN_DEG, wrapped_gaussian_smooth
    from feeder.mechanics.pmf import bin_masses

    copies = np.arange(int(round(FULL_TURN_DEG / float(period_deg)))) * float(period_deg)
    yaws = np.mod((np.asarray(final_deg, np.float64) + frame_deg)[:, None] + copies[None, :], FULL_TURN_DEG).ravel()
    hist = bin_masses(yaws, np.full(yaws.size, 1.0 / yaws.size), int(bins))
    return wrapped_gaussian_smooth(hist, float(sigma_bins)) if sigma_bins > 0 else hist


def drop_arrays(arrays: dict, sim_dir, k: int, bins: int, sigma_bins: float) -> dict:
    """``arrays`` with, per row, the label of ``k`` start-grid drops of its simulation file
    (:func:`start_grid_drops`, :func:`drops_label`) as ``drop_pmf`` (the row's analytic PMF where
    none of them is ok), their ok share ``drop_ok`` and whether any is ok ``drop_has``."""
    from feeder.sim.record import load_sim

    n = len(arrays["part"])
    pmf, ok, has = np.array(model_analytic(arrays), dtype=np.float64), np.zeros(n), np.zeros(n)
    for i, (part, cid) in enumerate(zip(arrays["part"], arrays["config_id"], strict=True)):
        path = Path(sim_dir) / str(part) / f"{cid}.npz"
        rec = load_sim(path, min_ok_drops=0)
        try:
            pick = start_grid_drops(rec.initial, rec.meta.get("design"), int(k))
        except FeederError as err:
            raise FeederError(f"{path}: {err}") from None
        design = rec.meta["design"]
        good = pick[rec.ok[pick]]
        ok[i] = good.size / pick.size
        if good.size:
            has[i] = 1.0
            pmf[i] = drops_label(rec.yaws[good], design["period_deg"], float(arrays["frame_deg"][i]), bins, sigma_bins)
    return dict(arrays, drop_pmf=pmf, drop_ok=ok, drop_has=has)


def with_drops(arrays: dict, top: int, merge_deg: float, window_deg: float) -> dict:
    """``arrays`` (with :func:`drop_arrays`) whose rows read their own few drops: the drops'
    label as one more diffuse component (after the neighbours', starting as they do), its ok share
    and presence as inputs (:data:`DROP_FEATURES`), and the modes of its ``top`` largest basins as
    candidates with the drops' mass near every candidate as a feature (:func:`neighbour_candidates`)."""
    drop = np.asarray(arrays["drop_pmf"], dtype=np.float64)[:, None, :]
    n = drop.shape[0]
    extra = arrays.get("neighbour_pmf")
    comps = drop if extra is None else np.concatenate([np.asarray(extra, dtype=np.float64), drop], axis=1)
    out = dict(
        arrays,
        x=np.concatenate([arrays["x"], np.column_stack([arrays["drop_ok"], arrays["drop_has"]])], axis=1),
        neighbour_pmf=comps,
    )
    if "neighbour_offset" in arrays:
        out["neighbour_offset"] = np.concatenate([arrays["neighbour_offset"], np.zeros((n, 1))], axis=1)
    present = np.where(np.asarray(arrays["drop_has"]) > 0, np.arange(n), -1)[:, None]  # each row its own drops
    return neighbour_candidates(out, drop, present, int(top), float(merge_deg), float(window_deg))


# ----------------------------------------------------------------------------------------------
# A two-fence configuration composed from the part's own one-fence maps (known parts)
# ----------------------------------------------------------------------------------------------
# appended to x by with_composed: present (0/1); the upstream and downstream maps' angle distances
# over 90° (FAR_DEG when missing); closeness exp(−(both distances) / near_deg); the composed ok share
COMPOSED_FEATURES = ("has", "up_distance", "down_distance", "closeness", "ok")
COMPOSE_YAWS = 36_000  # initial yaws on an even grid (0.01° apart) pushed through both maps


def compose_maps(upstream, downstream, frame_deg: float, bins: int, sigma_bins: float, yaws: int = COMPOSE_YAWS):
    """The label of a part that meets the upstream fence's drop map and then, at rest on the belt
    and carried without turning, the downstream fence's (two sampled maps,
    :class:`feeder.sim.adaptive.Design`, final yaws in the part frame, as
    :func:`feeder.sim.pushforward.map_yaws` interpolates them): the even grid of ``yaws`` initial
    yaws pushed through both, binned in the label frame ``frame_deg`` and smoothed by
    ``sigma_bins`` as labels are. Returns (PMF, or None when no yaw ends ok; the ok share)."""
    from feeder.circular import FULL_TURN_DEG, normalize_yaw, wrapped_gaussian_smooth
    from feeder.labels.metrics import histogram
    from feeder.sim.pushforward import map_yaws

    if int(yaws) < 1:
        raise FeederError(f"compose_maps: yaws must be >= 1, got {yaws!r}")
    beta = (np.arange(int(yaws)) + 0.5) * (FULL_TURN_DEG / int(yaws))
    mid, _ = map_yaws(upstream, beta)
    final, _ = map_yaws(downstream, mid[np.isfinite(mid)])
    final = final[np.isfinite(final)]
    share = final.size / int(yaws)
    if not final.size:
        return None, share
    hist = histogram(normalize_yaw(final + float(frame_deg)), int(bins))
    return (wrapped_gaussian_smooth(hist, float(sigma_bins)) if sigma_bins > 0 else hist / hist.sum()), share


def fence_alone(config_id: str) -> tuple[int, str] | None:
    """(location, type) of a configuration's only fence, or None when it has two or none."""
    (t1, t2), _ = fence_key(config_id)
    if (t1 == "none") == (t2 == "none"):
        return None
    return (2, t2) if t1 == "none" else (1, t1)


def one_fence_rows(parts, config_ids, pool, rows) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For each of ``rows`` with two fences: the row of ``pool`` (a boolean mask) of the same part
    with the upstream (Location 2) fence alone, of its type and nearest in angle, and the one with
    the downstream (Location 1) fence alone, likewise; ties to the lower index. Returns (upstream
    indices, −1 where none or the row has fewer than two fences; their angle distances (inf);
    downstream indices; distances)."""
    parts = np.asarray(parts).astype(str)
    keys = [fence_key(c) for c in config_ids]
    alone: dict[tuple, list[int]] = {}  # (part, location, type) -> rows with that fence alone
    for j in np.flatnonzero(np.asarray(pool, dtype=bool)):
        only = fence_alone(config_ids[j])
        if only is not None:
            alone.setdefault((parts[j], *only), []).append(int(j))
    rows = np.asarray(rows, dtype=np.int64)
    out = [np.full(rows.size, -1, dtype=np.int64) if k % 2 == 0 else np.full(rows.size, np.inf) for k in range(4)]
    for n, i in enumerate(rows):
        (t1, t2), (a1, a2) = keys[i]
        if t1 == "none" or t2 == "none":
            continue
        for slot, (loc, kind, angle) in enumerate(((2, t2, a2), (1, t1, a1))):
            group = alone.get((parts[i], loc, kind), [])
            if group:
                d = np.abs(np.array([keys[j][1][loc - 1] for j in group]) - angle)
                best = int(np.argmin(d))  # the first of equal distances: the lower index
                out[2 * slot][n], out[2 * slot + 1][n] = group[best], d[best]
    return out[0], out[1], out[2], out[3]


def one_fence_maps(arrays: dict, sim_dir, sigma_bins: float) -> dict:
    """The ``composed_maps`` entry that :func:`with_composed` reads: ``maps``, the sampled drop maps
    (:func:`feeder.labels.pmf.record_design`, part frame) of every kept one-fence row by row index;
    ``sigma_bins``, the labels' smoothing; ``memo``, the compositions made so far. A missing or
    broken file is a one-line FeederError naming it."""
    from feeder.labels.pmf import record_design
    from feeder.sim.record import BadData, load_sim

    maps = {}
    for i, (part, cid) in enumerate(zip(arrays["part"], arrays["config_id"], strict=True)):
        if not arrays["kept"][i] or fence_alone(cid) is None:
            continue
        path = Path(sim_dir) / str(part) / f"{cid}.npz"
        try:
            maps[i] = record_design(load_sim(path, min_ok_drops=0))
        except BadData as err:
            raise FeederError(f"{path}: {err}") from None
    return {"maps": maps, "sigma_bins": float(sigma_bins), "memo": {}}


def composed_block(arrays: dict, pool, near_deg: float, rows=None) -> tuple[np.ndarray, np.ndarray]:
    """Every row's composition of its part's one-fence maps in ``pool`` (kept rows,
    :func:`one_fence_rows`, :func:`compose_maps`) as an input of the structured predictor:
    (features (N, 5) of :data:`COMPOSED_FEATURES`, PMFs (N, 1, bins)). A row with fewer than two
    fences, or without both maps, or whose composition ends no yaw ok, gets its analytic PMF (the
    component then changes nothing) and its analytic ok mass. ``arrays["composed_maps"]``
    (:func:`one_fence_maps`) holds the maps; compositions are memoised there per (upstream row,
    downstream row, frame); a pool row without a map there is left out. ``rows``: compose for these
    rows only (default: every row); the others get the analytic PMF as if they had no maps."""
    entry = arrays["composed_maps"]
    maps, memo, sigma_bins = entry["maps"], entry["memo"], entry["sigma_bins"]
    n = len(arrays["part"])
    mapped = np.isin(np.arange(n), list(maps))  # a row without a map is no one-fence row to compose
    pool = np.asarray(pool, dtype=bool) & np.asarray(arrays["kept"], dtype=bool) & mapped
    asked = np.zeros(n, dtype=bool)
    asked[np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64)] = True
    up, d_up, down, d_down = one_fence_rows(arrays["part"], arrays["config_id"], pool, np.arange(n))
    analytic = np.asarray(model_analytic(arrays), np.float64)
    pmfs = analytic[:, None, :].copy()
    ok = np.asarray(arrays["analytic_ok"], np.float64).copy()
    has = np.zeros(n)
    for i in np.flatnonzero((up >= 0) & (down >= 0) & asked):
        key = (int(up[i]), int(down[i]), float(arrays["frame_deg"][i]))
        if key not in memo:
            memo[key] = compose_maps(maps[key[0]], maps[key[1]], key[2], analytic.shape[1], sigma_bins)
        pmf, share = memo[key]
        if pmf is not None:
            pmfs[i, 0], ok[i], has[i] = pmf, share, 1.0
    du = np.where(has > 0, d_up, FAR_DEG)
    dd = np.where(has > 0, d_down, FAR_DEG)
    close = np.where(has > 0, np.exp(-(du + dd) / float(near_deg)), 0.0)
    return np.column_stack([has, du / RIGHT_ANGLE_DEG, dd / RIGHT_ANGLE_DEG, close, ok]), pmfs


def with_composed(arrays: dict, pool, near_deg: float, start_logit: float = 0.0) -> dict:
    """``arrays`` whose two-fence rows read the composition of their part's one-fence maps in
    ``pool`` (:func:`composed_block`): its PMF as one more diffuse component (after the
    neighbours', its logit offset by ``start_logit`` throughout: 0 starts it as they start) and its
    inputs appended to ``x``."""
    if not near_deg > 0:
        raise FeederError(f"model.neighbour_near_deg must be > 0, got {near_deg}")
    feats, comp = composed_block(arrays, pool, near_deg)
    n = comp.shape[0]
    extra = arrays.get("neighbour_pmf")
    comps = comp if extra is None else np.concatenate([np.asarray(extra, dtype=np.float64), comp], axis=1)
    out = dict(arrays, x=np.concatenate([arrays["x"], feats], axis=1), neighbour_pmf=comps)
    if "neighbour_offset" in arrays or float(start_logit) != 0.0:
        before = arrays.get("neighbour_offset", np.zeros((n, comps.shape[1] - 1)))
        out["neighbour_offset"] = np.concatenate([before, np.full((n, 1), float(start_logit))], axis=1)
    return out
