"""The superposed 1x response's per-step bookkeeping compiled (issue 20 s.3): what
:meth:`gfb_env.envs.synchronous_plant.SuperposedResponse.after_step` adds to a step's samples, in one
``nogil`` call instead of ~30 numpy calls on 120-sample arrays (the Python around them cost more than the
synchronous solve itself).

Per sample ``i`` of the step (time ``t = tau_i - tau0``, weight ``w = t / span``, angle ``theta = theta0 +
Lambda0 t + (rate / 2) t^2``) and per superposed entry ``j`` (the rotor's 4, then the recorded pressure
taps), the 1x response ``Re((X0_j + w (X1_j - X0_j)) e^{i theta})`` is added to the sample; the film's
minimum gets that of the thinnest column; the ranges are the new samples' min and max.

Arithmetic: the numpy implementation (:func:`superpose_reference`) multiplies complex arrays, which numpy
does with fused multiply-adds where the CPU has them (AVX2/AVX-512: ``Re(a b) = fma(a_r, b_r, -a_i
b_i)``); the kernel computes ``Re`` the same way (:func:`_fma`, LLVM's ``llvm.fma``: one rounding on
every CPU), so on such a CPU the two agree bit for bit (tests/envs/test_superposition_kernel.py), and
elsewhere to rounding.  ``e^{i theta}`` is ``cos``, ``sin`` of libm (what numpy's complex ``exp`` gives
for a zero real part).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

__all__ = [
    "superpose_kernel",
    "superpose_reference",
    "stepped_residual_kernel",
    "stepped_residual_reference",
    "whirl_amplitude_kernel",
]


@intrinsic
def _fma(typingctx, a, b, c):  # noqa: ARG001 - numba's intrinsic protocol
    """``a b + c`` rounded once (LLVM's ``llvm.fma``: the instruction, or libm's exact ``fma``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ARG001
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True, nogil=True)
def _angle(tau: float, tau0: float, theta0: float, lam0: float, half_rate: float) -> float:
    t = tau - tau0
    return (theta0 + lam0 * t) + (half_rate * t) * t


@njit(cache=True, nogil=True)
def superpose_kernel(
    tau: np.ndarray,
    rotor: np.ndarray,
    film: np.ndarray,
    probes: np.ndarray,
    tau0: float,
    theta0: float,
    lam0: float,
    rate: float,
    span: float,
    x0: np.ndarray,
    x1: np.ndarray,
    idx: np.ndarray,
    h0: complex,
    h1: complex,
    out_rotor: np.ndarray,
    out_film: np.ndarray,
    out_probes: np.ndarray,
    ranges: np.ndarray,
) -> None:
    """The superposed samples of one step (module docstring).

    ``tau`` (n,): the samples' times; ``rotor`` (4, n): the unforced xi, eta, xi', eta'; ``film`` (n,):
    the unforced min film thickness; ``probes`` (n, k): the recorded taps; ``x0``, ``x1``: X (state
    layout, complex) at the step's ends; ``idx`` (4 + k,): the state indices of the rotor's 4 entries and
    the taps; ``h0``, ``h1``: the film's 1x amplitude of the thinnest column at the ends.  Writes the
    superposed samples into ``out_rotor`` (4, n), ``out_film`` (n,), ``out_probes`` (n, k) and
    ``(min film, min xi, max xi, min eta, max eta)`` into ``ranges`` (5; untouched for n = 0; NaN
    propagates as numpy's ``min``/``max``)."""
    n = tau.shape[0]
    m = idx.shape[0]
    half_rate = 0.5 * rate
    ar = np.empty(m)
    ai = np.empty(m)
    dr = np.empty(m)
    di = np.empty(m)
    for j in range(m):
        a, b = x0[idx[j]], x1[idx[j]]
        ar[j], ai[j] = a.real, a.imag
        dr[j], di[j] = b.real - a.real, b.imag - a.imag
    hdr, hdi = h1.real - h0.real, h1.imag - h0.imag
    lo_h, lo_x, hi_x, lo_e, hi_e = math.inf, math.inf, -math.inf, math.inf, -math.inf
    nan = False
    for i in range(n):
        w = (tau[i] - tau0) / span if span > 0 else 1.0
        th = _angle(tau[i], tau0, theta0, lam0, half_rate)
        c, s = math.cos(th), math.sin(th)
        for j in range(m):
            xr = ar[j] + w * dr[j]
            xi = ai[j] + w * di[j]
            add = _fma(xr, c, -(xi * s))
            if j < 4:
                out_rotor[j, i] = rotor[j, i] + add
            else:
                out_probes[i, j - 4] = probes[i, j - 4] + add
        hr = h0.real + w * hdr
        hi = h0.imag + w * hdi
        h = film[i] + _fma(hr, c, -(hi * s))
        out_film[i] = h
        x, e = out_rotor[0, i], out_rotor[1, i]
        if h != h or x != x or e != e:
            nan = True
        lo_h = min(lo_h, h)
        lo_x, hi_x = min(lo_x, x), max(hi_x, x)
        lo_e, hi_e = min(lo_e, e), max(hi_e, e)
    if n == 0:
        return
    if nan:  # numpy's min / max of an array holding NaN is NaN (each array on its own)
        for i in range(n):
            if out_film[i] != out_film[i]:
                lo_h = math.nan
            if out_rotor[0, i] != out_rotor[0, i]:
                lo_x = hi_x = math.nan
            if out_rotor[1, i] != out_rotor[1, i]:
                lo_e = hi_e = math.nan
    ranges[0], ranges[1], ranges[2], ranges[3], ranges[4] = lo_h, lo_x, hi_x, lo_e, hi_e


def superpose_reference(
    tau: np.ndarray, rotor: np.ndarray, film: np.ndarray, probes: np.ndarray, tau0: float, theta0: float,
    lam0: float, rate: float, span: float, x0: np.ndarray, x1: np.ndarray, idx: np.ndarray, h0: complex,
    h1: complex,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float, float, float, float] | None]:  # fmt: skip
    """:func:`superpose_kernel` in numpy (the implementation it replaced, kept as its reference):
    ``(rotor (4, n), film (n,), probes (n, k), ranges or None for n = 0)``."""
    t = tau - tau0
    theta = theta0 + lam0 * t + 0.5 * rate * t * t
    w = (t / span) if span > 0 else np.ones_like(t)
    rot = np.exp(1j * theta)
    xs = x0[idx][None, :] + np.outer(w, x1[idx] - x0[idx])
    add = (xs * rot[:, None]).real
    dh = ((h0 + w * (h1 - h0)) * rot).real
    out_rotor = rotor + add[:, :4].T
    h = film + dh
    out_probes = probes + add[:, 4:]
    n = len(tau)
    xi, eta = out_rotor[0], out_rotor[1]
    ranges = (
        (float(h.min()), float(xi.min()), float(xi.max()), float(eta.min()), float(eta.max())) if n else None
    )
    return out_rotor, h, out_probes, ranges


@njit(cache=True, nogil=True)
def stepped_residual_kernel(
    tau: np.ndarray, xi: np.ndarray, eta: np.ndarray, tau0: float, theta0: float, lam0: float, rate: float,
    span: float, x0_xi: complex, x1_xi: complex, x0_eta: complex, x1_eta: complex, out: np.ndarray,
) -> None:  # fmt: skip
    """The stepped motion less its 1x response (``out`` (2, n): xi, eta), whose deviation decides when a
    stepped run may be superposed again (``SuperposedResponse.after_step``, stepped)."""
    n = tau.shape[0]
    half_rate = 0.5 * rate
    xdr, xdi = x1_xi.real - x0_xi.real, x1_xi.imag - x0_xi.imag
    edr, edi = x1_eta.real - x0_eta.real, x1_eta.imag - x0_eta.imag
    for i in range(n):
        w = (tau[i] - tau0) / span if span > 0 else 1.0
        th = _angle(tau[i], tau0, theta0, lam0, half_rate)
        c, s = math.cos(th), math.sin(th)
        xr, xim = x0_xi.real + w * xdr, x0_xi.imag + w * xdi
        er, eim = x0_eta.real + w * edr, x0_eta.imag + w * edi
        out[0, i] = xi[i] - _fma(xr, c, -(xim * s))
        out[1, i] = eta[i] - _fma(er, c, -(eim * s))


def stepped_residual_reference(
    tau: np.ndarray, xi: np.ndarray, eta: np.ndarray, tau0: float, theta0: float, lam0: float, rate: float,
    span: float, x0_xi: complex, x1_xi: complex, x0_eta: complex, x1_eta: complex,
) -> np.ndarray:  # fmt: skip
    """:func:`stepped_residual_kernel` in numpy (the implementation it replaced): (2, n)."""
    t = tau - tau0
    theta = theta0 + lam0 * t + 0.5 * rate * t * t
    w = (t / span) if span > 0 else np.ones_like(t)
    rot = np.exp(1j * theta)
    xr = x0_xi + w * (x1_xi - x0_xi)
    er = x0_eta + w * (x1_eta - x0_eta)
    return np.array([xi - (xr * rot).real, eta - (er * rot).real])


@njit(cache=True, nogil=True)
def whirl_amplitude_kernel(tau: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> float:
    """The judge's whirl amplitude (``gfb_env.envs.base._whirl_amplitude``: the largest distance of the
    journal from its linear trend over the step, units of C; NaN for fewer than 3 samples or a record
    without a time span or holding NaN) in one pass of sums instead of numpy's pairwise ones: the same to
    rounding.  For the superposed response's deviation, which only decides against thresholds whether a
    step is superposed (the judge's own amplitude stays numpy's)."""
    n = tau.shape[0]
    if n < 3:
        return math.nan
    st, sx, se = 0.0, 0.0, 0.0
    for i in range(n):
        st += tau[i]
        sx += xi[i]
        se += eta[i]
    mt, mx, me = st / n, sx / n, se / n
    denom, tx, te = 0.0, 0.0, 0.0
    for i in range(n):
        t = tau[i] - mt
        denom += t * t
        tx += t * xi[i]
        te += t * eta[i]
    if not denom > 0:
        return math.nan
    bx, be = tx / denom, te / denom
    best = 0.0
    for i in range(n):
        t = tau[i] - mt
        xd = xi[i] - mx - t * bx
        ed = eta[i] - me - t * be
        d = xd * xd + ed * ed
        if d != d:
            return math.nan
        best = max(best, d)
    return math.sqrt(best)
