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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg as spla
from numba import njit

from gfb_env import _kernels as K
from gfb_env.model import GFBModel

__all__ = [
    "TrapezoidalIntegrator",
    "Trajectory",
    "AdvanceResult",
    "TouchdownEvent",
    "IntegrationError",
    "EquilibriumError",
    "find_equilibrium",
]

# status codes of the compiled loop
_DONE, _TOUCHDOWN, _FAILED, _MAX_STEPS = 0, 1, 2, 3
_STATUS = {_DONE: "done", _TOUCHDOWN: "touchdown", _FAILED: "failed", _MAX_STEPS: "max_steps"}

# scalar integrator state (float vector): time, next step, previous step, have previous step
# _HISTORY: how many earlier accepted states the predictor may use (0, 1 or 2)
_T, _H, _HPREV, _HISTORY, _HPREV2 = 0, 1, 2, 3, 4
# statistics (int vector)
_NSTEPS, _NREJ_ERR, _NREJ_NEWTON, _NJAC, _NFACT, _NRHS, _NREC, _NBAD_H, _NDIVERGED = 0, 1, 2, 3, 4, 5, 6, 7, 8
# extremes (float vector)
_MINH, _XIMIN, _XIMAX, _ETAMIN, _ETAMAX, _EPSMAX, _EVT, _EVXI, _EVETA = 0, 1, 2, 3, 4, 5, 6, 7, 8


class IntegrationError(RuntimeError):
    """The integrator could not continue (step size below the minimum, or too many steps)."""


class EquilibriumError(RuntimeError):
    """No static equilibrium was found."""


@njit(cache=True)
def _wnorm(dx, x, y, rtol, atol):
    mx = 0.0
    for i in range(dx.shape[0]):
        sc = atol + rtol * max(abs(x[i]), abs(y[i]))
        v = abs(dx[i]) / sc
        if not v <= mx:  # also catches NaN
            mx = v
    return mx


@njit(cache=True)
def _advance(
    s, f, fprev, sprev, sprev2, fs, t_end, lam0, lam1, dw0, dw1, ip, fp, sn, cs,
    Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv,
    rtol, atol, h_min, h_max, touchdown, max_steps, max_newton, newton_tol,
    rec_idx, rec_dt, rec_next, rec_buf, stats, ext, fact_ratio, slow_iters, sparse, size_tag,
):  # fmt: skip
    n = s.shape[0]
    nc = ip[0]
    nr = ip[1]
    H = np.empty(nc)
    Hd = np.empty(nc)
    x = np.empty(n)
    fx = np.empty(n)
    fnew = np.empty(n)
    r = np.empty(n)
    dx = np.empty(n)
    ftmp = np.empty(n)
    zb = np.empty((nc, Ad.shape[1]))
    nrec_cols = rec_idx.shape[0]
    t = fs[_T]
    h = fs[_H]
    t_start = t
    span = t_end - t_start
    if span <= 0.0:
        return _DONE
    jac_valid = False
    jac_fresh = False
    fact_valid = False
    h_fact = -1.0
    eps_t = 1e-12 * max(1.0, abs(t_end))
    rec_n = 0
    rec_cap = rec_buf.shape[0]
    K.film_thickness(s, ip, fp, sn, cs, H)
    hmin_old = H.min()
    status = _DONE
    while True:
        if t >= t_end - eps_t:
            status = _DONE
            break
        if stats[_NSTEPS] >= max_steps:
            status = _MAX_STEPS
            break
        hstep = h
        truncated = False
        if t + hstep > t_end - eps_t:
            hstep = t_end - t
            truncated = True
        tn = t + hstep
        th0 = (t - t_start) / span
        th1 = min((tn - t_start) / span, 1.0)
        lam_a = lam0 + (lam1 - lam0) * th0
        dw_a = dw0 + (dw1 - dw0) * th0
        lam_b = lam0 + (lam1 - lam0) * th1
        dw_b = dw0 + (dw1 - dw0) * th1
        if not jac_valid:
            K.jacobian_blocks(s, lam_a, dw_a, ip, fp, sn, cs, ftmp, H, Hd, Ad, Ap, Am, Er, Rr, Srr)
            stats[_NJAC] += 1
            jac_valid = True
            jac_fresh = True
            fact_valid = False
        if (not fact_valid) or hstep > h_fact * fact_ratio or hstep < h_fact / fact_ratio:
            stats[_NFACT] += 1
            if not K.factor_system(
                0.5 * hstep, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag
            ):  # fmt: skip
                fact_valid = False
                h = 0.25 * hstep
                stats[_NREJ_NEWTON] += 1
                if h < h_min:
                    status = _FAILED
                    break
                continue
            fact_valid = True
            h_fact = hstep
        # predictor: linear extrapolation of the states (not of k, which rings in stiff modes)
        hp = fs[_HPREV]
        if fs[_HISTORY] >= 2.0:
            # Lagrange weights of the quadratic through (-hp - hp2, sprev2), (-hp, sprev), (0, s) at hstep
            hp2 = fs[_HPREV2]
            ta = -hp - hp2
            w2 = (hstep + hp) * hstep / (hp2 * (hp + hp2))
            w1 = -(hstep - ta) * hstep / (hp2 * hp)
            w0 = (hstep - ta) * (hstep + hp) / (ta * -hp)
            for i in range(n):
                x[i] = w0 * s[i] + w1 * sprev[i] + w2 * sprev2[i]
        elif fs[_HISTORY] >= 1.0:
            c2 = hstep / hp
            for i in range(n):
                x[i] = s[i] + c2 * (s[i] - sprev[i])
        else:
            for i in range(n):
                x[i] = s[i] + hstep * f[i]
        converged = False
        dprev = 0.0
        iters = 0
        for it in range(max_newton):
            iters = it + 1
            K.rhs(x, lam_b, dw_b, ip, fp, sn, cs, fx, H, Hd)
            stats[_NRHS] += 1
            if not H.min() > 0.0:  # intermediate iterates may dip below P = 0, never below H = 0
                stats[_NBAD_H] += 1
                break
            for i in range(n):
                r[i] = -(x[i] - s[i] - 0.5 * hstep * (f[i] + fx[i]))
            K.solve_system(
                0.5 * h_fact, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, r, dx, zb, sparse, size_tag
            )  # fmt: skip
            for i in range(n):
                x[i] += dx[i]
            dn = _wnorm(dx, x, s, rtol, atol)
            if not dn < 1e30:
                break
            if dn <= newton_tol:
                converged = True
                break
            if it > 0:
                rate = dn / dprev
                if rate >= 0.9:
                    stats[_NDIVERGED] += 1
                    break
                if rate / (1.0 - rate) * dn <= newton_tol:
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
        if not converged:
            stats[_NREJ_NEWTON] += 1
            if not jac_fresh:
                jac_valid = False
            else:
                h = 0.25 * hstep
                if h < h_min:
                    status = _FAILED
                    break
            continue
        # local error estimate from the divided difference of k, filtered through (I - h/2 J)^-1
        if fs[_HISTORY] >= 1.0:
            c3 = hstep**3 / 12.0 * 2.0 / (hstep + hp)
            for i in range(n):
                r[i] = c3 * ((fnew[i] - f[i]) / hstep - (f[i] - fprev[i]) / hp)
        else:
            c3 = hstep / 6.0
            for i in range(n):
                r[i] = c3 * (fnew[i] - f[i])
        err = _wnorm(r, x, s, rtol, atol)
        if err > 1.0:  # only a rejected raw estimate is worth the filtering solve
            K.solve_system(
                0.5 * h_fact, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, r, dx, zb, sparse, size_tag
            )  # fmt: skip
            err = _wnorm(dx, x, s, rtol, atol)
        if err > 1.0:
            stats[_NREJ_ERR] += 1
            h = hstep * max(0.2, 0.9 * err ** (-1.0 / 3.0))
            if h < h_min:
                status = _FAILED
                break
            continue
        # accept
        t_old = t
        t = tn
        hmin_new = H.min()
        # dense output (cubic Hermite) at the uniform recording times in (t_old, t]
        while rec_n < rec_cap and rec_next <= t + eps_t:
            th = (rec_next - t_old) / hstep
            h00 = (1.0 + 2.0 * th) * (1.0 - th) ** 2
            h10 = th * (1.0 - th) ** 2
            h01 = th * th * (3.0 - 2.0 * th)
            h11 = th * th * (th - 1.0)
            rec_buf[rec_n, 0] = rec_next
            for q in range(nrec_cols):
                k = rec_idx[q]
                rec_buf[rec_n, 1 + q] = h00 * s[k] + h10 * hstep * f[k] + h01 * x[k] + h11 * hstep * fnew[k]
            rec_buf[rec_n, 1 + nrec_cols] = hmin_old + th * (hmin_new - hmin_old)
            rec_n += 1
            rec_next += rec_dt
        for i in range(n):
            fprev[i] = f[i]
            f[i] = fnew[i]
            sprev2[i] = sprev[i]
            sprev[i] = s[i]
            s[i] = x[i]
        fs[_HPREV2] = fs[_HPREV]
        fs[_HPREV] = hstep
        fs[_HISTORY] = min(fs[_HISTORY] + 1.0, 2.0)
        stats[_NSTEPS] += 1
        jac_fresh = False
        if iters > slow_iters:
            jac_valid = False
        r0 = n - 4
        xi = s[r0]
        eta = s[r0 + 1]
        ext[_MINH] = min(ext[_MINH], hmin_new)
        ext[_XIMIN] = min(ext[_XIMIN], xi)
        ext[_XIMAX] = max(ext[_XIMAX], xi)
        ext[_ETAMIN] = min(ext[_ETAMIN], eta)
        ext[_ETAMAX] = max(ext[_ETAMAX], eta)
        ext[_EPSMAX] = max(ext[_EPSMAX], math.sqrt(xi * xi + eta * eta))
        if hmin_new < touchdown:
            th = (hmin_old - touchdown) / (hmin_old - hmin_new) if hmin_old > hmin_new else 1.0
            th = min(max(th, 0.0), 1.0)
            ext[_EVT] = t_old + th * hstep
            ext[_EVXI] = s[r0] - (1.0 - th) * hstep * f[r0]
            ext[_EVETA] = s[r0 + 1] - (1.0 - th) * hstep * f[r0 + 1]
            status = _TOUCHDOWN
            break
        hmin_old = hmin_new
        # next step size
        fac = 2.0 if err == 0.0 else min(2.0, 0.8 * err ** (-1.0 / 3.0))
        if not truncated or fac < 1.0:
            h = min(hstep * max(fac, 0.2), h_max)
        # a step truncated to hit t_end keeps the previous step-size proposal
    fs[_T] = t
    fs[_H] = h
    stats[_NREC] = rec_n
    return status


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

    status: str
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
        return self.status in ("done", "touchdown")


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
    """

    def __init__(
        self,
        model: GFBModel,
        state: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        tau: float = 0.0,
        rtol: float = 3e-4,
        atol: float = 3e-4,
        first_step: float = 0.01,
        max_step: float = 2.0,
        min_step: float = 1e-7,
        touchdown_film_thickness: float = 0.01,
        max_newton_iterations: int = 6,
        newton_tol: float = 0.3,
        factorization_ratio: float = 2.0,
        slow_newton_iterations: int = 3,
    ):
        for name, v in (
            ("rtol", rtol),
            ("atol", atol),
            ("first_step", first_step),
            ("max_step", max_step),
            ("min_step", min_step),
            ("newton_tol", newton_tol),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and positive, got {v!r}")
        if not (math.isfinite(touchdown_film_thickness) and 0 <= touchdown_film_thickness < 1):
            raise ValueError(f"touchdown_film_thickness must lie in [0, 1), got {touchdown_film_thickness!r}")
        if int(max_newton_iterations) < 1:
            raise ValueError(f"max_newton_iterations must be >= 1, got {max_newton_iterations!r}")
        self.model = model
        self.rtol, self.atol = float(rtol), float(atol)
        self.first_step, self.max_step, self.min_step = float(first_step), float(max_step), float(min_step)
        self.touchdown_film_thickness = float(touchdown_film_thickness)
        self.max_newton_iterations = int(max_newton_iterations)
        self.newton_tol = float(newton_tol)
        if not factorization_ratio >= 1.0:
            raise ValueError(f"factorization_ratio must be >= 1, got {factorization_ratio!r}")
        self.factorization_ratio = float(factorization_ratio)
        self.slow_newton_iterations = int(slow_newton_iterations)
        b = model.new_blocks()
        self._blocks = b
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        self._Dlu = np.zeros((nc, m, m))
        self._Dpiv = np.zeros((nc, m), dtype=np.int64)
        self._Uhat = np.zeros((nc, m, m))
        self._Y = np.zeros((nc, m, nb))
        self._Slu = np.zeros((nb, nb))
        self._Spiv = np.zeros(nb, dtype=np.int64)
        self.reset(state, bearing_number, foil_damping, tau)

    # ------------------------------------------------------------------------------------------
    def reset(
        self, state: np.ndarray, bearing_number: float, foil_damping: float = 1.0, tau: float = 0.0
    ) -> None:
        """Restart from ``state`` at time ``tau`` (forgets the step history)."""
        self.model.check_operating_point(bearing_number, foil_damping)
        s = np.array(self.model.layout.check(state), dtype=float, copy=True)
        if not np.all(np.isfinite(s)):
            raise ValueError("state must be finite")
        self._s = s
        self._lam = float(bearing_number)
        self._dw = float(foil_damping)
        self._f = self.model.rhs(s, self._lam, self._dw)
        self._fprev = np.zeros_like(s)
        self._sprev = s.copy()
        self._sprev2 = s.copy()
        self._fs = np.array([float(tau), self.first_step, 0.0, 0.0, 0.0])
        self.stats = np.zeros(9, dtype=np.int64)
        self._last_record_tau = -math.inf

    @property
    def tau(self) -> float:
        return float(self._fs[_T])

    @property
    def state(self) -> np.ndarray:
        """Current state (a copy)."""
        return self._s.copy()

    @property
    def bearing_number(self) -> float:
        return self._lam

    @property
    def foil_damping(self) -> float:
        return self._dw

    @property
    def step_size(self) -> float:
        """The step size the next step will try."""
        return float(self._fs[_H])

    def get_state(self) -> dict:
        """Snapshot everything the continuation depends on (restore with :meth:`set_state`)."""
        return {
            "s": self._s.copy(),
            "f": self._f.copy(),
            "fprev": self._fprev.copy(),
            "sprev": self._sprev.copy(),
            "sprev2": self._sprev2.copy(),
            "fs": self._fs.copy(),
            "lam": self._lam,
            "dw": self._dw,
            "stats": self.stats.copy(),
            "last_record_tau": self._last_record_tau,
        }

    def set_state(self, snap: dict) -> None:
        self._s = snap["s"].copy()
        self._f = snap["f"].copy()
        self._fprev = snap["fprev"].copy()
        self._sprev = snap["sprev"].copy()
        self._sprev2 = snap["sprev2"].copy()
        self._fs = snap["fs"].copy()
        self._lam = float(snap["lam"])
        self._dw = float(snap["dw"])
        self.stats = snap["stats"].copy()
        self._last_record_tau = float(snap["last_record_tau"])

    # ------------------------------------------------------------------------------------------
    def advance(
        self,
        tau_end: float,
        bearing_number: float | None = None,
        foil_damping: float | None = None,
        record_interval: float | None = None,
        record_indices: np.ndarray | None = None,
        max_steps: int = 10_000_000,
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
        """
        lam1 = self._lam if bearing_number is None else float(bearing_number)
        dw1 = self._dw if foil_damping is None else float(foil_damping)
        self.model.check_operating_point(lam1, dw1)
        if not math.isfinite(tau_end):
            raise ValueError(f"tau_end must be finite, got {tau_end!r}")
        t0 = self.tau
        if tau_end < t0:
            raise ValueError(f"tau_end must not be before the current time {t0}, got {tau_end}")
        L = self.model.layout
        rot = np.arange(L.rotor_offset, L.size, dtype=np.int64)
        extra = (
            np.zeros(0, dtype=np.int64) if record_indices is None else np.asarray(record_indices, np.int64)
        )
        if extra.size and (extra.min() < 0 or extra.max() >= L.size):
            raise ValueError("record_indices out of range")
        rec_idx = np.concatenate([rot, extra])
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
            if k0 * rec_dt <= self._last_record_tau + 1e-9 * rec_dt:
                k0 += 1
            rec_next = k0 * rec_dt
            cap = max(int(math.floor((tau_end - rec_next) / rec_dt + 1e-9)) + 2, 0)
        rec_buf = np.empty((cap, len(rec_idx) + 2))
        stats = np.zeros(9, dtype=np.int64)
        ext = np.array([np.inf, np.inf, -np.inf, np.inf, -np.inf, 0.0, np.nan, np.nan, np.nan])
        first = 0
        if cap and rec_next <= t0 + 1e-9 * rec_dt:  # a sample exactly at the start
            rec_buf[0, 0] = t0
            rec_buf[0, 1:-1] = self._s[rec_idx]
            rec_buf[0, -1] = self.model.min_film_thickness(self._s)
            first = 1
            rec_next += rec_dt
        b = self._blocks
        code = _advance(
            self._s, self._f, self._fprev, self._sprev, self._sprev2, self._fs,
            float(tau_end), self._lam, lam1, self._dw, dw1,
            self.model._ip, self.model._fp, self.model._sin, self.model._cos,
            b["Ad"], b["Ap"], b["Am"], b["Er"], b["Rr"], b["Srr"],
            self._Dlu, self._Dpiv, self._Uhat, self._Y, self._Slu, self._Spiv,
            self.rtol, self.atol, self.min_step, self.max_step, self.touchdown_film_thickness,
            int(max_steps), self.max_newton_iterations, self.newton_tol,
            rec_idx, rec_dt, rec_next, rec_buf[first:], stats, ext, self.factorization_ratio,
            self.slow_newton_iterations, self.model.sparse_offdiagonal_blocks, K.size_tag(L.block_size),
        )  # fmt: skip
        self.stats += stats
        t = self.tau
        span = float(tau_end) - t0
        theta = (t - t0) / span if span > 0 else 1.0
        lam_t = self._lam + (lam1 - self._lam) * theta
        dw_t = self._dw + (dw1 - self._dw) * theta
        lam_start, dw_start = self._lam, self._dw
        self._lam, self._dw = lam_t, dw_t
        nrec = first + int(stats[_NREC])
        rb = rec_buf[:nrec]
        if nrec:
            self._last_record_tau = float(rb[-1, 0])
        tau_s = rb[:, 0]
        th = (tau_s - t0) / span if span > 0 else np.ones_like(tau_s)
        traj = Trajectory(
            tau=tau_s.copy(),
            xi=rb[:, 1].copy(),
            eta=rb[:, 2].copy(),
            xi_dot=rb[:, 3].copy(),
            eta_dot=rb[:, 4].copy(),
            min_film_thickness=rb[:, -1].copy(),
            probes=rb[:, 5:-1].copy(),
            bearing_number=lam_start + (lam1 - lam_start) * th,
            foil_damping=dw_start + (dw1 - dw_start) * th,
        )
        status = _STATUS[code]
        event = None
        if code == _TOUCHDOWN:
            event = TouchdownEvent(
                float(ext[_EVT]), float(ext[_EVXI]), float(ext[_EVETA]), self.touchdown_film_thickness
            )
        msg = ""
        if code == _FAILED:
            msg = (
                f"step size fell below min_step={self.min_step:g} at tau={t:.6g} "
                f"(Lambda={lam_t:.4g}, D_W={dw_t:.4g}); the state is the last accepted one"
            )
        elif code == _MAX_STEPS:
            msg = f"max_steps={max_steps} reached at tau={t:.6g}"
        if not math.isfinite(ext[_MINH]):
            ext[_MINH] = self.model.min_film_thickness(self._s)
        res = AdvanceResult(
            status=status,
            tau=t,
            trajectory=traj,
            touchdown=event,
            steps=int(stats[_NSTEPS]),
            rejected_steps=int(stats[_NREJ_ERR]),
            newton_failures=int(stats[_NREJ_NEWTON]),
            jacobians=int(stats[_NJAC]),
            factorizations=int(stats[_NFACT]),
            rhs_evaluations=int(stats[_NRHS]),
            min_film_thickness=float(ext[_MINH]),
            xi_range=(float(ext[_XIMIN]), float(ext[_XIMAX])),
            eta_range=(float(ext[_ETAMIN]), float(ext[_ETAMAX])),
            max_eccentricity=float(ext[_EPSMAX]),
            message=msg,
        )
        if raise_on_failure and code in (_FAILED, _MAX_STEPS):
            raise IntegrationError(msg)
        return res


# ------------------------------------------------------------------------------------------------
def find_equilibrium(
    model: GFBModel,
    bearing_number: float,
    guess: np.ndarray | None = None,
    tol: float = 1e-10,
    max_iterations: int = 50,
) -> np.ndarray:
    """Static equilibrium ``k(s0, Lambda) = 0`` by damped Newton with the analytic sparse Jacobian.

    Without a ``guess`` it starts from the centred journal and continues in the load (a quarter of
    M G, a half, ..., all of it), warm-starting each stage; a failed stage is retried with smaller
    load increments before :class:`EquilibriumError` is raised.  The equilibrium does not depend on
    D_W (Q' = 0).  Returns the state (rotor velocities zero).
    """
    model.check_operating_point(bearing_number, 1.0)
    if bearing_number <= 0:
        raise ValueError("bearing_number must be positive for a gas-film equilibrium")
    if guess is not None:
        s = np.array(model.layout.check(guess), dtype=float, copy=True)
        try:
            return _newton_equilibrium(model, bearing_number, s, 1.0, tol, max_iterations)
        except EquilibriumError:
            pass  # fall back to load continuation from the centre
    s = model.layout.centred_state()
    load = 0.0
    step = 0.25
    while load < 1.0:
        target = min(1.0, load + step)
        try:
            s = _newton_equilibrium(model, bearing_number, s, target, tol, max_iterations)
            load = target
            step = min(step * 2, 0.5)
        except EquilibriumError:
            step /= 4
            if step < 1e-3:
                raise EquilibriumError(
                    f"no equilibrium found at Lambda={bearing_number:g} ({model}); load continuation "
                    f"stalled at {load:.3f} M G"
                ) from None
    return s


def _newton_equilibrium(
    model: GFBModel, lam: float, s: np.ndarray, load_fraction: float, tol: float, max_iterations: int
) -> np.ndarray:
    L = model.layout
    s = s.copy()
    s[L.xi_dot_index] = 0.0
    s[L.eta_dot_index] = 0.0
    fp = model._fp.copy()  # the same parameters with the gravity scaled by the load fraction
    fp[3] = model.params.gravity_parameter * load_fraction

    def residual(x):
        out = np.empty_like(x)
        mn = K.rhs(x, lam, 1.0, model._ip, fp, model._sin, model._cos, out, model._H, model._Hd)
        return out, mn

    r, mn = residual(s)
    if not mn > 0:
        raise EquilibriumError("inadmissible starting state")
    rn = np.linalg.norm(r, np.inf)
    for _ in range(max_iterations):
        if rn < tol:
            return s
        J = model.jacobian(s, lam, 1.0)  # G enters k only as a constant: J is load-independent
        try:
            ds = spla.spsolve(J.tocsc(), -r)
        except RuntimeError as exc:  # singular
            raise EquilibriumError(str(exc)) from None
        if not np.all(np.isfinite(ds)):
            raise EquilibriumError("singular Jacobian")
        alpha = 1.0
        while alpha > 1e-4:
            x = s + alpha * ds
            rx, mn = residual(x)
            if mn > 0 and np.all(np.isfinite(rx)):
                rxn = np.linalg.norm(rx, np.inf)
                if rxn < (1 - 0.25 * alpha) * rn or rxn < tol:
                    break
            alpha *= 0.5
        else:
            raise EquilibriumError("line search failed")
        s, r, rn = x, rx, rxn
    if rn < tol * 100:
        return s
    raise EquilibriumError(f"Newton did not converge (residual {rn:.3g})")
