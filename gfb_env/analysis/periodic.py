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

with the analytic Jacobian ``J_n = J(s_n)``.  One sweep over the orbit stores ``J_n`` and the factors
of ``I - h/2 J_n`` in the model's block form (periodic block-tridiagonal columns, the rotor as a
border: the integrator's factorisation; they also serve as the Newton matrix of step ``n``) in a few
preallocated arrays, after which a monodromy-vector product costs only ``N`` block solves (~0.02 s on
the paper grid; ~60 MB per sweep there, one sweep alive at a time).  An
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

The branch starts at the Hopf point (:func:`hopf_cycles`): the critical eigenvector gives the small
cycles, shot with ``Lambda`` free at a fixed amplitude, so no transient has to settle on the large
whirl first (on the coarse grids the developed whirl at ``Lambda_c + 0.01`` closes the film, although
the fold exists below).  The branch is followed through the unstable cycles, round the fold and up
the stable whirl to ``Lambda_c``; it stops near contact (min film thickness below 0.01).

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
import scipy.sparse.linalg as spla
from numba import njit

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
    "hopf_cycles",
    "coast_down_fold",
]

_T_SCALE = 10.0  # u_T = T / 10 in the arclength metric


class ShootingError(RuntimeError):
    """The shooting Newton iteration (or the orbit sweep inside it) failed."""


# ------------------------------------------------------------------------------------------------
class _StepFactors:
    """The Jacobians ``J_n`` at the ``N + 1`` mesh points of one sweep and the factors of
    ``I - h/2 J_n``, in the model's block form, in preallocated arrays (one per kind, indexed by ``n``).

    Why: a sweep needs them all again for every monodromy product.  Stored as 2 x 300 SuperLU and
    CSR objects per sweep (the first implementation) they took ~107 MB per sweep on 79x7, and their
    hundreds of separate allocations fragmented the heap so that the freed memory of one sweep was not
    reused by the next (2.4 GB peak for one ``gfb hysteresis`` run).  The block form (periodic
    block-tridiagonal columns with the rotor as a border, :func:`gfb_env._kernels.factor_system`, the
    factorisation the integrator uses) holds ~185 KB per mesh point on 79x7, in a dozen large arrays.
    """

    def __init__(self, model: GFBModel, n_points: int, hh: float):
        from gfb_env import _kernels as K

        self._K = K
        L, g = model.layout, model.grid
        nc, m = g.n_columns, L.block_size
        nb = m + 4
        N = int(n_points)
        self.model, self.hh = model, float(hh)
        z = np.zeros
        self.Ad, self.Ap, self.Am = z((N, nc, m, m)), z((N, nc, m, m)), z((N, nc, m, m))
        self.Er, self.Rr, self.Srr = z((N, nc, m, 4)), z((N, nc, 4, m)), z((N, 4, 4))
        self.Dlu, self.Uhat, self.Y = z((N, nc, m, m)), z((N, nc, m, m)), z((N, nc, m, nb))
        self.Dpiv, self.Slu, self.Spiv = z((N, nc, m), np.int64), z((N, nb, nb)), z((N, nb), np.int64)
        self._zb = z((nc, m))
        self._static = (g.n_rows, model.sparse_offdiagonal_blocks, K.size_tag(m))
        # column unknowns x_i = [P_i0 .. P_i,nr-1, (Q_i)] in state layout, and the rotor
        nr = g.n_rows
        col = np.empty((nc, m), dtype=np.int64)
        col[:, :nr] = np.arange(nc * nr).reshape(nc, nr)
        if m > nr:
            col[:, nr] = L.n_pressure + np.arange(nc)
        self._col = col
        self._rot = slice(L.rotor_offset, L.size)

    def set(self, n: int, s: np.ndarray, lam: float, dw: float) -> None:
        """``J_n = J(s)`` and the factors of ``I - h/2 J_n``."""
        b = {k: getattr(self, k)[n] for k in ("Ad", "Ap", "Am", "Er", "Rr", "Srr")}
        self.model.jacobian_blocks(s, lam, dw, blocks=b)
        nr, sparse, tag = self._static
        ok = self._K.factor_system(
            self.hh, b["Ad"], b["Ap"], b["Am"], b["Er"], b["Rr"], b["Srr"], self.Dlu[n], self.Dpiv[n],
            self.Uhat[n], self.Y[n], self.Slu[n], self.Spiv[n], sparse, tag,
        )  # fmt: skip
        if not ok:
            raise ShootingError(f"I - h/2 J is singular at mesh point {n} (h={2 * self.hh:.3g})")

    def solve(self, n: int, rhs: np.ndarray) -> np.ndarray:
        """``(I - h/2 J_n)^{-1} rhs``."""
        nr, sparse, tag = self._static
        x = np.empty_like(rhs)
        self._K.solve_system(
            self.hh, self.Am[n], self.Ap[n], self.Rr[n], self.Dlu[n], self.Dpiv[n], self.Uhat[n],
            self.Y[n], self.Slu[n], self.Spiv[n], nr, rhs, x, self._zb, sparse, tag,
        )  # fmt: skip
        return x

    def jac(self, n: int, v: np.ndarray) -> np.ndarray:
        """``J_n v`` from the blocks."""
        out = np.empty_like(v)
        _block_matvec(
            self.Ad[n], self.Ap[n], self.Am[n], self.Er[n], self.Rr[n], self.Srr[n], self._col,
            self._rot.start, v, out,
        )  # fmt: skip
        return out


@njit(cache=True)
def _block_matvec(Ad, Ap, Am, Er, Rr, Srr, col, r0, v, out):  # pragma: no cover - compiled
    """``out = J v`` for J in the model's blocks: ``Ad[i]`` couples column ``i`` to itself, ``Ap[i]``
    to column ``i + 1``, ``Am[i]`` to ``i - 1`` (periodic), ``Er``/``Rr``/``Srr`` the rotor border;
    ``col[i]`` are the state indices of column ``i``'s unknowns, ``r0`` the first rotor index."""
    nc, m = col.shape
    for a in range(4):
        acc = 0.0
        for b in range(4):
            acc += Srr[a, b] * v[r0 + b]
        out[r0 + a] = acc
    for i in range(nc):
        ip = (i + 1) % nc
        im = (i - 1) % nc
        for a in range(m):
            acc = 0.0
            for b in range(m):
                acc += Ad[i, a, b] * v[col[i, b]] + Ap[i, a, b] * v[col[ip, b]] + Am[i, a, b] * v[col[im, b]]
            for b in range(4):
                acc += Er[i, a, b] * v[r0 + b]
            out[col[i, a]] = acc
        for a in range(4):
            acc = 0.0
            for b in range(m):
                acc += Rr[i, a, b] * v[col[i, b]]
            out[r0 + a] += acc


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
        # mesh point i holds J(s_i) and the factors of I - h/2 J(s_i): the Newton matrix of step i and
        # the implicit side of the variational recursion of step i - 1
        self.factors = F = _StepFactors(model, N + 1, 0.5 * h)
        s = np.array(s0, dtype=float)
        k = model.rhs(s, lam, dw)
        F.set(0, s, lam, dw)
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
                    dx = F.solve(i, -r)
                    x = x + dx
                    if np.max(np.abs(dx)) <= 1e-12 * (1.0 + np.max(np.abs(x))):
                        ok = True
                        break
                if ok:
                    break
                # start again from the explicit Euler predictor (the Newton matrix is J(s) already)
                x = s + h * k
            if not ok or model.min_film_thickness(x) <= 0:
                raise ShootingError(f"trapezoidal step {i} of {N} did not converge (h={h:.3g})")
            kx = model.rhs(x, lam, dw)
            F.set(i + 1, x, lam, dw)
            # variational recursion for dphi/dT (and dphi/dLambda)
            zT = F.solve(i + 1, zT + 0.5 * h * F.jac(i, zT) + (k + kx) / (2 * N))
            if need_dlam:
                kLx = (model.rhs(x, lam + d, dw) - model.rhs(x, lam - d, dw)) / (2 * d)
                zL = F.solve(i + 1, zL + 0.5 * h * F.jac(i, zL) + 0.5 * h * (kL + kLx))
                kL = kLx
            s_prev, s, k = s, x, kx
            self.rotor[i + 1] = L.rotor(s)
            self.min_film[i + 1] = model.min_film_thickness(s)
        self.end = s
        self.k_end = k
        self.dphi_dT = zT
        self.dphi_dlam = zL

    def monodromy_product(self, X: np.ndarray) -> np.ndarray:
        """``M X`` for a vector or an ``(n, m)`` block."""
        Y = np.array(X, dtype=float)
        if Y.ndim == 2:
            return np.column_stack([self.monodromy_product(c) for c in Y.T])
        hh = 0.5 * self.h
        F = self.factors
        for i in range(self.N):
            Y = F.solve(i + 1, Y + hh * F.jac(i, Y))
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
        # drop this sweep (and the operator holding it) before the next one is built: two sweeps'
        # stored factors alive at once double the peak memory
        sw = A = matvec = None
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
    second: PeriodicOrbit | None = None,
    stop_bearing_number: float | None = None,
    min_film_thickness: float = 0.01,
) -> CycleBranch:
    """Pseudo-arclength continuation of a branch of cycles from ``orbit``, first in the direction
    ``sign(first_step)`` of ``Lambda`` (a natural-parameter step of ``first_step`` gives the second
    point and the first secant), until the fold of cycles is passed (``Lambda`` along the branch turns
    back) plus ``points_after_fold`` points, ``Lambda < min_bearing_number`` or ``max_points``.

    ``second``: the branch's second point, given (e.g. the second of :func:`hopf_cycles`); the first
    secant is then ``orbit -> second`` and ``first_step`` is not used.  ``stop_bearing_number``:
    instead of ``points_after_fold`` points past the fold, continue until the branch, rising in
    ``Lambda`` (after any folds), passes it: e.g. just above ``Lambda_c`` for a branch from the Hopf
    point, which then holds the fold and the stable whirl at ``Lambda_c``.
    ``min_film_thickness``: stop once a cycle comes this close to contact (the coarse grids' discrete
    film pressure then loses positivity and the sweeps fail one after another at ever smaller steps).
    """
    if second is None and (first_step == 0 or not math.isfinite(first_step)):
        raise ValueError(f"first_step must be a non-zero finite number, got {first_step!r}")
    dw = orbit.foil_damping
    n_steps = orbit.n_steps
    orbits = [orbit]
    if second is None:
        lam1 = orbit.bearing_number + first_step
        second = find_periodic_orbit(
            model, lam1, dw, orbit.state, orbit.period, n_steps=n_steps, tol=tol, floquet=floquet
        )
    elif second.n_steps != n_steps or second.foil_damping != dw:
        raise ValueError("second must have the n_steps and foil_damping of orbit")
    o2 = second
    sign = 1.0 if o2.bearing_number > orbit.bearing_number else -1.0
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
                    last = orbits[-1]
                    message = (
                        f"step size underflow: the branch could not be continued past Lambda="
                        f"{last.bearing_number:.5g} (amplitude {last.amplitude:.3g}, min film thickness "
                        f"{last.min_film_thickness:.3g})"
                    )
                    break
        if ds < 1e-4:
            break
        mu = _floquet(sw) if floquet else np.zeros(0, dtype=complex)
        orb = PeriodicOrbit(lam, dw, T, s0, n_steps, res, its, mu, sw.rotor.copy(), sw.min_film.copy())
        sw = None  # the sweep's stored factors are large: free them before the next point
        orbits.append(orb)
        lams = [o.bearing_number for o in orbits]
        dl = np.diff(lams)
        if turned == 0 and len(dl) >= 2 and np.sign(dl[-1]) != np.sign(dl[0]):
            turned = 1
        elif turned:
            turned += 1
        if orb.min_film_thickness < min_film_thickness:
            message = (
                f"near contact: the cycle at Lambda={lam:.5g} (amplitude {orb.amplitude:.3g}) has min film "
                f"thickness {orb.min_film_thickness:.3g} < {min_film_thickness:g}"
            )
            break
        if stop_bearing_number is not None:
            if dl[-1] > 0 and lam >= stop_bearing_number:
                message = "fold passed" if turned else f"rose past Lambda={stop_bearing_number:.5g}"
                break
        elif turned > points_after_fold:
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
    fold, famp = _fold_from_branch(orbits, sign=sign)
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
    """Fold of cycles of one configuration (:func:`fold_bearing_number`).

    ``fold_bearing_number``: the lowest ``Lambda`` of the branch of cycles where it folds (None: no
    fold).  ``contact_bearing_number``: where a subcritical branch has no fold, the lowest ``Lambda``
    of its unstable cycles before they reach contact (None otherwise).  ``band_lower_bearing_number``
    combines them into the lower edge of the hysteresis band.
    """

    critical_bearing_number: float
    fold_bearing_number: float | None
    amplitude_at_critical: float
    max_eccentricity_at_critical: float
    period_at_critical: float
    branch: CycleBranch | None = field(repr=False)
    message: str = ""
    contact_bearing_number: float | None = None

    @property
    def subcritical(self) -> bool | None:
        if self.fold_bearing_number is None:
            return None
        return self.fold_bearing_number < self.critical_bearing_number

    @property
    def band_lower_bearing_number(self) -> float:
        """Lower edge of the hysteresis band, the region below ``Lambda_c`` where a large enough
        disturbance does not die out: the fold of cycles where the branch has one below ``Lambda_c``
        (the whirl persists above it); else ``contact_bearing_number``, the lowest ``Lambda`` of a
        branch of unstable cycles that runs into contact without folding (above it such a disturbance
        ends in touchdown); else ``Lambda_c`` (no band)."""
        lc = self.critical_bearing_number
        if self.fold_bearing_number is not None and self.fold_bearing_number < lc:
            return self.fold_bearing_number
        if self.contact_bearing_number is not None and self.contact_bearing_number < lc:
            return self.contact_bearing_number
        return lc


def _critical_mode(model: GFBModel, dw: float, lam_c: float) -> tuple[np.ndarray, float, np.ndarray]:
    """``(s_eq, omega, v)`` at the Hopf point: the equilibrium and the rightmost oscillatory
    eigenpair ``i omega, v`` of its Jacobian."""
    import scipy.linalg as sla

    s_eq = find_equilibrium(model, lam_c)
    ev, V = sla.eig(model.jacobian(s_eq, lam_c, dw).toarray(), check_finite=False)
    osc = np.flatnonzero(ev.imag > 1e-8)
    if len(osc) == 0:
        raise ShootingError(f"no oscillatory eigenvalue at Lambda_c={lam_c:.5g}: no Hopf point")
    j = osc[np.argmax(ev.real[osc])]
    return s_eq, float(ev[j].imag), V[:, j]


def hopf_cycles(
    model: GFBModel,
    foil_damping: float,
    critical: float,
    amplitudes: tuple[float, float] = (0.05, 0.1),
    n_steps: int = 600,
    tol: float = 1e-8,
    floquet: bool = True,
) -> list[PeriodicOrbit]:
    """The first two cycles of the branch born at the Hopf point ``Lambda_c = critical``.

    At the Hopf point the critical eigenpair ``lambda = i omega``, ``v`` of the Jacobian gives the
    small cycle ``s(tau) ~ s_eq + a Re(v e^{i omega tau})`` of period ``2 pi / omega`` (Kuznetsov,
    Sect. 3.5).  With ``v`` scaled so that its ``xi`` entry is 1, ``tau = 0`` is a maximum of ``xi``
    (``xi' = 0``: the phase condition).  Each cycle is shot with ``Lambda`` free and the arclength
    equation ``w . (s0 - s_eq) = a |w|^2`` along ``w = Re(v)``, which fixes the amplitude ``a`` instead
    of ``Lambda``: the side of ``Lambda_c`` the branch lies on (below: subcritical) comes out of the
    Newton iteration, not from a guess.  Nothing is integrated to a settled whirl first, so this works
    where the developed whirl closes the film (the coarse grids), and for the unstable cycles of the
    band.

    Args:
        critical: ``Lambda_c`` (e.g. from :func:`gfb_env.analysis.critical_bearing_number`).
        amplitudes: the two amplitudes ``a`` (clearances of ``xi``), small enough for the linear
            shape to be a good guess.

    Raises:
        ShootingError: no complex critical eigenpair, or the shooting did not converge.
    """
    dw = check_positive("foil_damping", foil_damping)
    lam_c = check_positive("critical", critical)
    if len(amplitudes) != 2 or not all(math.isfinite(a) and a > 0 for a in amplitudes):
        raise ValueError(f"amplitudes must be two positive numbers, got {amplitudes!r}")
    L = model.layout
    n = L.size
    s_eq, omega, v = _critical_mode(model, dw, lam_c)
    if abs(v[L.xi_index]) == 0:
        raise ShootingError("the critical mode does not move the journal horizontally")
    w = (v / v[L.xi_index]).real  # xi entry 1 (real), so xi' = Re(i omega) = 0 at tau = 0
    t = np.concatenate([w, [0.0, 0.0]])
    t /= np.linalg.norm(t)
    u_hopf = np.concatenate([s_eq, [2 * math.pi / omega / _T_SCALE, lam_c]])
    out = []
    for a in amplitudes:
        u_pred = u_hopf.copy()
        u_pred[:n] += a * w
        sw, s0, T, lam, its, res = _newton_shoot(
            model,
            u_pred[:n],
            u_pred[n] * _T_SCALE,
            lam_c,
            dw,
            int(n_steps),
            tol,
            15,
            tangent=t,
            u_pred=u_pred,
        )
        mu = _floquet(sw) if floquet else np.zeros(0, dtype=complex)
        out.append(
            PeriodicOrbit(lam, dw, T, s0, int(n_steps), res, its, mu, sw.rotor.copy(), sw.min_film.copy())
        )
        sw = None
    return out


def fold_bearing_number(
    model: GFBModel,
    foil_damping: float = 1.0,
    critical: float | None = None,
    offset: float = 0.01,
    n_steps: int = 600,
    max_points: int | None = None,
    progress: bool = False,
    start: str = "hopf",
) -> FoldResult:
    """``Lambda_fold``, the lowest ``Lambda`` of the branch of cycles born at the Hopf point.

    ``start="hopf"`` (default): the branch starts at the Hopf point (:func:`hopf_cycles`: the small
    unstable cycles) and is continued by pseudo-arclength round the fold and back up to ``Lambda_c``
    on the stable large cycles (:func:`continue_periodic_orbits`).  ``start="whirl"``: the branch
    starts on the whirl that develops at ``Lambda_c + offset`` (integrated from a kicked equilibrium by
    :func:`settle_whirl`) and is continued downwards round the fold; that fails where the developed
    whirl closes the film before it settles (31x7 and 21x5 at ``K_W = 1, D_W = 1``: the transient
    reaches min H ~ 0.003 with P -> 0 and the step size collapses, although the fold and the stable
    cycles at it exist).  Both give the same fold where both work.

    The limit-cycle amplitude (and max eccentricity, period) at ``Lambda_c`` is interpolated on the
    stable part of the branch (beyond the fold), NaN where that part does not reach ``Lambda_c``
    (the cycle closes the film first; the message says so).  At a supercritical Hopf point the branch
    rises in ``Lambda`` from amplitude 0; it is followed to ``Lambda_c + offset`` and a fold is
    reported only if it turns back below ``Lambda_c`` on the way.  A subcritical branch that reaches
    contact (min film thickness 0.01) without folding gives ``contact_bearing_number`` instead (21x5 at
    ``K_W = 1, D_W = 1``; the tasks' foil on 31x7 at ``D_W <= 0.5``).

    Raises:
        ShootingError: no whirl settles (``"whirl"``), or the first cycles cannot be shot.
    """
    from gfb_env.analysis.stability import critical_bearing_number

    dw = check_positive("foil_damping", foil_damping)
    if start not in ("hopf", "whirl"):
        raise ValueError(f"start must be 'hopf' or 'whirl', got {start!r}")
    if critical is None:
        critical = critical_bearing_number(model, dw).critical_bearing_number
    contact = None
    amp = eps = per = math.nan
    if start == "whirl":
        lam0 = critical + offset
        sw = settle_whirl(
            model, lam0, dw, kick=0.3, tau_max=8000, integrator_options={"touchdown_film_thickness": 1e-4}
        )
        if sw.status != "whirl":
            raise ShootingError(f"no settled whirl at Lambda={lam0:.4g} (status {sw.status})")
        o = periodic_orbit_from_simulation(model, lam0, dw, sw.state, sw.period, n_steps=n_steps)
        sw = None
        br = continue_periodic_orbits(
            model, o, first_step=-min(offset, 0.01), max_points=max_points or 30, progress=progress
        )
        # the stable (upper) part: before the fold
        j = int(np.argmin(br.bearing_number)) + 1 if br.fold_bearing_number is not None else len(br.orbits)
        upper = br.orbits[:j]
    else:
        o1, o2 = hopf_cycles(model, dw, critical, n_steps=n_steps)
        br = continue_periodic_orbits(
            model,
            o1,
            second=o2,
            max_points=max_points or 60,
            progress=progress,
            stop_bearing_number=critical + offset,
        )
        # the band's lower edge is the lowest Lambda of the branch (a supercritical Hopf point's branch
        # rises first and may still fold back below Lambda_c further on)
        br.fold_bearing_number, br.fold_amplitude = _fold_from_branch(br.orbits, -1.0)
        upper = []
        if br.fold_bearing_number is not None:
            upper = br.orbits[int(np.argmin(br.bearing_number)) :]  # the stable whirl: from the fold on
        elif o2.bearing_number > o1.bearing_number:
            amp = 0.0  # supercritical: the cycles grow from zero amplitude at Lambda_c
            per = 2 * math.pi / _critical_mode(model, dw, critical)[1]
        elif br.orbits[-1].min_film_thickness < 0.02:
            # subcritical without a fold: the unstable cycles run into contact
            contact = float(br.bearing_number.min())
    ls = np.array([x.bearing_number for x in upper])
    message = br.message
    if len(ls) and ls.min() <= critical <= ls.max():
        order = np.argsort(ls)

        def interp(v):
            return float(np.interp(critical, ls[order], np.asarray(v)[order]))

        amp = interp([x.amplitude for x in upper])
        eps = interp([x.max_eccentricity for x in upper])
        per = interp([x.period for x in upper])
    elif br.fold_bearing_number is not None:
        message += "; the stable cycles do not reach Lambda_c (no amplitude there)"
    if contact is not None:
        message += (
            f"; no fold: the unstable cycles reach contact at Lambda={contact:.5g} (the band's lower edge: "
            "above it a large disturbance ends in touchdown)"
        )
    return FoldResult(critical, br.fold_bearing_number, amp, eps, per, br, message, contact)


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
