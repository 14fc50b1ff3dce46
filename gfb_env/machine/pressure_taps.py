"""Midplane pressure taps: the film pressure at ``n`` angles of the bearing's midplane (Z = 0).

A tap is a small hole through the top foil to a pressure transducer (test rigs of foil bearings carry
them; production machines rarely do).  It reads the absolute film pressure in kPa with a per-episode
offset (the transducer's zero and its thermal shift) and Gaussian noise per reading.  The observation is
``P = p / p0``, so the error in kPa becomes ``error * 1000 / p0[Pa]`` in the observation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gfb_env.machine._checks import finite, nonnegative

__all__ = ["PressureTaps"]


@dataclass(frozen=True)
class PressureTaps:
    """Pressure taps with offset and noise (see the module docstring).

    The defaults are realistic (``docs/machine.md``); :meth:`ideal` is the exact sensor.

    Attributes:
        noise_kpa: standard deviation of the noise of one reading, kPa (default 0.35: 0.1 % of the
            full scale of a 0-350 kPa absolute miniature piezoresistive transducer, its typical combined
            non-linearity, hysteresis and repeatability).
        bias_kpa: fixed offset of every tap, kPa (default 0).
        bias_spread_kpa: standard deviation of a per-episode offset drawn for each tap, kPa (default
            0.9: 0.25 % of the full scale, the zero offset and thermal zero shift of such a transducer
            over a few tens of kelvin).
    """

    noise_kpa: float = 0.35
    bias_kpa: float = 0.0
    bias_spread_kpa: float = 0.9

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "noise_kpa", nonnegative("noise_kpa", self.noise_kpa))
        put(self, "bias_kpa", finite("bias_kpa", self.bias_kpa))
        put(self, "bias_spread_kpa", nonnegative("bias_spread_kpa", self.bias_spread_kpa))

    @classmethod
    def ideal(cls) -> PressureTaps:
        """No noise, no offset: the exact pressures."""
        return cls(noise_kpa=0.0, bias_kpa=0.0, bias_spread_kpa=0.0)

    @property
    def is_ideal(self) -> bool:
        return self.noise_kpa == 0.0 and self.bias_kpa == 0.0 and self.bias_spread_kpa == 0.0

    def draw_bias(self, rng: np.random.Generator, n_taps: int) -> np.ndarray:
        """This episode's offsets (kPa) of ``n_taps`` taps: ``bias_kpa`` plus, if
        ``bias_spread_kpa > 0``, a Gaussian draw per tap from ``rng`` (no draw otherwise)."""
        b = np.full(n_taps, self.bias_kpa)
        if self.bias_spread_kpa > 0:
            b = b + self.bias_spread_kpa * rng.standard_normal(n_taps)
        return b

    def errors_kpa(self, rng: np.random.Generator, bias_kpa: np.ndarray) -> np.ndarray:
        """The errors (kPa) of one reading of each tap: offset plus noise (drawn only if
        ``noise_kpa > 0``)."""
        bias_kpa = np.asarray(bias_kpa, dtype=float)
        if self.noise_kpa == 0.0:
            return bias_kpa.copy()
        return bias_kpa + self.noise_kpa * rng.standard_normal(len(bias_kpa))

    def read_kpa(self, pressure_pa: np.ndarray, rng: np.random.Generator, bias_kpa: np.ndarray) -> np.ndarray:
        """Readings (kPa) of the true absolute pressures ``pressure_pa`` (Pa)."""
        return np.asarray(pressure_pa, dtype=float) * 1e-3 + self.errors_kpa(rng, bias_kpa)
