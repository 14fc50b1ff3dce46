"""Single-threaded BLAS defaults for the entry points (never set on ``import gfb_env``).

The dense solves are small (n ~ 500): threaded BLAS only thrashes on shared cores.  OpenBLAS/MKL/OpenMP
read these variables when the library loads, so setting them in a process that already imported numpy
takes effect in the processes it starts (sweep and vector-env workers), not in itself; the ``gfb_experiments``
package sets them before numpy loads, the Makefile exports them.  A value already set is kept.
"""

from __future__ import annotations

import os

__all__ = ["THREAD_VARIABLES", "set_thread_defaults"]

THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def set_thread_defaults(threads: int = 1) -> None:
    """``os.environ.setdefault`` of the BLAS/OpenMP thread counts (call from an entry point only)."""
    for var in THREAD_VARIABLES:
        os.environ.setdefault(var, str(int(threads)))
