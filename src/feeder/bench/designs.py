"""What a label costs under each initial-yaw design, against a dense reference (``feeder bench-designs``).

With one part per world a drop's outcome is a function of its initial yaw, so a configuration's
label is the push-forward of the uniform initial yaw through that map. This bench measures how
close each design gets to it, and at what cost:

* ``feeder bench-designs run``, one job per configuration (resumable: one file each):
  - the **reference**: an evenly spaced grid of ``reference_yaws`` initial yaws per full turn
    (0.125° apart at 2,880), simulated over one period of the part's rotational symmetry, its
    label the push-forward of the sampled map (:func:`feeder.labels.pmf.record_design`'s grid
    rule);
  - the **adaptive** design, simulated for real at each budget of ``adaptive_budgets``;
  - a **paired check** of the reference map: ``paired_drops`` independent initial yaws simulated
    for real and compared drop by drop with what the reference map gives at the same yaws
    (same-status and same-basin fractions, median |Δ final yaw|): how well the sampled map
    stands in for the simulator between its samples.
* ``feeder bench-designs table``: every design's label against the reference label:
  - ``adaptive`` from its real runs;
  - ``random``, ``golden`` and ``grid`` at each of ``drop_levels`` drops, ``repeats`` seeded
    realisations each, **emulated** through the reference map (the drops a design would simulate,
    mapped by :func:`feeder.labels.pushforward.map_yaws`). The paired check says how exact that is.
  Columns per configuration and design: simulations, CPU seconds (real for the reference and the
  adaptive design; for emulated designs, drops × the reference's CPU per drop), sup|ΔCDF|, W1 on
  the CDF, circular W1 (:func:`feeder.labels.metrics.circular_w1`), JS (bits) and the label's
  own bound. Rows ``config == "mean"`` average over configurations, with a 95 % interval over the
  emulated realisations.

Raw data stay in the per-configuration files (docs/data.md), so a new statistic needs no rerun.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

EMULATED_DESIGNS = ("random", "golden", "grid")
SAME_BASIN_DEG = 5.0  # |Δ final yaw| on the circle below which two ok drops ended in one basin


# ----------------------------------------------------------------------------------------------
# Configurations
# ----------------------------------------------------------------------------------------------
def entries(settings: dict) -> list[dict]:
    """The bench's configurations: the simulation bench's panel (shape specs) and
    ``sim.design_bench.library`` (part ids of ``parts.dir``), each with a file-safe key."""
    sim = settings["sim"]
    out = [{"kind": "shape", "part": e[0], "loc1": e[1], "loc2": e[2]} for e in sim["bench"]["panel"]]
    out += [{"kind": "part", "part": e[0], "loc1": e[1], "loc2": e[2]} for e in sim["design_bench"]["library"]]
    for e in out:
        e["key"] = entry_key(e)
    keys = [e["key"] for e in out]
    if len(set(keys)) != len(keys):
        raise FeederError("sim.design_bench: a configuration is listed twice")
    return out


def entry_key(entry: dict) -> str:
    """``rect-40x20__straight45_none``: part and fence configuration, file-safe."""
    fences = "_".join(str(entry[k]).replace(":", "") for k in ("loc1", "loc2"))
    return re.sub(r"[^A-Za-z0-9._-]", "-", f"{entry['part']}__{fences}")


def entry_geometry(entry: dict, settings: dict):
    if entry["kind"] == "shape":
        from feeder.parts.shapes import shape_part

        return shape_part(entry["part"], float(settings["sim"]["bench"]["thickness"]))
    from feeder.parts.geometry import load_part

    path = Path(settings["parts"]["dir"]) / f"{entry['part']}.stl"
    if not path.is_file():
        raise FeederError(f"sim.design_bench.library: part file {path} not found")
    return load_part(path)


def _seed(*tokens) -> int:
    return int.from_bytes(hashlib.sha256("|".join(map(str, tokens)).encode()).digest()[:8], "little")


# ----------------------------------------------------------------------------------------------
# One configuration (simulation)
# ----------------------------------------------------------------------------------------------
def reference_grid(order: int, reference_yaws: int, seed: int) -> tuple[np.ndarray, float, float]:
    """Initial yaws of the reference over one symmetry period: ``reference_yaws / order`` evenly
    spaced yaws with a seeded offset. Returns (yaws, period, offset)."""
    period = 360.0 / order
    n = max(2, int(round(reference_yaws / order)))
    offset = float(np.random.default_rng(seed).uniform(0.0, period / n))
    return offset + period * np.arange(n) / n, period, offset


def run_entry(entry: dict, settings: dict) -> dict:
    """Simulate one configuration's reference, adaptive runs and paired check: the arrays of its file."""
    from feeder.labels.pushforward import design_from_samples, map_yaws
    from feeder.parts.symmetry import rotational_order
    from feeder.sim.drops import get_preset, run_drops, simulate
    from feeder.sim.fences import parse_location

    db, scene = settings["sim"]["design_bench"], settings["scene"]
    preset = get_preset(settings["sim"]["presets"], db["preset"])
    geom = entry_geometry(entry, settings)
    loc1, loc2 = parse_location(entry["loc1"]), parse_location(entry["loc2"])
    order = rotational_order(geom.outline)
    yaws, period, offset = reference_grid(order, int(db["reference_yaws"]), _seed(entry["key"], "reference"))
    c0 = time.process_time()
    ref = run_drops(geom, loc1, loc2, yaws, scene, preset)
    out = {
        "ref_initial": yaws,
        "ref_final": ref["final_yaw_deg"],
        "ref_status": ref["status"].astype(str),
        "ref_cpu_s": np.float64(time.process_time() - c0),
    }
    meta = {
        "entry": entry,
        "symmetry_order": order,
        "period_deg": period,
        "offset_deg": offset,
        "preset": db["preset"],
        "budgets": [],
        "adaptive": settings["sim"]["adaptive"],
    }
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
        meta["budgets"].append({"budget": int(budget), "design": json.loads(str(res["meta"]))["design"]})
    beta = np.random.default_rng(_seed(entry["key"], "paired")).uniform(0.0, 360.0, int(db["paired_drops"]))
    real = run_drops(geom, loc1, loc2, beta, scene, preset)
    ref_design = design_from_samples(
        yaws,
        ref["final_yaw_deg"],
        ref["status"],
        period_deg=period,
        offset_deg=offset,
        tolerance_deg=float(settings["sim"]["adaptive"]["tolerance_deg"]),
        min_width_deg=period / yaws.size,
        max_width_deg=period / yaws.size,
        band_gap_deg=0.0,
        edge_check_deg=0.0,
    )
    mapped_final, mapped_status = map_yaws(ref_design, beta)
    out |= {
        "paired_initial": beta,
        "paired_final": real["final_yaw_deg"],
        "paired_status": real["status"].astype(str),
        "paired_mapped_final": mapped_final,
        "paired_mapped_status": mapped_status.astype(str),
        "meta": np.array(json.dumps(meta, sort_keys=True)),
    }
    return out


# ----------------------------------------------------------------------------------------------
# The table (pure: reads the per-configuration files)
# ----------------------------------------------------------------------------------------------
def reference_design(z, tolerance_deg: float):
    from feeder.labels.pushforward import design_from_samples

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


def paired_check(z) -> dict[str, float]:
    """The reference map against real drops at the same initial yaws."""
    from feeder.labels.pushforward import circular_distance

    same_status = z["paired_status"] == z["paired_mapped_status"]
    both_ok = same_status & (z["paired_status"] == "ok")
    d = circular_distance(z["paired_final"][both_ok], z["paired_mapped_final"][both_ok])
    same_basin = same_status.copy()
    same_basin[both_ok] = d < SAME_BASIN_DEG
    return {
        "paired_same_status": float(same_status.mean()),
        "paired_same_basin": float(same_basin.mean()),
        "paired_median_dyaw_deg": float(np.median(d[d < SAME_BASIN_DEG])) if (d < SAME_BASIN_DEG).any() else math.nan,
    }


def emulated_label(ref_design, design: str, drops: int, seed: int, bins: int, sigma: float):
    """The label ``design`` would give with ``drops`` drops (seeded), its drops mapped through the reference."""
    from feeder.labels.pmf import sim_label
    from feeder.labels.pushforward import map_yaws
    from feeder.sim.drops import initial_yaws
    from feeder.sim.record import SimRecord

    beta = initial_yaws(seed, drops, design)
    final, status = map_yaws(ref_design, beta)
    rec = SimRecord(yaws=final, ok=status == "ok", meta={"yaw_sampling": design}, initial=beta, status=status)
    return sim_label(rec, bins, sigma)


def entry_rows(path: Path, settings: dict) -> list[dict]:
    """Rows of one configuration: the reference's own, the adaptive runs and every emulated design."""
    from feeder.labels.pmf import sim_label
    from feeder.labels.pushforward import label_cdf_bound, pushforward_pmf
    from feeder.sim.record import SimRecord

    db, labels = settings["sim"]["design_bench"], settings["labels"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    with np.load(path, allow_pickle=False) as z:
        z = {k: z[k] for k in z.files}
    meta = json.loads(str(z["meta"]))
    ref = reference_design(z, float(settings["sim"]["adaptive"]["tolerance_deg"]))
    ref_pmf, ref_masses = pushforward_pmf(ref, bins, sigma)
    n_ref = int(z["ref_initial"].size)
    cpu_per_drop = float(z["ref_cpu_s"]) / n_ref
    base = {"config": meta["entry"]["key"], "symmetry_order": meta["symmetry_order"], **paired_check(z)}
    rows = [
        {
            **base,
            "design": "reference",
            "drops": n_ref,
            "repeat": 0,
            "simulations": n_ref,
            "cpu_s": float(z["ref_cpu_s"]),
            "ok_mass": ref_masses.get("ok", 0.0),
            "label_bound": label_cdf_bound(ref, ref_masses["ok"]),
            **distances(ref_pmf, ref_pmf),
        }
    ]
    for b in meta["budgets"]:
        tag = f"adaptive{b['budget']}"
        rec = SimRecord(
            yaws=z[f"{tag}_final"],
            ok=z[f"{tag}_status"] == "ok",
            meta={"yaw_sampling": "adaptive", "design": b["design"]},
            initial=z[f"{tag}_initial"],
            status=z[f"{tag}_status"],
        )
        label = sim_label(rec, bins, sigma)
        rows.append(
            {
                **base,
                "design": "adaptive",
                "drops": b["budget"],
                "repeat": 0,
                "simulations": label.simulations,
                "cpu_s": float(z[f"{tag}_cpu_s"]),
                "ok_mass": label.ok_mass,
                "label_bound": label.cdf_bound,
                **distances(label.pmf, ref_pmf),
            }
        )
    for design in EMULATED_DESIGNS:
        for drops in db["drop_levels"]:
            for r in range(int(db["repeats"])):
                label = emulated_label(ref, design, int(drops), _seed(base["config"], design, drops, r), bins, sigma)
                rows.append(
                    {
                        **base,
                        "design": design,
                        "drops": int(drops),
                        "repeat": r,
                        "simulations": int(drops),
                        "cpu_s": cpu_per_drop * int(drops),
                        "ok_mass": label.ok_mass,
                        "label_bound": label.cdf_bound,
                        **distances(label.pmf, ref_pmf),
                    }
                )
    return rows


METRICS = ("sup_cdf", "w1_deg", "circular_w1_deg", "js")


def summary(frame):
    """Mean over configurations per design and drop count; for emulated designs a 95 % interval
    of that mean over the realisations (each realisation's mean over configurations)."""
    import pandas as pd

    rows = []
    for (design, drops), g in frame.groupby(["design", "drops"], sort=True):
        per_rep = g.groupby("repeat")[list(METRICS)].mean()
        row = {
            "config": "mean",
            "design": design,
            "drops": drops,
            "configurations": g["config"].nunique(),
            "simulations": g["simulations"].mean(),
            "cpu_s": g["cpu_s"].mean(),
        }
        for m in METRICS:
            row[m] = float(per_rep[m].mean())
            lo, hi = np.quantile(per_rep[m], [0.025, 0.975]) if len(per_rep) > 1 else (math.nan, math.nan)
            row[f"{m}_lo"], row[f"{m}_hi"] = float(lo), float(hi)
        rows.append(row)
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------
def _settings(args) -> dict:
    from feeder.config import load_study_config, parse_settings, study_root

    if args.settings:
        return parse_settings(args.settings)
    overlays = [str(Path(f).resolve()) for f in args.configfile or []]
    return load_study_config(*overlays, root=study_root())


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder bench-designs", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    for name in ("run", "table", "list"):
        p = sub.add_parser(name)
        p.add_argument("--settings", default=None, help="JSON of the config sections (the workflow passes it)")
        p.add_argument("--configfile", action="append", default=None, help="an overlay of config/config.yaml")
        if name == "run":
            p.add_argument("--key", required=True, help="configuration key (feeder bench-designs list)")
            p.add_argument("--out", required=True, type=Path)
        if name == "table":
            p.add_argument("files", nargs="+", type=Path)
            p.add_argument(
                "--out-csv", required=True, type=Path, help="one row per configuration, design, drops, repeat"
            )
            p.add_argument("--out-summary", required=True, type=Path, help="means over configurations")
    args = parser.parse_args(argv)
    settings = _settings(args)
    if "design_bench" not in settings.get("sim", {}):
        raise FeederError("settings lack section sim.design_bench")
    from feeder.io import write_csv, write_npz

    if args.cmd == "list":
        print("\n".join(e["key"] for e in entries(settings)))
        return 0
    if args.cmd == "run":
        entry = {e["key"]: e for e in entries(settings)}.get(args.key)
        if entry is None:
            raise FeederError(f"no configuration {args.key!r} in the design bench (feeder bench-designs list)")
        write_npz(args.out, **run_entry(entry, settings))
        return 0
    import pandas as pd

    frame = pd.DataFrame([r for f in args.files for r in entry_rows(f, settings)])
    write_csv(args.out_csv, frame)
    means = summary(frame)
    write_csv(args.out_summary, means)
    for _, r in means.iterrows():
        print(
            f"{r['design']:>9} {int(r['drops']):5d}: sup|dCDF| {r['sup_cdf']:.4f}  W1 {r['w1_deg']:6.2f}  "
            f"circW1 {r['circular_w1_deg']:6.2f}  JS {r['js']:.4f}  sims {r['simulations']:.0f}",
            file=sys.stderr,
        )
    return 0
