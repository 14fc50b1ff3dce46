"""Random base shocks: Poisson arrivals of half-sine acceleration pulses of random size and direction.

A machine in service (a vehicle's turbocompressor, an aircraft's air-cycle machine, a portable
generator) sees base shocks: potholes, landings, handling.  They are modelled as a Poisson process of
rate ``rate_per_s`` (independent arrivals: counts in disjoint intervals are independent, so drawing
control step by control step is the same process as drawing the whole episode at once).  Each event has

* a peak base acceleration ``peak_g`` (in g), log-uniform in ``peak_g_range``: many small shocks, few
  large ones, and no scale preferred inside the range;
* a duration ``duration_ms`` of the half-sine, uniform in ``duration_ms_range``;
* a direction ``direction_deg`` in the bearing plane, uniform in ``direction_deg_range``, measured like
  the attitude angle: from the downward vertical (+eta, the direction of gravity) toward +xi.

The events are records (:class:`ShockEvent`); the forcing (``gfb_env.forcing.HalfSineShock
.from_physical(bearing, start_s, peak_g, duration_ms, direction_deg)``) turns them into the rotor
equations' base excitation.  Every draw comes from the ``np.random.Generator`` passed in (the env's
``np_random``); with ``rate_per_s = 0`` nothing is drawn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.machine._checks import finite, finite_pair, nonnegative

__all__ = ["ShockArrivals", "ShockEvent", "poisson_arrival_times"]


def poisson_arrival_times(
    rng: np.random.Generator, rate_per_s: float, start_s: float, end_s: float
) -> np.ndarray:
    """The arrival times (s, sorted) of a Poisson process of ``rate_per_s`` in ``[start_s, end_s)``.

    Draws one Poisson count (none if the rate is 0 or the interval empty), then the times: given the
    count, a Poisson process's arrival times are independent and uniform.  Raises ``ValueError`` for a
    non-finite bound or ``end_s < start_s``."""
    # (a finite float passes finite() unchanged: checked by its type first, every control step)
    if type(start_s) is not float or not math.isfinite(start_s):
        start_s = finite("start_s", start_s)
    if type(end_s) is not float or not math.isfinite(end_s):
        end_s = finite("end_s", end_s)
    if end_s < start_s:
        raise ValueError(f"end_s must not be before start_s, got [{start_s}, {end_s})")
    span = end_s - start_s
    if rate_per_s == 0.0 or span == 0.0:
        return np.empty(0)
    n = int(rng.poisson(rate_per_s * span))
    if n == 0:
        return np.empty(0)
    return np.sort(start_s + span * rng.random(n))


@dataclass(frozen=True)
class ShockEvent:
    """One base shock: a half-sine base acceleration pulse.

    Attributes:
        time_s: start of the pulse, s (episode time, ``BearingParameters.seconds(tau)``).
        peak_g: peak base acceleration, in g (9.80665 m/s^2).
        duration_ms: duration of the half-sine, ms.
        direction_deg: direction of the base acceleration, degrees from the downward vertical toward +xi.
    """

    time_s: float
    peak_g: float
    duration_ms: float
    direction_deg: float


@dataclass(frozen=True)
class ShockArrivals:
    """Generator of random :class:`ShockEvent` s (see the module docstring; ``docs/machine.md``).

    Attributes:
        rate_per_s: mean arrivals per second (default 0.5: about one shock per 2-s episode).
        peak_g_range: ``(min, max)`` peak acceleration in g, log-uniform (default (2, 20): from a rough
            road up to the 20 g functional-test shock of flight equipment, MIL-STD-810 Method 516).
        duration_ms_range: ``(min, max)`` pulse duration in ms, uniform (default (5, 15), around the
            11 ms of the standard functional shock).
        direction_deg_range: ``(min, max)`` direction, uniform (default (0, 360): any direction).
    """

    rate_per_s: float = 0.5
    peak_g_range: tuple[float, float] = (2.0, 20.0)
    duration_ms_range: tuple[float, float] = (5.0, 15.0)
    direction_deg_range: tuple[float, float] = (0.0, 360.0)

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "rate_per_s", nonnegative("rate_per_s", self.rate_per_s))
        put(self, "peak_g_range", finite_pair("peak_g_range", self.peak_g_range, positive_values=True))
        put(
            self,
            "duration_ms_range",
            finite_pair("duration_ms_range", self.duration_ms_range, positive_values=True),
        )
        put(self, "direction_deg_range", finite_pair("direction_deg_range", self.direction_deg_range))

    @classmethod
    def none(cls) -> ShockArrivals:
        """No shocks."""
        return cls(rate_per_s=0.0)

    def draw(self, rng: np.random.Generator, start_s: float, end_s: float) -> list[ShockEvent]:
        """The shocks that start in ``[start_s, end_s)``, in time order.

        Draws: one Poisson count (if ``rate_per_s > 0`` and the interval is not empty), then per event
        its time, peak, duration and direction (vectorised, in that order)."""
        times = poisson_arrival_times(rng, self.rate_per_s, start_s, end_s)
        n = len(times)
        if n == 0:
            return []
        lo, hi = self.peak_g_range
        peaks = np.exp(rng.uniform(math.log(lo), math.log(hi), n))
        durations = rng.uniform(*self.duration_ms_range, n)
        directions = rng.uniform(*self.direction_deg_range, n)
        return [
            ShockEvent(float(t), float(p), float(d), float(a))
            for t, p, d, a in zip(times, peaks, durations, directions, strict=True)
        ]
