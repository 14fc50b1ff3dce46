"""The trapezoidal integrator as a package (step 1 of its split: the module moved as it was to
:mod:`gfb_env.integrator.stepper`; its names are re-exported here)."""

from gfb_env.integrator.options import IntegratorOptions
from gfb_env.integrator.stepper import *  # noqa: F403
from gfb_env.integrator.stepper import (  # noqa: F401  (used by name outside the module)
    DEFAULT_MAX_STEPS,
    STEPS_PER_REVOLUTION,
    PreparedCall,
    _advance_batch,
    _call_compiled,
)
from gfb_env.integrator.stepper import __all__ as _stepper_all

__all__ = [*_stepper_all, "DEFAULT_MAX_STEPS", "IntegratorOptions", "PreparedCall", "STEPS_PER_REVOLUTION"]
