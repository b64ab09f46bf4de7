"""Check (issue #37/#38, 2026-11-25, session 25): do 1.67 ms steps move the labels of the default
physics (16 pads + outline) more than the label floor, paired against 0.5 ms? Not part of the
workflow. From the repository root:

    .venv/bin/python docs/experiments/step_against_reference.py OUT_RAW.csv

Composes one raw file of ``feeder bench-physics`` drops, all on the same 31 configurations and
initial yaws (grid of 20, seed 0, one drop per world), from three committed runs:

- the reference (``baseline``): the ``step_x0.5`` drops of ``results/bench/physics/physics_drops.csv``
  (the default scene at 0.5 ms);
- the floor rows (second grid offset, yaws nudged by 0.01 deg) of that run's 1 ms baseline;
- ``step1ms``: that run's 1 ms baseline drops;
- ``step1.67ms`` and ``step2.5ms``: ``results/bench/physics/adoption/step167_drops.csv``;
- ``step1.67ms_iters5``: ``step167_iterations_drops.csv`` (1.67 ms with half the solver iterations).

The 1 ms baselines of the two runs, and the 1.67 ms rows of the two adoption runs, are
bit-identical (checked here). Then ``feeder bench-physics-table --raw OUT_RAW.csv`` gives
``results/bench/physics/adoption/step167_vs_0.5ms_table.csv``. Its floor row mixes 0.5 ms and 1 ms
runs: read the floor from ``results/tables/physics_sensitivity.csv`` instead.
"""

from __future__ import annotations

import sys

import pandas as pd

SENS = "results/bench/physics/physics_drops.csv"
STEP = "results/bench/physics/adoption/step167_drops.csv"
ITERS = "results/bench/physics/adoption/step167_iterations_drops.csv"
KEY = ["part", "configuration", "drop"]


def first_run(df: pd.DataFrame, factor: str) -> pd.DataFrame:
    """The drops of ``factor`` at the first offset, not nudged."""
    return df[(df.factor == factor) & (df.offset == "a") & (df.yaw_shift_deg == 0)]


def same(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    m = a.merge(b, on=KEY)
    return len(m) == len(a) == len(b) and bool((m.final_yaw_deg_x.fillna(-1) == m.final_yaw_deg_y.fillna(-1)).all())


def main(out: str) -> None:
    sens, step, iters = pd.read_csv(SENS), pd.read_csv(STEP), pd.read_csv(ITERS)
    if not same(first_run(sens, "baseline"), first_run(step, "baseline")):
        raise SystemExit("the 1 ms baselines of the two runs differ: not one experiment")
    if not same(first_run(step, "step1.67ms"), first_run(iters, "baseline")):
        raise SystemExit("the 1.67 ms drops of the two adoption runs differ: not one experiment")
    ref = first_run(sens, "step_x0.5").assign(factor="baseline", path=float("nan"), level=float("nan"))
    floor = sens[(sens.factor == "baseline") & ~((sens.offset == "a") & (sens.yaw_shift_deg == 0))]
    one = first_run(sens, "baseline").assign(factor="step1ms", path="preset.substeps", level="=5")
    half_iters = iters[iters.factor != "baseline"].assign(factor="step1.67ms_iters5")
    pd.concat([ref, floor, one, step[step.factor != "baseline"], half_iters]).to_csv(out, index=False)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    main(sys.argv[1])
