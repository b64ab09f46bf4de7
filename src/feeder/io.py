"""Atomic output: every file is written to a temporary sibling and renamed into place,
so a crash never leaves a half-written result that a rerun would trust."""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp makes the file private (0600); a result gets the usual mode (0666 minus umask)
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text(path: str | os.PathLike, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def write_json(path: str | os.PathLike, obj: Any) -> None:
    write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def write_npz(path: str | os.PathLike, **arrays: Any) -> None:
    """Compressed npz, written atomically. Arrays must not need pickling."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes(path, buf.getvalue())


def write_csv(path: str | os.PathLike, frame) -> None:
    """Write a pandas DataFrame as CSV atomically (no index)."""
    write_text(path, frame.to_csv(index=False, lineterminator="\n"))


def save_figure(path: str | os.PathLike, fig) -> None:
    """Save a matplotlib figure atomically (format from the suffix) and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    write_bytes(path, buf.getvalue())


def parse_settings(text: str, *sections: str) -> dict:
    """The ``--settings`` JSON of a command (config sections, as the workflow passes them), with
    the named top-level sections required; a one-line :class:`FeederError` otherwise."""
    from feeder.errors import FeederError

    try:
        obj = json.loads(text)
    except json.JSONDecodeError as err:
        raise FeederError(f"--settings is not valid JSON: {err.msg}") from None
    if not isinstance(obj, dict):
        raise FeederError("--settings must be a JSON object of config sections")
    missing = [s for s in sections if s not in obj]
    if missing:
        raise FeederError(f"--settings lacks the config section(s): {', '.join(missing)}")
    return obj
