"""Shared fixtures: the default synthetic datasets of ``factories.py``, built once per session,
and every test's pyplot figures closed after it.

They are read-only; a test that needs other arguments calls the factory itself
(``from factories import make_regression_dataset, make_level_dataset``).
"""

from __future__ import annotations

# isort: off
import feeder  # noqa: F401 - first, before numpy loads: it pins OpenBLAS's kernel (feeder/__init__.py)

# isort: on
import pytest
from factories import make_level_dataset, make_regression_dataset


@pytest.fixture(scope="session")
def regression_dataset(tmp_path_factory):
    """dataset.npz of :func:`factories.make_regression_dataset` with its defaults."""
    path = tmp_path_factory.mktemp("regression") / "dataset.npz"
    make_regression_dataset(path)
    return path


@pytest.fixture(scope="session")
def push_regression_dataset(tmp_path_factory):
    """dataset.npz of :func:`factories.make_regression_dataset` with the synthetic push block."""
    path = tmp_path_factory.mktemp("regression_push") / "dataset.npz"
    make_regression_dataset(path, push=True)
    return path


@pytest.fixture(scope="session")
def level_dataset(tmp_path_factory):
    """dataset.npz of :func:`factories.make_level_dataset` with its defaults."""
    path = tmp_path_factory.mktemp("levels") / "dataset.npz"
    make_level_dataset(path)
    return path


@pytest.fixture(autouse=True)
def _close_figures():
    """Figures a test draws and returns are closed after it (pyplot keeps them otherwise)."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")
