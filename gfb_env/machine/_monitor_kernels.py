"""The vibration monitor's per-step arithmetic compiled (issue 20 s.3): the joint least-squares fit, the
band projection, the delta-method noise and the dominant-ratio scan of
:meth:`gfb_env.machine.VibrationMonitor.measure`, in one ``nogil`` call without numpy's LAPACK layer.

The v2 envs call the monitor every control step; in numpy its ~20 calls on 120 x 14 arrays cost ~0.4 ms
of Python and call overhead, more than the compiled plant near equilibrium.  The same quantities, by
other but equivalent means (the reference is ``VibrationMonitor.measure_reference``, the numpy
implementation; tests/machine/test_monitor_kernel.py compares the two):

* the QR of the columns by modified Gram-Schmidt with one reorthogonalisation (orthonormal to rounding
  for any well-conditioned matrix; QR is nested, so its first 6 vectors span the nuisance columns);
* the band level from the same QR: the band columns made orthogonal to the nuisance span are spanned by
  the QR's last 2K vectors, so the projection's norm is that of their coefficients.  numpy drops the
  band's directions with a singular value below ``1e-8`` of the band's largest column norm; the kernel
  proves none is (``sigma_min(R_bb) >= 1 / ||R_bb^-1||_F``) or reports ``NEEDS_REFERENCE`` and the
  caller runs the numpy implementation;
* the cos / sin of evenly spaced ratios by the angle-addition recurrence along the ratios (the error
  grows by an ulp per ratio: 1e-14 at the scan's 51), so that a step costs 8 trigonometric calls per
  sample instead of 120;
* the scan's Gram entries as ``|c|^2 - |Q_n^T c|^2`` (the nuisance part removed in closed form).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: the kernel's status (:func:`measure_kernel`)
OK = 0
NEEDS_REFERENCE = 1
BAD_RECORD = 2
TOO_SLOW = 3
#: the fields of one probe's row, in :class:`~gfb_env.machine.monitor.ProbeVibration`'s order
N_FIELDS = 13
_N_NUISANCE = 6
_UNIFORM_PHASE_STD_RAD = math.pi / math.sqrt(3.0)
_RANK_TOL = 1e-8  # numpy's band basis drops singular values below this fraction of the column scale


@njit(cache=True, nogil=True)
def _cos_sin_grid(phi: float, r0: float, dr: float, out_c: np.ndarray, out_s: np.ndarray) -> None:
    """``out_c[j], out_s[j] = cos, sin((r0 + j dr) phi)`` by the angle-addition recurrence."""
    c, s = math.cos(r0 * phi), math.sin(r0 * phi)
    cd, sd = math.cos(dr * phi), math.sin(dr * phi)
    for j in range(out_c.shape[0]):
        out_c[j] = c
        out_s[j] = s
        c, s = c * cd - s * sd, s * cd + c * sd


@njit(cache=True, nogil=True)
def _vector(a: float, b: float, c00: float, c01: float, c11: float, sigma: float, out: np.ndarray) -> None:
    """Amplitude (zero-to-peak), lag (deg, [0, 360)) and their delta-method std into ``out[0:4]``."""
    amp = math.hypot(a, b)
    lag = math.degrees(math.atan2(b, a)) % 360.0
    out[0], out[1] = amp, lag
    if sigma == 0.0:
        out[2], out[3] = 0.0, 0.0
        return
    if amp > 0:
        g0, g1 = a / amp, b / amp
        a2 = amp * amp
        h0, h1 = -b / a2, a / a2
        va = g0 * (c00 * g0 + c01 * g1) + g1 * (c01 * g0 + c11 * g1)
        vl = h0 * (c00 * h0 + c01 * h1) + h1 * (c01 * h0 + c11 * h1)
        out[2] = sigma * math.sqrt(max(va, 0.0))
        out[3] = math.degrees(min(sigma * math.sqrt(max(vl, 0.0)), _UNIFORM_PHASE_STD_RAD))
    else:
        out[2] = sigma * math.sqrt(max(0.5 * (c00 + c11), 0.0))
        out[3] = math.degrees(_UNIFORM_PHASE_STD_RAD)


@njit(cache=True, nogil=True)
def measure_kernel(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    theta: np.ndarray,
    sigma: float,
    keyphasor_rad: float,
    min_revolutions: float,
    band_r0: float,
    band_dr: float,
    n_band: int,
    scan_r0: float,
    scan_dr: float,
    n_scan: int,
    out: np.ndarray,
    kinematics: np.ndarray,
) -> int:
    """One control step's monitor values (``VibrationMonitor.measure``) into ``out`` (2,
    :data:`N_FIELDS`): per probe (X, Y) the :class:`ProbeVibration` fields in order; and the record's
    ``(duration s, omega rad/s, running speed rpm, revolutions)`` into ``kinematics`` (4).  ``t``, ``x``,
    ``y``, ``theta``: one-dimensional, of one length (at least the monitor's ``min_samples``); the band's
    ``n_band`` and the scan's ``n_scan`` ratios are ``r0 + j dr``.

    Returns :data:`OK`; :data:`BAD_RECORD` (nothing computed) for a record the numpy checks must judge
    (not finite, times not increasing, angles not within [0, a quarter revolution] per sample: an error,
    or reduced angles to unwrap); :data:`TOO_SLOW` (only ``kinematics``) below ``min_revolutions``;
    :data:`NEEDS_REFERENCE` where numpy's band basis may drop a direction."""
    n = t.shape[0]
    for i in range(n):
        if not (
            math.isfinite(t[i]) and math.isfinite(x[i]) and math.isfinite(y[i]) and math.isfinite(theta[i])
        ):
            return BAD_RECORD
    for i in range(1, n):
        d = theta[i] - theta[i - 1]
        if not (t[i] > t[i - 1] and d >= 0.0 and d <= 0.5 * math.pi):
            return BAD_RECORD
    duration = t[n - 1] - t[0]
    sweep = theta[n - 1] - theta[0]
    omega = sweep / duration  # mean running speed, rad/s
    revolutions = sweep / (2.0 * math.pi)
    kinematics[0], kinematics[1] = duration, omega
    kinematics[2], kinematics[3] = omega * 60.0 / (2.0 * math.pi), revolutions
    if revolutions < min_revolutions:
        return TOO_SLOW
    data = np.empty((2, n))
    for i in range(n):
        data[0, i], data[1, i] = x[i], y[i]
    p = _N_NUISANCE + 2 * n_band
    tm = 0.5 * (t[0] + t[n - 1])
    # --- the columns, one sample per row ------------------------------------------------------
    q = np.empty((n, p))
    phis = np.empty(n)
    bc = np.empty(n_band)
    bs = np.empty(n_band)
    for i in range(n):
        q[i, 0] = 1.0
        q[i, 1] = (t[i] - tm) / duration
        ph = theta[i] - keyphasor_rad
        c1, s1 = math.cos(ph), math.sin(ph)
        q[i, 2], q[i, 3] = c1, s1
        q[i, 4], q[i, 5] = (c1 - s1) * (c1 + s1), 2.0 * s1 * c1  # cos, sin 2 theta
        phi = omega * (t[i] - t[0])
        phis[i] = phi
        _cos_sin_grid(phi, band_r0, band_dr, bc, bs)
        for k in range(n_band):
            q[i, _N_NUISANCE + 2 * k] = bc[k]
            q[i, _N_NUISANCE + 2 * k + 1] = bs[k]
    band_scale = 0.0
    for k in range(_N_NUISANCE, p):
        acc = 0.0
        for i in range(n):
            acc += q[i, k] * q[i, k]
        band_scale = max(band_scale, math.sqrt(acc))
    # --- QR by classical Gram-Schmidt, twice ("twice is enough": orthogonal to rounding) --------
    # (classical: each pass's j projections are independent sums over the samples, not a chain)
    r = np.zeros((p, p))
    h = np.empty(p)
    for j in range(p):
        for _ in range(2):
            h[:j] = 0.0
            for i in range(n):
                v = q[i, j]
                for k in range(j):
                    h[k] += q[i, k] * v
            for i in range(n):
                acc = 0.0
                for k in range(j):
                    acc += h[k] * q[i, k]
                q[i, j] -= acc
            for k in range(j):
                r[k, j] += h[k]
        nrm = 0.0
        for i in range(n):
            nrm += q[i, j] * q[i, j]
        nrm = math.sqrt(nrm)
        if not nrm > 0.0:
            return NEEDS_REFERENCE
        r[j, j] = nrm
        for i in range(n):
            q[i, j] /= nrm
    # R^-1 (upper triangular): the covariance (A^T A)^-1 = R^-1 R^-T and the band's rank check
    rinv = np.zeros((p, p))
    for j in range(p - 1, -1, -1):
        rinv[j, j] = 1.0 / r[j, j]
        for i in range(j - 1, -1, -1):
            acc = 0.0
            for k in range(i + 1, j + 1):
                acc += r[i, k] * rinv[k, j]
            rinv[i, j] = -acc / r[i, i]
    fro = 0.0
    for i in range(_N_NUISANCE, p):
        for j in range(i, p):
            fro += rinv[i, j] * rinv[i, j]
    if not 1.0 / math.sqrt(fro) > _RANK_TOL * band_scale:
        return NEEDS_REFERENCE
    cov = np.zeros((2, 2))
    for a in range(2):
        for b in range(2):
            acc = 0.0
            for k in range(2 + max(a, b), p):
                acc += rinv[2 + a, k] * rinv[2 + b, k]
            cov[a, b] = acc
    # --- coefficients, residual, what the nuisance columns leave -----------------------------
    z = np.zeros((2, p))
    for i in range(n):
        d0, d1 = data[0, i], data[1, i]
        for j in range(p):
            z[0, j] += q[i, j] * d0
            z[1, j] += q[i, j] * d1
    coef = np.zeros((p, 2))
    for m in range(2):
        for j in range(p):
            acc = 0.0
            for k in range(j, p):
                acc += rinv[j, k] * z[m, k]
            coef[j, m] = acc
    resid = np.empty((2, n))  # after the nuisance columns
    res_ms = np.zeros(2)
    for m in range(2):
        for i in range(n):
            e = data[m, i]
            for j in range(_N_NUISANCE):
                e -= z[m, j] * q[i, j]
            resid[m, i] = e
            for j in range(_N_NUISANCE, p):
                e -= z[m, j] * q[i, j]
            res_ms[m] += e * e
        res_ms[m] /= n
    # --- the dominant ratio: one sinusoid scanned over the band -------------------------------
    # the cos / sin table (samples x ratios; the recurrence runs across the samples, independent),
    # then sums over the samples with the ratios innermost (independent: they vectorise)
    tc = np.empty((n, n_scan))
    ts = np.empty((n, n_scan))
    cd = np.empty(n)
    sd = np.empty(n)
    for i in range(n):
        phi = phis[i]
        tc[i, 0], ts[i, 0] = math.cos(scan_r0 * phi), math.sin(scan_r0 * phi)
        cd[i], sd[i] = math.cos(scan_dr * phi), math.sin(scan_dr * phi)
    for j in range(1, n_scan):
        for i in range(n):
            c, s = tc[i, j - 1], ts[i, j - 1]
            tc[i, j] = c * cd[i] - s * sd[i]
            ts[i, j] = s * cd[i] + c * sd[i]
    cc = np.zeros(n_scan)
    ss = np.zeros(n_scan)
    cs = np.zeros(n_scan)
    vc = np.zeros((2, n_scan))
    vs = np.zeros((2, n_scan))
    qc = np.zeros((_N_NUISANCE, n_scan))
    qs = np.zeros((_N_NUISANCE, n_scan))
    for i in range(n):
        gc, gs = tc[i], ts[i]
        r0i, r1i = resid[0, i], resid[1, i]
        for j in range(n_scan):
            c, s = gc[j], gs[j]
            cc[j] += c * c
            ss[j] += s * s
            cs[j] += c * s
            vc[0, j] += c * r0i
            vc[1, j] += c * r1i
            vs[0, j] += s * r0i
            vs[1, j] += s * r1i
        for k in range(_N_NUISANCE):
            qk = q[i, k]
            for j in range(n_scan):
                qc[k, j] += gc[j] * qk
                qs[k, j] += gs[j] * qk
    power = np.empty((2, n_scan))
    for j in range(n_scan):
        gcc, gss, gcs = cc[j], ss[j], cs[j]
        for k in range(_N_NUISANCE):
            gcc -= qc[k, j] * qc[k, j]
            gss -= qs[k, j] * qs[k, j]
            gcs -= qc[k, j] * qs[k, j]
        det = gcc * gss - gcs * gcs
        for m in range(2):
            a, b = vc[m, j], vs[m, j]
            power[m, j] = (gss * a * a - 2.0 * gcs * a * b + gcc * b * b) / det
    # --- per probe -------------------------------------------------------------------------
    rank = 2 * n_band
    floor = sigma * math.sqrt(rank / n)
    level_std = sigma / math.sqrt(n)
    vec = np.empty(4)
    for m in range(2):
        lo, hi = data[m, 0], data[m, 0]
        for i in range(n):
            lo = min(lo, data[m, i])
            hi = max(hi, data[m, i])
        _vector(coef[2, m], coef[3, m], cov[0, 0], cov[0, 1], cov[1, 1], sigma, vec)
        lev = 0.0
        for j in range(_N_NUISANCE, p):
            lev += z[m, j] * z[m, j]
        # the grid maximum (its first), refined by a parabola through it and its neighbours
        kbest = 0
        for j in range(1, n_scan):
            if power[m, j] > power[m, kbest]:
                kbest = j
        ratio = scan_r0 + kbest * scan_dr
        if 0 < kbest < n_scan - 1:
            p0, p1, p2 = power[m, kbest - 1], power[m, kbest], power[m, kbest + 1]
            den = p0 - 2.0 * p1 + p2
            if den < 0:
                off = 0.5 * (p0 - p2) / den
                ratio += max(-0.5, min(0.5, off)) * scan_dr
        row = out[m]
        row[0] = hi - lo
        row[1] = 2.0 * vec[0]
        row[2] = vec[1]
        row[3] = 2.0 * vec[2]
        row[4] = vec[3]
        row[5] = 2.0 * math.hypot(coef[4, m], coef[5, m])
        row[6] = math.sqrt(lev / n)
        row[7] = level_std
        row[8] = floor
        row[9] = ratio
        row[10] = coef[0, m]
        row[11] = coef[1, m] / duration
        row[12] = math.sqrt(res_ms[m])
    return OK


@njit(cache=True, nogil=True)
def probe_step_kernel(
    xs: np.ndarray,
    es: np.ndarray,
    taus: np.ndarray,
    noise: np.ndarray,
    clearance_um: float,
    directions: np.ndarray,
    inverse_directions: np.ndarray,
    bias_um: np.ndarray,
    sample_interval_s: float,
    velocity_window: int,
    last: np.ndarray,
    ramp: np.ndarray,
    time_scale_s: float,
    errors: np.ndarray,
    samples: np.ndarray,
) -> int:
    """The v2 interface's probe arithmetic of one control step (``MonitorInterface.read_probes``, noisy
    probes): what ``ProximityProbes.errors_of_noise`` and ``read_um`` and ``keyphasor_angles`` compute,
    in one call.  ``xs``, ``es``, ``taus``: the step's journal record (units of C) and its times (tau);
    ``noise`` (``max(n, velocity_window)``, 2): the step's draw (um); ``last``: the step's end (xi, eta);
    ``ramp``: ``(tau0, theta0, Lambda0, tau1, Lambda1)`` of the step (``tau0`` NaN: no keyphasor record).

    Fills ``errors`` (5, 2): the position, velocity and extent errors, the last noise sample (as
    ``ProbeErrors``) and the readings (X, Y) at ``last``; and the first rows of ``samples`` (4, n) with
    the step's own samples ``(tau0, tau1]``: time (s), X, Y (um), keyphasor angle (rad).  Returns how
    many samples (0: none)."""
    n = xs.shape[0]
    m = noise.shape[0]
    w = velocity_window
    inv = inverse_directions
    u = directions
    for k in range(2):
        # noise in the (xi, eta) frame; bias_xe + noise_xe[-1]: the position error
        bias_xe = inv[k, 0] * bias_um[0] + inv[k, 1] * bias_um[1]
        errors[0, k] = bias_xe + (noise[m - 1, 0] * inv[k, 0] + noise[m - 1, 1] * inv[k, 1])
        # velocity: the least-squares slope of the noise over the last w samples
        num, den = 0.0, 0.0
        for i in range(w):
            tt = (i - 0.5 * (w - 1)) * sample_interval_s
            num += tt * (noise[m - w + i, 0] * inv[k, 0] + noise[m - w + i, 1] * inv[k, 1])
            den += tt * tt
        errors[1, k] = num / den
        # extent: (max - min) of the measured samples less that of the true ones
        true_lo, true_hi, lo, hi = math.inf, -math.inf, math.inf, -math.inf
        for i in range(n):
            tr = (xs[i] if k == 0 else es[i]) * clearance_um
            me = tr + (noise[m - n + i, 0] * inv[k, 0] + noise[m - n + i, 1] * inv[k, 1])
            true_lo, true_hi = min(true_lo, tr), max(true_hi, tr)
            lo, hi = min(lo, me), max(hi, me)
        errors[2, k] = (hi - lo) - (true_hi - true_lo)
        errors[3, k] = noise[m - 1, k]
        xi_um, eta_um = last[0] * clearance_um, last[1] * clearance_um
        errors[4, k] = u[k, 0] * xi_um + u[k, 1] * eta_um + bias_um[k] + noise[m - 1, k]
    tau0, theta0, lam0, tau1, lam1 = ramp[0], ramp[1], ramp[2], ramp[3], ramp[4]
    if not (math.isfinite(tau0) and tau1 > tau0):
        return 0
    rate = (lam1 - lam0) / (tau1 - tau0)
    count = 0
    for i in range(n):
        if taus[i] > tau0 + 1e-9:  # the step's own samples
            xi_um, eta_um = xs[i] * clearance_um, es[i] * clearance_um
            d = taus[i] - tau0
            samples[0, count] = taus[i] * time_scale_s
            samples[1, count] = u[0, 0] * xi_um + u[0, 1] * eta_um + bias_um[0] + noise[m - n + i, 0]
            samples[2, count] = u[1, 0] * xi_um + u[1, 1] * eta_um + bias_um[1] + noise[m - n + i, 1]
            samples[3, count] = theta0 + lam0 * d + 0.5 * rate * d * d
            count += 1
    return count
