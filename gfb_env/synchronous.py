"""The synchronous (1x) unbalance response, solved analytically per control step.

A residual unbalance ``U`` at the angle ``phi`` ahead of the rotation angle theta adds to the rotor's
velocity rows the forcing of :mod:`gfb_env.forcing`, ``U (theta'^2 sin, theta'^2 cos) - U theta''
(cos, -sin)`` of ``theta + phi``: in complex form ``Re(b e^{i theta})`` with

    b_xi' = U e^{i phi} (-i Lambda^2 - Lambda'),     b_eta' = U e^{i phi} (Lambda^2 - i Lambda').

Linearised about the plant's state (``s = s_u + Re(X e^{i theta})``, ``theta' = Lambda``) the steady
synchronous response solves ``(i Lambda I - J) X = b`` (as :func:`gfb_env.analysis.unbalance_response`,
there with a sparse LU of the whole matrix).  Here ``I - hh J`` with the complex ``hh = 1 / (i Lambda)``
goes through the integrator's own block elimination (periodic block-tridiagonal with the rotor as a
border, :func:`gfb_env._kernels.factor_system`), in complex arithmetic: the same loops with complex
workspace (:func:`_factor_complex`, :func:`_solve_complex`; copies because the real kernels allocate
real workspace and must stay bit for bit).  One Jacobian, one complex factorisation and one solve per
call.

The same call tracks the least damped eigenvalue of J (one step of shifted inverse iteration from the
previous estimate, a second complex factorisation): its real part, the growth rate, is the plant's
distance from ``Lambda_c`` (it crosses 0 there), which decides where superposing the 1x response is
valid (:mod:`gfb_env.envs.base`, ``synchronous_response="superposed"``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gfb_env import _kernels as K
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel

__all__ = ["SynchronousSolver", "synchronous_forcing"]

# The block LU of _kernels (complex blocks here) and this module's factorisation and solve are inlined in
# numba's IR, not called as separately compiled (cached) functions: with those calls, a process that
# loaded the kernels from numba's on-disk cache computed other last bits (4e-14 on one call) than the
# process that had compiled them, so the first run after an install or an edit was not the next one
# (tests/install/test_cache_determinism.py); inlined, both run the same code.
_lu = njit(inline="always", fastmath=True)(K._lu.py_func)
_lu_solve = njit(inline="always", fastmath=True)(K._lu_solve.py_func)
_invert = njit(inline="always", fastmath=True)(K._invert.py_func)


def synchronous_forcing(
    model: GFBModel, unbalance: Unbalance, bearing_number: float, rotation_acceleration: float = 0.0
) -> np.ndarray:
    """``b``: the complex amplitude (state layout) of the unbalance forcing ``Re(b e^{i theta})`` at
    ``Lambda = bearing_number`` and ``Lambda' = rotation_acceleration`` (module docstring)."""
    L = model.layout
    b = np.zeros(L.size, dtype=np.complex128)
    lam2 = float(bearing_number) ** 2
    a = float(rotation_acceleration)
    c = unbalance.magnitude * complex(math.cos(unbalance.phase_rad), math.sin(unbalance.phase_rad))
    b[L.xi_dot_index] = c * complex(-a, -lam2)
    b[L.eta_dot_index] = c * complex(lam2, -a)
    return b


@njit(cache=True, fastmath=True, inline="always")
def _factor_complex(hh, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag):
    """``K.factor_system`` for a complex ``hh`` (complex workspace).  Returns False if a pivot vanishes.

    ``sparse``: Am and Ap hold only their diagonal and last column (rigid and viscoelastic foil; the
    elastic foil's Sherman-Morrison coupling fills them).  ``size_tag``: a tuple of length m.
    """
    nc = Ad.shape[0]
    m = len(size_tag)
    nb = m + 4
    ml = m - 1
    last = nc - 1
    work = np.empty((m, m), dtype=np.complex128)
    w = np.empty((m, nb), dtype=np.complex128)
    # block-Thomas forward sweep over columns 1..nc-1
    for i in range(1, nc):
        for r in range(m):
            for q in range(m):
                work[r, q] = -hh * Ad[i, r, q]
            work[r, r] += 1.0
        if i > 1:
            # D_i -= L_i Uhat_{i-1},  L_i = -hh Am[i]  (Am is mostly diagonal: skip its zeros)
            for r in range(m):
                for t in range(m):
                    a = hh * Am[i, r, t]
                    if a != 0.0:
                        for q in range(m):
                            work[r, q] += a * Uhat[i - 1, t, q]
        if not _lu(work, Dpiv[i], size_tag, 0):
            return False
        # keep the explicit inverse of D_i: the solves then run on matrix-vector products
        _invert(work, Dpiv[i], Dlu[i], size_tag)
        if i < last:
            # Uhat_i = D_i^{-1} (-hh Ap[i])
            if sparse:
                for r in range(m):
                    for q in range(ml):
                        Uhat[i, r, q] = -hh * Dlu[i, r, q] * Ap[i, q, q]
                    acc = 0.0j
                    for t in range(m):
                        acc += Dlu[i, r, t] * Ap[i, t, ml]
                    Uhat[i, r, ml] = -hh * acc
            else:
                for r in range(m):
                    for q in range(m):
                        acc = 0.0j
                        for t in range(m):
                            acc += Dlu[i, r, t] * Ap[i, t, q]
                        Uhat[i, r, q] = -hh * acc
    # Y = T^{-1} W: the response of columns 1..nc-1 to the border unknowns [x_0, rotor].
    # Forward: Y_i = D_i^{-1} (W_i - L_i Y_{i-1}), the bracket staged in w (m x nb).
    for i in range(1, nc):
        for r in range(m):
            for q in range(m):
                w[r, q] = 0.0
            for q in range(4):
                w[r, m + q] = -hh * Er[i, r, q]
            if i == 1:
                for q in range(m):
                    w[r, q] -= hh * Am[1, r, q]
            if i == last:
                for q in range(m):
                    w[r, q] -= hh * Ap[last, r, q]
            if i > 1:
                for t in range(m):
                    a = hh * Am[i, r, t]
                    if a != 0.0:
                        for q in range(nb):
                            w[r, q] += a * Y[i - 1, t, q]
        for r in range(m):
            for q in range(nb):
                acc = 0.0j
                for t in range(m):
                    acc += Dlu[i, r, t] * w[t, q]
                Y[i, r, q] = acc
    for i in range(last - 1, 0, -1):
        for r in range(m):
            for t in range(m):
                a = Uhat[i, r, t]
                for q in range(nb):
                    Y[i, r, q] -= a * Y[i + 1, t, q]
    # Schur complement on the border [x_0, rotor]
    for r in range(nb):
        for q in range(nb):
            Slu[r, q] = 0.0
    for r in range(m):
        for q in range(m):
            Slu[r, q] = -hh * Ad[0, r, q]
        Slu[r, r] += 1.0
        for q in range(4):
            Slu[r, m + q] = -hh * Er[0, r, q]
    for r in range(4):
        for q in range(m):
            Slu[m + r, q] = -hh * Rr[0, r, q]
        for q in range(4):
            Slu[m + r, m + q] = -hh * Srr[r, q]
        Slu[m + r, m + r] += 1.0
    for r in range(m):
        for t in range(m):
            a = hh * Ap[0, r, t]
            b = hh * Am[0, r, t]
            for q in range(nb):
                Slu[r, q] += a * Y[1, t, q] + b * Y[last, t, q]
    for r in range(2, 4):  # rows 0, 1 of Rr are zero
        for i in range(1, nc):
            for t in range(m):
                a = hh * Rr[i, r, t]
                if a != 0.0:
                    for q in range(nb):
                        Slu[m + r, q] += a * Y[i, t, q]
    return _lu(Slu, Spiv, size_tag, 4)


@njit(cache=True, fastmath=True, inline="always")
def _solve_complex(hh, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, rhs_vec, x, zb, sparse, size_tag):
    """``K.solve_system`` for complex factors (:func:`_factor_complex`) and a complex ``rhs_vec``.

    ``rhs_vec`` and ``x`` are in state layout; ``zb`` is workspace of shape (nc, m).  ``sparse``: the
    off-diagonal blocks Am, Ap hold only their diagonal and last column (rigid and viscoelastic foil).
    ``size_tag`` is any tuple of length m (see :func:`size_tag`).
    """
    nc = Am.shape[0]
    m = len(size_tag)
    nb = m + 4
    npres = nc * nr
    has_q = m > nr
    r0 = npres + (nc if has_q else 0)
    last = nc - 1
    ml = m - 1
    border = np.empty(nb, dtype=np.complex128)
    col = np.empty(m, dtype=np.complex128)
    for r in range(nr):
        zb[0, r] = rhs_vec[r]
    if has_q:
        zb[0, nr] = rhs_vec[npres]
    # forward: z_i = D_i^{-1} (r_i - L_i z_{i-1}),  L_i = -hh Am[i],  Dlu[i] holds D_i^{-1}
    for i in range(1, nc):
        for r in range(nr):
            col[r] = rhs_vec[i * nr + r]
        if has_q:
            col[nr] = rhs_vec[npres + i]
        if i > 1:
            if sparse:
                zl = zb[i - 1, ml]
                for r in range(ml):
                    col[r] += hh * (Am[i, r, r] * zb[i - 1, r] + Am[i, r, ml] * zl)
                col[ml] += hh * Am[i, ml, ml] * zl
            else:
                for r in range(m):
                    acc = 0.0j
                    for t in range(m):
                        acc += Am[i, r, t] * zb[i - 1, t]
                    col[r] += hh * acc
        for r in range(m):
            acc = 0.0j
            for t in range(m):
                acc += Dlu[i, r, t] * col[t]
            zb[i, r] = acc
    for i in range(last - 1, 0, -1):
        for r in range(m):
            acc = 0.0j
            for t in range(m):
                acc += Uhat[i, r, t] * zb[i + 1, t]
            zb[i, r] -= acc
    # border
    for r in range(m):
        acc = 0.0j
        for t in range(m):
            acc += Ap[0, r, t] * zb[1, t] + Am[0, r, t] * zb[last, t]
        border[r] = zb[0, r] + hh * acc
    for r in range(2):  # rows 0, 1 of Rr are zero: xi' = xi_dot, eta' = eta_dot
        border[m + r] = rhs_vec[r0 + r]
    for r in range(2, 4):
        acc = 0.0j
        for i in range(1, nc):
            for t in range(m):
                acc += Rr[i, r, t] * zb[i, t]
        border[m + r] = rhs_vec[r0 + r] + hh * acc
    _lu_solve(Slu, Spiv, border, size_tag, 4)
    # back-substitute the border and scatter into state layout
    for r in range(nr):
        x[r] = border[r]
    if has_q:
        x[npres] = border[nr]
    for i in range(1, nc):
        for r in range(m):
            acc = 0.0j
            for q in range(nb):
                acc += Y[i, r, q] * border[q]
            col[r] = zb[i, r] - acc
        for r in range(nr):
            x[i * nr + r] = col[r]
        if has_q:
            x[npres + i] = col[nr]
    for r in range(4):
        x[r0 + r] = border[m + r]


@njit(cache=True, fastmath=True)
def _synchronous_update(
    s, lam, dw, ip, fp, sn, cs, F, H, Hd, Ad, Ap, Am, Er, Rr, Srr,
    Dlu, Dpiv, Uhat, Y, Slu, Spiv, zb, nr, sparse, size_tag, b, x, mu, v, w,
):  # fmt: skip
    """J at ``s``; ``x`` <- X of ``(i lam I - J) X = b``; then one inverse-iteration step of the
    eigenvalue nearest ``mu`` from the unit vector ``v`` (``v`` <- the new unit vector).  Returns
    ``(ok, eigenvalue estimate)``; ``ok`` False when a pivot vanished."""
    K.jacobian_blocks(s, lam, dw, ip, fp, sn, cs, F, H, Hd, Ad, Ap, Am, Er, Rr, Srr)
    # (i lam I - J) X = b  <=>  (I - hh J) X = b / (i lam),  hh = 1 / (i lam)
    hh = 1.0 / (1j * lam)
    if not _factor_complex(hh, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag):
        return False, mu
    n = b.shape[0]
    for k in range(n):
        w[k] = b[k] * hh
    _solve_complex(hh, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, w, x, zb, sparse, size_tag)
    # (J - mu I) u = v  <=>  (I - J / mu) u = -v / mu
    if mu == 0.0:
        return True, mu
    hm = 1.0 / mu
    if not _factor_complex(hm, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag):
        return True, mu  # mu is an eigenvalue to working precision
    rhs = np.empty(n, dtype=np.complex128)
    for k in range(n):
        rhs[k] = -v[k] * hm
    _solve_complex(hm, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, rhs, w, zb, sparse, size_tag)
    vw = 0.0j
    nw = 0.0
    for k in range(n):
        vw += v[k].conjugate() * w[k]
        nw += w[k].real * w[k].real + w[k].imag * w[k].imag
    if vw == 0.0 or nw == 0.0 or not math.isfinite(nw):
        return True, mu
    lam_est = mu + 1.0 / vw  # Rayleigh quotient of (J - mu I)^{-1}: v^H v / v^H u with |v| = 1
    inv = 1.0 / math.sqrt(nw)
    for k in range(n):
        v[k] = w[k] * inv
    return True, lam_est


class SynchronousSolver:
    """Workspace and the compiled call of the synchronous response for one model (module docstring).

    :meth:`update` gives ``X`` (the steady 1x response, state layout) and the tracked least damped
    eigenvalue of J at a state; :meth:`start_mode` finds that eigenvalue for a new episode.
    """

    #: the whirl of this bearing runs at 0.34-0.46 of the running speed (docs/machine.md): the shift
    #: that :meth:`start_mode`'s Rayleigh-quotient iteration starts from
    WHIRL_RATIO_GUESS = 0.4

    def __init__(self, model: GFBModel):
        self.model = model
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        n = model.layout.size
        self._kargs = model.kernel_args()
        self._blocks = model.new_blocks()
        self._F = np.empty(n)
        self._H = np.empty(nc)
        self._Hd = np.empty(nc)
        c = np.complex128
        self._lu = (
            np.zeros((nc, m, m), c),
            np.zeros((nc, m), np.int64),
            np.zeros((nc, m, m), c),
            np.zeros((nc, m, nb), c),
            np.zeros((nb, nb), c),
            np.zeros(nb, np.int64),
            np.zeros((nc, m), c),
        )
        self._nr = model.grid.n_rows
        self._sparse = model.sparse_offdiagonal_blocks
        self._tag = K.size_tag(m)
        self._w = np.zeros(n, c)
        self._h = np.empty(nc)
        self._h_zero = model.film_thickness(np.zeros(n))  # H of the zero state (H is affine in s)
        #: the compiled variant's entry point once known: numba's dispatcher types each of the ~30
        #: arguments on every call (tens of us); their types are fixed for one solver
        self._entry = None
        #: the tracked eigenvalue and its unit eigenvector estimate
        self.mode = 0.0j
        self.mode_vector = np.zeros(n, c)

    def __getstate__(self) -> dict:
        # the cached entry point is a compiled function (it does not pickle); it is found again on the
        # next call (an env's snapshot goes between processes: the vector env's worker processes)
        return {**self.__dict__, "_entry": None}

    def _call(self, s: np.ndarray, lam: float, dw: float, b: np.ndarray, mu: complex) -> tuple:
        bl = self._blocks
        x = np.empty(b.shape[0], np.complex128)
        args = (
            np.ascontiguousarray(s, dtype=np.float64), float(lam), float(dw), *self._kargs, self._F,
            self._H, self._Hd, bl["Ad"], bl["Ap"], bl["Am"], bl["Er"], bl["Rr"], bl["Srr"], *self._lu,
            self._nr, self._sparse, self._tag, b, x, complex(mu), self.mode_vector, self._w,
        )  # fmt: skip
        if self._entry is not None:
            ok, est = self._entry(*args)
        else:
            ok, est = _synchronous_update(*args)
            try:
                types = tuple(_synchronous_update.typeof_pyval(a) for a in args)
                self._entry = _synchronous_update.overloads[types].entry_point
            except (KeyError, AttributeError):  # pragma: no cover - numba without these internals
                pass
        if not ok:
            raise np.linalg.LinAlgError("synchronous response: i Lambda I - J is singular")
        return x, complex(est)

    def start_mode(self, s: np.ndarray, lam: float, dw: float, iterations: int = 8) -> complex:
        """The eigenvalue of J at ``s`` nearest the whirl's ``i 0.4 Lambda`` (Rayleigh-quotient
        iteration from the rotor's unit vectors), tracked from then on by :meth:`update`."""
        L = self.model.layout
        v = self.mode_vector
        v[:] = 0.0
        v[L.xi_index], v[L.eta_index] = 1.0, 1.0j
        v /= np.linalg.norm(v)
        mu = complex(-0.0, self.WHIRL_RATIO_GUESS * max(float(lam), 1e-3))
        b = np.zeros(L.size, np.complex128)
        for _ in range(iterations):
            _, est = self._call(s, max(float(lam), 1e-6), dw, b, mu)
            if abs(est - mu) <= 1e-10 * max(abs(mu), 1.0):
                mu = est
                break
            mu = est
        self.mode = mu
        return mu

    def update(self, s: np.ndarray, lam: float, dw: float, b: np.ndarray, track: bool = True) -> np.ndarray:
        """``X`` at the state ``s`` (``Lambda = lam > 0``, ``D_W = dw``) for the forcing amplitude ``b``
        (:func:`synchronous_forcing`), and (``track``) one tracking step of :attr:`mode` (its second
        factorisation: about half the call)."""
        if not track:
            return self._call(s, lam, dw, b, 0.0)[0]
        x, self.mode = self._call(s, lam, dw, b, self.mode)
        return x

    def film_response(self, x: np.ndarray) -> np.ndarray:
        """The complex amplitude of the film thickness per column of the state change ``Re(x e^{i
        theta})`` (H is affine in the state)."""
        h, h0 = self._h, self._h_zero
        K.film_thickness(np.ascontiguousarray(x.real), *self._kargs, h)
        out = (h - h0).astype(np.complex128)
        K.film_thickness(np.ascontiguousarray(x.imag), *self._kargs, h)
        out.imag = h - h0
        return out
