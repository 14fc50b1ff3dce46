"""Two eddy-current proximity probes, X and Y, 45 degrees either side of the vertical.

As on real machines (API 670), the probes look at the journal from above, at 45 degrees left and right
of the top: neither sits on the gravity axis, where the static deflection of the journal would eat
into the probes' linear range, and the pair is orthogonal, so the orbit is the two signals plotted
against each other.  Each probe reads the journal's displacement *toward* it (the gap shrinking gives
a positive reading), in micrometres, with a bias (calibration and zero-reference offset, thermal
drift) and Gaussian noise (electronics noise at the probe's bandwidth) per sample.

Geometry, in the model's frame (xi horizontal, eta vertical and positive *downward*, along gravity;
lengths in units of the clearance C): a probe at the angle ``beta`` from the *upward* vertical,
positive toward +xi, has the unit vector ``u = (sin beta, -cos beta)`` pointing from the bearing centre
to the probe, and reads ``C (u . (xi, eta)) + bias + noise``.  Defaults: X at ``beta = +45 deg``,
Y at ``beta = -45 deg``.

The probes sample at the integrator's recording grid (120 samples per control step).  The observation
is built from the readings by the controller's signal conditioning (the inverse of the probe geometry,
then the observation scales):

* position: the last sample of the step;
* envelope (extent of xi and eta): max - min over the step's samples;
* velocity: the least-squares slope over the last ``velocity_window`` samples.

:meth:`ProximityProbes.measurement_errors` returns what the readings add to the truth in each of those
channels (in the xi/eta frame, um and um/s): the env adds it to the exact values it has always
observed, so that an ideal probe (no noise, no bias) reproduces the exact observation bit for bit.  For
the velocity this leaves out the estimator's own truncation error (the slope of a line through 5
samples 0.5 tau apart of a whirl of period ~25 tau): only its noise is modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from gfb_env.machine._checks import finite, is_number, nonnegative

__all__ = ["ProximityProbes", "ProbeErrors"]


@dataclass(frozen=True)
class ProbeErrors:
    """What the probe readings add to the true journal motion over one control step.

    Attributes:
        position_um: (xi, eta) error of the position at the last sample, um.
        velocity_um_per_s: (xi', eta') error of the velocity estimate, um/s.
        extent_um: (xi, eta) error of the orbit extent (max - min) over the step, um.
        noise_um: the (X, Y) noise of the last sample, um (the bias is the episode's).
    """

    position_um: np.ndarray
    velocity_um_per_s: np.ndarray
    extent_um: np.ndarray
    noise_um: np.ndarray


@dataclass(frozen=True)
class ProximityProbes:
    """Two proximity probes (X, Y) with bias and Gaussian noise (see the module docstring).

    The defaults are a realistic pair (``docs/machine.md``); :meth:`ideal` is the exact sensor.

    Attributes:
        noise_um: standard deviation of the noise of one sample of one probe, um (default 0.3: a
            commercial eddy-current system of ~1-2 mm range at ~10 kHz bandwidth resolves 0.1-0.5 um).
        bias_um: fixed offset (X, Y) of the readings, um (default (0, 0)).
        bias_spread_um: standard deviation of a per-episode offset drawn for each probe (from the env's
            ``np_random``) on top of ``bias_um``, um (default 1.0: zero reference set cold, thermal
            drift of the gap and the target's runout are each ~1 um on a 50 um clearance).
        x_angle_deg, y_angle_deg: probe angles from the upward vertical, positive toward +xi
            (default +45 and -45); they must not be parallel.
        velocity_window: samples in the least-squares velocity estimate (default 5: 2.5 tau, a tenth of
            a whirl period, with 60-tau control steps).
    """

    noise_um: float = 0.3
    bias_um: tuple[float, float] = (0.0, 0.0)
    bias_spread_um: float = 1.0
    x_angle_deg: float = 45.0
    y_angle_deg: float = -45.0
    velocity_window: int = 5

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "noise_um", nonnegative("noise_um", self.noise_um))
        try:
            bx, by = self.bias_um
        except (TypeError, ValueError):
            raise ValueError(f"bias_um must be a pair (X, Y), got {self.bias_um!r}") from None
        put(self, "bias_um", (finite("bias_um", bx), finite("bias_um", by)))
        put(self, "bias_spread_um", nonnegative("bias_spread_um", self.bias_spread_um))
        put(self, "x_angle_deg", finite("x_angle_deg", self.x_angle_deg))
        put(self, "y_angle_deg", finite("y_angle_deg", self.y_angle_deg))
        if abs(math.sin(math.radians(self.x_angle_deg - self.y_angle_deg))) < 0.1:
            raise ValueError(
                f"x_angle_deg and y_angle_deg must be at least ~6 degrees from parallel, got "
                f"{self.x_angle_deg!r} and {self.y_angle_deg!r}"
            )
        w = self.velocity_window
        if not (is_number(w) and float(w).is_integer() and 2 <= w <= 1000):
            raise ValueError(f"velocity_window must be an integer in [2, 1000], got {w!r}")
        put(self, "velocity_window", int(w))

    @classmethod
    def ideal(cls) -> ProximityProbes:
        """No noise, no bias: the exact observation."""
        return cls(noise_um=0.0, bias_um=(0.0, 0.0), bias_spread_um=0.0)

    @property
    def is_ideal(self) -> bool:
        return self.noise_um == 0.0 and self.bias_um == (0.0, 0.0) and self.bias_spread_um == 0.0

    @cached_property
    def directions(self) -> np.ndarray:
        """Rows: the unit vectors (xi, eta components) from the bearing centre to the X and Y probes
        (computed once: the probes are read every control step)."""
        b = np.radians([self.x_angle_deg, self.y_angle_deg])
        return np.stack([np.sin(b), -np.cos(b)], axis=1)

    @cached_property
    def _inverse_directions(self) -> np.ndarray:
        """``np.linalg.inv(directions)``, computed once (read-only: every step's errors use it)."""
        inv = np.linalg.inv(self.directions)
        inv.flags.writeable = False
        return inv

    def read_um(
        self, xi_um: np.ndarray | float, eta_um: np.ndarray | float, bias_um: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free readings (X, Y) in um of the journal displacement ``(xi_um, eta_um)`` (um; eta
        downward), plus ``bias_um`` (default: the fixed ``bias_um``)."""
        u = self.directions
        b = np.asarray(self.bias_um if bias_um is None else bias_um, dtype=float)
        xi, eta = np.asarray(xi_um, dtype=float), np.asarray(eta_um, dtype=float)
        return u[0, 0] * xi + u[0, 1] * eta + b[0], u[1, 0] * xi + u[1, 1] * eta + b[1]

    def displacement_um(self, x_um: np.ndarray, y_um: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The inverse of the geometry: (xi, eta) in um from readings (X, Y) in um (bias not removed)."""
        inv = np.linalg.inv(self.directions)
        x, y = np.asarray(x_um, dtype=float), np.asarray(y_um, dtype=float)
        return inv[0, 0] * x + inv[0, 1] * y, inv[1, 0] * x + inv[1, 1] * y

    def draw_bias(self, rng: np.random.Generator) -> np.ndarray:
        """This episode's (X, Y) bias in um: ``bias_um`` plus, if ``bias_spread_um > 0``, a Gaussian
        draw per probe from ``rng`` (no draw otherwise)."""
        b = np.array(self.bias_um, dtype=float)
        if self.bias_spread_um > 0:
            b = b + self.bias_spread_um * rng.standard_normal(2)
        return b

    def readings_um(
        self, rng: np.random.Generator, xi_um: np.ndarray, eta_um: np.ndarray, bias_um: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The measured readings (X, Y) in um of every sample of a journal record ``xi_um``, ``eta_um``
        (um): the geometry, this episode's ``bias_um`` and, if ``noise_um > 0``, white Gaussian noise
        drawn from ``rng`` (rows: samples, columns: X, Y, as :meth:`measurement_errors` draws it).  What
        the vibration monitor (:mod:`gfb_env.machine.monitor`) takes; the v1 observation does not use it."""
        xi_um, eta_um = np.asarray(xi_um, dtype=float), np.asarray(eta_um, dtype=float)
        x, y = self.read_um(xi_um, eta_um, bias_um)
        if self.noise_um == 0.0:
            return x, y
        noise = self.noise_um * rng.standard_normal((len(xi_um), 2))
        return x + noise[:, 0], y + noise[:, 1]

    def measurement_errors(
        self,
        rng: np.random.Generator,
        xi_um: np.ndarray,
        eta_um: np.ndarray,
        sample_interval_s: float,
        bias_um: np.ndarray,
    ) -> ProbeErrors:
        """The errors of the observed channels for one control step whose true journal samples are
        ``xi_um``, ``eta_um`` (um, at ``sample_interval_s``; the last one is the step's end).

        Noise is drawn (from ``rng``) only if ``noise_um > 0``: ``2 max(n, velocity_window)`` normal
        numbers, one per probe and sample; before the first sample of an episode the probes were
        sampling too, so a short record is padded with earlier noise samples for the velocity."""
        xi_um, eta_um = np.asarray(xi_um, dtype=float), np.asarray(eta_um, dtype=float)
        n = len(xi_um)
        if n < 1:
            raise ValueError("measurement_errors needs at least one sample")
        return self.errors_of_noise(self.draw_noise(rng, n), xi_um, eta_um, sample_interval_s, bias_um)

    def draw_noise(self, rng: np.random.Generator, n: int) -> np.ndarray | None:
        """The white noise of a step of ``n`` samples, um: ``(max(n, velocity_window), 2)`` (rows:
        samples, columns: X, Y; a short record is padded with earlier samples for the velocity), or
        None (and no draw) for noise-free probes."""
        if self.noise_um == 0.0:
            return None
        return self.noise_um * rng.standard_normal((max(n, self.velocity_window), 2))

    def errors_of_noise(
        self,
        noise: np.ndarray | None,
        xi_um: np.ndarray,
        eta_um: np.ndarray,
        sample_interval_s: float,
        bias_um: np.ndarray,
    ) -> ProbeErrors:
        """:meth:`measurement_errors` for a given draw ``noise`` (rows: the ``max(n, velocity_window)``
        samples, the last ``n`` those of the record; columns X, Y; um; None: noise-free probes).  One
        draw then serves every channel: the v2 interface takes the same noise for the vibration
        monitor's sample readings (:mod:`gfb_env.envs.interface_v2`)."""
        xi_um, eta_um = np.asarray(xi_um, dtype=float), np.asarray(eta_um, dtype=float)
        n = len(xi_um)
        inv = self._inverse_directions
        bias_xe = inv @ np.asarray(bias_um, dtype=float)
        if noise is None:
            zero = np.zeros(2)
            return ProbeErrors(bias_xe, zero, zero.copy(), zero.copy())
        m = len(noise)
        if m != max(n, self.velocity_window) or noise.shape != (m, 2):
            raise ValueError(
                f"noise must have shape ({max(n, self.velocity_window)}, 2), got {np.shape(noise)}"
            )
        noise_xe = noise @ inv.T  # the same noise in the (xi, eta) frame
        # extent: (max - min) of the measured samples minus that of the true ones
        tail = noise_xe[m - n :]
        extent = np.empty(2)
        for k, true in enumerate((xi_um, eta_um)):
            meas = true + tail[:, k]
            extent[k] = (meas.max() - meas.min()) - (true.max() - true.min())
        # velocity: least-squares slope of the noise over the last velocity_window samples
        w = self.velocity_window
        t = (np.arange(w) - 0.5 * (w - 1)) * sample_interval_s
        slope = (t @ noise_xe[m - w :]) / float(t @ t)
        return ProbeErrors(bias_xe + noise_xe[-1], slope, extent, noise[-1].copy())
