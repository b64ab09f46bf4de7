"""The merged dataset: part features and fence vectors, labels from the simulation files, the
input scaler, ``dataset.npz`` (docs/data.md) and Table 4; and the ``feeder datasets`` command.

* :func:`build_dataset` merges the simulation file of every row of the configuration table
  (:func:`feeder.labels.grid.configurations`) with its part's DFT features into the arrays of
  ``dataset.npz``: labels (PMF, CDF, partial-level PMFs) in the label frame, the raw 45 + 8
  inputs, the leave-parts-out fold of every row and the excluded configurations. Given the part
  files (``--parts-dir``, default ``parts.dir`` of the settings), also the analytic push block of
  every row (:func:`push_arrays`): ``push_raw`` (the :data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`
  features, named in ``push_feature_names``) and ``pmf_analytic`` (the analytic PMF, in the label
  frame and with the labels' smoothing). Datasets without them still load; models that need
  them say so (:func:`raw_inputs`).
* :func:`load_dataset` reads ``dataset.npz`` back, checked: the one reader every stage uses.
* :class:`Scaler` / :func:`fit_scaler`: the model-input scaler, fit on training rows only.
* Model inputs (``model.inputs`` of the Hydra model configs, :data:`INPUTS`): ``paper``, the
  paper's 53 (:data:`INPUT_NAMES`), ``paper+push``, those and the push block, or ``fence+push``,
  the 8 fence inputs and the push block without the DFT (:func:`input_names`,
  :func:`features_version`).

``feeder datasets configurations|build|table4|convergence`` (``feeder datasets <cmd> -h``); the
grid and splits are in :mod:`feeder.labels.grid`, the convergence study in
:mod:`feeder.labels.convergence`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io as fio
from feeder.config import parse_settings
from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.labels.convergence import convergence_data
from feeder.labels.grid import SPLITS, WIDE, configurations
from feeder.labels.pmf import check_ok_mass, level_drops, sim_label
from feeder.lane.fences import TYPES, Fence, parse_config_id
from feeder.mechanics.features import PUSH_FEATURE_NAMES, PUSH_FEATURES_VERSION
from feeder.parts.features import DFT, DFT_FEATURE_NAMES, FEATURES_VERSION, load_frame_deg
from feeder.sim.record import BadData, SimRecord, load_sim

log = logging.getLogger("feeder.labels.dataset")

N_DFT = 45
N_FEEDER = 8
# what every learner reads from dataset.npz, and the partial-level labels the VAE and delta use
DATASET_KEYS = ("part", "config_id", "split", "group_fold", "part_raw", "feeder_raw", "pmf", "cdf")
LEVEL_KEYS = ("pmf_levels", "levels_pct")
# the analytic push block (build_dataset with the part files): features, their names, the PMF
PUSH_KEYS = ("push_raw", "push_feature_names", "pmf_analytic")
# the 8 feeder inputs in the order of :func:`feeder_vector`: per location the one-hot fence type,
# then the angle
FEEDER_FEATURE_NAMES = tuple(
    name for loc in (1, 2) for name in (*(f"loc{loc}_{t}" for t in TYPES), f"loc{loc}_angle_deg")
)
INPUT_NAMES = DFT_FEATURE_NAMES + FEEDER_FEATURE_NAMES  # the 53 raw model inputs, in order
FEATURES_DIGEST_CHARS = 12  # hex digits of the sha256 kept in features_version()
PAPER_INPUTS = "paper"  # model.inputs: the paper's 53 inputs
PUSH_INPUTS = "paper+push"  # model.inputs: the 53 and the analytic push block
FENCE_PUSH_INPUTS = "fence+push"  # model.inputs: the 8 fence inputs and the push block, no DFT
INPUTS = (PAPER_INPUTS, PUSH_INPUTS, FENCE_PUSH_INPUTS)
PUSH_INPUT_PREFIX = "push_"  # the push block's input names: push_<PUSH_FEATURE_NAMES entry>


def check_inputs(inputs: str) -> str:
    """``inputs`` itself when it is one of :data:`INPUTS`, else a one-line FeederError."""
    if inputs not in INPUTS:
        raise FeederError(f"model.inputs must be one of {', '.join(INPUTS)}, got {inputs!r}")
    return inputs


def uses_dft(inputs: str) -> bool:
    """Whether the model inputs ``inputs`` include the part's 45 DFT values (all but ``fence+push``)."""
    return check_inputs(inputs) != FENCE_PUSH_INPUTS


def uses_push(inputs: str) -> bool:
    """Whether the model inputs ``inputs`` include the analytic push block (all but ``paper``)."""
    return check_inputs(inputs) != PAPER_INPUTS


def input_names(inputs: str = PAPER_INPUTS) -> tuple[str, ...]:
    """The raw model inputs of ``model.inputs`` in network order: :data:`INPUT_NAMES` (without the
    DFT values for ``fence+push``), then, but for ``paper``, the push block (``push_`` +
    :data:`feeder.mechanics.features.PUSH_FEATURE_NAMES`)."""
    names = INPUT_NAMES if uses_dft(inputs) else FEEDER_FEATURE_NAMES
    if not uses_push(inputs):
        return names
    return names + tuple(PUSH_INPUT_PREFIX + name for name in PUSH_FEATURE_NAMES)


def features_version(inputs: str = PAPER_INPUTS) -> str:
    """The version of the model inputs this code computes, ``"<FEATURES_VERSION>-<digest>"``:
    the hand-bumped :data:`feeder.parts.features.FEATURES_VERSION` and a short sha256 of it, the
    ordered :data:`INPUT_NAMES` and the DFT settings (:data:`feeder.parts.features.DFT`); for
    inputs with the push block also its names, its hand-bumped
    :data:`feeder.mechanics.features.PUSH_FEATURES_VERSION` and settings, and for ``fence+push`` that the
    DFT values are left out (the ``paper`` version is the one the paper's models always had). A
    model card records it; a model whose inputs were computed otherwise gets a different one."""
    import dataclasses
    import hashlib

    from feeder.mechanics.distribution import YAW_SAMPLES
    from feeder.mechanics.features import FOURIER_K
    from feeder.mechanics.pmf import DEFAULT_SMOOTH_DEG

    if len(INPUT_NAMES) != N_DFT + N_FEEDER:
        raise FeederError(f"INPUT_NAMES lists {len(INPUT_NAMES)} inputs, the models take {N_DFT + N_FEEDER}")
    content: dict = {"version": FEATURES_VERSION, "inputs": list(INPUT_NAMES), "dft": dataclasses.asdict(DFT)}
    if not uses_dft(inputs):
        content["dft_inputs"] = False
    if uses_push(inputs):
        content["push"] = {
            "version": PUSH_FEATURES_VERSION,
            "names": list(PUSH_FEATURE_NAMES),
            "smooth_deg": DEFAULT_SMOOTH_DEG,
            "fourier_k": FOURIER_K,
            "yaw_samples": YAW_SAMPLES,
        }
    blob = json.dumps(content, sort_keys=True)
    return f"{FEATURES_VERSION}-{hashlib.sha256(blob.encode()).hexdigest()[:FEATURES_DIGEST_CHARS]}"


# ----------------------------------------------------------------------------------------------
# Reading simulation and feature files
# ----------------------------------------------------------------------------------------------
def load_features(path) -> np.ndarray:
    """The 45 raw DFT values of a part as triplets k1, |a1|, arg a1, k2, ..."""
    path = Path(path)
    try:
        obj = json.loads(path.read_text())
        k, mag, ph = (np.asarray(obj[key], dtype=np.float64) for key in ("k", "magnitude", "phase"))
    except FileNotFoundError:
        raise FeederError(f"feature file {path} is missing") from None
    except OSError as err:
        raise FeederError(f"feature file {path}: cannot read ({err.strerror})") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
        raise FeederError(f"feature file {path} is not {{k, magnitude, phase}} JSON ({err})") from None
    if not (k.shape == mag.shape == ph.shape == (N_DFT // 3,)) or not np.isfinite(np.r_[k, mag, ph]).all():
        raise FeederError(f"feature file {path} must hold {N_DFT // 3} finite values per key")
    return np.stack([k, mag, ph], axis=1).ravel()


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
_SCALER_KEYS = ("mean", "std", "angle_min", "angle_max")
_PUSH_SCALER_KEYS = ("push_mean", "push_std")


@dataclass
class Scaler:
    """z-score of the 45 DFT values and min-max of the two fence angles, fit on training rows;
    for ``paper+push`` and ``fence+push`` models also the z-score of the push block
    (``push_mean``/``push_std``, None for the paper's inputs). ``dft`` False (``fence+push``):
    the DFT values are left out of the scaled inputs."""

    mean: np.ndarray  # (45,)
    std: np.ndarray  # (45,), zero SDs replaced by 1
    angle_min: np.ndarray  # (2,)
    angle_max: np.ndarray  # (2,)
    push_mean: np.ndarray | None = None  # (P,)
    push_std: np.ndarray | None = None  # (P,), zero SDs replaced by 1
    dft: bool = True  # whether the scaled inputs hold the DFT values

    def __post_init__(self) -> None:
        if not self.dft and self.push_mean is None:
            raise FeederError("a scaler without the DFT values needs the push block (model.inputs: fence+push)")

    @property
    def inputs(self) -> str:
        """The model inputs the scaler was fit on (:data:`INPUTS`)."""
        if self.push_mean is None:
            return PAPER_INPUTS
        return PUSH_INPUTS if self.dft else FENCE_PUSH_INPUTS

    def transform(self, part_raw, feeder_raw, push_raw=None) -> np.ndarray:
        """The scaled model inputs: 53 columns (the 8 fence columns without the DFT), then the
        push block's for a push scaler (which needs ``push_raw``; a paper scaler ignores it)."""
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
        if self.push_mean is None:
            return np.concatenate([z, f], axis=1)
        if push_raw is None:
            raise FeederError(f"this model takes the analytic push features (model.inputs: {self.inputs}): none given")
        push_raw = np.atleast_2d(np.asarray(push_raw, dtype=np.float64))
        if push_raw.shape != (len(part_raw), self.push_mean.size):
            raise FeederError(
                f"Scaler.transform needs ({len(part_raw)}, {self.push_mean.size}) push features, got {push_raw.shape}"
            )
        blocks = [z, f] if self.dft else [f]
        return np.concatenate([*blocks, (push_raw - self.push_mean) / self.push_std], axis=1)

    def to_dict(self) -> dict:
        keys = _SCALER_KEYS if self.push_mean is None else _SCALER_KEYS + _PUSH_SCALER_KEYS
        out: dict = {k: getattr(self, k).tolist() for k in keys}
        if not self.dft:
            out["dft"] = False  # written only when off: the paper's scalers stay as they were
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Scaler:
        keys = _SCALER_KEYS + tuple(k for k in _PUSH_SCALER_KEYS if d.get(k) is not None)
        return cls(**{k: np.asarray(d[k], dtype=np.float64) for k in keys}, dft=bool(d.get("dft", True)))


def _zscore(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column means and SDs (ddof = 0), zero SDs replaced by 1."""
    std = x.std(axis=0)
    return x.mean(axis=0), np.where(std > 0, std, 1.0)


def fit_scaler(part_raw, feeder_raw, mask, push_raw=None, dft: bool = True) -> Scaler:
    """Fit on the rows selected by ``mask`` (bool (N,) or indices) only: no other row is read.
    With ``push_raw`` ((N, P) push features) the scaler also z-scores the push block; ``dft``
    False leaves the DFT values out of its scaled inputs (``fence+push``)."""
    part_raw = np.asarray(part_raw, dtype=np.float64)
    feeder_raw = np.asarray(feeder_raw, dtype=np.float64)
    p = part_raw[mask]
    f = feeder_raw[mask]
    if p.ndim != 2 or len(p) == 0:
        raise FeederError("fit_scaler: no training rows selected")
    mean, std = _zscore(p)
    lo, hi = np.zeros(2), np.ones(2)
    for j in range(2):
        a = f[f[:, 4 * j] == 0, 4 * j + 3]
        if a.size:
            lo[j], hi[j] = a.min(), a.max()
    push_mean = push_std = None
    if push_raw is not None:
        push_mean, push_std = _zscore(np.asarray(push_raw, dtype=np.float64)[mask])
    return Scaler(mean=mean, std=std, angle_min=lo, angle_max=hi, push_mean=push_mean, push_std=push_std, dft=dft)


def raw_inputs(data: dict[str, np.ndarray], inputs: str = PAPER_INPUTS, rows=None) -> tuple[np.ndarray, ...]:
    """The raw arrays a model of ``inputs`` reads from a dataset (of ``rows``, default all):
    ``(part_raw, feeder_raw)``, and ``push_raw`` but for ``paper``. A dataset without the push
    block, or with one of other features than this code computes, is a one-line FeederError."""
    arrays = [data["part_raw"], data["feeder_raw"]]
    if uses_push(inputs):
        if "push_raw" not in data:
            raise FeederError(
                f"model.inputs: {inputs} needs the dataset's analytic push features (push_raw), which this "
                "dataset.npz lacks: rebuild it with `feeder datasets build --parts-dir DIR`"
            )
        names = tuple(str(n) for n in np.asarray(data.get("push_feature_names", PUSH_FEATURE_NAMES)).ravel())
        if names != PUSH_FEATURE_NAMES:
            raise FeederError(
                "the dataset's push features (push_feature_names) are not the ones this code computes: rebuild it"
            )
        arrays.append(data["push_raw"])
    if rows is None:
        return tuple(arrays)
    return tuple(a[rows] for a in arrays)


# ----------------------------------------------------------------------------------------------
# Dataset build
# ----------------------------------------------------------------------------------------------
def _progress(iterable, total, desc):
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, disable=not sys.stderr.isatty(), file=sys.stderr)


def _row_sim(sim_dir: Path, row) -> SimRecord:
    """The checked simulation record of one configuration-table row."""
    path = sim_dir / row.part / f"{row.config_id}.npz"
    rec = load_sim(path)
    meta_part = rec.meta.get("part")
    if meta_part is not None and meta_part != row.part:
        raise BadData(f"simulation file {path} holds part {meta_part!r}, not {row.part!r}")
    return rec


@dataclass
class _Rows:
    """The usable rows of a configuration table with their records (yaws in the label frame),
    the features of their parts and the excluded rows (part, config_id, dataset, reason, split)."""

    kept: list
    recs: list[SimRecord]
    excluded: list[tuple[str, str, str, str, str]]
    feats: dict[str, np.ndarray]  # raw DFT values per part
    frames: dict[str, float]  # frame_deg per part (0 in the part frame)


def _read_rows(configs: pd.DataFrame, features_dir: Path, sim_dir: Path, labels: dict, min_ok_mass: float) -> _Rows:
    """Read every row's simulation file and its part's features; a bad simulation file raises,
    or with ``labels.on_bad: exclude`` is logged and listed as excluded."""
    frame = labels["frame"]
    out = _Rows([], [], [], {}, {})
    for row in _progress(configs.itertuples(index=False), len(configs), "dataset"):
        try:
            rec = _row_sim(sim_dir, row)
            label = sim_label(rec, int(labels["bins"]), float(labels["sigma_bins"]))
            check_ok_mass(label, min_ok_mass, f"simulation file {sim_dir / row.part / f'{row.config_id}.npz'}")
        except BadData as err:
            if labels["on_bad"] != "exclude":
                raise
            log.warning("excluded %s/%s: %s", row.part, row.config_id, err)
            out.excluded.append((row.part, row.config_id, row.dataset, str(err), row.split))
            continue
        if row.part not in out.feats:
            out.feats[row.part] = load_features(features_dir / f"{row.part}.json")
            out.frames[row.part] = load_frame_deg(features_dir / f"{row.part}.json") if frame == "principal" else 0.0
        rec.yaws = label_yaws(rec.yaws, frame, out.frames[row.part])
        out.kept.append(row)
        out.recs.append(rec)
    if not out.kept:
        raise FeederError("no usable configuration left for the dataset")
    return out


def _label_arrays(rows: _Rows, levels: np.ndarray, bins: int, sigma: float, emulated: int) -> dict[str, np.ndarray]:
    """Per kept row: the yaws (NaN-padded), full and partial-level PMFs, ok drops per level and
    the raw fence vector."""
    n, n_levels = len(rows.kept), levels.size
    # the drops in drop order: the simulated ones of a drawn design, the emulated i.i.d. ones of a
    # sampled map (its samples are unequally weighted and sorted by initial yaw: no prefix of them
    # is a sample of the label), so the convergence study reads drops of one kind
    drop_lists = [level_drops(rec, emulated) for rec in rows.recs]
    drops = np.array([d.size for d, _ in drop_lists])
    yaw_mat = np.full((n, drops.max()), np.nan)
    pmf = np.empty((n, bins))
    pmf_levels = np.empty((n, n_levels, bins))
    n_ok_levels = np.empty((n, n_levels), dtype=np.int64)
    feeder_raw = np.empty((n, N_FEEDER))
    for i, (row, rec, (drop_yaws, drop_ok)) in enumerate(zip(rows.kept, rows.recs, drop_lists, strict=True)):
        yaw_mat[i, : drop_yaws.size] = drop_yaws
        pmf[i] = sim_label(rec, bins, sigma).pmf
        pmf_levels[i], n_ok_levels[i] = L.partial_pmfs(drop_yaws, levels, bins, sigma, ok=drop_ok)
        feeder_raw[i] = feeder_vector(*parse_config_id(row.config_id))
    return {
        "final_yaw_deg": yaw_mat,
        "pmf": pmf,
        "pmf_levels": pmf_levels,
        "n_ok_levels": n_ok_levels,
        "feeder_raw": feeder_raw,
        "n_drops": drops,
    }


def label_smooth_deg(bins: int, sigma_bins: float) -> float:
    """The labels' wrapped-Gaussian smoothing (``labels.sigma_bins``) in degrees."""
    return float(sigma_bins) * L.FULL_TURN_DEG / int(bins)


def _part_push(part: str, profile, frame_deg: float, config_ids: list[str], scene: dict, bins: int, smooth_deg: float):
    """The push block of one part in each of ``config_ids`` (its geometry built once, its fence
    responses shared): ``{config_id: (push_raw, pmf)}``."""
    from feeder.mechanics.features import push_block
    from feeder.mechanics.hull import push_geometry

    geom = push_geometry(*profile) if isinstance(profile, tuple) else push_geometry(profile)
    memo: dict = {}
    out = {}
    for cid in config_ids:
        loc1, loc2 = parse_config_id(cid)
        out[cid] = push_block(
            geom, loc1, loc2, scene, frame_deg=frame_deg, bins=int(bins), pmf_smooth_deg=smooth_deg, responses=memo
        )
    return out


def push_arrays(
    parts: np.ndarray,
    config_ids: np.ndarray,
    outlines: dict,
    frames: dict[str, float],
    scene: dict,
    bins: int,
    smooth_deg: float,
    workers: int = 1,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Per row: the push features and the analytic PMF (:func:`feeder.mechanics.features.push_block`) of
    the row's part outline in its fence configuration, both in the label frame (``frame_deg`` of
    the part: the PMF of ``yaw + frame_deg``, as :func:`label_yaws`), the PMF smoothed by
    ``smooth_deg``. Each part's geometry is built once and its fence responses are shared by its
    rows; a repeated (part, configuration) is computed once. ``workers`` > 1 spreads the parts over
    that many processes (the block is ~90 % of the build; each part's values are those of one
    process, bit for bit). Returns ``(push_raw, pmf_analytic, seconds)``."""
    t0 = time.perf_counter()
    n = len(parts)
    if int(workers) < 1:
        raise FeederError(f"push block: workers must be >= 1, got {workers!r}")
    wanted: dict[str, list[str]] = {}
    for part, cid in zip(parts, config_ids, strict=True):
        cids = wanted.setdefault(str(part), [])
        if str(cid) not in cids:
            cids.append(str(cid))
    jobs = [(part, outlines[part], frames[part], cids, scene, int(bins), smooth_deg) for part, cids in wanted.items()]
    done: dict[str, dict] = {}
    if int(workers) > 1 and len(jobs) > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        ctx = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(max_workers=min(int(workers), len(jobs)), mp_context=ctx) as pool:
            futures = {job[0]: pool.submit(_part_push, *job) for job in jobs}
            for part in _progress(futures, len(futures), "push features (parts)"):
                done[part] = futures[part].result()
    else:
        for job in _progress(jobs, len(jobs), "push features (parts)"):
            done[job[0]] = _part_push(*job)
    push_raw = np.empty((n, len(PUSH_FEATURE_NAMES)))
    pmf = np.empty((n, int(bins)))
    for i, (part, cid) in enumerate(zip(parts, config_ids, strict=True)):
        push_raw[i], pmf[i] = done[str(part)][str(cid)]
    return push_raw, pmf, time.perf_counter() - t0


def _part_outlines(parts, parts_dir: Path, units: str) -> dict[str, tuple[np.ndarray, list[np.ndarray]]]:
    """``(outline, holes)`` of every part (``<parts_dir>/<part>.stl``, metres, the part file's
    frame, as the simulator reads it); a missing or bad file is a one-line FeederError naming it."""
    from feeder.parts.geometry import load_profile

    out = {}
    for part in sorted(set(parts)):
        path = parts_dir / f"{part}.stl"
        if not path.is_file():
            raise FeederError(f"part file {path} is missing (the push features need every part's outline)")
        outline, holes, _ = load_profile(path, units)
        out[part] = (outline, holes)
    return out


def _group_folds(parts: np.ndarray, n_folds: int) -> np.ndarray:
    """Leave-parts-out fold of every row (sklearn GroupKFold over the parts)."""
    from sklearn.model_selection import GroupKFold

    n = parts.size
    n_parts = len(set(parts))
    if n_parts < n_folds:
        raise FeederError(f"datasets.group_folds={n_folds} needs at least that many parts, have {n_parts}")
    group_fold = np.empty(n, dtype=np.int64)
    for fold, (_, test) in enumerate(GroupKFold(n_splits=n_folds).split(np.zeros(n), groups=parts)):
        group_fold[test] = fold
    return group_fold


def parts_dir_of(settings: dict, parts_dir=None) -> Path | None:
    """Where the part files are: ``parts_dir`` when given, else ``parts.dir`` of the settings,
    else None (no push block)."""
    if parts_dir is not None:
        return Path(parts_dir)
    value = (settings.get("parts") or {}).get("dir")
    return None if value is None else Path(value)


def build_dataset(
    configs: pd.DataFrame, features_dir, sim_dir, settings: dict, parts_dir=None, workers: int = 1
) -> dict:
    """The arrays of ``dataset.npz`` (docs/data.md) for the rows of ``configs``.

    ``parts_dir`` (default ``parts.dir`` of ``settings``): the part files; with them the dataset
    also holds the analytic push block (:data:`PUSH_KEYS`, :func:`push_arrays`), in the scene of
    ``settings["scene"]`` (default: the study config's) with the parts read in ``parts.units``
    (default ``auto``). Without them it has none (a ``paper+push`` model cannot train on it)."""
    labels = settings["labels"]
    bins = int(labels["bins"])
    sigma = float(labels["sigma_bins"])
    levels = np.asarray(labels["levels_pct"], dtype=np.int64)
    frame = check_label_frame(labels["frame"])  # before any file is read
    parts_dir = parts_dir_of(settings, parts_dir)
    outlines = None
    if parts_dir is not None:  # read first: a missing part file fails before the simulation files are read
        if not parts_dir.is_dir():
            raise FeederError(f"parts directory {parts_dir} does not exist")
        units = str((settings.get("parts") or {}).get("units", "auto"))
        outlines = _part_outlines(configs["part"], parts_dir, units)
    rows = _read_rows(configs, Path(features_dir), Path(sim_dir), labels, float(settings["sim"]["min_ok_mass"]))
    lab = _label_arrays(rows, levels, bins, sigma, int(labels["emulated_drops"]))
    parts = np.array([r.part for r in rows.kept])
    group_fold = _group_folds(parts, int(settings["datasets"]["group_folds"]))
    ex = np.array(rows.excluded, dtype=str).reshape(-1, 5)
    out = {
        "part": parts,
        "config_id": np.array([r.config_id for r in rows.kept]),
        "dataset": np.array([r.dataset for r in rows.kept]),
        "split": np.array([r.split for r in rows.kept]),
        "group_fold": group_fold,
        "part_raw": np.stack([rows.feats[p] for p in parts]),
        "feeder_raw": lab["feeder_raw"],
        "pmf": lab["pmf"],
        "cdf": L.cdf(lab["pmf"]),
        "pmf_levels": lab["pmf_levels"],
        "levels_pct": levels,
        "n_ok": np.array([int(r.ok.sum()) for r in rows.recs]),
        "n_ok_levels": lab["n_ok_levels"],
        "n_drops": lab["n_drops"],
        "final_yaw_deg": lab["final_yaw_deg"],
        "frame_deg": np.array([rows.frames[p] for p in parts]),
        "label_frame": np.array(frame),
        "excluded_part": ex[:, 0],
        "excluded_config_id": ex[:, 1],
        "excluded_dataset": ex[:, 2],
        "excluded_reason": ex[:, 3],
        "excluded_split": ex[:, 4],
        "settings": np.array(json.dumps(settings, sort_keys=True)),
    }
    if outlines is None:
        log.warning("no part files (--parts-dir or parts.dir): the dataset has no analytic push block")
    else:
        from feeder.mechanics.fence import default_scene

        scene = settings["scene"] if "scene" in settings else default_scene()
        push_raw, pmf_analytic, secs = push_arrays(
            parts, out["config_id"], outlines, rows.frames, scene, bins, label_smooth_deg(bins, sigma), workers
        )
        out["push_raw"] = push_raw
        out["push_feature_names"] = np.array(PUSH_FEATURE_NAMES)
        out["pmf_analytic"] = pmf_analytic
        log.info("push block of %d rows (%d parts) in %.1f s", len(parts), len(set(parts)), secs)
    for key, arr in out.items():
        if arr.dtype.kind == "f" and key != "final_yaw_deg" and not np.isfinite(arr).all():
            raise FeederError(f"dataset array {key} has non-finite values")  # never a silent NaN row
    return out


# ----------------------------------------------------------------------------------------------
# Reading dataset.npz
# ----------------------------------------------------------------------------------------------
def _check_dataset(path: Path, data: dict[str, np.ndarray]) -> None:
    """Shapes (against ``pmf``) and finiteness of the learners' arrays that are present."""
    if "pmf" in data:
        if data["pmf"].ndim != 2:
            raise FeederError(f"{path}: pmf must be (configurations, bins), got shape {data['pmf'].shape}")
        n, bins = data["pmf"].shape
        want = {"part_raw": (n, N_DFT), "feeder_raw": (n, N_FEEDER), "cdf": (n, bins), "pmf_analytic": (n, bins)}
        if "levels_pct" in data:
            want["pmf_levels"] = (n, data["levels_pct"].size, bins)
        if "push_feature_names" in data:
            want["push_raw"] = (n, data["push_feature_names"].size)
        bad = [k for k, shape in want.items() if k in data and data[k].shape != shape]
        if bad:
            raise FeederError(f"{path}: the shapes of {', '.join(bad)} do not match pmf (docs/data.md)")
    if ("push_raw" in data) != ("push_feature_names" in data):
        raise FeederError(f"{path}: push_raw and push_feature_names go together")
    for key in ("part_raw", "feeder_raw", "pmf", "cdf", "pmf_levels", "push_raw", "pmf_analytic"):
        if key in data and not np.isfinite(data[key]).all():
            raise FeederError(f"{path}: {key} has non-finite values")


def load_dataset(path, keys: tuple[str, ...] = DATASET_KEYS) -> dict[str, np.ndarray]:
    """All arrays of a ``dataset.npz`` (docs/data.md) as a dict, ``keys`` required; the learners'
    arrays checked (shapes against ``pmf``, finite values) and the id columns (part, config_id,
    split) as str arrays. Every problem is a one-line :class:`FeederError` naming the file."""
    path = Path(path)
    data = fio.read_npz(path, keys, what="dataset file")
    _check_dataset(path, data)
    for key in ("part", "config_id", "split", "push_feature_names"):
        if key in data:
            data[key] = data[key].astype(str)
    return data


# ----------------------------------------------------------------------------------------------
# Table 4
# ----------------------------------------------------------------------------------------------
_TABLE4_ROWS = [
    ("Main (Train)", ("train",), "Model training (includes the validation rows)", "fit"),
    ("Main (Test)", ("test",), "Held-out configurations of known parts (random row split)", "P1"),
    ("Fences", ("fences",), "Type combinations never seen with these parts in training", "P1"),
    ("Parts", ("parts",), "Unseen part geometries with known fences", "P3"),
    ("Wide", (WIDE,), "The wider library: unseen parts of the leave-parts-out GroupKFold only", "GroupKFold"),
    ("Total (All)", SPLITS, "All datasets combined", ""),
]


def table4(ds: dict) -> pd.DataFrame:
    """Samples and unique parts per dataset; ``excluded``: bad configurations dropped from it,
    counted by the split each row had before exclusion (the split is made first, per row);
    ``share_of_main``: the realised Train and Test shares of the Main rows kept.

    Datasets written before the split of excluded rows was kept (no ``excluded_split``) count
    Main exclusions on the Main (Train) row, as they used to, and say so in ``excluded_note``."""
    has_split = "excluded_split" in ds
    ex_split = (
        ds["excluded_split"]
        if has_split
        else np.where(ds["excluded_dataset"] == "main", "train", ds["excluded_dataset"])
    )
    n_main = int(np.isin(ds["split"], ("train", "test")).sum())
    rows = []
    for name, splits, purpose, protocol in _TABLE4_ROWS:
        sel = np.isin(ds["split"], splits)
        if splits == (WIDE,) and not sel.any() and not np.isin(ex_split, splits).any():
            continue  # a study without the wider library: the paper's rows only
        rows.append(
            {
                "dataset": name,
                "samples": int(sel.sum()),
                "unique_parts": int(np.unique(ds["part"][sel]).size),
                "purpose": purpose,
                "protocol": protocol,
                "excluded": int(np.isin(ex_split, splits).sum()),
                "share_of_main": float(sel.sum() / n_main) if splits in (("train",), ("test",)) and n_main else np.nan,
                "excluded_note": "" if has_split else "split of excluded rows not recorded: Main exclusions on Train",
            }
        )
    return pd.DataFrame(rows)


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
    parser = argparse.ArgumentParser(
        prog="feeder datasets", description="The configuration table, dataset.npz, Table 4 and the convergence study."
    )
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("configurations", help="write the part x fence configuration table")
    p.add_argument("--settings", required=True, help="JSON with the fences and datasets config sections")
    p.add_argument("--parts", required=True, help="comma-separated part ids")
    p.add_argument("--out", required=True, type=Path)
    p = sub.add_parser("build", help="merge simulation and feature files into dataset.npz")
    p.add_argument("--configurations", required=True, type=Path)
    p.add_argument("--features-dir", required=True, type=Path)
    p.add_argument("--sim-dir", required=True, type=Path)
    p.add_argument(
        "--parts-dir",
        type=Path,
        help="the part files (<id>.stl) for the analytic push block (default: parts.dir of --settings; "
        "without either the dataset has none)",
    )
    p.add_argument(
        "--settings",
        required=True,
        help="JSON with the sim, labels and datasets sections (and optionally scene, parts.dir, parts.units)",
    )
    p.add_argument("--workers", type=int, default=1, help="processes for the analytic push block (default: 1)")
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
        settings = parse_settings(args.settings, "fences", "datasets")
        parts = [p for p in args.parts.split(",") if p]
        df = configurations(settings, parts)
        fio.write_csv(args.out, df)
        print(df.groupby("split").size().to_string(), file=sys.stderr)
    elif args.cmd == "build":
        settings = parse_settings(args.settings, "sim", "labels", "datasets")
        ds = build_dataset(
            _read_configs(args.configurations), args.features_dir, args.sim_dir, settings, args.parts_dir, args.workers
        )
        fio.write_npz(args.out, **ds)
        log.info("%d configurations, %d excluded -> %s", len(ds["part"]), ds["excluded_part"].size, args.out)
    elif args.cmd == "table4":
        t = table4(load_dataset(args.dataset))
        fio.write_csv(args.out_csv, t)
        fio.write_text(args.out_md, fio.markdown_table(t, "Table 4. Dataset summary"))
    elif args.cmd == "convergence":
        settings = parse_settings(args.settings, "labels", "datasets")
        out = convergence_data(load_dataset(args.dataset), settings)
        fio.write_csv(args.fig4_data, out["fig4"])
        fio.write_npz(args.fig5_data, **out["fig5"])
        fio.write_npz(args.fig9_data, **out["fig9"])
        fio.write_npz(args.dkw_data, **out["dkw"])
        fio.write_csv(args.dkw_csv, out["dkw_table"])
        fio.write_csv(args.js_csv, out["js_table"])
    return 0
