"""Drops needed per initial-yaw design: mean JS divergence (left) and W1 on the CDF (right) of each
design's orientation distribution to a large independent reference, against drops per
configuration, log–log; thin lines are single panel configurations.

Data: ``results/tables/yaw_sampling.csv`` (``feeder bench-yaws``): rows per design, drop count and
panel configuration plus ``config == "mean"`` rows, with ``js``, ``w1_deg`` and
``random_drops_same_w1``.
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("design", "drops", "config", "js", "w1_deg", "random_drops_same_w1", "reference_drops")


def draw(df):
    fig, axes = style.subplots(1, 2, figsize=(11, 4.5))
    designs = list(dict.fromkeys(df["design"]))
    for ax, col, label in [
        (axes[0], "js", "JS divergence to reference (bits)"),
        (axes[1], "w1_deg", "W1 on the CDF to reference (deg)"),
    ]:
        for j, design in enumerate(designs):
            sub = df[df["design"] == design]
            for _, per in sub[sub["config"] != "mean"].groupby("config"):
                per = per.sort_values("drops")
                ax.plot(per["drops"], per[col], color=f"C{j}", alpha=0.15, lw=0.8)
            mean = sub[sub["config"] == "mean"].sort_values("drops")
            ax.plot(mean["drops"], mean[col], "o-", color=f"C{j}", label=f"{design} (mean)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("drops per configuration (log)")
        ax.set_ylabel(label)
        ax.legend()
    mean = df[(df["config"] == "mean")]
    top = mean[mean["drops"] == mean["drops"].max()].set_index("design")["random_drops_same_w1"]
    same = ", ".join(f"{d}: {top[d]:.0f}" for d in designs if d in top)
    fig.suptitle(
        f"Sampling error against drops ({df[df['config'] != 'mean']['config'].nunique()} configurations, "
        f"reference {int(df['reference_drops'].iloc[0])} independent drops); independent drops with the "
        f"same W1 as {int(mean['drops'].max())}: {same}",
        fontsize=9,
    )
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("yaw_sampling", __doc__, "yaw_sampling.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
