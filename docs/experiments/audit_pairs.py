"""Do the labels' audit estimates hold on the study's own maps, under today's physics? (issue #38 item 1)

The design bench measures the estimate's coverage against dense reference maps, simulated under an
earlier contact model. This check uses real labels of the current study instead. For the 40 Test
configurations that ``feeder bench-frontier-known`` simulated again at budget 40 with another base
seed (``results/bench/frontier_known/sim/<part>/<config>__b40.npz``, committed), that file is a
second label L1 of the configuration, independent of the study's label L0 (``results/sim``, base
seed 0). L0's estimate e0 comes from the study's audit (``results/audit/<part>.csv``); L1 is audited
here the same way (``sim.adaptive_target.audits`` drops each, simulated). If both estimates cover
their labels' true errors, then e0 + e1 >= d(L0, L1) by the triangle inequality (both metrics are
distances). The share of configurations where this holds is a necessary condition of coverage,
checked on the study's real maps; d(L0, L1) itself is a lower bound of err0 + err1, so the ratio
(e0 + e1) / d says at most how conservative the estimates are.

    python docs/experiments/audit_pairs.py RESULTS_DIR PARTS_DIR OUT_CSV

RESULTS_DIR holds the study's ``sim/`` and ``audit/`` (e.g. a run's ``results``); the frontier's
files are read from this repository. Raw rows go to OUT_CSV; ``--summary OUT_CSV`` prints the summary.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.bench.designs import distances
from feeder.config import load_study_config
from feeder.labels import audit as A
from feeder.labels.pmf import sim_label
from feeder.parts.geometry import load_part_units
from feeder.sim.record import load_sim

ROOT = Path(__file__).resolve().parents[2]
FRONTIER = ROOT / "results" / "bench" / "frontier_known" / "sim"
BUDGET = 40  # the frontier's budget equal to the study's


def pair_row(l0_path: Path, l1_path: Path, audits0: pd.DataFrame, parts_dir: Path, settings: dict) -> dict:
    labels, sim = settings["labels"], settings["sim"]
    bins, sigma = int(labels["bins"]), float(labels["sigma_bins"])
    k, confidence = int(sim["adaptive_target"]["audits"]), float(sim["adaptive_target"]["confidence"])
    r0, r1 = load_sim(l0_path), load_sim(l1_path)
    part, config = r0.meta["part"], r0.meta["config_id"]
    assert (r1.meta["part"], r1.meta["config_id"]) == (part, config)
    drops0 = audits0[audits0.config_id == config]
    e0 = A.estimate_from_audit(r0, drops0, bins, sigma, confidence)
    geom, _ = load_part_units(parts_dir / f"{part}.stl", settings["parts"]["units"])
    drops1 = pd.DataFrame(A.audit_rows(r1, k, A.simulator(geom, r1)))
    e1 = A.estimate_from_audit(r1, drops1, bins, sigma, confidence)
    p0, p1 = sim_label(r0, bins, sigma).pmf, sim_label(r1, bins, sigma).pmf
    d = distances(p0, p1)
    return {
        "part": part,
        "config_id": config,
        "seed0": r0.meta["seed"],
        "seed1": r1.meta["seed"],
        "sup_cdf": d["sup_cdf"],
        "circular_w1_deg": d["circular_w1_deg"],
        "est0_sup_cdf": e0.sup_cdf,
        "est1_sup_cdf": e1.sup_cdf,
        "est0_circular_w1_deg": e0.circular_w1_deg,
        "est1_circular_w1_deg": e1.circular_w1_deg,
        "misses0": e0.misses,
        "misses1": e1.misses,
        "audit1_cpu_s": float(drops1.cpu_s.sum()),
    }


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    out = []
    for short, col in (("sup", "sup_cdf"), ("w1", "circular_w1_deg")):
        total = rows[f"est0_{col}"] + rows[f"est1_{col}"]
        d = rows[col]
        ratio = (total / d)[d > 0]
        out.append(
            {
                "metric": short,
                "configurations": len(rows),
                "holds": int((total >= d - 1e-12).sum()),
                "distance_mean": d.mean(),
                "estimates_sum_mean": total.mean(),
                "ratio_median": ratio.median() if len(ratio) else np.nan,
                "identical_labels": int((d == 0).sum()),
            }
        )
    return pd.DataFrame(out)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--summary"]:
        print(summary(pd.read_csv(argv[1])).to_string(index=False))
        return 0
    results, parts_dir, out = Path(argv[0]), Path(argv[1]), Path(argv[2])
    settings = load_study_config(root=ROOT)
    rows = []
    for l1 in sorted(FRONTIER.glob(f"*/*__b{BUDGET}.npz")):
        part, config = l1.parent.name, l1.name.split("__")[0]
        audits0 = A.read_drops(results / "audit" / f"{part}.csv")
        rows.append(pair_row(results / "sim" / part / f"{config}.npz", l1, audits0, parts_dir, settings))
        print(f"{len(rows)}: {part} {config}", file=sys.stderr)
    frame = pd.DataFrame(rows)
    io.write_csv(out, frame)
    print(summary(frame).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
