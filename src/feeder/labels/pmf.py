"""The label of one simulation file, whatever its initial-yaw design (``feeder labels pmf``).

One function, :func:`sim_label`, turns a simulation record into the label the workflow builds:

* drawn designs (``random``, ``golden``): the histogram of the ok drops' final yaws, smoothed
  (:func:`feeder.labels.metrics.pmf_from_yaws`); each drop carries 1/N of the probability;
* sampled maps (``grid``, ``adaptive``): the push-forward of the uniform initial yaw through the
  interpolated drop map (:func:`feeder.sim.pushforward.pushforward_pmf`), with a bound on
  sup|ΔCDF| from what the design left unresolved.

Failed drops (jammed, fell_off, ...) are probability mass too: ``masses`` maps every status to
its share, and ``masses["ok"]`` is what a configuration must keep (``sim.min_ok_mass``).
Partial levels of the paper's convergence studies need i.i.d. drops: :func:`level_drops` gives the
drops in drop order, emulated for sampled maps by seeded uniform draws through the interpolated map.

``feeder labels pmf SIM.npz --out pmf.csv`` writes the 360-bin label (columns ``angle_deg,pmf,cdf``,
as ``feeder predict --out``), in the part file's own frame unless ``--frame`` names a features
file; a JSON summary (design, simulations, status masses, bound) goes to stdout.
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

from feeder.labels import metrics as L
from feeder.sim.adaptive import DEFAULT_TOLERANCE_DEG, Design, design_from_samples
from feeder.sim.pushforward import DEFAULT_BINS, DEFAULT_SIGMA, emulate_drops, label_cdf_bound, pushforward_pmf
from feeder.sim.record import BadData, SimRecord, load_sim

DRAWN_DESIGNS = ("random", "golden")  # drops are samples: the label is their histogram
MAP_DESIGNS = ("grid", "adaptive")  # drops sample the map: the label is its push-forward


@dataclass
class Label:
    """A configuration's label: ``pmf`` (bins, smoothed, sums to 1 over the ok mass), the share of
    every status (``masses``), the bound on sup|ΔCDF| a sampled map leaves (NaN for drawn designs,
    whose error is statistical), the design and the simulations it took."""

    pmf: np.ndarray
    masses: dict[str, float]
    cdf_bound: float
    design: str
    simulations: int

    @property
    def ok_mass(self) -> float:
        return self.masses.get("ok", 0.0)


def record_design(rec: SimRecord) -> Design:
    """The sampled map of a ``grid`` or ``adaptive`` simulation record (final yaws as the record
    holds them, e.g. already in the label frame)."""
    if rec.initial is None or rec.status is None:
        raise BadData(f"a {rec.design} simulation record needs its initial yaws and statuses")
    if rec.design == "adaptive":
        d = rec.meta.get("design") or {}
        try:
            return design_from_samples(
                rec.initial,
                rec.yaws,
                rec.status,
                period_deg=d["period_deg"],
                offset_deg=d["offset_deg"],
                tolerance_deg=d["tolerance_deg"],
                min_width_deg=d["min_width_deg"],
                max_width_deg=d["max_width_deg"],
                band_gap_deg=d["band_gap_deg"],
                edge_check_deg=d["edge_check_deg"],
                calls=d.get("calls", 1),
            )
        except KeyError as err:
            raise BadData(f"an adaptive simulation record lacks design setting {err}") from None
    spacing = 360.0 / rec.initial.size
    tolerance = DEFAULT_TOLERANCE_DEG
    return design_from_samples(
        rec.initial,
        rec.yaws,
        rec.status,
        period_deg=360.0,
        offset_deg=float(np.min(rec.initial)),
        tolerance_deg=tolerance,
        min_width_deg=spacing,
        max_width_deg=spacing,
        band_gap_deg=0.0,
        edge_check_deg=0.0,
    )


def sim_label(rec: SimRecord, bins: int, sigma: float) -> Label:
    """The label of one simulation record (final yaws in whatever frame the record holds)."""
    n = int(rec.yaws.size)
    if rec.design in MAP_DESIGNS:
        design = record_design(rec)
        pmf, masses = pushforward_pmf(design, bins, sigma)
        return Label(pmf, masses, label_cdf_bound(design, masses["ok"]), rec.design, n)
    if rec.design not in DRAWN_DESIGNS:
        raise BadData(f"unknown initial-yaw design {rec.design!r} in a simulation record")
    if not rec.ok.any():
        raise BadData("no ok drop: the configuration has no label")
    status = rec.status if rec.status is not None else np.where(rec.ok, "ok", "failed")
    names, counts = np.unique(status, return_counts=True)
    masses = {str(s): float(c) / n for s, c in zip(names, counts)}
    return Label(L.pmf_from_yaws(rec.yaws[rec.ok], bins, sigma), masses, math.nan, rec.design, n)


def emulation_seed(rec: SimRecord) -> int:
    """Seed of a record's emulated drops, from its part, configuration and base seed."""
    key = f"{rec.meta.get('part')}|{rec.meta.get('config_id')}|{rec.meta.get('seed', 0)}|emulated"
    return int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little")


def level_drops(rec: SimRecord, n_emulated: int) -> tuple[np.ndarray, np.ndarray]:
    """Final yaws (NaN where not ok) and ok flags in drop order, for the partial levels: the
    drops themselves for drawn designs; for sampled maps ``n_emulated`` i.i.d. uniform initial
    yaws (seeded by :func:`emulation_seed`) mapped through the interpolated map."""
    if rec.design not in MAP_DESIGNS:
        return rec.yaws, rec.ok
    final, status = emulate_drops(record_design(rec), int(n_emulated), emulation_seed(rec))
    ok = status == "ok"
    return np.where(ok, final, np.nan), ok


def check_ok_mass(label: Label, min_ok_mass: float, where: str) -> None:
    """BadData when a configuration keeps less than ``min_ok_mass`` of its drops ok."""
    if label.ok_mass < min_ok_mass:
        raise BadData(
            f"{where} has ok mass {label.ok_mass:.3f} of its drops (< sim.min_ok_mass={min_ok_mass:g}; "
            + ", ".join(f"{k} {v:.3f}" for k, v in sorted(label.masses.items()) if k != "ok")
            + ")"
        )


def _frame_deg(features: Path | None) -> float:
    if features is None:
        return 0.0
    from feeder.parts.features import load_frame_deg

    return load_frame_deg(features)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder labels", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pmf", help="the label of one simulation file (any initial-yaw design)")
    p.add_argument("sim", type=Path, help="results/sim/<part>/<config>.npz")
    p.add_argument("--bins", type=int, default=DEFAULT_BINS)
    p.add_argument("--sigma", type=float, default=DEFAULT_SIGMA, help="smoothing sigma in bins")
    p.add_argument(
        "--frame",
        type=Path,
        default=None,
        help="the part's features JSON (results/features/<part>.json): label in its feature "
        "(principal) frame, as the workflow's labels; default: the part file's own frame",
    )
    p.add_argument("--out", type=Path, default=None, help="CSV with angle_deg,pmf,cdf (one row per bin)")
    args = parser.parse_args(argv)

    sim = load_sim(args.sim)
    frame_deg = _frame_deg(args.frame)
    sim.yaws = L.normalize_yaw(sim.yaws + frame_deg) if frame_deg else sim.yaws
    label = sim_label(sim, args.bins, args.sigma)
    if args.out is not None:
        import pandas as pd

        from feeder.io import write_csv

        width = 360.0 / args.bins
        write_csv(
            args.out,
            pd.DataFrame({"angle_deg": np.arange(args.bins) * width, "pmf": label.pmf, "cdf": L.cdf(label.pmf)}),
        )
    summary = {
        "file": str(args.sim),
        "design": label.design,
        "simulations": label.simulations,
        "frame": "principal" if args.frame else "part",
        "masses": {k: round(v, 6) for k, v in sorted(label.masses.items())},
        "cdf_bound": None if math.isnan(label.cdf_bound) else round(label.cdf_bound, 6),
        "mode_deg": float((np.argmax(label.pmf) + 0.5) * 360.0 / args.bins),
        "max_bin_probability": float(label.pmf.max()),
        "js_to_uniform_bits": float(L.js_divergence(label.pmf, np.full(args.bins, 1.0 / args.bins))),
    }
    json.dump(summary, sys.stdout, indent=2)
    print()
    return 0
