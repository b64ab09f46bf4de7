"""What a label costs under each initial-yaw design: mean sup|ΔCDF| (left) and circular W1 on
the CDF (right) of each design's label to the dense reference, against simulations per
configuration, log–log; bands are 95 % intervals over the emulated realisations (random,
golden, grid, and ``adaptive_emulated``: the adaptive refinement run on the reference map); the
line ``adaptive`` is the adaptive design simulated for real at its budgets (one realisation).

Data: ``results/tables/label_designs_summary.csv`` (``feeder bench-designs table``): one row per
design and drop count with ``simulations``, ``sup_cdf``, ``circular_w1_deg`` and their ``_lo`` /
``_hi`` interval columns.
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = (
    "design",
    "drops",
    "simulations",
    "configurations",
    "sup_cdf",
    "sup_cdf_lo",
    "sup_cdf_hi",
    "circular_w1_deg",
    "circular_w1_deg_lo",
    "circular_w1_deg_hi",
)


def draw(df):
    fig, axes = style.subplots(1, 2, figsize=(11, 4.5))
    df = df[df["design"] != "reference"]
    for ax, col, label in [
        (axes[0], "sup_cdf", "sup |ΔCDF| to the dense reference"),
        (axes[1], "circular_w1_deg", "circular W1 to the dense reference (deg)"),
    ]:
        for j, (design, sub) in enumerate(df.groupby("design", sort=True)):
            sub = sub.sort_values("simulations")
            ax.plot(sub["simulations"], sub[col], "o-", color=f"C{j}", label=design)
            ax.fill_between(sub["simulations"], sub[f"{col}_lo"], sub[f"{col}_hi"], color=f"C{j}", alpha=0.2, lw=0)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("simulations per configuration (log)")
        ax.set_ylabel(label)
        ax.legend()
    fig.suptitle(f"Label error against simulations ({int(df['configurations'].max())} configurations)", fontsize=9)
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("label_designs", __doc__, "label_designs_summary.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
