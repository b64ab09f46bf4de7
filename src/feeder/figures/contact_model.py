"""The belt footprint: CPU per drop against the part's convex pieces, and the drops' agreement.

Data: ``results/tables/contact_model.csv`` (``feeder bench-contact``): ``part``, ``pieces``,
``configuration``, ``footprint`` (``pieces`` or ``padsK``), ``cpu_ms_per_drop`` and
``same_basin_vs_reference`` (the same drops against the largest pad count). Left: the mean CPU
per drop over the configurations of each part against its pieces, one line per footprint. Right:
the share of drops in the same basin as under the largest pad count, same axes.
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("part", "pieces", "configuration", "footprint", "cpu_ms_per_drop", "same_basin_vs_reference")


def _footprint_order(name: str) -> tuple[int, int]:
    return (0, 0) if name == "pieces" else (1, int(name[4:]))


def per_part(table):
    """Mean over configurations: one row per (footprint, part), sorted by pieces then part."""
    cols = ["cpu_ms_per_drop", "same_basin_vs_reference"]
    means = table.groupby(["footprint", "part", "pieces"], as_index=False)[cols].mean()
    return means.sort_values(["footprint", "pieces", "part"], ignore_index=True)


def draw(table):
    means = per_part(table)
    fig, (cost, agree) = style.subplots(1, 2, figsize=(10, 3.8))
    colours = [style.PALETTE["secondary"], style.PALETTE["primary"], "tab:green", "tab:purple", "tab:brown"]
    for k, name in enumerate(sorted(means["footprint"].unique(), key=_footprint_order)):
        rows = means[means["footprint"] == name]
        colour = colours[k % len(colours)]
        label = "each convex piece" if name == "pieces" else f"{name[4:]} pads"
        cost.plot(rows["pieces"], rows["cpu_ms_per_drop"], "o-", color=colour, label=label)
        agree.plot(rows["pieces"], rows["same_basin_vs_reference"], "o-", color=colour, label=label)
    cost.set_yscale("log")
    cost.set_xlabel("convex pieces of the part")
    cost.set_ylabel("CPU per drop (ms, mean over configurations)")
    cost.set_title("What the belt contact costs")
    agree.set_xlabel("convex pieces of the part")
    agree.set_ylabel("drops in the same basin as the most pads")
    agree.set_ylim(-0.05, 1.05)
    agree.set_title("The same drops, paired")
    for ax in (cost, agree):
        ax.legend(fontsize=8)
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("contact_model", __doc__, "the belt footprint bench (contact_model.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
