"""What the study cost: wall and CPU seconds summed over the jobs of each workflow stage.

Data: ``results/tables/cost_by_stage.csv`` (``feeder cost``): ``stage``, ``jobs``, ``wall_s``,
``cpu_s`` per stage and a ``TOTAL`` row (left out of the plot).
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("stage", "jobs", "wall_s", "cpu_s")


def draw(table):
    stages = table[table["stage"] != "TOTAL"]
    fig, ax = style.subplots(figsize=(7, 0.4 * max(len(stages), 3) + 1.2))
    y = list(range(len(stages)))
    ax.barh(y, stages["wall_s"], color=style.PALETTE["primary"], label="wall s (sum over jobs)")
    ax.barh(y, stages["cpu_s"], height=0.35, color=style.PALETTE["secondary"], label="CPU s")
    ax.set_yticks(y, [f"{s} ({j} jobs)" for s, j in zip(stages["stage"], stages["jobs"])])
    ax.invert_yaxis()
    ax.set_xlabel("seconds")
    ax.set_title("Cost by workflow stage")
    ax.legend(loc="lower right")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("cost_by_stage", __doc__, "cost_by_stage.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
