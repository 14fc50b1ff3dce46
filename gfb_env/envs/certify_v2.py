"""The certificate of the v2 tasks: no irreducible loss from a base shock inside the scoring window
(issue 19 s.4; ``docs/envs.md``, "The v2 interface").

v1's certificate (:class:`~gfb_env.envs.certify.StabilityCertificate`) asks every whirl amplitude of
the last ``hold_steps`` control steps to stay below ``stable_amplitude``.  A base shock that arrives in
that window kicks the rotor, and at a point near ``lambda_best`` (where a good policy holds) the whirl
mode's decay rate tends to zero, so the ring-down of a shock outlasts any window: the certificate then
fails on a linearly stable plant that does exactly what it should, and no policy could have avoided it
(the v1 oracle lost 4-12 % of its episodes this way).  :class:`AfterShockCertificate` keeps v1's rule
for a window without a shock and replaces it from a shock on by "not growing":

* a shock *acts* in the window if its pulse (arrival to arrival + duration) overlaps the window;
* the steps of the window before the first acting shock's arrival must stay below ``stable_amplitude``
  (as v1);
* from the first shock's arrival on, the amplitude at the window's end ``A_end`` must not exceed
  ``max(stable_amplitude, A_ref)``, ``A_ref`` the amplitude of the first step that starts after the last
  acting pulse has ended (the free ring-down's first step): not growing; and it must decay at least as
  the actual plant's slowest mode does, ``A_end <= stable_amplitude + A_ref exp(g dtau)`` (g < 0 the
  growth rate of the equilibrium below, dtau the time from that step to the window's end; the slack
  ``stable_amplitude`` holds the transient's other modes and the amplitude measured over a non-integer
  number of periods).  The second test closes a hole of the first: in a hysteresis band (a linearly
  stable equilibrium beside a stable whirl cycle, docs/envs.md) a shock can kick the rotor onto the
  cycle, whose amplitude does not grow but does not decay either.  Where no step of the window starts
  after the last pulse (a shock in the window's last step or two) the amplitude condition holds
  trivially;
* the actual plant's equilibrium at the final Lambda and actual D_W must be linearly stable, as v1 (this
  is what the certificate certifies: a ring-down on a stable plant decays, a growing whirl after a shock
  fails, and an unstable plant fails whatever the amplitudes).

Reasons: v1's ``"stable"``, ``"whirl_in_window"``, ``"unstable_equilibrium"``, ``"no_equilibrium"``, plus
``"whirl_growing_after_shock"`` and ``"whirl_not_decaying_after_shock"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_env.envs.certify import Certificate, StabilityCertificate, linear_certificate

__all__ = ["AfterShockCertificate"]


@dataclass(frozen=True)
class AfterShockCertificate:
    """Certify the operating point at the horizon, forgiving a shock's ring-down (module docstring).

    Attributes:
        stable_amplitude: whirl amplitude (units of C) the window's steps before a shock must stay
            below, and the floor of the "not growing" test after it.
        hold_steps: length of the window (control steps).
    """

    stable_amplitude: float = 0.05
    hold_steps: int = 10

    # the same fields, checked the same way, as v1's certificate
    __post_init__ = StabilityCertificate.__post_init__

    def certify(
        self, window_amplitudes: list[float], plant: Any, bearing_number: float, foil_damping: float
    ) -> Certificate:
        """The verdict of the window and the plant (a :class:`~gfb_env.envs.commanded.CertifiedPlant`:
        its model, state, the episode's ``shocks``, the horizon's ``time_s`` and a step's ``step_s``)."""
        return self.judge(
            window_amplitudes,
            plant.shocks,
            plant.time_s,
            plant.step_s,
            plant.step_tau,
            plant.model,
            bearing_number,
            foil_damping,
            plant.state,
        )

    def judge(
        self,
        window_amplitudes: list[float],
        shocks: tuple,
        time_s: float,
        step_s: float,
        step_tau: float,
        model: Any,
        bearing_number: float,
        foil_damping: float,
        state: np.ndarray,
    ) -> Certificate:
        """The certificate of the window's last ``hold_steps`` true whirl amplitudes, ending at
        ``time_s`` (s) in steps of ``step_s`` (s), given the episode's ``shocks`` (objects with
        ``time_s`` and ``duration_ms``; ``step_tau``: a step in tau), and of the plant ``model`` at
        ``bearing_number`` with the actual ``foil_damping`` (``state``: the warm start)."""
        n, stable = self.hold_steps, self.stable_amplitude
        window = list(window_amplitudes[-n:])
        if len(window) < n or not all(math.isfinite(a) for a in window):
            return Certificate(False, "whirl_in_window", math.nan)
        start = time_s - n * step_s
        acting = [e for e in shocks if e.time_s <= time_s and e.time_s + 1e-3 * e.duration_ms > start]
        ref = None
        if not acting:
            if not all(a <= stable for a in window):
                return Certificate(False, "whirl_in_window", math.nan)
        else:
            first = min(max(int((min(e.time_s for e in acting) - start) // step_s), 0), n - 1)
            if not all(a <= stable for a in window[:first]):
                return Certificate(False, "whirl_in_window", math.nan)
            quiet = max(e.time_s + 1e-3 * e.duration_ms for e in acting)
            # the first step that starts after every acting pulse has ended (a relative tolerance
            # for the seconds of the step starts)
            ref = next((i for i in range(n) if start + i * step_s >= quiet - 1e-9 * step_s), None)
            if ref is not None and window[-1] > max(stable, window[ref]):
                return Certificate(False, "whirl_growing_after_shock", math.nan)
        verdict = linear_certificate(model, bearing_number, foil_damping, state)
        g = verdict.growth_rate
        if not verdict.certified:
            return verdict
        if ref is not None:
            decayed = stable + window[ref] * math.exp(g * (n - 1 - ref) * step_tau)
            if window[-1] > decayed:
                return Certificate(False, "whirl_not_decaying_after_shock", g)
        return Certificate(True, "stable", g)
