"""Fig. 13: the reference model's CDF predictions against the simulated CDFs for four Parts
(unseen part) configurations at set quantiles of its R². Drawing: :mod:`feeder.figures._cdf_predictions`;
data: ``results/figdata/fig13_parts_predictions.npz`` (``feeder evaluate figure-data``)."""

from __future__ import annotations

from feeder.figures._cdf_predictions import draw, run  # noqa: F401


def main(argv: list[str]) -> int:
    return run("fig13_parts_predictions", __doc__, argv)
