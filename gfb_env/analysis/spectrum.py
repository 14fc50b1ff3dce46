"""Amplitude spectra of uniformly sampled trajectories (paper Fig. 7).

For samples ``x_k = x(tau_0 + k dtau)``, ``k = 0..N-1`` (the last ``fraction`` of the record, where the
orbit has settled), the one-sided amplitude spectrum is

    A(omega_j) = 2 / sum(w) |sum_k w_k (x_k - mean(x)) exp(-i omega_j k dtau)|,
    omega_j = 2 pi j / (N dtau),

with the Hann window ``w_k = sin^2(pi k / N)`` (Harris, Proc. IEEE 66, 1978), so a sinusoid of amplitude
``a`` shows a peak of height ``a``.  Frequencies are *angular* (rad per unit tau) so that they compare
directly with the bearing number ``Lambda = omega_0 T`` (the rotor's angular speed in the same units):
the whirl of the paper has ``omega / Lambda ~ 1/2``.  The peak is refined by quadratic interpolation of
the log-amplitude over the three bins around the maximum (Gasior & Gonzalez, CERN-AB-2004-023).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AmplitudeSpectrum", "DominantFrequency", "amplitude_spectrum", "dominant_frequency"]


@dataclass(frozen=True)
class AmplitudeSpectrum:
    """One-sided amplitude spectrum: angular frequencies ``omega`` (rad per unit tau), amplitudes."""

    omega: np.ndarray
    amplitude: np.ndarray


@dataclass(frozen=True)
class DominantFrequency:
    """The strongest spectral line.

    Attributes:
        omega: angular frequency (rad per unit tau).
        amplitude: its amplitude (Hann-window corrected).
        period: ``2 pi / omega``.
        ratio: ``omega / Lambda`` when a bearing number was given, else NaN.
    """

    omega: float
    amplitude: float
    period: float
    ratio: float


def _check(signal: np.ndarray, sample_interval: float, fraction: float) -> tuple[np.ndarray, float]:
    x = np.asarray(signal, dtype=float).ravel()
    if not (math.isfinite(sample_interval) and sample_interval > 0):
        raise ValueError(f"sample_interval must be finite and positive, got {sample_interval!r}")
    if not (0 < fraction <= 1):
        raise ValueError(f"fraction must be in (0, 1], got {fraction!r}")
    n = int(round(len(x) * fraction))
    if n < 8:
        raise ValueError(f"signal too short: {n} samples in the analysed part (need >= 8)")
    x = x[len(x) - n :]
    if not np.all(np.isfinite(x)):
        raise ValueError("signal must be finite")
    return x, float(sample_interval)


def amplitude_spectrum(
    signal: np.ndarray, sample_interval: float, fraction: float = 0.5
) -> AmplitudeSpectrum:
    """Hann-windowed one-sided amplitude spectrum of the last ``fraction`` of a uniformly sampled signal.

    Args:
        signal: samples, uniformly spaced in tau.
        sample_interval: ``dtau`` between samples.
        fraction: the trailing part of the signal analysed (transients are in the first part).
    """
    x, dt = _check(signal, sample_interval, fraction)
    n = len(x)
    w = np.sin(np.pi * np.arange(n) / n) ** 2
    X = np.fft.rfft((x - x.mean()) * w)
    amp = 2.0 * np.abs(X) / w.sum()
    omega = 2.0 * np.pi * np.fft.rfftfreq(n, dt)
    return AmplitudeSpectrum(omega=omega, amplitude=amp)


def dominant_frequency(
    signal: np.ndarray,
    sample_interval: float,
    fraction: float = 0.5,
    bearing_number: float | None = None,
) -> DominantFrequency:
    """The strongest non-zero spectral line of :func:`amplitude_spectrum`, refined between bins.

    Args:
        signal, sample_interval, fraction: see :func:`amplitude_spectrum`.
        bearing_number: ``Lambda``; when given, ``ratio = omega / Lambda``.
    """
    spec = amplitude_spectrum(signal, sample_interval, fraction)
    a = spec.amplitude
    if len(a) < 3 or not np.any(a[1:] > 0):
        raise ValueError("signal has no oscillating part")
    j = 1 + int(np.argmax(a[1:]))
    dw = spec.omega[1] - spec.omega[0]
    omega, amp = spec.omega[j], a[j]
    if 1 <= j < len(a) - 1 and min(a[j - 1], a[j + 1]) > 0:
        la, lb, lc = np.log(a[j - 1]), np.log(a[j]), np.log(a[j + 1])
        den = la - 2 * lb + lc
        if den < 0:
            p = 0.5 * (la - lc) / den
            omega = spec.omega[j] + p * dw
            amp = float(np.exp(lb - 0.25 * (la - lc) * p))
    ratio = math.nan
    if bearing_number is not None:
        if not (math.isfinite(bearing_number) and bearing_number > 0):
            raise ValueError(f"bearing_number must be finite and positive, got {bearing_number!r}")
        ratio = omega / bearing_number
    period = float(2 * math.pi / omega)
    return DominantFrequency(omega=float(omega), amplitude=float(amp), period=period, ratio=float(ratio))
