"""The merged dataset: part features and fence vectors, labels from the simulation files, the
input scaler, ``dataset.npz`` (docs/data.md) and Table 4; and the ``feeder datasets`` command.

* :func:`build_dataset` merges the simulation file of every row of the configuration table
  (:func:`feeder.labels.grid.configurations`) with its part's DFT features into the arrays of
  ``dataset.npz``: labels (PMF, CDF, partial-level PMFs) in the label frame, the raw 45 + 8
  inputs, the leave-parts-out fold of every row and the excluded configurations.
* :func:`load_dataset` reads ``dataset.npz`` back, checked: the one reader every stage uses.
* :class:`Scaler` / :func:`fit_scaler`: the model-input scaler, fit on training rows only.

``feeder datasets configurations|build|table4|convergence`` (``feeder datasets <cmd> -h``); the
grid and splits are in :mod:`feeder.labels.grid`, the convergence study in
:mod:`feeder.labels.convergence`.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io as fio
from feeder.config import parse_settings
from feeder.errors import FeederError
from feeder.labels import metrics as L
from feeder.labels.convergence import convergence_data
from feeder.labels.grid import SPLITS, configurations
from feeder.labels.pmf import check_ok_mass, level_drops, sim_label
from feeder.parts.features import DFT, DFT_FEATURE_NAMES, FEATURES_VERSION
from feeder.sim.fences import TYPES, Fence, parse_config_id
from feeder.sim.record import BadData, SimRecord, load_sim

log = logging.getLogger("feeder.labels.dataset")

N_DFT = 45
N_FEEDER = 8
# what every learner reads from dataset.npz, and the partial-level labels the VAE and delta use
DATASET_KEYS = ("part", "config_id", "split", "group_fold", "part_raw", "feeder_raw", "pmf", "cdf")
LEVEL_KEYS = ("pmf_levels", "levels_pct")
# the 8 feeder inputs in the order of :func:`feeder_vector`: per location the one-hot fence type,
# then the angle
FEEDER_FEATURE_NAMES = tuple(
    name for loc in (1, 2) for name in (*(f"loc{loc}_{t}" for t in TYPES), f"loc{loc}_angle_deg")
)
INPUT_NAMES = DFT_FEATURE_NAMES + FEEDER_FEATURE_NAMES  # the 53 raw model inputs, in order
FEATURES_DIGEST_CHARS = 12  # hex digits of the sha256 kept in features_version()


def features_version() -> str:
    """The version of the model inputs this code computes, ``"<FEATURES_VERSION>-<digest>"``:
    the hand-bumped :data:`feeder.parts.features.FEATURES_VERSION` and a short sha256 of it, the
    ordered :data:`INPUT_NAMES` and the DFT settings (:data:`feeder.parts.features.DFT`). A model
    card records it; a model whose inputs were computed otherwise gets a different one."""
    import dataclasses
    import hashlib

    if len(INPUT_NAMES) != N_DFT + N_FEEDER:
        raise FeederError(f"INPUT_NAMES lists {len(INPUT_NAMES)} inputs, the models take {N_DFT + N_FEEDER}")
    blob = json.dumps(
        {"version": FEATURES_VERSION, "inputs": list(INPUT_NAMES), "dft": dataclasses.asdict(DFT)}, sort_keys=True
    )
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
    def from_dict(cls, d: dict) -> Scaler:
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


def build_dataset(configs: pd.DataFrame, features_dir, sim_dir, settings: dict) -> dict:
    """The arrays of ``dataset.npz`` (docs/data.md) for the rows of ``configs``."""
    labels = settings["labels"]
    bins = int(labels["bins"])
    sigma = float(labels["sigma_bins"])
    levels = np.asarray(labels["levels_pct"], dtype=np.int64)
    frame = check_label_frame(labels["frame"])  # before any file is read
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
        want = {"part_raw": (n, N_DFT), "feeder_raw": (n, N_FEEDER), "cdf": (n, bins)}
        if "levels_pct" in data:
            want["pmf_levels"] = (n, data["levels_pct"].size, bins)
        bad = [k for k, shape in want.items() if k in data and data[k].shape != shape]
        if bad:
            raise FeederError(f"{path}: the shapes of {', '.join(bad)} do not match pmf (docs/data.md)")
    for key in ("part_raw", "feeder_raw", "pmf", "cdf", "pmf_levels"):
        if key in data and not np.isfinite(data[key]).all():
            raise FeederError(f"{path}: {key} has non-finite values")


def load_dataset(path, keys: tuple[str, ...] = DATASET_KEYS) -> dict[str, np.ndarray]:
    """All arrays of a ``dataset.npz`` (docs/data.md) as a dict, ``keys`` required; the learners'
    arrays checked (shapes against ``pmf``, finite values) and the id columns (part, config_id,
    split) as str arrays. Every problem is a one-line :class:`FeederError` naming the file."""
    path = Path(path)
    data = fio.read_npz(path, keys, what="dataset file")
    _check_dataset(path, data)
    for key in ("part", "config_id", "split"):
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
        settings = parse_settings(args.settings, "fences", "datasets")
        parts = [p for p in args.parts.split(",") if p]
        df = configurations(settings, parts)
        fio.write_csv(args.out, df)
        print(df.groupby("split").size().to_string(), file=sys.stderr)
    elif args.cmd == "build":
        settings = parse_settings(args.settings, "sim", "labels", "datasets")
        ds = build_dataset(_read_configs(args.configurations), args.features_dir, args.sim_dir, settings)
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
