"""What an answer costs and how close it is: every predictor and simulation budget.

Data: ``results/tables/frontier.csv`` (``feeder bench-frontier``): per answer (``kind`` predictor
or simulate, ``budget``) and set of ``configurations`` (``all``, ``unseen``), the mean circular W1
to the dense labels with its 95 % interval (``circular_w1_deg``, ``_low``, ``_high``) and the mean
CPU seconds per answer (``cpu_s_mean``). Drawn: circular W1 against CPU seconds, log scale, all
configurations; the mean PMF, a lookup, at the axis' left edge.
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = (
    "configurations",
    "answer",
    "kind",
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
        for xi, yi, name in zip(x, y, g["answer"]):
            ax.annotate(name, (xi, yi), textcoords="offset points", xytext=(5, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("CPU seconds per answer (log)")
    ax.set_ylabel("circular W1 to the dense label (deg)")
    ax.set_title(f"What an answer costs and how close it is ({int(t['n'].max())} configurations)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("frontier", __doc__, "the frontier summary (frontier.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
