"""The study's own answer: its simulations where it has the part, the analytic push PMF elsewhere.

``feeder predict`` and ``feeder recommend`` answer with this predictor when no ``--model`` is given
(``--model study``). It is what the committed tables support (docs/results.md):

* **a part the study simulated, at a configuration it simulated**: that configuration's label, as
  the workflow labels it (the simulator's own answer, at no cost);
* **a part the study simulated, at a new angle**: the label of its nearest simulated angle of the
  same fence types, when that lies within the gate (``neighbour_gated`` of
  ``results/tables/neighbour.csv``, which beats the analytic PMF on Test by a paired interval);
* **anything else** (a new part, a fence-type combination the part was not simulated with, a
  neighbour beyond the gate, another scene): the untrained analytic push PMF, which no trained
  network beats on unseen parts (``results/tables/groupkfold_*_paired.csv``).

A part is known by the SHA-256 of its STL file's bytes: the study's own ``parts/<id>.stl`` (or a
byte-identical copy) is known, a re-exported one is new. The labels are the study's only for the
scene they were simulated in: a study config with another scene gets the analytic PMF throughout.

``feeder export-study`` writes the folder ``models/study`` (committed): ``labels.npz`` with every
configuration's raw drops (final and initial yaws, statuses, design metadata: the labels are
recomputed from them at the caller's bins and smoothing) and ``card.json`` with the gate, chosen on
every labelled configuration (each from its nearest other one; :func:`feeder.learn.neighbour.choose_gate`),
and the evidence it rests on.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError
from feeder.learn.analytic import AnalyticModel, AnalyticSpec
from feeder.learn.structured_data import fence_key, nearest_configuration
from feeder.learn.structured_shipped import SHIPPED_FILE, scene_digest

STUDY_MODEL = "study"  # the --model value that names this predictor (the default)
STUDY_DIR = "study"  # its folder under the shipped-model root (models/study)
LABELS_FILE = "labels.npz"
CARD_FILE = "card.json"
CARD_MARKDOWN = "MODEL_CARD.md"
# the rows of structured_protocol.csv the card quotes: the seeds scored one by one (the protocol's
# headline; their averaged PMFs, which the shipped file answers with, are the table's
# structured_ensemble rows and score no worse, circular W1 being convex in the CDF)
EVIDENCE_MODEL = "structured"
LIBRARY_FORMAT = 1  # version of the layout of labels.npz and card.json
# how a row was answered (StudyModel.sources)
SIMULATED, NEIGHBOUR, STRUCTURED, ANALYTIC = "simulated", "neighbour", "structured", "analytic"


# ----------------------------------------------------------------------------------------------
# Pure functions
# ----------------------------------------------------------------------------------------------
def file_digest(path) -> str:
    """SHA-256 (hex) of a file's bytes: how the library knows a part."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def check_gates(gates) -> list[float]:
    """The candidate gates (degrees) as floats: at least one, each finite and >= 0; a one-line
    FeederError otherwise."""
    try:
        out = [float(g) for g in gates]
    except (TypeError, ValueError):
        raise FeederError(f"neighbour.gates_deg: a list of angles in degrees, got {gates!r}") from None
    if not out or not all(np.isfinite(out)) or min(out) < 0:
        raise FeederError(f"neighbour.gates_deg: at least one finite angle >= 0, got {gates!r}")
    return out


def pad_rows(rows: list[np.ndarray], fill, dtype) -> np.ndarray:
    """Ragged 1-D arrays as one (len(rows), longest) array, short rows filled with ``fill``."""
    width = max((r.size for r in rows), default=0)
    out = np.full((len(rows), width), fill, dtype=dtype)
    for i, r in enumerate(rows):
        out[i, : r.size] = r
    return out


# ----------------------------------------------------------------------------------------------
# The library (models/study)
# ----------------------------------------------------------------------------------------------
@dataclass
class Library:
    """Every simulated configuration of the study, as raw drops (``labels.npz``) and its card."""

    part: np.ndarray  # (n,) part id of each configuration
    config_id: np.ndarray  # (n,)
    kept: np.ndarray  # (n,) bool: a row of the dataset (not excluded as jammed): may serve as a neighbour
    final_yaw_deg: np.ndarray  # (n, drops) NaN beyond a row's drops
    initial_yaw_deg: np.ndarray  # (n, drops)
    status: np.ndarray  # (n, drops) '' beyond a row's drops
    drops: np.ndarray  # (n,) drops of each row
    meta: np.ndarray  # (n,) the simulation file's design metadata (JSON)
    part_ids: np.ndarray  # (p,) every part of the library ...
    part_digests: np.ndarray  # (p,) ... and the SHA-256 of its STL
    card: dict
    structured: object = None  # the shipped structured predictor (structured.npz), when exported with one
    # each row's audit estimate of its label's error (feeder audit; NaN: no label or not audited),
    # when exported with the study's label error table
    est_circular_w1_deg: np.ndarray | None = None
    est_sup_cdf: np.ndarray | None = None

    def record(self, i: int):
        """Row ``i`` as the :class:`feeder.sim.record.SimRecord` its simulation file held."""
        from feeder.sim.record import record_of

        n = int(self.drops[i])
        return record_of(
            {
                "final_yaw_deg": self.final_yaw_deg[i, :n],
                "initial_yaw_deg": self.initial_yaw_deg[i, :n],
                "status": self.status[i, :n],
                "meta": str(self.meta[i]),
            }
        )

    def part_of(self, digest: str) -> str | None:
        """The library's part id of an STL digest, or None."""
        hit = np.flatnonzero(self.part_digests == digest)
        return str(self.part_ids[hit[0]]) if hit.size else None


def build_library(configurations: pd.DataFrame, sim_dir, parts_dir, dataset: dict) -> dict:
    """The arrays of ``labels.npz`` from the study's simulation files (``sim_dir/<part>/<config>.npz``,
    one per row of ``configurations``: columns ``part``, ``config_id``), its parts' STLs and the
    dataset's kept rows (``part``, ``config_id``)."""
    from feeder.sim.record import load_sim

    if configurations.empty:
        raise FeederError("export-study: the configuration table has no row")
    kept_pairs = set(zip(np.asarray(dataset["part"]).astype(str), np.asarray(dataset["config_id"]).astype(str)))
    parts, cids, kept, finals, initials, statuses, metas = [], [], [], [], [], [], []
    for part, cid in zip(configurations["part"].astype(str), configurations["config_id"].astype(str), strict=True):
        rec = load_sim(Path(sim_dir) / part / f"{cid}.npz", min_ok_drops=0)
        if rec.initial is None:
            raise FeederError(f"simulation file {sim_dir}/{part}/{cid}.npz has no initial yaws: rerun its simulation")
        parts.append(part)
        cids.append(cid)
        kept.append((part, cid) in kept_pairs)
        finals.append(np.where(rec.ok, rec.yaws, np.nan))
        initials.append(rec.initial)
        statuses.append(rec.status)
        metas.append(json.dumps(rec.meta, sort_keys=True))
    part_ids = sorted(set(parts))
    digests = []
    for p in part_ids:
        stl = Path(parts_dir) / f"{p}.stl"
        if not stl.is_file():
            raise FeederError(f"export-study: part file {stl} is missing")
        digests.append(file_digest(stl))
    return {
        "part": np.array(parts),
        "config_id": np.array(cids),
        "kept": np.array(kept, dtype=bool),
        "final_yaw_deg": pad_rows(finals, np.nan, np.float64),
        "initial_yaw_deg": pad_rows(initials, np.nan, np.float64),
        "status": pad_rows(statuses, "", "<U16"),
        "drops": np.array([f.size for f in finals], dtype=np.int64),
        "meta": np.array(metas),
        "part_ids": np.array(part_ids),
        "part_digests": np.array(digests),
    }


def label_error_arrays(arrays: dict, table: pd.DataFrame) -> dict:
    """Each library row's audit estimates from the study's label error table
    (``results/tables/label_error_estimate.csv``, ``feeder audit table``): ``est_circular_w1_deg``
    and ``est_sup_cdf`` (NaN where the row has no label). A library row missing from the table is a
    one-line error: the table is of another run."""
    missing = {"part", "config_id", "est_circular_w1_deg", "est_sup_cdf"} - set(table.columns)
    if missing:
        raise FeederError(f"export-study: the label error table lacks column {sorted(missing)[0]!r}")
    index = {(str(p), str(c)): i for i, (p, c) in enumerate(zip(table["part"], table["config_id"]))}
    rows = [index.get((str(p), str(c))) for p, c in zip(arrays["part"], arrays["config_id"])]
    absent = [f"{p} {c}" for p, c, r in zip(arrays["part"], arrays["config_id"], rows) if r is None]
    if absent:
        raise FeederError(f"export-study: the label error table has no row for {absent[0]} (of another run?)")
    return {
        key: table[key].to_numpy(dtype=np.float64)[np.array(rows, dtype=np.int64)]
        for key in ("est_circular_w1_deg", "est_sup_cdf")
    }


def scene_kind(config_id: str, steep_deg: float) -> str:
    """The kind of scene a configuration is, as the analytic PMF's error is told by
    (:func:`analytic_by_scene`): its fence types as its id writes them (Location 1 first, e.g.
    ``straight_none``), with ", steep" when one of its straight fences stands at ``steep_deg`` or
    more, where the push model misses most."""
    from feeder.lane.fences import parse_config_id

    fences = parse_config_id(str(config_id))
    steep = any(f.type == "straight" and float(f.angle) >= float(steep_deg) for f in fences)
    return f"{fences[0].type}_{fences[1].type}" + (", steep" if steep else "")


def check_steep_deg(value) -> float:
    """``analytic_scenes.steep_deg`` as a float in (0, 90); a one-line FeederError otherwise."""
    try:
        steep = float(value)
    except (TypeError, ValueError):
        steep = float("nan")
    if not 0.0 < steep < 90.0:
        raise FeederError(f"analytic_scenes.steep_deg must be a number of degrees in (0, 90), got {value!r}")
    return steep


def analytic_by_scene(config_ids, pmf, pmf_analytic, steep_deg: float) -> list[dict]:
    """How far the analytic PMF lies from the labels, by :func:`scene_kind`: per kind (sorted by
    name) its number of configurations and the mean, median and 90th percentile of the circular W1
    (degrees) between each label ``pmf`` and its analytic PMF ``pmf_analytic`` (rows alike)."""
    from feeder.labels.metrics import circular_w1

    pmf, analytic = np.asarray(pmf, np.float64), np.asarray(pmf_analytic, np.float64)
    if pmf.shape != analytic.shape or pmf.ndim != 2 or pmf.shape[0] != len(config_ids):
        raise FeederError("analytic_by_scene: one label and one analytic PMF per configuration, on the same bins")
    w1 = np.atleast_1d(circular_w1(np.cumsum(pmf, axis=1), np.cumsum(analytic, axis=1)))
    kinds = np.array([scene_kind(c, steep_deg) for c in config_ids])
    out = []
    for kind in sorted(set(kinds.tolist())):
        w = w1[kinds == kind]
        out.append(
            {
                "scene": kind,
                "configurations": int(w.size),
                "mean_circular_w1_deg": float(w.mean()),
                "median_circular_w1_deg": float(np.median(w)),
                "p90_circular_w1_deg": float(np.percentile(w, 90)),
            }
        )
    return out


def gate_scores(dataset: dict, gates) -> pd.DataFrame:
    """Mean circular W1 of the gated neighbour at each gate over every labelled configuration of the
    dataset, each predicted from its nearest other one of the same part and fence types
    (:func:`feeder.learn.neighbour.choose_gate`'s score); one row per gate."""
    from feeder.labels.metrics import circular_w1
    from feeder.learn.neighbour import angle_distance, neighbour_index

    pmf, analytic = np.asarray(dataset["pmf"], np.float64), np.asarray(dataset["pmf_analytic"], np.float64)
    parts, cids = np.asarray(dataset["part"]).astype(str), np.asarray(dataset["config_id"]).astype(str)
    rows = np.arange(pmf.shape[0])
    idx = neighbour_index(parts, cids, np.ones(rows.size, dtype=bool), rows)
    have = idx >= 0
    cdf = np.cumsum(pmf, axis=1)
    w_nb = np.full(rows.size, np.inf)
    w_nb[have] = circular_w1(cdf[have], np.cumsum(pmf[idx[have]], axis=1))
    w_an = circular_w1(cdf, np.cumsum(analytic, axis=1))
    dist = np.array([angle_distance(cids[i], cids[j]) if j >= 0 else np.inf for i, j in zip(rows, idx, strict=True)])
    out = []
    for g in sorted(float(x) for x in gates):
        use = dist <= g
        out.append(
            {
                "gate_deg": g,
                "configurations": int(rows.size),
                "neighbour_share": float(use.mean()),
                "circular_w1_deg": float(np.where(use, w_nb, w_an).mean()),
            }
        )
    return pd.DataFrame(out)


def neighbour_evidence(table: pd.DataFrame) -> dict:
    """The Test comparison the card quotes: ``neighbour_gated`` against the analytic PMF by circular
    W1 (``results/tables/neighbour.csv``)."""
    hit = table[(table.predictor == "neighbour_gated") & (table.baseline == "analytic_pmf") & (table.metric == "cw1")]
    if len(hit) != 1:
        raise FeederError("export-study: the neighbour table has no neighbour_gated / analytic_pmf / cw1 row")
    r = hit.iloc[0]
    keys = ("configurations", "repeats", "value", "baseline_value", "diff", "diff_low", "diff_high", "level", "verdict")
    return {k: (r[k].item() if hasattr(r[k], "item") else r[k]) for k in keys}


ERROR_BIN_KEYS = (
    "low_deg",
    "high_deg",
    "model",
    "rows",
    "mean_circular_w1_deg",
    "median_circular_w1_deg",
    "p90_circular_w1_deg",
)


def structured_error_bins(table: pd.DataFrame) -> list[dict]:
    """The rows of ``structured_by_distance.csv`` (:func:`feeder.learn.structured_protocol.error_by_distance`)
    the card keeps: the bins with scored rows, as plain values (inf: no label of the fence types)."""
    missing = set(ERROR_BIN_KEYS) - set(table.columns)
    if missing:
        raise FeederError(f"export-study: the structured error table has no column {', '.join(sorted(missing))}")
    hit = table[table.rows > 0]
    out = [{k: (r[k].item() if hasattr(r[k], "item") else r[k]) for k in ERROR_BIN_KEYS} for _, r in hit.iterrows()]
    for b in out:  # JSON has no infinity: no label of the fence types is a bin without bounds
        b["low_deg"], b["high_deg"] = (None, None) if np.isinf(float(b["low_deg"])) else (b["low_deg"], b["high_deg"])
    return out


def _bound(value) -> float:
    return float("inf") if value is None else float(value)


def error_bin(bins: list[dict], dist: float) -> dict | None:
    """The bin of :func:`structured_error_bins` holding angle distance ``dist`` (inf: the bin of no
    label of the fence types), or None (pure)."""
    top = max((_bound(b["high_deg"]) for b in bins if b["high_deg"] is not None), default=None)
    for b in bins:
        lo, hi = _bound(b["low_deg"]), _bound(b["high_deg"])
        if (np.isinf(dist) and np.isinf(lo)) or (lo <= dist < hi) or (dist == hi == top):  # the last bin is closed
            return b
    return None


def structured_evidence(table: pd.DataFrame) -> list[dict]:
    """The rows of ``results/tables/structured_protocol.csv`` the card quotes: the structured
    predictor against the analytic PMF and the gated neighbour by circular W1 on Test and Fences."""
    hit = table[
        table.experiment.isin(["test", "fences"])
        & table.baseline.isin(["analytic_pmf", "neighbour_gated"])
        & (table.metric == "cw1")
        & (table.model == EVIDENCE_MODEL if "model" in table else True)
    ]
    if hit.empty:
        raise FeederError("export-study: the structured table has no test/fences cw1 row against analytic_pmf")
    keys = (
        "experiment",
        "baseline",
        "n",
        "structured",
        "baseline_value",
        "diff",
        "diff_low",
        "diff_high",
        "level",
        "verdict",
    )
    return [{k: (r[k].item() if hasattr(r[k], "item") else r[k]) for k in keys} for _, r in hit.iterrows()]


def export_study(
    configurations,
    sim_dir,
    parts_dir,
    dataset_path,
    neighbour_table,
    gates,
    out,
    structured=None,
    structured_table=None,
    label_errors=None,
    steep_deg: float | None = None,
    structured_errors=None,
) -> dict:
    """Write ``out`` (``labels.npz``, ``card.json``, ``MODEL_CARD.md`` and, given ``structured``, the
    shipped structured predictor of :mod:`feeder.learn.structured_shipped` with the evidence of
    ``structured_table`` and, given ``structured_errors`` (``structured_by_distance.csv``), its error
    by the distance to the part's nearest label (:func:`structured_error_bins`); given
    ``label_errors``, each label's audit estimate; given ``steep_deg``,
    the analytic PMF's error on the labels by kind of scene, :func:`analytic_by_scene`) atomically;
    returns the card."""
    with np.load(dataset_path, allow_pickle=False) as z:
        dataset = {k: z[k] for k in ("part", "config_id", "pmf", "pmf_analytic", "settings")}
    settings = json.loads(str(dataset["settings"]))
    arrays = build_library(configurations, sim_dir, parts_dir, dataset)
    scores = gate_scores(dataset, gates)
    best = scores.loc[scores.circular_w1_deg.idxmin()]  # idxmin: the first (smallest) of equal gates
    card = {
        "format": LIBRARY_FORMAT,
        "predictor": STUDY_MODEL,
        "configurations": int(arrays["part"].size),
        "labelled": int(arrays["kept"].sum()),
        "parts": int(arrays["part_ids"].size),
        "gate_deg": float(best.gate_deg),
        "gate_scores": scores.to_dict(orient="records"),
        "scene_sha256": scene_digest(settings["scene"]),
        "sim": settings.get("sim", {}),
        "test_evidence": neighbour_evidence(pd.read_csv(neighbour_table)),
    }
    if steep_deg is not None:
        card["analytic_scenes"] = {
            "steep_deg": check_steep_deg(steep_deg),
            "kinds": analytic_by_scene(dataset["config_id"], dataset["pmf"], dataset["pmf_analytic"], steep_deg),
        }
    if label_errors is not None:
        arrays |= label_error_arrays(arrays, pd.read_csv(label_errors, dtype={"part": str, "config_id": str}))
        w1 = arrays["est_circular_w1_deg"][arrays["kept"]]
        w1 = w1[np.isfinite(w1)]
        card["label_errors"] = {
            "audited": int(w1.size),
            "est_circular_w1_deg_median": float(np.median(w1)) if w1.size else None,
        }
    shipped = None
    if structured is not None:
        from feeder.learn.structured_shipped import ShippedStructured

        with np.load(structured, allow_pickle=False) as z:
            shipped = {k: z[k] for k in z.files}
        model = ShippedStructured(shipped)
        if model.meta["scene_sha256"] != card["scene_sha256"]:
            raise FeederError(f"export-study: {structured} was trained in another scene than the dataset's")
        card["structured"] = {
            "choice": model.meta["choice"],
            "seeds": model.meta["seeds"],
            "neighbours": model.meta["neighbours"],
            "cross_neighbours": model.meta["cross_neighbours"],
            "specialist": (model.meta.get("specialist") or {}).get("choice"),
            "calibration": calibration_counts(model.meta.get("calibration")),
            "blend": model.meta.get("blend"),
            "specialist_blend": (model.meta.get("specialist") or {}).get("blend"),
            "mirror_parts": mirror_count(model.mirrors) if model.meta.get("mirror_labels") else None,
            "evidence": [] if structured_table is None else structured_evidence(pd.read_csv(structured_table)),
            "by_distance": [] if structured_errors is None else structured_error_bins(pd.read_csv(structured_errors)),
        }
    _write_folder(Path(out), arrays, card, shipped)
    return card


def _write_folder(out: Path, arrays: dict, card: dict, structured: dict | None = None) -> None:
    """``out`` with the library's files, all or nothing: written in a sibling folder, then swapped in
    (:func:`feeder.learn.export.replace_dir`). Only an earlier export (or an empty folder) is replaced."""
    from feeder.io import write_json, write_npz, write_text
    from feeder.learn.export import write_folder

    if out.exists() and (not out.is_dir() or (not (out / CARD_FILE).is_file() and any(out.iterdir()))):
        raise FeederError(f"--out {out} exists and is not an exported study folder (no {CARD_FILE}): not replacing it")

    def fill(work: Path) -> None:
        write_npz(work / LABELS_FILE, **arrays)
        if structured is not None:
            write_npz(work / SHIPPED_FILE, **structured)
        write_json(work / CARD_FILE, card)
        write_text(work / CARD_MARKDOWN, card_markdown(card))

    write_folder(out, fill)


def card_markdown(card: dict) -> str:
    """The human-readable card of the study's labels."""
    ev = card["test_evidence"]
    lines = [
        "# The study's answer (`feeder predict` / `feeder recommend` without `--model`)",
        "",
        f"{card['configurations']} simulated configurations of {card['parts']} parts "
        f"({card['labelled']} labelled, the rest excluded as jammed), as raw drops (`labels.npz`).",
        "",
        "- A configuration the study simulated: its label (the simulator's answer).",
        *_card_label_errors(card),
        *_card_new_angle(card),
        "- A new part, or another scene: the analytic push PMF.",
        *_card_analytic_scenes(card),
        "",
        f"Test evidence (`results/tables/neighbour.csv`, {ev['configurations']} configurations x {ev['repeats']} "
        f"Main splits): circular W1 {ev['value']:.1f} deg against {ev['baseline_value']:.1f} for the analytic PMF, "
        f"{ev['diff']:+.1f} [{ev['diff_low']:.1f}, {ev['diff_high']:.1f}] ({ev['level']:.0%} paired bootstrap).",
        "",
        "The gate, chosen on every labelled configuration (each from its nearest other one):",
        "",
        "| gate (deg) | answered by a neighbour | mean circular W1 (deg) |",
        "|---|---|---|",
    ]
    for s in card["gate_scores"]:
        lines.append(f"| {s['gate_deg']:g} | {s['neighbour_share']:.0%} | {s['circular_w1_deg']:.2f} |")
    return "\n".join(lines) + "\n"


def _card_label_errors(card: dict) -> list[str]:
    """The card's line on the labels' audit estimates, when exported with them."""
    errors = card.get("label_errors")
    if not errors or not errors["audited"]:
        return []
    return [
        f"  Each label carries its audit's upper estimate of its own error (`feeder audit`, "
        f"`results/tables/label_error_estimate.csv`; {errors['audited']} kept labels, median circular W1 "
        f"{errors['est_circular_w1_deg_median']:.1f} deg), which `feeder predict` prints with it."
    ]


def _card_analytic_scenes(card: dict) -> list[str]:
    """The card's table of the analytic PMF's error on the labels by kind of scene, when exported with it."""
    scenes = card.get("analytic_scenes")
    if not scenes:
        return []
    lines = [
        "",
        f"How far the analytic push PMF lies from the study's labels (circular W1, deg; every labelled configuration, "
        f"none trained on: it is untrained), by kind of scene (fence types as configuration ids write them, Location 1 "
        f"first; steep: a straight fence at "
        f"{scenes['steep_deg']:g} deg or more). `feeder predict` prints its row with the analytic answer:",
        "",
        "| scene | configurations | mean | median | 90th percentile |",
        "|---|---|---|---|---|",
    ]
    for k in scenes["kinds"]:
        lines.append(
            f"| {k['scene']} | {k['configurations']} | {k['mean_circular_w1_deg']:.1f} | "
            f"{k['median_circular_w1_deg']:.1f} | {k['p90_circular_w1_deg']:.1f} |"
        )
    return lines


def _refit_words(choice: dict) -> str:
    """``, then ...`` when the shipped seeds were trained again on every row (``train.refit``)."""
    n = int(choice.get("refit_rows", 0) or 0)
    return f", then trained again on all {n} kept rows for the steps early stopping kept" if n else ""


def calibration_counts(calibration: dict | None) -> dict | None:
    """The shipped file's calibration (``calibration.network``) as the card states it: the margin,
    the modes' names and how many trained parts each mode answers (``base``: the model's own)."""
    if not calibration:
        return None
    names = ["base"] + [m["name"] for m in calibration["modes"]]
    chosen = list(calibration["part_modes"].values())
    return {
        "margin_deg": calibration["margin_deg"],
        "modes": len(calibration["modes"]),
        "parts": {n: chosen.count(n) for n in names if n in chosen},
    }


def _calibration_words(cal: dict | None) -> str:
    """`` Its analytic component ...`` when the shipped network is calibrated, else ''."""
    if not cal:
        return ""
    kept = cal["parts"].get("base", 0)
    total = sum(cal["parts"].values())
    return (
        " Its own analytic component is the analytic model calibrated on the part's labels: of "
        f"{cal['modes']} variants, the one with the least mean circular W1 on them "
        f"where it beats the model's own by {cal['margin_deg']:g} deg ({total - kept} of {total} parts; "
        "docs/structured.md)."
    )


NEAREST_WORDS = "the label of the nearest simulated angle of the same fence types{gate}, else the analytic PMF"


def _blend_words(blend: dict | None, fallback: str) -> str:
    """`` It answers ... blended ...`` when the shipped network's answer is blended with its fallback
    (blend.weights; with blend.by_fallback one weight where the fallback is a neighbour's label and
    one where it is the analytic PMF), else ''."""
    from feeder.learn.structured_blend import analytic_weight, blends_anything

    if not blends_anything(blend):
        return ""
    w, wa = float(blend["weight"]), analytic_weight(blend)
    gate = "" if blend.get("gate_deg") is None else f" within {float(blend['gate_deg']):g} degrees"
    if "split_val_cw1" in blend and blend.get("gate_deg") is not None:
        alone = (blend.get("val_cw1") or {}).get("1.0")
        on_val = (
            ""
            if alone is None
            else f" (validation circular W1 {blend['split_val_cw1']:.2f} against {alone:.2f} deg alone)"
        )
        return (
            f" Its answer is {w:g} times the network's plus {1 - w:g} times the label of the nearest simulated "
            f"angle of the same fence types{gate} where there is one, else {wa:g} times the network's plus "
            f"{1 - wa:g} times the analytic PMF, each weight chosen on the validation parts' rows of its kind{on_val}."
        )
    scores = blend.get("val_cw1") or {}
    alone, chosen = scores.get("1.0"), scores.get(str(w))
    on_val = (
        ""
        if alone is None or chosen is None
        else f" (validation circular W1 {chosen:.2f} against {alone:.2f} deg alone)"
    )
    return (
        f" Its answer is {w:g} times the network's plus {1 - w:g} times "
        f"{fallback.format(gate=gate)}, the weight chosen on the validation parts{on_val}."
    )


def mirror_count(mirrors: dict[str, float]) -> int:
    """How many of the shipped predictor's parts have a mirror axis (a finite mirror constant)."""
    return int(sum(math.isfinite(c) for c in mirrors.values()))


def _mirror_words(parts: int | None) -> str:
    """`` A one-fence label ...`` when the shipped predictor reads mirrored labels (model.mirror_labels)."""
    if parts is None:
        return ""
    return (
        f" A one-fence label of a part with a mirror axis ({parts} of its parts) is also read at the other "
        "location, reflected: the two locations are mirror images of one scene (docs/structured.md)."
    )


def _card_new_angle(card: dict) -> list[str]:
    """The card's lines on a simulated part at a configuration the study did not simulate."""
    gated = (
        f"the label of its nearest simulated angle of the same fence types within {card['gate_deg']:g} degrees "
        "(|d theta1| + |d theta2|), else the analytic push PMF"
    )
    st = card.get("structured")
    if st is None:
        return [f"- A simulated part at a new angle: {gated}."]
    c = st["choice"]
    lines = [
        "- A simulated part at a new angle: the structured predictor (`structured.npz`, docs/structured.md) "
        f"when the part has a labelled configuration of the same fence types or of the same downstream fence "
        f"type ({st['neighbours']} + {st['cross_neighbours']} neighbours), else {gated}. It was trained on every "
        f"configuration ({c['kind']}, hidden {c['hidden']}, weight decay {c['weight_decay']:g}, {st['seeds']} seeds, "
        f"PMFs averaged), early-stopped and chosen on {c['val_parts']} validation parts "
        f"(circular W1 {c['val_cw1']:.2f} deg){_refit_words(c)}. Its ok mass is the analytic one."
        f"{_calibration_words(st.get('calibration'))}"
        f"{_blend_words(st.get('blend'), NEAREST_WORDS)}"
        f"{_mirror_words(st.get('mirror_parts'))}",
    ]
    sp = st.get("specialist")
    if sp:  # model.fences_specialist
        lines.append(
            "  Where the part has no labelled configuration of the query's own fence types, a second network "
            "answers, trained and chosen reading only the part's labels of other type combinations, as such a "
            f"query must (the Fences specialist: {sp['kind']}, hidden {sp['hidden']}, weight decay "
            f"{sp['weight_decay']:g}, validation circular W1 {sp['val_cw1']:.2f} deg; docs/structured.md)."
            f"{_blend_words(st.get('specialist_blend'), 'the analytic PMF')}"
        )
    if st["evidence"]:
        lines += [
            "",
            "Evidence (`results/tables/structured_protocol.csv`, `feeder structured`; 95 % paired bootstrap):",
            "",
        ]
        lines += ["| set | against | n | structured (deg) | baseline (deg) | difference |", "|---|---|---|---|---|---|"]
        for e in st["evidence"]:
            lines.append(
                f"| {e['experiment']} | {e['baseline']} | {e['n']} | {e['structured']:.2f} | {e['baseline_value']:.2f} "
                f"| {e['diff']:+.2f} [{e['diff_low']:.2f}, {e['diff_high']:.2f}] |"
            )
        lines.append("")
    if st.get("by_distance"):
        lines += [
            "Its error by how far the part's nearest label of the same fence types lies (|d theta1| + |d theta2|; "
            "`results/tables/structured_by_distance.csv`: the protocol's Test and Fences rows of its Main splits, "
            "each row of each split once, circular W1 in degrees of its seeds' averaged PMF, as shipped; the "
            "evidence above scores the seeds one by one). `feeder predict` prints the row of its answer:",
            "",
            "| nearest label | scored rows | mean | median | 90th percentile |",
            "|---|---|---|---|---|",
        ]
        for b in st["by_distance"]:
            lines.append(
                f"| {distance_words(b)} | {b['rows']} | {b['mean_circular_w1_deg']:.1f} | "
                f"{b['median_circular_w1_deg']:.1f} | {b['p90_circular_w1_deg']:.1f} |"
            )
        lines.append("")
    return lines


def distance_words(b: dict) -> str:
    """A bin of :func:`structured_error_bins` for a person (pure)."""
    if np.isinf(_bound(b["low_deg"])):
        return "none of its fence types"
    return f"{float(b['low_deg']):g} to {float(b['high_deg']):g} deg away"


def study_dir() -> Path:
    """``models/study`` at the repository root (beside the shipped models; located from the package)."""
    import feeder
    from feeder.learn.export import SHIPPED_ROOT

    return Path(feeder.__file__).resolve().parents[2] / SHIPPED_ROOT / STUDY_DIR


def load_library(folder: Path | None = None) -> Library:
    """The library in ``folder`` (default :func:`study_dir`); a one-line FeederError when absent."""
    folder = study_dir() if folder is None else Path(folder)
    labels, card_path = folder / LABELS_FILE, folder / CARD_FILE
    if not (labels.is_file() and card_path.is_file()):
        raise FeederError(
            f"the study's labels are not in {folder}: run `make run` (rule export_study), "
            "or pass --model analytic or a model folder"
        )
    try:
        card = json.loads(card_path.read_text())
    except json.JSONDecodeError:
        raise FeederError(f"{card_path} is not JSON: export the study again (feeder export-study)") from None
    if not isinstance(card, dict) or card.get("format") != LIBRARY_FORMAT:
        found = card.get("format") if isinstance(card, dict) else None
        raise FeederError(f"{card_path}: format {found!r}, this code reads {LIBRARY_FORMAT}: export the study again")
    with np.load(labels, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    structured = None
    if (folder / SHIPPED_FILE).is_file():
        from feeder.learn.structured_shipped import ShippedStructured

        structured = ShippedStructured.load(folder / SHIPPED_FILE)
    return Library(**arrays, card=card, structured=structured)


# ----------------------------------------------------------------------------------------------
# The predictor
# ----------------------------------------------------------------------------------------------
class StudyModel(AnalyticModel):
    """The study's labels where it has the part (module doc), the analytic push PMF elsewhere, over
    ``bins`` yaw bins in the part's own frame. :meth:`bind` tells it the part and the rows'
    configurations before :meth:`predict`."""

    def __init__(self, bins: int, sigma: float, scene: dict, library: Library):
        super().__init__(bins)
        self.spec = AnalyticSpec(STUDY_MODEL, int(bins))
        self.sigma = float(sigma)
        self.library = library
        self.scene = scene
        self.same_scene = scene_digest(scene) == library.card["scene_sha256"]
        shipped = library.structured
        self.structured = shipped if shipped is not None and shipped.serves(bins, sigma, scene_digest(scene)) else None
        self.answers: list[tuple[str, int, float]] | None = None  # per row: (source, library row, distance)
        self.known: str | None = None  # the bound part's id in the library
        self.part_path: Path | None = None
        self.config_ids: list[str] = []
        self._structured_pmf: dict[int, np.ndarray] | None = None  # per structured row: its PMF (part frame)
        self.progress = None  # called with a message during a long structured answer (feeder recommend)

    @property
    def gate_deg(self) -> float:
        return float(self.library.card["gate_deg"])

    def bind(self, part: Path | None, config_ids) -> str:
        """Decide each configuration's answer for ``part`` (an STL; None: features only, the analytic
        PMF throughout); returns one line saying what the study knows of the part."""
        lib = self.library
        known = None if part is None or not self.same_scene else lib.part_of(file_digest(part))
        self.answers, self.known, self.part_path, self._structured_pmf = [], known, part, None
        self.config_ids = [str(c) for c in config_ids]
        if known is None:
            self.answers = [(ANALYTIC, -1, float("inf"))] * len(config_ids)
            if part is not None and not self.same_scene:
                return "the study's labels are of another scene: the analytic push PMF"
            return "a part the study has not simulated: the analytic push PMF"
        rows = np.flatnonzero(lib.part == known)
        by_id = {str(lib.config_id[i]): int(i) for i in rows}
        pool = [int(i) for i in rows if lib.kept[i]]
        pool_ids = [str(lib.config_id[i]) for i in pool]
        structured = self.structured is not None and self.structured.knows(known)
        # the structured predictor also reads each one-fence label at the other location (model.mirror_labels)
        mirrored = self.structured.mirrored_ids(known, pool_ids) if structured else []
        read_ids, read_rows = pool_ids + [c for c, _ in mirrored], pool + [pool[n] for _, n in mirrored]
        for cid in config_ids:
            if cid in by_id:
                self.answers.append((SIMULATED, by_id[cid], 0.0))
                continue
            if structured and self.structured.has_neighbour(cid, read_ids):
                k, dist = nearest_configuration(cid, read_ids)
                self.answers.append((STRUCTURED, read_rows[k] if k >= 0 else -1, dist))
                continue
            k, dist = nearest_configuration(cid, pool_ids)
            if k >= 0 and dist <= self.gate_deg:
                self.answers.append((NEIGHBOUR, pool[k], dist))
            else:
                self.answers.append((ANALYTIC, -1, dist))
        return f"part {known} of the study ({rows.size} simulated configurations)"

    def describe(self, row: int = 0) -> str:
        """How row ``row`` was answered, for a person."""
        source, i, dist = self._answers()[row]
        if source == SIMULATED:
            return f"the study's simulated label of {self.library.config_id[i]}{self._label_error(i)}"
        if source == STRUCTURED:
            label = str(self.library.config_id[i]) if i >= 0 else ""
            if i >= 0 and fence_key(label)[0] != fence_key(self.config_ids[row])[0]:  # model.mirror_labels
                label = f"{label} read at the other location (the part's mirror image)"
            near = (
                f"; nearest simulated angle of its fence types {label}, {dist:g} deg away"
                if i >= 0
                else "; none of its fence types, only of its downstream fence"
                + ("; its Fences specialist answers" if "specialist" in self.structured.networks else "")
            )
            return (
                f"the structured predictor from the part's labelled configurations{near} (docs/structured.md)"
                f"{self._structured_error(dist)}"
            )
        if source == NEIGHBOUR:
            return (
                f"the study's label of the nearest simulated angle {self.library.config_id[i]} "
                f"({dist:g} deg away, gate {self.gate_deg:g})"
            )
        if np.isfinite(dist):
            return (
                f"the analytic push PMF (the nearest simulated angle is {dist:g} deg away, gate {self.gate_deg:g})"
                f"{self._analytic_error(row)}"
            )
        return f"the analytic push PMF{self._analytic_error(row)}"

    def _analytic_error(self, row: int) -> str:
        """``; ...`` with how far the analytic PMF lay from the study's labels in row ``row``'s kind of
        scene (:func:`analytic_by_scene`), or '' without that table, in another scene or for a kind
        the study has no label of."""
        k = self._analytic_kind(row)
        if k is None:
            return ""
        return (
            f"; on the study's {k['configurations']} labelled configurations of this kind ({k['scene']}) it lay "
            f"circular W1 {k['mean_circular_w1_deg']:.1f} deg from the simulator on average (median "
            f"{k['median_circular_w1_deg']:.1f}, 90th percentile {k['p90_circular_w1_deg']:.1f}); "
            "--simulate BUDGET asks the simulator"
        )

    def _structured_error(self, dist: float) -> str:
        """``; ...`` with the structured predictor's error on the protocol's scored rows whose nearest
        label of the same fence types lay as far (the card's :func:`structured_error_bins`), or ''."""
        b = error_bin((self.library.card.get("structured") or {}).get("by_distance") or [], dist)
        if b is None:
            return ""
        where = (
            "with no label of their fence types"
            if np.isinf(_bound(b["low_deg"]))
            else (f"whose nearest label of their fence types lay {distance_words(b)}")
        )
        return (
            f"; on the protocol's {b['rows']} held-out rows {where} it lay circular W1 "
            f"{b['mean_circular_w1_deg']:.1f} deg from the simulator on average (median "
            f"{b['median_circular_w1_deg']:.1f}, 90th percentile {b['p90_circular_w1_deg']:.1f}); "
            "--simulate BUDGET asks the simulator"
        )

    def _analytic_kind(self, row: int) -> dict | None:
        """The card's row of :func:`analytic_by_scene` for row ``row``'s kind of scene, or None
        without that table, in another scene or for a kind the study has no label of."""
        scenes = self.library.card.get("analytic_scenes")
        if not scenes or not self.same_scene or row >= len(self.config_ids):
            return None
        kind = scene_kind(self.config_ids[row], scenes["steep_deg"])
        hit = [k for k in scenes["kinds"] if k["scene"] == kind]
        return hit[0] if hit else None

    def analytic_error_deg(self) -> np.ndarray:
        """Per bound configuration answered by the analytic PMF, the mean circular W1 (degrees) it
        lay from the study's labels in that kind of scene (:func:`analytic_by_scene`); NaN for the
        other answers and where the card has no such row."""
        out = np.full(len(self._answers()), np.nan)
        for row, (source, _, _) in enumerate(self._answers()):
            k = self._analytic_kind(row) if source == ANALYTIC else None
            if k is not None:
                out[row] = float(k["mean_circular_w1_deg"])
        return out

    def structured_error_deg(self) -> np.ndarray:
        """Per bound configuration answered by the structured predictor, the mean circular W1
        (degrees) of the protocol's held-out rows whose nearest label of their fence types lay as far
        (the card's :func:`structured_error_bins`); NaN for the other answers and where the card has
        no such bin."""
        bins = (self.library.card.get("structured") or {}).get("by_distance") or []
        out = np.full(len(self._answers()), np.nan)
        for row, (source, _, dist) in enumerate(self._answers()):
            b = error_bin(bins, dist) if source == STRUCTURED else None
            if b is not None:
                out[row] = float(b["mean_circular_w1_deg"])
        return out

    def label_error_deg(self) -> np.ndarray:
        """Per bound configuration answered by the study's own simulated label, its audit's upper
        estimate of that label's circular W1 from the simulator's exact label (degrees, ``feeder
        audit``); NaN for the other answers and for labels the study did not audit."""
        w1 = self.library.est_circular_w1_deg
        out = np.full(len(self._answers()), np.nan)
        for row, (source, i, _) in enumerate(self._answers()):
            if source == SIMULATED and self._label_error(i):  # the estimate describe() quotes
                out[row] = float(w1[i])
        return out

    def _label_error(self, i: int) -> str:
        """``; ...`` with library row ``i``'s audit estimate, or '' without one."""
        w1, sup = self.library.est_circular_w1_deg, self.library.est_sup_cdf
        if w1 is None or sup is None or not (np.isfinite(w1[i]) and np.isfinite(sup[i])):
            return ""
        return (
            f"; its audit puts it within circular W1 {w1[i]:.1f} deg and sup|dCDF| {sup[i]:.3f} of the simulator's "
            "exact label (upper estimates, feeder audit)"
        )

    def sources(self) -> list[str]:
        return [a[0] for a in self._answers()]

    def _answers(self):
        if self.answers is None:
            raise FeederError("the study's predictor needs bind(part, configurations) before it answers")
        return self.answers

    def _label(self, i: int, frame_deg: float = 0.0):
        """(PMF or None, ok mass) of library row ``i``, labelled as the workflow labels it, its yaws
        turned by ``frame_deg`` (the label frame of a ``principal``-frame study)."""
        from feeder.labels.dataset import label_yaws
        from feeder.labels.pmf import sim_label

        rec = self.library.record(i)
        if not rec.ok.any():
            return None, 0.0
        if frame_deg:
            rec.yaws = label_yaws(rec.yaws, "principal", float(frame_deg))
        label = sim_label(rec, self.spec.bins, self.sigma)
        return label.pmf, float(label.ok_mass)

    def _structured(self) -> dict[int, np.ndarray]:
        """The structured predictor's PMF (part frame) of every row :meth:`bind` gave it, computed
        once per binding (:meth:`feeder.learn.structured_shipped.ShippedStructured.answer`)."""
        if self._structured_pmf is not None:
            return self._structured_pmf
        rows = [r for r, a in enumerate(self._answers()) if a[0] == STRUCTURED]
        self._structured_pmf = {}
        if not rows:
            return self._structured_pmf
        from feeder.labels.metrics import shift_pmf
        from feeder.mechanics.hull import push_geometry
        from feeder.parts.geometry import load_profile

        lib, shipped = self.library, self.structured
        frame = shipped.frame_of(self.known)
        pool = [int(i) for i in np.flatnonzero(lib.part == self.known) if lib.kept[i]]
        labels = [self._label(i, frame) for i in pool]
        maps = self._one_fence_maps(pool) if shipped.composes else None
        outline, holes, _ = load_profile(self.part_path, shipped.units)
        pmf = shipped.answer(
            push_geometry(outline, holes),
            self.known,
            [self.config_ids[r] for r in rows],
            [str(lib.config_id[i]) for i in pool],
            [p for p, _ in labels],
            [ok for _, ok in labels],
            self.scene,
            self.progress,
            maps,
        )
        pmf = shift_pmf(pmf, -frame) if frame else pmf
        self._structured_pmf = dict(zip(rows, pmf, strict=True))
        return self._structured_pmf

    def _one_fence_maps(self, pool: list[int]) -> dict:
        """The sampled drop maps (part frame) of the one-fence configurations among library rows
        ``pool``, by their index in ``pool`` (what the structured predictor composes); a row of a
        design that samples no map (random drops) has none."""
        from feeder.labels.pmf import MAP_DESIGNS, record_design
        from feeder.learn.structured_data import fence_alone

        maps = {}
        for k, i in enumerate(pool):
            if fence_alone(str(self.library.config_id[i])) is not None:
                rec = self.library.record(i)
                if rec.design in MAP_DESIGNS:
                    maps[k] = record_design(rec)
        return maps

    def predict(self, part_raw, feeder_raw, push_raw=None, analytic=None) -> tuple[np.ndarray, np.ndarray]:
        """(pmf, cdf) of each row: the study's label where :meth:`bind` found one, else the analytic
        PMF. A simulated configuration in which no drop left the fences has no PMF: a row of zeros
        (its ok mass is 0; ``feeder predict`` says so)."""
        answers = self._answers()
        pmf, _ = super().predict(part_raw, feeder_raw, push_raw, analytic)
        if len(answers) != pmf.shape[0]:
            raise FeederError(f"the study's predictor was bound to {len(answers)} configurations, asked {pmf.shape[0]}")
        for r, (source, i, _) in enumerate(answers):
            if source == STRUCTURED:
                pmf[r] = self._structured()[r]
            elif source != ANALYTIC:
                label, _ = self._label(i)
                pmf[r] = 0.0 if label is None else label
        return pmf, np.cumsum(pmf, axis=1)

    def ok_mass(self, push_raw) -> np.ndarray:
        """The share of drops that leave without jamming: simulated where the row's answer is a label,
        analytic elsewhere (the structured predictor's ok head ties with the analytic ok mass on every
        set of results/tables/structured_protocol.csv, so it is not shipped)."""
        ok = np.array(super().ok_mass(push_raw), dtype=np.float64)
        for r, (source, i, _) in enumerate(self._answers()):
            if source in (SIMULATED, NEIGHBOUR):
                ok[r] = self._label(i)[1]
        return ok


def is_study(model_arg) -> bool:
    """Whether ``--model`` names the study's predictor: ``study``, or no ``--model`` unless
    ``$FEEDER_MODEL_DIR`` names a model folder to use instead (:func:`feeder.learn.export.shipped_model_dir`)."""
    import os

    from feeder.learn.export import MODEL_DIR_ENV

    if model_arg is None:
        return not os.environ.get(MODEL_DIR_ENV)
    return str(model_arg) == STUDY_MODEL


def study_model(study: dict, folder: Path | None = None) -> StudyModel:
    """The study's predictor over the study config's ``labels`` and ``scene``."""
    from feeder.mechanics.fence import default_scene

    scene = study.get("scene") or default_scene()
    return StudyModel(int(study["labels"]["bins"]), float(study["labels"]["sigma_bins"]), scene, load_library(folder))


# ----------------------------------------------------------------------------------------------
# feeder export-study
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder export-study", description=__doc__.split("\n\n")[0])
    parser.add_argument("--configurations", type=Path, required=True, help="results/datasets/configurations.csv")
    parser.add_argument("--sim-dir", type=Path, required=True, help="results/sim")
    parser.add_argument("--parts-dir", type=Path, required=True, help="the parts' STLs (parts)")
    parser.add_argument("--dataset", type=Path, required=True, help="results/datasets/dataset.npz")
    parser.add_argument("--neighbour-table", type=Path, required=True, help="results/tables/neighbour.csv")
    parser.add_argument("--out", type=Path, required=True, help="the folder to write (models/study; replaced)")
    parser.add_argument(
        "--structured", type=Path, help="the shipped structured predictor (feeder fit-structured) to answer new angles"
    )
    parser.add_argument(
        "--structured-table", type=Path, help="results/tables/structured_protocol.csv: its evidence, quoted by the card"
    )
    parser.add_argument(
        "--structured-errors",
        type=Path,
        help="results/tables/structured_by_distance.csv: its error by neighbour distance, quoted and printed",
    )
    parser.add_argument(
        "--label-errors",
        type=Path,
        help="results/tables/label_error_estimate.csv: each label's error estimate, printed with it",
    )
    parser.add_argument(
        "overrides", nargs="*", help="Hydra overrides of config/hydra/structured.yaml (the gates: neighbour.gates_deg)"
    )
    args = parser.parse_args(argv)
    from feeder.config import compose_config

    settings = compose_config("structured", args.overrides)
    gates = check_gates(settings["neighbour"]["gates_deg"])
    steep_deg = check_steep_deg(settings["analytic_scenes"]["steep_deg"])
    for given in ("structured_table", "structured_errors"):
        if getattr(args, given) is not None and args.structured is None:
            raise FeederError(f"--{given.replace('_', '-')} is the evidence of --structured: give both")
    for path in (
        args.configurations,
        args.dataset,
        args.neighbour_table,
        args.structured,
        args.structured_table,
        args.structured_errors,
        args.label_errors,
    ):
        if path is not None and not path.is_file():
            raise FeederError(f"{path} is missing")
    configurations = pd.read_csv(args.configurations)
    missing = {"part", "config_id"} - set(configurations.columns)
    if missing:
        raise FeederError(f"{args.configurations}: no column {', '.join(sorted(missing))} (a configuration table)")
    card = export_study(
        configurations,
        args.sim_dir,
        args.parts_dir,
        args.dataset,
        args.neighbour_table,
        gates,
        args.out,
        args.structured,
        args.structured_table,
        args.label_errors,
        steep_deg,
        args.structured_errors,
    )
    print(
        f"feeder export-study: {card['configurations']} configurations of {card['parts']} parts, "
        f"gate {card['gate_deg']:g} deg -> {args.out}",
        file=sys.stderr,
    )
    return 0
