"""Drawing shared by the two frontier figures (``frontier``, ``frontier_known``): each answer's
error against its CPU seconds per answer, predictors and simulation budgets."""

from __future__ import annotations

import numpy as np

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
LOOKUP_S = 1e-4  # where an answer that costs a lookup is drawn on the log axis


def draw_answers(ax, table) -> None:
    """Every answer of ``table`` (one set of configurations) as a point with its 95 % interval at
    its CPU seconds (log axis), named beside it: by error, alternately right and left, so that
    answers of nearly equal cost and error stay readable."""
    for kind, marker in (("predictor", "o"), ("simulate", "s")):
        g = table[table["kind"] == kind]
        x = np.maximum(g["cpu_s_mean"].to_numpy(float), LOOKUP_S)
        y = g["circular_w1_deg"].to_numpy(float)
        err = np.vstack([y - g["circular_w1_low"].to_numpy(float), g["circular_w1_high"].to_numpy(float) - y])
        ax.errorbar(x, y, yerr=err, fmt=marker, capsize=3, label=kind)
        names = g["answer"].to_numpy()
        for k, n in enumerate(np.argsort(y, kind="stable")):
            side = 1 if k % 2 == 0 else -1
            ax.annotate(
                names[n],
                (x[n], y[n]),
                textcoords="offset points",
                xytext=(6 * side, -3),
                ha="left" if side > 0 else "right",
                fontsize=8,
            )
    ax.set_xscale("log")
    ax.set_xlabel("CPU seconds per answer (log)")
    ax.grid(True, alpha=0.3)
