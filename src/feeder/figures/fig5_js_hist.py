"""Fig. 5: histogram over configurations of JS(P_N || P_full) at one partial level, with the
bootstrap noise floor of that level.

Data (``results/figdata/fig5_js_hist.npz``, written by ``feeder datasets convergence``): ``js``
(C,) bits, one value per configuration; ``noise_floor`` and ``noise_quantile`` (scalars: the
floor and the bootstrap quantile it is); ``n_drops`` (N) and ``n_drops_full`` (scalars).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

KEYS = ("js", "noise_floor", "noise_quantile", "n_drops", "n_drops_full")
BINS = 30


def draw(data: dict[str, np.ndarray]):
    floor = float(data["noise_floor"])
    fig, ax = style.subplots(figsize=(5, 3.5))
    ax.hist(data["js"], bins=BINS, color=style.PALETTE["neutral"], edgecolor=style.PALETTE["reference"])
    ax.axvline(
        floor,
        color=style.PALETTE["threshold"],
        ls="--",
        label=f"bootstrap noise floor ({float(data['noise_quantile']):g} quantile) = {floor:.3g}",
    )
    ax.set_xlabel(f"JS(P_{int(data['n_drops'])} || P_{int(data['n_drops_full'])}) [bits]")
    ax.set_ylabel("configurations")
    ax.legend(fontsize=7)
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("fig5_js_hist", __doc__, "fig5_js_hist.npz").parse_args(argv)
    style.save(draw(style.read_npz(args.data, KEYS)), args.out)
    return 0
