"""Compiled (numba) kernels of the coupled model: right-hand side, Jacobian blocks, linear solver.

Private module: only :mod:`gfb_env.model`, :mod:`gfb_env.integrator` and the shooting sweep of
:mod:`gfb_env.analysis.periodic` (its stored per-step factors) call it, through
:class:`gfb_env.model.StateLayout`, which owns the state ordering these kernels assume:

    s = [P_00 .. P_0,nr-1, P_10 .. P_nc-1,nr-1,   (nc*nr interior pressures, phi-major)
         Q_0 .. Q_nc-1,                           (foil deflection, viscoelastic model only)
         xi, eta, xi', eta']                      (rotor, Cartesian)

Discretisation of Eq. (4) on nc periodic columns (dphi = 2 pi / nc) and nr interior rows
(dZ = 1 / (nr + 1), P = 1 on the edges Z = +-1/2), flux-conservative central differences with
P H^3 dP/dphi = H^3 d(P^2/2)/dphi:

    R_ij = a [W_{i+1/2} (P_{i+1,j}^2 - P_ij^2) - W_{i-1/2} (P_ij^2 - P_{i-1,j}^2)]
         + b H_i^3 (P_{i,j+1}^2 - 2 P_ij^2 + P_{i,j-1}^2)
         - c (P_{i+1,j} H_{i+1} - P_{i-1,j} H_{i-1}),
    a = 1 / (4 dphi^2),  b = kappa^2 / (4 dZ^2),  c = Lambda / (4 dphi),  W_{i+1/2} = ((H_i + H_{i+1})/2)^3

and per column  H_i P'_ij + P_ij H'_i = R_ij,  H'_i = -xi' sin(phi_i) - eta' cos(phi_i) - Q'_i.

The Jacobian is stored as blocks over "column unknowns" x_i = [P_i0 .. P_i,nr-1, (Q_i)] of size m:
``Ad[i] = dk_i/dx_i``, ``Ap[i] = dk_i/dx_{i+1}``, ``Am[i] = dk_i/dx_{i-1}``, ``Er[i] = dk_i/d rotor``,
``Rr[i] = dk_rotor/dx_i`` and ``Srr = dk_rotor/d rotor`` (a periodic block-tridiagonal matrix with a
border of four rotor unknowns).  :func:`factor_system` factors ``I - hh J`` by block-Thomas elimination
of columns 1..nc-1 with column 0 and the rotor as a border (a Schur complement of size m + 4).  It keeps
the explicit inverses of the m x m pivot blocks: a factorisation costs ~25 % more, a solve (several per
step, against one factorisation per several steps) 2-4x less.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

RIGID = 0
ELASTIC = 1
VISCOELASTIC = 2
FRICTIONAL = 3

# Integer and float parameter vectors (kept as arrays so that compiled signatures stay small).
# ip = [nc, nr, structure]; fp = [foil_stiffness, kappa, mass, gravity, stick_stiffness,
# friction_coefficient, slip_viscosity] (the last three only read by the frictional foil).  Only this
# module indexes them; the model builds them with :func:`pack_parameters` from its named
# ``KernelParameters``.
_NC, _NR, _STRUCT = 0, 1, 2
_KW, _KAPPA, _MASS, _GRAV, _KT, _MU, _ETA = 0, 1, 2, 3, 4, 5, 6
#: Relative band below the Coulomb limit in which the Jacobian takes the slip branch (see
#: :func:`slider_rate_derivatives`).
SLIP_BRANCH_BAND = 1e-7
#: Length of ``fp`` (callers that stack parameter vectors allocate this many).
N_FLOAT_PARAMETERS = 7


def pack_parameters(
    n_columns: int,
    n_rows: int,
    structure_code: int,
    foil_stiffness: float,
    kappa: float,
    mass_parameter: float,
    gravity_parameter: float,
    sin_phi: np.ndarray,
    cos_phi: np.ndarray,
    stick_stiffness: float = 0.0,
    friction_coefficient: float = 0.0,
    slip_viscosity: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(ip, fp, sn, cs)``: the leading parameter arguments of :func:`rhs`, :func:`jacobian_blocks` and
    :func:`film_thickness`."""
    ip = np.array([n_columns, n_rows, structure_code], dtype=np.int64)
    fp = np.array(
        [
            foil_stiffness,
            kappa,
            mass_parameter,
            gravity_parameter,
            stick_stiffness,
            friction_coefficient,
            slip_viscosity,
        ],
        dtype=np.float64,
    )
    return ip, fp, sin_phi, cos_phi


@njit(cache=True)
def coulomb_slider_rate(f, fc, eta):
    """Regularised Coulomb slider: ``eta S' = sign(F) max(|F| - F_c, 0)`` (Perzyna viscoplasticity).

    Exactly stuck (returns 0) while ``|F| <= F_c``; slipping with the overstress ``eta |S'|``."""
    if abs(f) - fc > 0.0:
        return (f - fc if f > 0.0 else f + fc) / eta
    return 0.0


@njit(cache=True)
def slider_rate(sl, ssum, nr, dz, kw, kt, mu, eta):
    """Slider rate S' of one column's Jenkins element (frictional foil).

    ``Pbar - 1 = dz (ssum - nr)``; deflection ``Q = (K_T S - (Pbar - 1)) / (K_W + K_T)``; friction force
    ``F = K_T (Q - S)``; Coulomb limit ``F_c = mu_C |Pbar - 1|``.  Regularised (Perzyna viscoplastic)
    Coulomb law ``eta S' = sign(F) max(|F| - F_c, 0)``: exactly stuck (S' = 0) while ``|F| <= F_c``,
    slipping with the overstress ``|F| - F_c = eta |S'|`` otherwise (:func:`coulomb_slider_rate`).
    """
    pm1 = dz * (ssum - nr)
    q = (kt * sl - pm1) / (kw + kt)
    f = kt * (q - sl)
    return coulomb_slider_rate(f, mu * abs(pm1), eta)


@njit(cache=True)
def slider_rate_derivatives(sl, ssum, nr, dz, kw, kt, mu, eta, out):
    """``out = [dS'/dP_l (the same for every row l of the column), dS'/dS]`` of :func:`slider_rate`.

    At the threshold ``|F| = F_c`` (and for ``F_c = 0``: mu_C = 0 or an ambient column) the slip branch is
    taken, so the linearisation at mu_C = 0 is the free slider of the K_W foil.  "At the threshold" has
    the band :data:`SLIP_BRANCH_BAND` (relative to F_c, plus 1e-9 absolute): a slider that an
    equilibrium put on its limit sits there only to the Newton tolerance, and its linearisation must not
    depend on the last bits of that solve.  (Either one-sided derivative is a valid Newton matrix there.)"""
    pm1 = dz * (ssum - nr)
    q = (kt * sl - pm1) / (kw + kt)
    f = kt * (q - sl)
    fc = mu * abs(pm1)
    if abs(f) - fc >= -(SLIP_BRANCH_BAND * fc + 1e-9):
        sg = 1.0 if f >= 0.0 else -1.0
        spm = 1.0 if pm1 > 0.0 else (-1.0 if pm1 < 0.0 else 0.0)
        dfdp = -kt * dz / (kw + kt)
        dfcdp = mu * dz * spm
        out[0] = (dfdp - sg * dfcdp) / eta
        out[1] = -kt * kw / ((kw + kt) * eta)
    else:
        out[0] = 0.0
        out[1] = 0.0


@njit(cache=True)
def slider_return_map(x, s, f, h, theta, ip, fp):
    """Solve every slider row of an implicit step exactly for its column's pressures in ``x`` (frictional
    foil; in place on ``x``'s slider entries): ``S = base + th S'(S, P)`` with ``S'`` the regularised
    Coulomb law of :func:`slider_rate` (``th`` = h/2 for the trapezoidal rule's slider rows, ``base`` =
    the step start's S + h/2 S').  The friction force is linear in S (``F = (K_T K_W (-S) - K_T (Pbar - 1))
    / (K_W + K_T)``) and the law piecewise linear in F, so the row's root is closed-form: stuck if
    ``|F(base)| <= F_c``, else on the slip branch of F(base)'s sign (the row is monotone in S, so that
    branch holds the root).  Gives the Newton iteration the slider's branch at the step end instead of
    the one its Jacobian was taken on (the implicit return map of plasticity codes)."""
    nc = ip[_NC]
    nr = ip[_NR]
    kw = fp[_KW]
    kt = fp[_KT]
    mu = fp[_MU]
    eta = fp[_ETA]
    npres = nc * nr
    dz = 1.0 / (nr + 1)
    c = kt * kw / (kw + kt)
    th = theta * h
    for i in range(nc):
        ssum = 0.0
        for j in range(nr):
            ssum += x[i * nr + j]
        pm1 = dz * (ssum - nr)
        fc = mu * abs(pm1)
        a0 = -kt * pm1 / (kw + kt)
        b = s[npres + i] + (1.0 - theta) * h * f[npres + i]
        fb = a0 - c * b
        if fb - fc > 0.0:
            x[npres + i] = (b + th * (a0 - fc) / eta) / (1.0 + th * c / eta)
        elif fb + fc < 0.0:
            x[npres + i] = (b + th * (a0 + fc) / eta) / (1.0 + th * c / eta)
        else:
            x[npres + i] = b


@njit(cache=True)
def film_thickness(s, ip, fp, sn, cs, H):
    """Film thickness H_i per column; returns its minimum."""
    nc = ip[_NC]
    nr = ip[_NR]
    st = ip[_STRUCT]
    kw = fp[_KW]
    npres = nc * nr
    r0 = npres + (nc if (st == VISCOELASTIC or st == FRICTIONAL) else 0)
    xi = s[r0]
    eta = s[r0 + 1]
    dz = 1.0 / (nr + 1)
    hmin = np.inf
    for i in range(nc):
        q = 0.0
        if st == VISCOELASTIC:
            q = s[npres + i]
        elif st == ELASTIC:
            acc = 0.0
            for j in range(nr):
                acc += s[i * nr + j]
            q = -dz * (acc - nr) / kw
        elif st == FRICTIONAL:
            # K_W Q + K_T (Q - S) = -(Pbar - 1), Pbar - 1 = dz (sum P - nr)
            acc = 0.0
            for j in range(nr):
                acc += s[i * nr + j]
            kt = fp[_KT]
            q = (kt * s[npres + i] - dz * (acc - nr)) / (kw + kt)
        H[i] = 1.0 - xi * sn[i] - eta * cs[i] - q
        if H[i] < hmin:
            hmin = H[i]
    return hmin


@njit(cache=True)
def rhs(s, lam, dw, ip, fp, sn, cs, out, H, Hd):
    """k(s, Lambda, D_W) of Eq. (14) into ``out``; H and H' per column into ``H``, ``Hd``.

    Returns min(min H, min P): callers treat a non-positive value as an inadmissible state.
    """
    nc = ip[_NC]
    nr = ip[_NR]
    st = ip[_STRUCT]
    kw = fp[_KW]
    kappa = fp[_KAPPA]
    mass = fp[_MASS]
    grav = fp[_GRAV]
    npres = nc * nr
    r0 = npres + (nc if (st == VISCOELASTIC or st == FRICTIONAL) else 0)
    dphi = 2.0 * math.pi / nc
    dz = 1.0 / (nr + 1)
    a = 1.0 / (4.0 * dphi * dphi)
    b = kappa * kappa / (4.0 * dz * dz)
    c = lam / (4.0 * dphi)
    ce = dz / kw
    kt = fp[_KT]
    if st == FRICTIONAL:
        ce = dz / (kw + kt)  # dQ/dPbar of the parallel springs K_W + K_T (S held)
    hmin = film_thickness(s, ip, fp, sn, cs, H)
    u = s[r0 + 2]
    v = s[r0 + 3]
    fxi = 0.0
    feta = 0.0
    pmin = np.inf
    for i in range(nc):
        ip1 = i + 1 if i + 1 < nc else 0
        im1 = i - 1 if i > 0 else nc - 1
        hi = H[i]
        hp = H[ip1]
        hm = H[im1]
        wp = 0.125 * (hi + hp) ** 3
        wm = 0.125 * (hi + hm) ** 3
        hi3 = hi * hi * hi
        ar = -u * sn[i] - v * cs[i]
        ssum = 0.0
        colf = 0.0
        for j in range(nr):
            k = i * nr + j
            p = s[k]
            pp = s[ip1 * nr + j]
            pm = s[im1 * nr + j]
            pn = s[k + 1] if j < nr - 1 else 1.0
            ps = s[k - 1] if j > 0 else 1.0
            p2 = p * p
            r = (
                a * (wp * (pp * pp - p2) - wm * (p2 - pm * pm))
                + b * hi3 * (pn * pn - 2.0 * p2 + ps * ps)
                - c * (pp * hp - pm * hm)
            )
            out[k] = r - p * ar
            ssum += p
            colf += p - 1.0
            if p < pmin:
                pmin = p
        fxi += colf * sn[i]
        feta += colf * cs[i]
        if st == RIGID:
            Hd[i] = ar
            for j in range(nr):
                out[i * nr + j] /= hi
        elif st == VISCOELASTIC:
            qd = -(kw * s[npres + i] + dz * (1.0 + ssum) - 1.0) / dw
            out[npres + i] = qd
            Hd[i] = ar - qd
            for j in range(nr):
                k = i * nr + j
                out[k] = (out[k] + s[k] * qd) / hi
        else:
            if st == FRICTIONAL:
                # Jenkins element: slider rate S' (regularised Coulomb law, see slider_rate); the
                # deflection rate Q' = (K_T S' - Pbar') / (K_W + K_T) puts -K_T S' / (K_W + K_T) into H'
                sd = slider_rate(s[npres + i], ssum, nr, dz, kw, kt, fp[_MU], fp[_ETA])
                out[npres + i] = sd
                ar = ar - kt * sd / (kw + kt)
                for j in range(nr):
                    k = i * nr + j
                    out[k] += s[k] * kt * sd / (kw + kt)
            sb = 0.0
            for j in range(nr):
                sb += out[i * nr + j]
            sig = sb / (hi + ce * ssum)
            Hd[i] = ar + ce * sig
            for j in range(nr):
                k = i * nr + j
                out[k] = (out[k] - ce * s[k] * sig) / hi
    scale = dphi * dz
    out[r0] = u
    out[r0 + 1] = v
    out[r0 + 2] = -fxi * scale / mass
    out[r0 + 3] = grav - feta * scale / mass
    return min(hmin, pmin)


@njit(cache=True)
def jacobian_blocks(s, lam, dw, ip, fp, sn, cs, F, H, Hd, Ad, Ap, Am, Er, Rr, Srr):
    """Analytic Jacobian of :func:`rhs` as blocks (see the module docstring).  Also fills F = k(s)."""
    nc = ip[_NC]
    nr = ip[_NR]
    st = ip[_STRUCT]
    kw = fp[_KW]
    kappa = fp[_KAPPA]
    mass = fp[_MASS]
    dphi = 2.0 * math.pi / nc
    dz = 1.0 / (nr + 1)
    a = 1.0 / (4.0 * dphi * dphi)
    b = kappa * kappa / (4.0 * dz * dz)
    c = lam / (4.0 * dphi)
    ce = dz / kw
    kt = fp[_KT]
    if st == FRICTIONAL:
        ce = dz / (kw + kt)
    npres = nc * nr
    dsd = np.zeros(2)
    rhs(s, lam, dw, ip, fp, sn, cs, F, H, Hd)
    Ad[:] = 0.0
    Ap[:] = 0.0
    Am[:] = 0.0
    Er[:] = 0.0
    Rr[:] = 0.0
    Srr[:] = 0.0
    m = Ad.shape[1]
    dRdH0 = np.empty(nr)
    dRdHp = np.empty(nr)
    dRdHm = np.empty(nr)
    g = np.empty(nr)
    scale = dphi * dz / mass
    for i in range(nc):
        ip1 = i + 1 if i + 1 < nc else 0
        im1 = i - 1 if i > 0 else nc - 1
        hi = H[i]
        hp = H[ip1]
        hm = H[im1]
        wp = 0.125 * (hi + hp) ** 3
        wm = 0.125 * (hi + hm) ** 3
        dwp = 0.375 * (hi + hp) ** 2
        dwm = 0.375 * (hi + hm) ** 2
        hi3 = hi * hi * hi
        hdi = Hd[i]
        ssum = 0.0
        # direct derivatives of R (P stencil) and dR/dH, column-block rows j
        for j in range(nr):
            k = i * nr + j
            p = s[k]
            pp = s[ip1 * nr + j]
            pm = s[im1 * nr + j]
            pn = s[k + 1] if j < nr - 1 else 1.0
            ps = s[k - 1] if j > 0 else 1.0
            p2 = p * p
            ssum += p
            dRdH0[j] = a * (dwp * (pp * pp - p2) - dwm * (p2 - pm * pm)) + 3.0 * b * hi * hi * (
                pn * pn - 2.0 * p2 + ps * ps
            )
            dRdHp[j] = a * dwp * (pp * pp - p2) - c * pp
            dRdHm[j] = -a * dwm * (p2 - pm * pm) + c * pm
            Ad[i, j, j] = -2.0 * a * p * (wp + wm) - 4.0 * b * hi3 * p - hdi
            if j < nr - 1:
                Ad[i, j, j + 1] = 2.0 * b * hi3 * pn
            if j > 0:
                Ad[i, j, j - 1] = 2.0 * b * hi3 * ps
            Ap[i, j, j] = 2.0 * a * wp * pp - c * hp
            Am[i, j, j] = 2.0 * a * wm * pm + c * hm
            # rotor columns of g: xi, eta, xi', eta'
            Er[i, j, 0] = -(dRdH0[j] * sn[i] + dRdHp[j] * sn[ip1] + dRdHm[j] * sn[im1]) + F[k] * sn[i]
            Er[i, j, 1] = -(dRdH0[j] * cs[i] + dRdHp[j] * cs[ip1] + dRdHm[j] * cs[im1]) + F[k] * cs[i]
            Er[i, j, 2] = p * sn[i]
            Er[i, j, 3] = p * cs[i]
        if st == VISCOELASTIC:
            for j in range(nr):
                p = s[i * nr + j]
                for l in range(nr):
                    Ad[i, j, l] -= p * dz / dw
                Ad[i, j, nr] = -dRdH0[j] + F[i * nr + j] - p * kw / dw
                Ap[i, j, nr] = -dRdHp[j]
                Am[i, j, nr] = -dRdHm[j]
            for l in range(nr):
                Ad[i, nr, l] = -dz / dw
            Ad[i, nr, nr] = -kw / dw
        elif st == ELASTIC or st == FRICTIONAL:
            for j in range(nr):
                fj = F[i * nr + j]
                for l in range(nr):
                    Ad[i, j, l] += (dRdH0[j] - fj) * ce
                    Ap[i, j, l] += dRdHp[j] * ce
                    Am[i, j, l] += dRdHm[j] * ce
            if st == FRICTIONAL:
                # dH/dS = -K_T/(K_W+K_T); the slider rate enters H' as -K_T S'/(K_W+K_T); the slider row
                # is d S'/d[P, S] (its own column only)
                kq = kt / (kw + kt)
                slider_rate_derivatives(s[npres + i], ssum, nr, dz, kw, kt, fp[_MU], fp[_ETA], dsd)
                for j in range(nr):
                    p = s[i * nr + j]
                    fj = F[i * nr + j]
                    for l in range(nr):
                        Ad[i, j, l] += p * kq * dsd[0]
                    Ad[i, j, nr] = -dRdH0[j] * kq + fj * kq + p * kq * dsd[1]
                    Ap[i, j, nr] = -dRdHp[j] * kq
                    Am[i, j, nr] = -dRdHm[j] * kq
                for l in range(nr):
                    Ad[i, nr, l] = dsd[0]
                Ad[i, nr, nr] = dsd[1]
        # divide by H (rigid, viscoelastic) or apply the Sherman-Morrison inverse (elastic, frictional)
        if st == ELASTIC or st == FRICTIONAL:
            den = hi + ce * ssum
            for blk in range(3):
                for l in range(m):
                    sg = 0.0
                    for j in range(nr):
                        if blk == 0:
                            g[j] = Ad[i, j, l]
                        elif blk == 1:
                            g[j] = Ap[i, j, l]
                        else:
                            g[j] = Am[i, j, l]
                        sg += g[j]
                    corr = ce * sg / den
                    for j in range(nr):
                        val = (g[j] - s[i * nr + j] * corr) / hi
                        if blk == 0:
                            Ad[i, j, l] = val
                        elif blk == 1:
                            Ap[i, j, l] = val
                        else:
                            Am[i, j, l] = val
            for l in range(4):
                sg = 0.0
                for j in range(nr):
                    sg += Er[i, j, l]
                corr = ce * sg / den
                for j in range(nr):
                    Er[i, j, l] = (Er[i, j, l] - s[i * nr + j] * corr) / hi
        else:
            for j in range(nr):
                for l in range(m):
                    Ad[i, j, l] /= hi
                    Ap[i, j, l] /= hi
                    Am[i, j, l] /= hi
                for l in range(4):
                    Er[i, j, l] /= hi
        for j in range(nr):
            Rr[i, 2, j] = -scale * sn[i]
            Rr[i, 3, j] = -scale * cs[i]
    Srr[0, 2] = 1.0
    Srr[1, 3] = 1.0


# ------------------------------------------------------------------------------------------------
# Linear algebra of I - hh J.  The block size m = nr (+1 for the foil deflection) is small (6 on the
# paper grid), so hand loops beat LAPACK calls; the kernels take ``size_tag``, a tuple of length m, so
# that numba compiles them once per block size with constant trip counts (the short inner loops then
# unroll and vectorise: ~20 % off a solve).  n = len(tag) + extra with extra = 0 (pivot blocks) or 4
# (the border).
def size_tag(m: int) -> tuple:
    """The ``size_tag`` argument of :func:`factor_system` / :func:`solve_system` for block size m."""
    return (0,) * int(m)


@njit(cache=True, fastmath=True)
def _lu(A, piv, tag, extra):
    """In-place LU with partial pivoting of the leading n x n part of A.  False if singular."""
    n = len(tag) + extra
    for k in range(n):
        p = k
        amax = abs(A[k, k])
        for r in range(k + 1, n):
            if abs(A[r, k]) > amax:
                amax = abs(A[r, k])
                p = r
        piv[k] = p
        if amax == 0.0:
            return False
        if p != k:
            for cidx in range(n):
                tmp = A[k, cidx]
                A[k, cidx] = A[p, cidx]
                A[p, cidx] = tmp
        inv = 1.0 / A[k, k]
        for r in range(k + 1, n):
            A[r, k] *= inv
            f = A[r, k]
            if f != 0.0:
                for cidx in range(k + 1, n):
                    A[r, cidx] -= f * A[k, cidx]
    return True


@njit(cache=True, fastmath=True)
def _lu_solve(LU, piv, x, tag, extra):
    n = len(tag) + extra
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = x[k]
            x[k] = x[p]
            x[p] = tmp
    for r in range(n):
        acc = x[r]
        for cidx in range(r):
            acc -= LU[r, cidx] * x[cidx]
        x[r] = acc
    for r in range(n - 1, -1, -1):
        acc = x[r]
        for cidx in range(r + 1, n):
            acc -= LU[r, cidx] * x[cidx]
        x[r] = acc / LU[r, r]


@njit(cache=True, fastmath=True)
def _invert(A, piv, Ainv, tag):
    """Ainv <- A^{-1} from the LU factors in A (m x m, m = len(tag))."""
    n = len(tag)
    for r in range(n):
        for q in range(n):
            Ainv[r, q] = 1.0 if r == q else 0.0
    for k in range(n):
        p = piv[k]
        if p != k:
            for q in range(n):
                tmp = Ainv[k, q]
                Ainv[k, q] = Ainv[p, q]
                Ainv[p, q] = tmp
    for r in range(n):
        for c in range(r):
            a = A[r, c]
            for q in range(n):
                Ainv[r, q] -= a * Ainv[c, q]
    for r in range(n - 1, -1, -1):
        for c in range(r + 1, n):
            a = A[r, c]
            for q in range(n):
                Ainv[r, q] -= a * Ainv[c, q]
        inv = 1.0 / A[r, r]
        for q in range(n):
            Ainv[r, q] *= inv


@njit(cache=True, fastmath=True)
def factor_system(hh, Ad, Ap, Am, Er, Rr, Srr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, sparse, size_tag):
    """Factor ``I - hh J`` (J in blocks).  Returns False if a pivot vanishes.

    ``sparse``: Am and Ap hold only their diagonal and last column (rigid and viscoelastic foil; the
    elastic foil's Sherman-Morrison coupling fills them).  ``size_tag``: a tuple of length m.
    """
    nc = Ad.shape[0]
    m = len(size_tag)
    nb = m + 4
    ml = m - 1
    last = nc - 1
    work = np.empty((m, m))
    w = np.empty((m, nb))
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
                    acc = 0.0
                    for t in range(m):
                        acc += Dlu[i, r, t] * Ap[i, t, ml]
                    Uhat[i, r, ml] = -hh * acc
            else:
                for r in range(m):
                    for q in range(m):
                        acc = 0.0
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
                acc = 0.0
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


@njit(cache=True, fastmath=True)
def solve_system(hh, Am, Ap, Rr, Dlu, Dpiv, Uhat, Y, Slu, Spiv, nr, rhs_vec, x, zb, sparse, size_tag):
    """Solve ``(I - hh J) x = rhs_vec`` with the factors of :func:`factor_system`.

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
    border = np.empty(nb)
    col = np.empty(m)
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
                    acc = 0.0
                    for t in range(m):
                        acc += Am[i, r, t] * zb[i - 1, t]
                    col[r] += hh * acc
        for r in range(m):
            acc = 0.0
            for t in range(m):
                acc += Dlu[i, r, t] * col[t]
            zb[i, r] = acc
    for i in range(last - 1, 0, -1):
        for r in range(m):
            acc = 0.0
            for t in range(m):
                acc += Uhat[i, r, t] * zb[i + 1, t]
            zb[i, r] -= acc
    # border
    for r in range(m):
        acc = 0.0
        for t in range(m):
            acc += Ap[0, r, t] * zb[1, t] + Am[0, r, t] * zb[last, t]
        border[r] = zb[0, r] + hh * acc
    for r in range(2):  # rows 0, 1 of Rr are zero: xi' = xi_dot, eta' = eta_dot
        border[m + r] = rhs_vec[r0 + r]
    for r in range(2, 4):
        acc = 0.0
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
            acc = 0.0
            for q in range(nb):
                acc += Y[i, r, q] * border[q]
            col[r] = zb[i, r] - acc
        for r in range(nr):
            x[i * nr + r] = col[r]
        if has_q:
            x[npres + i] = col[nr]
    for r in range(4):
        x[r0 + r] = border[m + r]
