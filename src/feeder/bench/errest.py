"""How often a label's error estimate covers its error, emulated through the design bench's references.

(``feeder bench-errest``)

For every reference of the design bench (``feeder bench-reference``: a dense map, initial yaw →
final yaw and status) and ``sim.design_bench.repeats`` seeded offsets, each design of
``sim.errest_bench.designs`` is emulated through the reference map (every simulation
replaced by the map at that initial yaw, as ``feeder bench-designs`` does; nothing is simulated):

* ``adaptive``: the study's adaptive design at the budget ``sim.drops``, then one round of
  ``sim.adaptive_target.audits`` audit drops that only estimate (the label is the budget's), drawn
  as the study's own audit draws them (``feeder audit``, :mod:`feeder.labels.audit`);
* ``targeted``: the design whose budget follows the scene (:func:`feeder.sim.errest.targeted`,
  ``sim.adaptive_target``), at its targets times each of ``sim.errest_bench.target_scales``.

Each row: simulations spent (audits included), the label's true sup|ΔCDF| and circular W1 to the
reference label, the estimates, and whether each estimate covers the error. The summary gives,
per configuration and design, the coverage (fraction of offsets whose estimate is ≥ the error,
to a round-off floor), the mean simulations and the mean errors; rows ``config == "mean"`` average
over the configurations. Configurations whose reference has less ok mass than
``sim.min_ok_mass`` are left out (the study drops them). Raw rows are kept, so a new statistic
needs no rerun.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

DESIGNS = ("adaptive", "targeted")
ROUND_OFF = 1e-9  # an estimate within this of the error covers it (a zero error is computed as ~1e-16)


def check_errest(settings: dict) -> dict:
    """``sim.errest_bench`` checked: a one-line FeederError for an unknown design or a
    scale ≤ 0; the targets themselves are checked by :func:`feeder.sim.errest.check_target`."""
    from feeder.sim.errest import check_target

    sim = settings["sim"]
    cfg = sim.get("errest_bench")
    if cfg is None:
        raise FeederError("settings lack section sim.errest_bench")
    unknown = [d for d in cfg["designs"] if d not in DESIGNS]
    if unknown:
        raise FeederError(f"sim.errest_bench.designs: unknown design {unknown[0]!r} (known: {', '.join(DESIGNS)})")
    for s in cfg["target_scales"]:
        if not (isinstance(s, (int, float)) and np.isfinite(s) and s > 0):
            raise FeederError(f"sim.errest_bench.target_scales must be numbers > 0, got {s!r}")
    check_target(sim.get("adaptive_target") or {}, int(sim["adaptive"]["n0"]))
    return cfg


def scaled(adaptive: dict, scale: float) -> dict:
    """``sim.adaptive`` with both targets multiplied by ``scale``."""
    t = dict(adaptive["target"])
    t["target_w1_deg"] = float(t["target_w1_deg"]) * scale
    t["target_sup_cdf"] = float(t["target_sup_cdf"]) * scale
    return {**adaptive, "target": t}


def entry_rows(reference: Path, settings: dict, cfg: dict) -> list[dict]:
    """Rows of one configuration's reference file (module docstring)."""
    from feeder.bench.designs import _load, distances, reference_design
    from feeder.bench.reference import seed_of
    from feeder.sim import errest as E
    from feeder.sim.pushforward import map_yaws, pushforward_pmf
    from feeder.sim.simulate import run_design

    sim, labels = settings["sim"], settings["labels"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    adaptive = {**sim["adaptive"], "target": sim["adaptive_target"]}
    z = _load(reference)
    meta = json.loads(str(z["meta"]))
    key = meta["entry"]["key"]
    ref = reference_design(z, float(adaptive["tolerance_deg"]))
    if not (z["ref_status"] == "ok").any():
        return []
    ref_pmf, ref_masses = pushforward_pmf(ref, bins, sigma)
    base = {"config": key, "symmetry_order": meta["symmetry_order"], "ref_ok_mass": ref_masses.get("ok", 0.0)}
    order = round(360.0 / float(meta["period_deg"]))

    def evaluate(yaws):
        return map_yaws(ref, yaws)

    def row(design, target_scale, r, d, est, sims):
        if not (d.status == "ok").any():
            dist = {"sup_cdf": 1.0, "circular_w1_deg": 180.0}
        else:
            dist = distances(pushforward_pmf(d, bins, sigma)[0], ref_pmf)
        return {
            **base,
            "design": design,
            "target_scale": target_scale,
            "repeat": r,
            "simulations": int(sims),
            "sup_cdf": dist["sup_cdf"],
            "circular_w1_deg": dist["circular_w1_deg"],
            "est_sup_cdf": est.sup_cdf,
            "est_circular_w1_deg": est.circular_w1_deg,
            "audit_misses": est.misses,
            "covers_sup": bool(est.sup_cdf >= dist["sup_cdf"] - ROUND_OFF),
            "covers_w1": bool(est.circular_w1_deg >= dist["circular_w1_deg"] - ROUND_OFF),
        }

    rows = []
    budget = int(sim["drops"])
    t = adaptive["target"]
    for r in range(int(sim["design_bench"]["repeats"])):
        seed = seed_of(key, "adaptive", budget, r)  # the offsets of feeder bench-designs' emulated rows
        if "adaptive" in cfg["designs"]:
            d = run_design(evaluate, seed, budget, adaptive, order)
            rng = np.random.default_rng([seed, int(t["audits"])])  # as the study's audit draws (feeder audit)
            beta = E.audit_yaws(rng, int(t["audits"]), d.offset_deg, d.period_deg)
            final, status = evaluate(beta)
            est = E.estimate_or_worst(d, beta, final, status, bins, sigma, float(t["confidence"]))
            rows.append(row("adaptive", np.nan, r, d, est, d.evaluations + beta.size))
        if "targeted" in cfg["designs"]:
            for scale in cfg["target_scales"]:
                d, est, _ = E.targeted(evaluate, seed, scaled(adaptive, float(scale)), order, bins, sigma)
                rows.append(row("targeted", float(scale), r, d, est, d.evaluations))
    return rows


def summary(frame, min_ok_mass: float):
    """Per configuration, design and target scale: coverage, mean simulations and errors; rows
    ``config == "mean"`` average the configurations (coverage: its mean and its minimum)."""
    import pandas as pd

    usable = frame[frame["ref_ok_mass"] >= min_ok_mass]
    keys = ["design", "target_scale"]
    cols = [
        "simulations",
        "sup_cdf",
        "circular_w1_deg",
        "est_sup_cdf",
        "est_circular_w1_deg",
        "covers_sup",
        "covers_w1",
    ]
    per = usable.fillna({"target_scale": 0.0}).groupby(["config", *keys])[cols].mean().reset_index()
    per = per.rename(columns={"covers_sup": "coverage_sup", "covers_w1": "coverage_w1"})
    means = []
    for (design, scale), g in per.groupby(keys):
        means.append(
            {
                "config": "mean",
                "design": design,
                "target_scale": scale,
                **{
                    c: g[c].mean()
                    for c in ["simulations", "sup_cdf", "circular_w1_deg", "est_sup_cdf", "est_circular_w1_deg"]
                },
                "coverage_sup": g["coverage_sup"].mean(),
                "coverage_w1": g["coverage_w1"].mean(),
                "min_coverage_sup": g["coverage_sup"].min(),
                "min_coverage_w1": g["coverage_w1"].min(),
                "configurations": g["config"].nunique(),
            }
        )
    out = pd.concat([per, pd.DataFrame(means)], ignore_index=True)
    out["target_scale"] = out["target_scale"].replace(0.0, np.nan)
    return out


def main(argv: list[str]) -> int:
    import pandas as pd

    from feeder.config import add_settings_options, study_settings
    from feeder.io import write_csv

    parser = add_settings_options(
        argparse.ArgumentParser(prog="feeder bench-errest", description=__doc__.splitlines()[0])
    )
    parser.add_argument(
        "--references", nargs="+", required=True, type=Path, help="reference files (feeder bench-reference)"
    )
    parser.add_argument("--out-csv", required=True, type=Path, help="one row per configuration, design, scale, offset")
    parser.add_argument(
        "--out-summary", required=True, type=Path, help="coverage, simulations and errors per configuration"
    )
    args = parser.parse_args(argv)
    settings = study_settings(args)
    cfg = check_errest(settings)
    missing = [p for p in args.references if not p.is_file()]
    if missing:
        raise FeederError(f"reference file {missing[0]} not found")
    frame = pd.DataFrame([r for ref in args.references for r in entry_rows(ref, settings, cfg)])
    if frame.empty:
        raise FeederError("no reference has an ok drop: nothing to measure")
    table = summary(frame, float(settings["sim"]["min_ok_mass"]))
    write_csv(args.out_csv, frame)
    write_csv(args.out_summary, table)
    for _, r in table[table["config"] == "mean"].iterrows():
        print(
            f"{r['design']:>9} x{r['target_scale']:<4g} sims {r['simulations']:5.1f}  sup|dCDF| {r['sup_cdf']:.4f}"
            f" (est {r['est_sup_cdf']:.3f})  circW1 {r['circular_w1_deg']:.2f} (est {r['est_circular_w1_deg']:.2f})"
            f"  coverage sup {r['coverage_sup']:.2f} (min {r['min_coverage_sup']:.2f})"
            f" w1 {r['coverage_w1']:.2f} (min {r['min_coverage_w1']:.2f})",
            file=sys.stderr,
        )
    return 0
