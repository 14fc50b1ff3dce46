"""Adaptive implicit trapezoidal integrator for the coupled GFB model (the static equilibrium is re-exported).

The trapezoidal rule (paper Sect. 3.3: chosen because it has no numerical damping)::

    s_{n+1} = s_n + h/2 [k(s_n, Lambda_n, D_n) + k(s_{n+1}, Lambda_{n+1}, D_{n+1})]

is solved by a modified Newton iteration on ``(I - h/2 J) ds = -r``.  J is the analytic Jacobian in
its periodic block-tridiagonal + rotor-border form (:mod:`gfb_env._kernels`); the factorisation is
reused across iterations and steps while the iteration converges fast, the Jacobian is refreshed when
it slows down and the step is cut when even a fresh Jacobian fails (Hairer & Wanner, *Solving ODEs II*,
Sect. IV.8).  The predictor is the quadratic through the last three accepted *states* (linear after
a restart).  Extrapolating k instead would amplify the slowly decaying stiff pressure modes that the
trapezoidal rule does not damp; the quadratic state extrapolation amplifies their ringing only by 7
(against 3 for linear) while its smooth error drops from O(h^2) to O(h^3), so two Newton iterations
suffice for most steps (``python -m gfb_experiments.bench_integrator``: 3.7 against 4.05 right-hand
sides per step).

Local error control: the local truncation error of the trapezoidal rule is ``-h^3/12 s'''``; s''' is
estimated by the divided difference of k over the last three points,
``s''' ~ 2/(h_n + h_{n-1}) [(f_{n+1} - f_n)/h_n - (f_n - f_{n-1})/h_{n-1}]``.
The trapezoidal rule is A- but not L-stable: stiff pressure modes ring with a factor close to -1
and make that raw estimate useless (it would force h ~ 0.03 near equilibrium).  As in scipy's Radau
(Hairer & Wanner IV.8, Shampine's filter) the estimate is filtered, ``err = (I - h/2 J)^{-1} LTE``,
with the factorisation at hand: smooth components pass, ringing stiff ones are divided by |h lambda|/2.
The step is accepted when the weighted max-norm ``max_i |err_i| / (atol + rtol |s_i|) <= 1`` and the
next step is ``h * clip(0.8 err^(-1/3), 0.2, 2)``; the factorisation of ``I - h'/2 J`` is reused while
``h / h'`` stays within ``factorization_ratio`` (the modified Newton iteration tolerates the mismatch).

The bearing number Lambda and the foil damping D_W vary linearly in time over one call of
:meth:`TrapezoidalIntegrator.advance`; every step uses their values at both of its ends.  A trial step
whose iterate has a non-positive pressure or film thickness, or is not finite, counts as a Newton
failure and is retried smaller; below ``min_step`` the integrator reports failure instead of returning
garbage.  Touchdown (min film thickness below a threshold) ends the call with an event.

The state machine (one call of the compiled kernel per :meth:`advance`)::

    jacobian stale --(evaluate J at s_n)--> jacobian fresh --(factor I - h/2 J)--> factored
    factored --(Newton converged, error <= 1)--> accepted step (J now "old"; slow convergence: stale)
    factored --(Newton failed, J old)--> jacobian stale (same h)
    factored --(Newton failed, J fresh)--> h /= 4
    factored --(error > 1)--> h reduced (refactored if outside factorization_ratio)

Package layout (after diffrax: one concern per module, each using only those before it):
:mod:`~gfb_env.integrator.results` (IntegrationStatus, AdvanceResult with its IntegratorStatistics,
Trajectory, TouchdownEvent), :mod:`~gfb_env.integrator.controller` (the step-size controller),
:mod:`~gfb_env.integrator.options` (IntegratorOptions: every setting once, the controller included),
:mod:`~gfb_env.integrator.arguments` (the compiled call's named argument groups and their packing, for
one call and for a batch), :mod:`~gfb_env.integrator.stages` (the compiled loop and its stages:
predictor, Newton, error estimate, dense output, extremes, touchdown, forcing),
:mod:`~gfb_env.integrator.state` (StepperState, the one snapshot), :mod:`~gfb_env.integrator.stepper`
(TrapezoidalIntegrator) and :mod:`~gfb_env.integrator.batch` (BatchAdvance).  The names below are the
public interface; import them from here.

A contributor's note: numba's on-disk cache (``cache=True``) checks only the file of each compiled
function, not the files of the functions it inlines or calls; :mod:`gfb_env._numba_cache` therefore
drops every cache of the compiled sources when any of them changed (at ``import gfb_env``).  A new
file with compiled code goes into its ``COMPILED_SOURCES``.
"""

from gfb_env.equilibrium import EquilibriumError, find_equilibrium  # re-exported (moved there)
from gfb_env.integrator.batch import BatchAdvance
from gfb_env.integrator.controller import StepSizeController, WhirlGrowthControl
from gfb_env.integrator.options import BENCHMARK_INTEGRATOR_OPTIONS, STEPS_PER_REVOLUTION, IntegratorOptions
from gfb_env.integrator.results import (
    AdvanceResult,
    IntegrationError,
    IntegrationStatus,
    IntegratorStatistics,
    TouchdownEvent,
    Trajectory,
)
from gfb_env.integrator.state import StepperState
from gfb_env.integrator.stepper import DEFAULT_MAX_STEPS, PreparedCall, TrapezoidalIntegrator

__all__ = [
    "BENCHMARK_INTEGRATOR_OPTIONS",
    "DEFAULT_MAX_STEPS",
    "STEPS_PER_REVOLUTION",
    "AdvanceResult",
    "BatchAdvance",
    "EquilibriumError",
    "IntegrationError",
    "IntegrationStatus",
    "IntegratorOptions",
    "IntegratorStatistics",
    "PreparedCall",
    "StepSizeController",
    "StepperState",
    "TouchdownEvent",
    "Trajectory",
    "TrapezoidalIntegrator",
    "WhirlGrowthControl",
    "find_equilibrium",
]
