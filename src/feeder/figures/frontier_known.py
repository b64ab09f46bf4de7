"""What an answer costs for a known part at a new angle: every predictor and simulation budget.

Data: ``results/tables/frontier_known.csv`` (``feeder bench-frontier-known``): per answer (``kind``
predictor or simulate, ``budget``) and set of ``configurations`` (``all``: the Test configurations
simulated again, every answer scored; ``test``: every kept Test configuration, predictors only),
the mean circular W1 to the study's label with its 95 % interval and the mean CPU seconds per
answer. Drawn: circular W1 against CPU seconds, log scale, on the ``all`` set; the mean PMF, a
lookup, at the axis' left edge; a dotted line at the largest budget's score, how far two labels of
one configuration at that budget lie apart (differences of that size are not resolved).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = (
    "configurations",
    "answer",
    "kind",
    "budget",
    "n",
    "cpu_s_mean",
    "circular_w1_deg",
    "circular_w1_low",
    "circular_w1_high",
)
_LOOKUP_S = 1e-4  # where an answer that costs a lookup is drawn on the log axis


def draw(table):
    t = table[table["configurations"] == "all"]
    fig, ax = style.subplots(1, 1, figsize=(7.0, 4.5))
    for kind, marker in (("predictor", "o"), ("simulate", "s")):
        g = t[t["kind"] == kind]
        x = np.maximum(g["cpu_s_mean"].to_numpy(float), _LOOKUP_S)
        y = g["circular_w1_deg"].to_numpy(float)
        err = np.vstack([y - g["circular_w1_low"].to_numpy(float), g["circular_w1_high"].to_numpy(float) - y])
        ax.errorbar(x, y, yerr=err, fmt=marker, capsize=3, label=kind)
        names = g["answer"].to_numpy()
        for k, n in enumerate(np.argsort(y, kind="stable")):  # by error, alternately right and left: close ones overlap
            side = 1 if k % 2 == 0 else -1
            ax.annotate(
                names[n],
                (x[n], y[n]),
                textcoords="offset points",
                xytext=(6 * side, -3),
                ha="left" if side > 0 else "right",
                fontsize=8,
            )
    sims = t[t["kind"] == "simulate"]
    if len(sims):
        floor = float(sims.loc[sims["budget"].astype(int).idxmax(), "circular_w1_deg"])
        budget = int(sims["budget"].astype(int).max())
        ax.axhline(floor, ls=":", color="grey", label=f"two labels of one configuration ({budget} drops)")
    ax.set_xscale("log")
    ax.set_xlabel("CPU seconds per answer (log)")
    ax.set_ylabel("circular W1 to the study's label (deg)")
    n = int(t["n"].max()) if len(t) else 0
    ax.set_title(f"A known part at a new angle: cost and error ({n} Test configurations)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("frontier_known", __doc__, "the summary (frontier_known.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
