"""Which fence angles let parts through: share of ok drops against the fence angle.

Data: ``results/tables/jam_rates.csv`` (``feeder bench-jams``): ``fence``, ``angle_deg``,
``location``, ``part``, ``ok_rate`` per part and ``part = mean`` rows. One panel per fence type;
the mean over parts per location as lines, each part as faint points.
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("fence", "angle_deg", "location", "part", "ok_rate")


def draw(table):
    kinds = sorted(table["fence"].unique())
    fig, axes = style.subplots(1, len(kinds), figsize=(5.5 * len(kinds), 3.8), sharey=True, squeeze=False)
    colours = {"loc1": style.PALETTE["primary"], "loc2": style.PALETTE["secondary"]}
    for ax, kind in zip(axes[0], kinds):
        rows = table[table["fence"] == kind]
        for loc, colour in colours.items():
            at = rows[rows["location"] == loc]
            parts = at[at["part"] != "mean"]
            mean = at[at["part"] == "mean"].sort_values("angle_deg")
            ax.scatter(parts["angle_deg"], parts["ok_rate"], s=10, alpha=0.25, color=colour)
            ax.plot(
                mean["angle_deg"],
                mean["ok_rate"],
                "o-",
                color=colour,
                label=f"Location {loc[-1]} (mean of {parts['part'].nunique()} parts)",
            )
        ax.set_title(f"{kind} fence alone")
        ax.set_xlabel("fence angle to the direction of travel (deg)")
        ax.set_ylim(-0.05, 1.05)
        ax.legend(loc="lower left", fontsize=8)
    axes[0][0].set_ylabel("share of drops that pass (ok)")
    fig.suptitle("Jam survey: the rest of the drops are held by the fence")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("jam_rates", __doc__, "the jam survey (jam_rates.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
