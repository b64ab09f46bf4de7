"""Emulated against real drops: ECDFs over configurations of JS(P_N, P_all) (bits, log scale),
one panel per N, for the real independent drops (black), the first emulated realisation (solid)
and all realisations pooled (dashed). Curves on top of each other: the partial-iteration studies
can use drops emulated through a sampled map.

Data: ``results/tables/label_emulation.csv`` (``feeder bench-emulation table``): one row per
configuration, N (``n_drops``), ``source`` (real / emulated) and ``repeat``, with ``js`` and
``usable`` (configurations the study would drop are not drawn).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

COLUMNS = ("config", "n_drops", "source", "repeat", "js", "usable")
FLOOR = 1e-6  # JS values below this are drawn at it (log axis)


def _ecdf(ax, values, **kwargs):
    x = np.sort(np.maximum(np.asarray(values, dtype=np.float64), FLOOR))
    ax.step(x, np.arange(1, x.size + 1) / x.size, where="post", **kwargs)


def draw(df):
    df = df[df["usable"].astype(bool) & np.isfinite(df["js"])]
    levels = sorted(df["n_drops"].unique())
    fig, axes = style.subplots(1, max(1, len(levels)), figsize=(4.2 * max(1, len(levels)), 3.8), squeeze=False)
    for ax, n in zip(axes[0], levels, strict=False):
        g = df[df["n_drops"] == n]
        real, emu = g[g["source"] == "real"], g[g["source"] == "emulated"]
        _ecdf(ax, real["js"], color=style.PALETTE["reference"], label=f"real ({len(real)})")
        _ecdf(ax, emu[emu["repeat"] == 0]["js"], color=style.PALETTE["primary"], label="emulated, first realisation")
        _ecdf(
            ax,
            emu["js"],
            color=style.PALETTE["primary"],
            ls="--",
            alpha=0.7,
            label=f"emulated, {emu['repeat'].nunique()} realisations",
        )
        ax.set_xscale("log")
        ax.set_xlabel(f"JS(P_{n}, P_all) (bits, log)")
        ax.set_ylabel("fraction of configurations")
        ax.set_title(f"N = {n}")
        ax.grid(True)
        ax.legend(loc="upper left")
    fig.suptitle(f"Emulated against real drops ({df['config'].nunique()} configurations)", fontsize=9)
    fig.tight_layout()
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("label_emulation", __doc__, "label_emulation.csv").parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS)), args.out)
    return 0
