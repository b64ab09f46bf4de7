"""The ``feeder`` command line: one subcommand per stage, dispatched lazily.

Each stage module owns its subcommand through a ``main(argv: list[str]) -> int`` function, so
``feeder features`` never imports torch and the workflow's many small jobs start quickly.
A :class:`feeder.errors.FeederError` is printed as one line and the process exits with status 2.
Output into a pipe that closes early (``feeder labels pmf sim.npz | head -1``) ends quietly with
the status of a process killed by SIGPIPE (141), as ``cat`` does. Every option's help shows its
default (:class:`DefaultsShown`).
"""

from __future__ import annotations

import importlib
import os
import sys

from feeder.errors import FeederError

SIGPIPE_STATUS = 128 + 13  # the shell's status of a process ended by SIGPIPE (signal 13)
DEFAULT_UNSET = "unset"  # how an option's help shows a default of None
DEFAULT_OFF = "off"  # how a flag's help shows its default (False)

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
    "bench-errest": ("feeder.bench.errest", "does a label's error estimate cover its error (emulated designs)"),
    "bench-mirror": ("feeder.bench.mirror", "a fence at Location 2 against its mirror image at Location 1, paired"),
    "bench-frontier": ("feeder.bench.frontier", "each predictor and simulation budget: its error against its cost"),
    "bench-frontier-known": (
        "feeder.bench.frontier_known",
        "the same on the study's Test configurations (known parts at new angles), the structured predictor included",
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
    "bench-decomposition-table": (
        "feeder.bench.decomposition_table",
        "the decomposition test's table and verdicts from its raw drops (no simulation)",
    ),
    "bench-physics": (
        "feeder.bench.physics",
        "how far the labels move with the physics: one factor at a time, the same drops, raw drops kept",
    ),
    "bench-physics-table": (
        "feeder.bench.physics_table",
        "the physics sensitivity table (shifts with intervals, floor, model errors) from its raw drops",
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
    "audit": (
        "feeder.labels.audit",
        "each grid or adaptive label's error estimate: a few audit drops simulated beside it (run), the table (table)",
    ),
    "datasets": ("feeder.labels.dataset", "configuration list, splits and the merged dataset"),
    "train": ("feeder.learn.train", "train one regression model (Hydra config)"),
    "evaluate": ("feeder.learn.evaluate", "evaluate trained models into tables"),
    "generalisation-sets": (
        "feeder.learn.generalisation_sets",
        "every predictor on unseen parts by library set: the protocol parts and the wider library",
    ),
    "neighbour": (
        "feeder.learn.neighbour",
        "known parts at new angles: the part's nearest simulated angle against the analytic PMF and the mean PMF",
    ),
    "structured": (
        "feeder.learn.structured_protocol",
        "train and score the structured predictor (candidate masses, offsets, widths, ok mass) under the protocol",
    ),
    "fit-structured": (
        "feeder.learn.structured_shipped",
        "train the shipped structured predictor on every configuration of the study (models/study answers with it)",
    ),
    "predict": ("feeder.learn.predict", "predict the orientation PMF of a part and fences"),
    "recommend": ("feeder.learn.recommend", "rank fence configurations by the predicted chance of a target yaw"),
    "export-model": (
        "feeder.learn.export",
        "copy a trained model into the repository's shipped-model folder with its model card",
    ),
    "export-study": (
        "feeder.learn.study",
        "write models/study: the study's simulated labels, which predict and recommend answer from by default",
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


class DefaultsShown:
    """A help-formatter mixin: every optional argument's help ends with its default
    (``(default: fast)``; ``unset`` for None, ``off`` for a flag), unless the help already says
    it (it names a default) or the option is required. An option without help gets the default
    alone. Mixed into whatever formatter a parser chose (:func:`_formatter_class`)."""

    def _get_help_string(self, action):
        import argparse

        text = action.help or ""
        if (
            not action.option_strings
            or action.required
            or action.default is argparse.SUPPRESS
            or "default" in text.lower()
        ):
            return text
        if action.default is None:
            shown = DEFAULT_UNSET
        elif action.default is False and action.nargs == 0:
            shown = DEFAULT_OFF
        else:
            shown = "%(default)s"
        return f"{text} (default: {shown})".strip()

    def _format_action(self, action):
        if action.option_strings and not action.help:
            import copy

            shown = self._get_help_string(action)
            if shown:  # argparse formats no help at all for an empty one
                action = copy.copy(action)
                action.help = shown
        return super()._format_action(action)


_FORMATTERS: dict[type, type] = {}


def _formatter_class(base: type) -> type:
    """``base`` (a parser's formatter class) with :class:`DefaultsShown` mixed in, made once."""
    if issubclass(base, DefaultsShown):
        return base
    if base not in _FORMATTERS:
        _FORMATTERS[base] = type(f"DefaultsShown{base.__name__}", (DefaultsShown, base), {})
    return _FORMATTERS[base]


def _get_formatter(self):
    return _formatter_class(self.formatter_class)(prog=self.prog)


def _house_argparse() -> None:
    """Every parser of the run: one-line usage errors (:func:`_one_line_errors`) and help that
    shows each option's default (:class:`DefaultsShown`)."""
    import argparse

    argparse.ArgumentParser.error = _one_line_errors
    argparse.ArgumentParser._get_formatter = _get_formatter


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush of a closed pipe is quiet."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout is not a file descriptor (a test's capture)
        pass


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; its status: 0, 2 for a :class:`FeederError` or a usage error, and
    :data:`SIGPIPE_STATUS` when the reader of stdout went away (no traceback)."""
    try:
        try:
            return _run(list(sys.argv[1:] if argv is None else argv))
        finally:  # also after argparse's --help exit: a closed pipe shows here, not at the interpreter's exit
            sys.stdout.flush()
    except BrokenPipeError:
        _silence_stdout()
        return SIGPIPE_STATUS


def _run(argv: list[str]) -> int:
    if not argv or argv[0] in {"-h", "--help"}:
        print(_usage())
        return 0
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"feeder: unknown command {name!r} (feeder --help lists them)", file=sys.stderr)
        return 2
    _house_argparse()
    module = importlib.import_module(COMMANDS[name][0])
    try:
        return int(module.main(rest) or 0)
    except FeederError as err:
        print(f"feeder {name}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
