"""Rows and inputs of ``dataset.npz`` for the learners (regression models, VAE, delta model).

The dataset itself is read by :func:`feeder.labels.dataset.load_dataset`; this module selects
rows from it: split masks, the seeded validation carve-out of a training set, the model inputs
scaled on training rows only, and the index of a partial level.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from feeder.errors import FeederError
from feeder.labels.grid import SPLITS


def validation_split(rows, fraction: float, seed: int, setting: str = "val_fraction") -> tuple[np.ndarray, np.ndarray]:
    """Split the row indices ``rows`` into sorted (fit, validation) indices with a seeded
    permutation: ``round(fraction · len(rows))`` validation rows, at least one on each side.
    ``setting`` names the fraction's config key in errors."""
    rows = np.asarray(rows)
    if rows.size < 2:
        raise FeederError(f"need at least 2 training rows for a validation split, got {rows.size}")
    if not 0.0 < fraction < 1.0:
        raise FeederError(f"{setting} must be in (0, 1), got {fraction}")
    n_val = int(min(max(1, round(fraction * rows.size)), rows.size - 1))
    perm = np.random.default_rng(seed).permutation(rows)
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def split_mask(data: dict[str, np.ndarray], splits: Sequence[str], what: str) -> np.ndarray:
    """Rows whose split is one of ``splits``; ``what`` names the setting in errors."""
    bad = [s for s in splits if s not in SPLITS]
    if bad:
        raise FeederError(f"{what}: unknown split names {bad} (known: {sorted(SPLITS)})")
    return np.isin(data["split"], list(splits))


def scaled_features(data: dict[str, np.ndarray], fit_mask: np.ndarray) -> np.ndarray:
    """The 53 model inputs of every row, with the scaler fitted on ``fit_mask`` rows only."""
    from feeder.labels.dataset import fit_scaler

    scaler = fit_scaler(data["part_raw"], data["feeder_raw"], fit_mask)
    return np.asarray(scaler.transform(data["part_raw"], data["feeder_raw"]), dtype=np.float64)


def level_index(levels_pct: np.ndarray, level: int) -> int:
    """Position of the partial level ``level`` (%) in the dataset's ``levels_pct``."""
    hits = np.flatnonzero(np.asarray(levels_pct) == int(level))
    if hits.size != 1:
        raise FeederError(f"level {level} % is not one of the dataset's levels {list(map(int, levels_pct))}")
    return int(hits[0])
