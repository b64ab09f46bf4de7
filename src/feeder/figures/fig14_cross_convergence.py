"""Fig. 14 (P2): VAEs trained on the CDFs of each partial iteration level, scored on a shared
holdout against the same level (within-level) and against the full run (cross-convergence), with
the level's CDF itself compared to the full run as the no-model reference.

Data: the P2 table ``results/tables/p2_levels.csv`` (``feeder vae p2-gather``), one row per level:
``level_pct``, ``within_r2_mean``/``_sd``, ``cross_r2_mean``/``_sd``, ``partial_baseline_r2_mean``.
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = ("level_pct", "within_r2_mean", "within_r2_sd", "cross_r2_mean", "cross_r2_sd", "partial_baseline_r2_mean")


def draw(frame):
    fig, ax = style.subplots(figsize=(7, 4.2))
    lv = frame["level_pct"].to_numpy()
    ax.errorbar(
        lv,
        frame["within_r2_mean"],
        yerr=frame["within_r2_sd"],
        color=style.PALETTE["within"],
        marker="o",
        capsize=3,
        label="within-level (level-k input, level-k target)",
    )
    ax.errorbar(
        lv,
        frame["cross_r2_mean"],
        yerr=frame["cross_r2_sd"],
        color=style.PALETTE["cross"],
        marker="s",
        capsize=3,
        label="cross-convergence (level-k input, 100 % target)",
    )
    ax.plot(
        lv,
        frame["partial_baseline_r2_mean"],
        color=style.PALETTE["muted"],
        ls="--",
        marker=".",
        label="level-k CDF itself vs 100 % (no model)",
    )
    ax.set_xlabel("simulation drops used (% of the full run)")
    ax.set_ylabel("CDF R² on the shared holdout (mean ± 1 SD)")
    ax.set_xticks(lv)
    ax.tick_params(axis="x", labelsize=7)
    lo = float(
        np.nanmin(
            np.concatenate(
                [(frame[f"{k}_mean"] - frame[f"{k}_sd"]).to_numpy() for k in ("within_r2", "cross_r2")]
                + [frame["partial_baseline_r2_mean"].to_numpy()]
            )
        )
    )
    ax.set_ylim(max(-1.0, min(0.0, lo) - 0.05), 1.05)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("P2: VAEs trained per iteration level (Fig. 14)")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("fig14_cross_convergence", __doc__, "the P2 table (p2_levels.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
