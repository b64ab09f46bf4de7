"""Every sampled-map label's estimate of its own error: a few audit drops simulated beside it.

(``feeder audit``, ``feeder label-errors``; issue #38 item 1)

A grid or adaptive label is the push-forward of the uniform initial yaw through the interpolated
map of its samples (:mod:`feeder.sim.pushforward`). :mod:`feeder.sim.errest` estimates how far
that label is from the label of the simulator's own map, from a few *audit* drops: initial yaws
drawn one in each of ``k`` equal strata of the period, simulated for real. The design bench
measured this estimate, for the study's design (budget ``sim.drops``) followed by one round of
``sim.adaptive_target.audits`` audits, on 20 dense reference maps: it covers the true error on at
least 95 % of the seeded offsets of every one of them (``feeder bench-errest``,
``results/tables/design_error_estimate*.csv``).

This module runs that audit round after the study's simulations, from their files, so the labels
stay exactly as they are (the audits only estimate; they do not join the label):

* :func:`audit_plan`: the audit yaws of one simulation file, drawn from the configuration's own
  seed (the design's) on the stream of the targeted design's audit rounds, so the audit is exactly
  the round that design would draw next (:data:`TARGETED_STREAM`);
* ``feeder audit``: simulates one part's audit drops, configuration by configuration, under the
  scene and preset each simulation file records, and writes them raw (one row per drop);
* :func:`estimate_from_audit` and ``feeder label-errors``: each label's error estimate from its
  simulation file and its audit drops (no simulation), one row per configuration, and a summary by
  fence types.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from feeder.errors import FeederError
from feeder.sim.record import BadData

DROP_COLUMNS = ("part", "config_id", "seed", "audits", "audit", "initial_yaw_deg", "final_yaw_deg", "status", "cpu_s")
# initial yaws recomputed from the seed must equal the stored ones to this (degrees): else the audit
# file belongs to another simulation file or another audit setting
YAW_MATCH_DEG = 1e-9
SUMMARY_QUANTILE = 0.9  # the summary's upper quantile of the estimates
# A budget (or grid) label is audited on the stream of the targeted design's audit rounds, [design seed,
# audits]: the study's audit is then exactly the first round of that design run on from the label's own
# simulations (feeder.sim.errest.targeted with min_budget = the budget), so a later pass that refines only
# the labels whose estimate misses a target continues from these files. A targeted label's own rounds
# already drew from that stream and joined the label; it is audited on [design seed, audits, TARGETED_STREAM].
TARGETED_STREAM = 1


def audit_seed(rec) -> int:
    """The seed of a simulation record's design (:func:`feeder.sim.drops.drop_seed` of its part,
    configuration and base seed); the audits draw from :func:`audit_stream`."""
    from feeder.sim.drops import drop_seed

    meta = rec.meta
    try:
        return drop_seed(str(meta["part"]), str(meta["config_id"]), int(meta["seed"]))
    except KeyError as err:
        raise BadData(f"a simulation record without {err} in its meta cannot be audited") from None


def audit_stream(rec, audits: int) -> list[int]:
    """The audits' random stream of a record (see :data:`TARGETED_STREAM`)."""
    stop = (rec.meta.get("design") or {}).get("stop", "budget")
    return [audit_seed(rec), int(audits)] + ([TARGETED_STREAM] if stop == "target" else [])


def check_audits(audits) -> int:
    """The audit count: an integer ≥ 2 (the estimate's standard error needs two), else a one-line error."""
    if isinstance(audits, bool) or not isinstance(audits, (int, np.integer)) or audits < 2:
        raise FeederError(f"audits must be an integer of at least 2, got {audits!r}")
    return int(audits)


def audit_plan(rec, audits: int, design=None) -> np.ndarray:
    """The ``audits`` stratified random initial yaws of a grid or adaptive record, over its
    design's period from its offset (ascending, not reduced mod 360). ``design``: the record's
    :func:`feeder.labels.pmf.record_design`, when the caller has it already."""
    from feeder.labels.pmf import MAP_DESIGNS, record_design
    from feeder.sim.errest import audit_yaws

    k = check_audits(audits)
    if rec.design not in MAP_DESIGNS:
        raise FeederError(
            f"a {rec.design} label is a sample of drops (its error is statistical): "
            "only grid and adaptive labels are audited"
        )
    design = record_design(rec) if design is None else design
    rng = np.random.default_rng(audit_stream(rec, k))
    return audit_yaws(rng, k, design.offset_deg, design.period_deg)


def has_label(rec) -> bool:
    """Whether a record carries an orientation label at all (some drop ended ok)."""
    return bool(np.any(rec.ok))


def audit_rows(rec, audits: int, evaluate) -> list[dict]:
    """One configuration's audit drops as rows (:data:`DROP_COLUMNS`); none when the record has
    no label. ``evaluate(yaws)`` simulates initial yaws in [0, 360) and returns (final, status)."""
    from feeder.circular import normalize_yaw

    if not has_label(rec):
        return []
    beta = audit_plan(rec, audits)
    c0 = time.process_time()
    final, status = evaluate(normalize_yaw(beta))
    cpu = time.process_time() - c0
    final = np.asarray(final, dtype=np.float64)
    status = np.asarray(status).astype(str)
    if final.shape != beta.shape or status.shape != beta.shape:
        raise FeederError(f"the audit simulation returned {final.shape} yaws for {beta.shape} initial yaws")
    base = {
        "part": rec.meta["part"],
        "config_id": rec.meta["config_id"],
        "seed": int(rec.meta["seed"]),
        "audits": beta.size,
    }
    return [
        {
            **base,
            "audit": i,
            "initial_yaw_deg": float(beta[i]),
            "final_yaw_deg": float(final[i]),
            "status": status[i],
            "cpu_s": cpu / beta.size,
        }
        for i in range(beta.size)
    ]


def simulator(geom, rec):
    """``evaluate(yaws)`` for a record's configuration: every drop in a world of its own
    (:func:`feeder.sim.drops.run_each`, as the study's designs run them), under the scene and
    preset the record itself was simulated with."""
    from feeder.lane.fences import parse_location
    from feeder.sim.drops import run_each

    settings = rec.meta.get("settings") or {}
    scene, preset = settings.get("scene"), settings.get("preset")
    if not isinstance(scene, dict) or not isinstance(preset, dict):
        raise BadData(
            f"simulation record of {rec.meta.get('part')} {rec.meta.get('config_id')} "
            "lacks its scene and preset settings"
        )
    loc1, loc2 = parse_location(rec.meta["loc1"]), parse_location(rec.meta["loc2"])

    def evaluate(yaws):
        out = run_each(geom, loc1, loc2, np.asarray(yaws, dtype=np.float64), scene, preset)
        return out["final_yaw_deg"], out["status"]

    return evaluate


def estimate_from_audit(rec, drops, bins: int, sigma: float, confidence: float, design=None):
    """The record's error estimate (:class:`feeder.sim.errest.ErrorEstimate`) from its audit drops
    (a frame of :data:`DROP_COLUMNS` rows of this configuration). The drops must be this record's:
    the initial yaws recomputed from its seed and their count must match, else a one-line error.
    ``design``: the record's :func:`feeder.labels.pmf.record_design`, when the caller has it."""
    from feeder.labels.pmf import record_design
    from feeder.sim.errest import estimate_or_worst

    where = f"{rec.meta.get('part')} {rec.meta.get('config_id')}"
    if len(drops) == 0:
        raise BadData(f"{where}: no audit drops (run feeder audit on its simulation file)")
    counts = set(int(a) for a in drops["audits"])
    if len(counts) != 1 or counts != {len(drops)}:
        raise BadData(f"{where}: {len(drops)} audit drops against the count {sorted(counts)} they were drawn for")
    design = record_design(rec) if design is None else design
    drops = drops.sort_values("audit")
    beta = np.asarray(drops["initial_yaw_deg"], dtype=np.float64)
    expected = audit_plan(rec, len(drops), design)
    if not np.allclose(beta, expected, rtol=0.0, atol=YAW_MATCH_DEG):
        raise BadData(
            f"{where}: the audit drops were drawn for another simulation file (initial yaws differ); rerun feeder audit"
        )
    final = np.asarray(drops["final_yaw_deg"], dtype=np.float64)
    status = np.asarray(drops["status"]).astype(str)
    return estimate_or_worst(design, beta, final, status, int(bins), float(sigma), float(confidence))


def fence_type(spec: str) -> str:
    """``straight:30`` -> ``straight``; ``none`` -> ``none``."""
    return str(spec).split(":")[0]


def label_error_rows(entries, audit_drops, settings: dict) -> list[dict]:
    """One row per simulation file of ``entries`` (``(dataset, path)`` pairs; ``dataset`` may be
    empty): its label's simulations, ok mass, the share of the period its design left unresolved
    and the audit's estimate. ``audit_drops``: every audit drop (:data:`DROP_COLUMNS`), of any parts.
    ``settings``: ``labels`` (bins, sigma_bins), ``sim.min_ok_mass`` and
    ``sim.adaptive_target.confidence``."""
    from feeder.labels.pmf import record_design, sim_label
    from feeder.sim.record import load_sim

    labels, sim = settings["labels"], settings["sim"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    confidence, min_ok = float(sim["adaptive_target"]["confidence"]), float(sim["min_ok_mass"])
    by_configuration = {key: g for key, g in audit_drops.groupby(["part", "config_id"], sort=False)}
    rows = []
    for dataset, path in entries:
        rec = load_sim(path, min_ok_drops=0)
        part, config = str(rec.meta.get("part")), str(rec.meta.get("config_id"))
        row = {
            "part": part,
            "config_id": config,
            "dataset": dataset,
            "loc1": fence_type(rec.meta.get("loc1", "")),
            "loc2": fence_type(rec.meta.get("loc2", "")),
            "simulations": int(rec.yaws.size),
            "sim_cpu_s": sim_cpu_s(path),
        }
        if not has_label(rec):
            rows.append(
                {
                    **row,
                    "ok_mass": 0.0,
                    "kept": False,
                    "unresolved_share": np.nan,
                    "audits": 0,
                    "misses": 0,
                    "est_sup_cdf": np.nan,
                    "est_circular_w1_deg": np.nan,
                    "split_sup": np.nan,
                    "audit_cpu_s": 0.0,
                }
            )
            continue
        label = sim_label(rec, bins, sigma)
        drops = by_configuration.get((part, config), audit_drops.iloc[:0])
        design = record_design(rec)
        est = estimate_from_audit(rec, drops, bins, sigma, confidence, design)
        rows.append(
            {
                **row,
                "ok_mass": label.ok_mass,
                "kept": bool(label.ok_mass >= min_ok),
                "unresolved_share": float(design.unresolved_share),
                "audits": est.audits,
                "misses": est.misses,
                "est_sup_cdf": est.sup_cdf,
                "est_circular_w1_deg": est.circular_w1_deg,
                "split_sup": est.split_sup,
                "audit_cpu_s": float(drops["cpu_s"].sum()),
            }
        )
    return rows


def summary(frame):
    """The estimates of the kept labels by fence types (Location 1 + Location 2) and over all:
    configurations, mean, median and the :data:`SUMMARY_QUANTILE` quantile of each estimate, the
    share of labels some audit contradicted and their audits' CPU; over all also every configuration's
    audit CPU over its simulations' (``sim_cpu_s``), kept or not."""
    import pandas as pd

    kept = frame[frame["kept"]].copy()
    kept["fences"] = kept["loc1"] + " + " + kept["loc2"]
    groups = [(name, g) for name, g in kept.groupby("fences")] + [("all", kept)]
    out = []
    for name, g in groups:
        row = {"fences": name, "configurations": len(g)}
        for col, short in (("est_circular_w1_deg", "w1"), ("est_sup_cdf", "sup")):
            v = g[col].to_numpy(dtype=np.float64)
            row[f"est_{short}_mean"] = float(np.mean(v)) if v.size else np.nan
            row[f"est_{short}_median"] = float(np.median(v)) if v.size else np.nan
            row[f"est_{short}_q{round(100 * SUMMARY_QUANTILE)}"] = (
                float(np.quantile(v, SUMMARY_QUANTILE)) if v.size else np.nan
            )
        row["share_contradicted"] = float(np.mean(g["misses"] > 0)) if len(g) else np.nan
        row["audit_cpu_s"] = float(g["audit_cpu_s"].sum())
        out.append(row)
    table = pd.DataFrame(out)
    # what the audit stage cost beside the simulations: every configuration's, kept or not
    sim_cpu = float(frame["sim_cpu_s"].sum())  # 0 for files that predate the key
    everything = float(frame["audit_cpu_s"].sum()) / sim_cpu if sim_cpu > 0 else np.nan
    table["audit_cpu_over_sim"] = np.where(table["fences"] == "all", everything, np.nan)
    return table


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def read_drops(path):
    """An audit file (:data:`DROP_COLUMNS`), a one-line error when it is missing, unreadable, lacks
    a column, holds a non-numeric count or yaw, an unknown status, or an ok drop without a finite
    final yaw."""
    import pandas as pd

    from feeder.sim.drops import STATUSES

    path = Path(path)
    if not path.is_file():
        raise BadData(f"audit file {path} is missing")
    try:
        frame = pd.read_csv(path, dtype={"part": str, "config_id": str, "status": str}, keep_default_na=False)
    except (ValueError, OSError) as err:
        raise BadData(f"audit file {path} is unreadable ({type(err).__name__}: {err})") from None
    missing = [c for c in DROP_COLUMNS if c not in frame.columns]
    if missing:
        raise BadData(f"audit file {path} lacks column {missing[0]!r}")
    for column in ("seed", "audits", "audit", "initial_yaw_deg", "final_yaw_deg", "cpu_s"):
        values = pd.to_numeric(frame[column].replace("", np.nan), errors="coerce")
        if values.isna().to_numpy()[frame[column].astype(str) != ""].any():
            raise BadData(f"audit file {path}: column {column!r} holds a value that is not a number")
        frame[column] = values
    unknown = sorted(set(frame["status"]) - set(STATUSES))
    if unknown:
        raise BadData(f"audit file {path}: unknown status {unknown[0]!r} (known: {', '.join(STATUSES)})")
    ok = frame["status"] == "ok"
    if not np.isfinite(frame.loc[ok, "final_yaw_deg"].to_numpy(dtype=np.float64)).all():
        raise BadData(f"audit file {path}: an ok drop has no finite final yaw")
    if not np.isfinite(frame["initial_yaw_deg"].to_numpy(dtype=np.float64)).all():
        raise BadData(f"audit file {path}: a drop has no finite initial yaw")
    return frame


def sim_cpu_s(path) -> float:
    """The CPU seconds a simulation file records (``cpu_s``; 0 when it predates the key)."""
    with np.load(path, allow_pickle=False) as z:
        return float(z["cpu_s"]) if "cpu_s" in z.files else 0.0


def _parser() -> argparse.ArgumentParser:
    from feeder.config import add_settings_options

    parser = argparse.ArgumentParser(prog="feeder audit", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run", help="simulate one part's audit drops beside its grid or adaptive labels (raw rows)")
    run.add_argument("--part", required=True, help="parts/<id>.stl")
    run.add_argument(
        "--sims", required=True, nargs="+", help="the part's simulation files (results/sim/<part>/<config>.npz)"
    )
    run.add_argument(
        "--audits", required=True, type=int, help="audit drops per configuration (sim.adaptive_target.audits)"
    )
    run.add_argument("--units", default="auto", choices=("auto", "m", "mm"), help="units of the part file")
    run.add_argument("--out", required=True, help="output CSV, one row per audit drop")
    table = add_settings_options(
        sub.add_parser(
            "table", help="each label's error estimate from its simulation file and audit drops (no simulation)"
        )
    )
    table.add_argument(
        "--configurations", default=None, help="the study's results/datasets/configurations.csv (with --sim-dir)"
    )
    table.add_argument("--sim-dir", default=None, help="the study's results/sim")
    table.add_argument("--sims", nargs="+", default=None, help="or: simulation files of your own (feeder simulate)")
    table.add_argument("--audits", required=True, nargs="+", help="the audit files (results/audit/<part>.csv)")
    table.add_argument("--out-csv", required=True, help="one row per configuration")
    table.add_argument("--out-summary", required=True, help="by fence types and over all")
    return parser


def _run(args) -> int:
    import pandas as pd

    from feeder.io import write_csv
    from feeder.parts.geometry import load_part_units
    from feeder.sim.record import load_sim

    k = check_audits(args.audits)
    path = Path(args.part)
    if not path.is_file():
        raise FeederError(f"part file {path} not found")
    geom, _ = load_part_units(path, args.units)
    records = [load_sim(f, min_ok_drops=0) for f in args.sims]  # every file read and checked before any simulation
    for f, rec in zip(args.sims, records):
        if rec.meta.get("part") != geom.part_id:
            raise BadData(f"simulation file {f} is of part {rec.meta.get('part')!r}, not {geom.part_id!r}")
        audit_plan(rec, k)  # a drawn design is refused here, before any simulation
    rows, t0 = [], time.perf_counter()
    for i, rec in enumerate(records, 1):
        rows += audit_rows(rec, k, simulator(geom, rec))
        print(
            f"{geom.part_id}: {i}/{len(records)} configurations audited ({time.perf_counter() - t0:.0f} s)",
            file=sys.stderr,
        )
    write_csv(args.out, pd.DataFrame(rows, columns=list(DROP_COLUMNS)))
    return 0


def _table(args) -> int:
    import pandas as pd

    from feeder.config import study_settings
    from feeder.io import write_csv

    settings = study_settings(args, "labels", "sim")
    if (args.configurations is None) == (args.sims is None):
        raise FeederError("give either --configurations (with --sim-dir) or --sims")
    if args.configurations is not None:
        if args.sim_dir is None:
            raise FeederError("--configurations needs --sim-dir (the folder holding <part>/<config>.npz)")
        if not Path(args.configurations).is_file():
            raise FeederError(f"{args.configurations} is missing")
        configurations = pd.read_csv(args.configurations, dtype={"part": str, "config_id": str})
        for column in ("part", "config_id"):
            if column not in configurations.columns:
                raise BadData(f"{args.configurations} lacks column {column!r}")
        datasets = configurations["dataset"] if "dataset" in configurations.columns else [""] * len(configurations)
        entries = [
            (str(d), Path(args.sim_dir) / p / f"{c}.npz")
            for d, p, c in zip(datasets, configurations["part"], configurations["config_id"])
        ]
    else:
        entries = [("", Path(f)) for f in args.sims]
    if not entries:
        raise FeederError("no configuration to tabulate")
    drops = pd.concat([read_drops(f) for f in args.audits], ignore_index=True)
    frame = pd.DataFrame(label_error_rows(entries, drops, settings))
    table = summary(frame)  # both built before either is written
    write_csv(args.out_csv, frame)
    write_csv(args.out_summary, table)
    kept = frame[frame["kept"]]
    print(
        f"{len(frame)} configurations, {len(kept)} kept labels: estimated circular W1 median "
        f"{kept['est_circular_w1_deg'].median():.2f} deg, sup|dCDF| median {kept['est_sup_cdf'].median():.4f}",
        file=sys.stderr,
    )
    return 0


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    return _run(args) if args.cmd == "run" else _table(args)
