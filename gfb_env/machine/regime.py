"""Friction-regime changes of the foil: abrupt jumps of the damping effectiveness ``g`` within an episode.

The bump foil's damping is dry (Coulomb) friction at the bump-top foil and the bump-housing contacts
(issue 22's frictional foil, ``results/friction_mu_sweep``): the dissipated energy per cycle scales with
the friction coefficient mu and with whether the bumps stick or slip.  Both change abruptly in service:

* the paper's energy balance (Eq. 15) makes the equivalent viscous damping of the Coulomb contact
  proportional to the friction coefficient mu_C, and the solid-lubricant coatings of foil bearings
  (PTFE, MoS2, PS304-type) change mu_C abruptly when their **transfer film** on the counterface forms
  or breaks (flash heating, wear debris, a rub): about 0.1 with the film, 0.2-0.4 without -- a factor
  of about 1.5-3 (the range reported for bump-foil coatings by DellaCorte and co-workers at NASA Glenn;
  cited from memory, as ``docs/analysis.md`` cites the friction range);
* a group of bumps passes from **stick to slip** (or back) as the contact load or the whirl amplitude
  crosses the bumps' stick limit: the frictional foil of issue 22 (``docs/analysis.md``,
  ``results/friction_mu_sweep``) has an equivalent damping of 0.8-1.2 at mu_C = 0.08-0.3 that falls as
  ``1 / q_hat`` with the slip amplitude once the bumps slip, and sticking columns that stiffen the foil
  instead of damping it, so a change of regime moves the effective D_W by a factor, not a drift.

So the commanded-to-actual effectiveness ``g`` (actual D_W = g x commanded,
:class:`~gfb_env.machine.FoilDampingActuator`) is piecewise constant: a Poisson process of regime
changes at rate ``rate_per_s`` (independent of everything else: drawn control step by control step, the
same process as drawn at once), each one multiplying ``g`` by a factor ``f`` whose size is log-uniform in
``factor_range`` (``1 <= f_min <= f_max``) and whose direction (up or down) is a fair coin, reflected in
``ln g`` into ``gain_bounds`` (a regime cannot take the contact outside the friction coefficients the
coating pair has: the task's range of ``g``).  A change takes effect on the foil at once; the
actuator's own position feedback (the indicated damping, ``D_W / g``) does not move, since the actuator
is not what changed.  What changes is only what the machine's vibration shows: the 1x response, the
sub-synchronous growth or decay.

Every draw comes from the ``np.random.Generator`` passed in (the env's ``np_random``); with
``rate_per_s = 0`` (the default: :meth:`DampingRegimeChanges.none`) nothing is drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.machine._checks import finite, finite_pair, nonnegative, positive
from gfb_env.machine.shocks import poisson_arrival_times

__all__ = ["DampingRegimeChange", "DampingRegimeChanges"]


@dataclass(frozen=True)
class DampingRegimeChange:
    """One friction-regime change of the foil.

    Attributes:
        time_s: when it happened, s (episode time, ``BearingParameters.seconds(tau)``).
        factor: ``gain_after / gain_before`` (after the reflection into the bounds).
        gain_before, gain_after: the damping effectiveness ``g`` before and after.
    """

    time_s: float
    factor: float
    gain_before: float
    gain_after: float

    def as_dict(self) -> dict[str, float]:
        return {
            "time_s": self.time_s,
            "factor": self.factor,
            "gain_before": self.gain_before,
            "gain_after": self.gain_after,
        }


@dataclass(frozen=True)
class DampingRegimeChanges:
    """Generator of friction-regime changes of ``g`` (module docstring; ``docs/task_redesign.md``).

    Attributes:
        rate_per_s: mean changes per second, >= 0 (default 0: off, nothing drawn).
        factor_range: ``(f_min, f_max)``, 1 <= f_min <= f_max: the size of one change, log-uniform
            (default (1.5, 2.5): a transfer film formed or broken, mu 0.1 <-> 0.15-0.25).
        gain_bounds: ``(g_min, g_max)``: the range ``g`` stays in (reflected in ``ln g``); ``None``
            (default): the actuator's ``gain_range`` (the env refuses the component if it has none).
    """

    rate_per_s: float = 0.0
    factor_range: tuple[float, float] = (1.5, 2.5)
    gain_bounds: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "rate_per_s", nonnegative("rate_per_s", self.rate_per_s))
        lo, hi = finite_pair("factor_range", self.factor_range, positive_values=True)
        if lo < 1.0:
            raise ValueError(
                f"factor_range must have f_min >= 1 (the direction is drawn), got {self.factor_range!r}"
            )
        put(self, "factor_range", (lo, hi))
        if self.gain_bounds is not None:
            glo, ghi = finite_pair("gain_bounds", self.gain_bounds, positive_values=True)
            if not glo < ghi:
                raise ValueError(f"gain_bounds must have g_min < g_max, got {self.gain_bounds!r}")
            put(self, "gain_bounds", (glo, ghi))

    @classmethod
    def none(cls) -> DampingRegimeChanges:
        """No regime changes (``g`` constant over the episode)."""
        return cls(rate_per_s=0.0)

    @property
    def is_off(self) -> bool:
        return self.rate_per_s == 0.0

    def draw(
        self,
        rng: np.random.Generator,
        start_s: float,
        end_s: float,
        gain: float,
        bounds: tuple[float, float],
    ) -> list[DampingRegimeChange]:
        """The changes in ``[start_s, end_s)`` starting from the effectiveness ``gain``, in time order
        (each one's ``gain_before`` the previous one's ``gain_after``).  ``bounds``: the range of ``g``
        (the env passes ``gain_bounds`` or the actuator's ``gain_range``).

        Draws: one Poisson count (if ``rate_per_s > 0`` and the interval is not empty), then per change
        its time, size and direction (vectorised, in that order)."""
        start_s, end_s = finite("start_s", start_s), finite("end_s", end_s)
        if end_s < start_s:
            raise ValueError(f"end_s must not be before start_s, got [{start_s}, {end_s})")
        g = positive("gain", gain)
        glo, ghi = finite_pair("bounds", bounds, positive_values=True)
        times = poisson_arrival_times(rng, self.rate_per_s, start_s, end_s)
        n = len(times)
        if n == 0:
            return []
        flo, fhi = self.factor_range
        sizes = rng.uniform(math.log(flo), math.log(fhi), n)
        signs = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        out = []
        for t, s, d in zip(times, sizes, signs, strict=True):
            after = reflect_log(g * math.exp(d * s), glo, ghi)
            out.append(DampingRegimeChange(float(t), after / g, g, after))
            g = after
        return out


def reflect_log(g: float, lo: float, hi: float) -> float:
    """``g`` folded into ``[lo, hi]`` by reflection at the ends in ``ln g`` (a triangle wave: any
    excursion, however large, lands inside)."""
    a, b = math.log(lo), math.log(hi)
    if b <= a:
        return lo
    x = math.log(g) - a
    w = b - a
    x = math.fmod(x, 2.0 * w)
    if x < 0.0:
        x += 2.0 * w
    if x > w:
        x = 2.0 * w - x
    return float(min(max(math.exp(a + x), lo), hi))
