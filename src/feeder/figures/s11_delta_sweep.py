"""Supplementary Fig. S11 (P4): CDF R² of the delta-to-full correction against the partial PMF
taken as the answer, per level of drops used, for unseen parts (left) and seen parts (right).

Data: Table 10 ``results/tables/table10.csv`` (``feeder delta table``), one row per level:
``level_pct`` and, for each split mode ``part`` and ``config``, ``<mode>_r2_mean``/``_sd`` and
``<mode>_baseline_mean``/``_sd``.
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

MODES = ("part", "config")
COLUMNS = ("level_pct",) + tuple(f"{m}_{k}_{s}" for m in MODES for k in ("r2", "baseline") for s in ("mean", "sd"))


def draw(frame):
    fig, axes = style.subplots(1, 2, figsize=(10, 4), sharey=True)
    lv = frame["level_pct"].to_numpy()
    for ax, mode, title in zip(axes, MODES, ("part split (unseen parts)", "config split (seen parts)")):
        for key, color, label in (
            ("r2", style.PALETTE["primary"], "delta model"),
            ("baseline", style.PALETTE["baseline"], "partial PMF as answer"),
        ):
            m, s = frame[f"{mode}_{key}_mean"].to_numpy(), frame[f"{mode}_{key}_sd"].to_numpy()
            ax.plot(lv, m, marker="o", color=color, label=label)
            ax.fill_between(lv, m - s, m + s, color=color, alpha=0.15)
        ax.set_title(title)
        ax.set_xlabel("drops used (% of the full run)")
        ax.grid(alpha=0.3)
        lo = float(np.nanmin([(frame[f"{mode}_{k}_mean"] - frame[f"{mode}_{k}_sd"]).min() for k in ("r2", "baseline")]))
        ax.set_ylim(max(-1.5, min(0.0, lo) - 0.1), 1.05)
    axes[0].set_ylabel("CDF R² vs the 100 % CDF (mean ± 1 SD)")
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle("P4: delta-to-full correction sweep (S11)")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("s11_delta_sweep", __doc__, "Table 10 (table10.csv)").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
