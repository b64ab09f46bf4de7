"""Shared drawing of Figs. 12 and 13: simulated vs predicted CDFs of a few configurations, one
panel each (the two figure modules differ only in their data file and title).

Data (``results/figdata/fig12_test_predictions.npz`` / ``fig13_parts_predictions.npz``, written by
``feeder evaluate figure-data``): ``part``, ``config_id`` (K,) strings; ``yaw_deg`` (B,) bin
edges' lower angles; ``cdf_true``, ``cdf_pred`` (K, B); ``r2`` (K,) CDF R² of each row;
``model`` and ``split`` (scalar strings).
"""

from __future__ import annotations

import numpy as np

from feeder.errors import FeederError
from feeder.figures import style

KEYS = ("part", "config_id", "yaw_deg", "cdf_true", "cdf_pred", "r2", "model", "split")


def draw(data: dict[str, np.ndarray]):
    k = len(data["cdf_true"])
    fig, axes = style.subplots(1, k, figsize=(3.6 * k, 3.2), squeeze=False, sharey=True)
    for ax, part, cid, true, pred, r2 in zip(
        axes[0], data["part"], data["config_id"], data["cdf_true"], data["cdf_pred"], data["r2"]
    ):
        ax.plot(data["yaw_deg"], true, color=style.PALETTE["reference"], lw=1.5, label="simulation")
        ax.plot(data["yaw_deg"], pred, color=style.PALETTE["cross"], lw=1.2, ls="--", label="prediction")
        ax.set_title(f"{part} | {cid}\nR² = {float(r2):.3f}", fontsize=8)
        ax.set_xlabel("yaw [deg]")
        ax.set_xlim(0, 360)
    axes[0][0].set_ylabel("CDF")
    axes[0][0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{data['model']} on {data['split']}: representative CDF predictions", fontsize=10)
    fig.tight_layout()
    return fig


def run(name: str, doc: str | None, argv: list[str]) -> int:
    args = style.parser(name, doc, f"{name}.npz").parse_args(argv)
    data = style.read_npz(args.data, KEYS)
    shape = data["cdf_true"].shape
    if len(shape) != 2 or not shape[0] or data["cdf_pred"].shape != shape or data["yaw_deg"].size != shape[1]:
        raise FeederError(f"figure data {args.data}: cdf_true/cdf_pred must both be (K >= 1, len(yaw_deg))")
    style.save(draw(data), args.out)
    return 0
