"""Settings of :class:`~gfb_env.integrator.TrapezoidalIntegrator` as one validated, frozen object.

The defaults are the integrator's (tolerance 3e-4 from the convergence study of the limit-cycle
amplitude, README "The integrator").  An unknown name or a bad value is refused when the object is
made, so a typo in ``gym.make(..., integrator_options={...})`` fails at construction, not at ``reset``.
The touchdown threshold is not an integrator *option* here: the environments own it
(``touchdown_film_thickness``), so there is one place and one rule for it.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["IntegratorOptions"]


@dataclass(frozen=True)
class IntegratorOptions:
    """Error control and Newton settings of the trapezoidal stepper (see its docstring for each).

    Attributes:
        rtol, atol: local error tolerances (weighted max-norm).
        first_step, max_step, min_step: step-size limits (tau).
        max_newton_iterations: Newton iterations per trial step.
        newton_tol: Newton stops below this fraction of the error tolerance.
        factorization_ratio: reuse the factorisation for steps within this ratio of the factored one.
        slow_newton_iterations: a step that needed more iterations marks the Jacobian stale.
    """

    rtol: float = 3e-4
    atol: float = 3e-4
    first_step: float = 0.01
    max_step: float = 2.0
    min_step: float = 1e-7
    max_newton_iterations: int = 6
    newton_tol: float = 0.3
    factorization_ratio: float = 2.0
    slow_newton_iterations: int = 3

    def __post_init__(self) -> None:
        for name in ("rtol", "atol", "first_step", "max_step", "min_step", "newton_tol"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite positive number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not self.min_step <= self.first_step <= self.max_step:
            raise ValueError(
                "the step limits must satisfy min_step <= first_step <= max_step, got "
                f"{self.min_step!r}, {self.first_step!r}, {self.max_step!r}"
            )
        for name in ("max_newton_iterations", "slow_newton_iterations"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not 1 <= v <= 100:
                raise ValueError(f"{name} must be an integer in [1, 100], got {v!r}")
            object.__setattr__(self, name, int(v))
        v = self.factorization_ratio
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and v >= 1):
            raise ValueError(f"factorization_ratio must be finite and >= 1, got {v!r}")
        object.__setattr__(self, "factorization_ratio", float(v))

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | IntegratorOptions | None) -> IntegratorOptions:
        """From a dict of keyword arguments (``None``: the defaults); unknown keys are refused."""
        if options is None:
            return cls()
        if isinstance(options, IntegratorOptions):
            return options
        if not isinstance(options, Mapping):
            raise ValueError(f"integrator_options must be a dict or None, got {type(options).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        for key in options:
            if key == "touchdown_film_thickness":
                raise ValueError(
                    "integrator_options['touchdown_film_thickness'] is not allowed: pass the environment's "
                    "touchdown_film_thickness argument instead"
                )
            if key not in known:
                raise ValueError(f"integrator_options has unknown key {key!r}; allowed: {sorted(known)}")
        try:
            return cls(**options)
        except ValueError as exc:
            raise ValueError(f"integrator_options: {exc}") from None

    def as_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`~gfb_env.integrator.TrapezoidalIntegrator`."""
        return dataclasses.asdict(self)
