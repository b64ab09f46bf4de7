"""Pins recorded on one machine and checked on any x86-64 machine (docs/testing.md, "Pins").

A golden file stores the values themselves and ``recorded_on``: what decided their floating-point
arithmetic (:func:`arithmetic`). Where the current process has the same arithmetic, the values
must be equal to the bit (a refactor changes nothing); elsewhere within the pin's stated relative
tolerance (numpy's and torch's kernels dispatch to other
vector code on another CPU: AVX2 or AVX-512, other sums, other last bits).

The AVX2 arithmetic of the recording machine can be had on an AVX-512 machine, to check the pins
to the bit there too::

    NPY_DISABLE_CPU_FEATURES=X86_V4,AVX512_ICL ATEN_CPU_CAPABILITY=avx2 pytest tests/<file>
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
from pathlib import Path

import numpy as np

# the environment that gives, on an AVX-512 machine, the arithmetic the golden files were recorded with
AVX2_ENV = {"NPY_DISABLE_CPU_FEATURES": "X86_V4,AVX512_ICL", "ATEN_CPU_CAPABILITY": "avx2"}


# besides the library versions: what else a fingerprint holds (same_arithmetic tells them apart)
_FIXED_KEYS = ("machine", "cpu", "openblas_coretype", "libc", "numpy_simd", "torch_cpu")


def cpu_model() -> str:
    """The processor's model name (Linux ``/proc/cpuinfo``; the platform's word elsewhere): BLAS
    picks its kernels by processor, so two machines with the same libraries and SIMD level can still
    sum in another order."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def arithmetic(*dists: str) -> dict:
    """The library versions (``dists``), the processor and the BLAS core type forced on it
    (``OPENBLAS_CORETYPE``), the C library, and which vector code numpy and (if named) torch
    dispatch to in this process: equal dicts give equal bits."""
    from numpy._core import _multiarray_umath as mu

    out = {
        "machine": platform.machine(),
        "cpu": cpu_model(),
        "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE", ""),
        "libc": "-".join(platform.libc_ver()),
    }
    out.update({d: importlib.metadata.version(d) for d in dists})
    out["numpy_simd"] = [t for t in mu.__cpu_dispatch__ if mu.__cpu_features__.get(t)]
    if "torch" in dists:
        import torch

        out["torch_cpu"] = torch.backends.cpu.get_cpu_capability()
    return out


def same_arithmetic(recorded_on: dict) -> bool:
    dists = [k for k in recorded_on if k not in _FIXED_KEYS]
    return arithmetic(*dists) == recorded_on


def assert_pinned(got, want, recorded_on: dict, rtol: float, atol: float | None = None, what: str = "") -> None:
    """``got`` equals the pinned ``want`` to the bit under the recording arithmetic, and under any
    other within ``rtol`` of each value plus ``atol`` (default: ``rtol`` times the array's largest
    magnitude); NaN where the pin has NaN."""
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert got.shape == want.shape, f"{what}: shape {got.shape} != pinned {want.shape}"
    if same_arithmetic(recorded_on):
        assert got.tobytes() == want.tobytes(), f"{what}: not bit-identical to the pin (same arithmetic)"
    else:
        if atol is None:
            atol = rtol * (float(np.nanmax(np.abs(want))) if np.isfinite(want).any() else 0.0)
        np.testing.assert_allclose(got, want, rtol=rtol, atol=atol, equal_nan=True, err_msg=what)
