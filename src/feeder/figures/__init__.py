"""Drawing code of the study's figures, one module per figure, kept apart from the computation.

A compute stage writes the numbers a figure shows to a data file (CSV or NPZ); the module named
after the figure reads that file and draws it. The workflow gives every figure its own rule whose
inputs are its data file(s), its module, :mod:`feeder.figures.style` and this file, so editing
one figure's look reruns only that figure. Each module has ``draw(...) -> Figure`` (from the data)
and ``main(argv)`` (``feeder figure <name> --data FILE --out PNG``). Every data file is small and
committed with its figure (``results/tables/`` or ``results/figdata/``), so a clone redraws any
figure from its data alone, without the simulations behind it (``make fresh``, :mod:`feeder.fresh`).

=============================  ========================================  =============================================
module (= PNG name)            figure                                    data file(s), written by
=============================  ========================================  =============================================
``fig6_dft_reconstruction``    Fig. 6b: outlines and DFT reconstructions ``results/figdata/fig6_dft_reconstruction.npz``
                                                                         (``feeder parts fig6-data``)
``s1_dft_mse``                 Fig. S1: reconstruction MSE vs kept       ``results/tables/s1_dft_mse.csv``
                               coefficients                              (``feeder parts s1``)
``fig4_js_vs_drops``           Fig. 4: JS to the full run vs drops       ``results/figdata/fig4_js_vs_drops.csv``
``fig5_js_hist``               Fig. 5: JS histogram and noise floor      ``results/figdata/fig5_js_hist.npz``
``fig9_example_pmfs``          Fig. 9: example PMFs of different shapes  ``results/figdata/fig9_example_pmfs.npz``
``convergence_dkw``            ECDF distance vs drops with the DKW band  ``results/figdata/convergence_dkw.npz``
                                                                         (all four: ``feeder datasets convergence``)
``fig12_test_predictions``     Fig. 12: predicted vs simulated CDFs,     ``results/figdata/fig12_test_predictions.npz``
                               four Test rows
``fig13_parts_predictions``    Fig. 13: the same for four Parts rows     ``results/figdata/fig13_parts_predictions.npz``
                                                                         (both: ``feeder evaluate figure-data``)
``fig14_cross_convergence``    Fig. 14: P2 within vs cross convergence   ``results/tables/p2_levels.csv``
                                                                         (``feeder vae p2-gather``)
``s11_delta_sweep``            Fig. S11: delta-to-full sweep             ``results/tables/table10.csv``
                                                                         (``feeder delta table``)
``sim_accuracy_vs_time``       simulation settings: accuracy vs CPU time ``results/tables/sim_accuracy_vs_time.csv``
                                                                         (``feeder bench-sim``)
``yaw_sampling``               sampling error vs drops per yaw design    ``results/tables/yaw_sampling.csv``
                                                                         (``feeder bench-yaws``)
``step_cost``                  CPU per internal step against a bare      ``results/tables/step_cost.csv``
                               one-box world                             (``feeder bench-step``)
``sim_cost``                   CPU ms per drop of sampled simulation     ``results/tables/sim_cost_sample.csv``
                               jobs, by part                             (``feeder bench-cost``)
``cost_by_stage``              wall/CPU seconds per workflow stage       ``results/tables/cost_by_stage.csv``
                                                                         (``feeder cost``)
``frontier``                   error against CPU per answer: predictors  ``results/tables/frontier.csv``
                               and simulation budgets                    (``feeder bench-frontier``)
``frontier_known``             the same on the study's Test              ``results/tables/frontier_known.csv``
                               configurations (known parts)              (``feeder bench-frontier-known``)
=============================  ========================================  =============================================

Figure modules import only :mod:`feeder.figures.style`, the core (``feeder.io``,
``feeder.errors``) and shared drawing modules of this package (names starting with ``_``, e.g.
``_cdf_predictions`` for Figs. 12 and 13, listed as extra inputs of the figures that use them),
never a stage module.
"""

from __future__ import annotations

import importlib
import pkgutil
import re

from feeder.errors import FeederError

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_NOT_FIGURES = {"style"}


def figure_names() -> list[str]:
    """Every figure module of this package (sorted)."""
    return sorted(
        m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_") and m.name not in _NOT_FIGURES
    )


def main(argv: list[str]) -> int:
    """``feeder figure <name> [options]``: run ``feeder.figures.<name>.main(options)``."""
    names = figure_names()
    if not argv or argv[0] in {"-h", "--help"}:
        print(
            "usage: feeder figure <name> [options]   (feeder figure <name> --help)\n\nfigures:\n  " + "\n  ".join(names)
        )
        return 0
    name, rest = argv[0], argv[1:]
    if not _NAME.match(name) or name not in names:
        raise FeederError(f"unknown figure {name!r} (one of: {', '.join(names)})")
    module = importlib.import_module(f"{__name__}.{name}")
    return int(module.main(rest) or 0)
