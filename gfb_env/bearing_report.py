"""Design summary of a bearing file: derived groups, load figures and sanity warnings (``gfb bearing``).

Layer: uses only :mod:`gfb_env.params`.  Every warning states its formula and source; they are
rules of thumb from the foil-bearing literature and industry, meant to flag a bearing file with a
typo or a design far from practice, not to replace a design analysis.

* **Specific (projected-area) load** ``w = W / (L D)`` with ``D = 2 R`` and the static load per
  bearing ``W = m g + F_L``.  Barber-Nichols' foil-bearing application guide ("Gas bearing
  applications", barber-nichols.com) lists as lower risk a start-up load below 5 psi (34 kPa) and an
  operating static + dynamic radial load below 20 psi (140 kPa), more challenging above 50 psi
  (340 kPa).  The start-up limit matters because the foil carries ``W`` in sliding contact until
  lift-off.
* **DellaCorte's rule of thumb** (DellaCorte & Valco, "Load capacity estimation of foil air journal
  bearings for oil-free turbomachinery applications", Tribology Transactions 43(4), 2000, NASA
  TM-2000-209782): ``W_max = D_c (L D)(D Omega)`` with ``L, D`` in inches, ``Omega`` in krpm and
  ``W_max`` in lbf; the load capacity coefficient ``D_c`` is about 0.1 lbf/(in^3 krpm) for
  first-generation bump foils (0.5 for the second, about 1 for the third generation).  In SI
  ``1 lbf/(in^3 krpm) = 271 447 N/(m^3 krpm)``.
* **Clearance ratio** ``C / R``: hydrodynamic gas bearings are usually built with ``C/R`` of order
  1e-3 (Table 1: 2.6e-3); outside [5e-4, 5e-3] the file probably has a unit slip.  The model itself
  refuses ``C/R >= 0.02`` (its film equation linearises in ``C/R``).
* **Surface speed** ``U = Omega R`` at the nominal speed: the same guide gives 150-225 m/s as lower
  risk, below 30 m/s or above 305 m/s as challenging.

The *static load ratio* reported is ``W / (p0 L D)``: the specific load over the ambient pressure
(a self-acting gas bearing's load scale is ``p0 L D``; the model's nondimensional load ``M G`` is the
same ratio with ``p0 R L``, i.e. twice it).
"""

from __future__ import annotations

import math

from gfb_env.params import BearingParameters

__all__ = [
    "DELLACORTE_GEN1_LBF_IN3_KRPM",
    "LBF_IN3_KRPM_TO_SI",
    "bearing_report",
    "dellacorte_load_capacity_n",
]

#: DellaCorte & Valco (2000): load capacity coefficient of first-generation bump foil bearings.
DELLACORTE_GEN1_LBF_IN3_KRPM = 0.1
#: 1 lbf/(in^3 krpm) in N/(m^3 krpm): 4.448222 N / (0.0254 m)^3.
LBF_IN3_KRPM_TO_SI = 4.4482216152605 / 0.0254**3
#: Barber-Nichols application guide: start-up and operating specific loads (Pa).
STARTUP_SPECIFIC_LOAD_PA = 34e3
OPERATING_SPECIFIC_LOAD_PA = 140e3
CHALLENGING_SPECIFIC_LOAD_PA = 340e3
#: Usual clearance ratios of gas foil bearings.
CLEARANCE_RATIO_RANGE = (5e-4, 5e-3)
#: Barber-Nichols application guide: shaft surface speeds (m/s).
SURFACE_SPEED_LOW_RISK = (150.0, 225.0)
SURFACE_SPEED_CHALLENGING = (30.0, 305.0)


def dellacorte_load_capacity_n(
    b: BearingParameters, speed_rpm: float, coefficient: float = DELLACORTE_GEN1_LBF_IN3_KRPM
) -> float:
    """``W_max = D_c (L D)(D Omega)`` in newtons (``D_c`` in lbf/(in^3 krpm), default first generation)."""
    d = 2.0 * b.radius_m
    return coefficient * LBF_IN3_KRPM_TO_SI * (b.length_m * d) * d * (speed_rpm / 1000.0)


def bearing_report(b: BearingParameters, speed_rpm: float | None = None) -> dict:
    """Derived groups, load figures and warnings of a bearing at ``speed_rpm`` (default: its own).

    Keys: the groups ``time_scale_s``, ``bearing_number``, ``bearing_number_per_1000_rpm``,
    ``mass_parameter``, ``gravity_parameter``, ``load`` (= M G), ``foil_stiffness``, ``kappa``;
    physical figures ``static_load_n``, ``specific_load_kpa``, ``static_load_ratio`` (W / (p0 L D)),
    ``dellacorte_capacity_n``, ``dellacorte_load_ratio`` (W / W_max), ``clearance_ratio`` (C/R),
    ``surface_speed_m_s``, ``bump_pitch_m``; and ``warnings`` (a list of one-line strings).
    """
    speed = b.speed_rpm if speed_rpm is None else float(speed_rpm)
    lam = b.bearing_number_at(speed)
    d = 2.0 * b.radius_m
    w = b.rotor_mass_per_bearing_kg * b.modified_gravity_m_s2
    area = b.length_m * d
    specific = w / area
    capacity = dellacorte_load_capacity_n(b, speed) if speed > 0 else 0.0
    cr = b.clearance_m / b.radius_m
    surface = speed * 2.0 * math.pi / 60.0 * b.radius_m
    warnings: list[str] = []
    if specific > CHALLENGING_SPECIFIC_LOAD_PA:
        warnings.append(
            f"specific load W/(L D) = {specific / 1e3:.1f} kPa is above 340 kPa (50 psi), challenging "
            "for a radial foil bearing even in operation (Barber-Nichols guide)"
        )
    elif specific > OPERATING_SPECIFIC_LOAD_PA:
        warnings.append(
            f"specific load W/(L D) = {specific / 1e3:.1f} kPa is above the 140 kPa (20 psi) lower-risk "
            "operating load of a radial foil bearing (Barber-Nichols guide)"
        )
    if specific > STARTUP_SPECIFIC_LOAD_PA:
        warnings.append(
            f"specific load W/(L D) = {specific / 1e3:.1f} kPa is above the 34 kPa (5 psi) start-up "
            "guideline: the foil carries W in sliding contact until lift-off (Barber-Nichols guide)"
        )
    if speed > 0 and w > capacity:
        warnings.append(
            f"static load W = {w:.3g} N exceeds DellaCorte's first-generation load capacity "
            f"W_max = 0.1 (L D)(D Omega) = {capacity:.3g} N at {speed:.0f} rpm (DellaCorte & Valco 2000)"
        )
    if not CLEARANCE_RATIO_RANGE[0] <= cr <= CLEARANCE_RATIO_RANGE[1]:
        warnings.append(
            f"clearance ratio C/R = {cr:.3g} is outside the usual [5e-4, 5e-3] of gas foil bearings "
            "(a unit slip in clearance_m or radius_m?)"
        )
    if speed > 0 and not SURFACE_SPEED_CHALLENGING[0] <= surface <= SURFACE_SPEED_CHALLENGING[1]:
        warnings.append(
            f"surface speed Omega R = {surface:.0f} m/s at {speed:.0f} rpm is outside 30-305 m/s "
            "(Barber-Nichols guide: challenging)"
        )
    return {
        "speed_rpm": speed,
        "time_scale_s": b.time_scale_s,
        "bearing_number": lam,
        "bearing_number_per_1000_rpm": b.bearing_number_at(1000.0),
        "mass_parameter": b.mass_parameter,
        "gravity_parameter": b.gravity_parameter,
        "load": b.mass_parameter * b.gravity_parameter,
        "foil_stiffness": b.foil_stiffness,
        "kappa": b.kappa,
        "static_load_n": w,
        "specific_load_kpa": specific / 1e3,
        "static_load_ratio": specific / b.ambient_pressure_pa,
        "dellacorte_capacity_n": capacity,
        "dellacorte_load_ratio": w / capacity if capacity > 0 else None,
        "clearance_ratio": cr,
        "surface_speed_m_s": surface,
        "bump_pitch_m": b.bump_pitch_m,
        "warnings": warnings,
    }
