"""Base Gymnasium environment: speed and foil-damping control of a gas foil bearing (GFB) rotor.

The plant is the viscoelastic GFB rotor model of Leister, Baum & Seemann (paper Sect. 2,
:class:`~gfb_env.model.GFBModel`), advanced by the adaptive trapezoidal integrator
(:class:`~gfb_env.integrator.TrapezoidalIntegrator`).  One control step spans ``control_interval``
units of tau (several whirl periods ``~4 pi / Lambda``) and many integrator steps; over a control step
the bearing number Lambda and the foil damping D_W ramp linearly from their current values to the
commanded ones.

One control step is four stages (:meth:`GFBEnv.step`): *command* (sanitise the action; the motor
turns the speed action into Lambda at the step's end, the foil-damping actuator turns the damping
command into the actual D_W at the step's end: :mod:`gfb_env.machine`), *plant* (a disturbance kick,
then the integrator over the control interval), *judge* (stability, hold, success, termination and the
task's reward terms, from the true plant) and *emit* (the observation, built from the sensors:
proximity probes and pressure taps, and info).  With the default (ideal) actuator and sensors the
machine is exactly v0's.  Everything that changes within an episode is
one :class:`~gfb_env.envs.episode.Episode`; the configuration is one frozen
:class:`~gfb_env.envs.config.EnvConfig`.

Subclasses define the task (:meth:`GFBEnv._setup_episode`, :meth:`GFBEnv._reward_terms` and optionally
:meth:`GFBEnv._is_at_target` and :attr:`GFBEnv.reset_options`); see ``run_up.py``,
``run_up_randomized.py`` and ``whirl_recovery.py``, ``docs/envs.md`` and ``docs/extending.md``.

Scaling of the observations: the sensors measure in physical units and the observation divides them
by the scales of the *nominal* bearing of the task (clearance C_nom, time scale T_nom, ``speed_scale_rpm``).
For the nominal bearing this is exactly the nondimensional state of the paper (xi, eta in units of C,
velocities in C / T); for a randomised bearing (other C) the observation does not reveal the drawn
clearance except through the physics.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gfb_env.envs.config import DEFAULT_GRID, EnvConfig
from gfb_env.envs.episode import Episode, EpisodeSetup, History, StepOutcome, TerminationReason
from gfb_env.envs.render import EpisodeRenderer
from gfb_env.envs.units import (
    N_ROTOR_OBS,
    OBS_DAMPING,
    OBS_ETA,
    OBS_ETA_DOT,
    OBS_ETA_EXTENT,
    OBS_SPEED,
    OBS_XI,
    OBS_XI_DOT,
    OBS_XI_EXTENT,
    ActionMap,
    ObservationLayout,
)
from gfb_env.forcing import HalfSineShock
from gfb_env.integrator import AdvanceResult, IntegrationError, TrapezoidalIntegrator
from gfb_env.machine import FoilDampingActuator, Motor, PressureTaps, ProximityProbes
from gfb_env.model import GFBModel, Grid, Structure
from gfb_env.params import BearingParameters

__all__ = ["GFBEnv", "EpisodeSetup", "StepOutcome", "DEFAULT_GRID", "viscoelastic_model"]

#: The numerical failures a control step survives (reported as ``"solver_failure"``); anything else is
#: a programming error and propagates.
NUMERICAL_FAILURES = (IntegrationError, FloatingPointError, np.linalg.LinAlgError)


@dataclass(frozen=True)
class PlantTrace:
    """What one control step of the plant leaves besides its :class:`StepOutcome`."""

    xi_range: tuple[float, float]
    eta_range: tuple[float, float]
    orbit: tuple[np.ndarray, np.ndarray]
    integrator_steps: int


class _FromConfig:
    """A read-only attribute of the env forwarded to its :class:`EnvConfig` (one owner)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        return self if obj is None else getattr(obj.config, self.name)


class GFBEnv(gym.Env):
    """Common machinery of the GFB tasks (actions, observations, integration, snapshots, rendering).

    Keyword arguments are those of :class:`~gfb_env.envs.config.EnvConfig` (``grid``,
    ``control_interval``, ``max_acceleration_rpm_per_s``, ``speed_range_rpm``, ``damping_range``,
    ``n_pressure_probes``, ``observation_noise``, ``touchdown_film_thickness``, ``stable_amplitude``,
    ``hold_steps``, ``disturbance_probability``, ``disturbance_magnitude``, ``speed_scale_rpm``,
    ``nominal_bearing``, ``integrator_options``, and the machine's components ``motor``,
    ``damping_actuator``, ``proximity_probes``, ``pressure_taps``: objects of :mod:`gfb_env.machine` or
    dicts of their fields), plus ``render_mode`` (``None``, ``"rgb_array"`` or
    ``"human"``).  An unknown keyword or a bad value raises ``ValueError`` naming it.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    #: keys that ``reset(options=...)`` accepts (the task validates their values)
    reset_options: ClassVar[tuple[str, ...]] = ()

    def __init__(self, render_mode: str | None = None, **kwargs: Any):
        super().__init__()
        self.config = EnvConfig.from_kwargs(kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.actions = ActionMap(cfg.damping_range, cfg.max_acceleration_rpm_per_s)
        extra = self._extra_observation_bounds()
        self.observation_layout = ObservationLayout(
            n_pressure_probes=cfg.n_pressure_probes,
            speed_scale_rpm=cfg.speed_scale_rpm,
            max_speed_rpm=cfg.speed_range_rpm[1],
            extra_low=tuple(float(x) for x in extra[0]) if extra is not None else (),
            extra_high=tuple(float(x) for x in extra[1]) if extra is not None else (),
            extra_names=self._extra_observation_names(),
        )
        # record the trajectory ~120 times per control step (>= 30 samples per whirl period)
        self.record_interval = cfg.control_interval / 120.0
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        low, high = self.observation_layout.bounds()
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._integ: TrapezoidalIntegrator | None = None
        self._ep: Episode | None = None
        self._renderer: EpisodeRenderer | None = None

    # ------------------------------------------------------------------------------------------
    # the configuration, read-only (one owner: self.config)
    grid = _FromConfig()
    control_interval = _FromConfig()
    max_acceleration_rpm_per_s = _FromConfig()
    speed_range_rpm = _FromConfig()
    damping_range = _FromConfig()
    n_pressure_probes = _FromConfig()
    observation_noise = _FromConfig()
    touchdown_film_thickness = _FromConfig()
    stable_amplitude = _FromConfig()
    hold_steps = _FromConfig()
    disturbance_probability = _FromConfig()
    disturbance_magnitude = _FromConfig()
    speed_scale_rpm = _FromConfig()
    nominal_bearing = _FromConfig()
    motor: Motor = _FromConfig()  # type: ignore[assignment]
    damping_actuator: FoilDampingActuator = _FromConfig()  # type: ignore[assignment]
    proximity_probes: ProximityProbes = _FromConfig()  # type: ignore[assignment]
    pressure_taps: PressureTaps = _FromConfig()  # type: ignore[assignment]

    # ------------------------------------------------------------------------------------------
    # task hooks
    def _setup_episode(self, options: Mapping[str, Any]) -> EpisodeSetup:  # pragma: no cover - abstract
        """The plant, its start and the task's record for a new episode (``options`` already checked
        against :attr:`reset_options`; the task validates the values)."""
        raise NotImplementedError

    def _reward_terms(self, out: StepOutcome, success: bool) -> dict[str, float]:  # pragma: no cover
        """The named terms of the reward of one control step (they sum to the reward)."""
        raise NotImplementedError

    def _is_at_target(self, out: StepOutcome) -> bool:
        """Whether the speed counts for a success (default: any speed)."""
        return True

    def _step_success(self, out: StepOutcome, stable: bool) -> bool:
        """Whether this step completes a success (``stable``: no touchdown, no failure, small whirl).
        Default (v0): ``hold_steps`` consecutive stable steps at the target."""
        ep = self._ep
        ep.hold = ep.hold + 1 if (stable and self._is_at_target(out)) else 0
        return ep.hold >= self.hold_steps

    def _horizon_reached(self) -> bool:
        """Whether a fixed-horizon task ends after this step (default: no horizon; a TimeLimit truncates)."""
        return False

    def _extra_observation_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounds of task-specific observations appended after the probes (None: none)."""
        return None

    def _extra_observation_names(self) -> tuple[str, ...]:
        """Names of the task-specific observations (empty: ``extra_0``, ``extra_1``, ...)."""
        return ()

    def _extra_observation(self) -> np.ndarray | None:
        return None

    # ------------------------------------------------------------------------------------------
    @property
    def episode(self) -> Episode:
        """The current episode's state."""
        if self._ep is None:
            raise RuntimeError("call reset() first")
        return self._ep

    @property
    def model(self) -> GFBModel:
        """The plant of the current episode."""
        return self.episode.model

    @property
    def bearing(self) -> BearingParameters:
        """Dimensional parameters of the current episode's bearing."""
        return self.episode.bearing

    def damping_from_action(self, a: float) -> float:
        """``D_W`` of the damping action ``a`` (:meth:`ActionMap.damping_from_action`)."""
        return self.actions.damping_from_action(a)

    def action_from_damping(self, d: float) -> float:
        """The damping action of ``D_W = d`` (:meth:`ActionMap.action_from_damping`)."""
        return self.actions.action_from_damping(d)

    def max_rate(self, bearing: BearingParameters | None = None) -> float:
        """Motor limit as ``dLambda/dtau`` of ``bearing`` (default: the episode's)."""
        return self.actions.max_rate(bearing if bearing is not None else self.bearing)

    def bearing_number_limits(self, bearing: BearingParameters | None = None) -> tuple[float, float]:
        """Lambda at the ends of ``speed_range_rpm`` for ``bearing`` (default: the episode's)."""
        b = bearing if bearing is not None else self.bearing
        return b.bearing_number_at(self.speed_range_rpm[0]), b.bearing_number_at(self.speed_range_rpm[1])

    def new_integrator(
        self, model: GFBModel, state: np.ndarray, bearing_number: float, foil_damping: float
    ) -> TrapezoidalIntegrator:
        """The one place where the environments make an integrator: the configured options and the
        env's touchdown threshold."""
        return TrapezoidalIntegrator(
            model,
            state,
            bearing_number,
            foil_damping,
            touchdown_film_thickness=self.touchdown_film_thickness,
            options=self.config.integrator,
        )

    # ------------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        setup = self._setup_episode(self._check_options(options))
        if self._integ is not None and self._integ.model is setup.model:
            self._integ.reset(setup.state, setup.bearing_number, setup.foil_damping)
        else:
            self._integ = self.new_integrator(
                setup.model, setup.state, setup.bearing_number, setup.foil_damping
            )
        self._probe_idx = setup.model.layout.midplane_probe_indices(self.n_pressure_probes)
        b, nb = setup.bearing, self.nominal_bearing
        pos_scale = b.clearance_m / nb.clearance_m
        rotor = setup.model.layout.rotor(setup.state)
        history = History()
        history.append(self._integ.tau, setup.bearing_number, setup.foil_damping, 0.0)
        # the machine's per-episode state, drawn after the task's draws (an ideal machine draws nothing)
        rng = self.np_random
        act = self.damping_actuator
        gain = setup.damping_gain if setup.damping_gain is not None else act.draw_gain(rng)
        actuator = act.start(setup.foil_damping, gain)
        probe_bias = self.proximity_probes.draw_bias(rng)
        tap_bias = self.pressure_taps.draw_bias(rng, self.n_pressure_probes)
        unbalance, grade = self.config.rotor_balance.draw(rng, b, self.speed_range_rpm[1])
        self._integ.set_unbalance(unbalance)
        self._ep = Episode(
            model=setup.model,
            bearing=b,
            task=setup.task,
            task_info=dict(setup.info),
            position_scale=pos_scale,
            velocity_scale=pos_scale * nb.time_scale_s / b.time_scale_s,
            min_film_thickness=setup.model.min_film_thickness(setup.state),
            orbit=(np.array([rotor[0]]), np.array([rotor[1]])),
            history=history,
            actuator=actuator,
            probe_bias_um=probe_bias,
            tap_bias_kpa=tap_bias,
            balance_grade_mm_s=grade,
            command=setup.command,
        )
        return self._emit()

    def _check_options(self, options: Any) -> Mapping[str, Any]:
        if options is None:
            return {}
        if not isinstance(options, Mapping):
            raise ValueError(f"options must be a dict or None, got {type(options).__name__}")
        for key in options:
            if key not in self.reset_options:
                allowed = ", ".join(self.reset_options) if self.reset_options else "none"
                raise ValueError(f"reset options: unknown key {key!r} (allowed: {allowed})")
        return options

    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict]:
        self._check_can_step()
        a, sanitised = self._sanitise(action)
        lam0, bearing_number, foil_damping, kick = self._prepare_plant(a)
        res = self._run_integrator(bearing_number, foil_damping)
        out, trace = self._plant_outcome(lam0, res)
        self._judge(out, trace, a, sanitised, kick)
        obs, info = self._emit()
        return obs, self._ep.reward, self._ep.done, False, info

    # The stages of :meth:`step`, also called one at a time over a batch of envs by
    # :class:`~gfb_env.envs.vector.GFBVectorEnv` (each env's random draws stay in the same order).
    def _check_can_step(self) -> None:
        if self._integ is None or self._ep is None:
            raise RuntimeError("call reset() before step()")
        if self._ep.done:
            raise RuntimeError("the episode has ended; call reset()")

    def _prepare_plant(self, a: np.ndarray) -> tuple[float, float, float, bool]:
        """Command, kick and shocks of one step: Lambda at the start, Lambda and D_W commanded for the
        end of the step, and whether a kick was applied (the integrator is then ready to advance)."""
        bearing_number, foil_damping = self._command(a)
        kick = self._maybe_kick()
        lam0 = self._integ.bearing_number
        self._schedule_shocks()
        return lam0, bearing_number, foil_damping, kick

    # ---- command ------------------------------------------------------------------------------
    def _sanitise(self, action: Any) -> tuple[np.ndarray, bool]:
        """nan -> 0, +-inf and out-of-range -> clipped to [-1, 1]; reports whether anything changed."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,):
            raise ValueError(f"action must have shape (2,), got {np.shape(action)}")
        # two scalars: plain Python is ~10x cheaper than nan_to_num + clip on a 2-vector, same values
        x0, x1 = float(a[0]), float(a[1])
        c0, c1 = _clip_action(x0), _clip_action(x1)
        return np.array([c0, c1]), (c0 != x0 or c1 != x1)

    def _command(self, a: np.ndarray) -> tuple[float, float]:
        """Lambda and the actual D_W at the end of the control step: the motor's speed ramp (within
        the speed range) and the actuator's response to the damping command held over the step (its
        state moves to the step's end)."""
        ep = self._ep
        b = ep.bearing
        lam1 = self.motor.bearing_number_at_step_end(
            self._integ.bearing_number, a[0], b, self.control_interval, self.bearing_number_limits(b)
        )
        commanded = self.actions.damping_from_action(a[1])
        ep.actuator = self.damping_actuator.step(ep.actuator, commanded, b.seconds(self.control_interval))
        return lam1, ep.actuator.foil_damping

    # ---- plant --------------------------------------------------------------------------------
    def _maybe_kick(self) -> bool:
        """Random disturbance: a journal velocity impulse (drawn from ``self.np_random``)."""
        if self.disturbance_probability <= 0 or self.disturbance_magnitude <= 0:
            return False
        u, angle = self.np_random.random(), self.np_random.uniform(0.0, 2.0 * math.pi)
        if u >= self.disturbance_probability:
            return False
        integ, L = self._integ, self._ep.model.layout
        s = integ.state
        xi, eta, xi_dot, eta_dot = L.rotor(s)
        dv = self.disturbance_magnitude / self._ep.velocity_scale
        s = L.with_rotor(s, xi, eta, xi_dot + dv * math.cos(angle), eta_dot + dv * math.sin(angle))
        # a discontinuity: restart the step history (deterministic, like any reset)
        integ.reset(s, integ.bearing_number, integ.foil_damping, integ.tau, integ.rotation_angle)
        return True

    def _run_integrator(self, bearing_number: float, foil_damping: float) -> AdvanceResult | Exception:
        """The integrator over one control interval (the only compiled work of a step): its result, or
        the numerical failure it raised (judged by :meth:`_plant_outcome`)."""
        integ = self._integ
        try:
            return integ.advance(
                integ.tau + self.control_interval,
                bearing_number,
                foil_damping,
                record_interval=self.record_interval,
                record_indices=self._probe_idx,
                raise_on_failure=False,
            )
        except NUMERICAL_FAILURES as exc:
            return exc

    def _plant_outcome(self, lam0: float, res: AdvanceResult | Exception) -> tuple[StepOutcome, PlantTrace]:
        """What the plant did in the step (``lam0``: Lambda at its start) from the integrator's result."""
        integ, ep = self._integ, self._ep
        touchdown = failure = False
        steps = 0
        try:
            if isinstance(res, Exception):
                raise res
            touchdown = res.status == "touchdown"
            failure = res.status in ("failed", "max_steps")
            steps = res.steps
            tr = res.trajectory
            amp = _whirl_amplitude(tr.tau, tr.xi, tr.eta)
            min_h = float(res.min_film_thickness)
            xr, er = res.xi_range, res.eta_range
            orbit = (tr.xi, tr.eta)
        except NUMERICAL_FAILURES:
            failure = True
            amp, min_h = math.nan, math.nan
            xr = er = (math.nan, math.nan)
            orbit = ep.orbit
        if not math.isfinite(amp):
            amp = 0.5 * max(_span(xr), _span(er)) if math.isfinite(_span(xr) + _span(er)) else 0.0
        if not math.isfinite(min_h):
            min_h = ep.model.min_film_thickness(integ.state)
        out = StepOutcome(lam0, integ.bearing_number, integ.foil_damping, amp, min_h, touchdown, failure)
        return out, PlantTrace(xr, er, orbit, steps)

    def _schedule_shocks(self) -> None:
        """Random base shocks starting in this control step (drawn from ``self.np_random``; none and no
        draw without shock arrivals), handed to the integrator as half-sine pulses."""
        integ, ep, b = self._integ, self._ep, self._ep.bearing
        t0 = b.seconds(integ.tau)
        events = self.config.shock_arrivals.draw(self.np_random, t0, t0 + b.seconds(self.control_interval))
        for e in events:
            shock = HalfSineShock.from_physical(b, e.time_s, e.peak_g, e.duration_ms, e.direction_deg)
            # tau -> s -> tau may round below the current time by an ulp
            integ.add_shock(dataclasses.replace(shock, start_tau=max(shock.start_tau, integ.tau)))
        ep.shocks = tuple(events)
        ep.shock_count += len(events)

    # ---- judge --------------------------------------------------------------------------------
    def _judge(self, out: StepOutcome, trace: PlantTrace, a: np.ndarray, sanitised: bool, kick: bool) -> None:
        """Stability, hold, success, termination and reward of the step, written into the episode."""
        ep = self._ep
        stable = (
            (not out.touchdown) and (not out.solver_failure) and out.whirl_amplitude <= self.stable_amplitude
        )
        success = self._step_success(out, stable)
        terms = self._reward_terms(out, success)
        ep.reward_terms = terms
        ep.reward = float(sum(terms.values()))
        ep.episode_return += ep.reward
        ep.step += 1
        ep.xi_range, ep.eta_range = trace.xi_range, trace.eta_range
        ep.whirl_amplitude, ep.min_film_thickness = out.whirl_amplitude, out.min_film_thickness
        ep.orbit = trace.orbit
        ep.integrator_steps += trace.integrator_steps
        ep.history.append(self._integ.tau, out.bearing_number, out.foil_damping, out.whirl_amplitude)
        ep.last_action, ep.action_sanitised, ep.disturbance = a, sanitised, kick
        if out.solver_failure:
            ep.termination = TerminationReason.SOLVER_FAILURE
        elif out.touchdown:
            ep.termination = TerminationReason.TOUCHDOWN
        elif success:
            ep.termination = TerminationReason.SUCCESS
        elif self._horizon_reached():
            ep.termination = TerminationReason.HORIZON

    # ---- emit ---------------------------------------------------------------------------------
    def _emit(self) -> tuple[np.ndarray, dict]:
        raw, info = self._emit_raw()
        return self._finish_observation(raw), info

    def _emit_raw(self) -> tuple[np.ndarray, dict]:
        """The unclipped float64 observation (:meth:`_raw_observation`) and the info."""
        raw, info = self._raw_observation(), self._info()
        if self.render_mode == "human":
            self.render()
        return raw, info

    def _observation(self) -> np.ndarray:
        return self._finish_observation(self._raw_observation())

    def _finish_observation(self, raw: np.ndarray) -> np.ndarray:
        """NaN/inf -> 0, clipped to the observation space, float32: elementwise, so the vector env
        finishes a whole batch ``(n_envs, size)`` in one call with the same bits."""
        obs = np.nan_to_num(raw, nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(obs, self.observation_space.low, self.observation_space.high).astype(np.float32)

    def _raw_observation(self) -> np.ndarray:
        ep, s = self._ep, self._integ.state
        xi, eta, xi_dot, eta_dot = ep.model.layout.rotor(s)
        n = N_ROTOR_OBS + self.n_pressure_probes
        obs = np.zeros(n, dtype=np.float64)
        obs[OBS_XI], obs[OBS_ETA] = xi * ep.position_scale, eta * ep.position_scale
        obs[OBS_XI_DOT], obs[OBS_ETA_DOT] = xi_dot * ep.velocity_scale, eta_dot * ep.velocity_scale
        obs[OBS_XI_EXTENT] = _span(ep.xi_range) * ep.position_scale
        obs[OBS_ETA_EXTENT] = _span(ep.eta_range) * ep.position_scale
        obs[N_ROTOR_OBS:] = s[self._probe_idx]
        self._add_sensor_errors(obs, xi, eta)
        if self.observation_noise > 0:
            measured = self.observation_layout.measured_indices
            obs[measured] += self.observation_noise * self.np_random.standard_normal(len(measured))
        obs[OBS_SPEED] = ep.bearing.speed_rpm_at(self._integ.bearing_number) / self.speed_scale_rpm
        # the actuator's position feedback: the damping it believes it sets (the gain is hidden)
        obs[OBS_DAMPING] = self.actions.action_from_damping(self._integ.foil_damping / ep.actuator.gain)
        extra = self._extra_observation()
        if extra is not None:
            obs = np.concatenate([obs, extra])
        return obs

    def _add_sensor_errors(self, obs: np.ndarray, xi: float, eta: float) -> None:
        """Add what the probes and taps add to the truth (nothing, and no draw, for ideal sensors).

        The readings are in um and kPa; the observation is in the nominal bearing's units (C_nom,
        C_nom / T_nom, p0), so an error maps to it independently of the episode's bearing."""
        ep, nb = self._ep, self.nominal_bearing
        c_um = ep.bearing.clearance_m * 1e6
        probes = self.proximity_probes
        if probes.is_ideal:
            ep.probe_readings_um = np.array(probes.read_um(xi * c_um, eta * c_um, ep.probe_bias_um))
        else:
            cnom_um = nb.clearance_m * 1e6
            xs, es = ep.orbit
            if len(xs) == 0:  # a step that ended at once (touchdown in its first integrator step)
                xs, es = np.array([xi]), np.array([eta])
            err = probes.measurement_errors(
                self.np_random,
                np.asarray(xs) * c_um,
                np.asarray(es) * c_um,
                ep.bearing.seconds(self.record_interval),
                ep.probe_bias_um,
            )
            obs[[OBS_XI, OBS_ETA]] += err.position_um / cnom_um
            obs[[OBS_XI_DOT, OBS_ETA_DOT]] += err.velocity_um_per_s * nb.time_scale_s / cnom_um
            obs[[OBS_XI_EXTENT, OBS_ETA_EXTENT]] += err.extent_um / cnom_um
            x, y = probes.read_um(xi * c_um, eta * c_um, ep.probe_bias_um)
            ep.probe_readings_um = np.array([x + err.noise_um[0], y + err.noise_um[1]])
        if not self.pressure_taps.is_ideal:
            obs[N_ROTOR_OBS:] += self.pressure_taps.errors_kpa(self.np_random, ep.tap_bias_kpa) * (
                1e3 / nb.ambient_pressure_pa
            )

    def _info(self) -> dict:
        ep, integ, model = self._ep, self._integ, self._ep.model
        b = ep.bearing
        s = integ.state
        xi, eta, xi_dot, eta_dot = model.layout.rotor(s)
        force = model.bearing_force(s)
        lam = integ.bearing_number
        eps = math.hypot(xi, eta)  # = model.eccentricity(s), without a second state check
        info = {
            "step": ep.step,
            "tau": integ.tau,
            "time_s": b.seconds(integ.tau),
            "bearing_number": lam,
            "foil_damping": integ.foil_damping,
            "damping_gain": ep.actuator.gain,
            "balance_grade_mm_s": ep.balance_grade_mm_s,
            "unbalance_um": b.micrometres(integ.unbalance.magnitude) if integ.unbalance is not None else 0.0,
            "shocks": len(ep.shocks),
            "shock_peak_g": max((e.peak_g for e in ep.shocks), default=0.0),
            "probe_x_um": float(ep.probe_readings_um[0]),
            "probe_y_um": float(ep.probe_readings_um[1]),
            "speed_rpm": b.speed_rpm_at(lam),
            "xi_um": b.micrometres(xi),
            "eta_um": b.micrometres(eta),
            "xi_dot_m_s": b.micrometres(xi_dot) * 1e-6 / b.time_scale_s,
            "eta_dot_m_s": b.micrometres(eta_dot) * 1e-6 / b.time_scale_s,
            "eccentricity": eps,
            "eccentricity_um": b.micrometres(eps),
            "min_film_thickness": ep.min_film_thickness,
            "min_film_thickness_um": b.micrometres(ep.min_film_thickness),
            "whirl_amplitude": ep.whirl_amplitude,
            "whirl_amplitude_um": b.micrometres(ep.whirl_amplitude),
            "bearing_force_n": (b.newtons(float(force[0])), b.newtons(float(force[1]))),
            "hold_steps": ep.hold,
            "action_applied": ep.last_action.copy(),
            "action_sanitised": ep.action_sanitised,
            "disturbance": ep.disturbance,
            "termination_reason": ep.termination,
            "is_success": ep.termination is TerminationReason.SUCCESS,
            "integrator_steps": ep.integrator_steps,
        }
        # the reward's terms, as Gymnasium's MuJoCo tasks report them (they sum to the reward)
        info.update({f"reward_{k}": v for k, v in ep.reward_terms.items()})
        info.update(ep.task_info)
        return info

    # ------------------------------------------------------------------------------------------
    # snapshots
    def get_state(self) -> dict:
        """Exact snapshot of the episode: integrator, episode state and the ``np_random`` state."""
        if self._integ is None or self._ep is None:
            raise RuntimeError("call reset() first")
        return {
            "integrator": self._integ.snapshot(),
            "episode": copy.deepcopy(self._ep),
            "np_random": copy.deepcopy(self.np_random.bit_generator.state),
        }

    def set_state(self, snapshot: dict) -> None:
        """Restore a snapshot from :meth:`get_state`; the continuation is bit-for-bit identical."""
        ep: Episode = copy.deepcopy(snapshot["episode"])
        integ_state = snapshot["integrator"]
        if self._integ is None or self._integ.model is not ep.model:
            self._integ = self.new_integrator(
                ep.model, integ_state.s, integ_state.bearing_number, integ_state.foil_damping
            )
            self._probe_idx = ep.model.layout.midplane_probe_indices(self.n_pressure_probes)
        self._integ.restore(integ_state)
        self._ep = ep
        self.np_random.bit_generator.state = copy.deepcopy(snapshot["np_random"])

    # ------------------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """``"rgb_array"``: an (H, W, 3) uint8 image; ``"human"``: draw into a matplotlib window."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._integ is None or self._ep is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._renderer = EpisodeRenderer(
                self.render_mode, self.damping_range, self.metadata["render_fps"]
            )
        return self._renderer.render(self._ep, self._integ.state, self._integ.tau)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


# ----------------------------------------------------------------------------------------------
def _clip_action(x: float) -> float:
    """NaN -> 0, +-inf and out-of-range -> clipped to [-1, 1] (a NaN compares unequal, so the caller's
    ``clean != raw`` reports it)."""
    if x != x:
        return 0.0
    return 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)


def _span(r: tuple[float, float]) -> float:
    v = float(r[1]) - float(r[0])
    return v if math.isfinite(v) and v >= 0 else 0.0


def _whirl_amplitude(tau: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> float:
    """Largest distance of the journal from its linear trend over the control interval (units of C).

    The trend is the slow drift of the equilibrium while the speed ramps; what is left is the
    vibration (the whirl).  NaN if fewer than 3 samples.

    The means are ``np.add.reduce(x) / n``, what ``x.mean()`` computes (the same pairwise sum and
    division) without its Python layer, and the largest distance is the root of the largest square
    (the correctly rounded root is monotonic): bit for bit the earlier result at a third of the cost."""
    n = len(tau)
    if n < 3:
        return float("nan")
    add = np.add.reduce
    t = tau - add(tau) / n
    denom = float(t @ t)
    if denom <= 0:
        return float("nan")
    xd = xi - add(xi) / n - t * (float(t @ xi) / denom)
    ed = eta - add(eta) / n - t * (float(t @ eta) / denom)
    xd *= xd
    ed *= ed
    xd += ed
    return math.sqrt(float(np.maximum.reduce(xd)))


def viscoelastic_model(
    grid: Grid, bearing: BearingParameters, foil_stiffness: float | None = None
) -> GFBModel:
    """The viscoelastic plant (D_W is an action, so the foil is always viscoelastic)."""
    return GFBModel(Structure.VISCOELASTIC, grid, bearing=bearing, foil_stiffness=foil_stiffness)
