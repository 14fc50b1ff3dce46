"""Periodic orbits (limit cycles, paper Eq. 16), their Floquet multipliers and the fold of cycles.

A limit cycle ``s_p(tau) = s_p(tau + T)`` of ``s' = k(s, Lambda)`` is computed by **single shooting**:
Newton's method on the unknowns ``(s0, T)`` for

    r(s0, T) = phi_T(s0) - s0 = 0,        g(s0) = xi'(0) = 0      (phase condition),

where ``phi_T`` is the time-``T`` map and the phase condition pins the start of the orbit at an extremum
of the horizontal journal position ``xi`` (transversal to the flow there because ``xi'' != 0``).

Choice of the time-``T`` map (justification).  ``phi_T`` is the *fixed-step* trapezoidal rule (the
paper's own scheme, no numerical damping) with ``N`` equal steps ``h = T/N``.  The discrete map is then a
smooth function of ``(s0, T, Lambda)`` and its exact derivatives come from the discrete variational
recursion (the linearisation of one trapezoidal step)::

    (I - h/2 J_{n+1}) X_{n+1} = (I + h/2 J_n) X_n                              (monodromy M = dphi/ds0)
    (I - h/2 J_{n+1}) z_{n+1} = (I + h/2 J_n) z_n + (k_n + k_{n+1}) / (2N)      (dphi/dT)
    (I - h/2 J_{n+1}) y_{n+1} = (I + h/2 J_n) y_n + h/2 (k_L,n + k_L,n+1)       (dphi/dLambda)

with the analytic sparse Jacobian ``J_n = J(s_n)``.  One sweep over the orbit stores the sparse LU
factors of ``I - h/2 J_{n+1}`` (which also serve as the Newton matrix of the next step), after which a
monodromy-vector product costs only ``N`` sparse triangular solves (~0.05 s on the paper grid).  An
adaptive integrator with finite differences would instead put the step-size control's noise into the
derivatives, and forming the full ``n x n`` monodromy (``n = 472``) would cost ~100x more than the
matrix-free products.  The Newton system is bordered and solved matrix-free by GMRES: the bulk of the
multipliers (the strongly damped pressure modes) is clustered near 0, so ``M - I`` has its spectrum
clustered at -1 plus a few outliers and GMRES converges in a few dozen products.  ``k`` is affine in
``Lambda`` so ``k_L = dk/dLambda`` is exact from a central difference.

Floquet multipliers are the eigenvalues of ``M`` of largest modulus, computed by ARPACK
(:func:`scipy.sparse.linalg.eigs`) on the matrix-free product.  One multiplier is 1 (the phase shift
along the orbit, up to the ``O(h^2)`` discretisation error); the orbit is stable when all the others lie
inside the unit circle.

Continuation in ``Lambda`` uses pseudo-arclength (Keller 1977; Allgower & Georg, Ch. 2): the unknowns
``u = (s0, T/10, Lambda)`` with the extra equation ``t . (u - u_pred) = 0`` along a secant tangent ``t``,
so the branch of cycles can be followed round the **fold of cycles** (saddle-node of limit cycles),
where ``Lambda`` along the branch has a minimum ``Lambda_fold`` and a nontrivial multiplier passes +1.
``Lambda_fold`` is the vertex of a parabola ``Lambda(sigma)`` through the three branch points around the
minimum (``sigma`` the arclength).  Between ``Lambda_fold`` and ``Lambda_c`` (subcritical Hopf) both the
equilibrium and the large whirl are stable: the hysteresis band the paper inferred from Fig. 5.

A brute-force cross-check, :func:`coast_down_fold`, integrates the developed whirl with the adaptive
integrator while lowering ``Lambda`` in small steps until it collapses.

References: Leister, Baum & Seemann (2017), Sect. 3.3-3.4; Seydel, *Practical Bifurcation and
Stability Analysis*, 3rd ed., Ch. 7 (shooting, monodromy, Floquet multipliers); Kuznetsov, *Elements of
Applied Bifurcation Theory*, Sect. 10.3 (continuation of cycles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.params import check_positive

__all__ = [
    "ShootingError",
    "PeriodicOrbit",
    "CycleBranch",
    "SettledWhirl",
    "CoastDownResult",
    "FoldResult",
    "settle_whirl",
    "find_periodic_orbit",
    "periodic_orbit_from_simulation",
    "continue_periodic_orbits",
    "fold_bearing_number",
    "coast_down_fold",
]

_T_SCALE = 10.0  # u_T = T / 10 in the arclength metric


class ShootingError(RuntimeError):
    """The shooting Newton iteration (or the orbit sweep inside it) failed."""


# ------------------------------------------------------------------------------------------------
class _OrbitSweep:
    """Fixed-step trapezoidal sweep ``s0 -> phi_T(s0)``, storing the factors for the variational products."""

    def __init__(
        self,
        model: GFBModel,
        s0: np.ndarray,
        period: float,
        lam: float,
        dw: float,
        n_steps: int,
        need_dlam: bool = False,
    ):
        self.model = model
        n = model.layout.size
        self.N = N = int(n_steps)
        self.h = h = period / N
        I = sp.identity(n, format="csc")
        self.Js: list[sp.csr_matrix] = []
        self.lus: list = []
        s = np.array(s0, dtype=float)
        k = model.rhs(s, lam, dw)
        J = model.jacobian(s, lam, dw)
        lu = spla.splu((I - 0.5 * h * J).tocsc())
        self.rotor = np.empty((N + 1, 4))
        self.min_film = np.empty(N + 1)
        L = model.layout
        self.rotor[0] = L.rotor(s)
        self.min_film[0] = model.min_film_thickness(s)
        zT = np.zeros(n)
        zL = np.zeros(n) if need_dlam else None
        d = 1e-3
        kL = (model.rhs(s, lam + d, dw) - model.rhs(s, lam - d, dw)) / (2 * d) if need_dlam else None
        s_prev = None
        for i in range(N):
            x = 2 * s - s_prev if s_prev is not None else s + h * k
            ok = False
            for _attempt in range(2):
                for _ in range(25):
                    if model.min_film_thickness(x) <= 0:
                        break
                    kx = model.rhs(x, lam, dw)
                    if not np.all(np.isfinite(kx)):
                        break
                    r = x - s - 0.5 * h * (k + kx)
                    dx = lu.solve(-r)
                    x = x + dx
                    if np.max(np.abs(dx)) <= 1e-12 * (1.0 + np.max(np.abs(x))):
                        ok = True
                        break
                if ok:
                    break
                # refresh the Newton matrix at the (possibly poor) iterate and start again
                x = s + h * k
                lu = spla.splu((I - 0.5 * h * model.jacobian(s, lam, dw)).tocsc())
            if not ok or model.min_film_thickness(x) <= 0:
                raise ShootingError(f"trapezoidal step {i} of {N} did not converge (h={h:.3g})")
            kx = model.rhs(x, lam, dw)
            Jx = model.jacobian(x, lam, dw)
            lu = spla.splu((I - 0.5 * h * Jx).tocsc())
            # variational recursion for dphi/dT (and dphi/dLambda)
            zT = lu.solve(zT + 0.5 * h * (J @ zT) + (k + kx) / (2 * N))
            if need_dlam:
                kLx = (model.rhs(x, lam + d, dw) - model.rhs(x, lam - d, dw)) / (2 * d)
                zL = lu.solve(zL + 0.5 * h * (J @ zL) + 0.5 * h * (kL + kLx))
                kL = kLx
            self.Js.append(J)
            self.lus.append(lu)
            s_prev, s, k, J = s, x, kx, Jx
            self.rotor[i + 1] = L.rotor(s)
            self.min_film[i + 1] = model.min_film_thickness(s)
        self.end = s
        self.k_end = k
        self.dphi_dT = zT
        self.dphi_dlam = zL

    def monodromy_product(self, X: np.ndarray) -> np.ndarray:
        """``M X`` for a vector or an ``(n, m)`` block."""
        Y = np.array(X, dtype=float)
        hh = 0.5 * self.h
        for J, lu in zip(self.Js, self.lus):
            Y = lu.solve(Y + hh * (J @ Y))
        return Y

    def operator(self) -> spla.LinearOperator:
        n = self.model.layout.size
        return spla.LinearOperator((n, n), matvec=self.monodromy_product, dtype=float)


def _floquet(sweep: _OrbitSweep, k: int = 3) -> np.ndarray:
    """Leading Floquet multipliers (largest modulus first).

    Three are enough for stability (the trivial one at 1, the critical one, the next) and cheap: the
    rest are tiny and clustered (stiff pressure modes, |mu| ~ 2e-3), so asking ARPACK for six made it
    separate members of that cluster: 650 to 14 000 monodromy products per call against 21 to 36 for
    three (K_W = 1, D_W = 4, 79x7: a whole hysteresis-map point took 410 s instead of 29 s, same fold).
    """
    op = sweep.operator()
    try:
        mu = spla.eigs(op, k=k, which="LM", tol=1e-8, maxiter=2000, return_eigenvectors=False)
    except spla.ArpackNoConvergence as exc:  # pragma: no cover - rare
        mu = exc.eigenvalues
    return mu[np.argsort(-np.abs(mu))]


@dataclass
class PeriodicOrbit:
    """A converged periodic orbit (limit cycle) of Eq. (16).

    Attributes:
        bearing_number: ``Lambda``.
        foil_damping: ``D_W``.
        period: ``T`` (whirl angular frequency ``2 pi / T``).
        state: ``s_p(0)`` (on the section ``xi' = 0``).
        n_steps: trapezoidal steps per period.
        residual: ``||phi_T(s0) - s0||_inf`` at convergence.
        newton_iterations: iterations used.
        floquet_multipliers: leading multipliers by decreasing modulus (empty if not computed).
        rotor: ``[xi, eta, xi', eta']`` at the ``n_steps + 1`` mesh points of the orbit.
        min_film: ``min H`` at the mesh points.
    """

    bearing_number: float
    foil_damping: float
    period: float
    state: np.ndarray = field(repr=False)
    n_steps: int
    residual: float
    newton_iterations: int
    floquet_multipliers: np.ndarray = field(repr=False)
    rotor: np.ndarray = field(repr=False)
    min_film: np.ndarray = field(repr=False)

    @property
    def whirl_frequency(self) -> float:
        return 2 * math.pi / self.period

    @property
    def whirl_frequency_ratio(self) -> float:
        """``(2 pi / T) / Lambda`` (the paper: about 1/2)."""
        return self.whirl_frequency / self.bearing_number

    @property
    def max_eccentricity(self) -> float:
        return float(np.hypot(self.rotor[:, 0], self.rotor[:, 1]).max())

    @property
    def amplitude(self) -> float:
        """Half the peak-to-peak horizontal journal motion ``(max xi - min xi) / 2``."""
        return float(0.5 * (self.rotor[:, 0].max() - self.rotor[:, 0].min()))

    @property
    def min_film_thickness(self) -> float:
        return float(self.min_film.min())

    @property
    def trivial_multiplier(self) -> complex:
        """The multiplier closest to 1 (the phase direction)."""
        mu = self.floquet_multipliers
        if len(mu) == 0:
            return complex("nan")
        return complex(mu[np.argmin(np.abs(mu - 1.0))])

    @property
    def nontrivial_multipliers(self) -> np.ndarray:
        mu = self.floquet_multipliers
        if len(mu) == 0:
            return mu
        return np.delete(mu, np.argmin(np.abs(mu - 1.0)))

    @property
    def stable(self) -> bool | None:
        """All nontrivial multipliers inside the unit circle (None if not computed)."""
        if len(self.floquet_multipliers) == 0:
            return None
        return bool(np.all(np.abs(self.nontrivial_multipliers) < 1.0))

    def as_dict(self) -> dict:
        mu = self.floquet_multipliers
        return {
            "bearing_number": self.bearing_number,
            "foil_damping": self.foil_damping,
            "period": self.period,
            "whirl_frequency_ratio": self.whirl_frequency_ratio,
            "max_eccentricity": self.max_eccentricity,
            "amplitude": self.amplitude,
            "min_film_thickness": self.min_film_thickness,
            "residual": self.residual,
            "stable": self.stable,
            "floquet_multipliers_abs": [float(abs(m)) for m in mu],
        }


def _newton_shoot(model, s0, T, lam, dw, n_steps, tol, max_iterations, tangent=None, u_pred=None):
    """Newton on (s0, T) (tangent None) or (s0, T, Lambda) with the arclength equation."""
    L = model.layout
    n = L.size
    ix = L.xi_dot_index
    s0 = np.array(s0, dtype=float)
    free = tangent is not None
    for it in range(1, max_iterations + 1):
        sw = _OrbitSweep(model, s0, T, lam, dw, n_steps, need_dlam=free)
        r = sw.end - s0
        g = s0[ix]
        res = max(np.max(np.abs(r)), abs(g))
        arc = 0.0
        if free:
            u = np.concatenate([s0, [T / _T_SCALE, lam]])
            arc = float(tangent @ (u - u_pred))
            res = max(res, abs(arc))
        if res < tol and it > 1:
            return sw, s0, T, lam, it, res
        m = n + (2 if free else 1)

        def matvec(v, sw=sw, m=m):
            out = np.empty(m)
            ds = v[:n]
            out[:n] = sw.monodromy_product(ds) - ds + _T_SCALE * v[n] * sw.dphi_dT
            if free:
                out[:n] += v[n + 1] * sw.dphi_dlam
            out[n] = ds[ix]
            if free:
                out[n + 1] = tangent @ v
            return out

        A = spla.LinearOperator((m, m), matvec=matvec, dtype=float)
        b = np.concatenate([-r, [-g]] + ([[-arc]] if free else []))
        dv, info = spla.gmres(A, b, rtol=1e-10, atol=0.0, restart=80, maxiter=4)
        if not np.all(np.isfinite(dv)):
            raise ShootingError("GMRES failed in the shooting Newton step")
        # damp steps that would move the rotor by more than 0.2 clearances
        step = np.max(np.abs(dv[L.rotor_slice])) if n > 4 else 0.0
        alpha = min(1.0, 0.2 / step) if step > 0 else 1.0
        s0 = s0 + alpha * dv[:n]
        T = T + alpha * _T_SCALE * dv[n]
        if free:
            lam = lam + alpha * dv[n + 1]
        if not (T > 0 and lam > 0) or model.min_film_thickness(s0) <= 0:
            raise ShootingError("Newton left the admissible region (T, Lambda or film thickness <= 0)")
    raise ShootingError(
        f"shooting Newton did not converge in {max_iterations} iterations (residual {res:.2e})"
    )


def find_periodic_orbit(
    model: GFBModel,
    bearing_number: float,
    foil_damping: float,
    state: np.ndarray,
    period: float,
    n_steps: int = 600,
    tol: float = 1e-8,
    max_iterations: int = 15,
    floquet: bool = True,
    n_multipliers: int = 3,
) -> PeriodicOrbit:
    """Periodic orbit near ``(state, period)`` by shooting (see the module docstring).

    Args:
        model: the coupled model.
        bearing_number: ``Lambda`` (fixed).
        foil_damping: ``D_W``.
        state: initial guess of ``s_p(0)`` near the section ``xi' = 0`` (e.g. from
            :func:`periodic_orbit_from_simulation`).
        period: initial guess of ``T``.
        n_steps: trapezoidal steps per period (``h = T / n_steps``).
        tol: on ``max(||phi_T(s0) - s0||_inf, |xi'(0)|)``.
        max_iterations: Newton iterations.
        floquet: also compute the leading ``n_multipliers`` Floquet multipliers.

    Raises:
        ValueError: invalid arguments.
        ShootingError: Newton did not converge.
    """
    lam = check_positive("bearing_number", bearing_number)
    dw = check_positive("foil_damping", foil_damping)
    T = check_positive("period", period)
    if int(n_steps) < 20:
        raise ValueError(f"n_steps must be >= 20, got {n_steps!r}")
    state = model.layout.check(state)
    sw, s0, T, lam, its, res = _newton_shoot(model, state, T, lam, dw, int(n_steps), tol, max_iterations)
    mu = _floquet(sw, n_multipliers) if floquet else np.zeros(0, dtype=complex)
    return PeriodicOrbit(lam, dw, T, s0, int(n_steps), res, its, mu, sw.rotor.copy(), sw.min_film.copy())


# ------------------------------------------------------------------------------------------------
@dataclass
class SettledWhirl:
    """Result of :func:`settle_whirl`: the state after the transient and the last orbit.

    Attributes:
        status: ``"whirl"`` (settled limit cycle), ``"equilibrium"`` (decayed), ``"touchdown"``,
            ``"failed"`` (the integrator's step size collapsed, e.g. the film closing),
            ``"unsettled"`` (still changing at ``tau_max``).
        state: final state; ``tau``: final time.
        amplitude: half the peak-to-peak ``xi`` of the last window.
        max_eccentricity, min_film_thickness: over the last window.
        period: whirl period from the ``xi'`` zero crossings (NaN if not whirling).
        trajectory: the last window (a :class:`gfb_env.Trajectory`), all windows in ``history``.
    """

    status: str
    state: np.ndarray = field(repr=False)
    tau: float
    amplitude: float
    max_eccentricity: float
    min_film_thickness: float
    period: float
    trajectory: object = field(repr=False)
    history: list = field(repr=False, default_factory=list)


def _xi_maxima_times(tau: np.ndarray, xi_dot: np.ndarray) -> np.ndarray:
    """Times where xi' crosses zero from + to - (maxima of xi), linearly interpolated."""
    i = np.nonzero((xi_dot[:-1] > 0) & (xi_dot[1:] <= 0))[0]
    frac = xi_dot[i] / (xi_dot[i] - xi_dot[i + 1])
    return tau[i] + frac * (tau[i + 1] - tau[i])


def settle_whirl(
    model: GFBModel,
    bearing_number: float,
    foil_damping: float = 1.0,
    state: np.ndarray | None = None,
    kick: float = 0.05,
    window: float = 200.0,
    tau_max: float = 6000.0,
    settle_rtol: float = 2e-3,
    record_interval: float = 0.25,
    record_indices: np.ndarray | None = None,
    integrator_options: dict | None = None,
) -> SettledWhirl:
    """Integrate until the motion settles on a limit cycle or on the equilibrium.

    Starts from ``state`` or from the equilibrium with the journal displaced by ``kick`` horizontally;
    integrates in windows of ``window`` tau with :class:`~gfb_env.integrator.TrapezoidalIntegrator`
    and stops when the peak-to-peak ``xi`` of two consecutive windows agrees to ``settle_rtol``
    (whirl), falls below ``1e-4`` (equilibrium), on touchdown, or at ``tau_max``.
    """
    lam = check_positive("bearing_number", bearing_number)
    dw = check_positive("foil_damping", foil_damping)
    check_positive("window", window)
    L = model.layout
    if state is None:
        s = find_equilibrium(model, lam)
        s = L.with_rotor(s, s[L.xi_index] + kick, s[L.eta_index])
    else:
        s = L.check(state)
    integ = TrapezoidalIntegrator(model, s, lam, dw, **(integrator_options or {}))
    prev = None
    history = []
    status = "unsettled"
    res = None
    while integ.tau < tau_max - 1e-9:
        res = integ.advance(
            min(integ.tau + window, tau_max),
            record_interval=record_interval,
            record_indices=record_indices,
            raise_on_failure=False,
        )
        if res.status in ("failed", "max_steps"):
            status = "failed"
            break
        tr = res.trajectory
        ptp = float(np.ptp(tr.xi)) if len(tr) else 0.0
        history.append((integ.tau, ptp, float(tr.eccentricity.max()) if len(tr) else math.nan))
        if res.status == "touchdown":
            status = "touchdown"
            break
        if ptp < 1e-4:
            status = "equilibrium"
            break
        if prev is not None and abs(ptp - prev) <= settle_rtol * ptp:
            status = "whirl"
            break
        prev = ptp
    tr = res.trajectory
    period = math.nan
    if status in ("whirl", "unsettled") and len(tr) > 4:
        tm = _xi_maxima_times(tr.tau, tr.xi_dot)
        if len(tm) >= 2:
            period = float(np.mean(np.diff(tm)))
    return SettledWhirl(
        status=status,
        state=integ.state,
        tau=integ.tau,
        amplitude=0.5 * float(np.ptp(tr.xi)) if len(tr) else 0.0,
        max_eccentricity=float(tr.eccentricity.max()) if len(tr) else math.nan,
        min_film_thickness=float(tr.min_film_thickness.min()) if len(tr) else math.nan,
        period=period,
        trajectory=tr,
        history=history,
    )


def periodic_orbit_from_simulation(
    model: GFBModel,
    bearing_number: float,
    foil_damping: float,
    state: np.ndarray,
    period_guess: float | None = None,
    **shooting_options,
) -> PeriodicOrbit:
    """Seed the shooting from a (settled) whirl state: integrate about two periods, locate a maximum of
    ``xi`` (``xi' = 0``), take the state there and the spacing of the maxima as the period guess, and
    call :func:`find_periodic_orbit`."""
    lam = check_positive("bearing_number", bearing_number)
    dw = check_positive("foil_damping", foil_damping)
    T0 = period_guess if period_guess else 4 * math.pi / lam
    integ = TrapezoidalIntegrator(model, model.layout.check(state), lam, dw, rtol=1e-5, atol=1e-5)
    snap = integ.snapshot()
    res = integ.advance(3.2 * T0, record_interval=T0 / 400)
    tr = res.trajectory
    tm = _xi_maxima_times(tr.tau, tr.xi_dot)
    if len(tm) < 2:
        raise ShootingError("no whirl in the seed simulation (fewer than two maxima of xi)")
    T = float(np.mean(np.diff(tm)))
    integ.restore(snap)
    integ.advance(float(tm[0]))
    return find_periodic_orbit(model, lam, dw, integ.state, T, **shooting_options)


# ------------------------------------------------------------------------------------------------
@dataclass
class CycleBranch:
    """Periodic orbits continued in ``Lambda`` (see :func:`continue_periodic_orbits`).

    Attributes:
        orbits: converged orbits in branch order.
        fold_bearing_number: ``Lambda_fold`` (minimum of Lambda along the branch), or None if no fold
            was passed.
        fold_amplitude: amplitude (half peak-to-peak xi) at the fold, by the same parabola.
        message: why the continuation stopped.
    """

    orbits: list[PeriodicOrbit]
    fold_bearing_number: float | None
    fold_amplitude: float | None
    message: str

    @property
    def bearing_number(self) -> np.ndarray:
        return np.array([o.bearing_number for o in self.orbits])

    @property
    def amplitude(self) -> np.ndarray:
        return np.array([o.amplitude for o in self.orbits])


def _u(o: PeriodicOrbit) -> np.ndarray:
    return np.concatenate([o.state, [o.period / _T_SCALE, o.bearing_number]])


def continue_periodic_orbits(
    model: GFBModel,
    orbit: PeriodicOrbit,
    first_step: float = -0.01,
    max_points: int = 30,
    min_bearing_number: float = 0.05,
    max_arclength_step: float = 0.5,
    tol: float = 1e-8,
    floquet: bool = True,
    points_after_fold: int = 1,
    progress: bool = False,
) -> CycleBranch:
    """Pseudo-arclength continuation of a branch of cycles from ``orbit``, first in the direction
    ``sign(first_step)`` of ``Lambda`` (a natural-parameter step of ``first_step`` gives the second
    point and the first secant), until the fold of cycles is passed (``Lambda`` along the branch turns
    back) plus ``points_after_fold`` points, ``Lambda < min_bearing_number`` or ``max_points``.
    """
    if first_step == 0 or not math.isfinite(first_step):
        raise ValueError(f"first_step must be a non-zero finite number, got {first_step!r}")
    dw = orbit.foil_damping
    n_steps = orbit.n_steps
    orbits = [orbit]
    lam1 = orbit.bearing_number + first_step
    o2 = find_periodic_orbit(
        model, lam1, dw, orbit.state, orbit.period, n_steps=n_steps, tol=tol, floquet=floquet
    )
    orbits.append(o2)
    ds = float(np.linalg.norm(_u(o2) - _u(orbit)))
    message = "max_points reached"
    turned = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=max_points, desc=f"cycles D_W={dw:g}", leave=False)
    while len(orbits) < max_points:
        if bar is not None:
            bar.update(1)
        u1, u0 = _u(orbits[-1]), _u(orbits[-2])
        t = u1 - u0
        t /= np.linalg.norm(t)
        while True:
            u_pred = u1 + ds * t
            try:
                sw, s0, T, lam, its, res = _newton_shoot(
                    model,
                    u_pred[:-2],
                    u_pred[-2] * _T_SCALE,
                    u_pred[-1],
                    dw,
                    n_steps,
                    tol,
                    8,
                    tangent=t,
                    u_pred=u_pred,
                )
                break
            except ShootingError:
                ds *= 0.5
                if ds < 1e-4:
                    message = "step size underflow"
                    break
        if ds < 1e-4:
            break
        mu = _floquet(sw) if floquet else np.zeros(0, dtype=complex)
        orb = PeriodicOrbit(lam, dw, T, s0, n_steps, res, its, mu, sw.rotor.copy(), sw.min_film.copy())
        orbits.append(orb)
        lams = [o.bearing_number for o in orbits]
        dl = np.diff(lams)
        if turned == 0 and len(dl) >= 2 and np.sign(dl[-1]) != np.sign(dl[0]):
            turned = 1
        elif turned:
            turned += 1
        if turned > points_after_fold:
            message = "fold passed"
            break
        if lam < min_bearing_number:
            message = "reached min_bearing_number"
            break
        if its <= 3:
            ds = min(ds * 1.5, max_arclength_step)
        elif its >= 6:
            ds *= 0.6
    if bar is not None:
        bar.close()
    fold, famp = _fold_from_branch(orbits, sign=np.sign(first_step))
    return CycleBranch(orbits, fold, famp, message)


def _fold_from_branch(orbits: list[PeriodicOrbit], sign: float) -> tuple[float | None, float | None]:
    lams = np.array([o.bearing_number for o in orbits])
    if len(lams) < 3:
        return None, None
    # extreme of Lambda in the direction of travel (a minimum when continuing downwards)
    key = lams * sign  # maximise key: -Lambda when continuing downwards
    j = int(np.argmax(key))
    if j == 0 or j == len(lams) - 1:
        return None, None
    U = np.array([_u(o) for o in orbits[j - 1 : j + 2]])
    sig = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(U, axis=0), axis=1))])
    amps = np.array([o.amplitude for o in orbits[j - 1 : j + 2]])
    c = np.polyfit(sig, lams[j - 1 : j + 2], 2)
    if c[0] == 0:
        return float(lams[j]), float(amps[1])
    sv = -c[1] / (2 * c[0])
    sv = float(np.clip(sv, sig[0], sig[-1]))
    ca = np.polyfit(sig, amps, 2)
    return float(np.polyval(c, sv)), float(np.polyval(ca, sv))


# ------------------------------------------------------------------------------------------------
@dataclass
class FoldResult:
    """Fold of cycles of one configuration (:func:`fold_bearing_number`)."""

    critical_bearing_number: float
    fold_bearing_number: float | None
    amplitude_at_critical: float
    max_eccentricity_at_critical: float
    period_at_critical: float
    branch: CycleBranch | None = field(repr=False)
    message: str = ""

    @property
    def subcritical(self) -> bool | None:
        if self.fold_bearing_number is None:
            return None
        return self.fold_bearing_number < self.critical_bearing_number


def fold_bearing_number(
    model: GFBModel,
    foil_damping: float = 1.0,
    critical: float | None = None,
    offset: float = 0.01,
    n_steps: int = 600,
    max_points: int = 30,
    progress: bool = False,
) -> FoldResult:
    """``Lambda_fold``: start on the whirl that develops at ``Lambda_c + offset`` (integrated from a kicked
    equilibrium by :func:`settle_whirl`), shoot it, and continue the cycle branch downwards in ``Lambda``
    round the fold (:func:`continue_periodic_orbits`).  The limit-cycle amplitude at ``Lambda_c`` is taken
    from the branch (linear interpolation).

    Raises:
        ShootingError: when no whirl settles or the first shooting fails.
    """
    from gfb_env.analysis.stability import critical_bearing_number

    dw = check_positive("foil_damping", foil_damping)
    if critical is None:
        critical = critical_bearing_number(model, dw).critical_bearing_number
    lam0 = critical + offset
    sw = settle_whirl(
        model, lam0, dw, kick=0.3, tau_max=8000, integrator_options={"touchdown_film_thickness": 1e-4}
    )
    if sw.status != "whirl":
        raise ShootingError(f"no settled whirl at Lambda={lam0:.4g} (status {sw.status})")
    o = periodic_orbit_from_simulation(model, lam0, dw, sw.state, sw.period, n_steps=n_steps)
    br = continue_periodic_orbits(
        model, o, first_step=-min(offset, 0.01), max_points=max_points, progress=progress
    )
    lams, amps = br.bearing_number, br.amplitude
    eps = np.array([x.max_eccentricity for x in br.orbits])
    per = np.array([x.period for x in br.orbits])
    # the stable (upper) part: before the fold
    j = int(np.argmin(lams)) + 1 if br.fold_bearing_number is not None else len(lams)
    ls, order = lams[:j], np.argsort(lams[:j])

    def interp(v):
        return float(np.interp(critical, ls[order], v[:j][order]))

    return FoldResult(
        critical, br.fold_bearing_number, interp(amps), interp(eps), interp(per), br, br.message
    )


# ------------------------------------------------------------------------------------------------
@dataclass
class CoastDownResult:
    """Brute-force fold estimate (:func:`coast_down_fold`).

    Attributes:
        fold_bearing_number: midpoint between the last ``Lambda`` with a sustained whirl and the first
            where it collapsed (None if it never collapsed).
        last_whirl_bearing_number, collapse_bearing_number: the bracket.
        bearing_number, amplitude: the staircase (amplitude at the end of each dwell).
    """

    fold_bearing_number: float | None
    last_whirl_bearing_number: float | None
    collapse_bearing_number: float | None
    bearing_number: np.ndarray
    amplitude: np.ndarray


def coast_down_fold(
    model: GFBModel,
    foil_damping: float,
    start_bearing_number: float,
    state: np.ndarray | None = None,
    step: float = 0.005,
    ramp: float = 50.0,
    dwell: float = 400.0,
    min_bearing_number: float = 0.1,
    collapse_fraction: float = 0.3,
    progress: bool = False,
) -> CoastDownResult:
    """Lower ``Lambda`` from a developed whirl in steps of ``step`` (each ramped over ``ramp`` tau and held
    for ``dwell`` tau) until the whirl amplitude falls below ``collapse_fraction`` of its starting value.

    This is the paper's coast-down done quasi-statically; critical slowing-down near the fold lets the
    whirl survive a little below ``Lambda_fold``, so the estimate is biased low by about a step.
    """
    dw = check_positive("foil_damping", foil_damping)
    lam = check_positive("start_bearing_number", start_bearing_number)
    check_positive("step", step)
    if state is None:
        st = settle_whirl(model, lam, dw, tau_max=8000)
        if st.status != "whirl":
            raise ShootingError(f"no settled whirl at Lambda={lam:.4g} to coast down from ({st.status})")
        state = st.state
    integ = TrapezoidalIntegrator(model, model.layout.check(state), lam, dw)
    lams, amps = [], []
    a0 = None
    last_whirl = collapse = None
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int((lam - min_bearing_number) / step) + 1, desc="coast-down", leave=False)
    while lam >= min_bearing_number:
        integ.advance(integ.tau + ramp, bearing_number=lam)
        res = integ.advance(integ.tau + dwell, record_interval=0.5)
        tail = res.trajectory.xi[-int(min(len(res.trajectory), 2 * 4 * math.pi / lam / 0.5)) :]
        a = 0.5 * float(np.ptp(tail))
        if a0 is None:
            a0 = a
        lams.append(lam)
        amps.append(a)
        if bar is not None:
            bar.update(1)
        if a < collapse_fraction * a0 or res.status == "touchdown":
            collapse = lam
            break
        last_whirl = lam
        lam = lam - step
    if bar is not None:
        bar.close()
    fold = None if collapse is None or last_whirl is None else 0.5 * (collapse + last_whirl)
    return CoastDownResult(fold, last_whirl, collapse, np.array(lams), np.array(amps))
