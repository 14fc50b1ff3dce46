"""Where a number was computed: what its last bits depend on besides the code.

The compiled kernels are specialised for the host CPU by numba/LLVM, and numpy's LAPACK/BLAS pick their
kernels per CPU too, so the same code can round differently on another machine.  Measured: the
integrator benchmark took 24 292 steps on the machine of 2026-11-22 and 24 336 on an AMD znver4 with
the same code (max eccentricity equal to 5 digits).  Bit-for-bit reproducibility is therefore a
property of one machine; files of recorded results carry this fingerprint.
"""

from __future__ import annotations

__all__ = ["platform_fingerprint"]


def platform_fingerprint() -> dict[str, str]:
    """The CPU numba compiles for, and the versions of numba, llvmlite and numpy."""
    import llvmlite
    import llvmlite.binding as llvm
    import numba
    import numpy as np

    return {
        "cpu": llvm.get_host_cpu_name(),
        "numba": numba.__version__,
        "llvmlite": llvmlite.__version__,
        "numpy": np.__version__,
    }
