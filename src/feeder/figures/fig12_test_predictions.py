"""Fig. 12: the reference model's CDF predictions against the simulated CDFs for four Test
configurations at set quantiles of its R² (best to worst). Drawing: :mod:`feeder.figures._cdf_predictions`;
data: ``results/figdata/fig12_test_predictions.npz`` (``feeder evaluate figure-data``)."""

from __future__ import annotations

from feeder.figures._cdf_predictions import draw, run  # noqa: F401


def main(argv: list[str]) -> int:
    return run("fig12_test_predictions", __doc__, argv)
