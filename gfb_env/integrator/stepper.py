"""Adaptive implicit trapezoidal integrator for the coupled GFB model, and the static equilibrium.

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

Code layout (after diffrax): the compiled loop :func:`_advance` carries a typed loop state (the arrays
and clock of :class:`StepperState`, the Jacobian and factorisation flags) and calls one small inlined
helper per stage: :func:`_predict`, :func:`_newton`, :func:`_error_norm`, :func:`_record_dense`,
:func:`_shift_history`, :func:`_update_extremes`, :func:`_touchdown` and the step-size controller
(:func:`_step_after_rejection`, :func:`_step_after_acceptance`).  Its arguments come in named groups
(:class:`_Jacobian`, :class:`_Factorization`, :class:`_Options`, :class:`_Recording`, the model's
:meth:`~gfb_env.model.GFBModel.kernel_args`), unpacked once per call (the stages take their arrays one
by one, which keeps the loop as fast as the single function it was); it ends with an
:class:`IntegrationStatus`.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit, prange

from gfb_env import _kernels as K
from gfb_env import forcing as F
from gfb_env.equilibrium import EquilibriumError, find_equilibrium  # re-exported (moved there)
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.forcing import shock_acceleration as _shock_acceleration
from gfb_env.forcing import unbalance_acceleration as _unbalance_acceleration
from gfb_env.integrator.options import IntegratorOptions
from gfb_env.model import GFBModel

__all__ = [
    "TrapezoidalIntegrator",
    "BatchAdvance",
    "Trajectory",
    "AdvanceResult",
    "TouchdownEvent",
    "IntegrationError",
    "IntegrationStatus",
    "IntegratorStatistics",
    "StepperState",
    "EquilibriumError",
    "find_equilibrium",
]


class IntegrationStatus(enum.StrEnum):
    """How one :meth:`TrapezoidalIntegrator.advance` ended (a str: ``status == "touchdown"`` works)."""

    DONE = "done"
    TOUCHDOWN = "touchdown"
    FAILED = "failed"
    MAX_STEPS = "max_steps"


# codes of the compiled loop, in the order of IntegrationStatus
_DONE, _TOUCHDOWN, _FAILED, _MAX_STEPS = 0, 1, 2, 3
_STATUS_OF_CODE = tuple(IntegrationStatus)

# step-size controller (Hairer & Wanner IV.8): h' = h * clip(SAFETY err^EXPONENT, MIN_FACTOR, MAX_FACTOR);
# a rejected step uses the milder REJECT_SAFETY, a Newton failure divides h by 4
_SAFETY = 0.8
_REJECT_SAFETY = 0.9
_MIN_FACTOR = 0.2
_MAX_FACTOR = 2.0
_ERROR_EXPONENT = -1.0 / 3.0  # the trapezoidal rule's local error is O(h^3)
_NEWTON_FAILURE_FACTOR = 0.25

# statistics (int vector of the compiled loop; named by IntegratorStatistics, in this order)
_NSTEPS, _NREJ_ERR, _NREJ_NEWTON, _NJAC, _NFACT, _NRHS, _NREC, _NBAD_H, _NDIVERGED = 0, 1, 2, 3, 4, 5, 6, 7, 8
# extremes and the touchdown event (float vector of the compiled loop)
_MINH, _XIMIN, _XIMAX, _ETAMIN, _ETAMAX, _EPSMAX, _EVT, _EVXI, _EVETA = 0, 1, 2, 3, 4, 5, 6, 7, 8


class IntegrationError(RuntimeError):
    """The integrator could not continue (step size below the minimum, or too many steps)."""


# ------------------------------------------------------------------------------------------------
# Argument groups of the compiled loop (numba passes NamedTuples by value; the arrays are shared).
# _advance unpacks them by position once per call, so the field order is part of the contract.
class _Jacobian(NamedTuple):
    """The blocks of J (see :mod:`gfb_env._kernels`), refreshed in place."""

    Ad: np.ndarray
    Ap: np.ndarray
    Am: np.ndarray
    Er: np.ndarray
    Rr: np.ndarray
    Srr: np.ndarray


class _Factorization(NamedTuple):
    """Workspace of the factors of ``I - h/2 J`` and the solver's static parameters."""

    Dlu: np.ndarray
    Dpiv: np.ndarray
    Uhat: np.ndarray
    Y: np.ndarray
    Slu: np.ndarray
    Spiv: np.ndarray
    n_rows: int
    sparse: bool
    size_tag: tuple


class _Options(NamedTuple):
    """The integrator's settings (see :class:`TrapezoidalIntegrator`) and the call's ``max_steps``."""

    rtol: float
    atol: float
    min_step: float
    max_step: float
    touchdown_film_thickness: float
    max_steps: int
    max_newton_iterations: int
    newton_tol: float
    factorization_ratio: float
    slow_newton_iterations: int


class _Recording(NamedTuple):
    """Dense output: rows ``[tau, s[indices]..., min H]`` every ``interval`` from ``first_tau``."""

    indices: np.ndarray
    interval: float
    first_tau: float
    buffer: np.ndarray


class _Forcing(NamedTuple):
    """The external forcing of one call (:mod:`gfb_env.forcing`); an unforced call passes None instead."""

    unbalance: float  # U
    angle: float  # theta at the call's start plus the unbalance phase
    shocks: np.ndarray  # rows HalfSineShock.as_row(), shape (k, 4)
    max_step: float  # the step limit that resolves the unbalance forcing (inf without one)


_NO_SHOCKS = np.zeros((0, 4))
#: The default ``max_steps`` of one :meth:`TrapezoidalIntegrator.advance`.
DEFAULT_MAX_STEPS = 10_000_000
_NO_INDICES = np.zeros(0, dtype=np.int64)
# the extremes' start (min H, xi min/max, eta min/max, max eccentricity, touchdown time, xi, eta)
_EXTREMES_START = np.array([np.inf, np.inf, -np.inf, np.inf, -np.inf, 0.0, np.nan, np.nan, np.nan])


class PreparedCall(NamedTuple):
    """One prepared call of the compiled loop (:meth:`TrapezoidalIntegrator.prepare`): its arguments
    and what :meth:`TrapezoidalIntegrator._finish` needs besides the loop's outputs."""

    st: StepperState  # the state the call starts from (its arrays are advanced in place)
    schedule: tuple  # (tau_end, Lambda_0, Lambda_1, D_W0, D_W1)
    span: float
    rate: float  # theta'' of the call's ramp
    options: _Options
    recording: _Recording
    rec_buf: np.ndarray  # the whole sample buffer (a sample at the start in row 0 when first == 1)
    first: int
    stats: np.ndarray
    ext: np.ndarray
    forcing: _Forcing | None
    max_steps: Any  # as passed (it appears in the max_steps message)


#: Default of ``steps_per_revolution``: with an unbalance the step is at most 1/32 of a revolution.  The
#: error control alone (absolute tolerance 3e-4) lets small forced orbits through with errors of 6-16 %
#: (U = 1e-3..1e-2, rigid 31x7, Lambda = 0.4); the cap bounds the trapezoidal rule's frequency warping,
#: amplitude error ~ (2 pi / N)^2 / 4: measured 4 % at N = 16, 1.0 % at 32, 0.25 % at 64.
STEPS_PER_REVOLUTION = 32
#: Steps inside a shock pulse at least (the impulse's quadrature error pi^2 / (12 n^2) = 0.08 %).
_STEPS_PER_PULSE = 32.0


# ------------------------------------------------------------------------------------------------
# Stages of one step, inlined into _advance.  They take arrays one by one, not in their groups: in
# numba every extraction of an array from a tuple is a reference-count pair, and one per stage and step
# cost 3 % of a step (``python -m gfb_experiments.bench_interleaved``).  Scalars travel in tuples freely.
# What is left (+0.7-1 % against the single function) is _newton's array arguments, whose reference
# counts survive across its calls to k and the solver; written out in _advance it measured +0.3 %.
@njit(cache=True)
def _wnorm(dx, x, y, rtol, atol):
    mx = 0.0
    for i in range(dx.shape[0]):
        sc = atol + rtol * max(abs(x[i]), abs(y[i]))
        v = abs(dx[i]) / sc
        if not v <= mx:  # also catches NaN
            mx = v
    return mx


@njit(inline="always")
def _ramp(a0, a1, theta):
    return a0 + (a1 - a0) * theta


@njit(inline="always")
def _predict(x, s, sprev, sprev2, f, hstep, hp, hp2, history):
    """Extrapolate the states (not k, which rings in stiff modes): quadratic through the last three
    accepted states, linear after a restart, an Euler step without history."""
    n = x.shape[0]
    if history >= 2:
        # Lagrange weights of the quadratic through (-hp - hp2, sprev2), (-hp, sprev), (0, s) at hstep
        ta = -hp - hp2
        w2 = (hstep + hp) * hstep / (hp2 * (hp + hp2))
        w1 = -(hstep - ta) * hstep / (hp2 * hp)
        w0 = (hstep - ta) * (hstep + hp) / (ta * -hp)
        for i in range(n):
            x[i] = w0 * s[i] + w1 * sprev[i] + w2 * sprev2[i]
    elif history >= 1:
        c2 = hstep / hp
        for i in range(n):
            x[i] = s[i] + c2 * (s[i] - sprev[i])
    else:
        for i in range(n):
            x[i] = s[i] + hstep * f[i]


@njit(inline="always")
def _newton(
    x, fx, fnew, r, dx, zb, H, Hd,  # workspace: x holds the prediction, then the iterate
    s, f, hstep, h_fact, lam_b, dw_b,  # the step from (s, f) with the factors of I - h_fact/2 J
    ip, fp, sn, cs,  # the model (GFBModel.kernel_args)
    Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, lu_static,  # the factorisation
    opt, stats,
):  # fmt: skip
    """Modified Newton iteration for the trapezoidal step; on success ``fnew = k(x)`` (checked
    admissible and finite).  Returns (converged, iterations).

    ``f`` enters only the residual ``x - s - h/2 (f + k(x))``: with an external forcing (state-independent,
    so the Jacobian is unchanged) :func:`_advance` passes f plus the forcing at the step end and adds
    that to ``fnew`` itself, so this stage is the unforced one, bit for bit and at the same cost.
    (At most 30 arguments: beyond that CPython passes them as ``*args``, which numba cannot inline.)"""
    n_rows, sparse, size_tag = lu_static
    n = x.shape[0]
    converged = False
    dprev = 0.0
    iters = 0
    for it in range(opt.max_newton_iterations):
        iters = it + 1
        K.rhs(x, lam_b, dw_b, ip, fp, sn, cs, fx, H, Hd)
        stats[_NRHS] += 1
        if not H.min() > 0.0:  # intermediate iterates may dip below P = 0, never below H = 0
            stats[_NBAD_H] += 1
            break
        for i in range(n):
            r[i] = -(x[i] - s[i] - 0.5 * hstep * (f[i] + fx[i]))
        K.solve_system(
            0.5 * h_fact, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, n_rows, r, dx, zb, sparse, size_tag
        )  # fmt: skip
        for i in range(n):
            x[i] += dx[i]
        dn = _wnorm(dx, x, s, opt.rtol, opt.atol)
        if not dn < 1e30:
            break
        if dn <= opt.newton_tol:
            converged = True
            break
        if it > 0:
            rate = dn / dprev
            if rate >= 0.9:
                stats[_NDIVERGED] += 1
                break
            if rate / (1.0 - rate) * dn <= opt.newton_tol:
                converged = True
                break
        dprev = dn
    if converged:
        mn = K.rhs(x, lam_b, dw_b, ip, fp, sn, cs, fnew, H, Hd)
        stats[_NRHS] += 1
        if not mn > 0.0:
            converged = False
        else:
            for i in range(n):
                if not abs(fnew[i]) < 1e300:
                    converged = False
                    break
    return converged, iters


@njit(inline="always")
def _error_norm(
    r, dx, zb, x, fnew,  # workspace, the accepted iterate x and fnew = k(x)
    s, f, fprev, hstep, hp, history, h_fact,
    Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, lu_static,  # the factorisation
    opt,
):  # fmt: skip
    """Weighted max-norm of the local error ``-h^3/12 s'''`` (s''' from the divided difference of k),
    filtered through ``(I - h/2 J)^-1`` when the raw estimate rejects the step."""
    n = s.shape[0]
    if history >= 1:
        c3 = hstep**3 / 12.0 * 2.0 / (hstep + hp)
        for i in range(n):
            r[i] = c3 * ((fnew[i] - f[i]) / hstep - (f[i] - fprev[i]) / hp)
    else:
        c3 = hstep / 6.0
        for i in range(n):
            r[i] = c3 * (fnew[i] - f[i])
    err = _wnorm(r, x, s, opt.rtol, opt.atol)
    if err > 1.0:  # only a rejected raw estimate is worth the filtering solve
        n_rows, sparse, size_tag = lu_static
        K.solve_system(
            0.5 * h_fact, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, n_rows, r, dx, zb, sparse, size_tag
        )  # fmt: skip
        err = _wnorm(dx, x, s, opt.rtol, opt.atol)
    return err


@njit(inline="always")
def _record_dense(
    buf, idx, interval, rec_n, rec_next, t_old, t, eps_t, hstep, s, f, x, fnew, hmin_old, hmin_new
):
    """Cubic Hermite samples at the recording times in (t_old, t] into ``buf`` (rows ``[tau, s[idx]...,
    min H]``, min H linear in time); returns the new (count, next time)."""
    ncols = idx.shape[0]
    while rec_n < buf.shape[0] and rec_next <= t + eps_t:
        th = (rec_next - t_old) / hstep
        h00 = (1.0 + 2.0 * th) * (1.0 - th) ** 2
        h10 = th * (1.0 - th) ** 2
        h01 = th * th * (3.0 - 2.0 * th)
        h11 = th * th * (th - 1.0)
        buf[rec_n, 0] = rec_next
        for q in range(ncols):
            k = idx[q]
            buf[rec_n, 1 + q] = h00 * s[k] + h10 * hstep * f[k] + h01 * x[k] + h11 * hstep * fnew[k]
        buf[rec_n, 1 + ncols] = hmin_old + th * (hmin_new - hmin_old)
        rec_n += 1
        rec_next += interval
    return rec_n, rec_next


@njit(inline="always")
def _shift_history(s, f, fprev, sprev, sprev2, x, fnew):
    """Accept x: (s, sprev, sprev2) <- (x, s, sprev) and (f, fprev) <- (fnew, f)."""
    for i in range(s.shape[0]):
        fprev[i] = f[i]
        f[i] = fnew[i]
        sprev2[i] = sprev[i]
        sprev[i] = s[i]
        s[i] = x[i]


@njit(inline="always")
def _update_extremes(ext, xi, eta, hmin):
    ext[_MINH] = min(ext[_MINH], hmin)
    ext[_XIMIN] = min(ext[_XIMIN], xi)
    ext[_XIMAX] = max(ext[_XIMAX], xi)
    ext[_ETAMIN] = min(ext[_ETAMIN], eta)
    ext[_ETAMAX] = max(ext[_ETAMAX], eta)
    ext[_EPSMAX] = max(ext[_EPSMAX], math.sqrt(xi * xi + eta * eta))


@njit(inline="always")
def _touchdown(ext, hmin_old, hmin_new, threshold, t_old, hstep, s, f, r0):
    """Whether the accepted step crossed the touchdown threshold; if so, its time and rotor position
    (linear in min H, the position from the state and its derivative at the step end) go into ext."""
    if not hmin_new < threshold:
        return False
    th = (hmin_old - threshold) / (hmin_old - hmin_new) if hmin_old > hmin_new else 1.0
    th = min(max(th, 0.0), 1.0)
    ext[_EVT] = t_old + th * hstep
    ext[_EVXI] = s[r0] - (1.0 - th) * hstep * f[r0]
    ext[_EVETA] = s[r0 + 1] - (1.0 - th) * hstep * f[r0 + 1]
    return True


@njit(inline="always")
def _step_after_rejection(hstep, err):
    return hstep * max(_MIN_FACTOR, _REJECT_SAFETY * err**_ERROR_EXPONENT)


@njit(inline="always")
def _step_after_acceptance(h, hstep, err, truncated, max_step):
    """The next step; a step truncated to hit t_end keeps the previous proposal ``h`` unless the error
    asks for a smaller one."""
    fac = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err**_ERROR_EXPONENT)
    if not truncated or fac < 1.0:
        return min(hstep * max(fac, _MIN_FACTOR), max_step)
    return h


@njit(inline="always")
def _forcing(th, lam0, lam1, span, unbalance, angle0, tn, shocks):
    """The external rotor acceleration at the time ``tn`` (fraction ``th`` of the call's span): the
    unbalance at theta(tn) = angle0 + span (Lambda_0 th + (Lambda_1 - Lambda_0) th^2 / 2) (exact for
    the linear ramp of Lambda, theta' = Lambda, theta'' = dLambda/dtau) plus the base shocks."""
    a_xi, a_eta = _shock_acceleration(tn, shocks)
    if unbalance != 0.0:
        theta = angle0 + span * (lam0 * th + 0.5 * (lam1 - lam0) * th * th)
        u_xi, u_eta = _unbalance_acceleration(unbalance, theta, _ramp(lam0, lam1, th), (lam1 - lam0) / span)
        a_xi += u_xi
        a_eta += u_eta
    return a_xi, a_eta


@njit(inline="always")
def _land_on_shocks(t, hstep, truncated, shocks, eps_t):
    """The step cut so that it ends on the next start or end of a shock pulse after ``t`` and stays
    within 1/_STEPS_PER_PULSE of a pulse while inside one (the forcing's kinks are step ends, its hump
    resolved)."""
    for k in range(shocks.shape[0]):
        t_on = shocks[k, 0]
        d = shocks[k, 1]
        t_off = t_on + d
        if t < t_on - eps_t:
            if t + hstep > t_on - eps_t:
                hstep = t_on - t
                truncated = True
        elif t < t_off - eps_t:
            if hstep > d / _STEPS_PER_PULSE:
                hstep = d / _STEPS_PER_PULSE
                truncated = True
            if t + hstep > t_off - eps_t:
                hstep = t_off - t
                truncated = True
    return hstep, truncated


# ------------------------------------------------------------------------------------------------
@njit(cache=True)
def _advance(y, clock, schedule, kargs, jac, lu, opt, rec, stats, ext, forcing):
    """Integrate to ``schedule[0]`` (see the module docstring's state machine).

    y = (s, f, fprev, sprev, sprev2), updated in place; clock = (tau, step, previous_step,
    previous_step2, history); schedule = (tau_end, Lambda_0, Lambda_1, D_W0, D_W1); kargs: the model's
    :meth:`~gfb_env.model.GFBModel.kernel_args`; jac: :class:`_Jacobian`; lu: :class:`_Factorization`;
    opt: :class:`_Options`; rec: :class:`_Recording`; stats, ext: counters and extremes (in place);
    forcing: :class:`_Forcing`, or None for an unforced call.  Returns (status code, clock at the end).

    The forcing is chosen at compile time, not by a run-time flag: numba compiles one variant per type
    of ``forcing`` and, for None, prunes every ``if forcing is not None`` branch before typing, so the
    unforced loop has no forcing code and its machine code is the loop from before the forcing existed
    (a run-time ``forced`` flag left the forcing code and the f-or-fa alias in the compiled loop, 576
    more instructions and 9 more reference-count sites in the function: +1.7 % per step measured with
    ``python -m gfb_experiments.bench_interleaved``; without it the unforced cost is the old one).
    Keep those tests in the form ``forcing is not None`` on the argument itself: pruning sees no other.
    """
    # the groups' arrays into locals once (see "Stages of one step")
    s, f, fprev, sprev, sprev2 = y
    t, h, hp, hp2, history = clock
    t_end, lam0, lam1, dw0, dw1 = schedule
    ip, fp, sn, cs = kargs
    Ad, Ap, Am, Er, Rr, Srr = jac
    Dlu, Dpiv, Uhat, Y, Slu, Spiv, n_rows, sparse, size_tag = lu
    lu_static = (n_rows, sparse, size_tag)
    rec_idx, rec_dt, rec_next, rec_buf = rec
    if forcing is not None:
        unbalance, angle0, shocks, forcing_max_step = forcing
        n_shocks = shocks.shape[0]
        fa = np.empty(s.shape[0])  # f plus the forcing at the step end
    # workspace
    n = s.shape[0]
    nc = Ad.shape[0]
    x = np.empty(n)  # Newton iterate (the new state once accepted)
    fx = np.empty(n)  # k(x) during the iteration
    fnew = np.empty(n)  # k at the accepted x
    r = np.empty(n)  # residual, then the local error estimate
    dx = np.empty(n)  # Newton update, then the filtered error
    ftmp = np.empty(n)  # k at s_n (by-product of the Jacobian)
    zb = np.empty((nc, Ad.shape[1]))  # solver workspace
    H = np.empty(nc)  # film thickness per column at the last k evaluation
    Hd = np.empty(nc)  # its time derivative
    t_start = t
    span = t_end - t_start
    if span <= 0.0:
        return _DONE, (t, h, hp, hp2, history)
    r0 = n - 4  # the rotor follows the film and foil unknowns
    jac_valid = False
    jac_fresh = False
    fact_valid = False
    h_fact = -1.0
    eps_t = 1e-12 * max(1.0, abs(t_end))
    rec_n = 0
    K.film_thickness(s, ip, fp, sn, cs, H)
    hmin_old = H.min()
    status = _DONE
    while True:
        if t >= t_end - eps_t:
            status = _DONE
            break
        if stats[_NSTEPS] >= opt.max_steps:
            status = _MAX_STEPS
            break
        hstep = h
        truncated = False
        if t + hstep > t_end - eps_t:
            hstep = t_end - t
            truncated = True
        if forcing is not None:
            if hstep > forcing_max_step:
                hstep = forcing_max_step
                truncated = True
            if n_shocks > 0:
                hstep, truncated = _land_on_shocks(t, hstep, truncated, shocks, eps_t)
        tn = t + hstep
        th0 = (t - t_start) / span
        th1 = min((tn - t_start) / span, 1.0)
        if not jac_valid:
            lam_a = _ramp(lam0, lam1, th0)
            dw_a = _ramp(dw0, dw1, th0)
            K.jacobian_blocks(s, lam_a, dw_a, ip, fp, sn, cs, ftmp, H, Hd, Ad, Ap, Am, Er, Rr, Srr)
            stats[_NJAC] += 1
            jac_valid = True
            jac_fresh = True
            fact_valid = False
        ratio = opt.factorization_ratio
        if (not fact_valid) or hstep > h_fact * ratio or hstep < h_fact / ratio:
            stats[_NFACT] += 1
            if not K.factor_system(
                0.5 * hstep, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag
            ):  # fmt: skip
                fact_valid = False
                h = _NEWTON_FAILURE_FACTOR * hstep
                stats[_NREJ_NEWTON] += 1
                if h < opt.min_step:
                    status = _FAILED
                    break
                continue
            fact_valid = True
            h_fact = hstep
        _predict(x, s, sprev, sprev2, f, hstep, hp, hp2, history)
        lam_b = _ramp(lam0, lam1, th1)
        dw_b = _ramp(dw0, dw1, th1)
        if forcing is not None:  # the residual's f + k(x) gains the forcing at the step end (see _newton)
            a_xi, a_eta = _forcing(th1, lam0, lam1, span, unbalance, angle0, tn, shocks)
            for i in range(n):
                fa[i] = f[i]
            fa[r0 + 2] += a_xi
            fa[r0 + 3] += a_eta
            converged, iters = _newton(
                x, fx, fnew, r, dx, zb, H, Hd, s, fa, hstep, h_fact, lam_b, dw_b, ip, fp, sn, cs,
                Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, lu_static, opt, stats,
            )  # fmt: skip
            if converged:
                fnew[r0 + 2] += a_xi
                fnew[r0 + 3] += a_eta
        else:
            converged, iters = _newton(
                x, fx, fnew, r, dx, zb, H, Hd, s, f, hstep, h_fact, lam_b, dw_b, ip, fp, sn, cs,
                Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, lu_static, opt, stats,
            )  # fmt: skip
        if not converged:
            stats[_NREJ_NEWTON] += 1
            if not jac_fresh:
                jac_valid = False  # retry with a fresh Jacobian at the same h
            else:
                h = _NEWTON_FAILURE_FACTOR * hstep
                if h < opt.min_step:
                    status = _FAILED
                    break
            continue
        err = _error_norm(
            r, dx, zb, x, fnew, s, f, fprev, hstep, hp, history, h_fact,
            Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, lu_static, opt,
        )  # fmt: skip
        if err > 1.0:
            stats[_NREJ_ERR] += 1
            h = _step_after_rejection(hstep, err)
            if h < opt.min_step:
                status = _FAILED
                break
            continue
        # accept
        t_old = t
        t = tn
        hmin_new = H.min()
        rec_n, rec_next = _record_dense(
            rec_buf, rec_idx, rec_dt, rec_n, rec_next, t_old, t, eps_t, hstep, s, f, x, fnew,
            hmin_old, hmin_new,
        )  # fmt: skip
        _shift_history(s, f, fprev, sprev, sprev2, x, fnew)
        hp2 = hp
        hp = hstep
        history = min(history + 1, 2)
        stats[_NSTEPS] += 1
        jac_fresh = False
        if iters > opt.slow_newton_iterations:
            jac_valid = False
        _update_extremes(ext, s[r0], s[r0 + 1], hmin_new)
        if _touchdown(ext, hmin_old, hmin_new, opt.touchdown_film_thickness, t_old, hstep, s, f, r0):
            status = _TOUCHDOWN
            break
        hmin_old = hmin_new
        h = _step_after_acceptance(h, hstep, err, truncated, opt.max_step)
    stats[_NREC] = rec_n
    return status, (t, h, hp, hp2, history)


# ------------------------------------------------------------------------------------------------
@njit(cache=True)
def _advance_env(
    i,
    Y, clocks, history, schedules, IP, FP, SN, CS,  # states, clocks, schedules, kernel args
    Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Yw, Slu, Spiv, n_rows, sparse, size_tag,  # workspace
    opt_f, opt_i, rec_idx, rec_t, rec_bufs, rec_rows, stats, ext,  # options, recording, outputs
    forced, force_f, shocks, n_shocks, codes,  # the forcing per env, the status codes (out)
):  # fmt: skip
    """:func:`_advance` of env i of a batch: it gets exactly the argument groups (types included) that
    :meth:`TrapezoidalIntegrator.advance` passes, built from row i of the stacked arrays, so it runs the
    same compiled loop and its result is bit for bit the single call's.

    Y (N, 5, n): y per env; clocks (N, 4) and history (N,): the clock (updated in place); schedules
    (N, 5); IP, FP, SN, CS: the stacked kernel args; Ad..Spiv: each env's Jacobian and factorisation
    workspace (every call evaluates J first, so it carries nothing from call to call); lu_static:
    (n_rows, sparse, size_tag), the same for the batch; opt_f (N, 7) / opt_i (N, 3): the float / int
    fields of :class:`_Options`; rec_idx: the recorded entries (the same for the batch); rec_t (N, 2):
    (interval, first_tau); rec_bufs (N, cap, k) with rec_rows (N, 2): the rows [lo, hi) each env's
    loop records into; stats, ext (N, 9): counters and extremes; forced (N,): whether env i passes a
    :class:`_Forcing` (force_f (N, 3): unbalance, angle, max_step; shocks (N, kmax, 4) with n_shocks)
    or None; codes (N,): the status codes (out).  A failure is a status of its env only.  (The
    batch functions unpack lu_static before their loop: a nested tuple cannot enter a parallel loop.)"""
    y = (Y[i, 0], Y[i, 1], Y[i, 2], Y[i, 3], Y[i, 4])
    clock = (clocks[i, 0], clocks[i, 1], clocks[i, 2], clocks[i, 3], history[i])
    schedule = (schedules[i, 0], schedules[i, 1], schedules[i, 2], schedules[i, 3], schedules[i, 4])
    kargs = (IP[i], FP[i], SN[i], CS[i])
    jac = _Jacobian(Ad[i], Ap[i], Am[i], Er[i], Rr[i], Srr[i])
    lu = _Factorization(Dlu[i], Dpiv[i], Uhat[i], Yw[i], Slu[i], Spiv[i], n_rows, sparse, size_tag)
    opt = _Options(
        opt_f[i, 0], opt_f[i, 1], opt_f[i, 2], opt_f[i, 3], opt_f[i, 4], opt_i[i, 0], opt_i[i, 1],
        opt_f[i, 5], opt_f[i, 6], opt_i[i, 2],
    )  # fmt: skip
    rec = _Recording(rec_idx, rec_t[i, 0], rec_t[i, 1], rec_bufs[i, rec_rows[i, 0] : rec_rows[i, 1]])
    if forced[i]:
        forcing = _Forcing(force_f[i, 0], force_f[i, 1], shocks[i, : n_shocks[i]], force_f[i, 2])
        code, c = _advance(y, clock, schedule, kargs, jac, lu, opt, rec, stats[i], ext[i], forcing)
    else:
        code, c = _advance(y, clock, schedule, kargs, jac, lu, opt, rec, stats[i], ext[i], None)
    codes[i] = code
    clocks[i, 0] = c[0]
    clocks[i, 1] = c[1]
    clocks[i, 2] = c[2]
    clocks[i, 3] = c[3]
    history[i] = c[4]


@njit(parallel=True, cache=True)
def _advance_batch(
    Y, clocks, history, schedules, IP, FP, SN, CS,  # states, clocks, schedules, kernel args
    Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Yw, Slu, Spiv, lu_static,  # per-env workspace
    opt_f, opt_i, rec_idx, rec_t, rec_bufs, rec_rows, stats, ext,  # options, recording, outputs
    forced, force_f, shocks, n_shocks, codes,  # the forcing per env, the status codes (out)
):  # fmt: skip
    """:func:`_advance_env` of env i = 0..N-1 in a ``prange`` (the arguments: see there)."""
    n_rows, sparse, size_tag = lu_static
    for i in prange(Y.shape[0]):
        _advance_env(
            i, Y, clocks, history, schedules, IP, FP, SN, CS, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Yw,
            Slu, Spiv, n_rows, sparse, size_tag, opt_f, opt_i, rec_idx, rec_t, rec_bufs, rec_rows, stats,
            ext, forced, force_f, shocks, n_shocks, codes,
        )  # fmt: skip


@njit(cache=True)
def _advance_batch_serial(
    Y, clocks, history, schedules, IP, FP, SN, CS,  # states, clocks, schedules, kernel args
    Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Yw, Slu, Spiv, lu_static,  # per-env workspace
    opt_f, opt_i, rec_idx, rec_t, rec_bufs, rec_rows, stats, ext,  # options, recording, outputs
    forced, force_f, shocks, n_shocks, codes,  # the forcing per env, the status codes (out)
):  # fmt: skip
    """:func:`_advance_env` of env i = 0..N-1 one after the other, in the calling thread: for one
    thread or one env (numba's parallel launch costs ~50 us of CPU per call even then, measured)."""
    n_rows, sparse, size_tag = lu_static
    for i in range(Y.shape[0]):
        _advance_env(
            i, Y, clocks, history, schedules, IP, FP, SN, CS, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Yw,
            Slu, Spiv, n_rows, sparse, size_tag, opt_f, opt_i, rec_idx, rec_t, rec_bufs, rec_rows, stats,
            ext, forced, force_f, shocks, n_shocks, codes,
        )  # fmt: skip


# ------------------------------------------------------------------------------------------------
def _check_unbalance(unbalance: Unbalance | None) -> None:
    if unbalance is not None and not isinstance(unbalance, Unbalance):
        raise ValueError(f"unbalance must be an Unbalance or None, got {type(unbalance).__name__}")


@dataclass(frozen=True)
class IntegratorStatistics:
    """Work counters, summed over the calls since the last reset."""

    steps: int = 0
    rejected_steps: int = 0  # by the error test
    newton_failures: int = 0  # trial steps whose Newton iteration (or factorisation) failed
    jacobians: int = 0
    factorizations: int = 0
    rhs_evaluations: int = 0
    recorded_samples: int = 0  # by the compiled loop (a sample at the very start is not counted)
    inadmissible_iterates: int = 0  # Newton iterates with H <= 0 somewhere
    diverged_iterations: int = 0  # Newton iterations stopped for a contraction rate >= 0.9

    @classmethod
    def from_array(cls, a: np.ndarray) -> IntegratorStatistics:
        """From the compiled loop's counter vector (in the field order)."""
        return cls(*(int(v) for v in a))

    def as_array(self) -> np.ndarray:
        # not dataclasses.astuple: it deep-copies recursively, 10 % of an env's control step (profiled)
        return np.array([getattr(self, name) for name in _STATISTICS_FIELDS], dtype=np.int64)

    def __add__(self, other: IntegratorStatistics) -> IntegratorStatistics:
        return IntegratorStatistics.from_array(self.as_array() + other.as_array())

    def plus(self, counts: list[int]) -> IntegratorStatistics:
        """These counters plus the compiled loop's ``counts`` (a list in the field order; plain ints:
        the arrays of ``+`` cost ~8 us per control step)."""
        s = self
        return IntegratorStatistics(
            s.steps + counts[0],
            s.rejected_steps + counts[1],
            s.newton_failures + counts[2],
            s.jacobians + counts[3],
            s.factorizations + counts[4],
            s.rhs_evaluations + counts[5],
            s.recorded_samples + counts[6],
            s.inadmissible_iterates + counts[7],
            s.diverged_iterations + counts[8],
        )


_STATISTICS_FIELDS = tuple(f.name for f in dataclasses.fields(IntegratorStatistics))


@dataclass(frozen=True)
class StepperState:
    """Everything the continuation of a run depends on: the one owner of the integrator's saved state.

    The arrays are updated in place by the compiled loop (so "frozen" means: the fields are not
    rebound); :meth:`TrapezoidalIntegrator.snapshot` hands out a :meth:`copy`.  ``history`` counts the
    earlier accepted states the predictor may use (0, 1 or 2).
    """

    s: np.ndarray  # the state s_n at tau
    f: np.ndarray  # k(s_n)
    fprev: np.ndarray  # k(s_{n-1})
    sprev: np.ndarray  # s_{n-1}
    sprev2: np.ndarray  # s_{n-2}
    tau: float
    step: float  # the step size the next step will try
    previous_step: float  # h_{n-1}
    previous_step2: float  # h_{n-2}
    history: int
    bearing_number: float  # Lambda at tau
    foil_damping: float  # D_W at tau
    statistics: IntegratorStatistics
    last_record_tau: float  # the last recorded sample (each grid time is recorded once)
    rotation_angle: float = 0.0  # theta at tau (carried exactly, reduced to [0, 2 pi))
    rotation_acceleration: float = 0.0  # theta'' = dLambda/dtau that f's unbalance term was taken at
    unbalance: Unbalance | None = None  # the rotor's unbalance (f includes its forcing)
    shocks: tuple[HalfSineShock, ...] = ()  # base shocks not yet over at tau

    ARRAYS = ("s", "f", "fprev", "sprev", "sprev2")

    @classmethod
    def start(
        cls,
        model: GFBModel,
        s: np.ndarray,
        bearing_number: float,
        foil_damping: float,
        tau: float,
        first_step: float,
        rotation_angle: float = 0.0,
        unbalance: Unbalance | None = None,
    ) -> StepperState:
        """A fresh start from ``s`` (no step history), with the rotation angle theta and the
        unbalance (whose forcing at ``tau`` enters ``f``)."""
        f = model.rhs(s, bearing_number, foil_damping)
        if unbalance is not None and unbalance.magnitude != 0.0:
            # at a fresh start the speed is taken as constant (theta'' = 0): the ramp of the next
            # advance call enters from its first step on
            a = F.unbalance_acceleration(
                unbalance.magnitude, rotation_angle + unbalance.phase_rad, float(bearing_number), 0.0
            )
            f[model.layout.xi_dot_index] += a[0]
            f[model.layout.eta_dot_index] += a[1]
        return cls(
            s=s,
            f=f,
            fprev=np.zeros_like(s),
            sprev=s.copy(),
            sprev2=s.copy(),
            tau=float(tau),
            step=float(first_step),
            previous_step=0.0,
            previous_step2=0.0,
            history=0,
            bearing_number=float(bearing_number),
            foil_damping=float(foil_damping),
            statistics=IntegratorStatistics(),
            last_record_tau=-math.inf,
            rotation_angle=float(rotation_angle),
            unbalance=unbalance,
        )

    def copy(self) -> StepperState:
        """A copy with copied arrays."""
        return dataclasses.replace(self, **{k: getattr(self, k).copy() for k in self.ARRAYS})

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(s, f, fprev, sprev, sprev2)``: the compiled loop's ``y``."""
        return self.s, self.f, self.fprev, self.sprev, self.sprev2

    @property
    def clock(self) -> tuple[float, float, float, float, int]:
        """``(tau, step, previous_step, previous_step2, history)``: the compiled loop's ``clock``."""
        return (
            float(self.tau),
            float(self.step),
            float(self.previous_step),
            float(self.previous_step2),
            int(self.history),
        )

    def with_clock(self, clock: tuple[float, float, float, float, int]) -> StepperState:
        """The same arrays with the clock the compiled loop returned."""
        tau, step, previous_step, previous_step2, history = clock
        return dataclasses.replace(
            self,
            tau=float(tau),
            step=float(step),
            previous_step=float(previous_step),
            previous_step2=float(previous_step2),
            history=int(history),
        )

    def advanced(
        self,
        clock: tuple[float, float, float, float, int],
        *,
        bearing_number: float,
        foil_damping: float,
        counts: list[int],
        last_record_tau: float,
        rotation_angle: float,
        rotation_acceleration: float,
        shocks: tuple[HalfSineShock, ...],
    ) -> StepperState:
        """The state after a compiled call: the same (advanced in place) arrays, the loop's ``clock``
        and the rest as given (one constructor call: two ``dataclasses.replace`` cost ~10 us)."""
        tau, step, previous_step, previous_step2, history = clock
        # the frozen dataclass's __init__ sets its 18 fields one object.__setattr__ at a time (~3 us);
        # the instance dict filled at once holds the same fields (no __post_init__, no defaults left)
        new = object.__new__(StepperState)
        new.__dict__.update(
            s=self.s, f=self.f, fprev=self.fprev, sprev=self.sprev, sprev2=self.sprev2, tau=float(tau),
            step=float(step), previous_step=float(previous_step), previous_step2=float(previous_step2),
            history=int(history), bearing_number=bearing_number, foil_damping=foil_damping,
            statistics=self.statistics.plus(counts), last_record_tau=last_record_tau,
            rotation_angle=rotation_angle, rotation_acceleration=rotation_acceleration,
            unbalance=self.unbalance, shocks=shocks,
        )  # fmt: skip
        return new

    def as_dict(self) -> dict[str, Any]:
        """The fields as a dict (arrays copied), plus ``lam``/``dw``: aliases of the operating point for
        callers of the earlier dict snapshot (``gfb_env.envs.base`` reads them)."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d |= {k: d[k].copy() for k in self.ARRAYS}
        return d | {"lam": self.bearing_number, "dw": self.foil_damping}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StepperState:
        """Inverse of :meth:`as_dict` (arrays copied; the aliases are ignored; a dict from before the
        forcing existed has theta = 0, no unbalance and no shocks)."""
        kw = {f.name: d[f.name] for f in dataclasses.fields(cls) if f.name in d}
        kw |= {k: np.array(kw[k], dtype=float, copy=True) for k in cls.ARRAYS}
        return cls(**kw)


@dataclass
class Trajectory:
    """Uniformly sampled output of one or more :meth:`TrapezoidalIntegrator.advance` calls.

    Attributes: nondimensional time ``tau``; rotor ``xi``, ``eta``, ``xi_dot``, ``eta_dot``; minimum
    film thickness (linear between steps); ``probes`` (samples of the requested extra state entries,
    shape (n, k)); the schedule ``bearing_number`` and ``foil_damping`` at each sample.
    """

    tau: np.ndarray
    xi: np.ndarray
    eta: np.ndarray
    xi_dot: np.ndarray
    eta_dot: np.ndarray
    min_film_thickness: np.ndarray
    probes: np.ndarray
    bearing_number: np.ndarray
    foil_damping: np.ndarray

    @property
    def eccentricity(self) -> np.ndarray:
        return np.hypot(self.xi, self.eta)

    def __len__(self) -> int:
        return len(self.tau)

    @classmethod
    def concatenate(cls, parts: list[Trajectory]) -> Trajectory:
        if not parts:
            raise ValueError("parts must not be empty")
        names = [f for f in cls.__dataclass_fields__]
        return cls(**{k: np.concatenate([getattr(p, k) for p in parts]) for k in names})


@dataclass
class TouchdownEvent:
    """The journal touched the foil: min film thickness crossed the threshold at ``tau``."""

    tau: float
    xi: float
    eta: float
    min_film_thickness: float


@dataclass
class AdvanceResult:
    """What :meth:`TrapezoidalIntegrator.advance` did."""

    status: IntegrationStatus
    tau: float
    trajectory: Trajectory
    touchdown: TouchdownEvent | None
    steps: int
    rejected_steps: int
    newton_failures: int
    jacobians: int
    factorizations: int
    rhs_evaluations: int
    min_film_thickness: float
    xi_range: tuple[float, float]
    eta_range: tuple[float, float]
    max_eccentricity: float
    message: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status in (IntegrationStatus.DONE, IntegrationStatus.TOUCHDOWN)


class TrapezoidalIntegrator:
    """Adaptive trapezoidal-rule stepper for a :class:`~gfb_env.model.GFBModel` (see module docstring).

    Args:
        model: the coupled model.
        state: initial state (copied).
        bearing_number: Lambda at the initial time.
        foil_damping: D_W at the initial time (viscoelastic foil only).
        tau: initial nondimensional time.
        rtol, atol: local error tolerances (weighted max-norm).  Default 3e-4 from the convergence
            study of the limit-cycle amplitude (``python -m gfb_experiments.convergence_study``): the
            amplitude is within 0.06 % and the minimum film within 5 % of the rtol = 3e-5 result, at the
            same cost as 3e-3 (below ~1e-3 the step is limited by Newton convergence near contact,
            not by the error estimate).
        first_step, max_step, min_step: step-size limits in tau.
        touchdown_film_thickness: minimum film thickness H that counts as touchdown.
        max_newton_iterations: per trial step.
        newton_tol: Newton stops when the weighted update (or its rate-extrapolated remainder) is below
            this fraction of the error tolerance.
        factorization_ratio: the factorisation of ``I - h'/2 J`` is reused for a step h with
            ``h'/ratio <= h <= h' ratio`` (modified Newton still converges; on the paper grid a new one
            costs ~55 us, a solve ~6.5 us).
        slow_newton_iterations: a step that needed more iterations marks the Jacobian stale.
        unbalance: the rotor's :class:`~gfb_env.forcing.Unbalance` (None: none; see
            :meth:`set_unbalance`); its forcing uses the rotation angle theta, carried exactly from
            ``rotation_angle`` (theta' = Lambda; :attr:`rotation_angle`).
        steps_per_revolution: with an unbalance, the step is at most ``2 pi / (N Lambda)`` (see
            :data:`STEPS_PER_REVOLUTION`).  Base shocks (:meth:`add_shock`): steps land on the start and
            end of each pulse and take at most 1/32 of it inside (the trapezoidal quadrature of a
            half sine in n steps loses ``pi^2 / (12 n^2)`` of its impulse: 1.3 % at n = 8, 0.08 % at 32).
    """

    def __init__(
        self,
        model: GFBModel,
        state: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        tau: float = 0.0,
        rtol: float = IntegratorOptions.rtol,
        atol: float = IntegratorOptions.atol,
        first_step: float = IntegratorOptions.first_step,
        max_step: float = IntegratorOptions.max_step,
        min_step: float = IntegratorOptions.min_step,
        touchdown_film_thickness: float = 0.01,
        max_newton_iterations: int = IntegratorOptions.max_newton_iterations,
        newton_tol: float = IntegratorOptions.newton_tol,
        factorization_ratio: float = IntegratorOptions.factorization_ratio,
        slow_newton_iterations: int = IntegratorOptions.slow_newton_iterations,
        unbalance: Unbalance | None = None,
        rotation_angle: float = 0.0,
        steps_per_revolution: float = STEPS_PER_REVOLUTION,
    ):
        # one owner of the settings' defaults and validation (also used by the environments)
        self.options = IntegratorOptions(
            rtol=rtol,
            atol=atol,
            first_step=first_step,
            max_step=max_step,
            min_step=min_step,
            max_newton_iterations=max_newton_iterations,
            newton_tol=newton_tol,
            factorization_ratio=factorization_ratio,
            slow_newton_iterations=slow_newton_iterations,
        )
        if not (math.isfinite(touchdown_film_thickness) and 0 <= touchdown_film_thickness < 1):
            raise ValueError(f"touchdown_film_thickness must lie in [0, 1), got {touchdown_film_thickness!r}")
        if not (math.isfinite(steps_per_revolution) and steps_per_revolution >= 1):
            raise ValueError(f"steps_per_revolution must be finite and >= 1, got {steps_per_revolution!r}")
        self.steps_per_revolution = float(steps_per_revolution)
        self.model = model
        o = self.options
        self.rtol, self.atol = o.rtol, o.atol
        self.first_step, self.max_step, self.min_step = o.first_step, o.max_step, o.min_step
        self.touchdown_film_thickness = float(touchdown_film_thickness)
        self.max_newton_iterations = o.max_newton_iterations
        self.newton_tol = o.newton_tol
        self.factorization_ratio = o.factorization_ratio
        self.slow_newton_iterations = o.slow_newton_iterations
        self._kernel_args = model.kernel_args()
        self._shape_key = _shape_key(model)  # BatchAdvance batches integrators of one shape
        self._record_key: tuple | None = None  # the last record_indices (see _record_indices)
        self._record_idx = _NO_INDICES
        self._jacobian = _Jacobian(**model.new_blocks())
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        self._factorization = _Factorization(
            Dlu=np.zeros((nc, m, m)),
            Dpiv=np.zeros((nc, m), dtype=np.int64),
            Uhat=np.zeros((nc, m, m)),
            Y=np.zeros((nc, m, nb)),
            Slu=np.zeros((nb, nb)),
            Spiv=np.zeros(nb, dtype=np.int64),
            n_rows=model.grid.n_rows,
            sparse=model.sparse_offdiagonal_blocks,
            size_tag=K.size_tag(m),
        )
        self.reset(
            state, bearing_number, foil_damping, tau, rotation_angle=rotation_angle, unbalance=unbalance
        )

    # ------------------------------------------------------------------------------------------
    def reset(
        self,
        state: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        tau: float = 0.0,
        rotation_angle: float = 0.0,
        unbalance: Unbalance | None | str = "keep",
    ) -> None:
        """Restart from ``state`` at time ``tau`` with the rotation angle theta = ``rotation_angle``
        (forgets the step history and pending shocks; keeps the unbalance unless one is given)."""
        self.model.check_operating_point(bearing_number, foil_damping)
        s = np.array(self.model.layout.check(state), dtype=float, copy=True)
        if not np.all(np.isfinite(s)):
            raise ValueError("state must be finite")
        if not math.isfinite(rotation_angle):
            raise ValueError(f"rotation_angle must be finite, got {rotation_angle!r}")
        if isinstance(unbalance, str):
            unbalance = getattr(self, "_stepper", None) and self._stepper.unbalance
        _check_unbalance(unbalance)
        self._stepper = StepperState.start(
            self.model, s, bearing_number, foil_damping, tau, self.first_step,
            rotation_angle=math.fmod(float(rotation_angle), 2.0 * math.pi) % (2.0 * math.pi),
            unbalance=unbalance if unbalance is not None and unbalance.magnitude != 0.0 else None,
        )  # fmt: skip

    @property
    def rotation_angle(self) -> float:
        """theta at :attr:`tau` in [0, 2 pi): the rotor's angle from the downward vertical toward
        +xi (theta' = Lambda, carried exactly; see :mod:`gfb_env.forcing`)."""
        return self._stepper.rotation_angle

    @property
    def unbalance(self) -> Unbalance | None:
        return self._stepper.unbalance

    @property
    def shocks(self) -> tuple[HalfSineShock, ...]:
        """The base shocks scheduled and not yet over."""
        return self._stepper.shocks

    def set_unbalance(self, unbalance: Unbalance | None) -> None:
        """Switch the unbalance (None: none) from now on.  The forcing jumps: k at the current state is
        re-evaluated with it (the step history is kept, as for a jump of the damping command)."""
        _check_unbalance(unbalance)
        st = self._stepper
        old = st.unbalance
        new = unbalance if (unbalance is not None and unbalance.magnitude != 0.0) else None
        if new == old:
            return
        f = st.f.copy()
        L = self.model.layout
        for ub, sign in ((old, -1.0), (new, 1.0)):
            if ub is not None:
                a = F.unbalance_acceleration(
                    ub.magnitude,
                    st.rotation_angle + ub.phase_rad,
                    st.bearing_number,
                    st.rotation_acceleration,
                )
                f[L.xi_dot_index] += sign * a[0]
                f[L.eta_dot_index] += sign * a[1]
        if new is None:
            # bit for bit the unforced k again (no rounding residue of adding and removing)
            f = self.model.rhs(st.s, st.bearing_number, st.foil_damping)
        self._stepper = dataclasses.replace(st, f=f, unbalance=new)

    def add_shock(self, shock: HalfSineShock) -> None:
        """Schedule a base shock (it must not start before :attr:`tau`: its acceleration starts at zero,
        so k at the current state stays valid).  Steps land on its start and end."""
        if not isinstance(shock, HalfSineShock):
            raise ValueError(f"shock must be a HalfSineShock, got {type(shock).__name__}")
        st = self._stepper
        if shock.start_tau < st.tau:
            raise ValueError(f"shock start_tau {shock.start_tau:g} is before the current time {st.tau:g}")
        shocks = tuple(sorted(st.shocks + (shock,), key=lambda q: (q.start_tau, q.duration_tau)))
        self._stepper = dataclasses.replace(st, shocks=shocks)

    @property
    def tau(self) -> float:
        return self._stepper.tau

    @property
    def state(self) -> np.ndarray:
        """Current state (a copy)."""
        return self._stepper.s.copy()

    @property
    def bearing_number(self) -> float:
        return self._stepper.bearing_number

    @property
    def foil_damping(self) -> float:
        return self._stepper.foil_damping

    @property
    def step_size(self) -> float:
        """The step size the next step will try."""
        return self._stepper.step

    @property
    def statistics(self) -> IntegratorStatistics:
        """Work counters since the last :meth:`reset`."""
        return self._stepper.statistics

    @property
    def stats(self) -> np.ndarray:
        """:attr:`statistics` as a vector in its field order (``stats[0]`` is the step count)."""
        return self._stepper.statistics.as_array()

    def snapshot(self) -> StepperState:
        """Everything the continuation depends on (a copy; restore with :meth:`restore`)."""
        return self._stepper.copy()

    def restore(self, snapshot: StepperState) -> None:
        """Continue from ``snapshot`` (copied): the continuation is bit for bit the original one."""
        if snapshot.s.shape != (self.model.layout.size,):
            raise ValueError(
                f"snapshot state has shape {snapshot.s.shape}, the model needs ({self.model.layout.size},)"
            )
        self._stepper = snapshot.copy()

    def get_state(self) -> dict[str, Any]:
        """:meth:`snapshot` as a dict (:meth:`StepperState.as_dict`); restore with :meth:`set_state`."""
        return self._stepper.as_dict()

    def set_state(self, snap: dict[str, Any] | StepperState) -> None:
        """Restore a :meth:`get_state` dict (or a :class:`StepperState`)."""
        self.restore(snap if isinstance(snap, StepperState) else StepperState.from_dict(snap))

    # ------------------------------------------------------------------------------------------
    def _forcing_of_call(
        self, st: StepperState, span: float, lam0: float, lam1: float
    ) -> tuple[_Forcing | None, float]:
        """The compiled loop's forcing group for one call, and theta'' of its ramp.  With an unbalance,
        k at the start (``st.f``, in place) is moved to this call's theta'' (a ramp change is a jump of
        the angular acceleration, so the first step sees the new one at both of its ends)."""
        ub = st.unbalance
        if ub is None and not st.shocks:
            return None, st.rotation_acceleration
        rate = (lam1 - lam0) / span if span > 0 else st.rotation_acceleration
        u = 0.0 if ub is None else ub.magnitude
        angle = st.rotation_angle + (0.0 if ub is None else ub.phase_rad)
        if u != 0.0 and rate != st.rotation_acceleration:
            L = self.model.layout
            d = rate - st.rotation_acceleration
            st.f[L.xi_dot_index] -= u * d * math.cos(angle)
            st.f[L.eta_dot_index] += u * d * math.sin(angle)
        shocks = np.array([q.as_row() for q in st.shocks]) if st.shocks else _NO_SHOCKS
        lam_max = max(lam0, lam1)
        n_rev = self.steps_per_revolution
        max_step = math.inf if u == 0.0 or lam_max <= 0 else 2.0 * math.pi / (n_rev * lam_max)
        return _Forcing(u, angle, shocks, max_step), rate

    def advance(
        self,
        tau_end: float,
        bearing_number: float | None = None,
        foil_damping: float | None = None,
        record_interval: float | None = None,
        record_indices: np.ndarray | None = None,
        max_steps: int = DEFAULT_MAX_STEPS,
        raise_on_failure: bool = True,
    ) -> AdvanceResult:
        """Integrate to ``tau_end`` with Lambda and D_W ramped linearly from their current values to
        ``bearing_number`` / ``foil_damping`` (unchanged when None).

        Records the rotor state, the min film thickness and ``record_indices`` (extra state entries,
        e.g. pressure probes from :meth:`StateLayout.midplane_probe_indices`) every
        ``record_interval`` (a uniform grid anchored at tau = 0, by cubic Hermite interpolation).

        Stops early on touchdown (``status == "touchdown"``, with the event).  If the step size falls
        below ``min_step`` or ``max_steps`` is exceeded, raises :class:`IntegrationError` (or returns
        ``status == "failed"`` / ``"max_steps"`` when ``raise_on_failure`` is False); the state is
        then the last accepted one, never NaN.

        Three parts: :meth:`prepare` (Python: checks and the compiled call's arguments), the compiled
        loop :func:`_advance`, :meth:`_finish` (Python: the new :class:`StepperState` and the result).
        :func:`advance_batch` runs the same parts for many integrators with one compiled call.
        """
        call = self.prepare(tau_end, bearing_number, foil_damping, record_interval, record_indices, max_steps)
        code, clock = _call_compiled(
            _advance, (self._factorization.size_tag, call.forcing is None),
            call.st.arrays, call.st.clock, call.schedule, self._kernel_args, self._jacobian,
            self._factorization, call.options, call.recording, call.stats, call.ext, call.forcing,
        )  # fmt: skip
        return self._finish(
            call, code, clock, call.stats.tolist(), call.ext.tolist(), call.rec_buf, raise_on_failure
        )

    def _record_indices(self, record_indices: np.ndarray | None) -> np.ndarray:
        """The recorded state entries: the rotor, then ``record_indices`` (checked; the last one is
        kept, so an env that records the same probes every control step builds them once)."""
        extra = _NO_INDICES if record_indices is None else np.asarray(record_indices, np.int64)
        key = (extra.shape, extra.tobytes())
        if key == self._record_key:
            return self._record_idx
        if extra.size and (extra.min() < 0 or extra.max() >= self.model.layout.size):
            raise ValueError("record_indices out of range")
        L = self.model.layout
        rec_idx = np.concatenate([np.arange(L.rotor_offset, L.size, dtype=np.int64), extra])
        self._record_key, self._record_idx = key, rec_idx
        return rec_idx

    def prepare(
        self,
        tau_end: float,
        bearing_number: float | None,
        foil_damping: float | None,
        record_interval: float | None,
        record_indices: np.ndarray | None,
        max_steps: int,
    ) -> PreparedCall:
        """Check one call's arguments and build the compiled loop's (nothing is integrated yet; the
        unbalance's k at the start may move to this call's theta'', see :meth:`_forcing_of_call`)."""
        st = self._stepper
        lam0, dw0 = st.bearing_number, st.foil_damping
        lam1 = lam0 if bearing_number is None else float(bearing_number)
        dw1 = dw0 if foil_damping is None else float(foil_damping)
        self.model.check_operating_point(lam1, dw1)
        if not math.isfinite(tau_end):
            raise ValueError(f"tau_end must be finite, got {tau_end!r}")
        t0 = st.tau
        if tau_end < t0:
            raise ValueError(f"tau_end must not be before the current time {t0}, got {tau_end}")
        rec_idx = self._record_indices(record_indices)
        if record_interval is None:
            rec_dt = math.inf
            rec_next = math.inf
            cap = 0
        else:
            if not (math.isfinite(record_interval) and record_interval > 0):
                raise ValueError(f"record_interval must be positive, got {record_interval!r}")
            rec_dt = float(record_interval)
            # samples on the grid k * rec_dt, each recorded once across consecutive calls
            k0 = math.ceil(t0 / rec_dt - 1e-9)
            if k0 * rec_dt <= st.last_record_tau + 1e-9 * rec_dt:
                k0 += 1
            rec_next = k0 * rec_dt
            cap = max(int(math.floor((tau_end - rec_next) / rec_dt + 1e-9)) + 2, 0)
        rec_buf = np.empty((cap, len(rec_idx) + 2))
        first = 0
        if cap and rec_next <= t0 + 1e-9 * rec_dt:  # a sample exactly at the start
            rec_buf[0, 0] = t0
            rec_buf[0, 1:-1] = st.s[rec_idx]
            rec_buf[0, -1] = self.model.min_film_thickness(st.s)
            first = 1
            rec_next += rec_dt
        options = _Options(
            self.rtol, self.atol, self.min_step, self.max_step, self.touchdown_film_thickness,
            int(max_steps), self.max_newton_iterations, self.newton_tol, self.factorization_ratio,
            self.slow_newton_iterations,
        )  # fmt: skip
        span = float(tau_end) - t0
        forcing, rate = self._forcing_of_call(st, span, lam0, lam1)
        return PreparedCall(
            st=st,
            schedule=(float(tau_end), lam0, lam1, dw0, dw1),
            span=span,
            rate=rate,
            options=options,
            recording=_Recording(rec_idx, rec_dt, float(rec_next), rec_buf[first:]),
            rec_buf=rec_buf,
            first=first,
            stats=np.zeros(9, dtype=np.int64),
            ext=_EXTREMES_START.copy(),
            forcing=forcing,
            max_steps=max_steps,
        )

    def _finish(
        self,
        call: PreparedCall,
        code: int,
        clock: tuple[float, float, float, float, int],
        counts: list[int],
        ext: list[float],
        rec_buf: np.ndarray,
        raise_on_failure: bool,
    ) -> AdvanceResult:
        """The integrator's new state and the call's result from the compiled loop's outputs: its status
        code, clock, counters and extremes (as lists) and its sample buffer (``call.rec_buf`` or the
        batch's copy of it)."""
        st = call.st
        t0, lam0, lam1, dw0, dw1 = st.tau, *call.schedule[1:]
        span = call.span
        t = float(clock[0])
        theta = (t - t0) / span if span > 0 else 1.0
        lam_t = lam0 + (lam1 - lam0) * theta
        dw_t = dw0 + (dw1 - dw0) * theta
        nrec = call.first + counts[_NREC]
        rb = rec_buf[:nrec]
        # theta' = Lambda is linear in time over the call: theta advances by the exact trapezoid
        angle = st.rotation_angle + (t - t0) * 0.5 * (lam0 + lam_t)
        self._stepper = new = st.advanced(
            clock,
            bearing_number=lam_t,
            foil_damping=dw_t,
            counts=counts,
            last_record_tau=float(rb[-1, 0]) if nrec else st.last_record_tau,
            rotation_angle=math.fmod(angle, 2.0 * math.pi) if span > 0 else st.rotation_angle,
            rotation_acceleration=call.rate,
            shocks=tuple(q for q in st.shocks if q.end_tau > t) if st.shocks else (),
        )
        # one copy of the samples, column by column (each column contiguous; the probes a view of it)
        cols = rb.T.copy()
        tau_s = cols[0]
        th = (tau_s - t0) / span if span > 0 else np.ones_like(tau_s)
        traj = Trajectory(
            tau=tau_s,
            xi=cols[1],
            eta=cols[2],
            xi_dot=cols[3],
            eta_dot=cols[4],
            min_film_thickness=cols[-1],
            probes=cols[5:-1].T,
            bearing_number=lam0 + (lam1 - lam0) * th,
            foil_damping=dw0 + (dw1 - dw0) * th,
        )
        event = None
        if code == _TOUCHDOWN:
            event = TouchdownEvent(ext[_EVT], ext[_EVXI], ext[_EVETA], self.touchdown_film_thickness)
        msg = ""
        if code == _FAILED:
            msg = (
                f"step size fell below min_step={self.min_step:g} at tau={t:.6g} "
                f"(Lambda={lam_t:.4g}, D_W={dw_t:.4g}); the state is the last accepted one"
            )
        elif code == _MAX_STEPS:
            msg = f"max_steps={call.max_steps} reached at tau={t:.6g}"
        min_h = ext[_MINH]
        if not math.isfinite(min_h):
            min_h = self.model.min_film_thickness(new.s)
        res = AdvanceResult(
            status=_STATUS_OF_CODE[code],
            tau=t,
            trajectory=traj,
            touchdown=event,
            steps=counts[_NSTEPS],
            rejected_steps=counts[_NREJ_ERR],
            newton_failures=counts[_NREJ_NEWTON],
            jacobians=counts[_NJAC],
            factorizations=counts[_NFACT],
            rhs_evaluations=counts[_NRHS],
            min_film_thickness=float(min_h),
            xi_range=(ext[_XIMIN], ext[_XIMAX]),
            eta_range=(ext[_ETAMIN], ext[_ETAMAX]),
            max_eccentricity=ext[_EPSMAX],
            message=msg,
        )
        if raise_on_failure and code in (_FAILED, _MAX_STEPS):
            raise IntegrationError(msg)
        return res


# ------------------------------------------------------------------------------------------------
#: (compiled function, key) -> the entry point of its compiled variant for the argument types of that key
_ENTRY_POINTS: dict[tuple, Any] = {}


def _call_compiled(dispatcher: Any, key: tuple, *args: Any) -> Any:
    """``dispatcher(*args)``, the types of whose arguments ``key`` determines.  The first call of a key
    goes through numba's dispatcher (it compiles or loads the variant); later ones call that variant's
    entry point directly.  The dispatcher types every argument of every call, and the factorisation's
    ``size_tag`` tuple alone cost ~12 us of the ~22 us it spent on one control step's call (CPU time):
    the arguments' types here are fixed by the key (the block size and whether a forcing is passed
    for :func:`_advance`; the workspace's static part for :func:`_advance_batch`), the call is the same
    compiled code."""
    entry = _ENTRY_POINTS.get((dispatcher, key))
    if entry is not None:
        return entry(*args)
    result = dispatcher(*args)
    try:
        types = tuple(dispatcher.typeof_pyval(a) for a in args)
        _ENTRY_POINTS[(dispatcher, key)] = dispatcher.overloads[types].entry_point
    except (KeyError, AttributeError):  # pragma: no cover - numba without these internals: the dispatcher
        pass
    return result


def _choose_threading_layer() -> None:
    """numba's ``workqueue`` threading layer for the batch unless the user chose one
    (``NUMBA_THREADING_LAYER``) or numba already started one.  Measured on the shared 2-core machine
    (load ~4): with 2 threads GNU OpenMP's ``omp`` layer made a batch call 5x slower than 1 thread
    (its workers spin while the cores are busy), ``workqueue`` was as fast as 1 thread; ``workqueue``
    is also fork-safe (GNU OpenMP is not: a forked worker that launched threads would hang).  It is
    not thread-safe: do not step two batches from two Python threads at once."""
    if os.environ.get("NUMBA_THREADING_LAYER") is None and numba.config.THREADING_LAYER == "default":
        from numba.np.ufunc import parallel

        if not getattr(parallel, "_is_initialized", True):  # (numba internals: when unknown, leave it)
            numba.config.THREADING_LAYER = "workqueue"


class _BatchWorkspace:
    """The stacked arrays of :func:`_advance_batch` for up to ``capacity`` envs of one model shape."""

    def __init__(self, capacity: int, model: GFBModel, n_recorded: int):
        N, n = capacity, model.layout.size
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        z = np.zeros
        self.shape_key = _shape_key(model)
        self.capacity, self.n_recorded = capacity, n_recorded
        self.Y = z((N, 5, n))
        self.clocks, self.history, self.schedules = z((N, 4)), z(N, np.int64), z((N, 5))
        self.IP, self.FP, self.SN, self.CS = z((N, 3), np.int64), z((N, 4)), z((N, nc)), z((N, nc))
        self.kargs_of_slot: list[tuple | None] = [None] * N  # whose kernel args each row holds
        self.jac = (z((N, nc, m, m)), z((N, nc, m, m)), z((N, nc, m, m)), z((N, nc, m, 4)))
        self.jac += (z((N, nc, 4, m)), z((N, 4, 4)))
        self.lu = (z((N, nc, m, m)), z((N, nc, m), np.int64), z((N, nc, m, m)), z((N, nc, m, nb)))
        self.lu += (z((N, nb, nb)), z((N, nb), np.int64))
        self.lu_static = (model.grid.n_rows, model.sparse_offdiagonal_blocks, K.size_tag(m))
        self.opt_f, self.opt_i = z((N, 7)), z((N, 3), np.int64)
        self.rec_t, self.rec_rows = z((N, 2)), z((N, 2), np.int64)
        self.rec_bufs = np.empty((N, 0, n_recorded + 2))
        self.stats, self.ext = z((N, 9), np.int64), z((N, 9))
        self.forced, self.force_f = z(N, np.bool_), z((N, 3))
        self.shocks, self.n_shocks = z((N, 0, 4)), z(N, np.int64)
        self.codes = z(N, np.int64)

    def fits(self, n_envs: int, model: GFBModel, n_recorded: int) -> bool:
        return (
            n_envs <= self.capacity and _shape_key(model) == self.shape_key and n_recorded == self.n_recorded
        )

    def reserve(self, rows: int, shocks: int) -> None:
        """At least ``rows`` sample rows and ``shocks`` shock rows per env."""
        N = self.capacity
        if self.rec_bufs.shape[1] < rows:
            self.rec_bufs = np.empty((N, rows, self.rec_bufs.shape[2]))
        if self.shocks.shape[1] < shocks:
            self.shocks = np.zeros((N, shocks, 4))


def _shape_key(model: GFBModel) -> tuple:
    """What the stacked arrays' shapes and the solver's static arguments depend on."""
    g = model.grid
    return (
        model.layout.size,
        g.n_columns,
        g.n_rows,
        model.layout.block_size,
        model.sparse_offdiagonal_blocks,
    )


class BatchAdvance:
    """Advance many :class:`TrapezoidalIntegrator` objects with one compiled, parallel call.

    :meth:`advance` runs, for each integrator, exactly what its :meth:`TrapezoidalIntegrator.advance`
    runs: the same Python preparation and finish, and the same compiled loop (:func:`_advance`, called
    by :func:`_advance_batch` in a numba ``prange`` over the integrators), so every result and state is
    bit for bit the one-by-one result, for any thread count.  Integrators may have different models of
    one grid (e.g. randomised bearings), be forced (unbalance, shocks) or not; a failure (status
    ``"failed"``/``"max_steps"``) is that integrator's only.  Integrators of different grids, or calls
    with different recorded entries, are advanced one after the other (same results).

    Args:
        num_threads: numba threads of the call (``numba.set_num_threads``; at most
            ``numba.config.NUMBA_NUM_THREADS``, the cores numba sees, which is the default).  The
            environment variable ``NUMBA_NUM_THREADS`` caps it for the process.
    """

    def __init__(self, num_threads: int | None = None):
        self.num_threads = num_threads
        self._ws: _BatchWorkspace | None = None

    @property
    def num_threads(self) -> int:
        return self._num_threads

    @num_threads.setter
    def num_threads(self, value: int | None) -> None:
        limit = numba.config.NUMBA_NUM_THREADS
        if value is None:
            value = limit
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= limit:
            raise ValueError(
                f"num_threads must be an integer in [1, {limit}] (NUMBA_NUM_THREADS), got {value!r}"
            )
        self._num_threads = int(value)

    def advance(
        self,
        integrators: list[TrapezoidalIntegrator],
        tau_end: list[float],
        bearing_number: list[float | None],
        foil_damping: list[float | None],
        record_interval: float | None = None,
        record_indices: np.ndarray | None = None,
        max_steps: int = DEFAULT_MAX_STEPS,
        raise_on_failure: bool = True,
    ) -> list[AdvanceResult]:
        """:meth:`TrapezoidalIntegrator.advance` of every integrator (``tau_end``, ``bearing_number``,
        ``foil_damping``: one per integrator; the recording and ``max_steps`` are shared).  Bad
        arguments raise as one call after the other would (the integrators before the bad one are
        advanced).  With ``raise_on_failure`` an :class:`IntegrationError` is raised after all are
        advanced, for the first one that failed."""
        integs = list(integrators)
        n = len(integs)
        if len({id(x) for x in integs}) != n:
            raise ValueError("integrators: each integrator may appear only once")
        for name, v in (
            ("tau_end", tau_end),
            ("bearing_number", bearing_number),
            ("foil_damping", foil_damping),
        ):
            if len(v) != n:
                raise ValueError(f"{name}: {len(v)} values for {n} integrators")
        calls: list[PreparedCall] = []
        try:
            for k, integ in enumerate(integs):
                calls.append(
                    integ.prepare(
                        tau_end[k],
                        bearing_number[k],
                        foil_damping[k],
                        record_interval,
                        record_indices,
                        max_steps,
                    )
                )
        except Exception:
            self.run_prepared(integs[: len(calls)], calls)  # those before the bad one, as one by one
            raise
        results = self.run_prepared(integs, calls)
        if raise_on_failure:
            for r in results:
                if r.status in (IntegrationStatus.FAILED, IntegrationStatus.MAX_STEPS):
                    raise IntegrationError(r.message)
        return results

    def run_prepared(
        self, integs: list[TrapezoidalIntegrator], calls: list[PreparedCall]
    ) -> list[AdvanceResult]:
        """The compiled part and the finish of calls prepared by ``integs[k].prepare(...)`` (each
        integrator once; used by the vector env, which prepares each env's call itself)."""
        n = len(calls)
        _choose_threading_layer()
        if n == 0:
            return []
        model0 = integs[0].model
        key = integs[0]._shape_key
        rec_key = integs[0]._record_key
        rec_idx = calls[0].recording.indices
        if any(it._shape_key != key or it._record_key != rec_key for it in integs):
            return [self._one(it, c) for it, c in zip(integs, calls, strict=True)]
        ws = self._ws
        if ws is None or not ws.fits(n, model0, len(rec_idx)):
            ws = self._ws = _BatchWorkspace(
                max(n, ws.capacity if ws is not None else 0), model0, len(rec_idx)
            )
        ws.reserve(max(c.rec_buf.shape[0] for c in calls), max(len(c.st.shocks) for c in calls))
        sts = [c.st for c in calls]
        Y = ws.Y
        for k, st in enumerate(sts):
            Yk = Y[k]
            Yk[0], Yk[1], Yk[2], Yk[3], Yk[4] = st.s, st.f, st.fprev, st.sprev, st.sprev2
        ws.clocks[:n] = [(s.tau, s.step, s.previous_step, s.previous_step2) for s in sts]
        ws.history[:n] = [s.history for s in sts]
        ws.schedules[:n] = [c.schedule for c in calls]
        ws.opt_f[:n] = [(o[0], o[1], o[2], o[3], o[4], o[7], o[8]) for o in (c.options for c in calls)]
        ws.opt_i[:n] = [(o[5], o[6], o[9]) for o in (c.options for c in calls)]
        ws.rec_t[:n] = [(c.recording.interval, c.recording.first_tau) for c in calls]
        ws.rec_rows[:n] = [(c.first, c.rec_buf.shape[0]) for c in calls]
        ws.stats[:n] = 0
        ws.ext[:n] = _EXTREMES_START
        for k, (it, c) in enumerate(zip(integs, calls, strict=True)):
            if ws.kargs_of_slot[k] is not it._kernel_args:
                ws.IP[k], ws.FP[k], ws.SN[k], ws.CS[k] = it._kernel_args
                ws.kargs_of_slot[k] = it._kernel_args
            if c.first:
                ws.rec_bufs[k, 0] = c.rec_buf[0]
            f = c.forcing
            ws.forced[k] = f is not None
            if f is not None:
                ws.force_f[k] = (f.unbalance, f.angle, f.max_step)
                ws.n_shocks[k] = len(f.shocks)
                ws.shocks[k, : len(f.shocks)] = f.shocks
        args = (
            ws.Y[:n], ws.clocks[:n], ws.history[:n], ws.schedules[:n], ws.IP[:n], ws.FP[:n], ws.SN[:n],
            ws.CS[:n], *(a[:n] for a in ws.jac), *(a[:n] for a in ws.lu), ws.lu_static, ws.opt_f[:n],
            ws.opt_i[:n], rec_idx, ws.rec_t[:n], ws.rec_bufs[:n], ws.rec_rows[:n], ws.stats[:n], ws.ext[:n],
            ws.forced[:n], ws.force_f[:n], ws.shocks[:n], ws.n_shocks[:n], ws.codes[:n],
        )  # fmt: skip
        threads = min(self._num_threads, n)
        if threads == 1:
            self._launch(_advance_batch_serial, (ws.lu_static, len(rec_idx)), *args)
        else:
            old_threads = numba.get_num_threads()
            numba.set_num_threads(threads)
            # many envs of unequal cost: one at a time to each thread (dynamic scheduling costs ~30 us
            # more per launch, measured; with a few envs per thread the static split is cheaper)
            old_chunk = numba.set_parallel_chunksize(1 if n > 4 * threads else 0)
            try:
                self._launch(_advance_batch, (ws.lu_static, len(rec_idx)), *args)
            finally:
                numba.set_parallel_chunksize(old_chunk)
                numba.set_num_threads(old_threads)
        clocks, history, codes = ws.clocks[:n].tolist(), ws.history[:n].tolist(), ws.codes[:n].tolist()
        counts, exts = ws.stats[:n].tolist(), ws.ext[:n].tolist()
        out = []
        for k, (it, c) in enumerate(zip(integs, calls, strict=True)):
            st, Yk = c.st, Y[k]
            st.s[:], st.f[:], st.fprev[:], st.sprev[:], st.sprev2[:] = Yk
            rec_buf = ws.rec_bufs[k, : c.rec_buf.shape[0]]
            out.append(it._finish(c, codes[k], (*clocks[k], history[k]), counts[k], exts[k], rec_buf, False))
        return out

    @staticmethod
    def _launch(kernel: Any, key: tuple, *args: Any) -> None:
        """The compiled batch call (a method: ``bench_env`` times it)."""
        _call_compiled(kernel, key, *args)

    @staticmethod
    def _one(it: TrapezoidalIntegrator, c: PreparedCall) -> AdvanceResult:
        code, clock = _call_compiled(
            _advance, (it._factorization.size_tag, c.forcing is None),
            c.st.arrays, c.st.clock, c.schedule, it._kernel_args, it._jacobian, it._factorization,
            c.options, c.recording, c.stats, c.ext, c.forcing,
        )  # fmt: skip
        return it._finish(c, code, clock, c.stats.tolist(), c.ext.tolist(), c.rec_buf, False)
