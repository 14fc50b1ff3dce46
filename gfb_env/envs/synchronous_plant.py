"""The rotor's 1x unbalance response superposed analytically (``synchronous_response="superposed"``).

With an unbalance on, the integrator caps its step at 1/32 revolution (``steps_per_revolution``): a
v2 control step near equilibrium takes ~4x the integrator steps of an unforced one.  The synchronous
response is linear in the unbalance to 0.2-1.1 % at the drawn unbalances, so where the plant is in the
linear regime the env steps it *unforced* (no per-revolution cap) and adds the steady 1x response
``Re(X e^{i theta})`` to everything the sensors and the judge see: the recorded samples (rotor
position and velocity, pressure taps, film thickness), hence the monitor's 1x vector and direct
pk-pk, the whirl amplitude and the touchdown test, and the state at the step's end.  ``X`` solves ``(i
Lambda I - J) X = b`` at the unforced state (:class:`gfb_env.synchronous.SynchronousSolver`, one call
per control step); over a step it is interpolated linearly in time between its values at the two ends
(the signal is continuous from step to step), theta is the integrator's own rotation angle.

The plant's true state is always ``s_u + Re(X e^{i theta})`` (in full state space).  A control step is
superposed while (thresholds below, measured in ``experiments/synchronous_response_check.py``):

- the least damped mode decays: its growth rate ``Re(lambda) < -MIN_DECAY_RATE`` (tracked per step;
  it crosses 0 at ``Lambda_c``, where the unbalance that throws the rotor onto the whirl goes to 0);
- the free motion is small: the last step's deviation amplitude (the judge's whirl amplitude of the
  unforced samples; stepped, of the samples less the 1x) below ``MAX_DEVIATION`` -- the switch-on
  transient, a shock's or a ramp's transient, a whirl;
- no base shock or velocity kick falls in the step;
- the film stays far from touchdown (``MIN_FILM``: the unforced integrator does not see the 1x in
  its touchdown event).

Elsewhere the forcing is stepped as with ``"stepped"``.  A switch happens between control steps and is
continuous: to stepped, the integrator restarts from ``s_u + Re(X e^{i theta})`` with the unbalance
on; back, from the state minus it, unforced (same time, angle, sample grid, step size and pending
shocks; hysteresis: back only at half the thresholds).  At ``reset`` the start state is the true
state and carries no 1x yet: the switch-on transient (the size of the 1x orbit) is stepped.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable

import numpy as np

from gfb_env.envs._superposition_kernels import stepped_residual_kernel, superpose_kernel
from gfb_env.forcing import Unbalance
from gfb_env.integrator import AdvanceResult, TrapezoidalIntegrator
from gfb_env.integrator.results import Trajectory
from gfb_env.synchronous import SynchronousSolver, synchronous_forcing

__all__ = ["SYNCHRONOUS_RESPONSES", "SuperposedResponse"]

#: The values of ``synchronous_response``: the forcing through the integrator (today's plant, bit for
#: bit) or the analytic 1x response superposed where valid.
SYNCHRONOUS_RESPONSES = ("stepped", "superposed")

#: Superposing needs the least damped mode to decay faster than this (1/tau): 1/500 tau, about 1.5 %
#: of Lambda_c below it on the nominal plant at D_W = 1 (growth rate -0.0018 at Lambda 0.65, -0.0007
#: at 0.655, Lambda_c 0.659).  Measured (``experiments/synchronous_response_check.py --part
#: linearity``): held there on the forced orbit of the largest drawn unbalance (U = 0.02), the stepped
#: run's 1x agrees with the analytic X within 0.05 % in amplitude and 0.01 deg in phase down to a growth
#: rate of -0.0007 (no throw-over); the threshold leaves a factor ~3, and a growing whirl (rate > 0)
#: is never superposed.
MIN_DECAY_RATE = 0.002
#: Largest deviation amplitude (units of C) of the unforced motion from its trend (the free transient
#: of a shock, a ramp's start, the switch-on) for which a step is superposed: 0.001 C (0.05 um on the
#: nominal 50 um clearance, a sixth of the probes' 0.3 um noise).  Not a linearity limit (the 1x is
#: linear far beyond) but the unforced integrator's: without the per-revolution cap it takes steps
#: of up to ``max_step`` = 2 tau, whose frequency warping of the lightly damped whirl mode ((h
#: omega)^2 / 12 = 2 % at Lambda 0.65) dephases a slowly decaying free transient (measured: 19-86 %
#: of a switch-on transient of 0.023 C at Lambda 0.62-0.65 over 600 tau, against 1-2.5 % stepped).
#: A transient below this bound cannot be wrong by more than about itself.
MAX_DEVIATION = 0.001
#: Smallest film thickness (units of C) of a superposed step: 5x the tasks' touchdown threshold.
MIN_FILM = 0.1
#: The tracked eigenvalue is updated every step while its growth rate is above -0.02 (10x the threshold),
#: stepped, or when Lambda moved by 0.002 (the growth rate by ~5e-4: d Re(lambda) / d Lambda ~ 0.23 on
#: the nominal plant) or D_W by 2 % since the last update; otherwise it cannot have moved.
TRACK_ALWAYS_ABOVE = 0.02
TRACK_BEARING_NUMBER_CHANGE = 0.002
TRACK_LOG_DAMPING_CHANGE = 0.02
#: Back to superposed only well inside the thresholds (no chattering at the boundary).
HYSTERESIS = 0.5


class SuperposedResponse:
    """The superposed 1x response of one env's episode (module docstring).

    Made by :meth:`start` at ``reset``; the env calls :meth:`before_step` before preparing a step,
    :meth:`after_step` on its result and reads :meth:`true_state`.  Copied into snapshots.
    """

    def __init__(
        self,
        solver: SynchronousSolver,
        unbalance: Unbalance,
        whirl_amplitude: Callable[[np.ndarray, np.ndarray, np.ndarray], float],
    ):
        self.solver = solver
        self.unbalance = unbalance
        self._whirl_amplitude = whirl_amplitude
        self.x = np.zeros(solver.model.layout.size, np.complex128)  # X at the integrator's time
        self.superposed = False
        self.deviation = 0.0
        self.min_film = math.inf
        #: counts: control steps superposed, stepped, and switches of either kind
        self.superposed_steps = 0
        self.stepped_steps = 0
        self.switches = 0
        self._rate = 0.0
        self._tracked_at = (math.inf, 1.0)  # (Lambda, D_W) of the last tracking step
        self._film: tuple[np.ndarray | None, np.ndarray | None] = (None, None)  # (X, its film response)
        self._indices: tuple[np.ndarray, np.ndarray] | None = None  # (probe indices, their superposed idx)

    def __deepcopy__(self, memo: dict) -> SuperposedResponse:
        # the solver is workspace (its tracked mode is state): share the arrays, copy the state
        new = copy.copy(self)
        new.x = self.x.copy()
        new.solver = copy.copy(self.solver)
        new.solver.mode_vector = self.solver.mode_vector.copy()
        return new

    # ------------------------------------------------------------------------------------------
    @classmethod
    def start(
        cls,
        solver: SynchronousSolver,
        integ: TrapezoidalIntegrator,
        unbalance: Unbalance,
        whirl_amplitude: Callable[[np.ndarray, np.ndarray, np.ndarray], float],
    ) -> SuperposedResponse:
        """At ``reset``, the integrator at the episode's start with the unbalance on (stepped): the
        mode is found, X solved, and the integrator restarted unforced if superposing is valid."""
        self = cls(solver, unbalance, whirl_amplitude)
        s, lam, dw = integ.state, integ.bearing_number, integ.foil_damping
        solver.start_mode(s, lam, dw)
        self._solve(s, lam, dw)
        self.min_film = solver.model.min_film_thickness(s)
        # the true start carries no 1x yet: the switch-on transient is the 1x orbit itself
        L = solver.model.layout
        self.deviation = math.hypot(abs(self.x[L.xi_index]), abs(self.x[L.eta_index]))
        if self._valid(entering=True):
            self._switch(integ, to_superposed=True)
        return self

    @property
    def growth_rate(self) -> float:
        """Re of the tracked least damped eigenvalue of J (1/tau)."""
        return float(self.solver.mode.real)

    def _solve(self, s: np.ndarray, lam: float, dw: float) -> None:
        if lam <= 0:
            self.x[:] = 0.0
            return
        b = synchronous_forcing(self.solver.model, self.unbalance, lam, self._rate)
        # the eigenvalue moves only with the operating point: far from the threshold and with Lambda
        # and D_W where they were at the last tracking step it is not re-tracked (half the solve)
        lt, dt = self._tracked_at
        track = (
            self.growth_rate > -TRACK_ALWAYS_ABOVE
            or abs(lam - lt) > TRACK_BEARING_NUMBER_CHANGE
            or abs(math.log(dw / dt)) > TRACK_LOG_DAMPING_CHANGE
            or not self.superposed
        )
        self.x = self.solver.update(s, lam, dw, b, track=track)
        if track:
            self._tracked_at = (lam, dw)

    def _valid(self, entering: bool) -> bool:
        k = HYSTERESIS if entering else 1.0
        return (
            self.growth_rate < -MIN_DECAY_RATE / k
            and self.deviation < k * MAX_DEVIATION
            and self.min_film > MIN_FILM / k
        )

    def _offset(self, theta: float) -> np.ndarray:
        return (self.x * complex(math.cos(theta), math.sin(theta))).real

    def true_state(self, integ: TrapezoidalIntegrator) -> np.ndarray:
        """The plant's state: the integrator's, plus the 1x response while superposed."""
        s = integ.state
        if self.superposed:
            s += self._offset(integ.rotation_angle)
        return s

    def _switch(self, integ: TrapezoidalIntegrator, to_superposed: bool) -> None:
        """Restart the integrator at the same true state with the forcing moved (module docstring);
        the pending base shocks are kept."""
        off = self._offset(integ.rotation_angle)
        s = integ.state - off if to_superposed else integ.state + off
        before = integ.snapshot()
        integ.reset(s, integ.bearing_number, integ.foil_damping, integ.tau, integ.rotation_angle)
        integ.set_unbalance(None if to_superposed else self.unbalance)
        for q in before.shocks:
            integ.add_shock(q)
        # the sample grid goes on (a sample at the boundary is not recorded twice), the counters too
        integ.restore(
            dataclasses.replace(
                integ.snapshot(),
                step=before.step,
                last_record_tau=before.last_record_tau,
                statistics=before.statistics,
            )
        )
        self.superposed = to_superposed

    # ------------------------------------------------------------------------------------------
    def _superposed_indices(self, probe_indices: np.ndarray) -> np.ndarray:
        """The state indices of the rotor's 4 entries and the recorded taps (made once per taps)."""
        cached = self._indices
        if cached is not None and cached[0] is probe_indices:
            return cached[1]
        L = self.solver.model.layout
        rotor = L.rotor_offset + np.arange(4)
        idx = np.concatenate([rotor, np.asarray(probe_indices, np.int64)]).astype(np.int64)
        self._indices = (probe_indices, idx)
        return idx

    def before_step(self, integ: TrapezoidalIntegrator, kick: bool = False) -> None:
        """Decide the mode of the coming step from the last one (and switch if it changes): a step
        with a base shock (scheduled on ``integ``) or a velocity ``kick`` is stepped (its transient
        is large)."""
        valid = (not kick) and (not integ.shocks) and self._valid(entering=not self.superposed)
        if valid and not self.superposed:
            # after stepping (a whirl, a shock) the tracked eigenvalue may have wandered to another
            # mode: find the least damped one afresh at the orbit's centre before superposing
            s = integ.state - self._offset(integ.rotation_angle)
            self.solver.start_mode(s, integ.bearing_number, integ.foil_damping)
            valid = self._valid(entering=True)
        if valid != self.superposed:
            self._switch(integ, to_superposed=valid)
            self.switches += 1

    def after_step(
        self,
        integ: TrapezoidalIntegrator,
        tau0: float,
        theta0: float,
        lam0: float,
        probe_indices: np.ndarray,
        result: AdvanceResult | Exception,
    ) -> AdvanceResult | Exception:
        """The plant's result of a step that started at ``tau0`` with the angle ``theta0`` and
        ``Lambda = lam0`` (``probe_indices``: the recorded pressure taps): X at its end is solved;
        while superposed, the 1x response is added to the samples, the film thickness and the ranges
        (the integrator's ``result`` is unforced).  A numerical failure is passed on (the episode
        ends); a singular solve keeps X and steps the forcing from the next step on."""
        if isinstance(result, Exception):
            self.deviation = math.inf
            return result
        span = integ.tau - tau0
        lam1 = integ.bearing_number
        self._rate = (lam1 - lam0) / span if span > 0 else 0.0
        x0 = self.x
        # J at the unforced state: stepped, the state less the 1x (the orbit's centre)
        s1 = integ.state if self.superposed else integ.state - self._offset(integ.rotation_angle)
        try:
            self._solve(s1, lam1, integ.foil_damping)
        except np.linalg.LinAlgError:
            self.x = x0.copy()
            self.solver.mode = complex(math.inf, 0.0)
        tr = result.trajectory
        L = self.solver.model.layout
        n = len(tr.tau)
        rate = self._rate
        if self.superposed:
            self.superposed_steps += 1
            idx = self._superposed_indices(probe_indices)
            # the film's 1x at the step's start was computed at the end of the last one (same X)
            h0 = self._film[1] if self._film[0] is x0 else self.solver.film_response(x0)
            h1 = self.solver.film_response(self.x)
            self._film = (self.x, h1)
            i_min = int(self.solver.model.film_thickness(s1).argmin())  # (s1: the state, unforced)
            self.deviation = self._whirl_amplitude(tr.tau, tr.xi, tr.eta)
            # the 1x added to every sample in one compiled call (superpose_reference: the numpy of it)
            rotor = np.array((tr.xi, tr.eta, tr.xi_dot, tr.eta_dot))  # (4, n), one copy
            out_rotor, h, probes = np.empty((4, n)), np.empty(n), np.empty(tr.probes.shape)
            ranges = np.empty(5)
            superpose_kernel(
                tr.tau, rotor, tr.min_film_thickness, tr.probes, tau0, theta0, lam0, rate, span, x0, self.x,
                idx, h0[i_min], h1[i_min], out_rotor, h, probes, ranges,
            )  # fmt: skip
            xi, eta = out_rotor[0], out_rotor[1]
            traj = Trajectory(
                tr.tau, xi, eta, out_rotor[2], out_rotor[3], h, probes, tr.bearing_number, tr.foil_damping
            )
            if n:
                min_h, x_lo, x_hi, e_lo, e_hi = ranges.tolist()
                min_h, xr, er = min_h, (x_lo, x_hi), (e_lo, e_hi)
            else:
                min_h, xr, er = result.min_film_thickness, result.xi_range, result.eta_range
            # (dataclasses.replace's field walk, without it: the same result)
            result = AdvanceResult(
                result.status, result.tau, traj, result.touchdown, result.statistics, min_h, xr, er,
                result.max_eccentricity, result.message,
            )  # fmt: skip
        else:
            self.stepped_steps += 1
            # the deviation of the stepped motion: the samples less the 1x response
            less = np.empty((2, n))
            stepped_residual_kernel(
                tr.tau, tr.xi, tr.eta, tau0, theta0, lam0, rate, span, x0[L.xi_index], self.x[L.xi_index],
                x0[L.eta_index], self.x[L.eta_index], less,
            )  # fmt: skip
            self.deviation = self._whirl_amplitude(tr.tau, less[0], less[1])
        if not math.isfinite(self.deviation):
            self.deviation = 0.0
        self.min_film = float(result.min_film_thickness)
        return result
