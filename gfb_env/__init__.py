"""gfb-env: a validated gas foil bearing (GFB) rotor simulator and Gymnasium environments.

Layers (each uses only those above it): :mod:`gfb_env.params` -> :mod:`gfb_env.model` ->
:mod:`gfb_env.equilibrium` -> :mod:`gfb_env.integrator` -> analysis -> envs.  The physics is Leister,
Baum & Seemann (2017), "On the importance of frictional energy dissipation in the prevention of
undesirable self-excited vibrations in gas foil bearing rotor systems".
"""

# No thread settings here: a library does not change its host's os.environ.  Our matrices are small
# (n ~ 500) and OpenBLAS's spinning threads collapse on shared cores (a 472 x 472 eig took 10 s with 2
# threads on a loaded 2-core machine, 0.2 s with 1), so the entry points set single-threaded BLAS
# defaults (gfb_env._threads): the `gfb` CLI and `python -m gfb_experiments.train` for the worker processes
# they start, gfb_experiments before numpy loads; the Makefile exports the same variables.

# Before any compiled function loads its on-disk cache: recompile everything if one of the files compiled
# code is built from changed since (numba's cache checks only each function's own file; gfb_env._numba_cache).
import gfb_env._numba_cache  # noqa: F401  (its import does it)

# Registers gfb_env/RunUp-v2, gfb_env/RunUpRandomized-v2, gfb_env/WhirlRecovery-v2 with gymnasium (and
# the retired -v0 and -v1 ids, which refuse with the id to use).
import gfb_env.envs  # noqa: F401
from gfb_env.equilibrium import EquilibriumError, find_equilibrium
from gfb_env.integrator import (
    AdvanceResult,
    IntegrationError,
    IntegrationStatus,
    TouchdownEvent,
    Trajectory,
    TrapezoidalIntegrator,
)
from gfb_env.model import GFBModel, Grid, StateLayout, Structure
from gfb_env.params import BearingParameters, NondimensionalParameters

__version__ = "0.1.0"

__all__ = [
    "AdvanceResult",
    "BearingParameters",
    "EquilibriumError",
    "GFBModel",
    "Grid",
    "IntegrationError",
    "IntegrationStatus",
    "NondimensionalParameters",
    "StateLayout",
    "Structure",
    "TouchdownEvent",
    "Trajectory",
    "TrapezoidalIntegrator",
    "find_equilibrium",
]
