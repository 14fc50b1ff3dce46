"""Every setting of :class:`~gfb_env.integrator.TrapezoidalIntegrator` in one validated, frozen object.

The defaults are the integrator's (tolerance 3e-4 from the convergence study of the limit-cycle
amplitude, README "The integrator"); the step-size controller's constants are a part
(:class:`~gfb_env.integrator.controller.StepSizeController`).  An unknown name or a bad value is refused
when the object is made, so a typo in ``gym.make(..., integrator_options={...})`` fails at
construction, not at ``reset``.  The environments own the touchdown threshold (their
``touchdown_film_thickness`` argument, one rule for the event and the episode end), so
:meth:`IntegratorOptions.from_mapping` refuses it; they pass it to the integrator as an override.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gfb_env.integrator.controller import StepSizeController, WhirlGrowthControl

__all__ = ["BENCHMARK_INTEGRATOR_OPTIONS", "IntegratorOptions", "StepSizeController", "WhirlGrowthControl"]

#: Default of ``steps_per_revolution``: with an unbalance the step is at most 1/32 of a revolution.  The
#: error control alone (absolute tolerance 3e-4) lets small forced orbits through with errors of 6-16 %
#: (U = 1e-3..1e-2, rigid 31x7, Lambda = 0.4); the cap bounds the trapezoidal rule's frequency warping,
#: amplitude error ~ (2 pi / N)^2 / 4: measured 4 % at N = 16, 1.0 % at 32, 0.25 % at 64.
STEPS_PER_REVOLUTION = 32


@dataclass(frozen=True)
class IntegratorOptions:
    """Error control, step-size control, Newton and event settings of the trapezoidal stepper.

    Attributes:
        rtol, atol: local error tolerances (weighted max-norm).  Default 3e-4 from the convergence
            study of the limit-cycle amplitude (``python -m gfb_experiments.convergence_study``): the
            amplitude is within 0.06 % and the minimum film within 5 % of the rtol = 3e-5 result, at the
            same cost as 3e-3 (below ~1e-3 the step is limited by Newton convergence near contact,
            not by the error estimate).
        first_step, max_step, min_step: step-size limits in tau.
        touchdown_film_thickness: minimum film thickness H that counts as touchdown, in [0, 1).
        max_newton_iterations: Newton iterations per trial step.
        newton_tol: Newton stops when the weighted update (or its rate-extrapolated remainder) is below
            this fraction of the error tolerance.
        factorization_ratio: the factorisation of ``I - h'/2 J`` is reused for a step h with
            ``h'/ratio <= h <= h' ratio`` (modified Newton still converges; on the paper grid a new one
            costs ~55 us, a solve ~6.5 us).
        slow_newton_iterations: a step that needed more iterations marks the Jacobian stale.
        steps_per_revolution: with an unbalance, the step is at most ``2 pi / (N Lambda)`` (see
            :data:`STEPS_PER_REVOLUTION`).
        controller: the step-size controller's constants (a :class:`StepSizeController` or a dict of
            its fields).
        whirl_growth_control: the step limit at a settled operating point (a
            :class:`WhirlGrowthControl`, a dict of its fields, or None: off, ``max_step`` everywhere,
            the default).  See :mod:`gfb_env.integrator.controller`.
    """

    rtol: float = 3e-4
    atol: float = 3e-4
    first_step: float = 0.01
    max_step: float = 2.0
    min_step: float = 1e-7
    touchdown_film_thickness: float = 0.01
    max_newton_iterations: int = 6
    newton_tol: float = 0.3
    factorization_ratio: float = 2.0
    slow_newton_iterations: int = 3
    steps_per_revolution: float = STEPS_PER_REVOLUTION
    controller: StepSizeController = StepSizeController()
    whirl_growth_control: WhirlGrowthControl | None = None

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
        v = self.touchdown_film_thickness
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and 0 <= v < 1):
            raise ValueError(f"touchdown_film_thickness must lie in [0, 1), got {v!r}")
        object.__setattr__(self, "touchdown_film_thickness", float(v))
        v = self.steps_per_revolution
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and v >= 1):
            raise ValueError(f"steps_per_revolution must be finite and >= 1, got {v!r}")
        object.__setattr__(self, "steps_per_revolution", float(v))
        c = self.controller
        if isinstance(c, Mapping):
            known = {f.name for f in dataclasses.fields(StepSizeController)}
            unknown = sorted(set(c) - known)
            if unknown:
                raise ValueError(f"controller has unknown key(s) {unknown}; allowed: {sorted(known)}")
            object.__setattr__(self, "controller", StepSizeController(**c))
        elif not isinstance(c, StepSizeController):
            raise ValueError(f"controller must be a StepSizeController or a dict, got {type(c).__name__}")
        w = self.whirl_growth_control
        if isinstance(w, Mapping):
            known = {f.name for f in dataclasses.fields(WhirlGrowthControl)}
            unknown = sorted(set(w) - known)
            if unknown:
                raise ValueError(
                    f"whirl_growth_control has unknown key(s) {unknown}; allowed: {sorted(known)}"
                )
            object.__setattr__(self, "whirl_growth_control", WhirlGrowthControl(**w))
        elif w is not None and not isinstance(w, WhirlGrowthControl):
            raise ValueError(
                f"whirl_growth_control must be a WhirlGrowthControl, a dict or None, got {type(w).__name__}"
            )
        if (
            self.whirl_growth_control is not None
            and self.whirl_growth_control.settled_max_step < self.max_step
        ):
            raise ValueError(
                "whirl_growth_control.settled_max_step must be >= max_step, got "
                f"{self.whirl_growth_control.settled_max_step!r} < {self.max_step!r}"
            )

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | IntegratorOptions | None) -> IntegratorOptions:
        """From a dict of keyword arguments (``None``: the defaults); unknown keys are refused."""
        if options is None:
            return cls()
        if isinstance(options, IntegratorOptions):
            return options
        if not isinstance(options, Mapping):
            raise ValueError(f"integrator_options must be a dict or None, got {type(options).__name__}")
        known = _FIELDS
        for key in options:
            if key == "touchdown_film_thickness":
                raise ValueError(
                    "integrator_options['touchdown_film_thickness'] is not allowed: pass the environment's "
                    "touchdown_film_thickness argument instead"
                )
            if key not in known:
                allowed = sorted(known - {"touchdown_film_thickness"})
                raise ValueError(f"integrator_options has unknown key {key!r}; allowed: {allowed}")
        try:
            return cls(**options)
        except ValueError as exc:
            raise ValueError(f"integrator_options: {exc}") from None

    def replace(self, **overrides: Any) -> IntegratorOptions:
        """These options with ``overrides`` (field names; validated as a new object; none: ``self``).
        An unknown name is a TypeError, as for any unknown keyword argument."""
        if not overrides:
            return self
        unknown = sorted(set(overrides) - _FIELDS)
        if unknown:
            raise TypeError(f"unknown integrator option(s) {unknown}; allowed: {sorted(_FIELDS)}")
        return dataclasses.replace(self, **overrides)


_FIELDS = frozenset(f.name for f in dataclasses.fields(IntegratorOptions))


#: The integrator options of the benchmark tasks (issue 20 item 1: the lead puts them into the v2 task
#: specs as ``integrator_options``): the defaults with the step limit at a settled operating point
#: (:class:`WhirlGrowthControl`'s defaults).  With the unbalance stepped (today's v2 plant) the 1x orbit
#: never settles and every v2 result is the default's (plant_accuracy, 2 seeds x 3 policies x 3 tasks:
#: identical).  On the unforced plant (a balanced rotor, the stand-in for the analytic 1x response of
#: item 2): RunUp-v2 held at its start 30.0 -> 8.4 integrator steps per control step, whirl unchanged;
#: against the tight reference (4 seeds x hold/naive/random) the episode-entries beyond 1/3 of the noise
#: are 56/57/183 of 360 with the defaults and 56/58/183 with these (results/plant_accuracy/README.md).
BENCHMARK_INTEGRATOR_OPTIONS: dict[str, Any] = {"whirl_growth_control": {}}
