"""Supplementary Fig. S1: DFT reconstruction error over the parts vs the number of coefficients kept.

Data: the S1 table ``results/tables/s1_dft_mse.csv`` (``feeder parts s1``): one row per number of
largest-magnitude coefficients kept (``n_coefficients``) with ``mean_mse``, ``median_mse``,
``q25_mse``, ``q75_mse`` over ``n_parts`` parts. ``--chosen`` marks the count the features use.
"""

from __future__ import annotations

from feeder.figures import style

COLUMNS = ("n_coefficients", "mean_mse", "median_mse", "q25_mse", "q75_mse", "n_parts")


def draw(frame, chosen: int):
    counts = frame["n_coefficients"].to_numpy()
    fig, ax = style.subplots(figsize=(5.5, 3.5))
    ax.plot(counts, frame["mean_mse"], marker="o", ms=3, label="mean over parts")
    ax.plot(counts, frame["median_mse"], color=style.PALETTE["primary"], ls=":", label="median")
    ax.fill_between(counts, frame["q25_mse"], frame["q75_mse"], alpha=0.25, label="interquartile range")
    ax.axvline(chosen, color=style.PALETTE["reference"], ls="--", lw=1, label=f"{chosen} coefficients")
    ax.set_yscale("log")
    ax.set_xlabel("number of largest-magnitude DFT coefficients")
    ax.set_ylabel("reconstruction MSE (normalised units²)")
    ax.set_title(f"DFT reconstruction error, {int(frame['n_parts'].iloc[0])} parts")
    ax.legend(fontsize=8)
    return fig


def main(argv: list[str]) -> int:
    ap = style.parser("s1_dft_mse", __doc__, "the S1 table (s1_dft_mse.csv)")
    ap.add_argument("--chosen", type=int, required=True, help="coefficient count to mark (the feature count)")
    args = ap.parse_args(argv)
    style.save(draw(style.read_csv(args.data, COLUMNS), args.chosen), args.out)
    return 0
