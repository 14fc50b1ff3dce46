"""The rotor's residual unbalance, as a balance grade drawn per episode (ISO 1940-1 / ISO 21940-11).

A balanced rotor is specified by its balance grade G = e omega (mm/s) at its maximum service speed: the
permissible centre-of-mass eccentricity is ``e = G / omega_max``.  ISO 21940-11 recommends G 2.5 for gas
and steam turbines, turbo-compressors and turbochargers, G 1 for precision drives (grinders, small
high-speed armatures) and G 6.3 for general process machinery.  A small oil-free turbomachine on foil
bearings is balanced to about G 2.5 (G 1 with care); in service it degrades (erosion, deposits,
assembly).  The default draws G log-uniformly from [1, 6.3] per episode, at the top of the env's speed
range, and a uniform phase: the controller does not know the unbalance.  For Table 1 (C = 50 um) at
60 000 rpm that is e = 0.16-1.0 um, U = e / C = 0.003-0.02, far below the throw-over threshold of the
basin map at the band's lower edge (U* = 0.17) and comparable to it only next to Lambda_c (U* -> 0):
exactly where a run-up should not dwell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.forcing import Unbalance
from gfb_env.machine._checks import finite_pair, positive
from gfb_env.params import BearingParameters

__all__ = ["RotorBalance"]


@dataclass(frozen=True)
class RotorBalance:
    """Residual unbalance drawn per episode (module docstring).

    Attributes:
        grade_range_mm_s: ``(min, max)`` of the ISO balance grade G in mm/s, log-uniform; ``(0, 0)``:
            a perfectly balanced rotor.
        reference_speed_rpm: the speed at which the grade holds (the maximum service speed); ``None``:
            the top of the env's speed range.
    """

    grade_range_mm_s: tuple[float, float] = (1.0, 6.3)
    reference_speed_rpm: float | None = None

    def __post_init__(self) -> None:
        lo, hi = finite_pair("grade_range_mm_s", self.grade_range_mm_s)
        if not ((lo == hi == 0.0) or 0.0 < lo <= hi):
            raise ValueError(
                f"grade_range_mm_s must be (0, 0) or 0 < low <= high, got {self.grade_range_mm_s!r}"
            )
        object.__setattr__(self, "grade_range_mm_s", (lo, hi))
        if self.reference_speed_rpm is not None:
            object.__setattr__(
                self, "reference_speed_rpm", positive("reference_speed_rpm", self.reference_speed_rpm)
            )

    @classmethod
    def perfect(cls) -> RotorBalance:
        """No unbalance (the ideal machine): draws nothing."""
        return cls(grade_range_mm_s=(0.0, 0.0))

    @property
    def is_perfect(self) -> bool:
        return self.grade_range_mm_s[1] == 0.0

    def draw(
        self, rng: np.random.Generator, bearing: BearingParameters, top_speed_rpm: float
    ) -> tuple[Unbalance | None, float]:
        """``(unbalance, grade_mm_s)`` of a new episode: the grade log-uniform in the range, then the
        phase uniform in [0, 2 pi) (two draws from ``rng``; none for a perfect rotor)."""
        if self.is_perfect:
            return None, 0.0
        lo, hi = self.grade_range_mm_s
        grade = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
        phase = float(rng.uniform(0.0, 2.0 * math.pi))
        speed = self.reference_speed_rpm if self.reference_speed_rpm is not None else top_speed_rpm
        return Unbalance.from_iso1940(bearing, grade, speed, phase_rad=phase), grade
