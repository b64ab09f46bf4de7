"""Fig. 6 (panel b): part outlines and their reconstructions from the largest DFT coefficients.

Data (``results/figdata/fig6_dft_reconstruction.npz``, written by ``feeder parts fig6-data``):
``name`` (P,) part ids; ``outline`` (P, S) complex outline samples x + iy, normalised so the
canvas's drawable extent is 1; ``reconstruction`` (P, S) complex, the inverse DFT of the kept
coefficients; ``mse`` (P,) reconstruction MSE in normalised units² (longest aligned extent = 1);
``coefficients`` (scalar) the number of coefficients kept.
"""

from __future__ import annotations

import math

import numpy as np

from feeder.figures import style

KEYS = ("name", "outline", "reconstruction", "mse", "coefficients")


def draw(data: dict[str, np.ndarray]):
    names = [str(n) for n in data["name"]]
    count = int(data["coefficients"])
    n = len(names)
    cols = min(4, n)
    rows = int(math.ceil(n / cols))
    fig, axes = style.subplots(rows, cols, figsize=(3.0 * cols, 3.0 * rows), squeeze=False)
    for ax, name, z, rec, mse in zip(axes.ravel(), names, data["outline"], data["reconstruction"], data["mse"]):
        zc, rc = np.append(z, z[0]), np.append(rec, rec[0])
        ax.plot(zc.real, zc.imag, color=style.PALETTE["primary"], lw=2.0, label="outline")
        ax.plot(rc.real, rc.imag, color=style.PALETTE["secondary"], lw=1.2, label=f"{count} coefficients")
        ax.set_title(f"{name}  (MSE {float(mse):.1e})", fontsize=9)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"DFT reconstruction with the {count} largest coefficients (normalised units)")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("fig6_dft_reconstruction", __doc__, "fig6_dft_reconstruction.npz").parse_args(argv)
    data = style.read_npz(args.data, KEYS)
    if data["name"].size == 0:
        from feeder.errors import FeederError

        raise FeederError(f"figure data {args.data} holds no parts")
    style.save(draw(data), args.out)
    return 0
