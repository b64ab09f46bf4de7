"""How wrong each label may be, by its own audit: the cumulative share of the kept labels against
their estimated circular W1 and sup|ΔCDF|.

Data: ``results/tables/label_error_estimate.csv`` (``feeder audit table``): one row per
configuration with ``loc1``, ``loc2`` (fence types), ``kept`` and the estimates
``est_circular_w1_deg`` and ``est_sup_cdf``. Two panels (log x); one line for the one-fence
configurations, one for the two-fence ones, one for all.
"""

from __future__ import annotations

import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from feeder.figures import style

COLUMNS = ("loc1", "loc2", "kept", "est_circular_w1_deg", "est_sup_cdf")
PANELS = (
    ("est_circular_w1_deg", "estimated circular W1 to the exact label (deg)"),
    ("est_sup_cdf", "estimated sup|ΔCDF|"),
)


def fence_count(table) -> np.ndarray:
    """Fences in each configuration (0, 1 or 2)."""
    return (table["loc1"].astype(str) != "none").to_numpy(int) + (table["loc2"].astype(str) != "none").to_numpy(int)


def ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted values and the share of values at most each."""
    v = np.sort(np.asarray(values, dtype=np.float64))
    return v, np.arange(1, v.size + 1) / v.size


def draw(table):
    kept = table[table["kept"].astype(str).str.lower() == "true"]
    count = fence_count(kept)
    groups = [
        ("one fence", count == 1, style.PALETTE["primary"]),
        ("two fences", count == 2, style.PALETTE["secondary"]),
        ("all", np.ones(len(kept), bool), "black"),
    ]
    fig, axes = style.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    for ax, (column, xlabel) in zip(axes, PANELS):
        for name, mask, colour in groups:
            if not mask.any():
                continue
            x, y = ecdf(kept[column].to_numpy()[mask])
            ax.step(x, y, where="post", color=colour, label=f"{name} ({mask.sum()} labels; median {np.median(x):.3g})")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(xlabel)
        ax.legend(loc="lower right", fontsize=8)
    axes[0].set_ylabel("share of kept labels")
    fig.suptitle("Each label's own error estimate (audit drops beside it; an upper bound)")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("label_error_estimate", __doc__, "the label error table (label_error_estimate.csv)").parse_args(
        argv
    )
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
