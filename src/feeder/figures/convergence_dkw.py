"""Label convergence seen through the empirical CDF: sup |CDF_N − CDF_full| against the number of
drops N with the DKW band (left), and the share of configurations inside the band (right).

Data (``results/figdata/convergence_dkw.npz``, written by ``feeder datasets convergence``), one
entry per partial level: ``n_drops`` (N), ``q10_sup``, ``median_sup``, ``q90_sup`` (over
configurations), ``dkw_epsilon`` (the DKW half-width at N), ``fraction_inside_band``; scalars
``alpha`` and ``n_drops_full``. The left panel leaves out the full run itself (distance 0).
"""

from __future__ import annotations

import numpy as np

from feeder.figures import style

KEYS = ("n_drops", "q10_sup", "median_sup", "q90_sup", "dkw_epsilon", "fraction_inside_band", "alpha", "n_drops_full")


def draw(data: dict[str, np.ndarray]):
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    n_axis = data["n_drops"]
    alpha = float(data["alpha"])
    drops = int(data["n_drops_full"])
    keep = n_axis < drops
    fig, (a1, a2) = style.subplots(1, 2, figsize=(9, 3.5))
    a1.fill_between(
        n_axis[keep],
        data["q10_sup"][keep],
        data["q90_sup"][keep],
        color=style.PALETTE["primary"],
        alpha=0.3,
        label="10-90 % of configurations",
    )
    a1.plot(n_axis[keep], data["median_sup"][keep], "o-", color=style.PALETTE["primary"], ms=3, label="median")
    a1.plot(
        n_axis[keep], data["dkw_epsilon"][keep], "--", color=style.PALETTE["reference"], label=f"DKW ε, α={alpha:g}"
    )
    a1.set_xscale("log")
    a1.set_yscale("log")
    a1.xaxis.set_major_formatter(ScalarFormatter())
    a1.xaxis.set_minor_formatter(NullFormatter())
    a1.set_xlabel("drops N")
    a1.set_ylabel(f"sup |CDF_N − CDF_{drops}|")
    a1.legend(fontsize=7)
    a2.plot(n_axis, data["fraction_inside_band"], "o-", color=style.PALETTE["primary"], ms=3)
    a2.axhline(1 - alpha, color=style.PALETTE["reference"], ls=":", lw=1)
    a2.set_ylim(0, 1.05)
    a2.set_xlabel("drops N")
    a2.set_ylabel("fraction inside DKW band")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("convergence_dkw", __doc__, "convergence_dkw.npz").parse_args(argv)
    data = style.read_npz(args.data, KEYS)
    style.save(draw({k: np.asarray(v) for k, v in data.items()}), args.out)
    return 0
