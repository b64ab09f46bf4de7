"""feeder: predict how extruded parts leave a linear conveyor feeder with passive fences.

One module per stage of the study: ``parts`` / ``geometry`` (the part library), ``features`` (DFT
shape features), ``sim`` (pybullet drops), ``labels`` (PMF/CDF maths), ``datasets`` (splits and
scalers), ``models`` / ``train`` / ``evaluate`` (regression models), ``vae`` / ``delta`` (the VAE
and the delta-to-full model), ``report`` (tables and figures). The ``feeder`` command line
(``feeder.cli``) is how the Snakemake workflow calls each stage.
"""

import os as _os

__version__ = "0.1.0"

# OpenBLAS picks its kernels by processor when numpy loads it, and its AVX-512 ("SkylakeX") kernels
# round some small products differently from the AVX2 ("Haswell") ones that every committed
# simulation, label and pin was computed with. In a chaotic drop that last bit grows: on an AVX-512
# EPYC the pinned lshape-a `curved30_straight45` run ended 0.36 mm elsewhere (docs/testing.md). So
# where the processor has AVX2 and FMA and nobody chose a kernel, feeder asks for the AVX2 one. It
# must be set before numpy is first imported: importing feeder first does that.
BLAS_KERNEL = "Haswell"
BLAS_KERNEL_NEEDS = frozenset({"avx2", "fma"})  # /proc/cpuinfo flags the kernel runs on


def _pin_blas_kernel(environ=_os.environ, cpuinfo: str = "/proc/cpuinfo") -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to :data:`BLAS_KERNEL` in ``environ`` unless it is set already or
    the processor lacks :data:`BLAS_KERNEL_NEEDS` (or ``cpuinfo`` cannot be read); returns the
    value in effect, None if unset."""
    if "OPENBLAS_CORETYPE" in environ:
        return environ["OPENBLAS_CORETYPE"]
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return None
    if BLAS_KERNEL_NEEDS <= set(flags):
        environ["OPENBLAS_CORETYPE"] = BLAS_KERNEL
        return BLAS_KERNEL
    return None


_pin_blas_kernel()
