"""Fence configuration grid, datasets and splits, the merged dataset file, scalers, Table 4 and
the convergence study.

Configurations (``configurations(config, part_ids)``, pure and seeded by ids):

* Grid: every location holds ``none``, a straight fence at one of ``fences.straight_angles`` or a
  curved fence at one of ``fences.curved_angles``; a configuration is a (Location 1, Location 2)
  pair whose type combination (``<type1>_<type2>``) is listed in ``fences.combos``. The default
  list leaves out ``none_none``: with no fence the final yaw is the uniform initial yaw, which
  teaches a model nothing about fences.
* Parts dataset: ``datasets.holdout_parts`` (or, when that list is empty, the
  ``datasets.n_holdout`` parts ranked first by sha256(seed:holdout:id)); each gets
  ``datasets.parts_per_part`` configurations drawn from the configurations used in Main
  (unseen parts, known fences).
* Fences dataset: ``datasets.fences_parts`` Main parts (ranked by sha256(seed:fences:id)); each is
  given one reserved type combination from ``fences.reserved_combos`` (round robin). That part's
  Main configurations never use that combination; its Fences configurations all do.
  ``datasets.fences_samples`` configurations are spread over those parts.
* Main: every other part gets ``fences.main_per_part`` configurations, spread evenly over its
  allowed type combinations (remainder to a seeded choice of combinations), angles drawn without
  replacement. ``split`` is ``train``/``test`` by a random row split of the Main rows
  (``datasets.test_fraction``, ``datasets.split_seed``), ``fences`` and ``parts`` otherwise.

Seeds derive from ``fences.seed`` and the part id, so adding a part never changes another part's
configurations.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import logging
import math
import sys
from functools import lru_cache
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io as fio
from feeder.labels import metrics as L
from feeder.errors import FeederError
from feeder.sim.fences import TYPES, Fence, config_id, parse_config_id

log = logging.getLogger("feeder.labels.dataset")

DATASETS = ("main", "fences", "parts")
SPLITS = ("train", "test", "fences", "parts")
N_DFT = 45
N_FEEDER = 8


# ----------------------------------------------------------------------------------------------
# Configuration grid
# ----------------------------------------------------------------------------------------------
def _seed(*tokens) -> int:
    digest = hashlib.sha256(":".join(str(t) for t in tokens).encode()).digest()
    return int.from_bytes(digest[:8], "little")


def _rank(parts, *tokens) -> list[str]:
    return sorted(parts, key=lambda p: (_seed(*tokens, p), p))


def _angles(fences: dict, kind: str) -> list[float]:
    if kind == "none":
        return [0.0]
    values = fences[f"{kind}_angles"]
    return [float(a) for a in values]


def combo_grid(fences: dict, combo: str) -> list[str]:
    """Every configuration id of one type combination ``<type1>_<type2>`` on the angle grid."""
    t1, t2 = _split_combo(combo)
    return list(_grid(t1, tuple(_angles(fences, t1)), t2, tuple(_angles(fences, t2))))


@lru_cache(maxsize=64)
def _grid(t1: str, angles1: tuple, t2: str, angles2: tuple) -> tuple[str, ...]:
    first = [Fence(t1, a) for a in angles1]
    second = [Fence(t2, a) for a in angles2]
    return tuple(config_id(f1, f2) for f1, f2 in itertools.product(first, second))


def _split_combo(combo: str) -> tuple[str, str]:
    t = combo.split("_")
    if len(t) != 2 or t[0] not in TYPES or t[1] not in TYPES:
        raise FeederError(f"fence type combination {combo!r} is not <type>_<type> with types {TYPES}")
    return t[0], t[1]


def _combo_of(cid: str) -> str:
    f1, f2 = parse_config_id(cid)
    return f"{f1.type}_{f2.type}"


def _sample_main(fences: dict, part: str, combos: list[str], n: int) -> list[str]:
    rng = np.random.default_rng(_seed(fences["seed"], "main", part))
    base, rem = divmod(n, len(combos))
    extra = set(rng.permutation(len(combos))[:rem].tolist())
    chosen = []
    for i, combo in enumerate(combos):
        grid = combo_grid(fences, combo)
        k = min(base + (i in extra), len(grid))
        chosen += [grid[j] for j in sorted(rng.choice(len(grid), size=k, replace=False))]
    return chosen


def random_test_rows(n: int, test_fraction: float, seed: int) -> np.ndarray:
    """Row indices of a random test split, identical to sklearn's
    ``train_test_split(range(n), test_size=test_fraction, random_state=seed)`` test part
    (ceil(test_fraction * n) rows from ``RandomState(seed).permutation(n)``), without importing
    sklearn at workflow parse time."""
    n_test = int(math.ceil(test_fraction * n))
    if not 0 < n_test < n:
        raise FeederError(f"datasets.test_fraction={test_fraction} leaves no train or no test row of {n}")
    return np.random.RandomState(seed).permutation(n)[:n_test]


def holdout_parts(config: dict, part_ids) -> list[str]:
    """The Parts-dataset parts: the configured list, or the seeded hash-ranked first n_holdout."""
    ds = config["datasets"]
    parts = sorted(set(part_ids))
    listed = list(ds.get("holdout_parts") or [])
    if listed:
        missing = [p for p in listed if p not in parts]
        if missing:
            raise FeederError(f"datasets.holdout_parts names unknown parts: {', '.join(missing)}")
        return sorted(listed)
    return sorted(_rank(parts, config["fences"]["seed"], "holdout")[: int(ds["n_holdout"])])


def configurations(config: dict, part_ids) -> pd.DataFrame:
    """Every simulated (part, fence configuration) with its dataset and split (see module doc).

    Columns: part, config_id, loc1, loc2 (command-line fence specs), dataset (main/fences/parts),
    split (train/test/fences/parts). Rows are sorted by dataset, part, config_id.
    """
    fences, ds = config["fences"], config["datasets"]
    parts = sorted(set(part_ids))
    combos = list(fences["combos"])
    for c in combos + list(fences["reserved_combos"]):
        _split_combo(c)
    reserved = list(fences["reserved_combos"])
    if not set(reserved) <= set(combos):
        raise FeederError("fences.reserved_combos must be listed in fences.combos")
    held = holdout_parts(config, parts)
    main_parts = [p for p in parts if p not in held]
    if not main_parts:
        raise FeederError("no parts left for the Main dataset after the holdout parts")
    n_fp = int(ds["fences_parts"])
    if n_fp > len(main_parts):
        raise FeederError(f"datasets.fences_parts={n_fp} exceeds the {len(main_parts)} Main parts")
    if n_fp and not reserved:
        raise FeederError("datasets.fences_parts > 0 needs fences.reserved_combos")
    fence_parts = _rank(main_parts, fences["seed"], "fences")[:n_fp]
    reserved_of = {p: reserved[i % len(reserved)] for i, p in enumerate(fence_parts)}

    rows = []
    for p in main_parts:
        allowed = [c for c in combos if c != reserved_of.get(p)]
        rows += [(p, cid, "main") for cid in _sample_main(fences, p, allowed, int(fences["main_per_part"]))]
    known = sorted({cid for _, cid, _ in rows})
    n_fs = int(ds["fences_samples"])
    for i, p in enumerate(fence_parts):
        k = n_fs // n_fp + (i < n_fs % n_fp)
        grid = combo_grid(fences, reserved_of[p])
        rng = np.random.default_rng(_seed(fences["seed"], "fences", p))
        take = sorted(rng.choice(len(grid), size=min(k, len(grid)), replace=False))
        rows += [(p, grid[j], "fences") for j in take]
    for p in held:
        rng = np.random.default_rng(_seed(fences["seed"], "parts", p))
        take = sorted(rng.choice(len(known), size=min(int(ds["parts_per_part"]), len(known)), replace=False))
        rows += [(p, known[j], "parts") for j in take]

    df = pd.DataFrame(rows, columns=["part", "config_id", "dataset"])
    locs = [parse_config_id(c) for c in df["config_id"]]
    df["loc1"] = [a.spec for a, _ in locs]
    df["loc2"] = [b.spec for _, b in locs]
    order = {d: i for i, d in enumerate(DATASETS)}
    df = df.sort_values(["dataset", "part", "config_id"], key=lambda s: s.map(order) if s.name == "dataset" else s)
    df = df.reset_index(drop=True)
    split = df["dataset"].astype(object).copy()
    main_idx = np.flatnonzero(df["dataset"].to_numpy() == "main")
    split.iloc[main_idx] = "train"
    if main_idx.size >= 2:
        split.iloc[main_idx[random_test_rows(main_idx.size, float(ds["test_fraction"]), int(ds["split_seed"]))]] = "test"
    df["split"] = split
    return df[["part", "config_id", "loc1", "loc2", "dataset", "split"]]


# ----------------------------------------------------------------------------------------------
# Reading simulation and feature files
# ----------------------------------------------------------------------------------------------
class BadData(FeederError):
    """A simulation file that cannot be used (missing, truncated, too few ok drops, ...)."""


@dataclass
class SimRecord:
    yaws: np.ndarray  # (drops,) final yaw degrees, NaN where not ok
    ok: np.ndarray  # (drops,) bool
    meta: dict


def load_sim(path, min_ok_drops: int = 1) -> SimRecord:
    """Read and check one ``results/sim/<part>/<config>.npz``; raise :class:`BadData` naming it."""
    path = Path(path)
    if not path.is_file():
        raise BadData(f"simulation file {path} is missing")
    try:
        with np.load(path, allow_pickle=False) as z:
            for key in ("final_yaw_deg", "status"):
                if key not in z.files:
                    raise BadData(f"simulation file {path} lacks {key!r}")
            yaws = np.asarray(z["final_yaw_deg"], dtype=np.float64)
            status = np.asarray(z["status"]).astype(str)
            meta_raw = str(z["meta"]) if "meta" in z.files else "{}"
    except BadData:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError) as err:
        raise BadData(f"simulation file {path} is truncated or unreadable ({type(err).__name__}: {err})") from None
    if yaws.ndim != 1 or status.shape != yaws.shape or yaws.size == 0:
        raise BadData(f"simulation file {path}: final_yaw_deg {yaws.shape} and status {status.shape} must be equal non-empty vectors")
    ok = status == "ok"
    if not np.isfinite(yaws[ok]).all():
        raise BadData(f"simulation file {path}: an ok drop has a non-finite yaw")
    try:
        meta = json.loads(meta_raw)
    except json.JSONDecodeError:
        raise BadData(f"simulation file {path}: meta is not JSON") from None
    n_ok = int(ok.sum())
    if n_ok < min_ok_drops:
        raise BadData(f"simulation file {path} has {n_ok} ok drops of {yaws.size} (< sim.min_ok_drops={min_ok_drops})")
    return SimRecord(yaws=np.where(ok, yaws, np.nan), ok=ok, meta=meta)


def load_features(path) -> np.ndarray:
    """The 45 raw DFT values of a part as triplets k1, |a1|, arg a1, k2, ..."""
    path = Path(path)
    try:
        obj = json.loads(path.read_text())
        k, mag, ph = (np.asarray(obj[key], dtype=np.float64) for key in ("k", "magnitude", "phase"))
    except FileNotFoundError:
        raise FeederError(f"feature file {path} is missing") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
        raise FeederError(f"feature file {path} is not {{k, magnitude, phase}} JSON ({err})") from None
    if not (k.shape == mag.shape == ph.shape == (N_DFT // 3,)) or not np.isfinite(np.r_[k, mag, ph]).all():
        raise FeederError(f"feature file {path} must hold {N_DFT // 3} finite values per key")
    return np.stack([k, mag, ph], axis=1).ravel()


def load_frame_deg(path) -> float:
    """``frame_deg`` of a features JSON: where the part's feature frame lies in its own frame."""
    path = Path(path)
    try:
        value = json.loads(path.read_text()).get("frame_deg")
    except FileNotFoundError:
        raise FeederError(f"feature file {path} is missing") from None
    except (json.JSONDecodeError, AttributeError) as err:
        raise FeederError(f"feature file {path} is not a features JSON ({err})") from None
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FeederError(
            f"feature file {path} has no frame_deg (its face cloud does not lie in the part's x-y plane, "
            "or the file predates it: rerun `feeder features`); labels.frame: principal needs it")
    return float(value)


def check_label_frame(frame: str) -> str:
    if frame not in L.LABEL_FRAMES:
        raise FeederError(f"labels.frame must be one of {', '.join(L.LABEL_FRAMES)}, got {frame!r}")
    return frame


def label_yaws(yaws, frame: str, frame_deg: float) -> np.ndarray:
    """Final yaws (part frame, NaN kept) in the label frame ``part`` or ``principal``."""
    yaws = np.asarray(yaws, dtype=np.float64)
    return yaws if check_label_frame(frame) == "part" else L.normalize_yaw(yaws + frame_deg)


def feeder_vector(loc1: Fence, loc2: Fence) -> np.ndarray:
    """Raw 8-vector: per location one-hot none/straight/curved then the angle in degrees."""
    out = np.zeros(N_FEEDER)
    for j, f in enumerate((loc1, loc2)):
        out[4 * j + TYPES.index(f.type)] = 1.0
        out[4 * j + 3] = f.angle if f.present else 0.0
    return out


# ----------------------------------------------------------------------------------------------
# Scaler
# ----------------------------------------------------------------------------------------------
@dataclass
class Scaler:
    """z-score of the 45 DFT values and min-max of the two fence angles, fit on training rows."""

    mean: np.ndarray  # (45,)
    std: np.ndarray  # (45,), zero SDs replaced by 1
    angle_min: np.ndarray  # (2,)
    angle_max: np.ndarray  # (2,)

    def transform(self, part_raw, feeder_raw) -> np.ndarray:
        part_raw = np.atleast_2d(np.asarray(part_raw, dtype=np.float64))
        feeder_raw = np.atleast_2d(np.asarray(feeder_raw, dtype=np.float64))
        if part_raw.shape[1] != N_DFT or feeder_raw.shape[1] != N_FEEDER or len(part_raw) != len(feeder_raw):
            raise FeederError(f"Scaler.transform needs (N, {N_DFT}) and (N, {N_FEEDER}) arrays")
        z = (part_raw - self.mean) / self.std
        f = feeder_raw.copy()
        for j in range(2):
            col = 4 * j + 3
            present = f[:, 4 * j] == 0  # one-hot 'none' bit off
            span = self.angle_max[j] - self.angle_min[j]
            span = span if span > 0 else 1.0
            f[:, col] = np.where(present, (f[:, col] - self.angle_min[j]) / span, 0.0)
        return np.concatenate([z, f], axis=1)

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("mean", "std", "angle_min", "angle_max")}

    @classmethod
    def from_dict(cls, d: dict) -> "Scaler":
        return cls(**{k: np.asarray(d[k], dtype=np.float64) for k in ("mean", "std", "angle_min", "angle_max")})


def fit_scaler(part_raw, feeder_raw, mask) -> Scaler:
    """Fit on the rows selected by ``mask`` (bool (N,) or indices) only: no other row is read."""
    part_raw = np.asarray(part_raw, dtype=np.float64)
    feeder_raw = np.asarray(feeder_raw, dtype=np.float64)
    p = part_raw[mask]
    f = feeder_raw[mask]
    if p.ndim != 2 or len(p) == 0:
        raise FeederError("fit_scaler: no training rows selected")
    mean = p.mean(axis=0)
    std = p.std(axis=0)
    std = np.where(std > 0, std, 1.0)
    lo, hi = np.zeros(2), np.ones(2)
    for j in range(2):
        a = f[f[:, 4 * j] == 0, 4 * j + 3]
        if a.size:
            lo[j], hi[j] = a.min(), a.max()
    return Scaler(mean=mean, std=std, angle_min=lo, angle_max=hi)


# ----------------------------------------------------------------------------------------------
# Dataset build
# ----------------------------------------------------------------------------------------------
def _progress(iterable, total, desc):
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, disable=not sys.stderr.isatty(), file=sys.stderr)


def build_dataset(configs: pd.DataFrame, features_dir, sim_dir, settings: dict) -> dict:
    """The arrays of ``dataset.npz`` (docs/data.md) for the rows of ``configs``."""
    from sklearn.model_selection import GroupKFold

    bins = int(settings["labels"]["bins"])
    sigma = float(settings["labels"]["sigma_bins"])
    levels = np.asarray(settings["labels"]["levels_pct"], dtype=np.int64)
    on_bad = settings["labels"]["on_bad"]
    frame = check_label_frame(settings["labels"]["frame"])  # before any file is read
    min_ok = int(settings["sim"]["min_ok_drops"])
    n_folds = int(settings["datasets"]["group_folds"])
    features_dir, sim_dir = Path(features_dir), Path(sim_dir)

    feats: dict[str, np.ndarray] = {}
    frames: dict[str, float] = {}  # frame_deg per part (0 in the part frame)
    kept, excluded, recs = [], [], []
    for row in _progress(configs.itertuples(index=False), len(configs), "dataset"):
        path = sim_dir / row.part / f"{row.config_id}.npz"
        try:
            rec = load_sim(path, min_ok)
            meta_part = rec.meta.get("part")
            if meta_part is not None and meta_part != row.part:
                raise BadData(f"simulation file {path} holds part {meta_part!r}, not {row.part!r}")
        except BadData as err:
            if on_bad != "exclude":
                raise
            log.warning("excluded %s/%s: %s", row.part, row.config_id, err)
            excluded.append((row.part, row.config_id, row.dataset, str(err)))
            continue
        if row.part not in feats:
            feats[row.part] = load_features(features_dir / f"{row.part}.json")
            frames[row.part] = load_frame_deg(features_dir / f"{row.part}.json") if frame == "principal" else 0.0
        rec.yaws = label_yaws(rec.yaws, frame, frames[row.part])
        kept.append(row)
        recs.append(rec)
    if not kept:
        raise FeederError("no usable configuration left for the dataset")

    n, n_levels = len(kept), levels.size
    drops = np.array([r.yaws.size for r in recs])
    yaw_mat = np.full((n, drops.max()), np.nan)
    pmf = np.empty((n, bins))
    pmf_levels = np.empty((n, n_levels, bins))
    n_ok_levels = np.empty((n, n_levels), dtype=np.int64)
    feeder_raw = np.empty((n, N_FEEDER))
    for i, (row, rec) in enumerate(zip(kept, recs)):
        yaw_mat[i, : rec.yaws.size] = rec.yaws
        pmf[i] = L.pmf_from_yaws(rec.yaws[rec.ok], bins, sigma)
        pmf_levels[i], n_ok_levels[i] = L.partial_pmfs(rec.yaws, levels, bins, sigma, ok=rec.ok)
        feeder_raw[i] = feeder_vector(*parse_config_id(row.config_id))
    parts = np.array([r.part for r in kept])
    n_parts = len(set(parts))
    if n_parts < n_folds:
        raise FeederError(f"datasets.group_folds={n_folds} needs at least that many parts, have {n_parts}")
    group_fold = np.empty(n, dtype=np.int64)
    for fold, (_, test) in enumerate(GroupKFold(n_splits=n_folds).split(np.zeros(n), groups=parts)):
        group_fold[test] = fold
    ex = np.array(excluded, dtype=str).reshape(-1, 4)
    out = {
        "part": parts,
        "config_id": np.array([r.config_id for r in kept]),
        "dataset": np.array([r.dataset for r in kept]),
        "split": np.array([r.split for r in kept]),
        "group_fold": group_fold,
        "part_raw": np.stack([feats[p] for p in parts]),
        "feeder_raw": feeder_raw,
        "pmf": pmf,
        "cdf": L.cdf(pmf),
        "pmf_levels": pmf_levels,
        "levels_pct": levels,
        "n_ok": np.array([int(r.ok.sum()) for r in recs]),
        "n_ok_levels": n_ok_levels,
        "n_drops": drops,
        "final_yaw_deg": yaw_mat,
        "frame_deg": np.array([frames[p] for p in parts]),
        "label_frame": np.array(frame),
        "excluded_part": ex[:, 0],
        "excluded_config_id": ex[:, 1],
        "excluded_dataset": ex[:, 2],
        "excluded_reason": ex[:, 3],
        "settings": np.array(json.dumps(settings, sort_keys=True)),
    }
    for key, arr in out.items():
        if arr.dtype.kind == "f" and key != "final_yaw_deg" and not np.isfinite(arr).all():
            raise FeederError(f"dataset array {key} has non-finite values")  # never a silent NaN row
    return out


def load_dataset(path) -> dict:
    """All arrays of a dataset.npz as a dict."""
    path = Path(path)
    if not path.is_file():
        raise FeederError(f"dataset file {path} is missing")
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


# ----------------------------------------------------------------------------------------------
# Table 4 and the convergence study
# ----------------------------------------------------------------------------------------------
_TABLE4_ROWS = [
    ("Main (Train)", ("train",), "Model training (includes the validation rows)", "fit"),
    ("Main (Test)", ("test",), "Held-out configurations of known parts (random row split)", "P1"),
    ("Fences", ("fences",), "Type combinations never seen with these parts in training", "P1"),
    ("Parts", ("parts",), "Unseen part geometries with known fences", "P3"),
    ("Total (All)", SPLITS, "All datasets combined", ""),
]
_EXCLUDED_OF = {"train": "main", "test": "main", "fences": "fences", "parts": "parts"}


def table4(ds: dict) -> pd.DataFrame:
    """Samples and unique parts per dataset; ``excluded`` counts bad configurations dropped
    (Main exclusions are counted once, on the Main (Train) row, since the split is per row)."""
    rows = []
    for name, splits, purpose, protocol in _TABLE4_ROWS:
        sel = np.isin(ds["split"], splits)
        if name == "Main (Train)":
            ex = int(np.sum(ds["excluded_dataset"] == "main"))
        elif name == "Main (Test)":
            ex = 0
        elif name == "Total (All)":
            ex = int(ds["excluded_dataset"].size)
        else:
            ex = int(np.sum(ds["excluded_dataset"] == _EXCLUDED_OF[splits[0]]))
        rows.append({
            "dataset": name,
            "samples": int(sel.sum()),
            "unique_parts": int(np.unique(ds["part"][sel]).size),
            "purpose": purpose,
            "protocol": protocol,
            "excluded": ex,
        })
    return pd.DataFrame(rows)


def _markdown(df: pd.DataFrame) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(str(v) for v in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def js_by_level(ds: dict) -> np.ndarray:
    """(N, L) JS divergence in bits between each partial-level PMF and the full-run PMF."""
    return L.js_divergence(ds["pmf_levels"], ds["pmf"][:, None, :])


def bootstrap_js_floor(ds: dict, level_index: int, n_boot: int, quantile: float, seed: int, bins: int, sigma: float):
    """Noise floor of JS at one level: for every configuration draw ``n_boot`` resamples (with
    replacement) of its full-run ok yaws of the size of its ok drops at that level, smooth them
    the same way and take JS to the full PMF. Returns (floor = pooled quantile, all values)."""
    n_ok_lvl = ds["n_ok_levels"][:, level_index]
    vals = []
    for i in range(len(ds["part"])):
        yaws = ds["final_yaw_deg"][i]
        hist = L.histogram(yaws[np.isfinite(yaws)], bins)
        n = int(n_ok_lvl[i])
        if n == 0:
            continue
        rng = np.random.default_rng(_seed(seed, "bootstrap", ds["part"][i], ds["config_id"][i], level_index))
        draws = rng.multinomial(n, hist / hist.sum(), size=n_boot).astype(np.float64)
        boot = L.wrapped_gaussian_smooth(draws, sigma)
        vals.append(L.js_divergence(boot, ds["pmf"][i]))
    vals = np.concatenate(vals) if vals else np.zeros(0)
    floor = float(np.quantile(vals, quantile)) if vals.size else float("nan")
    return floor, vals


def js_table(ds: dict, conv: dict, bins: int, sigma: float) -> pd.DataFrame:
    """Per partial level: JS to the full run (median, mean, SD), counts below the absolute
    threshold and below the bootstrap noise floor of that level."""
    js = js_by_level(ds)
    levels = ds["levels_pct"]
    drops = int(np.max(ds["n_drops"]))
    rows = []
    for li, k in enumerate(levels):
        floor, _ = bootstrap_js_floor(ds, li, int(conv["bootstrap"]), float(conv["noise_quantile"]), int(conv["seed"]), bins, sigma)
        col = js[:, li]
        rows.append({
            "level_pct": int(k),
            "n_drops": int(drops * k // 100),
            "configurations": int(col.size),
            "median_js": float(np.median(col)),
            "mean_js": float(col.mean()),
            "sd_js": float(col.std()),
            "below_abs_threshold": int(np.sum(col < float(conv["js_threshold"]))),
            "noise_floor": floor,
            "below_noise_floor": int(np.sum(col < floor)),
        })
    return pd.DataFrame(rows)


def dkw_table(ds: dict, alpha: float) -> tuple[pd.DataFrame, np.ndarray]:
    """sup|CDF_N − CDF_full| (exact empirical CDFs, no binning) for every configuration and
    partial level, against the DKW half-width ε(n) = sqrt(ln(2/α) / 2n) with n the ok drops of
    the partial run. The partial run is a prefix of the full run, so for exchangeable drops the
    distance is at most the distance to the true CDF and ≥ 1 − α of configurations should lie
    inside the band; fewer means the drop sequence is not yet representative at that N."""
    levels = ds["levels_pct"]
    n_rows = len(ds["part"])
    sup = np.full((n_rows, levels.size), np.nan)
    for i in range(n_rows):
        y = ds["final_yaw_deg"][i, : int(ds["n_drops"][i])]
        full = y[np.isfinite(y)]
        counts = L.level_drop_counts(y.size, levels)
        for li, c in enumerate(counts):
            part = y[:c]
            part = part[np.isfinite(part)]
            if part.size:
                sup[i, li] = L.ecdf_sup_distance(part, full)
    n_ok = ds["n_ok_levels"]
    eps = L.dkw_epsilon(np.maximum(n_ok, 1), alpha)
    inside = np.where(np.isfinite(sup), sup <= eps, False)
    drops = int(np.max(ds["n_drops"]))
    rows = []
    for li, k in enumerate(levels):
        s = sup[:, li]
        s = s[np.isfinite(s)]
        rows.append({
            "level_pct": int(k),
            "n_drops": int(drops * k // 100),
            "configurations": int(s.size),
            "median_n_ok": float(np.median(n_ok[:, li])),
            "dkw_epsilon_at_n_drops": float(L.dkw_epsilon(max(drops * k // 100, 1), alpha)),
            "median_sup": float(np.median(s)) if s.size else float("nan"),
            "q90_sup": float(np.quantile(s, 0.9)) if s.size else float("nan"),
            "fraction_inside_band": float(inside[:, li].mean()),
        })
    return pd.DataFrame(rows), sup


def pick_examples(pmf: np.ndarray, prominence_frac: float) -> list[tuple[int, str]]:
    """Rows whose PMFs show different shapes: the median-entropy row with one, two and three or
    more peaks (peaks with prominence ≥ prominence_frac · max, found on the circle), plus the
    most concentrated and the most spread-out PMF."""
    from scipy.signal import find_peaks

    ent = -(np.where(pmf > 0, pmf * np.log2(np.where(pmf > 0, pmf, 1)), 0)).sum(axis=1)
    n_peaks = np.empty(len(pmf), dtype=np.int64)
    bins = pmf.shape[1]
    for i, p in enumerate(pmf):
        tripled = np.concatenate([p, p, p])
        pk, _ = find_peaks(tripled, prominence=prominence_frac * p.max())
        n_peaks[i] = int(np.sum((pk >= bins) & (pk < 2 * bins)))
    picks: list[tuple[int, str]] = []
    for label, sel in (("1 peak", n_peaks == 1), ("2 peaks", n_peaks == 2), ("3+ peaks", n_peaks >= 3)):
        idx = np.flatnonzero(sel)
        if idx.size:
            picks.append((int(idx[np.argsort(ent[idx])[idx.size // 2]]), label))
    for i, label in ((int(np.argmin(ent)), "most concentrated"), (int(np.argmax(ent)), "most spread")):
        if i not in [j for j, _ in picks]:
            picks.append((i, label))
    return picks


def convergence_data(ds: dict, settings: dict) -> dict:
    """Everything the convergence study shows: the two tables (``dkw_table``, ``js_table``) and the
    data of Figs. 4, 5, 9 and the DKW view (``fig4``, ``fig5``, ``fig9``, ``dkw``: the formats the
    modules of the same names in :mod:`feeder.figures` read; all drawing is there)."""
    conv = settings["datasets"]["convergence"]
    bins = int(settings["labels"]["bins"])
    sigma = float(settings["labels"]["sigma_bins"])
    levels = ds["levels_pct"]
    drops = int(np.max(ds["n_drops"]))
    n_axis = drops * levels // 100
    js = js_by_level(ds)

    # Fig. 4: JS(P_N || P_full) vs N, mean ± SD over random configurations
    rng = np.random.default_rng(_seed(conv["seed"], "fig4"))
    pick = rng.choice(len(js), size=min(int(conv["fig4_configurations"]), len(js)), replace=False)
    sub = js[np.sort(pick)]
    fig4 = pd.DataFrame({"level_pct": levels.astype(np.int64), "n_drops": n_axis.astype(np.int64),
                         "mean_js": sub.mean(axis=0), "sd_js": sub.std(axis=0), "configurations": len(pick)})

    # Fig. 5: JS at the comparison level with the bootstrap noise floor
    li = int(np.argmin(np.abs(levels - int(conv["compare_pct"]))))
    jst = js_table(ds, conv, bins, sigma)
    fig5 = {"js": js[:, li], "noise_floor": np.float64(jst["noise_floor"].iloc[li]),
            "noise_quantile": np.float64(conv["noise_quantile"]), "n_drops": np.int64(n_axis[li]),
            "n_drops_full": np.int64(drops)}

    # Fig. 9: example PMFs of different shapes
    picks = pick_examples(ds["pmf"], float(conv["peak_prominence"]))
    rows = [i for i, _ in picks]
    fig9 = {"part": np.asarray(ds["part"])[rows].astype(str), "config_id": np.asarray(ds["config_id"])[rows].astype(str),
            "label": np.array([label for _, label in picks]), "pmf": ds["pmf"][rows],
            "yaw_deg": (np.arange(bins) + 0.5) * 360.0 / bins}

    # DKW convergence view: quantiles over configurations of the sup distance per level
    alpha = float(conv["dkw_alpha"])
    table, sup = dkw_table(ds, alpha)
    ok = np.isfinite(sup)

    def per_level(q):
        return np.array([np.quantile(sup[ok[:, j], j], q) if ok[:, j].any() else np.nan for j in range(levels.size)])

    dkw = {"level_pct": levels.astype(np.int64), "n_drops": n_axis.astype(np.int64), "q10_sup": per_level(0.1),
           "median_sup": per_level(0.5), "q90_sup": per_level(0.9),
           "dkw_epsilon": L.dkw_epsilon(np.maximum(n_axis, 1), alpha),
           "fraction_inside_band": table["fraction_inside_band"].to_numpy(),
           "alpha": np.float64(alpha), "n_drops_full": np.int64(drops)}
    return {"dkw_table": table, "js_table": jst, "fig4": fig4, "fig5": fig5, "fig9": fig9, "dkw": dkw}


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def _read_configs(path) -> pd.DataFrame:
    path = Path(path)
    if not path.is_file():
        raise FeederError(f"configuration table {path} is missing")
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    need = {"part", "config_id", "dataset", "split"}
    if not need <= set(df.columns):
        raise FeederError(f"configuration table {path} lacks columns {sorted(need - set(df.columns))}")
    return df


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder datasets", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("configurations", help="write the part x fence configuration table")
    p.add_argument("--settings", required=True, help="JSON with the fences and datasets config sections")
    p.add_argument("--parts", required=True, help="comma-separated part ids")
    p.add_argument("--out", required=True, type=Path)
    p = sub.add_parser("build", help="merge simulation and feature files into dataset.npz")
    p.add_argument("--configurations", required=True, type=Path)
    p.add_argument("--features-dir", required=True, type=Path)
    p.add_argument("--sim-dir", required=True, type=Path)
    p.add_argument("--settings", required=True, help="JSON with the sim, labels and datasets sections")
    p.add_argument("--out", required=True, type=Path)
    p = sub.add_parser("table4", help="Table 4 (dataset summary) as CSV and Markdown")
    p.add_argument("--dataset", required=True, type=Path)
    p.add_argument("--out-csv", required=True, type=Path)
    p.add_argument("--out-md", required=True, type=Path)
    p = sub.add_parser("convergence", help="convergence tables and the data of Figs. 4, 5, 9 and the DKW view")
    p.add_argument("--dataset", required=True, type=Path)
    p.add_argument("--settings", required=True, help="JSON with the labels and datasets sections")
    for name in ("dkw-csv", "js-csv", "fig4-data", "fig5-data", "fig9-data", "dkw-data"):
        p.add_argument(f"--{name}", required=True, type=Path)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)

    if args.cmd == "configurations":
        settings = fio.parse_settings(args.settings, "fences", "datasets")
        parts = [p for p in args.parts.split(",") if p]
        df = configurations(settings, parts)
        fio.write_csv(args.out, df)
        print(df.groupby("split").size().to_string(), file=sys.stderr)
    elif args.cmd == "build":
        settings = fio.parse_settings(args.settings, "sim", "labels", "datasets")
        ds = build_dataset(_read_configs(args.configurations), args.features_dir, args.sim_dir, settings)
        fio.write_npz(args.out, **ds)
        log.info("%d configurations, %d excluded -> %s", len(ds["part"]), ds["excluded_part"].size, args.out)
    elif args.cmd == "table4":
        t = table4(load_dataset(args.dataset))
        fio.write_csv(args.out_csv, t)
        fio.write_text(args.out_md, "Table 4. Dataset summary\n\n" + _markdown(t))
    elif args.cmd == "convergence":
        settings = fio.parse_settings(args.settings, "labels", "datasets")
        out = convergence_data(load_dataset(args.dataset), settings)
        fio.write_csv(args.fig4_data, out["fig4"])
        fio.write_npz(args.fig5_data, **out["fig5"])
        fio.write_npz(args.fig9_data, **out["fig9"])
        fio.write_npz(args.dkw_data, **out["dkw"])
        fio.write_csv(args.dkw_csv, out["dkw_table"])
        fio.write_csv(args.js_csv, out["js_table"])
    return 0
