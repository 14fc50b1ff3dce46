"""A shaft-vibration monitor: what a machinery-protection rack computes from one control step's probe samples.

Per probe (X, Y) and per control step it reports

* the **direct** (unfiltered) peak-to-peak displacement, um pp: max - min of the step's samples.  Shaft
  displacement is specified peak-to-peak (``S_pp`` of ISO 7919 / ISO 20816 for shaft vibration), and a
  machinery-protection system (API 670) monitors the direct radial vibration;
* the **1x (synchronous) vector**: amplitude in um pp and phase lag in degrees behind the once-per-revolution
  key (keyphasor), by synchronous demodulation: least squares of the samples on ``cos theta(t)``,
  ``sin theta(t)`` with ``theta(t)`` the rotation angle the integrator tracks (exact for a speed that ramps
  over the step, which an FFT of a fixed frequency is not).  The phase convention is the keyphasor
  practice of API 670 monitors: the lag (0-360 degrees, in the rotation's degrees) from the key mark passing
  its sensor to the next positive peak of the 1x signal, i.e. ``signal = A cos(theta - phase_lag)``;
* the **2x** amplitude, um pp (the same demodulation at ``2 theta``; reported because it is free and it
  must be in the fit anyway, or the orbit's harmonic leaks into the band below);
* the **sub-synchronous level**, um rms: the rms over the step of the part of the signal in the band
  ``subsynchronous_band_ratio`` (default 0.30-0.55 of the running speed: the whirls of this bearing run at
  0.37-0.42x at onset (linear), 0.43-0.46x on the limit cycles of docs/analysis.md and 0.34x on the
  developed whirl WhirlRecovery starts from), and the **dominant sub-synchronous ratio** (the frequency /
  running speed at which a single sinusoid explains the most of it);
* the mean (the gap, "position") in um, its linear trend in um/s, and the rms of what the fit leaves.

The 1x and 2x vectors, mean and trend come out of one linear least-squares fit per probe with the columns

    1, (t - t_mid), cos theta, sin theta, cos 2 theta, sin 2 theta,     (the "nuisance" columns)
    cos(r_k Omega t), sin(r_k Omega t)    (k = 1..K, r_k evenly spaced over the band,
                                           Omega the step's mean speed)

so that a whirl does not leak into the 1x vector (< 1 % of its amplitude, tested).  The band columns are
at fixed frequencies of the step's *mean* speed, not order-tracked: a whirl is a natural frequency of the
rotor-bearing system, it does not follow the speed ramp.  A 60-tau control step holds 4-7 revolutions (2-3
whirl cycles), so the frequency resolution (1 / record length) is 0.15-0.25x: an FFT with a window could
not separate 0.45x from 0.3x or 0.6x, and its bins would not even sit on the band.  The level is instead
the data's orthogonal projection onto the band columns made orthogonal to the nuisance columns (K = 4
pairs 0.083x apart, closer than the resolution): any sinusoid in the band is captured to within 10 %
(0.91-1.00 of its rms, tested on 4.3-6.7 revolutions), a pure 1x, 2x, mean or trend gives exactly 0,
and being a projection the level never exceeds the signal (the joint fit's band coefficients would:
they trade off against the 1x and 2x columns on a short record).  The price is the band's skirts: the
record is too short for a sharp edge, so 0.2x and 0.6x still pass mostly (docs/machine.md has the table).

Noise (white Gaussian, ``noise_um`` = sigma per sample, as :class:`~gfb_env.machine.probes.ProximityProbes`
adds it): the coefficients have the covariance ``sigma^2 (A^T A)^-1`` exactly; the reported standard
deviations are its delta-method propagation (for many revolutions ``sigma_A ~ sigma sqrt(2 / N)``
zero-to-peak, so ``2 sigma sqrt(2 / N)`` pp, and ``sigma_phase ~ sigma_A / A`` rad, capped at
``pi / sqrt 3``, the standard deviation of a uniform phase, when the vector is lost in the noise).  The
band projection has ``r = 2K`` dimensions: pure noise gives the level ``noise_floor = sigma sqrt(r / N)``
(rms sense), ``E[level^2] = true^2 + floor^2``, and well above the floor the level's standard deviation is
``sigma / sqrt N`` (a non-central chi).  The direct peak-to-peak has no closed form (an extreme of noisy
samples): it is biased up by the noise (measured in ``tests/machine/test_monitor.py``).

The v2 ids' observation takes it per control step (:mod:`gfb_env.envs.interface_v2`); the v1
observation does not use it.  :meth:`VibrationMonitor.measure` computes it in one compiled call
(:mod:`gfb_env.machine._monitor_kernels`: the same quantities to ~1e-12, 79 instead of 560 us per call on
recorded v2 steps); :meth:`VibrationMonitor.measure_reference` is the numpy implementation, kept as the
kernel's reference and its fallback.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from gfb_env.forcing import rotation_angle
from gfb_env.machine import _monitor_kernels as _kernels
from gfb_env.machine._checks import finite, finite_pair, is_number, nonnegative, positive

__all__ = ["VibrationMonitor", "ProbeVibration", "MonitorReading", "keyphasor_angles"]

#: the standard deviation of a phase uniform on a circle: the most a phase estimate can scatter
_UNIFORM_PHASE_STD_RAD = math.pi / math.sqrt(3.0)
_N_NUISANCE = 6  # mean, trend, 1x (2), 2x (2)


def keyphasor_angles(
    tau: np.ndarray, tau_start: float, angle_start_rad: float, bearing_number_start: float,
    tau_end: float, bearing_number_end: float,
) -> np.ndarray:  # fmt: skip
    """The rotation angle theta (rad, not reduced) at the sample times ``tau`` of one control step, from
    the integrator's angle at the step's start (``TrapezoidalIntegrator.rotation_angle``) and the linear
    Lambda ramp of the step (theta' = Lambda, exactly as the integrator's unbalance forcing uses it)."""
    span = float(tau_end) - float(tau_start)
    if not span > 0:
        raise ValueError(f"tau_end must be after tau_start, got {tau_start!r} and {tau_end!r}")
    rate = (float(bearing_number_end) - float(bearing_number_start)) / span
    d = np.asarray(tau, dtype=float) - float(tau_start)
    return rotation_angle(float(angle_start_rad), float(bearing_number_start), rate, d)


@dataclass(frozen=True)
class ProbeVibration:
    """One probe's monitor values over one control step (module docstring).  ``*_std``: the standard
    deviation of the estimate that the probe's white noise alone causes (0 for an exact probe).

    Attributes:
        direct_um_pp: max - min of the samples, um peak-to-peak.
        synchronous_um_pp: 1x amplitude, um peak-to-peak (twice the zero-to-peak ``A``).
        synchronous_phase_lag_deg: 1x phase lag behind the key, degrees in [0, 360).
        synchronous_um_pp_std, synchronous_phase_lag_deg_std: their noise.
        second_harmonic_um_pp: 2x amplitude, um peak-to-peak.
        subsynchronous_um_rms: rms of the band component over the step, um.
        subsynchronous_um_rms_std: its noise well above the floor, ``noise_um / sqrt N``.
        subsynchronous_noise_floor_um_rms: the level pure noise gives (rms sense), ``noise_um
            sqrt(2K / N)``.
        subsynchronous_ratio: the dominant frequency in the band / the mean running speed.
        mean_um, trend_um_per_s: the gap (position) at the step's middle and its slope.
        residual_um_rms: rms of what the fit leaves (noise plus unmodelled content).
    """

    direct_um_pp: float
    synchronous_um_pp: float
    synchronous_phase_lag_deg: float
    synchronous_um_pp_std: float
    synchronous_phase_lag_deg_std: float
    second_harmonic_um_pp: float
    subsynchronous_um_rms: float
    subsynchronous_um_rms_std: float
    subsynchronous_noise_floor_um_rms: float
    subsynchronous_ratio: float
    mean_um: float
    trend_um_per_s: float
    residual_um_rms: float

    @property
    def synchronous_phasor_um(self) -> complex:
        """The 1x vector as the complex zero-to-peak amplitude ``Z`` with ``signal = Re(Z e^{i theta})``
        (the convention of :mod:`gfb_env.analysis.response`)."""
        return complex(
            0.5 * self.synchronous_um_pp * np.exp(-1j * math.radians(self.synchronous_phase_lag_deg))
        )


@dataclass(frozen=True)
class MonitorReading:
    """The monitor's output for one control step: both probes, the running speed from the key.

    ``valid`` is False when the rotor turned less than ``min_revolutions`` over the record (too slow for
    a 1x filter: a real monitor flags its filtered values "not OK" below a minimum speed).  Then every
    filtered value (1x, 2x, band, their noise) is 0 and ``subsynchronous_ratio`` is the band's middle;
    the direct peak-to-peak, mean, trend and residual are still computed."""

    x: ProbeVibration
    y: ProbeVibration
    running_speed_rpm: float
    revolutions: float
    n_samples: int
    valid: bool

    def as_dict(self) -> dict[str, float]:
        """Flat ``{probe_field: value}`` (``x_direct_um_pp``, ...) plus the speed and the flag."""
        out: dict[str, float] = {}
        for name, p in (("x", self.x), ("y", self.y)):
            for k, v in vars(p).items():
                out[f"{name}_{k}"] = v
        out["running_speed_rpm"] = self.running_speed_rpm
        out["revolutions"] = self.revolutions
        out["valid"] = float(self.valid)
        return out


@dataclass(frozen=True)
class VibrationMonitor:
    """Configuration of the vibration monitor (module docstring).

    Attributes:
        subsynchronous_band_ratio: ``(low, high)`` of the sub-synchronous band, in multiples of the
            running speed (default (0.30, 0.55): around the 0.34-0.46x whirls of this bearing, clear
            of 1x).
        subsynchronous_frequencies: K, the sinusoid pairs spanning the band (default 4: 0.083x apart,
            closer than the 0.15-0.25x resolution of a 4-7 revolution record).
        ratio_scan_step: grid step of the dominant-ratio search, in multiples of the speed (default
            0.005, refined by a parabola through the peak).
        min_revolutions: the fewest revolutions over the record for the filtered values (default 3.5:
            on shorter records the band columns and the 1x trade off, the 1x noise is 2.7x the
            ``sigma sqrt(2 / N)`` of a long record at 3.7 revolutions, 5-12x at 3; 60 tau is 3.5
            revolutions at Lambda 0.37, 22 000 rpm on the nominal bearing).
        keyphasor_angle_deg: the rotation angle theta (degrees, from the downward vertical toward +xi)
            at which the key mark passes its sensor: the zero of the phase (default 0).
    """

    subsynchronous_band_ratio: tuple[float, float] = (0.30, 0.55)
    subsynchronous_frequencies: int = 4
    ratio_scan_step: float = 0.005
    min_revolutions: float = 3.5
    keyphasor_angle_deg: float = 0.0

    def __post_init__(self) -> None:
        put = object.__setattr__
        lo, hi = finite_pair(
            "subsynchronous_band_ratio", self.subsynchronous_band_ratio, positive_values=True
        )
        if not (lo < hi < 0.9):
            raise ValueError(
                f"subsynchronous_band_ratio must be 0 < low < high < 0.9 (clear of 1x), got "
                f"{self.subsynchronous_band_ratio!r}"
            )
        put(self, "subsynchronous_band_ratio", (lo, hi))
        k = self.subsynchronous_frequencies
        if not (is_number(k) and float(k).is_integer() and 1 <= k <= 20):
            raise ValueError(f"subsynchronous_frequencies must be an integer in [1, 20], got {k!r}")
        put(self, "subsynchronous_frequencies", int(k))
        step = positive("ratio_scan_step", self.ratio_scan_step)
        if step > hi - lo:
            raise ValueError(f"ratio_scan_step must be at most the band's width {hi - lo:g}, got {step!r}")
        put(self, "ratio_scan_step", step)
        put(self, "min_revolutions", positive("min_revolutions", self.min_revolutions))
        put(self, "keyphasor_angle_deg", finite("keyphasor_angle_deg", self.keyphasor_angle_deg))
        # the kernel's arguments that only the configuration fixes (not a field: measure reads them
        # every control step instead of recomputing them from the band's ratios)
        ratios, ratios_scan = _ratios(self.subsynchronous_band_ratio, int(k), step)
        put(
            self,
            "_kernel_constants",
            (
                math.radians(self.keyphasor_angle_deg), self.min_revolutions, float(ratios[0]),
                float(ratios[1] - ratios[0]) if len(ratios) > 1 else 0.0, len(ratios),
                float(ratios_scan[0]), self.ratio_scan_step, len(ratios_scan),
            ),
        )  # fmt: skip

    @property
    def band_ratios(self) -> np.ndarray:
        """The K ratios of the band's columns (the band's middle if K = 1)."""
        cols, _ = _ratios(
            self.subsynchronous_band_ratio, self.subsynchronous_frequencies, self.ratio_scan_step
        )
        return cols.copy()

    @property
    def min_samples(self) -> int:
        """The fewest samples a record may have: twice the fit's columns."""
        return 2 * (_N_NUISANCE + 2 * self.subsynchronous_frequencies)

    # ------------------------------------------------------------------------------------------
    def measure(
        self,
        time_s: np.ndarray,
        x_um: np.ndarray,
        y_um: np.ndarray,
        rotation_angle_rad: np.ndarray,
        noise_um: float = 0.0,
    ) -> MonitorReading:
        """The monitor's values of one control step (pure: no state, no random numbers).

        Args:
            time_s: sample times, s, strictly increasing (the probes' record grid).
            x_um, y_um: the measured probe readings at those times, um (bias and noise included, as
                :meth:`ProximityProbes.readings_um` gives them).
            rotation_angle_rad: the rotation angle theta at those times, rad (reduced or not; at most
                a quarter revolution between samples, so that 2x is below the Nyquist frequency):
                :func:`keyphasor_angles`.
            noise_um: the standard deviation of the probes' white noise per sample (``ProximityProbes
                .noise_um``), for the ``*_std`` entries.

        Raises ``ValueError`` (naming the argument) for mismatched lengths, non-finite values, fewer than
        :attr:`min_samples` samples, times not increasing or a rotation too fast for the sampling."""
        # the checks run in the kernel; where it finds fault (or angles to unwrap), numpy's checks judge
        asarray = np.asarray
        t, x, y = asarray(time_s, dtype=float), asarray(x_um, dtype=float), asarray(y_um, dtype=float)
        theta = asarray(rotation_angle_rad, dtype=float)
        n = len(t)
        if not (t.ndim == x.ndim == y.ndim == theta.ndim == 1 and n == len(x) == len(y) == len(theta)) or (
            n < 2 * (_N_NUISANCE + 2 * self.subsynchronous_frequencies)  # (min_samples)
        ):
            t, x, y, theta, sigma, n = self._checked(time_s, x_um, y_um, rotation_angle_rad, noise_um)
        # (a finite float >= 0 passes nonnegative() unchanged: checked by its type first)
        sigma = noise_um if type(noise_um) is float and 0.0 <= noise_um < math.inf else None
        if sigma is None:
            sigma = nonnegative("noise_um", noise_um)
        out = np.empty((2, _kernels.N_FIELDS))
        kin = np.empty(4)
        args = (sigma, *self._kernel_constants, out, kin)
        status = _kernels.measure_kernel(t, x, y, theta, *args)
        if status == _kernels.BAD_RECORD:
            t, x, y, theta, sigma, n = self._checked(time_s, x_um, y_um, rotation_angle_rad, noise_um)
            status = _kernels.measure_kernel(t, x, y, theta, *args)
        duration, omega, speed_rpm, revolutions = kin.tolist()
        if status == _kernels.OK:
            px, py = out.tolist()
            return _reading(_probe(px), _probe(py), speed_rpm, revolutions, n, True)
        data = np.empty((n, 2))
        data[:, 0], data[:, 1] = x, y
        if status == _kernels.TOO_SLOW:
            return self._too_slow(t, data, speed_rpm, revolutions, n)
        # the band (almost) inside the nuisance span: numpy's SVD decides what it keeps
        return self._fit(t, data, theta, sigma, n, duration, omega, speed_rpm, revolutions)

    def measure_reference(
        self,
        time_s: np.ndarray,
        x_um: np.ndarray,
        y_um: np.ndarray,
        rotation_angle_rad: np.ndarray,
        noise_um: float = 0.0,
    ) -> MonitorReading:
        """:meth:`measure` by the numpy implementation (numpy's QR, SVD and solves): the reference of
        the compiled kernel (:mod:`gfb_env.machine._monitor_kernels`; they agree to ~1e-12), and what
        :meth:`measure` falls back on where the band may be rank-deficient."""
        t, x, y, theta, sigma, n = self._checked(time_s, x_um, y_um, rotation_angle_rad, noise_um)
        duration, omega, speed_rpm, revolutions = _kinematics(t, theta)
        data = np.empty((n, 2))
        data[:, 0], data[:, 1] = x, y
        if revolutions < self.min_revolutions:
            return self._too_slow(t, data, speed_rpm, revolutions, n)
        return self._fit(t, data, theta, sigma, n, duration, omega, speed_rpm, revolutions)

    def _fit(
        self, t: np.ndarray, data: np.ndarray, theta: np.ndarray, sigma: float, n: int,
        duration: float, omega: float, speed_rpm: float, revolutions: float,
    ) -> MonitorReading:  # fmt: skip
        """The numpy implementation of the filtered values (``data`` (n, 2))."""
        # --- the joint least-squares fit (columns scaled to O(1) for the conditioning) ----------
        tm = 0.5 * (t[0] + t[-1])
        s = (t - tm) / duration  # in [-1/2, 1/2]
        ph = theta - math.radians(self.keyphasor_angle_deg)
        ratios, ratios_scan = _ratios(
            self.subsynchronous_band_ratio, self.subsynchronous_frequencies, self.ratio_scan_step
        )
        band_phase = np.outer(omega * (t - t[0]), ratios)  # (n, K)
        k2 = 2 * len(ratios)
        # the columns written into one array (what np.column_stack builds, without its copies)
        A = np.empty((n, _N_NUISANCE + k2))
        A[:, 0] = 1.0
        A[:, 1] = s
        A[:, 2], A[:, 3] = np.cos(ph), np.sin(ph)
        ph2 = 2 * ph
        A[:, 4], A[:, 5] = np.cos(ph2), np.sin(ph2)
        band = A[:, _N_NUISANCE:]
        band[:, 0::2], band[:, 1::2] = np.cos(band_phase), np.sin(band_phase)
        band = band.copy()  # (the band columns alone, contiguous, as before)
        q, r = np.linalg.qr(A)
        coef = np.linalg.solve(r, q.T @ data)  # (p, 2)
        r_inv = np.linalg.solve(r, np.eye(r.shape[0]))
        cov = r_inv @ r_inv.T  # (A^T A)^-1: multiply by sigma^2
        fitted = A @ coef
        # (np.mean's sum and division by n, without its Python layer)
        residual_rms = np.sqrt(np.add.reduce((data - fitted) ** 2, axis=0) / n)

        # --- the dominant sub-synchronous ratio: one sinusoid scanned over the band ------------
        nuisance_q = q[:, :_N_NUISANCE]  # an orthonormal basis of the first 6 columns (QR is nested)
        power = _single_frequency_power(omega * (t - t[0]), ratios_scan, nuisance_q, data)  # (R, 2)

        probes = []
        # the band: the data's orthogonal projection onto the band columns made orthogonal to the
        # nuisance columns (mean, trend, 1x, 2x), so that the level never exceeds the signal
        band_q = _band_basis(band, nuisance_q)
        rank = band_q.shape[1]
        w = band_q.T @ data  # (rank, 2)
        floor = sigma * math.sqrt(rank / n)
        for j in range(2):
            c = coef[:, j]
            amp, lag, amp_std, lag_std = _vector(c[2], c[3], cov[2:4, 2:4], sigma)
            amp2 = math.hypot(c[4], c[5])
            level = math.sqrt(float(w[:, j] @ w[:, j]) / n)
            # sqrt(n) level = |w| is a non-central chi (rank degrees of freedom, scale sigma): its std
            # tends to sigma well above the floor (below sigma / sqrt 2 at it)
            level_std = sigma / math.sqrt(n)
            probes.append(
                ProbeVibration(
                    direct_um_pp=float(data[:, j].max() - data[:, j].min()),
                    synchronous_um_pp=2.0 * amp,
                    synchronous_phase_lag_deg=lag,
                    synchronous_um_pp_std=2.0 * amp_std,
                    synchronous_phase_lag_deg_std=lag_std,
                    second_harmonic_um_pp=2.0 * amp2,
                    subsynchronous_um_rms=level,
                    subsynchronous_um_rms_std=level_std,
                    subsynchronous_noise_floor_um_rms=floor,
                    subsynchronous_ratio=_peak(ratios_scan, power[:, j]),
                    mean_um=float(c[0]),
                    trend_um_per_s=float(c[1] / duration),
                    residual_um_rms=float(residual_rms[j]),
                )
            )
        return MonitorReading(probes[0], probes[1], speed_rpm, revolutions, n, True)

    def _checked(
        self, time_s: np.ndarray, x_um: np.ndarray, y_um: np.ndarray, rotation_angle_rad: np.ndarray,
        noise_um: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, int]:  # fmt: skip
        """:meth:`measure`'s checks of its arguments (the ``ValueError`` it documents); the float arrays,
        the angle unwrapped, the noise and the length."""
        t = _series("time_s", time_s)
        n = len(t)
        if n < self.min_samples:
            raise ValueError(f"time_s must have at least {self.min_samples} samples, got {n}")
        x, y = _series("x_um", x_um, n), _series("y_um", y_um, n)
        theta = _unwrap(_series("rotation_angle_rad", rotation_angle_rad, n))
        sigma = nonnegative("noise_um", noise_um)
        if not (t[1:] > t[:-1]).all():  # (np.diff's values, without its Python layer)
            raise ValueError("time_s must be strictly increasing")
        dth = theta[1:] - theta[:-1]
        if (dth < 0).any():
            raise ValueError("rotation_angle_rad must not decrease (the rotor turns one way)")
        if dth.max() > 0.5 * math.pi:
            raise ValueError(
                "rotation_angle_rad moves more than a quarter revolution between samples (2x above Nyquist)"
            )
        return t, x, y, theta, sigma, n

    def _too_slow(
        self, t: np.ndarray, data: np.ndarray, speed_rpm: float, revolutions: float, n: int
    ) -> MonitorReading:
        """The documented fallback below ``min_revolutions``: direct values only (mean + trend fit)."""
        duration = float(t[-1] - t[0])
        s = (t - 0.5 * (t[0] + t[-1])) / duration
        A = np.column_stack([np.ones(n), s])
        coef, *_ = np.linalg.lstsq(A, data, rcond=None)
        res = np.sqrt(np.mean((data - A @ coef) ** 2, axis=0))
        mid = 0.5 * sum(self.subsynchronous_band_ratio)
        probes = [
            ProbeVibration(
                float(data[:, j].max() - data[:, j].min()),
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                mid,
                float(coef[0, j]),
                float(coef[1, j] / duration),
                float(res[j]),
            )  # fmt: skip
            for j in range(2)
        ]
        return MonitorReading(probes[0], probes[1], speed_rpm, revolutions, n, False)


# ------------------------------------------------------------------------------------------------
_PROBE_FIELDS = tuple(ProbeVibration.__dataclass_fields__)
_READING_FIELDS = tuple(MonitorReading.__dataclass_fields__)


def _probe(row: list[float]) -> ProbeVibration:
    """``ProbeVibration(*row)`` without the frozen dataclass's per-field ``object.__setattr__`` (the
    kernel's row, the fields in order: the same object, a third of the cost; measure runs every step)."""
    p = object.__new__(ProbeVibration)
    p.__dict__.update(zip(_PROBE_FIELDS, row, strict=True))
    return p


def _reading(*values: object) -> MonitorReading:
    """``MonitorReading(*values)``, as :func:`_probe`."""
    r = object.__new__(MonitorReading)
    r.__dict__.update(zip(_READING_FIELDS, values, strict=True))
    return r


def _kinematics(t: np.ndarray, theta: np.ndarray) -> tuple[float, float, float, float]:
    """The record's duration (s), mean running speed (rad/s and rpm) and revolutions."""
    duration = float(t[-1] - t[0])
    sweep = float(theta[-1] - theta[0])
    omega = sweep / duration  # mean running speed, rad/s
    return duration, omega, omega * 60.0 / (2.0 * math.pi), sweep / (2.0 * math.pi)


def _series(name: str, v: np.ndarray, n: int | None = None) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {a.shape}")
    if n is not None and len(a) != n:
        raise ValueError(f"{name} must have as many samples as time_s ({n}), got {len(a)}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite")
    return a


def _unwrap(p: np.ndarray) -> np.ndarray:
    """``np.unwrap(p)`` of a finite 1-d series, bit for bit: where no step reaches pi it adds zero
    corrections (``p[1:] + 0.0``, which only turns a -0.0 into 0.0), so that case skips the rest of
    its work (a monitor's angles turn < a quarter revolution per sample)."""
    dd = p[1:] - p[:-1]
    if (np.abs(dd) < math.pi).all():
        up = p.copy()
        up[1:] += 0.0
        return up
    return np.unwrap(p)


def _vector(a: float, b: float, cov2: np.ndarray, sigma: float) -> tuple[float, float, float, float]:
    """Zero-to-peak amplitude, phase lag (deg, [0, 360)) of ``a cos + b sin = A cos(theta - lag)`` and
    their delta-method standard deviations (the phase's capped at that of a uniform phase)."""
    amp = math.hypot(a, b)
    lag = math.degrees(math.atan2(b, a)) % 360.0
    if sigma == 0.0:
        return amp, lag, 0.0, 0.0
    if amp > 0:
        g = np.array([a, b]) / amp
        h = np.array([-b, a]) / (amp * amp)
        amp_std = sigma * math.sqrt(max(float(g @ cov2 @ g), 0.0))
        lag_std = min(sigma * math.sqrt(max(float(h @ cov2 @ h), 0.0)), _UNIFORM_PHASE_STD_RAD)
    else:
        amp_std = sigma * math.sqrt(max(0.5 * float(np.trace(cov2)), 0.0))
        lag_std = _UNIFORM_PHASE_STD_RAD
    return amp, lag, amp_std, math.degrees(lag_std)


def _band_basis(band: np.ndarray, nuisance_q: np.ndarray) -> np.ndarray:
    """An orthonormal basis (n, r) of the band columns' part orthogonal to the nuisance columns
    (orthonormal ``nuisance_q``); directions of the band (almost) inside the nuisance span are dropped."""
    perp = band - nuisance_q @ (nuisance_q.T @ band)
    u, sv, _ = np.linalg.svd(perp, full_matrices=False)
    # the columns' norms as np.linalg.norm(band, axis=0) computes them for real input (the root of
    # the summed squares), without its Python layer
    scale = np.sqrt(np.add.reduce(band * band, axis=0)).max()
    return u[:, sv > 1e-8 * scale]


@functools.lru_cache(maxsize=16)
def _ratios(band: tuple[float, float], k: int, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The band's K column ratios (its middle if K = 1) and the dominant-ratio scan grid of a monitor
    configuration, computed once (read-only: every measure uses them)."""
    lo, hi = band
    cols = np.array([0.5 * (lo + hi)]) if k == 1 else np.linspace(lo, hi, k)
    scan = _scan_grid(band, step)
    cols.flags.writeable = scan.flags.writeable = False
    return cols, scan


def _scan_grid(band: tuple[float, float], step: float) -> np.ndarray:
    lo, hi = band
    m = int(math.floor((hi - lo) / step + 1e-9)) + 1
    return lo + step * np.arange(m)


def _single_frequency_power(
    phase_per_ratio: np.ndarray, ratios: np.ndarray, nuisance_q: np.ndarray, data: np.ndarray
) -> np.ndarray:
    """For each ratio r: the squared norm of the data's projection onto (cos, sin)(r Omega t) after the
    nuisance columns (orthonormal ``nuisance_q``) are removed from both.  Shape (R, 2)."""
    # plain matrix products and the 2x2 solve in closed form (batched einsums and solves cost ~1 ms;
    # this ~0.1 ms, the same numbers to rounding).  The reference path only: measure() runs the kernel
    ang = np.outer(ratios, phase_per_ratio)  # (R, n)
    c, s = np.cos(ang), np.sin(ang)
    c -= (c @ nuisance_q) @ nuisance_q.T
    s -= (s @ nuisance_q) @ nuisance_q.T
    resid = data - nuisance_q @ (nuisance_q.T @ data)  # (n, 2)
    gcc, gss, gcs = (c * c).sum(axis=1), (s * s).sum(axis=1), (c * s).sum(axis=1)  # (R,)
    vc, vs = c @ resid, s @ resid  # (R, 2): probe columns
    det = (gcc * gss - gcs * gcs)[:, None]
    return (gss[:, None] * vc * vc - 2.0 * gcs[:, None] * vc * vs + gcc[:, None] * vs * vs) / det


def _peak(ratios: np.ndarray, power: np.ndarray) -> float:
    """The grid maximum refined by a parabola through it and its neighbours (the grid point at an edge)."""
    k = int(np.argmax(power))
    if 0 < k < len(ratios) - 1:
        p0, p1, p2 = power[k - 1], power[k], power[k + 1]
        den = p0 - 2.0 * p1 + p2
        if den < 0:
            off = 0.5 * (p0 - p2) / den
            return float(ratios[k] + max(-0.5, min(0.5, off)) * (ratios[1] - ratios[0]))
    return float(ratios[k])
