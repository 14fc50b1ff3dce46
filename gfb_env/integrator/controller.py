"""The step-size controller of the trapezoidal stepper (Hairer & Wanner, *Solving ODEs II*, Sect. IV.8).

After an accepted step with error norm ``err <= 1`` the next step is
``h * clip(safety * err^error_exponent, min_factor, max_factor)`` (``max_factor`` for ``err == 0``; a
step truncated to hit the end of the call keeps the previous proposal unless the error asks for less),
at most ``max_step``; after a rejected one ``h * max(min_factor, reject_safety * err^error_exponent)``;
a Newton failure (or a singular factorisation) multiplies h by ``newton_failure_factor``.  The
trapezoidal rule's local error is O(h^3), hence the exponent -1/3.

:class:`StepSizeController` holds the constants (part of
:class:`~gfb_env.integrator.IntegratorOptions`); the compiled loop reads them from its options group
(:class:`~gfb_env.integrator.arguments.LoopOptions`) through the two functions below.

**The step limit at a settled operating point** (:class:`WhirlGrowthControl`, opt-in).  Near an
equilibrium the error test above lets the step grow without bound: the local error of a deviation ``d``
of the least damped (Hopf, half-frequency whirl) mode, ``|d| (h omega)^3 / 12`` with ``omega ~ Lambda / 2``,
is below ``atol`` for any useful h once ``|d|`` is small.  But the trapezoidal rule grows that mode
at ``sigma / (1 + (h omega)^2 / 4)`` instead of ``sigma`` (the derivative of ``log R(z)``,
``R = (1 + z/2) / (1 - z/2)``, at ``z = i h omega``): the growth rate is damped, never its sign.  A
whirl that grows at sigma ~ 0.004 from a small deviation therefore grows too slowly with large steps;
the absolute error test cannot see it, because the error is relative to a deviation far below
``atol``.  ``max_step = 2`` (``h omega <= 0.6`` at ``Lambda = 0.6``, the growth rate within 9 %) is
what protects it today, and it pins the step near every equilibrium: 30 steps per 60-tau control step
where 2 would do.  Measured on RunUp-v2 with a balanced rotor, full-speed ramp into the whirl:
touchdown at control step 78 with ``max_step`` 2 and with the tight reference (rtol = atol = 1e-5),
at step 120 with ``max_step`` 30.

Two designs were candidates. (a) The local error measured relative to the deviation from the current
equilibrium: this bounds ``(h omega)^3 / 12`` at every amplitude, so it pins the step near *every*
equilibrium whose least damped mode oscillates (``h omega ~ (12 rtol)^(1/3)``: h ~ 0.5 at rtol 3e-4,
smaller than today's cap) and gains nothing where the gain is wanted; with an absolute floor it returns to
the absolute test below the floor and the growth from a small deviation is lost again. (b) A cap from the
least damped mode's growth rate: only a *growing* (or barely decaying) mode needs its growth resolved, a
decaying mode's error decays with it, and the rest of the solution is held to ``atol`` by the error test.
This is (b), with the growth rate measured, not computed (an eigenvalue solve costs ~10 ms against a ~0.5
ms control step): at a held operating point (Lambda and D_W within ``operating_point_tolerance`` of their
values when the window started) the integrator measures the rotor's rate of motion ``m^2 = xi'^2 + eta'^2
+ (xi''^2 + eta''^2) / omega^2`` (omega = 0.4 Lambda, the whirl's frequency: m is the same at every phase
of a harmonic whirl; near the equilibrium ``k(s) = J d`` for a deviation ``d``, so m is 0 there) at the
end of each call. The operating point becomes *settled* when m is below ``settle_motion`` (the ring-down
is far below the instruments) and decayed at ``decay_rate`` or faster over a window of at least
``min_window`` (several whirl periods: the average removes the phase of an elliptic orbit), measured under
``max_step``, so the measured rate is the mode's to 9 %. A settled call takes ``settled_max_step``; under
it the numerical decay is slower (the factor above: ~10x at h = 30) and the numerical whirl's frequency is
warped (so m's phase is no longer the whirl's), so from then on a call restarts the window under
``max_step`` only when m exceeded ``growth_factor`` times its least value since the first settled call (in
which the step grows from ``max_step`` and m jumps: the stiff film modes, which the trapezoidal rule does
not damp at large h, ring at the error test's level), and the point is measured again after
``reverify_after`` in any case. A growing mode hidden under a decaying fast transient shows as a slowing
decay, which is why the last call of the window must decay at ``decay_rate`` too. Because the trapezoidal
rule keeps the sign of every mode's growth at any step, a mode that grows under the relaxed limit still
grows (slowly): it restarts the window when it has doubled or at the next re-measurement. Below
``rest_motion`` (1e-8 clearances per tau: a whirl of ~4e-8 C = 2 pm, 1e-5 of the probes' noise, about the
level at which the settled steps' own ringing sits) the rotor counts as at rest: a mode growing from below
it is not resolved until it is above it or the next re-measurement (the limitation of the design: a plant
at rest that a damping change inside the tolerance makes unstable). Any change of Lambda or D_W beyond the
tolerance restarts the window (a ramp moves the equilibrium, a damping change moves Lambda_c: both can
turn a decaying mode into a growing one), so a ramp into the whirl is stepped exactly as without the
option. The unbalance forcing keeps m up (its 1x orbit does not decay) and is capped by
``steps_per_revolution`` anyway; base shocks land on their pulse ends at any limit.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields

from numba import njit

__all__ = ["StepSizeController", "WHIRL_FREQUENCY_RATIO", "WhirlGrowthControl"]

#: The whirl's frequency over Lambda that the rotor's rate of motion is measured with (the paper's
#: whirl is near half the rotation frequency; 0.37 at onset on 21x5, K_W = 1).
WHIRL_FREQUENCY_RATIO = 0.4


@dataclass(frozen=True)
class StepSizeController:
    """The constants of the step-size control (see the module docstring for the rule).

    Attributes:
        safety: factor on the optimal step after an accepted step, in (0, 1].
        reject_safety: the same after a rejected step (milder), in (0, 1].
        min_factor: the step shrinks by at most this factor per step, in (0, 1).
        max_factor: the step grows by at most this factor per step, > 1.
        error_exponent: the exponent of the error norm, < 0 (-1/3: local error O(h^3)).
        newton_failure_factor: the step's factor after a Newton failure, in (0, 1).
    """

    safety: float = 0.8
    reject_safety: float = 0.9
    min_factor: float = 0.2
    max_factor: float = 2.0
    error_exponent: float = -1.0 / 3.0
    newton_failure_factor: float = 0.25

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"controller.{f.name} must be a finite number, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        for name in ("safety", "reject_safety"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"controller.{name} must lie in (0, 1], got {getattr(self, name)!r}")
        for name in ("min_factor", "newton_failure_factor"):
            if not 0.0 < getattr(self, name) < 1.0:
                raise ValueError(f"controller.{name} must lie in (0, 1), got {getattr(self, name)!r}")
        if not self.max_factor > 1.0:
            raise ValueError(f"controller.max_factor must be > 1, got {self.max_factor!r}")
        if not self.error_exponent < 0.0:
            raise ValueError(f"controller.error_exponent must be < 0, got {self.error_exponent!r}")


@dataclass(frozen=True)
class WhirlGrowthControl:
    """The step limit at a settled operating point (opt-in; see the module docstring for the rule).

    Attributes:
        settled_max_step: the step limit in tau of a settled call, >= the options' ``max_step`` (the
            error test still applies).
        decay_rate: the least decay rate per tau of the rotor's rate of motion m, measured under
            ``max_step`` over the window and over its last call, that settles the operating point, > 0.
        min_window: the shortest measurement window in tau, > 0.
        settle_motion: the point settles only once m is below this (clearances per tau; 1e-5 is a
            whirl of ~4e-5 C = 2 nm at omega = 0.25, 1/150 of the probes' noise): a visible ring-down of
            a slowly decaying whirl (a hold just below Lambda_c after a ramp) decays ~10x too slowly
            under the settled limit, which the plant_accuracy runs showed (0.2 -> 0.7 of the noise in
            the sub-synchronous level without this bound), > 0.
        growth_factor: a settled call whose m exceeds this factor times the least m since settling
            restarts the window, > 1 (under the settled limit the numerical decay is slow and m's phase
            is not the whirl's, so "any growth" would restart on noise).
        reverify_after: a settled operating point is measured again under ``max_step`` after this long
            in tau, > 0 (bounds what a growing mode the measurement missed can lose).
        rest_motion: below this m (clearances per tau) the rotor is at rest: the window settles without a
            measured decay and a settled call's m does not restart it (the settled steps' own ringing
            of the stiff film modes sits near 1e-8..1e-7 on 21x5), > 0.
        operating_point_tolerance: Lambda and D_W count as held while within this relative distance of
            their values at the window's start, > 0 (the damping actuator approaches its command
            geometrically, never exactly).
    """

    settled_max_step: float = 30.0
    decay_rate: float = 0.003
    min_window: float = 100.0
    settle_motion: float = 1e-5
    growth_factor: float = 2.0
    reverify_after: float = 600.0
    rest_motion: float = 1e-8
    operating_point_tolerance: float = 1e-2

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and v > 0):
                raise ValueError(f"whirl_growth_control.{f.name} must be a finite positive number, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        if not self.growth_factor > 1.0:
            raise ValueError(f"whirl_growth_control.growth_factor must be > 1, got {self.growth_factor!r}")

    def _same_point(self, window: tuple, operating_point: tuple) -> bool:
        if not window:
            return False
        tol = self.operating_point_tolerance
        lam, dw = operating_point
        return abs(lam - window[0]) <= tol * abs(window[0]) and abs(dw - window[1]) <= tol * abs(window[1])

    def window_after(self, window: tuple, tau: float, motion: float, operating_point: tuple) -> tuple:
        """The measurement window after a call that ended at ``tau`` with the rotor's rate of motion
        ``motion`` and ``operating_point`` = (Lambda, D_W).  A window is ``(Lambda, D_W, anchor tau,
        anchor motion, tau, motion, settled, settled since, least motion since)`` (Lambda, D_W: at its
        anchor) or ``()``; see the module docstring for when it restarts and settles."""
        restart = (*operating_point, tau, motion, tau, motion, False, tau, motion)
        if not self._same_point(window, operating_point):
            return restart
        lam, dw, t0, m0, tp, mp, settled, ts, m_min = window
        rest = self.rest_motion
        if settled:
            if tau - ts >= self.reverify_after:
                return restart
            if tp <= ts:  # the first settled call: the step grows from max_step, m jumps (not compared)
                return (lam, dw, t0, m0, tau, motion, True, ts, motion)
            if motion >= rest and motion > self.growth_factor * m_min:
                return restart
            return (lam, dw, t0, m0, tau, motion, True, ts, min(m_min, motion))
        tiny = 1e-300
        rate = self.decay_rate
        decayed = math.log(max(motion, tiny) / max(m0, tiny)) <= -rate * (tau - t0)
        last = tp > t0 and math.log(max(motion, tiny) / max(mp, tiny)) <= -rate * (tau - tp)
        at_rest = max(motion, mp, m0) < rest
        now = tau - t0 >= self.min_window and motion <= self.settle_motion
        now = now and ((decayed and (last or motion < rest)) or at_rest)
        return (lam, dw, t0, m0, tau, motion, bool(now), tau, motion)

    def settled(self, window: tuple, operating_point: tuple) -> bool:
        """Whether a call that ends at ``operating_point`` = (Lambda, D_W) may take ``settled_max_step``."""
        return self._same_point(window, operating_point) and bool(window[6])


# ------------------------------------------------------------------------------------------------
# The compiled rule (inlined into the loop; ``opt`` is its LoopOptions, which carries the constants).
@njit(inline="always")
def step_after_rejection(hstep, err, opt):
    return hstep * max(opt.min_factor, opt.reject_safety * err**opt.error_exponent)


@njit(inline="always")
def step_after_acceptance(h, hstep, err, truncated, opt):
    """The next step; a step truncated to hit t_end keeps the previous proposal ``h`` unless the error
    asks for a smaller one."""
    fac = opt.max_factor if err == 0.0 else min(opt.max_factor, opt.safety * err**opt.error_exponent)
    if not truncated or fac < 1.0:
        return min(hstep * max(fac, opt.min_factor), opt.max_step)
    return h
