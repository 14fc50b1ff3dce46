"""gfb-env: a validated gas foil bearing (GFB) rotor simulator and Gymnasium environments.

Layers (each uses only those above it): :mod:`gfb_env.params` -> :mod:`gfb_env.model` ->
:mod:`gfb_env.integrator` -> analysis -> envs.  The physics is Leister, Baum & Seemann (2017),
"On the importance of frictional energy dissipation in the prevention of undesirable self-excited
vibrations in gas foil bearing rotor systems".
"""

from gfb_env.integrator import (
    AdvanceResult,
    EquilibriumError,
    IntegrationError,
    TouchdownEvent,
    Trajectory,
    TrapezoidalIntegrator,
    find_equilibrium,
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
    "NondimensionalParameters",
    "StateLayout",
    "Structure",
    "TouchdownEvent",
    "Trajectory",
    "TrapezoidalIntegrator",
    "find_equilibrium",
]
