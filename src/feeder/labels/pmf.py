"""``feeder labels pmf SIM.npz``: the label of one simulation file (summary on stdout)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from feeder.labels.metrics import FULL_TURN_DEG, js_divergence, pmf_from_yaws
from feeder.sim.record import load_sim


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="feeder labels", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pmf", help="summarise the labels of one simulation file")
    p.add_argument("sim", type=Path, help="results/sim/<part>/<config>.npz")
    p.add_argument("--bins", type=int, required=True)
    p.add_argument("--sigma", type=float, required=True, help="smoothing sigma in bins")
    args = parser.parse_args(argv)

    sim = load_sim(args.sim)
    pmf = pmf_from_yaws(sim.yaws[sim.ok], args.bins, args.sigma)
    summary = {
        "file": str(args.sim),
        "drops": int(sim.yaws.size),
        "ok": int(sim.ok.sum()),
        "mode_deg": float((np.argmax(pmf) + 0.5) * FULL_TURN_DEG / args.bins),
        "max_bin_probability": float(pmf.max()),
        "js_to_uniform_bits": float(js_divergence(pmf, np.full(args.bins, 1.0 / args.bins))),
    }
    json.dump(summary, sys.stdout, indent=2)
    print()
    return 0
