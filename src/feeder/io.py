"""Atomic output: every file is written to a temporary sibling and renamed into place,
so a crash never leaves a half-written result that a rerun would trust. Also the one markdown
form of a result table (:func:`markdown_table`)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from feeder.errors import FeederError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only if the block succeeds.
    An output that cannot be written there (a directory in the way, a parent that is a file, no
    permission) is a one-line :class:`FeederError` naming it."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:
        raise FeederError(f"cannot write {path} ({err.strerror})") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp makes the file private (0600); a result gets the usual mode (0666 minus umask)
        os.chmod(tmp_path, 0o666 & ~_umask())
        try:
            os.replace(tmp_path, path)
        except OSError as err:
            raise FeederError(f"cannot write {path} ({err.strerror})") from None
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


def check_figure_path(path: str | os.PathLike) -> None:
    """FeederError unless matplotlib can write the image format of ``path``'s suffix (no suffix:
    png): check before the work whose result is drawn, so a bad name costs nothing."""
    from matplotlib.backend_bases import FigureCanvasBase

    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    formats = FigureCanvasBase.get_supported_filetypes()
    if fmt not in formats:
        raise FeederError(f"cannot draw {path}: unknown image format {fmt!r} (use one of {', '.join(sorted(formats))})")


def save_figure(path: str | os.PathLike, fig) -> None:
    """Save a matplotlib figure atomically (format from the suffix) and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    write_bytes(path, buf.getvalue())


def markdown_table(frame, caption: str) -> str:
    """A pandas DataFrame as a GitHub-markdown table under a caption line (floats to 4 significant
    digits, ``nan`` for non-finite ones; everything else as ``str``)."""

    def cell(value) -> str:
        if isinstance(value, (float, np.floating)):
            return "nan" if not np.isfinite(value) else f"{value:.4g}"
        return str(value)

    head = "| " + " | ".join(map(str, frame.columns)) + " |"
    rule = "|" + "|".join("---" for _ in frame.columns) + "|"
    body = ["| " + " | ".join(cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join([caption, "", head, rule, *body]) + "\n"


def read_npz(path: str | os.PathLike, keys=(), what: str = "npz file") -> dict:
    """An NPZ file's arrays as a dict holding at least ``keys``; a missing, unreadable or short
    file is a one-line :class:`FeederError` naming ``what`` and the path."""
    path = Path(path)
    if not path.is_file():
        raise FeederError(f"{what} {path} is missing")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise FeederError(f"{what} {path} is not a readable NPZ file ({err})".replace("\n", " ")) from None
    missing = [k for k in keys if k not in data]
    if missing:
        raise FeederError(f"{what} {path} lacks the array(s) {', '.join(missing)}")
    return data
