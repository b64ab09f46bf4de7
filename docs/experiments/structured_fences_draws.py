"""Is the Fences set's verdict on the Fences specialist a plausible draw of its parts? (issue #39)

The check built as the Fences set is (``structured_cross_only.py --combinations``) and the Fences
set itself disagree on ``model.cross_only``. This script reads both from their rows, fitting
nothing, and writes one table (``what``, ``n``, ``diff`` = specialist − default circular W1,
``diff_low``, ``diff_high``, ``share``):

* ``check``: the check's paired difference over its configurations, as its own table;
* ``check, the Fences set's parts``: the same on the check's rows of the parts the Fences set
  holds (their other two-fence combinations), with its 95 % bootstrap interval;
* ``check, draws of the Fences set's size``: ``DRAWS`` random draws of as many parts as the Fences
  set holds from the check's parts, each the mean over the drawn parts' configurations: their
  mean, their 2.5 and 97.5 percentiles, and the share of draws at least as high as the Fences
  set's difference (``share``);
* ``fences``: the Fences set's paired difference (specialist run against the default run);
* ``part <name>``: per part of the Fences set, its difference there and in the check (``check_diff``).

    python docs/experiments/structured_fences_draws.py \\
        results/tables/structured_cross_only_combinations_rows.csv \\
        results/tables/structured_crossonly_rows.csv results/tables/structured_rows.csv \\
        results/tables/structured_fences_draws.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from feeder import io
from feeder.learn.evaluate import paired_bootstrap
from feeder.learn.structured_protocol import STRUCTURED, unit_scores

BOOTSTRAP = {"resamples": 10000, "level": 0.95, "seed": 0}
DRAWS, DRAW_SEED = 20000, 0
FENCES = "fences"


def differences(run: pd.DataFrame, base: pd.DataFrame) -> pd.Series:
    """Per configuration (part, config_id), run − base circular W1 of the seeds one by one, as the
    protocol averages them, on the configurations both scored as Fences rows."""
    return (unit_scores(run, FENCES, STRUCTURED, "cw1") - unit_scores(base, FENCES, STRUCTURED, "cw1")).dropna()


def interval_row(what: str, d: pd.Series) -> dict:
    diff, lo, hi = paired_bootstrap(d.to_numpy(), BOOTSTRAP["resamples"], BOOTSTRAP["level"], BOOTSTRAP["seed"])
    return {"what": what, "n": len(d), "diff": diff, "diff_low": lo, "diff_high": hi}


def draws(check: pd.Series, n_parts: int, at_least: float) -> dict:
    """``DRAWS`` draws of ``n_parts`` parts (no part twice) from ``check``: the mean over their
    configurations; the draws' mean, central 95 % and the share at least ``at_least``."""
    groups = [g.to_numpy() for _, g in check.groupby(level="part")]
    rng = np.random.default_rng(DRAW_SEED)
    picks = (rng.choice(len(groups), n_parts, replace=False) for _ in range(DRAWS))
    means = np.array([np.concatenate([groups[k] for k in pick]).mean() for pick in picks])
    lo, hi = np.percentile(means, [2.5, 97.5])
    return {"n": n_parts, "diff": means.mean(), "diff_low": lo, "diff_high": hi, "share": (means >= at_least).mean()}


def main(argv: list[str]) -> int:
    if len(argv) != 4:
        raise SystemExit(__doc__)
    check_rows, run_rows, base_rows, out = (Path(a) for a in argv)
    rows = pd.read_csv(check_rows)
    check = differences(rows[rows.arm == "cross_only"], rows[rows.arm == "default"])
    fences = differences(pd.read_csv(run_rows), pd.read_csv(base_rows))
    parts = sorted(set(fences.index.get_level_values("part")))
    mine = check[check.index.get_level_values("part").isin(parts)]
    table = [
        interval_row("check", check),
        interval_row("check, the Fences set's parts", mine),
        {"what": "check, draws of the Fences set's size", **draws(check, len(parts), fences.mean())},
        interval_row("fences", fences),
    ]
    per_check = mine.groupby(level="part").mean()
    for part, d in fences.groupby(level="part"):
        table.append({"what": f"part {part}", "n": len(d), "diff": d.mean(), "check_diff": per_check.get(part)})
    frame = pd.DataFrame(table)
    io.write_csv(out, frame)
    print(frame.round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
