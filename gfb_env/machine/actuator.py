"""The foil-damping actuator: what turns a commanded foil damping D_W into the damping the foil has.

The paper treats the foil damping ``D_W`` (Eq. 9) as a parameter and gives it only as an order of
magnitude (Eq. 15).  A machine that controls it (a controllable friction, squeeze-film or
magnetorheological damper behind the bump foil) has three imperfections, modelled here:

* **effectiveness gain** ``g``: the actual damping is ``g`` times the commanded one (the command is
  calibrated against a damping that is itself only known to an order of magnitude); a task may draw
  ``g`` per episode and hide it;
* **first-order lag** with time constant ``T_a`` (``time_constant_ms``);
* **rate limit** ``r`` (``rate_limit_decades_per_s``).

Both the lag and the rate limit act on ``ln D_W``, because the command scale is logarithmic (the
action maps log-linearly onto ``[D_min, D_max]``, two decades) and the damping's effect on the
stability (paper Fig. 4) is smooth in ``log D_W``: a step from 0.1 to 10 and back from 10 to 0.1 then
take the same time, and the rate limit is a fixed fraction of the action range per second.  With
``x = ln D_W`` and the target ``c = ln(g D_cmd)``::

    x' = clip((c - x) / T_a, -r ln 10, +r ln 10)

The command is held over a control step (zero-order hold), so this has an exact solution over the step
(:meth:`FoilDampingActuator.step`): a linear ramp in ``x`` while ``|c - x| > r ln 10 T_a`` (the rate
limit is active), then the exponential ``c - x(t) = (c - x_1) exp(-(t - t_1) / T_a)``.

Inside the control step the integrator ramps D_W *linearly* between the step's two end values
(:meth:`~gfb_env.integrator.TrapezoidalIntegrator.advance`), while the exact path is the exponential
(and rate-limited) one in ``ln D_W``.  The end value of every step is exact (so the lag's state never
drifts); only the path inside the step is the linear-ramp approximation.  It misplaces *when* within
the step the damping changes, not how much: the largest difference between the two paths is a fraction
of the step's change of D_W (for a lag much shorter than the step it is nearly the whole change at the
step's start, for a lag much longer than the step it vanishes like ``dt / (8 T_a)`` of the change).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.machine._checks import finite_pair, nonnegative, positive

__all__ = ["FoilDampingActuator", "DampingActuatorState"]

_LN10 = math.log(10.0)


@dataclass(frozen=True)
class DampingActuatorState:
    """The actuator's state in one episode (part of the :class:`~gfb_env.envs.episode.Episode`).

    Attributes:
        foil_damping: the actual D_W at the end of the last control step (the plant's damping).
        gain: this episode's effectiveness ``g`` (actual / commanded; hidden from the observation).
    """

    foil_damping: float
    gain: float

    @property
    def indicated_damping(self) -> float:
        """What the actuator's own position feedback reads: ``D_W / g`` (the damping it believes it
        sets, on the command's calibration)."""
        return self.foil_damping / self.gain

    def with_gain(self, gain: float) -> DampingActuatorState:
        """The state after the foil's effectiveness changed to ``gain`` (a friction-regime change,
        :class:`~gfb_env.machine.DampingRegimeChanges`): the actuator's own setting (the indicated
        damping) stays, the actual D_W is the new ``gain`` times it."""
        g = positive("gain", gain)
        return DampingActuatorState(self.indicated_damping * g, g)


@dataclass(frozen=True)
class FoilDampingActuator:
    """First-order lag + rate limit on ``ln D_W`` and an effectiveness gain (see the module docstring).

    The defaults are a realistic actuator (``docs/machine.md``); :meth:`ideal` is the exact actuator
    (the command takes effect at once, exactly).

    Attributes:
        time_constant_ms: first-order lag ``T_a`` in ms, >= 0 (0: no lag).  Default 10 ms: the response
            time of a magnetorheological damper (coil current rise and fluid response, ~10 ms); about one
            control step (9.5 ms), so the lag matters to a controller but does not dominate.
        rate_limit_decades_per_s: the largest ``|d log10 D_W / dt|`` in decades per second, > 0 or inf
            (no limit).  Default 20: the whole two-decade range in 0.1 s (~10 control steps), the slew
            of a current-limited coil drive; it makes a chattering damping command ineffective.
        gain: the effectiveness ``g`` (actual D_W = g x commanded) when the task does not draw one.
        gain_range: ``(g_min, g_max)``: draw ``g`` log-uniformly per episode (from the env's
            ``np_random``) and hide it; ``None`` (default) keeps ``gain``.
    """

    time_constant_ms: float = 10.0
    rate_limit_decades_per_s: float = 20.0
    gain: float = 1.0
    gain_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "time_constant_ms", nonnegative("time_constant_ms", self.time_constant_ms))
        put(
            self,
            "rate_limit_decades_per_s",
            positive("rate_limit_decades_per_s", self.rate_limit_decades_per_s, allow_inf=True),
        )
        put(self, "gain", positive("gain", self.gain))
        if self.gain_range is not None:
            put(self, "gain_range", finite_pair("gain_range", self.gain_range, positive_values=True))

    @classmethod
    def ideal(cls) -> FoilDampingActuator:
        """No lag, no rate limit, gain 1: the command is the plant's D_W at the step's end."""
        return cls(time_constant_ms=0.0, rate_limit_decades_per_s=math.inf, gain=1.0)

    @property
    def is_ideal(self) -> bool:
        return (
            self.time_constant_ms == 0.0
            and math.isinf(self.rate_limit_decades_per_s)
            and self.gain == 1.0
            and self.gain_range is None
        )

    def draw_gain(self, rng: np.random.Generator) -> float:
        """This episode's gain: log-uniform in ``gain_range`` (one draw from ``rng``), else ``gain``
        (no draw, so an env without a gain range consumes no random numbers)."""
        if self.gain_range is None:
            return self.gain
        lo, hi = self.gain_range
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    def start(self, foil_damping: float, gain: float | None = None) -> DampingActuatorState:
        """The state at rest at the actual damping ``foil_damping`` (the plant's start D_W)."""
        g = self.gain if gain is None else positive("gain", gain)
        return DampingActuatorState(positive("foil_damping", foil_damping), g)

    def step(self, state: DampingActuatorState, commanded: float, dt_s: float) -> DampingActuatorState:
        """The state after holding the command ``commanded`` (D_W) for ``dt_s`` seconds; its
        ``foil_damping`` is the actual D_W at the end, exact for the lag and the rate limit."""
        target = state.gain * commanded
        return DampingActuatorState(self._end_value(state.foil_damping, target, dt_s), state.gain)

    def _end_value(self, d0: float, target: float, dt_s: float) -> float:
        if d0 == target or dt_s <= 0.0:
            return target if dt_s > 0.0 else d0
        r = self.rate_limit_decades_per_s * _LN10  # ln D_W per second
        ta = self.time_constant_ms * 1e-3
        x0, c = math.log(d0), math.log(target)
        e0 = c - x0
        sign = 1.0 if e0 > 0 else -1.0
        # phase 1: the rate limit holds while |c - x| > r T_a (for T_a = 0: until x reaches c)
        t_rate = 0.0 if math.isinf(r) else max(0.0, (abs(e0) - r * ta) / r)
        if t_rate >= dt_s:
            return math.exp(x0 + sign * r * dt_s)
        if ta == 0.0:
            return target  # reached within the step: exactly the target, no exp(log()) round-off
        e1 = e0 if t_rate == 0.0 else sign * r * ta
        return math.exp(c - e1 * math.exp(-(dt_s - t_rate) / ta))
