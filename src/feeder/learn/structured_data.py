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
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

log = logging.getLogger(__name__)

CANDIDATES_VERSION = 1  # bump when the candidate arrays change for the same inputs
RIGHT_ANGLE_DEG = 90.0  # the fence inputs' angle unit


def candidates_key(parts, config_ids, frames, scene: dict, variants, cand_cfg: dict, parts_dir) -> str:
    """sha256 of what the cached candidates depend on: the configurations, their frames, the
    scene, the variants, the candidate settings, the part files' bytes and the versions."""
    from feeder.mechanics.features import PUSH_FEATURES_VERSION

    h = hashlib.sha256()
    h.update(json.dumps([list(map(str, parts)), list(map(str, config_ids)), [float(f) for f in frames]]).encode())
    h.update(json.dumps(scene, sort_keys=True).encode())
    h.update(json.dumps([v.__dict__ for v in variants], sort_keys=True).encode())
    h.update(json.dumps(cand_cfg, sort_keys=True).encode())
    h.update(f"{CANDIDATES_VERSION}:{PUSH_FEATURES_VERSION}".encode())
    for part in sorted(set(map(str, parts))):
        h.update((Path(parts_dir) / f"{part}.stl").read_bytes())
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


def compute_candidates(parts, config_ids, frames, scene, variants, cand_cfg: dict, parts_dir, bins: int, units: str):
    """Per configuration: positions (K_i,), masses (K_i, V), variant ok masses (V,), and the push
    block (P,) and analytic PMF (bins,) of the configuration (label smoothing ``cand_cfg``'s
    ``label_smooth_deg``)."""
    from feeder.lane.fences import parse_config_id
    from feeder.mechanics.candidates import configuration_candidates
    from feeder.mechanics.features import push_block
    from feeder.mechanics.hull import push_geometry
    from feeder.parts.geometry import load_profile

    geoms, memos, out = {}, {}, []
    for part, cid, frame in zip(parts, config_ids, frames, strict=True):
        if part not in geoms:
            path = Path(parts_dir) / f"{part}.stl"
            if not path.is_file():
                raise FeederError(f"part file {path} is missing (the candidates need every part's outline)")
            outline, holes, _ = load_profile(path, units)
            geoms[part], memos[part] = push_geometry(outline, holes), {}
        loc1, loc2 = parse_config_id(cid)
        c = configuration_candidates(
            geoms[part],
            loc1,
            loc2,
            scene,
            variants,
            frame_deg=float(frame),
            bins=bins,
            min_mass=float(cand_cfg["min_mass"]),
            window_deg=float(cand_cfg["window_deg"]),
            merge_deg=float(cand_cfg["merge_deg"]),
            max_candidates=int(cand_cfg["max_candidates"]),
            responses=memos[part],
        )
        push, analytic = push_block(
            geoms[part],
            loc1,
            loc2,
            scene,
            frame_deg=float(frame),
            bins=bins,
            pmf_smooth_deg=float(cand_cfg["label_smooth_deg"]),
            responses=memos[part],
        )
        out.append((c.positions, c.masses, c.ok, push, analytic))
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


def structured_arrays(data: dict, cfg, sim_dir, parts_dir, features_dir, cache_path=None) -> dict:
    """The arrays of the module doc for ``data`` (:func:`feeder.labels.dataset.load_dataset`),
    with the candidate settings ``cfg.candidates`` of ``config/hydra/structured.yaml``."""
    from feeder.labels.dataset import feeder_vector, label_smooth_deg
    from feeder.lane.fences import parse_config_id
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
    splits = [*map(str, data["split"]), *map(str, data["excluded_split"])]
    frames_of = _frames(data, sorted(set(parts)), features_dir)
    frames = [frames_of[p] for p in parts]
    variants = variants_from_config(cfg.candidates.variants)
    cand_cfg = {k: cfg.candidates[k] for k in ("min_mass", "window_deg", "merge_deg", "max_candidates", "present_mass")}
    cand_cfg["label_smooth_deg"] = label_smooth_deg(bins, float(labels["sigma_bins"]))
    key = candidates_key(parts, cids, frames, scene, variants, cand_cfg, parts_dir)
    cands = None
    if cache_path is not None and Path(cache_path).is_file():
        with np.load(cache_path, allow_pickle=False) as z:
            if str(z["key"]) == key:
                k = z["k"]
                cands = [
                    (z["pos"][i, : k[i]], z["masses"][i, : k[i]], z["ok_var"][i], z["push"][i], z["analytic"][i])
                    for i in range(len(parts))
                ]
    if cands is None:
        log.info("computing candidates of %d configurations", len(parts))
        cands = compute_candidates(parts, cids, frames, scene, variants, cand_cfg, parts_dir, bins, units)
        if cache_path is not None:
            from feeder import io

            k_max = max(max(c[0].size for c in cands), 1)
            pos, masses, _ = _pad(cands, k_max, len(variants))
            io.write_npz(
                Path(cache_path),
                key=np.array(key),
                k=np.array([c[0].size for c in cands]),
                pos=pos,
                masses=masses,
                ok_var=np.stack([c[2] for c in cands]),
                push=np.stack([c[3] for c in cands]),
                analytic=np.stack([c[4] for c in cands]),
            )
    k_max = int(cfg.candidates.max_candidates)
    pos, masses, mask = _pad(cands, k_max, len(variants))
    ok_var = np.stack([c[2] for c in cands])
    push = np.stack([c[3] for c in cands])
    if "push_raw" in data and not np.allclose(push[:n_kept], data["push_raw"]):
        raise FeederError("the dataset's push_raw differs from this code's push block: rebuild the dataset")
    fences = np.stack([feeder_vector(*parse_config_id(c)) for c in cids])
    fences[:, [3, 7]] /= RIGHT_ANGLE_DEG
    x = np.concatenate([push, fences, ok_var], axis=1)
    sim_dir = Path(sim_dir)
    ok = np.array(
        [
            _ok_share(sim_dir / p / f"{c}.npz", bins, float(labels["sigma_bins"]))
            for p, c in zip(parts, cids, strict=True)
        ]
    )
    n = len(parts)
    pmf = np.zeros((n, bins))
    pmf[:n_kept] = data["pmf"]
    analytic = np.stack([c[4] for c in cands])
    fold_of = {str(p): int(f) for p, f in zip(data["part"], data["group_fold"], strict=True)}
    n_folds = int(np.max(data["group_fold"])) + 1
    group_fold = np.array([fold_of.get(p, int(hashlib.sha256(p.encode()).hexdigest(), 16) % n_folds) for p in parts])
    return {
        "part": np.array(parts),
        "config_id": np.array(cids),
        "split": np.array(splits),
        "kept": np.arange(n) < n_kept,
        "group_fold": group_fold,
        "ok": ok,
        "x": x,
        "pos": pos,
        "mask": mask,
        "masses": masses,
        "cf": candidate_features(masses, mask, float(cfg.candidates.present_mass)),
        "base_mass": masses[:, :, 0],
        "pmf": pmf,
        "cdf": np.cumsum(pmf, axis=1),
        "analytic": analytic,
        "analytic_ok": ok_var[:, 0],
        "wide_sigma_bins": float(cfg.model.wide_sigma_bins),
    }
