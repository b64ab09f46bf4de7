"""A steep curved fence's tip corner, pushed drop by drop (issue #39; not wired into the model).

At ``curved:80`` the fence's tip reaches 7 mm short of the lane's centre line, and the analytic
model counts every drop as grazing the tip and leaves it untouched, while the simulator turns
90 % of them (docs/structured.md, "Curved fences"). ``feeder.mechanics.exitturn.corner_push``
lets the tip corner meet the part head on where its path first meets the outline and runs the
exit turn's phases from there. This script applies it to the drops of the one-fence
configurations at the given curved angles that the model leaves untouched, from the simulated
drop's initial yaw (drop-by-drop rows of ``docs/experiments/analytic_dropwise.py``, the scene
the rows were simulated with: the study's default), and scores both against the simulated
final yaw (both ok within ``AGREE_DEG`` modulo the symmetry period). Per angle: the weighted
share that agrees with and without the push, the difference with a 95 % bootstrap interval over
configurations, how the pushes ended (``ExitTurn.reason``) and the CPU seconds per push. Rows:
OUT_CSV, one per drop. Nothing is fitted. About a minute on one core.

    python docs/experiments/corner_push.py results/tables/analytic_dropwise.csv.gz parts OUT_CSV \
        [--angles 80,90]
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, YAW_SAME_DEG, _one_fence  # noqa: E402
from fence_tip import paired_interval  # noqa: E402

from feeder.io import write_csv  # noqa: E402
from feeder.mechanics import distribution as D  # noqa: E402
from feeder.mechanics.exitturn import corner_push  # noqa: E402
from feeder.mechanics.fence import default_scene, fence_models, fence_mu  # noqa: E402
from feeder.mechanics.hull import as_geometry  # noqa: E402
from feeder.parts.geometry import load_part  # noqa: E402


def _gap(a, b, period):
    return np.abs((a - b + period / 2) % period - period / 2)


def pushed_rows(rows: pd.DataFrame, parts_dir: Path, angles: list[int]) -> tuple[pd.DataFrame, float]:
    """One row per drop of the chosen one-fence curved configurations: the model's yaw without
    and with the corner push, and the push's reason; and the CPU seconds per push."""
    scene = default_scene()
    mu = fence_mu(scene)
    one = _one_fence(rows)
    one = one[(one.fence == "curved") & one.angle.isin(angles)]
    out, cpu, pushes = [], 0.0, 0
    for (part, config_id), g in one.groupby(["part", "config_id"]):
        geom = as_geometry(load_part(parts_dir / f"{part}.stl"))
        model = fence_models(g.loc1.iloc[0], g.loc2.iloc[0], scene)[0]
        for r in g.itertuples():
            before = r.analytic_yaw_deg
            untouched = np.isfinite(before) and _gap(before, r.initial_yaw_deg, r.period) < YAW_SAME_DEG
            after, why = before, ""
            reach = float(D._support_towards(geom, np.array([r.initial_yaw_deg]), model.side)[0])
            if untouched and reach > model.inner:  # the centred part reaches the fence's innermost point
                t0 = time.process_time()
                turn = corner_push(geom, model.exit_deg, model.side, mu, r.initial_yaw_deg, -model.tip[0])
                cpu += time.process_time() - t0
                pushes += 1
                if turn is not None:
                    after, why = (r.initial_yaw_deg + turn.delta_deg) % 360.0, turn.reason
            ok = r.status == "ok"

            def agrees(yaw, r=r, ok=ok):
                return bool(ok and np.isfinite(yaw) and _gap(r.final_yaw_deg, yaw, r.period) < AGREE_DEG)

            out.append(
                {
                    "part": part,
                    "config_id": config_id,
                    "angle": int(r.angle),
                    "weight": r.weight,
                    "initial_yaw_deg": r.initial_yaw_deg,
                    "final_yaw_deg": r.final_yaw_deg,
                    "status": r.status,
                    "model_yaw_deg": before,
                    "pushed_yaw_deg": after,
                    "push_reason": why,
                    "agree_model": agrees(before),
                    "agree_pushed": agrees(after),
                }
            )
    return pd.DataFrame(out), cpu / max(pushes, 1)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows_csv", type=Path, help="analytic_dropwise.py's rows (.csv.gz)")
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    ap.add_argument("--angles", default="80,90")
    args = ap.parse_args(argv)
    angles = [int(a) for a in args.angles.split(",")]
    df, cpu = pushed_rows(pd.read_csv(args.rows_csv), args.parts_dir, angles)
    write_csv(args.out_csv, df)
    print(f"CPU per corner push: {1e3 * cpu:.1f} ms")
    for angle, g in df.groupby("angle"):
        per = g.groupby(["part", "config_id"]).apply(
            lambda c: pd.Series(
                {
                    "model": np.average(c.agree_model, weights=c.weight),
                    "pushed": np.average(c.agree_pushed, weights=c.weight),
                }
            )
        )
        diff = (per.pushed - per.model).to_numpy()
        lo, hi = paired_interval(diff)
        reasons = g[g.push_reason != ""].push_reason.value_counts(normalize=True).round(2).to_dict()
        print(
            f"curved {angle} deg ({len(per)} configurations): agree {per.model.mean():.3f} -> "
            f"{per.pushed.mean():.3f} ({diff.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]); pushes ended: {reasons}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
