"""How fragile is the analytic model's exit turn to the last bits of a fence angle? (hard cases)

The dataset rebuilt on 2026-11-28 from the archived simulations (``results/archive/sim-3396802.tar.gz``)
on a machine whose OpenBLAS ran its AVX-512 kernels gave the same labels, but one analytic PMF 47
degrees (circular W1 to the label: 37.8 against 85.2) away from the run's own: keyhole-c
``straight55_straight40``. feeder now pins OpenBLAS's AVX2 kernel (docs/testing.md); this script
(importing feeder first, so under that kernel) measures how fragile the exit turn is:

1. every configuration of the study (``configurations.csv``): the base analytic PMF
   (``feeder.mechanics.distribution.analytic_distribution``) as is, and with every exit turn
   integrated at a fence angle ``NUDGE_DEG`` higher (``exit_turn`` wrapped, nothing else moved):
   the circular W1 between the two, per configuration (raw rows written);
2. keyhole-c's edge 5 on a straight fence at Location 2: the exit turn's outcome (``H`` hooked,
   ``r`` released, ``p`` phases, ``w`` wedged, ...) at 81 angles within 2e-6 degrees of 40 and at
   101 within 0.5 degrees.

    python docs/experiments/exit_turn_fragility.py CONFIGURATIONS_CSV PARTS_DIR OUT_CSV

It reads no simulation; about 2 minutes on one core.
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import feeder.mechanics.distribution as D
from feeder import io
from feeder.labels.metrics import circular_w1
from feeder.lane.fences import parse_config_id
from feeder.mechanics.exitturn import exit_turn
from feeder.mechanics.fence import default_scene, fence_models, fence_mu
from feeder.mechanics.hull import as_geometry
from feeder.mechanics.pmf import bin_masses
from feeder.parts.geometry import load_part

NUDGE_DEG = 1e-7
BINS = 360


def pmfs(conf: pd.DataFrame, parts_dir: Path, nudge: float) -> np.ndarray:
    """The base analytic PMF (unsmoothed, part frame) of every configuration, its exit turns
    integrated ``nudge`` degrees above the fence's angle; rows of zeros where nothing is ok."""
    D.exit_turn = lambda geom, k, angle, side, mu, **kw: exit_turn(geom, k, angle + nudge, side, mu, **kw)
    scene, memo, out = default_scene(), {}, []
    for part, cid in zip(conf.part, conf.config_id, strict=True):
        geom = load_part(parts_dir / f"{part}.stl", "auto")
        loc1, loc2 = parse_config_id(cid)
        d = D.analytic_distribution(geom, loc1, loc2, scene, responses=memo.setdefault(part, {}))
        out.append(bin_masses(d.yaws, d.weights, BINS))
    D.exit_turn = exit_turn
    return np.array(out)


def main(argv: list[str]) -> int:
    conf, parts_dir, out = pd.read_csv(argv[0]), Path(argv[1]), Path(argv[2])
    a, b = pmfs(conf, parts_dir, 0.0), pmfs(conf, parts_dir, NUDGE_DEG)
    ok = (a.sum(axis=1) > 0) & (b.sum(axis=1) > 0)
    w1 = np.full(len(conf), np.nan)
    w1[ok] = circular_w1(
        np.cumsum(a[ok] / a[ok].sum(1, keepdims=True), 1), np.cumsum(b[ok] / b[ok].sum(1, keepdims=True), 1)
    )
    rows = conf[["part", "config_id"]].assign(ok=ok, max_abs_diff=np.abs(a - b).max(axis=1), nudged_circular_w1_deg=w1)
    io.write_csv(out, rows)
    print(
        f"{len(conf)} configurations, {int((~ok).sum())} with no ok mass; identical (1e-12): "
        f"{int((rows.max_abs_diff < 1e-12).sum())}; moved by > 0.1 deg: {int((w1 > 0.1).sum())}"
    )
    print(rows.sort_values("nudged_circular_w1_deg", ascending=False).head(5).to_string(index=False))
    scene = default_scene()
    geom = as_geometry(load_part(parts_dir / "keyhole-c.stl", "auto"))
    side, mu = fence_models("none", "straight:40", scene)[0].side, fence_mu(scene)
    for span, n in ((2e-6, 81), (0.5, 101)):
        marks = "".join(
            {"hooked": "H", "released": "r"}.get(t.reason, t.reason[0])
            for t in (exit_turn(geom, 5, 40.0 + d, side, mu) for d in np.linspace(-span, span, n))
        )
        print(f"keyhole-c edge 5, 40 +- {span:g} deg: {marks}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
