"""The shared look of every figure and the plumbing every figure module uses.

Editing this file reruns every figure (it is an input of each figure rule) and nothing else.

* :data:`RC` / :func:`apply_style`: matplotlib rcParams applied before a figure is created.
* :data:`PALETTE`: colours by meaning, so one kind of curve has one colour across figures.
* :func:`subplots`: ``plt.subplots`` with the style applied (Agg backend, no display needed).
* :func:`save`: write the figure atomically (:func:`feeder.io.save_figure`) and close it.
* :func:`read_csv` / :func:`read_npz`: read a figure's data file, one-line errors on a missing
  file, column or key.
* :func:`parser`: the ``--data`` / ``--out`` command line shared by the figure modules.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from feeder import io  # noqa: E402
from feeder.errors import FeederError  # noqa: E402

RC = {
    "font.size": 10,
    "axes.titlesize": 10,
    "axes.labelsize": 10,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "legend.fontsize": 8,
    "lines.linewidth": 1.5,
    "lines.markersize": 5,
    "errorbar.capsize": 2,
    "grid.alpha": 0.3,
    "figure.dpi": 100,
    "savefig.dpi": 150,
}

PALETTE = {
    "primary": "tab:blue",  # the measured / modelled quantity
    "secondary": "tab:orange",  # a second measured series (e.g. a reconstruction, CPU time)
    "within": "tab:green",  # within-level comparison
    "cross": "tab:red",  # cross-level comparison
    "baseline": "tab:gray",  # a no-model baseline
    "reference": "k",  # reference lines (bounds, chosen values, targets)
    "threshold": "r",  # a threshold the data is compared against
    "neutral": "0.6",  # histogram bars
    "muted": "0.5",  # a secondary baseline drawn dashed
}


def apply_style() -> None:
    matplotlib.rcParams.update(RC)


def subplots(*args, **kwargs):
    """``plt.subplots`` with :data:`RC` applied."""
    apply_style()
    return plt.subplots(*args, **kwargs)


def save(fig, path: str | os.PathLike) -> None:
    """Write ``fig`` atomically to ``path`` (format from the suffix) and close it."""
    io.save_figure(path, fig)


def read_csv(path: str | os.PathLike, columns: list[str] | tuple[str, ...]):
    """A figure's CSV data file with at least ``columns`` and one row."""
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise FeederError(f"figure data {path} is missing")
    try:
        frame = pd.read_csv(path)
    except (pd.errors.EmptyDataError, pd.errors.ParserError) as err:
        raise FeederError(f"figure data {path} is not a CSV table ({err})".replace("\n", " ")) from None
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise FeederError(f"figure data {path} lacks the column(s) {', '.join(missing)}")
    if frame.empty:
        raise FeederError(f"figure data {path} has no rows")
    return frame


def read_npz(path: str | os.PathLike, keys: list[str] | tuple[str, ...]) -> dict[str, np.ndarray]:
    """A figure's NPZ data file as a dict with at least ``keys``."""
    return io.read_npz(path, keys, what="figure data")


def parser(name: str, doc: str | None, data_help: str) -> argparse.ArgumentParser:
    """``feeder figure <name> --data FILE --out PNG`` (a module may add options)."""
    ap = argparse.ArgumentParser(prog=f"feeder figure {name}", description=(doc or "").split("\n\n")[0])
    ap.add_argument("--data", required=True, type=Path, help=data_help)
    ap.add_argument("--out", required=True, type=Path, help="image to write (format from the suffix)")
    return ap
