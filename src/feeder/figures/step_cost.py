"""What one simulation step costs: the study's scene against a bare one-box world.

Data: ``results/tables/step_cost.csv`` (``feeder bench-step``): ``part``, ``configuration``,
``world`` (``bare``: the part's box on a floor; ``drop``: real drops of the scene),
``us_per_step`` with ``us_per_step_low``/``_high`` (Bullet's CPU per internal step, interval
across repeats), ``us_per_step_all`` (drops: the Python loop included), ``mean_contact_points``
and the fitted ``us_at_no_contact`` and ``us_per_contact_point``. Left: CPU per internal step of
each part and world (error bars: the interval), the drops' total as a hollow marker. Right: CPU
per internal step against the mean contact points, each drop row with its fitted line.
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = (
    "part",
    "configuration",
    "world",
    "us_per_step",
    "us_per_step_low",
    "us_per_step_high",
    "us_per_step_all",
    "mean_contact_points",
    "us_at_no_contact",
    "us_per_contact_point",
)


def rows_in_order(table):
    """The rows as drawn: per part, the bare world first, then each configuration's drops."""
    table = table.fillna({"configuration": ""})
    order = table.assign(_bare=table["world"] != "bare").sort_values(["part", "_bare", "configuration"])
    return order.drop(columns="_bare").reset_index(drop=True)


def draw(table):
    rows = rows_in_order(table)
    fig, (bars, fit) = style.subplots(1, 2, figsize=(11, 4.0))
    colours = {"bare": style.PALETTE["secondary"], "drop": style.PALETTE["primary"]}
    x = np.arange(len(rows))
    low = (rows["us_per_step"] - rows["us_per_step_low"]).fillna(0.0)
    high = (rows["us_per_step_high"] - rows["us_per_step"]).fillna(0.0)
    bars.bar(x, rows["us_per_step"], color=[colours.get(w, "grey") for w in rows["world"]])
    bars.errorbar(x, rows["us_per_step"], yerr=[low, high], fmt="none", ecolor="black", capsize=3)
    drops = rows["world"] == "drop"
    bars.plot(
        x[drops], rows.loc[drops, "us_per_step_all"], "o", mfc="none", color="black", label="with the Python loop"
    )
    labels = [f"{p}\n{c or 'bare box'}" for p, c in zip(rows["part"], rows["configuration"])]
    bars.set_xticks(x, labels, rotation=60, ha="right", fontsize=7)
    bars.set_ylabel("CPU per internal step (µs)")
    bars.set_title("Bullet's step: a bare box world and the scene's drops")
    bars.legend(fontsize=8)
    for _, row in rows[drops].iterrows():
        line = fit.plot(row["mean_contact_points"], row["us_per_step"], "o")[0]
        if np.isfinite(row["us_per_contact_point"]):
            pts = np.linspace(0.0, max(row["mean_contact_points"] * 2.0, 1.0), 2)
            fit.plot(
                pts,
                row["us_at_no_contact"] + row["us_per_contact_point"] * pts,
                "-",
                color=line.get_color(),
                alpha=0.5,
                label=f"{row['part']} {row['configuration']}",
            )
    bare = rows[rows["world"] == "bare"]
    fit.plot(bare["mean_contact_points"], bare["us_per_step"], "s", color=colours["bare"], label="bare box")
    fit.set_xlabel("contact points of the part (mean over steps)")
    fit.set_ylabel("CPU per internal step (µs)")
    fit.set_title("The step's cost follows the contacts")
    fit.legend(fontsize=7)
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("step_cost", __doc__, "the step bench (step_cost.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
