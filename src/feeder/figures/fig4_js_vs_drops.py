"""Fig. 4: how far the PMF from the first N drops is from the full run's PMF, against N.

Data (``results/figdata/fig4_js_vs_drops.csv``, written by ``feeder datasets convergence``): one
row per partial level, ``n_drops`` (N), ``mean_js`` and ``sd_js`` (JS(P_N || P_full) in bits over
a seeded random subset of configurations) and ``configurations`` (the subset's size).
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("n_drops", "mean_js", "sd_js", "configurations")


def draw(frame):
    fig, ax = style.subplots(figsize=(5, 3.5))
    ax.errorbar(
        frame["n_drops"],
        frame["mean_js"],
        yerr=frame["sd_js"],
        color=style.PALETTE["primary"],
        marker="o",
        ms=3,
        capsize=2,
    )
    ax.set_xlabel("drops N")
    ax.set_ylabel("JS(P_N || P_full) [bits]")
    ax.set_title(f"JS vs drops, mean ± SD over {int(frame['configurations'].iloc[0])} configurations")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("fig4_js_vs_drops", __doc__, "fig4_js_vs_drops.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
