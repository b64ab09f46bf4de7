"""What a simulation job costs, by part: CPU milliseconds per drop of each sampled job of the
study (``feeder bench-cost``), parts sorted by their mean, with the sample mean as a dashed line.
The spread across parts is what the projection's interval comes from.

Data: ``results/tables/sim_cost_sample.csv`` (one row per sampled job: ``part``, ``config_id``,
``drops``, ``ms_per_drop``).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = ("part", "config_id", "drops", "ms_per_drop")


def draw(df):
    order = df.groupby("part")["ms_per_drop"].mean().sort_values().index.tolist()
    fig, ax = style.subplots(figsize=(max(6.0, 0.28 * len(order) + 2.0), 4.5))
    for i, part in enumerate(order):
        y = df.loc[df["part"] == part, "ms_per_drop"].to_numpy()
        ax.plot(np.full(y.size, i), y, "o", color=style.PALETTE["primary"], alpha=0.7)
    mean = float(df["ms_per_drop"].mean())
    ax.axhline(mean, color=style.PALETTE["reference"], ls="--", lw=1, label=f"sample mean {mean:.0f} ms/drop")
    ax.set_xticks(range(len(order)))
    ax.set_xticklabels(order, rotation=70, ha="right", fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("CPU ms per drop (log)")
    ax.grid(True, axis="y", which="both")
    ax.legend()
    ax.set_title(f"Simulation cost of {len(df)} sampled jobs ({int(df['drops'].iloc[0])} drops each) by part")
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("sim_cost", __doc__, "sim_cost_sample.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
