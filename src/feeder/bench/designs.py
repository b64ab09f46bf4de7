"""What a label costs under each initial-yaw design, against a dense reference (``feeder bench-designs``).

With one part per world a drop's outcome is a function of its initial yaw, so a configuration's
label is the push-forward of the uniform initial yaw through that map. This bench measures how
close each design gets to it, and at what cost:

* ``feeder bench-reference run`` (:mod:`feeder.bench.reference`), one job per configuration: the
  **reference**, an evenly spaced grid of ``reference_yaws`` initial yaws per full turn (0.125°
  apart at 2,880) over one period of the part's rotational symmetry, whose label is the
  push-forward of the sampled map (the grid rule of :func:`feeder.labels.pmf.record_design`),
  and ``paired_drops`` independent drops simulated for real;
* ``feeder bench-designs run``, one job per configuration: the **adaptive** design, simulated for
  real at each budget of ``adaptive_budgets`` (a change to the refinement reruns only these);
* ``feeder bench-designs table``: every design's label against the reference label, and a
  **paired check** of the reference map: the real paired drops against what the map gives at the
  same initial yaws (same-status and same-basin fractions, median |Δ final yaw|), which says how
  well the sampled map stands in for the simulator between its samples:
  - ``adaptive`` from its real runs (one realisation: the offset of seed ``design_bench.seed``);
  - ``adaptive_emulated``: the same refinement (the real runs' settings) at each budget and at
    the study's own (``sim.drops``, when ``sim.yaw_sampling`` is adaptive), ``repeats`` seeded
    offsets, each simulation replaced by the reference map (:func:`emulated_adaptive`), so the
    adaptive design gets an interval like the others; the real run says whether the emulation is
    faithful;
  - ``random``, ``golden`` and ``grid`` at each of ``drop_levels`` drops, ``repeats`` seeded
    realisations each, **emulated** through the reference map (the drops a design would simulate,
    mapped by :func:`feeder.sim.pushforward.map_yaws`). The paired check says how exact that is.
  Columns per configuration and design: simulations, CPU seconds (real for the reference and the
  adaptive design; for emulated designs, drops × the reference's CPU per drop), sup|ΔCDF|, W1 on
  the CDF, circular W1 (:func:`feeder.labels.metrics.circular_w1`), JS (bits) and the label's
  own bound. Rows ``config == "mean"`` average over configurations, with a 95 % t-interval of the mean over the
  emulated realisations.

Raw data stay in the per-configuration files (docs/data.md), so a new statistic needs no rerun.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

EMULATED_DESIGNS = ("random", "golden", "grid")
SAME_BASIN_DEG = 5.0  # |Δ final yaw| on the circle below which two ok drops ended in one basin


# ----------------------------------------------------------------------------------------------
# The adaptive runs of one configuration (simulation)
# ----------------------------------------------------------------------------------------------
def run_adaptive(entry: dict, settings: dict) -> dict:
    """The adaptive design at every budget of ``adaptive_budgets``, simulated for real: the arrays
    of the configuration's adaptive file (one ``adaptive<budget>_*`` group each, and ``meta``)."""
    from feeder.bench.reference import entry_geometry
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import get_preset
    from feeder.sim.simulate import simulate

    db, scene = settings["sim"]["design_bench"], settings["scene"]
    preset = get_preset(settings["sim"]["presets"], db["preset"])
    geom = entry_geometry(entry, settings)
    loc1, loc2 = parse_location(entry["loc1"]), parse_location(entry["loc2"])
    out, budgets = {}, []
    for budget in db["adaptive_budgets"]:
        res = simulate(
            geom,
            loc1,
            loc2,
            int(budget),
            int(db["seed"]),
            scene,
            preset,
            db["preset"],
            yaw_sampling="adaptive",
            adaptive=dict(settings["sim"]["adaptive"]),
        )
        tag = f"adaptive{int(budget)}"
        out |= {
            f"{tag}_initial": res["initial_yaw_deg"],
            f"{tag}_final": res["final_yaw_deg"],
            f"{tag}_status": res["status"],
            f"{tag}_cpu_s": res["cpu_s"],
        }
        budgets.append({"budget": int(budget), "design": json.loads(str(res["meta"]))["design"]})
    meta = {"entry": entry, "preset": db["preset"], "budgets": budgets, "adaptive": settings["sim"]["adaptive"]}
    return out | {"meta": np.array(json.dumps(meta, sort_keys=True))}


# ----------------------------------------------------------------------------------------------
# The table (pure: reads the per-configuration files)
# ----------------------------------------------------------------------------------------------
def reference_design(z, tolerance_deg: float):
    from feeder.sim.adaptive import design_from_samples

    meta = json.loads(str(z["meta"]))
    spacing = meta["period_deg"] / z["ref_initial"].size
    return design_from_samples(
        z["ref_initial"],
        z["ref_final"],
        z["ref_status"],
        period_deg=meta["period_deg"],
        offset_deg=meta["offset_deg"],
        tolerance_deg=tolerance_deg,
        min_width_deg=spacing,
        max_width_deg=spacing,
        band_gap_deg=0.0,
        edge_check_deg=0.0,
    )


def distances(pmf, ref_pmf) -> dict[str, float]:
    """sup|ΔCDF|, W1 and circular W1 on the CDF (degrees), JS (bits) of a label against the reference."""
    from feeder.labels import metrics as L

    a, b = L.cdf(pmf), L.cdf(ref_pmf)
    return {
        "sup_cdf": float(L.ks(a, b)),
        "w1_deg": float(L.w1(a, b)),
        "circular_w1_deg": float(L.circular_w1(a, b)),
        "js": float(L.js_divergence(pmf, ref_pmf)),
    }


def paired_basins(final_a, status_a, final_b, status_b, tolerance_deg: float = SAME_BASIN_DEG) -> dict:
    """Two runs of the same drops compared drop by drop (drop ``i`` of both started from the same
    initial yaw): final yaws in degrees (any turn; NaN for a drop that is not ok) and statuses.

    A pair is in the *same basin* when both drops are ``ok`` and their circular |Δ final yaw| is
    below ``tolerance_deg``, or when both ended with the same non-ok status. Returns ``n`` (pairs),
    ``same_status`` and ``same_basin`` (fractions of the pairs; NaN without pairs), and the median
    and the largest circular |Δ final yaw| over the same-basin ok pairs (``median_dyaw_deg``,
    ``max_dyaw_deg``; NaN when there is none), and the median of the signed difference ``a - b``
    over the same pairs, in [-180, 180) (``median_signed_dyaw_deg``): a small systematic turn of
    every drop, which barely moves the median |Δ| above the floor, shows there. Pooled
    distributions hide a drop that flips basin while another flips back; this counts it."""
    from feeder.circular import wrap180

    final_a, final_b = np.asarray(final_a, dtype=np.float64), np.asarray(final_b, dtype=np.float64)
    status_a, status_b = np.asarray(status_a).astype(str), np.asarray(status_b).astype(str)
    n = final_a.size
    if not (final_a.shape == final_b.shape == status_a.shape == status_b.shape == (n,)):
        raise FeederError(
            f"paired runs differ in shape: final {final_a.shape} vs {final_b.shape}, "
            f"status {status_a.shape} vs {status_b.shape}"
        )
    same_status = status_a == status_b
    both_ok = same_status & (status_a == "ok")
    signed = wrap180(final_a[both_ok] - final_b[both_ok])
    d = np.abs(signed)
    close = d < float(tolerance_deg)  # NaN (an ok drop without a yaw) is never close
    same_basin = same_status.copy()
    same_basin[both_ok] = close
    return {
        "n": int(n),
        "same_status": float(same_status.mean()) if n else math.nan,
        "same_basin": float(same_basin.mean()) if n else math.nan,
        "median_dyaw_deg": float(np.median(d[close])) if close.any() else math.nan,
        "max_dyaw_deg": float(np.max(d[close])) if close.any() else math.nan,
        "median_signed_dyaw_deg": float(np.median(signed[close])) if close.any() else math.nan,
    }


def paired_check(z, ref_design) -> dict[str, float]:
    """The reference map against the real drops of the reference file at the same initial yaws:
    same-status and same-basin fractions, median |Δ final yaw| among same-basin drops
    (:func:`paired_basins`)."""
    from feeder.sim.pushforward import map_yaws

    mapped_final, mapped_status = map_yaws(ref_design, z["paired_initial"])
    check = paired_basins(z["paired_final"], z["paired_status"], mapped_final, mapped_status)
    return {
        "paired_same_status": check["same_status"],
        "paired_same_basin": check["same_basin"],
        "paired_median_dyaw_deg": check["median_dyaw_deg"],
    }


def emulated_label(ref_design, design: str, drops: int, seed: int, bins: int, sigma: float):
    """The label ``design`` would give with ``drops`` drops (seeded), its drops mapped through the
    reference; None when every drop fails."""
    from feeder.labels.pmf import sim_label
    from feeder.sim.drops import initial_yaws
    from feeder.sim.pushforward import map_yaws
    from feeder.sim.record import SimRecord

    beta = initial_yaws(seed, drops, design)
    final, status = map_yaws(ref_design, beta)
    if not (status == "ok").any():
        return None  # every drop failed: the design gives no label
    rec = SimRecord(yaws=final, ok=status == "ok", meta={"yaw_sampling": design}, initial=beta, status=status)
    return sim_label(rec, bins, sigma)


def emulated_adaptive(ref_design, order: int, budget: int, seed: int, adaptive: dict, bins: int, sigma: float):
    """The label the adaptive design (``sim.adaptive``, at most ``budget`` simulations, offset from
    ``seed``) would give if the reference map were the simulator: the same refinement as a real
    run (:func:`feeder.sim.simulate.run_design`), each simulation replaced by the reference map at
    that initial yaw (:func:`feeder.sim.pushforward.map_yaws`). None when every sample failed."""
    from feeder.labels.pmf import Label
    from feeder.sim.pushforward import label_cdf_bound, map_yaws, pushforward_pmf
    from feeder.sim.simulate import run_design

    design = run_design(lambda yaws: map_yaws(ref_design, yaws), seed, budget, adaptive, order)
    if not (design.status == "ok").any():
        return None
    pmf, masses = pushforward_pmf(design, bins, sigma)
    return Label(pmf, masses, label_cdf_bound(design, masses["ok"]), "adaptive", int(design.evaluations))


# a label that does not exist (every drop of the design failed) scores the worst value of each metric
NO_LABEL = {"sup_cdf": 1.0, "w1_deg": 360.0, "circular_w1_deg": 180.0, "js": 1.0}


def _row(base: dict, design: str, drops: int, repeat: int, cpu_s: float, label, ref_pmf) -> dict:
    """One row of a design's ``label`` (None: no drop of the design was ok, scored as
    :data:`NO_LABEL`) against the reference label ``ref_pmf`` (None: the reference has no ok
    drop, so the configuration has no label to compare with: NaN distances)."""
    row = {**base, "design": design, "drops": int(drops), "repeat": repeat, "cpu_s": cpu_s, "no_label": label is None}
    if ref_pmf is None:
        scores = dict.fromkeys(METRICS, math.nan)
    else:
        scores = dict(NO_LABEL) if label is None else distances(label.pmf, ref_pmf)
    if label is None:
        return {**row, "simulations": int(drops), "ok_mass": 0.0, "unresolved_share": math.nan, **scores}
    return {
        **row,
        "simulations": label.simulations,
        "ok_mass": label.ok_mass,
        "unresolved_share": label.cdf_bound,
        **scores,
    }


def _load(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def emulated_budgets(run_meta: dict, sim: dict) -> list[int]:
    """Budgets of the emulated adaptive design: those of the real runs (``run_meta["budgets"]``)
    and, when the study labels adaptively, the study's own budget ``sim.drops``, so that the
    table always says what the default's labels cost and how close they are, even at a budget
    that was never simulated for real."""
    budgets = {int(b["budget"]) for b in run_meta["budgets"]}
    if sim.get("yaw_sampling") == "adaptive":
        budgets.add(int(sim["drops"]))
    return sorted(budgets)


def entry_rows(reference: Path, adaptive: Path, settings: dict) -> list[dict]:
    """Rows of one configuration (its reference file and its adaptive file): the reference's own,
    the adaptive runs and every emulated design. A configuration whose reference has no ok drop
    (every initial yaw jams) has no label to compare with: its rows carry NaN distances."""
    from feeder.bench.reference import seed_of
    from feeder.labels.pmf import Label, sim_label
    from feeder.sim.pushforward import label_cdf_bound, pushforward_pmf
    from feeder.sim.record import SimRecord

    db, labels = settings["sim"]["design_bench"], settings["labels"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    z, runs = _load(reference), _load(adaptive)
    meta, run_meta = json.loads(str(z["meta"])), json.loads(str(runs["meta"]))
    if run_meta["entry"]["key"] != meta["entry"]["key"]:
        raise FeederError(
            f"{adaptive} is configuration {run_meta['entry']['key']}, {reference} is {meta['entry']['key']}"
        )
    ref = reference_design(z, float(settings["sim"]["adaptive"]["tolerance_deg"]))
    n_ref = int(z["ref_initial"].size)
    cpu_per_drop = float(z["ref_cpu_s"]) / n_ref
    base = {"config": meta["entry"]["key"], "symmetry_order": meta["symmetry_order"], **paired_check(z, ref)}

    ref_label = None
    if (z["ref_status"] == "ok").any():
        pmf, masses = pushforward_pmf(ref, bins, sigma)
        ref_label = Label(pmf, masses, label_cdf_bound(ref, masses["ok"]), "reference", n_ref)
    ref_pmf = None if ref_label is None else ref_label.pmf
    rows = [_row(base, "reference", n_ref, 0, float(z["ref_cpu_s"]), ref_label, ref_pmf)]
    for b in run_meta["budgets"]:
        tag = f"adaptive{b['budget']}"
        status = runs[f"{tag}_status"]
        rec = SimRecord(
            yaws=runs[f"{tag}_final"],
            ok=status == "ok",
            meta={"yaw_sampling": "adaptive", "design": b["design"]},
            initial=runs[f"{tag}_initial"],
            status=status,
        )
        label = sim_label(rec, bins, sigma) if rec.ok.any() else None
        rows.append(_row(base, "adaptive", b["budget"], 0, float(runs[f"{tag}_cpu_s"]), label, ref_pmf))
    order = round(360.0 / float(meta["period_deg"]))
    for budget in emulated_budgets(run_meta, settings["sim"]):
        for r in range(int(db["repeats"])):
            seed = seed_of(base["config"], "adaptive", budget, r)
            label = emulated_adaptive(ref, order, budget, seed, run_meta["adaptive"], bins, sigma)
            sims = budget if label is None else label.simulations
            rows.append(_row(base, "adaptive_emulated", budget, r, cpu_per_drop * sims, label, ref_pmf))
    for design in EMULATED_DESIGNS:
        for drops in db["drop_levels"]:
            for r in range(int(db["repeats"])):
                label = emulated_label(ref, design, int(drops), seed_of(base["config"], design, drops, r), bins, sigma)
                rows.append(_row(base, design, drops, r, cpu_per_drop * int(drops), label, ref_pmf))
    return rows


METRICS = ("sup_cdf", "w1_deg", "circular_w1_deg", "js")


def summary(frame, min_ok_mass: float = 0.0):
    """Per design and drop count, the mean over configurations, and for emulated designs a 95 %
    t-interval of that mean over the seeded realisations. Configurations whose reference has no
    ok drop (NaN distances), or less ok mass than ``min_ok_mass`` (``sim.min_ok_mass``: the study
    drops such a configuration as bad data, so its label is never used), are left out of every
    mean and counted in ``excluded_configurations``; a realisation that gives no label scores
    :data:`NO_LABEL` and is counted in ``no_label``."""
    import pandas as pd
    from scipy import stats

    ref = frame[frame["design"] == "reference"]
    bad = set(ref.loc[ref["ok_mass"] < min_ok_mass, "config"]) if "ok_mass" in ref else set()
    usable = frame[~frame["config"].isin(bad)].dropna(subset=list(METRICS))
    excluded = frame["config"].nunique() - usable["config"].nunique()
    rows = []
    for (design, drops), g in usable.groupby(["design", "drops"], sort=True):
        per_rep = g.groupby("repeat")[list(METRICS)].mean()  # every realisation covers the same configurations
        k = len(per_rep)
        row = {
            "config": "mean",
            "design": design,
            "drops": drops,
            "configurations": g["config"].nunique(),
            "excluded_configurations": excluded,
            "realisations": k,
            "no_label": int(g["no_label"].sum()),
            "simulations": g["simulations"].mean(),
            "cpu_s": g["cpu_s"].mean(),
        }
        for m in METRICS:
            mean = float(per_rep[m].mean())
            half = float(stats.t.ppf(0.975, k - 1) * per_rep[m].std(ddof=1) / math.sqrt(k)) if k > 1 else math.nan
            row[m], row[f"{m}_lo"], row[f"{m}_hi"] = mean, mean - half, mean + half
        rows.append(row)
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def main(argv: list[str]) -> int:
    from feeder.bench.reference import entry_by_key
    from feeder.config import add_settings_options, study_settings
    from feeder.io import write_csv, write_npz

    parser = argparse.ArgumentParser(prog="feeder bench-designs", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = add_settings_options(sub.add_parser("run", help="the adaptive design of one configuration"))
    run.add_argument("--key", required=True, help="configuration key (feeder bench-reference list)")
    run.add_argument("--out", required=True, type=Path)
    table = add_settings_options(sub.add_parser("table", help="every design against the references"))
    table.add_argument("--references", nargs="+", required=True, type=Path, help="reference files")
    table.add_argument("--adaptive", nargs="+", required=True, type=Path, help="adaptive files, in the same order")
    table.add_argument("--out-csv", required=True, type=Path, help="one row per configuration, design, drops, repeat")
    table.add_argument("--out-summary", required=True, type=Path, help="means over configurations")
    args = parser.parse_args(argv)
    settings = study_settings(args)
    if "design_bench" not in settings.get("sim", {}):
        raise FeederError("settings lack section sim.design_bench")
    if args.cmd == "run":
        write_npz(args.out, **run_adaptive(entry_by_key(settings, args.key), settings))
        return 0
    import pandas as pd

    if len(args.references) != len(args.adaptive):
        raise FeederError("--references and --adaptive must name the same configurations")
    pairs = zip(args.references, args.adaptive, strict=True)
    frame = pd.DataFrame([r for ref, ada in pairs for r in entry_rows(ref, ada, settings)])
    write_csv(args.out_csv, frame)
    means = summary(frame, float(settings["sim"]["min_ok_mass"]))
    write_csv(args.out_summary, means)
    for _, r in means.iterrows():
        print(
            f"{r['design']:>9} {int(r['drops']):5d}: sup|dCDF| {r['sup_cdf']:.4f}  W1 {r['w1_deg']:6.2f}  "
            f"circW1 {r['circular_w1_deg']:6.2f}  JS {r['js']:.4f}  sims {r['simulations']:.0f}",
            file=sys.stderr,
        )
    return 0
