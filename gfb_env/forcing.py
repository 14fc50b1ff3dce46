"""External forcing of the rotor equations: mass unbalance and half-sine base shocks.

Both enter the rotor equations only as an acceleration added to ``xi''`` and ``eta''`` (a function of
time, not of the state): they are linear in the forcing, leave the Jacobian unchanged, and are zero
when the forcing is off.

Derivation of the unbalance term (signs).  Per bearing, lengths in units of the clearance C, time
``tau = t / T``.  The frame is the paper's: ``xi`` horizontal, ``eta`` along gravity (downward), the
attitude angle measured from the downward vertical toward +xi, which is also the sense of rotation
(the Couette term ``-Lambda d/dphi(P H)`` of Eq. 4 carries the gas toward increasing phi, and phi is
measured from the eta axis toward the xi axis: ``H = 1 - xi sin(phi) - eta cos(phi)``).  Let the rotor
(mass m per bearing) have its centre of mass at the distance ``e_G = m_u e / m`` from the journal centre,
at the rotation angle theta measured the same way::

    r_G = C (xi, eta) + e_G (sin theta, cos theta)

Newton's law for the whole rotor, ``m r_G'' = F_bearing + m (g + F_L/m) e_eta``, gives for the journal
centre ``m C (xi, eta)'' = F + m g_mod e_eta - m e_G (sin theta, cos theta)''`` and, with
``(sin theta)'' = theta'' cos theta - theta'^2 sin theta`` and ``(cos theta)'' = -theta'' sin theta -
theta'^2 cos theta``, after dividing by ``m C / T^2``::

    xi''  = -f_xi/M      + U (theta'^2 sin theta - theta'' cos theta)
    eta'' = G - f_eta/M  + U (theta'^2 cos theta + theta'' sin theta),     U = e_G / C = m_u e / (m C)

with ``theta' = omega T = Lambda`` and ``theta'' = dLambda/dtau``: the signs of issue 10 and of the
design notes (sect. 7).  At constant speed the forcing ``U Lambda^2 (sin theta, cos theta)`` points from
the journal centre toward the unbalance mass (the centrifugal force), as it must.

Base shock.  If the housing (base) moves with ``r_B(t)``, the bearing force depends on the journal
position relative to it, ``C (xi, eta) = r_J - r_B``, so the relative coordinates gain ``-a_B(t)``.  A
half-sine pulse ``a_B = A sin(pi (tau - tau_0) / d) (sin beta, cos beta)`` for ``tau_0 <= tau <=
tau_0 + d`` (zero outside) accelerates the base in the direction ``beta`` measured like the attitude
angle; ``A`` is in units of ``C / T^2``.

Physical units.  ``U`` is the eccentricity of the centre of mass in clearances.  For the paper's symmetric
rotor (two equal bearings, each carrying half the rotor mass; the static unbalance ``m_u e`` of the
rotor split equally between the two bearing planes) ``U = (m_u e / 2) / ((m / 2) C) = m_u e / (m C)``
with the *rotor* unbalance ``m_u e`` and the *rotor* mass ``m``.  The default rotor mass is twice
``BearingParameters.rotor_mass_per_bearing_kg`` (the paper's ``m`` is half the rotor mass).  The balance
grade of ISO 1940-1 / ISO 21940-11 is ``G = e_per omega`` (mm/s), so ``U = G / (omega C)`` whatever the
mass; the mass only converts it to g mm (``U_per = m e_per``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from gfb_env.params import BearingParameters, check_positive

__all__ = [
    "Unbalance",
    "HalfSineShock",
    "unbalance_acceleration",
    "half_sine_acceleration",
    "shock_acceleration",
    "rotation_angle",
    "STANDARD_GRAVITY_M_S2",
]

#: The unit "g" of shock peaks (standard gravity, not the bearing's ``gravity_m_s2``).
STANDARD_GRAVITY_M_S2 = 9.80665


def _finite(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


def _rotor_mass_kg(bearing: BearingParameters, rotor_mass_kg: float | None) -> float:
    if rotor_mass_kg is None:
        return 2.0 * bearing.rotor_mass_per_bearing_kg  # the paper's m is half the rotor mass
    return check_positive("rotor_mass_kg", rotor_mass_kg)


@dataclass(frozen=True)
class Unbalance:
    """A mass unbalance: ``magnitude`` U = m_u e / (m C) (centre-of-mass eccentricity in clearances)
    at the angle ``phase_rad`` ahead of the rotation angle theta (the forcing uses theta + phase).

    Validated on construction (``ValueError`` naming the field): U finite and >= 0, the phase finite.
    """

    magnitude: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        u = _finite("magnitude", self.magnitude)
        if u < 0:
            raise ValueError(f"magnitude must be non-negative, got {self.magnitude!r}")
        object.__setattr__(self, "magnitude", u)
        object.__setattr__(self, "phase_rad", _finite("phase_rad", self.phase_rad))

    # --- physical units (see the module docstring for the mass convention) --------------------
    @classmethod
    def from_mass_radius(
        cls,
        bearing: BearingParameters,
        mass_radius_g_mm: float,
        rotor_mass_kg: float | None = None,
        phase_rad: float = 0.0,
    ) -> Unbalance:
        """From the rotor's static unbalance ``m_u e`` in g mm: ``U = m_u e / (m C)``, ``m`` the rotor
        mass (default ``2 * bearing.rotor_mass_per_bearing_kg``)."""
        ue = _finite("mass_radius_g_mm", mass_radius_g_mm)
        if ue < 0:
            raise ValueError(f"mass_radius_g_mm must be non-negative, got {mass_radius_g_mm!r}")
        m = _rotor_mass_kg(bearing, rotor_mass_kg)
        return cls(ue * 1e-6 / (m * bearing.clearance_m), phase_rad)  # g mm = 1e-6 kg m

    def mass_radius_g_mm(self, bearing: BearingParameters, rotor_mass_kg: float | None = None) -> float:
        """Inverse of :meth:`from_mass_radius`."""
        return self.magnitude * _rotor_mass_kg(bearing, rotor_mass_kg) * bearing.clearance_m * 1e6

    @classmethod
    def from_iso1940(
        cls,
        bearing: BearingParameters,
        grade_mm_s: float,
        speed_rpm: float,
        rotor_mass_kg: float | None = None,
        phase_rad: float = 0.0,
    ) -> Unbalance:
        """From an ISO 1940-1 / 21940-11 balance grade G (mm/s; G 2.5 -> 2.5) at ``speed_rpm``: the
        permissible specific unbalance ``e_per = G / omega`` is the centre-of-mass eccentricity, so
        ``U = e_per / C``.  ``rotor_mass_kg`` is checked but does not change U (see the module
        docstring)."""
        g = check_positive("grade_mm_s", grade_mm_s)
        n = check_positive("speed_rpm", speed_rpm)
        _rotor_mass_kg(bearing, rotor_mass_kg)
        omega = n * 2.0 * math.pi / 60.0
        return cls(g * 1e-3 / omega / bearing.clearance_m, phase_rad)

    def iso1940_grade_mm_s(self, bearing: BearingParameters, speed_rpm: float) -> float:
        """Inverse of :meth:`from_iso1940`: the grade ``G = e omega`` in mm/s at ``speed_rpm``."""
        n = check_positive("speed_rpm", speed_rpm)
        return self.magnitude * bearing.clearance_m * n * 2.0 * math.pi / 60.0 * 1e3

    def eccentricity_um(self, bearing: BearingParameters) -> float:
        """The centre-of-mass eccentricity ``e = U C`` in micrometres."""
        return bearing.micrometres(self.magnitude)


@dataclass(frozen=True)
class HalfSineShock:
    """A half-sine acceleration pulse of the base (housing), nondimensional.

    Attributes:
        start_tau: pulse start.
        duration_tau: pulse length d (> 0).
        peak_acceleration: peak base acceleration A in units of ``C / T^2`` (>= 0).
        direction_rad: direction of the base acceleration, from the downward vertical toward +xi.
    """

    start_tau: float
    duration_tau: float
    peak_acceleration: float
    direction_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "start_tau", _finite("start_tau", self.start_tau))
        object.__setattr__(self, "duration_tau", check_positive("duration_tau", self.duration_tau))
        a = _finite("peak_acceleration", self.peak_acceleration)
        if a < 0:
            raise ValueError(f"peak_acceleration must be non-negative, got {self.peak_acceleration!r}")
        object.__setattr__(self, "peak_acceleration", a)
        object.__setattr__(self, "direction_rad", _finite("direction_rad", self.direction_rad))

    @property
    def end_tau(self) -> float:
        return self.start_tau + self.duration_tau

    @property
    def velocity_change(self) -> float:
        """``int a_B dtau = 2 A d / pi``: the base velocity change (units of C / T); the journal's
        relative velocity changes by minus this while the pulse is short against the bearing's
        response."""
        return 2.0 * self.peak_acceleration * self.duration_tau / math.pi

    @classmethod
    def from_physical(
        cls,
        bearing: BearingParameters,
        start_s: float,
        peak_g: float,
        duration_ms: float,
        direction_deg: float = 0.0,
    ) -> HalfSineShock:
        """From the start in s, the peak in g (9.80665 m/s^2), the duration in ms and the direction in
        degrees (from the downward vertical toward +xi): ``A = a T^2 / C``, ``tau = t / T``."""
        start = _finite("start_s", start_s)
        peak = _finite("peak_g", peak_g)
        if peak < 0:
            raise ValueError(f"peak_g must be non-negative, got {peak_g!r}")
        dur = check_positive("duration_ms", duration_ms)
        direction = _finite("direction_deg", direction_deg)
        T = bearing.time_scale_s
        return cls(
            start_tau=start / T,
            duration_tau=dur * 1e-3 / T,
            peak_acceleration=peak * STANDARD_GRAVITY_M_S2 * T * T / bearing.clearance_m,
            direction_rad=math.radians(direction),
        )

    def peak_g(self, bearing: BearingParameters) -> float:
        """Inverse of :meth:`from_physical` for the peak."""
        T = bearing.time_scale_s
        return self.peak_acceleration * bearing.clearance_m / (T * T) / STANDARD_GRAVITY_M_S2

    def duration_ms(self, bearing: BearingParameters) -> float:
        return self.duration_tau * bearing.time_scale_s * 1e3

    def as_row(self) -> tuple[float, float, float, float]:
        """``(start, duration, A sin beta, A cos beta)``: the row the compiled integrator takes."""
        a = self.peak_acceleration
        return (
            self.start_tau,
            self.duration_tau,
            a * math.sin(self.direction_rad),
            a * math.cos(self.direction_rad),
        )


# --- the forcing terms (compiled; also callable from Python) -------------------------------------
@njit(cache=True)
def unbalance_acceleration(u, theta, theta_dot, theta_ddot):
    """``(dxi'', deta'')`` of an unbalance ``u`` at the angle ``theta`` (incl. the phase):
    ``u (theta'^2 sin theta - theta'' cos theta, theta'^2 cos theta + theta'' sin theta)``."""
    sn = math.sin(theta)
    cs = math.cos(theta)
    w2 = theta_dot * theta_dot
    return u * (w2 * sn - theta_ddot * cs), u * (w2 * cs + theta_ddot * sn)


@njit(cache=True)
def half_sine_acceleration(tau, start, duration, peak):
    """The pulse ``peak sin(pi (tau - start)/duration)`` on ``[start, start + duration]``, else 0."""
    x = (tau - start) / duration
    if x <= 0.0 or x >= 1.0:
        return 0.0
    return peak * math.sin(math.pi * x)


@njit(cache=True)
def shock_acceleration(tau, shocks):
    """``(dxi'', deta'')`` of the base shocks at ``tau``: minus the base acceleration (relative
    coordinates).  ``shocks`` rows: :meth:`HalfSineShock.as_row`."""
    ax = 0.0
    ay = 0.0
    for k in range(shocks.shape[0]):
        x = (tau - shocks[k, 0]) / shocks[k, 1]
        if 0.0 < x < 1.0:
            w = math.sin(math.pi * x)
            ax -= w * shocks[k, 2]
            ay -= w * shocks[k, 3]
    return ax, ay


def rotation_angle(theta0: float, lam0: float, lam_rate: float, dtau: float) -> float:
    """theta after ``dtau`` when Lambda ramps linearly from ``lam0`` at the rate ``lam_rate``:
    ``theta0 + lam0 dtau + lam_rate dtau^2 / 2`` (exact: theta' = Lambda)."""
    return theta0 + lam0 * dtau + 0.5 * lam_rate * dtau * dtau
