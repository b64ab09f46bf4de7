"""Fig. 9: example final-yaw PMFs of different shapes (one, two, three or more peaks, the most
concentrated and the most spread-out), one panel each.

Data (``results/figdata/fig9_example_pmfs.npz``, written by ``feeder datasets convergence``):
``part``, ``config_id``, ``label`` (K,) strings; ``pmf`` (K, B) probability per yaw bin;
``yaw_deg`` (B,) the bin centres in degrees.
"""

from __future__ import annotations

import numpy as np

from feeder.errors import FeederError
from feeder.figures import style

KEYS = ("part", "config_id", "label", "pmf", "yaw_deg")


def draw(data: dict[str, np.ndarray]):
    k = len(data["pmf"])
    fig, axes = style.subplots(k, 1, figsize=(6, 1.6 * k), sharex=True, squeeze=False)
    for a, part, cid, label, pmf in zip(axes[:, 0], data["part"], data["config_id"], data["label"], data["pmf"]):
        a.plot(data["yaw_deg"], pmf, color=style.PALETTE["primary"], lw=1)
        a.set_title(f"{part} / {cid}: {label}", fontsize=8)
        a.set_ylabel("p per bin", fontsize=7)
    axes[-1, 0].set_xlabel("final yaw θ [deg]")
    return fig


def main(argv: list[str]) -> int:
    args = style.parser("fig9_example_pmfs", __doc__, "fig9_example_pmfs.npz").parse_args(argv)
    data = style.read_npz(args.data, KEYS)
    if data["pmf"].ndim != 2 or not len(data["pmf"]) or data["pmf"].shape[1] != data["yaw_deg"].size:
        raise FeederError(f"figure data {args.data}: pmf must be (K >= 1, len(yaw_deg)), got {data['pmf'].shape}")
    style.save(draw(data), args.out)
    return 0
