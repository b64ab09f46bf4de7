"""The ``feeder`` command line: one subcommand per stage, dispatched lazily.

Each stage module owns its subcommand through a ``main(argv: list[str]) -> int`` function, so
``feeder features`` never imports torch and the workflow's many small jobs start quickly.
A :class:`feeder.errors.FeederError` is printed as one line and the process exits with status 2.
"""

from __future__ import annotations

import importlib
import sys

from feeder.errors import FeederError

# subcommand -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "parts": ("feeder.parts.library", "generate the part library / write the catalog"),
    "features": ("feeder.parts.features", "print the 45 DFT shape features of a part (.xyz or .stl)"),
    "simulate": ("feeder.sim.simulate", "simulate drops of one part through one fence configuration"),
    "bench-sim": ("feeder.bench.accuracy", "accuracy-vs-time sweep of simulation settings"),
    "bench-jams": ("feeder.bench.jams", "ok and jam rates of every fence angle of the grid"),
    "bench-yaws": ("feeder.bench.yaws", "sampling error against drops for random and golden initial yaws"),
    "bench-reference": ("feeder.bench.reference", "the design bench's dense reference of one configuration"),
    "bench-designs": (
        "feeder.bench.designs",
        "each initial-yaw design's label against a dense reference, and its cost",
    ),
    "bench-emulation": (
        "feeder.bench.emulation",
        "JS(P_N, P_all) of drops emulated through the adaptive design against real independent drops",
    ),
    "bench-contact": (
        "feeder.bench.contact",
        "the belt footprint: each convex piece against footprint pads, the same drops paired",
    ),
    "bench-decomposition": (
        "feeder.bench.decomposition",
        "is the belt friction the part's or its convex pieces'? each contact model under other decompositions",
    ),
    "bench-step": (
        "feeder.bench.step",
        "what one simulation step costs against a bare one-box world, and what it is spent on",
    ),
    "bench-cost": ("feeder.bench.cost", "project the simulation stage's CPU and wall time from a sample of its jobs"),
    "bench-scheduler": ("feeder.bench.scheduler", "CPU the snakemake process spends scheduling simulation jobs"),
    "bench-predict": (
        "feeder.bench.predict",
        "time a trained model's answers: features from the STL, one configuration, the whole fence grid",
    ),
    "scene-table": ("feeder.sim.scene", "Table 1: every physical parameter of the simulated scene"),
    "labels": ("feeder.labels.pmf", "PMF/CDF labels from simulation outputs"),
    "datasets": ("feeder.labels.dataset", "configuration list, splits and the merged dataset"),
    "train": ("feeder.learn.train", "train one regression model (Hydra config)"),
    "evaluate": ("feeder.learn.evaluate", "evaluate trained models into tables"),
    "generalisation-sets": (
        "feeder.learn.generalisation_sets",
        "every predictor on unseen parts by library set: the protocol parts and the wider library",
    ),
    "predict": ("feeder.learn.predict", "predict the orientation PMF of a part and fences"),
    "recommend": ("feeder.learn.recommend", "rank fence configurations by the predicted chance of a target yaw"),
    "export-model": (
        "feeder.learn.export",
        "copy a trained model into the repository's shipped-model folder with its model card",
    ),
    "vae": ("feeder.learn.vae", "VAE training and the partial-iteration study"),
    "delta": ("feeder.learn.delta", "delta-to-full correction sweep"),
    "cost": ("feeder.report", "gather workflow benchmarks into cost_by_stage"),
    "figure": ("feeder.figures", "draw one figure from its data file"),
}


def _usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: feeder <command> [options]", "", "commands:"]
    lines += [f"  {name:<{width}}  {help_}" for name, (_, help_) in COMMANDS.items()]
    return "\n".join(lines)


def _one_line_errors(self, message: str):
    """argparse's error without the usage block: ``feeder CMD: error: MESSAGE`` on one line,
    exit 2, like every other error (``feeder CMD --help`` shows the usage)."""
    self.exit(2, f"{self.prog}: error: {message} (--help for usage)\n")


def _one_line_usage_errors() -> None:
    import argparse

    argparse.ArgumentParser.error = _one_line_errors


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in {"-h", "--help"}:
        print(_usage())
        return 0
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"feeder: unknown command {name!r} (feeder --help lists them)", file=sys.stderr)
        return 2
    _one_line_usage_errors()
    module = importlib.import_module(COMMANDS[name][0])
    try:
        return int(module.main(rest) or 0)
    except FeederError as err:
        print(f"feeder {name}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
