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

from feeder.figures import _frontier, style

COLUMNS = (*_frontier.COLUMNS, "budget")


def draw(table):
    t = table[table["configurations"] == "all"]
    fig, ax = style.subplots(1, 1, figsize=(7.0, 4.5))
    _frontier.draw_answers(ax, t)
    sims = t[t["kind"] == "simulate"]
    if len(sims):
        floor = float(sims.loc[sims["budget"].astype(int).idxmax(), "circular_w1_deg"])
        budget = int(sims["budget"].astype(int).max())
        ax.axhline(floor, ls=":", color="grey", label=f"two labels of one configuration ({budget} drops)")
    ax.set_ylabel("circular W1 to the study's label (deg)")
    n = int(t["n"].max()) if len(t) else 0
    ax.set_title(f"A known part at a new angle: cost and error ({n} Test configurations)")
    ax.legend()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("frontier_known", __doc__, "the summary (frontier_known.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
