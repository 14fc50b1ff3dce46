"""The compiled loop of the trapezoidal stepper and its stages (see :mod:`gfb_env.integrator`).

:func:`_advance` carries a typed loop state (the arrays and clock of
:class:`~gfb_env.integrator.StepperState`, the Jacobian and factorisation flags) and calls one small
inlined helper per stage: :func:`_predict`, :func:`_newton`, :func:`_error_norm`, :func:`_record_dense`,
:func:`_shift_history`, :func:`_update_extremes`, :func:`_touchdown`, the forcing
(:func:`_forcing`, :func:`_land_on_shocks`) and the step-size controller
(:mod:`gfb_env.integrator.controller`).  Its arguments come in the named groups of
:mod:`gfb_env.integrator.arguments`, unpacked once per call (the stages take their arrays one by one,
which keeps the loop as fast as the single function it was); it ends with an
:class:`~gfb_env.integrator.IntegrationStatus` code.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gfb_env import _kernels as K
from gfb_env.forcing import shock_acceleration as _shock_acceleration
from gfb_env.forcing import unbalance_acceleration as _unbalance_acceleration
from gfb_env.integrator.controller import step_after_acceptance, step_after_rejection
from gfb_env.integrator.results import (
    _DONE,
    _EPSMAX,
    _ETAMAX,
    _ETAMIN,
    _EVETA,
    _EVT,
    _EVXI,
    _FAILED,
    _MAX_STEPS,
    _MINH,
    _NBAD_H,
    _NDIVERGED,
    _NFACT,
    _NJAC,
    _NREC,
    _NREJ_ERR,
    _NREJ_NEWTON,
    _NRHS,
    _NSTEPS,
    _TOUCHDOWN,
    _XIMAX,
    _XIMIN,
)

#: Steps inside a shock pulse at least (the impulse's quadrature error pi^2 / (12 n^2) = 0.08 %).
_STEPS_PER_PULSE = 32.0


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
    # Frictional foil: after the prediction and after every update the slider rows are solved exactly
    # for the iterate's pressures (K.slider_return_map), and their change joins the update's norm.  The
    # Jacobian's slider rows are those of the step start's branch (a stuck slider: a zero row), so at a
    # slip onset or a re-stick the plain iteration diverged unless h was cut to ~ the slip relaxation
    # time eta (K_W + K_T) / (K_W K_T); with the rows solved on the branch the step end is on, the steps
    # cross the kinks (same trapezoidal equations, same tolerances: only the iteration's path changes).
    # Other structures skip both branches: their iteration is the one before, bit for bit.
    frictional = ip[2] == K.FRICTIONAL
    slider0 = ip[0] * ip[1]  # the slider entries slider0:slider1 (StateLayout.foil_slice)
    slider1 = slider0 + ip[0]
    if frictional:
        K.slider_return_map(x, s, f, hstep, 0.5, ip, fp)
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
        if frictional:
            for i in range(slider0, slider1):
                r[i] = x[i] - dx[i]  # the slider's iterate before this update (r is spent)
            K.slider_return_map(x, s, f, hstep, 0.5, ip, fp)
            for i in range(slider0, slider1):
                dx[i] = x[i] - r[i]
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
    :meth:`~gfb_env.model.GFBModel.kernel_args`; jac: :class:`~.arguments.Jacobian`; lu:
    :class:`~.arguments.Factorization`; opt: :class:`~.arguments.LoopOptions`; rec:
    :class:`~.arguments.Recording`; stats, ext: counters and extremes (in place); forcing:
    :class:`~.arguments.Forcing`, or None for an unforced call.  Returns (status code, clock at the end).

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
                h = opt.newton_failure_factor * hstep
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
                h = opt.newton_failure_factor * hstep
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
            h = step_after_rejection(hstep, err, opt)
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
        h = step_after_acceptance(h, hstep, err, truncated, opt)
    stats[_NREC] = rec_n
    return status, (t, h, hp, hp2, history)
