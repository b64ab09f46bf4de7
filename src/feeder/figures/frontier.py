"""What an answer costs and how close it is: every predictor and simulation budget.

Data: ``results/tables/frontier.csv`` (``feeder bench-frontier``): per answer (``kind`` predictor
or simulate, ``budget``) and set of ``configurations`` (``all``, ``unseen``), the mean circular W1
to the dense labels with its 95 % interval (``circular_w1_deg``, ``_low``, ``_high``) and the mean
CPU seconds per answer (``cpu_s_mean``). Drawn: circular W1 against CPU seconds, log scale, all
configurations; the mean PMF, a lookup, at the axis' left edge.
"""

from __future__ import annotations

from feeder.figures import _frontier, style

COLUMNS = _frontier.COLUMNS


def draw(table):
    t = table[table["configurations"] == "all"]
    fig, ax = style.subplots(1, 1, figsize=(7.0, 4.5))
    _frontier.draw_answers(ax, t)
    ax.set_ylabel("circular W1 to the dense label (deg)")
    ax.set_title(f"What an answer costs and how close it is ({int(t['n'].max())} configurations)")
    ax.legend()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("frontier", __doc__, "the frontier summary (frontier.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
