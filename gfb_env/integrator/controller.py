"""The step-size controller of the trapezoidal stepper (Hairer & Wanner, *Solving ODEs II*, Sect. IV.8).

After an accepted step with error norm ``err <= 1`` the next step is
``h * clip(safety * err^error_exponent, min_factor, max_factor)`` (``max_factor`` for ``err == 0``; a
step truncated to hit the end of the call keeps the previous proposal unless the error asks for less),
at most ``max_step``; after a rejected one ``h * max(min_factor, reject_safety * err^error_exponent)``;
a Newton failure (or a singular factorisation) multiplies h by ``newton_failure_factor``.  The
trapezoidal rule's local error is O(h^3), hence the exponent -1/3.

:class:`StepSizeController` holds the constants (part of
:class:`~gfb_env.integrator.IntegratorOptions`); the compiled loop reads them from its options group
(:class:`~gfb_env.integrator.arguments.LoopOptions`) through the two functions below.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields

from numba import njit

__all__ = ["StepSizeController"]


@dataclass(frozen=True)
class StepSizeController:
    """The constants of the step-size control (see the module docstring for the rule).

    Attributes:
        safety: factor on the optimal step after an accepted step, in (0, 1].
        reject_safety: the same after a rejected step (milder), in (0, 1].
        min_factor: the step shrinks by at most this factor per step, in (0, 1).
        max_factor: the step grows by at most this factor per step, > 1.
        error_exponent: the exponent of the error norm, < 0 (-1/3: local error O(h^3)).
        newton_failure_factor: the step's factor after a Newton failure, in (0, 1).
    """

    safety: float = 0.8
    reject_safety: float = 0.9
    min_factor: float = 0.2
    max_factor: float = 2.0
    error_exponent: float = -1.0 / 3.0
    newton_failure_factor: float = 0.25

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"controller.{f.name} must be a finite number, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        for name in ("safety", "reject_safety"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"controller.{name} must lie in (0, 1], got {getattr(self, name)!r}")
        for name in ("min_factor", "newton_failure_factor"):
            if not 0.0 < getattr(self, name) < 1.0:
                raise ValueError(f"controller.{name} must lie in (0, 1), got {getattr(self, name)!r}")
        if not self.max_factor > 1.0:
            raise ValueError(f"controller.max_factor must be > 1, got {self.max_factor!r}")
        if not self.error_exponent < 0.0:
            raise ValueError(f"controller.error_exponent must be < 0, got {self.error_exponent!r}")


# ------------------------------------------------------------------------------------------------
# The compiled rule (inlined into the loop; ``opt`` is its LoopOptions, which carries the constants).
@njit(inline="always")
def step_after_rejection(hstep, err, opt):
    return hstep * max(opt.min_factor, opt.reject_safety * err**opt.error_exponent)


@njit(inline="always")
def step_after_acceptance(h, hstep, err, truncated, opt):
    """The next step; a step truncated to hit t_end keeps the previous proposal ``h`` unless the error
    asks for a smaller one."""
    fac = opt.max_factor if err == 0.0 else min(opt.max_factor, opt.safety * err**opt.error_exponent)
    if not truncated or fac < 1.0:
        return min(hstep * max(fac, opt.min_factor), opt.max_step)
    return h
