"""A round tip caught in a notch: candidate rules for where the part goes (issue #39; "flush" adopted).

With the cap modelled (``docs/experiments/round_tip_model.py``), the exit turn still gives up on a
quarter of the steep one-fence drops: the cap reaches a concave vertex of the grown outline
(``notch``) and the model lets the part go as it is, which is always wrong. Where the simulated
part ends suggests that the cap hooks there and the part turns about it until an edge lies along
the travel direction. Which edge is not settled. (The rules are empirical: none checks whether the
corner's further path meets the part again, and after the turn it often does.)
This script patches ``feeder.mechanics.exitturn._Exit.release`` for ``notch`` (the package is not
changed; the library's own hook, the "flush" rule below since it was adopted for a round tip, is
switched off) with one rule at a time, turning the part about the corner by the smallest angle that
makes that edge parallel to the travel direction:

* ``none``: as the library (let go as it is);
* ``edge``: the outline edge the cap was on when it reached the notch;
* ``next``: the outline edge beyond the notch;
* ``flush``: the hull edge the part rested on along the face;
* ``library``: the library's hook as it is (``exit_turn(..., hook=True)``), to check that it is
  ``flush``.

Each is scored on the round-tip drops of ``docs/experiments/fence_tip.py`` (16 per configuration,
``results/tables/fence_tip.csv``): the share of drops that agree with the simulated ones (both ok
within ``AGREE_DEG``), per configuration, with a 95 % paired bootstrap interval against ``none``.
The rules were looked for on these same configurations, so the numbers are optimistic: a rule
is to be adopted only after it wins on configurations it was not chosen on (the rest of the study
once the round-tip re-baseline's labels exist: ``docs/experiments/analytic_dropwise.py``).

    python docs/experiments/notch_hook.py results/tables/fence_tip.csv parts OUT_CSV
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: OpenBLAS's AVX2 kernel (feeder/__init__.py)

# isort: on
import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from analytic_dropwise import AGREE_DEG, analytic_final  # noqa: E402
from fence_tip import paired_interval  # noqa: E402
from round_tip_model import group, round_tip_drops  # noqa: E402

import feeder.mechanics.distribution as D  # noqa: E402
import feeder.mechanics.exitturn as E  # noqa: E402
from feeder.io import write_csv  # noqa: E402
from feeder.mechanics.fence import fence_models  # noqa: E402

RULES = ("none", "edge", "next", "flush", "library")
RIGHT_ANGLE_DEG = 90.0
STRAIGHT_DEG = 180.0
_ORIGINAL_RELEASE = E._Exit.release
_ORIGINAL_EXIT_TURN = E.exit_turn
STATE = {"rule": "none", "edge": 0}  # the rule in force and the hull edge of the exit turn running


def _tracking_exit_turn(part, edge, *args, **kwargs):
    STATE["edge"] = int(edge)
    return _ORIGINAL_EXIT_TURN(part, edge, *args, **kwargs)


def _release(self, k, s, reason):
    self.hook_notch = STATE["rule"] == "library"
    if reason != "notch" or not self.concave or STATE["rule"] in ("none", "library"):
        return _ORIGINAL_RELEASE(self, k, s, reason)
    n = self.n
    a = self.poly[k]
    e = self.poly[(k + 1) % n] - a
    length = float(np.hypot(*e))
    self.X = -(self.rot() @ (a + s * e / length))  # the corner at the contact, as release does
    if STATE["rule"] == "next":
        j = (k + 1) % n if s >= length else (k - 1) % n
        e = self.poly[(j + 1) % n] - self.poly[j]
    elif STATE["rule"] == "flush":
        hull = self.geom.hull
        e = hull[(STATE["edge"] + 1) % len(hull)] - hull[STATE["edge"]]
    world = self.rot() @ e
    angle = math.degrees(math.atan2(world[1], world[0]))
    turn = math.radians((RIGHT_ANGLE_DEG - angle + RIGHT_ANGLE_DEG) % STRAIGHT_DEG - RIGHT_ANGLE_DEG)
    c, si = math.cos(turn), math.sin(turn)
    self.yaw += turn
    self.X = np.array([[c, -si], [si, c]]) @ self.X  # about the corner (the origin)
    return ("free", "notch")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fence_tip_csv", type=Path)
    ap.add_argument("parts_dir", type=Path)
    ap.add_argument("out_csv", type=Path)
    args = ap.parse_args(argv)
    E._Exit.release = _release
    D.exit_turn = _tracking_exit_turn
    configs = round_tip_drops(args.fence_tip_csv, args.parts_dir)
    scene, mu = next(configs)
    rows = []
    for part, config_id, geom, loc1, loc2, y0, period, ok, final, _ in configs:
        fences = fence_models(loc1, loc2, scene)
        for rule in RULES:
            STATE["rule"] = rule
            try:
                ana, _ = analytic_final(geom, fences, y0, mu, {})
            except ValueError:  # a fence rolls the part: no yaw per drop
                break
            d = np.abs((final - ana + period / 2) % period - period / 2)
            agree = float(np.mean(ok & np.isfinite(ana) & (d < AGREE_DEG)))
            rows.append({"part": part, "config_id": config_id, "group": group(config_id), "rule": rule, "agree": agree})
    out = pd.DataFrame(rows)
    write_csv(args.out_csv, out)
    wide = out.pivot_table(index=["group", "part", "config_id"], columns="rule", values="agree")
    for name, g in wide.groupby(level=0):
        parts = [f"{name} ({len(g)}): none {g['none'].mean():.3f}"]
        for rule in RULES[1:]:
            diff = (g[rule] - g["none"]).to_numpy()
            lo, hi = paired_interval(diff)
            parts.append(f"{rule} {g[rule].mean():.3f} ({diff.mean():+.3f} [{lo:+.3f}, {hi:+.3f}])")
        print("; ".join(parts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
