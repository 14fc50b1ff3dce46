"""gfb-env: a validated gas foil bearing (GFB) rotor simulator and Gymnasium environments.

Layers (each uses only those above it): :mod:`gfb_env.params` -> :mod:`gfb_env.model` ->
:mod:`gfb_env.equilibrium` -> :mod:`gfb_env.integrator` -> analysis -> envs.  The physics is Leister,
Baum & Seemann (2017), "On the importance of frictional energy dissipation in the prevention of
undesirable self-excited vibrations in gas foil bearing rotor systems".
"""

import os

# Single-threaded BLAS by default: our matrices are small (n ~ 500) and OpenBLAS's spinning threads
# collapse when the cores are shared (a 472 x 472 eig took 10 s with 2 threads on a loaded 2-core
# machine, 0.2 s with 1).  Only effective when gfb_env is imported before numpy; the Makefile exports
# the same variables.  Set them yourself to override.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Registers gfb_env/RunUp-v0, gfb_env/RunUpRandomized-v0, gfb_env/WhirlRecovery-v0 with gymnasium.
import gfb_env.envs  # noqa: E402, F401
from gfb_env.equilibrium import EquilibriumError, find_equilibrium  # noqa: E402
from gfb_env.integrator import (  # noqa: E402
    AdvanceResult,
    IntegrationError,
    IntegrationStatus,
    TouchdownEvent,
    Trajectory,
    TrapezoidalIntegrator,
)
from gfb_env.model import GFBModel, Grid, StateLayout, Structure  # noqa: E402
from gfb_env.params import BearingParameters, NondimensionalParameters  # noqa: E402

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
