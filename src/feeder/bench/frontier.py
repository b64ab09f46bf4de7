"""What an answer costs and how close it is: predictors against the simulator (``feeder bench-frontier``).

Issue #39 item 4. On the design bench's configurations (``results/bench/designs/<preset>-<yaws>/
reference``: a dense map of initial to final yaw each, 2,880 drops a turn), every way of answering
"what orientations does this part leave the fences with?" is scored against the label of the
dense map by circular W1 (and sup|ΔCDF|), beside what one answer costs in CPU seconds:

* the predictors, each timed in this process over ``repeats`` calls (the part's features or its
  push PMF, then the model; a fresh process adds its start-up, about 0.4 s, measured by
  ``feeder bench-predict``): the analytic push PMF and the shipped models (``models.export_dir``)
  named in ``sim.frontier_bench.models``; with ``--dataset``, the mean training PMF too (cost: a lookup);
* ``feeder simulate`` at each budget of ``sim.frontier_bench.budgets``: the study's adaptive design
  emulated through the dense map (:func:`feeder.bench.designs.emulated_adaptive`, seeded repeats
  as the design bench has them), below ``sim.adaptive.n0`` an evenly spaced grid of that many drops
  with no refinement; its cost is the budget times the reference's measured CPU per drop.

The labels of the map and of every answer are in the part's own frame, over ``labels.bins`` bins
smoothed as the study's. A configuration whose dense map leaves less ok mass than
``sim.min_ok_mass`` is left out, as the study leaves it out of its labels. The configurations mix
library parts that the networks trained on (crescent-a, lshape-a, ...) with generated shapes no
model has seen: ``seen_by_models`` says which. Writes one row per configuration and answer
(``--out-raw``; a new statistic needs no rerun) and a summary per answer: mean circular W1 with a
95 % bootstrap interval over configurations, and mean CPU seconds (the figure:
``feeder figure frontier``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feeder.errors import FeederError

ANALYTIC = "analytic"
MEAN_PMF = "mean_pmf"


def check_frontier(settings: dict) -> dict:
    """``sim.frontier_bench`` checked: budgets (integers >= 2), models, repeats, resamples, seed."""
    try:
        fb = settings["sim"]["frontier_bench"]
        budgets = [int(b) for b in fb["budgets"]]
        models, repeats, seed = [str(m) for m in fb["models"]], int(fb["repeats"]), int(fb["seed"])
        resamples = int(fb["resamples"])
    except (KeyError, TypeError, ValueError) as err:
        raise FeederError(f"--settings lacks or mistypes sim.frontier_bench: {err}") from None
    if not budgets or min(budgets) < 2:
        raise FeederError(f"sim.frontier_bench.budgets: simulation budgets of at least 2 drops (got {budgets})")
    if repeats < 1 or resamples < 1:
        raise FeederError(f"sim.frontier_bench: repeats and resamples must be at least 1 (got {repeats}, {resamples})")
    return {"budgets": budgets, "models": models, "repeats": repeats, "seed": seed, "resamples": resamples}


def budget_design(adaptive: dict, budget: int) -> dict:
    """The adaptive settings for ``budget`` simulations: below ``n0`` an evenly spaced grid of
    ``budget`` drops and no refinement (pure)."""
    return dict(adaptive, n0=min(int(adaptive["n0"]), int(budget)))


def bootstrap_mean(values, resamples: int, seed: int, level: float = 0.95) -> tuple[float, float, float]:
    """(mean, low, high) of ``values`` with a percentile bootstrap interval (pure, seeded)."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, size=(resamples, x.size))].mean(axis=1)
    tail = 100.0 * (1.0 - level) / 2.0
    return float(x.mean()), float(np.percentile(means, tail)), float(np.percentile(means, 100.0 - tail))


def _part_file(entry: dict, settings: dict, tmp: Path) -> Path:
    """The part's STL: the library's file, or a generated shape written to ``tmp``."""
    if entry["kind"] != "shape":
        return Path(settings["parts"]["dir"]) / f"{entry['part']}.stl"
    from feeder.bench.reference import entry_geometry
    from feeder.parts.geometry import stl_bytes

    geom = entry_geometry(entry, settings)
    path = tmp / f"{entry['part']}.stl"
    path.write_bytes(stl_bytes(np.asarray(geom.outline), float(geom.thickness), entry["part"], geom.holes))
    return path


def predictor_answers(entry: dict, part: Path, models: dict, study: dict, repeats: int) -> dict[str, tuple]:
    """``{name: (pmf in the part's frame, seconds per answer)}`` of every predictor in ``models``
    (name -> loaded model), each timed over ``repeats`` calls."""
    from feeder.learn.predict import part_vector, predict_frame, push_inputs

    out = {}
    for name, model in models.items():
        times, pmf = [], None
        for _ in range(repeats):
            t0 = time.process_time()
            part_raw, frame_deg = part_vector(part, None, scene=study["scene"])
            push_raw, analytic = push_inputs(model, part, [(entry["loc1"], entry["loc2"])], frame_deg, study)
            frame = predict_frame(model, part_raw, entry["loc1"], entry["loc2"], frame_deg, push_raw, analytic)
            times.append(time.process_time() - t0)
            pmf = frame["pmf"].to_numpy()
        out[name] = (pmf, float(np.median(times)))
    return out


def mean_pmf(dataset: Path, bins: int) -> np.ndarray:
    """The mean training PMF of a dataset (its ``train`` split), in the labels' frame."""
    from feeder.labels.dataset import load_dataset

    data = load_dataset(dataset)
    split = np.asarray(data["split"]).astype(str)
    pmf = np.asarray(data["pmf"], np.float64)[split == "train"]
    if pmf.size == 0 or pmf.shape[1] != bins:
        raise FeederError(f"--dataset {dataset}: no training PMF over {bins} bins")
    m = pmf.mean(axis=0)
    return m / m.sum()


def entry_rows(reference: Path, settings: dict, frontier: dict, models: dict, mean: np.ndarray | None) -> list[dict]:
    """Every answer's rows for one configuration (module docstring)."""
    from feeder.bench.designs import _load, distances, emulated_adaptive, reference_design
    from feeder.bench.reference import seed_of
    from feeder.sim.pushforward import pushforward_pmf

    labels, adaptive = settings["labels"], settings["sim"]["adaptive"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    z = _load(reference)
    meta = json.loads(str(z["meta"]))
    entry = meta["entry"]
    if not (z["ref_status"] == "ok").any():
        return []  # every drop jams: no label to score against
    ref = reference_design(z, float(adaptive["tolerance_deg"]))
    ref_pmf, masses = pushforward_pmf(ref, bins, sigma)
    if float(masses["ok"]) < float(settings["sim"]["min_ok_mass"]):
        return []  # the study labels no configuration that jams this often (labels.on_bad), nor scores one
    cpu_per_drop = float(z["ref_cpu_s"]) / int(z["ref_initial"].size)
    base = {"config": entry["key"], "part": entry["part"], "seen_by_models": entry["kind"] != "shape"}
    rows = []
    with tempfile.TemporaryDirectory(prefix="feeder-frontier-") as tmp:
        part = _part_file(entry, settings, Path(tmp))
        for name, (pmf, seconds) in predictor_answers(entry, part, models, settings, frontier["repeats"]).items():
            rows.append(
                {**base, "answer": name, "kind": "predictor", "budget": 0, "repeat": 0, "cpu_s": seconds}
                | distances(pmf, ref_pmf)
            )
        if mean is not None:  # the dataset's labels are in labels.frame; the reference in the part's own
            from feeder.labels import metrics as L
            from feeder.learn.predict import part_vector

            shifted = mean
            if str(labels.get("frame", "part")) == "principal":
                shifted = L.shift_pmf(mean[None, :], -float(part_vector(part, None)[1]))[0]
            rows.append(
                {**base, "answer": MEAN_PMF, "kind": "predictor", "budget": 0, "repeat": 0, "cpu_s": 0.0}
                | distances(shifted, ref_pmf)
            )
    order = round(360.0 / float(meta["period_deg"]))
    for budget in frontier["budgets"]:
        for r in range(frontier["repeats"]):
            seed = seed_of(entry["key"], "frontier", budget, r, frontier["seed"])
            label = emulated_adaptive(ref, order, budget, seed, budget_design(adaptive, budget), bins, sigma)
            sims = budget if label is None else label.simulations
            scores = {"sup_cdf": 1.0, "w1_deg": 360.0, "circular_w1_deg": 180.0, "js": 1.0}
            if label is not None:
                scores = distances(label.pmf, ref_pmf)
            rows.append(
                {
                    **base,
                    "answer": f"simulate{budget}",
                    "kind": "simulate",
                    "budget": budget,
                    "repeat": r,
                    "cpu_s": cpu_per_drop * sims,
                }
                | scores
            )
    return rows


def summary(raw: pd.DataFrame, resamples: int, seed: int) -> pd.DataFrame:
    """Per answer: configurations, mean CPU seconds, mean circular W1 and sup|ΔCDF| with 95 %
    bootstrap intervals over configurations (each configuration's repeats averaged first), all
    configurations and the generated shapes alone (``unseen``)."""
    rows = []
    for subset, frame in (("all", raw), ("unseen", raw[~raw["seen_by_models"].astype(bool)])):
        per_config = frame.groupby(["answer", "kind", "budget", "config"], as_index=False)[
            ["cpu_s", "circular_w1_deg", "sup_cdf"]
        ].mean()
        for (answer, kind, budget), g in per_config.groupby(["answer", "kind", "budget"], sort=False):
            w1 = bootstrap_mean(g["circular_w1_deg"], resamples, seed)
            sup = bootstrap_mean(g["sup_cdf"], resamples, seed)
            rows.append(
                {
                    "configurations": subset,
                    "answer": answer,
                    "kind": kind,
                    "budget": int(budget),
                    "n": len(g),
                    "cpu_s_mean": float(g["cpu_s"].mean()),
                    "circular_w1_deg": w1[0],
                    "circular_w1_low": w1[1],
                    "circular_w1_high": w1[2],
                    "sup_cdf": sup[0],
                    "sup_cdf_low": sup[1],
                    "sup_cdf_high": sup[2],
                }
            )
    return pd.DataFrame(rows).sort_values(["configurations", "cpu_s_mean"], ignore_index=True)


def load_models(names, bins: int, export_dir: str) -> dict:
    """``{name: model}``: ``analytic``, or a shipped model's folder ``<export_dir>/<name>`` of the
    project (:func:`feeder.config.project_path`)."""
    from feeder.config import project_path
    from feeder.learn.analytic import AnalyticModel
    from feeder.learn.predict import load_model

    out = {}
    for name in names:
        if name == ANALYTIC:
            out[name] = AnalyticModel(bins)
            continue
        path = project_path(Path(export_dir) / name)
        if not path.is_dir():
            raise FeederError(f"--models: {name} is not a shipped model folder ({path})")
        out[name] = load_model(path)
    return out


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-frontier", description=__doc__.splitlines()[0])
    parser.add_argument("--settings", required=True, help="JSON {scene, sim, labels, parts} config sections")
    parser.add_argument(
        "--references", nargs="+", required=True, type=Path, help="the design bench's dense maps (.npz)"
    )
    parser.add_argument("--dataset", type=Path, default=None, help="dataset.npz: adds the mean training PMF")
    parser.add_argument(
        "--models",
        nargs="+",
        default=None,
        help="analytic and/or shipped model names in models.export_dir (default: sim.frontier_bench.models)",
    )
    parser.add_argument("--out-raw", required=True, type=Path, help="one row per configuration and answer (CSV)")
    parser.add_argument("--out-csv", required=True, type=Path, help="the summary per answer (CSV)")
    args = parser.parse_args(argv)
    from feeder.config import parse_settings
    from feeder.io import write_csv

    settings = parse_settings(args.settings, "scene", "sim", "labels", "parts", "models")
    frontier = check_frontier(settings)
    missing = [str(p) for p in args.references if not p.is_file()]
    if missing:
        raise FeederError(f"--references: missing {', '.join(missing)}")
    bins = int(settings["labels"]["bins"])
    names = frontier["models"] if args.models is None else args.models
    models = load_models(names, bins, str(settings["models"]["export_dir"]))
    mean = None if args.dataset is None else mean_pmf(args.dataset, bins)
    rows = []
    for k, ref in enumerate(sorted(args.references), 1):
        rows += entry_rows(ref, settings, frontier, models, mean)
        print(f"feeder bench-frontier: {k}/{len(args.references)} {ref.stem}", file=sys.stderr)
    raw = pd.DataFrame(rows)
    table = summary(raw, frontier["resamples"], frontier["seed"])
    write_csv(args.out_raw, raw)
    write_csv(args.out_csv, table)
    return 0
