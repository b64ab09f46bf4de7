"""Simulation files ``results/sim/<part>/<config>.npz`` (docs/data.md): writing and checked reading.

:func:`write_sim` writes what :func:`feeder.sim.simulate.simulate` returns, less its in-memory
diagnostics: the keys :data:`SIM_KEYS`. :func:`load_sim` reads a file back for the labels,
checked; anything unusable is a one-line :class:`BadData` naming the file.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeder.errors import FeederError

# the keys of a simulation file, in the order they are written (docs/data.md)
SIM_KEYS = ("final_yaw_deg", "initial_yaw_deg", "status", "wall_s", "cpu_s", "meta")
# what an adaptive design adds (feeder.sim.simulate.design_record)
DESIGN_KEYS = ("unresolved_deg", "unchecked_deg", "unresolved_share")


def write_sim(path, result: dict) -> None:
    """Write one configuration's simulation file (atomically) from :func:`feeder.sim.simulate.simulate`'s
    result; its ``diag`` stays in memory."""
    from feeder.io import write_npz

    write_npz(path, **{k: result[k] for k in SIM_KEYS + DESIGN_KEYS if k in result})


class BadData(FeederError):
    """A simulation file that cannot be used (missing, truncated, too few ok drops, ...)."""


@dataclass
class SimRecord:
    yaws: np.ndarray  # (drops,) final yaw degrees, NaN where not ok
    ok: np.ndarray  # (drops,) bool
    meta: dict
    initial: np.ndarray | None = None  # (drops,) initial yaw degrees (docs/data.md: sorted for grid/adaptive)
    status: np.ndarray | None = None  # (drops,) status strings

    @property
    def design(self) -> str:
        """The initial-yaw design that made the file (``random`` for files that predate the key)."""
        return str(self.meta.get("yaw_sampling", "random"))


def record_of(result: dict) -> SimRecord:
    """The :class:`SimRecord` of a :func:`feeder.sim.simulate.simulate` payload held in memory: what
    :func:`load_sim` reads back once it is written (``feeder recommend --verify`` labels without a file)."""
    status = np.asarray(result["status"]).astype(str)
    ok = status == "ok"
    yaws = np.asarray(result["final_yaw_deg"], dtype=np.float64)
    initial = result.get("initial_yaw_deg")
    return SimRecord(
        yaws=np.where(ok, yaws, np.nan),
        ok=ok,
        meta=json.loads(str(result["meta"])),
        initial=None if initial is None else np.asarray(initial, dtype=np.float64),
        status=status,
    )


def load_sim(path, min_ok_drops: int = 1) -> SimRecord:
    """Read and check one ``results/sim/<part>/<config>.npz``; raise :class:`BadData` naming it."""
    path = Path(path)
    if not path.is_file():
        raise BadData(f"simulation file {path} is missing")
    try:
        with np.load(path, allow_pickle=False) as z:
            for key in ("final_yaw_deg", "status"):
                if key not in z.files:
                    raise BadData(f"simulation file {path} lacks {key!r}")
            yaws = np.asarray(z["final_yaw_deg"], dtype=np.float64)
            status = np.asarray(z["status"]).astype(str)
            meta_raw = str(z["meta"]) if "meta" in z.files else "{}"
            initial = np.asarray(z["initial_yaw_deg"], dtype=np.float64) if "initial_yaw_deg" in z.files else None
    except BadData:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError) as err:
        raise BadData(f"simulation file {path} is truncated or unreadable ({type(err).__name__}: {err})") from None
    if yaws.ndim != 1 or status.shape != yaws.shape or yaws.size == 0:
        raise BadData(
            f"simulation file {path}: final_yaw_deg {yaws.shape} and status {status.shape} "
            "must be equal non-empty vectors"
        )
    ok = status == "ok"
    if not np.isfinite(yaws[ok]).all():
        raise BadData(f"simulation file {path}: an ok drop has a non-finite yaw")
    try:
        meta = json.loads(meta_raw)
    except json.JSONDecodeError:
        raise BadData(f"simulation file {path}: meta is not JSON") from None
    n_ok = int(ok.sum())
    if n_ok < min_ok_drops:
        raise BadData(f"simulation file {path} has {n_ok} ok drops of {yaws.size} (< sim.min_ok_drops={min_ok_drops})")
    return SimRecord(yaws=np.where(ok, yaws, np.nan), ok=ok, meta=meta, initial=initial, status=status)
