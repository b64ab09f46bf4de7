"""What a simulation job costs, by part: CPU milliseconds per drop of each sampled job of the
study (``feeder bench-cost``), parts sorted by their mean, with the sample mean as a dashed line;
one colour per initial-yaw design (the study's and the baseline, on the same configurations).
The spread across parts is what the projection's interval comes from.

Data: ``results/tables/sim_cost_sample.csv`` (one row per sampled job: ``part``, ``config_id``,
``drops``, ``ms_per_drop``; optional ``yaw_sampling`` and ``design_drops``, the design, else one).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = ("part", "config_id", "drops", "ms_per_drop")


COLOURS = ("primary", "secondary", "within", "cross")


def _designs(df):
    """[(label, rows)] of each design of the sample, in the order they appear."""
    if "yaw_sampling" not in df.columns:
        return [(f"{int(df['drops'].iloc[0])} drops", df)]
    keys = ["yaw_sampling", "design_drops"] if "design_drops" in df.columns else ["yaw_sampling"]
    out = []
    for key, rows in df.groupby(keys, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        drops = rows["drops"]
        run = f"{int(drops.iloc[0])} drops" if drops.nunique() == 1 else f"{drops.mean():.0f} simulations on average"
        budget = f" (budget {int(key[1])})" if len(key) > 1 and key[0] == "adaptive" else ""
        out.append((f"{key[0]}{budget}: {run}", rows))
    return out


def draw(df):
    designs = _designs(df)
    first = designs[0][1]
    order = first.groupby("part")["ms_per_drop"].mean().sort_values().index.tolist()
    order += sorted(set(df["part"]) - set(order))
    fig, ax = style.subplots(figsize=(max(6.0, 0.28 * len(order) + 2.0), 4.5))
    width = 0.5 / max(1, len(designs) - 1) if len(designs) > 1 else 0.0
    for k, (label, rows) in enumerate(designs):
        colour = style.PALETTE[COLOURS[k % len(COLOURS)]]
        shift = (k - (len(designs) - 1) / 2) * width
        for i, part in enumerate(order):
            y = rows.loc[rows["part"] == part, "ms_per_drop"].to_numpy()
            ax.plot(np.full(y.size, i + shift), y, "o", color=colour, alpha=0.7, label=label if i == 0 else None)
        mean = float(rows["ms_per_drop"].mean())
        ax.axhline(mean, color=colour, ls="--", lw=1, label=f"mean {mean:.0f} ms/drop")
    ax.set_xticks(range(len(order)))
    ax.set_xticklabels(order, rotation=70, ha="right", fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("CPU ms per drop (log)")
    ax.grid(True, axis="y", which="both")
    ax.legend(fontsize=8)
    ax.set_title(f"Simulation cost of {len(first)} sampled configurations by part and design")
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("sim_cost", __doc__, "sim_cost_sample.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
