"""What would refining only the labels whose audit misses a target buy? (issue #38 item 2, emulated)

The study's audit (``feeder audit``) is the first audit round of the targeted design
(``feeder.sim.errest.targeted``) run on from a budget-40 label. So a second pass that refines only
the labels whose estimate misses a target is the targeted design with ``min_budget`` = 40. This
script emulates it through the design bench's 20 reference maps (as ``feeder bench-errest`` does,
simulating nothing) at several target scales, beside the study's design (budget 40 + one audit
round, estimate only) and the targeted design as configured (``min_budget`` 24), and writes the
means over the configurations and the worst configuration's coverage:

    python docs/experiments/errest_continuation.py results/tables/errest_continuation.csv

The references were simulated under the earlier pieces contact (docs/performance.md).
"""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path

import pandas as pd

from feeder import io
from feeder.bench.errest import entry_rows
from feeder.config import load_study_config
from feeder.workflow import select_settings

ROOT = Path(__file__).resolve().parents[2]
REFERENCES = ROOT / "results" / "bench" / "designs" / "fast-2880" / "reference"
SCALES = [4, 8, 12, 16, 24]
MIN_BUDGETS = [24, 40]  # the configured targeted design, and run on from the study's budget


def main(argv: list[str]) -> int:
    out = Path(argv[0])
    base = load_study_config(root=ROOT)
    rows = []
    for min_budget in MIN_BUDGETS:
        cfg = copy.deepcopy(base)
        cfg["sim"]["adaptive_target"]["min_budget"] = min_budget
        cfg["sim"]["errest_bench"]["target_scales"] = SCALES
        keys = ("labels", "sim.design_bench", "sim.errest_bench", "sim.adaptive", "sim.adaptive_target")
        settings = json.loads(select_settings(cfg, *keys, "sim.min_ok_mass", "sim.drops"))
        bench = settings["sim"]["errest_bench"]
        for ref in sorted(REFERENCES.glob("*.npz")):
            rows += [r | {"min_budget": min_budget} for r in entry_rows(ref, settings, bench)]
        print(f"min_budget {min_budget}: {len(rows)} rows", file=sys.stderr)
    frame = pd.DataFrame(rows)
    frame = frame[frame.ref_ok_mass >= base["sim"]["min_ok_mass"]]
    # the budget-40 design does not depend on min_budget: keep it once
    frame = frame[(frame.design == "targeted") | (frame.min_budget == MIN_BUDGETS[0])]
    per = frame.groupby(["design", "min_budget", "target_scale", "config"], dropna=False).agg(
        simulations=("simulations", "mean"),
        sup_cdf=("sup_cdf", "mean"),
        circular_w1_deg=("circular_w1_deg", "mean"),
        coverage_sup=("covers_sup", "mean"),
        coverage_w1=("covers_w1", "mean"),
    )
    table = per.groupby(["design", "min_budget", "target_scale"], dropna=False).agg(
        simulations=("simulations", "mean"),
        sup_cdf=("sup_cdf", "mean"),
        circular_w1_deg=("circular_w1_deg", "mean"),
        min_coverage_sup=("coverage_sup", "min"),
        min_coverage_w1=("coverage_w1", "min"),
        configurations=("simulations", "size"),
    )
    table = table.reset_index()
    table.loc[table.design == "adaptive", "min_budget"] = None
    io.write_csv(out, table)
    print(table.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
