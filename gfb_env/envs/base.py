"""Base Gymnasium environment: speed and foil-damping control of a gas foil bearing (GFB) rotor.

The plant is the viscoelastic GFB rotor model of Leister, Baum & Seemann (paper Sect. 2,
:class:`~gfb_env.model.GFBModel`), advanced by the adaptive trapezoidal integrator
(:class:`~gfb_env.integrator.TrapezoidalIntegrator`).  One control step spans ``control_interval``
units of tau (several whirl periods ``~4 pi / Lambda``) and many integrator steps; over a control step
the bearing number Lambda and the foil damping D_W ramp linearly from their current values to the
commanded ones.  Whose tau: the env's :class:`~gfb_env.envs.config.ControlClock` says (v1: the episode's
plant; the v2 interface: the nominal bearing's, a fixed period in seconds, so on a drawn bearing the
plant's tau per step :attr:`GFBEnv.step_tau` varies instead).

One control step is four stages (:meth:`GFBEnv.step`): *command* (sanitise the action; the motor
turns the speed action into Lambda at the step's end, the foil-damping actuator turns the damping
command into the actual D_W at the step's end: :mod:`gfb_env.machine`), *plant* (a disturbance kick,
then the integrator over the control interval), *judge* (stability, hold, success, termination and the
task's reward terms, from the true plant) and *emit* (the observation, built from the sensors:
proximity probes and pressure taps, and info).  With the default (ideal) actuator and sensors the
machine is ideal (the registered ids add the instrumented one).  Everything that changes within an episode is
one :class:`~gfb_env.envs.episode.Episode`; the configuration is one frozen
:class:`~gfb_env.envs.config.EnvConfig`.

Subclasses define the task: the episode (:meth:`GFBEnv._setup_episode`, :attr:`GFBEnv.reset_options`),
the first guess and caching of the plant's best stable point, and the objective they hold
(``self.objective``, a :class:`~gfb_env.envs.commanded.CommandedObjective`); see ``run_up.py``,
``run_up_randomized.py`` and ``whirl_recovery.py``, ``docs/envs.md`` and ``docs/extending.md``.

The step is a public two-phase protocol (:meth:`GFBEnv.plan_step`, the plant :func:`advance_plans`,
:meth:`GFBEnv.finish_step`): :meth:`GFBEnv.step` is the three for one env, the native vector env
(:mod:`gfb_env.envs.vector`) the same three over a batch with one compiled plant call.

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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gfb_env.envs._superposition_kernels import whirl_amplitude_kernel
from gfb_env.envs.certify import BestStablePoint, best_stable_operating_point
from gfb_env.envs.commanded import CertifiedPlant, CommandedEpisode, CommandedObjective, SpeedCommand
from gfb_env.envs.config import DEFAULT_GRID, ControlClock, EnvConfig
from gfb_env.envs.episode import Episode, EpisodeSetup, History, StepOutcome, TerminationReason
from gfb_env.envs.privileged import DrawnBearing, HiddenParameters, ResidualUnbalance, SensorDraws
from gfb_env.envs.render import EpisodeRenderer
from gfb_env.envs.synchronous_plant import SuperposedResponse
from gfb_env.envs.units import (
    N_ROTOR_OBS,
    OBS_DAMPING,
    OBS_SPEED,
    ActionMap,
    ObservationLayout,
)
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.integrator import (
    DEFAULT_MAX_STEPS,
    AdvanceResult,
    BatchAdvance,
    IntegrationError,
    PreparedCall,
    TrapezoidalIntegrator,
)
from gfb_env.machine import FoilDampingActuator, Motor, PressureTaps, ProximityProbes
from gfb_env.machine.probes import ProbeErrors
from gfb_env.model import GFBModel, Grid, Structure
from gfb_env.params import BearingParameters
from gfb_env.synchronous import SynchronousSolver

__all__ = [
    "GFBEnv",
    "StepPlan",
    "PlantResult",
    "advance_plans",
    "EpisodeSetup",
    "StepOutcome",
    "DEFAULT_GRID",
    "viscoelastic_model",
]

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
    #: the samples' times (tau) of ``orbit`` (None where the plant failed: no record)
    orbit_tau: np.ndarray | None = None


#: What the plant phase of a step gives :meth:`GFBEnv.finish_step`: the integrator's result, or the
#: numerical failure (:data:`NUMERICAL_FAILURES`) it raised.
PlantResult = AdvanceResult | Exception


@dataclass(frozen=True)
class StepPlan:
    """The first phase of one control step (:meth:`GFBEnv.plan_step`): what the env commanded and the
    plant's prepared call.

    Attributes:
        action: the sanitised action (float64, ``(2,)``); action_sanitised: whether it was mended.
        disturbance: a velocity kick was applied at the step's start.
        bearing_number_start: Lambda at the step's start.
        bearing_number, foil_damping: Lambda and the actual D_W commanded for the step's end.
        integrator: the env's integrator, which the plant advances.
        call: its prepared compiled call (:meth:`~gfb_env.integrator.TrapezoidalIntegrator.prepare`);
            None when preparing it raised a numerical failure, then ``failure``.
        tau_start, rotation_angle_start: tau and the rotation angle theta at the step's start (the
            once-per-revolution key of the v2 vibration monitor, :mod:`gfb_env.envs.interface_v2`).
    """

    action: np.ndarray
    action_sanitised: bool
    disturbance: bool
    bearing_number_start: float
    bearing_number: float
    foil_damping: float
    integrator: TrapezoidalIntegrator
    call: PreparedCall | None
    failure: Exception | None = None
    tau_start: float = math.nan
    rotation_angle_start: float = 0.0

    def __post_init__(self) -> None:
        if (self.call is None) == (self.failure is None):
            raise ValueError("StepPlan: exactly one of call and failure must be given")


def advance_plans(batch: BatchAdvance, plans: Sequence[StepPlan]) -> list[PlantResult]:
    """The plant phase of a step for any number of plans (one env's, or a vector env's batch): every
    prepared call in one compiled call of ``batch``
    (:meth:`~gfb_env.integrator.BatchAdvance.run_prepared`, the envs' loops in parallel when it has
    threads; each result is bit for bit the integrator's own ``advance``), a plan whose preparation
    failed keeps its failure."""
    ready = [p for p in plans if p.call is not None]
    done = iter(batch.run_prepared([p.integrator for p in ready], [p.call for p in ready]))
    return [next(done) if p.call is not None else p.failure for p in plans]  # type: ignore[misc]


class _FromConfig:
    """A read-only attribute of the env forwarded to its :class:`EnvConfig` (one owner)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        # the config is frozen and set once (``__init__``): kept in the instance's dict on the first
        # read, which then shadows this (non-data) descriptor (the env reads ~20 per control step)
        value = obj.__dict__[self.name] = getattr(obj.config, self.name)
        return value


class GFBEnv(gym.Env):
    """Common machinery of the GFB tasks (actions, observations, integration, snapshots, rendering).

    A task subclass decides the episode (:meth:`_setup_episode`: the plant, its start, the speed
    command) and holds its objective (``objective``, a
    :class:`~gfb_env.envs.commanded.CommandedObjective`: observation entries, judge, reward, horizon,
    info); everything else is here.

    Args:
        objective: the task's objective.
        config: the validated configuration (:class:`~gfb_env.envs.config.EnvConfig`: ``grid``,
            ``control_interval``, ``max_acceleration_rpm_per_s``, ``speed_range_rpm``, ``damping_range``,
            ``n_pressure_probes``, ``observation_noise``, ``touchdown_film_thickness``,
            ``stable_amplitude``, ``hold_steps``, ``disturbance_probability``, ``disturbance_magnitude``,
            ``speed_scale_rpm``, ``nominal_bearing``, ``integrator_options``, and the machine's
            components ``motor``, ``damping_actuator``, ``proximity_probes``, ``pressure_taps``,
            ``shock_arrivals``, ``rotor_balance``: objects of :mod:`gfb_env.machine` or dicts of their
            fields); the tasks build it from their keyword arguments (an unknown keyword or a bad value
            raises ``ValueError`` naming it).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    #: keys that ``reset(options=...)`` accepts (the task validates their values)
    reset_options: ClassVar[tuple[str, ...]] = ()

    def __init__(self, objective: CommandedObjective, config: EnvConfig, render_mode: str | None = None):
        super().__init__()
        if not isinstance(config, EnvConfig):
            raise ValueError(f"config must be an EnvConfig, got {config!r}")
        if not isinstance(objective, CommandedObjective):
            raise ValueError(f"objective must be a CommandedObjective, got {objective!r}")
        self.config = config
        self.objective = objective
        #: the information interface (None: v1's observation, reward, costs and info, in this module;
        #: the v2 ids pass :class:`~gfb_env.envs.interface_v2.MonitorInterface`)
        self.interface = config.interface
        self._public_reward = None
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.actions = ActionMap(cfg.damping_range, cfg.max_acceleration_rpm_per_s)
        # the task's own entries (if any), then the objective's (they end the observation)
        extra = self._extra_observation_bounds()
        own_lo, own_hi = objective.observation_bounds()
        extra_lo = (*(float(x) for x in extra[0]), *own_lo) if extra is not None else tuple(own_lo)
        extra_hi = (*(float(x) for x in extra[1]), *own_hi) if extra is not None else tuple(own_hi)
        extra_names = (*self._extra_observation_names(), *objective.observation_names)
        if self.interface is not None:  # its entries come first: after the pressure taps
            mon_lo, mon_hi = self.interface.observation_bounds()
            extra_lo, extra_hi = (*mon_lo, *extra_lo), (*mon_hi, *extra_hi)
            extra_names = (*self.interface.observation_names, *extra_names)
        self.observation_layout = ObservationLayout(
            n_pressure_probes=cfg.n_pressure_probes,
            speed_scale_rpm=cfg.speed_scale_rpm,
            max_speed_rpm=cfg.speed_range_rpm[1],
            extra_low=tuple(float(x) for x in extra_lo),
            extra_high=tuple(float(x) for x in extra_hi),
            extra_names=extra_names,
        )
        #: the control step's duration (tau of the plant, seconds): the v2 interface's clock runs in seconds
        #: (``control_interval`` tau of the nominal bearing), v1's in tau of the episode's plant
        clock = "plant" if self.interface is None else self.interface.control_clock
        self.control_clock = ControlClock(
            cfg.control_interval, cfg.nominal_bearing if clock == "seconds" else None
        )
        self._clock_values: tuple[BearingParameters, tuple[float, float, float, float]] | None = None
        #: (bearing, its :meth:`bearing_number_limits`): the command reads them every step
        self._limits_values: tuple[BearingParameters, tuple[float, float]] | None = None
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        low, high = self.observation_layout.bounds()
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._integ: TrapezoidalIntegrator | None = None
        #: the plant phase of :meth:`step` (one plan at a time: one thread)
        self._plant = BatchAdvance(num_threads=1)
        self._pending: StepPlan | None = None
        self._ep: Episode | None = None
        #: the superposed 1x response of the episode (``synchronous_response="superposed"`` and an
        #: unbalance; :mod:`gfb_env.envs.synchronous_plant`), else None; its solver per model
        self._sync: SuperposedResponse | None = None
        self._sync_solver: SynchronousSolver | None = None
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

    # the control step of the episode (before the first reset: of the nominal bearing)
    @property
    def _clock_bearing(self) -> BearingParameters:
        return self._ep.bearing if self._ep is not None else self.nominal_bearing

    def _clock(self) -> tuple[float, float, float, float]:
        """``(step_tau, control_step_s, record_interval, record_interval_s)`` of the episode's bearing,
        computed once per bearing (the step reads them ~6 times)."""
        ep = self._ep
        b = ep.bearing if ep is not None else self.nominal_bearing  # (_clock_bearing, inline)
        cached = self._clock_values
        if cached is not None and cached[0] is b:
            return cached[1]
        c = self.control_clock
        values = (c.step_tau(b), c.step_s(b), c.record_interval(b), c.record_interval_s(b))
        self._clock_values = (b, values)
        return values

    @property
    def step_tau(self) -> float:
        """One control step in tau of the episode's plant (:meth:`ControlClock.step_tau`; the v2 clock
        keeps the step's seconds fixed, so on a drawn bearing this is ``60 T_nom / T`` tau)."""
        return self._clock()[0]

    @property
    def control_step_s(self) -> float:
        """One control step in seconds (v2: ``control_interval x T_nom``, the same on every episode)."""
        return self._clock()[1]

    @property
    def record_interval(self) -> float:
        """The record grid's spacing, tau of the episode's plant (120 samples per control step)."""
        return self._clock()[2]

    @property
    def record_interval_s(self) -> float:
        """The probes' sampling period, seconds (120 samples per control step)."""
        return self._clock()[3]

    # ------------------------------------------------------------------------------------------
    # task hooks
    def _setup_episode(self, options: Mapping[str, Any]) -> EpisodeSetup:  # pragma: no cover - abstract
        """The plant, its start, the speed command and the task's record for a new episode
        (``options`` already checked against :attr:`reset_options`; the task validates the values)."""
        raise NotImplementedError

    def _best_bearing_number_guess(self) -> float:  # pragma: no cover - abstract
        """A first guess of the episode's best stable bearing number (the start of the exact search)."""
        raise NotImplementedError

    def _best_point_is_cached(self) -> bool:
        """Whether the episode's plant has its optimum cached (fixed plants: after the first time)."""
        return False

    def _unconstrained_best_point(self) -> tuple[float, float]:
        """``(lambda_best, D_opt)`` of the episode's plant over every actual damping any gain of the
        actuator can reach (:meth:`_damping_search_range`).  Tasks cache it where the plant is fixed."""
        return best_stable_operating_point(
            self.episode.model, self._damping_search_range(), self._best_bearing_number_guess()
        )

    def _drawn_bearing(self) -> DrawnBearing | None:
        """The episode's drawn bearing for :meth:`hidden` (None: the task runs the nominal bearing)."""
        return None

    def _extra_observation_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounds of task-specific observations appended after the probes, before the objective's
        (None: none)."""
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

    @property
    def speed_command(self) -> SpeedCommand:
        """The episode's speed command (observed: ``n_cmd``; here also ``Lambda_cmd``, ``Lambda_ref``)."""
        return self.episode.command.command

    @property
    def damping_gain(self) -> float:
        """The episode's hidden damping effectiveness ``g`` (actual D_W = g x commanded; for oracles)."""
        return float(self.episode.actuator.gain)

    @property
    def public_reward_config(self) -> Any:
        """The public configuration of the v2 reward and costs
        (:class:`~gfb_env.envs.monitor_reward.PublicRewardConfig`; with the episode's observations and
        final verdict, :func:`~gfb_env.envs.monitor_reward.recompute_rewards` gives every reward).
        ``ValueError`` on a v1 id (its reward reads the true plant)."""
        if self.interface is None:
            raise ValueError("public_reward_config: a v1 id's reward reads the true plant; use a -v2 id")
        if self._public_reward is None:
            self._public_reward = self.interface.reward_config(self)
        return self._public_reward

    # ---- the privileged channel (issue 19; gfb_env.envs.privileged, docs/envs.md) ---------------
    def hidden(self) -> HiddenParameters:
        """Every hidden draw of the current episode, typed
        (:class:`~gfb_env.envs.privileged.HiddenParameters`; :meth:`hidden_parameters` is its dict).
        Privileged: for oracles, teacher-student training and debugging, never for a benchmarked
        policy."""
        ep = self.episode
        u = self._rotor_unbalance()
        unbalance = None
        if u is not None:
            b = ep.bearing
            unbalance = ResidualUnbalance(
                float(ep.balance_grade_mm_s),
                float(u.magnitude),
                b.micrometres(u.magnitude),
                float(u.phase_rad),
            )
        err, taps, noise = ep.probe_errors, ep.tap_errors_kpa, ep.observation_noise_draw
        sensors = SensorDraws(
            probe_bias_um=_tuple(ep.probe_bias_um),
            tap_bias_kpa=_tuple(ep.tap_bias_kpa),
            probe_noise_um=None
            if err is None or self.proximity_probes.noise_um == 0
            else _tuple(err.noise_um),
            probe_position_error_um=None if err is None else _tuple(err.position_um),
            probe_velocity_error_um_per_s=None if err is None else _tuple(err.velocity_um_per_s),
            probe_extent_error_um=None if err is None else _tuple(err.extent_um),
            tap_error_kpa=None if taps is None else _tuple(taps),
            observation_noise=None if noise is None else _tuple(noise),
        )
        return HiddenParameters(
            damping_gain=float(ep.actuator.gain),
            bearing=ep.bearing,
            bearing_draw=self._drawn_bearing(),
            unbalance=unbalance,
            sensors=sensors,
            shocks=tuple(ep.shock_schedule),
            task=dict(ep.task_hidden),
            **(
                {}
                if self.config.damping_regime_changes.is_off
                else {"damping_gain_start": ep.damping_gain_start, "regime_changes": ep.regime_changes}
            ),
        )

    def hidden_parameters(self) -> dict[str, Any]:
        """Every hidden draw of the current episode as a JSON-serialisable dict (units in the keys;
        :meth:`~gfb_env.envs.privileged.HiddenParameters.as_dict`): ``damping_gain`` (the current g),
        ``damping_regime_changes`` (only with that component: the start g and every change so far),
        ``bearing`` (the
        drawn clearance, stiffness factor, load; None on a nominal bearing), ``unbalance`` (grade,
        amplitude, angle; None when balanced), ``sensors`` (biases, the last observation's noise),
        ``shocks`` (every base shock so far: time, peak, duration, direction) and ``task`` (the start's
        draws).  The same seed gives the same dict.  Privileged (module :mod:`gfb_env.envs.privileged`)."""
        return self.hidden().as_dict()

    def privileged_quantities(self) -> dict[str, Any]:
        """The true quantities of the last reset or step that the sensors do not give: the noise-free
        journal state, the actual Lambda and D_W, the judge's whirl amplitude and min film thickness,
        the bearing force.  ``info["privileged"]`` (``privileged_info=True``) is this plus
        ``hidden_parameters``.  Privileged (module :mod:`gfb_env.envs.privileged`)."""
        ep, integ = self.episode, self._integ
        model, b, s = ep.model, ep.bearing, self._plant_state()
        xi, eta, xi_dot, eta_dot = model.layout.rotor(s)
        force = model.bearing_force(s)
        eps = math.hypot(xi, eta)
        return {
            "xi": float(xi),
            "eta": float(eta),
            "xi_dot": float(xi_dot),
            "eta_dot": float(eta_dot),
            **_journal_physical(b, xi, eta, xi_dot, eta_dot, eps),
            "bearing_number": integ.bearing_number,
            "foil_damping": integ.foil_damping,
            "whirl_amplitude": ep.whirl_amplitude,
            "whirl_amplitude_um": b.micrometres(ep.whirl_amplitude),
            "min_film_thickness": ep.min_film_thickness,
            "min_film_thickness_um": b.micrometres(ep.min_film_thickness),
            "bearing_force_n": (b.newtons(float(force[0])), b.newtons(float(force[1]))),
        }

    def best_stable_operating_point(self) -> BestStablePoint:
        """The exact best stable operating point of this episode's plant for the achievable actual
        damping ``[g D_min, g D_max]`` (g: the episode's hidden damping effectiveness): ``lambda_best``,
        the actual ``D_opt``, the command ``D_opt / g`` and the speed.  Cached for the episode (~0.3 s
        for a drawn bearing, once per env for the nominal one).  For the oracle and the evaluation: it
        reads the hidden plant."""
        ep = self.episode
        ce: CommandedEpisode = ep.command
        if ce.best is not None:
            return ce.best
        g = ep.actuator.gain
        dmin, dmax = self.damping_range
        lo, hi = g * dmin, g * dmax
        lam_u, d_u = self._unconstrained_best_point()
        if lo <= d_u <= hi:
            lam, d = lam_u, d_u
        else:  # Lambda_c(D) is unimodal in log D: the best achievable damping is the nearer end
            d = lo if d_u < lo else hi
            lam, _ = best_stable_operating_point(ep.model, (d, d), lam_u)
        ce.best = BestStablePoint(lam, d, d / g, ep.bearing.speed_rpm_at(lam))
        return ce.best

    def _damping_search_range(self) -> tuple[float, float]:
        """The actual damping any gain of the actuator can reach (regime changes included)."""
        act, (dmin, dmax) = self.damping_actuator, self.damping_range
        glo, ghi = act.gain_range if act.gain_range is not None else (act.gain, act.gain)
        if not self.config.damping_regime_changes.is_off:
            blo, bhi = self._gain_bounds()
            glo, ghi = min(glo, blo), max(ghi, bhi)
        return glo * dmin, ghi * dmax

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
        self._pending = None
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
        self._start_synchronous_response(unbalance)
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
            damping_gain_start=float(actuator.gain),
            probe_bias_um=probe_bias,
            tap_bias_kpa=tap_bias,
            balance_grade_mm_s=grade,
            command=setup.command,
            task_hidden=dict(setup.hidden) if setup.hidden else {},
            interface=self.interface.new_episode() if self.interface is not None else None,
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

    # ------------------------------------------------------------------------------------------
    # the step: a public two-phase protocol (plan, the plant, finish); the stage order lives here only
    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict]:
        """One control step: :meth:`plan_step`, the plant (:func:`advance_plans`), :meth:`finish_step`.

        ``action``: real numbers of shape ``(2,)`` (a list, tuple or array of any real dtype); any other
        shape or a complex / non-numeric dtype raises ``ValueError``.  NaN and out-of-range entries are
        mended (``info["action_sanitised"]``)."""
        plan = self.plan_step(action)
        return self.finish_step(plan, advance_plans(self._plant, (plan,))[0])

    def plan_step(self, action: Any) -> StepPlan:
        """The first phase of a step: check and sanitise ``action``, then *command* (motor, actuator),
        the disturbance kick, the base shocks of the step, and prepare the plant's compiled call.  The
        env's random draws happen here and in :meth:`finish_step`, in that order, so a batch of envs
        stepped phase by phase (:class:`~gfb_env.envs.vector.GFBVectorEnv`) draws exactly as each env
        stepped alone.  Until :meth:`finish_step` takes the plan no other plan can be made (and no
        snapshot taken); a plant that raised (a programming error: numerical failures are results)
        leaves the plan pending until :meth:`reset` or :meth:`set_state`."""
        ep = self._ep
        if self._integ is None or ep is None:
            raise RuntimeError("call reset() before step()")
        if ep.termination is not None:  # (Episode.done)
            raise RuntimeError("the episode has ended; call reset()")
        if self._pending is not None:
            raise RuntimeError("a step is planned and not finished: call finish_step(plan, result) first")
        a, sanitised = self._sanitise(action)
        bearing_number, foil_damping = self._command(a)
        kick = self._maybe_kick()
        integ = self._integ
        lam0, tau0, theta0 = integ.bearing_number, integ.tau, integ.rotation_angle
        self._schedule_shocks()
        if self._sync is not None:
            self._sync.before_step(integ, kick)
        call: PreparedCall | None = None
        failure: Exception | None = None
        step_tau, _, record_interval, _ = self._clock()
        try:
            call = integ.prepare(
                integ.tau + step_tau, bearing_number, foil_damping, record_interval,
                self._probe_idx, DEFAULT_MAX_STEPS,
            )  # fmt: skip
        except NUMERICAL_FAILURES as exc:
            failure = exc
        # StepPlan(...) of these fields (exactly one of call and failure is set here, as its check
        # asks), its instance dict filled at once: the frozen dataclass's __init__ sets its 11 fields
        # one object.__setattr__ at a time, every step
        plan = object.__new__(StepPlan)
        plan.__dict__.update(
            action=a, action_sanitised=sanitised, disturbance=kick, bearing_number_start=lam0,
            bearing_number=bearing_number, foil_damping=foil_damping, integrator=integ, call=call,
            failure=failure, tau_start=tau0, rotation_angle_start=theta0,
        )  # fmt: skip
        self._pending = plan
        return plan

    def finish_step(self, plan: StepPlan, result: PlantResult) -> tuple[np.ndarray, float, bool, bool, dict]:
        """The second phase of a step: *judge* (stability, success, termination and reward, from the
        plant's ``result`` for ``plan``: its :class:`~gfb_env.integrator.AdvanceResult` or the numerical
        failure it raised, as :func:`advance_plans` returns it) and *emit* (the observation from the
        sensors, and the info).  Returns Gymnasium's ``(obs, reward, terminated, truncated, info)``;
        ``truncated`` is always False (the time limit is the ``TimeLimit`` wrapper's)."""
        if plan is not self._pending:
            raise ValueError("finish_step: plan is not this env's pending plan (from its plan_step)")
        self._pending = None
        if self._sync is not None:
            result = self._sync.after_step(
                self._integ, plan.tau_start, plan.rotation_angle_start, plan.bearing_number_start,
                self._probe_idx, result,
            )  # fmt: skip
        out, trace = self._plant_outcome(plan.bearing_number_start, result)
        self._judge(out, trace, plan.action, plan.action_sanitised, plan.disturbance)
        self._ep.record_start = (plan.tau_start, plan.rotation_angle_start, plan.bearing_number_start)
        obs, info = self._emit()
        return obs, self._ep.reward, self._ep.done, False, info

    # ---- command ------------------------------------------------------------------------------
    def _sanitise(self, action: Any) -> tuple[np.ndarray, bool]:
        """Check ``action`` (real numbers of shape ``(2,)``: no reshaping, so a (1, 2) or (2, 1) array,
        a complex or non-numeric one raises ``ValueError``), then nan -> 0, +-inf and out-of-range ->
        clipped to [-1, 1]; reports whether anything changed."""
        a = np.asarray(action)
        if a.shape != (2,):
            raise ValueError(f"action must have shape (2,), got {a.shape}")
        if a.dtype.kind not in _REAL_KINDS:
            raise ValueError(f"action must be real numbers, got dtype {a.dtype} ({action!r})")
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
        step_tau, step_s, _, _ = self._clock()
        limits = self._limits_values
        if limits is None or limits[0] is not b:
            limits = self._limits_values = (b, self.bearing_number_limits(b))
        # the entries as Python floats: the same arithmetic as on numpy's float64 scalars, cheaper
        a_speed, a_damping = a.tolist()
        lam1 = self.motor.bearing_number_at_step_end(
            self._integ.bearing_number, a_speed, b, step_tau, limits[1]
        )
        commanded = self.actions.damping_from_action(a_damping)
        if not self.config.damping_regime_changes.is_off:
            self._change_regimes()
        ep.actuator = self.damping_actuator.step(ep.actuator, commanded, step_s)
        return lam1, ep.actuator.foil_damping

    def _change_regimes(self) -> None:
        """The friction-regime changes of the foil in this control step (drawn from ``self.np_random``;
        only with ``damping_regime_changes``): the effectiveness ``g`` jumps, the actuator's setting
        stays.  A change anywhere in the step takes effect over the step (the integrator ramps D_W
        between the step's ends); the best stable point of the new plant is recomputed when asked."""
        ep, b = self._ep, self._ep.bearing
        t0 = b.seconds(self._integ.tau)
        events = self.config.damping_regime_changes.draw(
            self.np_random, t0, t0 + self.control_step_s, ep.actuator.gain, self._gain_bounds()
        )
        if events:
            ep.actuator = ep.actuator.with_gain(events[-1].gain_after)
            ep.regime_changes += tuple(events)
            ep.command.best = None  # the achievable actual damping [g D_min, g D_max] moved

    def _gain_bounds(self) -> tuple[float, float]:
        """The range the effectiveness ``g`` stays in under regime changes: the component's
        ``gain_bounds``, else the actuator's ``gain_range`` (the config refuses neither)."""
        bounds = self.config.damping_regime_changes.gain_bounds
        return bounds if bounds is not None else self.damping_actuator.gain_range  # type: ignore[return-value]

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

    def _start_synchronous_response(self, unbalance: Unbalance | None) -> None:
        """At ``reset``: the superposed 1x response of the episode (``synchronous_response=
        "superposed"`` and an unbalanced rotor; it may restart the integrator unforced), else None."""
        self._sync = None
        if self.config.synchronous_response != "superposed" or self._integ.unbalance is None:
            return
        model = self._integ.model
        if self._sync_solver is None or self._sync_solver.model is not model:
            self._sync_solver = SynchronousSolver(model)
        # its deviation (a threshold's input, nothing observed) by the compiled amplitude (to rounding)
        self._sync = SuperposedResponse.start(
            self._sync_solver, self._integ, unbalance, whirl_amplitude_kernel
        )

    def _rotor_unbalance(self) -> Unbalance | None:
        """The rotor's unbalance (the integrator's, or the superposed response's while it is off there)."""
        return self._sync.unbalance if self._sync is not None else self._integ.unbalance

    def _plant_state(self) -> np.ndarray:
        """The plant's true state: the integrator's (plus the superposed 1x response)."""
        return self._sync.true_state(self._integ) if self._sync is not None else self._integ.state

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
            orbit, orbit_tau = (tr.xi, tr.eta), tr.tau
        except NUMERICAL_FAILURES:
            failure = True
            amp, min_h = math.nan, math.nan
            xr = er = (math.nan, math.nan)
            orbit, orbit_tau = ep.orbit, None
        if not math.isfinite(amp):
            amp = 0.5 * max(_span(xr), _span(er)) if math.isfinite(_span(xr) + _span(er)) else 0.0
        if not math.isfinite(min_h):
            min_h = ep.model.min_film_thickness(self._plant_state())
        # StepOutcome(...) and PlantTrace(...) of these values, each instance dict filled at once (the
        # frozen dataclasses' __init__ set one field at a time; there is nothing to check)
        out = object.__new__(StepOutcome)
        out.__dict__.update(
            bearing_number_start=lam0, bearing_number=integ.bearing_number, foil_damping=integ.foil_damping,
            whirl_amplitude=amp, min_film_thickness=min_h, touchdown=touchdown, solver_failure=failure,
        )  # fmt: skip
        trace = object.__new__(PlantTrace)
        trace.__dict__.update(
            xi_range=xr, eta_range=er, orbit=orbit, integrator_steps=steps, orbit_tau=orbit_tau
        )
        return out, trace

    def _schedule_shocks(self) -> None:
        """Random base shocks starting in this control step (drawn from ``self.np_random``; none and no
        draw without shock arrivals), handed to the integrator as half-sine pulses."""
        integ, ep, b = self._integ, self._ep, self._ep.bearing
        t0 = b.seconds(integ.tau)
        events = self.config.shock_arrivals.draw(self.np_random, t0, t0 + self._clock()[1])
        for e in events:
            shock = HalfSineShock.from_physical(b, e.time_s, e.peak_g, e.duration_ms, e.direction_deg)
            # tau -> s -> tau may round below the current time by an ulp
            integ.add_shock(dataclasses.replace(shock, start_tau=max(shock.start_tau, integ.tau)))
        ep.shocks = tuple(events)
        ep.shock_count += len(events)
        if events:
            ep.shock_schedule += ep.shocks

    # ---- judge --------------------------------------------------------------------------------
    def _judge(self, out: StepOutcome, trace: PlantTrace, a: np.ndarray, sanitised: bool, kick: bool) -> None:
        """Stability, the objective's judge (success), reward and termination of the step, written into
        the episode."""
        ep, objective = self._ep, self.objective
        ce: CommandedEpisode = ep.command
        stable = (
            (not out.touchdown) and (not out.solver_failure) and out.whirl_amplitude <= self.stable_amplitude
        )
        # the certificate reads the plant at the horizon only (CommandedObjective.judge): built there
        plant = self._certified_plant() if objective.horizon_reached(ep.step + 1) else None
        success = objective.judge(ce, out, stable, ep.step, plant)
        terms = objective.reward_terms(ce, out)
        if self.interface is None:
            ep.reward_terms = terms
            ep.reward = float(sum(terms.values()))
            ep.episode_return += ep.reward
        else:  # the v1 terms are the judge's truth (privileged); the reward is the interface's (emit)
            ep.interface.truth_reward_terms = terms
        ep.step += 1
        ep.xi_range, ep.eta_range = trace.xi_range, trace.eta_range
        ep.whirl_amplitude, ep.min_film_thickness = out.whirl_amplitude, out.min_film_thickness
        ep.orbit, ep.orbit_tau = trace.orbit, trace.orbit_tau
        ep.integrator_steps += trace.integrator_steps
        ep.history.append(self._integ.tau, out.bearing_number, out.foil_damping, out.whirl_amplitude)
        ep.last_action, ep.action_sanitised, ep.disturbance = a, sanitised, kick
        if out.solver_failure:
            ep.termination = TerminationReason.SOLVER_FAILURE
        elif out.touchdown:
            ep.termination = TerminationReason.TOUCHDOWN
        elif success:
            ep.termination = TerminationReason.SUCCESS
        elif objective.horizon_reached(ep.step):
            ep.termination = TerminationReason.HORIZON

    def _certified_plant(self) -> CertifiedPlant:
        """The actual plant as the objective's certificate reads it."""
        ep = self._ep
        g, (dmin, dmax) = ep.actuator.gain, self.damping_range
        known = ep.command.best is not None or self._best_point_is_cached()
        b = ep.bearing
        return CertifiedPlant(
            ep.model,
            self._plant_state(),
            (g * dmin, g * dmax),
            self.best_stable_operating_point if known else None,
            shocks=ep.shock_schedule,
            time_s=b.seconds(self._integ.tau),
            step_s=self.control_step_s,
            step_tau=self.step_tau,
        )

    # ---- emit ---------------------------------------------------------------------------------
    def _emit(self) -> tuple[np.ndarray, dict]:
        """The observation (from the sensors; NaN/inf -> 0, clipped, float32) and the info."""
        if self.interface is not None:
            obs, info = self.interface.emit(self)
            if self.render_mode == "human":
                self.render()
            return obs, info
        raw, info = self._raw_observation(), self._info()
        if self.render_mode == "human":
            self.render()
        return self._finish_observation(raw), info

    def _finish_observation(self, raw: np.ndarray) -> np.ndarray:
        """NaN/inf -> 0, clipped to the observation space, float32 (elementwise).  ``raw``: a float64
        array of the caller's own (both callers pass the fresh raw observation), cleaned in place."""
        obs = raw if type(raw) is np.ndarray and raw.dtype == np.float64 else np.array(raw, dtype=np.float64)
        # what np.nan_to_num(nan=0, posinf=0, neginf=0) gives, in two ufunc calls (a third of its cost)
        np.copyto(obs, 0.0, where=~np.isfinite(obs))
        # np.clip's values for finite entries (what is left), by its two ufuncs without its Python layer
        space = self.observation_space
        np.minimum(np.maximum(obs, space.low, out=obs), space.high, out=obs)
        return obs.astype(np.float32)

    def _raw_observation(self) -> np.ndarray:
        ep, s = self._ep, self._plant_state()
        # the rotor's entries as Python floats (the same products as numpy's scalars give), the six
        # written in one assignment (OBS_XI .. OBS_ETA_EXTENT are 0 .. 5)
        xi, eta, xi_dot, eta_dot = ep.model.layout.rotor(s).tolist()
        n = N_ROTOR_OBS + self.n_pressure_probes
        obs = np.zeros(n, dtype=np.float64)
        ps, vs = ep.position_scale, ep.velocity_scale
        obs[:OBS_SPEED] = (
            xi * ps, eta * ps, xi_dot * vs, eta_dot * vs, _span(ep.xi_range) * ps, _span(ep.eta_range) * ps
        )  # fmt: skip
        obs[N_ROTOR_OBS:] = s[self._probe_idx]
        self._add_sensor_errors(obs, xi, eta)
        if self.observation_noise > 0:
            measured = self.observation_layout.measured_indices
            noise = self.observation_noise * self.np_random.standard_normal(len(measured))
            obs[measured] += noise
            ep.observation_noise_draw = noise
        obs[OBS_SPEED] = ep.bearing.speed_rpm_at(self._integ.bearing_number) / self.speed_scale_rpm
        # the actuator's position feedback: the damping it believes it sets (the gain is hidden)
        obs[OBS_DAMPING] = self.actions.action_from_damping(self._integ.foil_damping / ep.actuator.gain)
        own = self.objective.observation(ep.command, ep.step, self.speed_scale_rpm)
        extra = self._extra_observation()
        if self.interface is not None:  # after the taps, before the task's and the objective's entries
            mon = self.interface.observation(self)
            return np.concatenate([obs, mon, own] if extra is None else [obs, mon, extra, own])
        return np.concatenate([obs, own] if extra is None else [obs, extra, own])

    def _add_sensor_errors(self, obs: np.ndarray, xi: float, eta: float) -> None:
        """Add what the probes and taps add to the truth (nothing, and no draw, for ideal sensors).

        The readings are in um and kPa; the observation is in the nominal bearing's units (C_nom,
        C_nom / T_nom, p0), so an error maps to it independently of the episode's bearing."""
        ep, nb = self._ep, self.nominal_bearing
        c_um = ep.bearing.clearance_m * 1e6
        probes = self.proximity_probes
        if self.interface is not None:  # v2: one draw of per-sample readings serves every channel
            self.interface.read_probes(self, obs, xi, eta)
        elif probes.is_ideal:
            ep.probe_readings_um = np.array(probes.read_um(xi * c_um, eta * c_um, ep.probe_bias_um))
        else:
            xs, es = ep.orbit
            if len(xs) == 0:  # a step that ended at once (touchdown in its first integrator step)
                xs, es = np.array([xi]), np.array([eta])
            err = probes.measurement_errors(
                self.np_random,
                np.asarray(xs) * c_um,
                np.asarray(es) * c_um,
                self.record_interval_s,
                ep.probe_bias_um,
            )
            self._apply_probe_errors(obs, err)
            x, y = probes.read_um(xi * c_um, eta * c_um, ep.probe_bias_um)
            ep.probe_readings_um = np.array([x + err.noise_um[0], y + err.noise_um[1]])
            ep.probe_errors = err  # a reference, for the privileged channel
        if not self.pressure_taps.is_ideal:
            taps = self.pressure_taps.errors_kpa(self.np_random, ep.tap_bias_kpa)
            ep.tap_errors_kpa = taps
            obs[N_ROTOR_OBS:] += taps * (1e3 / nb.ambient_pressure_pa)

    def _apply_probe_errors(self, obs: np.ndarray, err: ProbeErrors) -> None:
        """Add a step's probe errors (um, um/s) to the rotor entries of ``obs`` (units of the nominal
        C and C / T: the same for every drawn bearing)."""
        nb = self.nominal_bearing
        cnom_um = nb.clearance_m * 1e6
        t = nb.time_scale_s
        # each entry's error as a float (what the arrays' elementwise operations give), added to the six
        # entries OBS_XI .. OBS_ETA_EXTENT (0 .. 5) in one in-place add: the same sums, one ufunc call
        (px, py), (vx, vy), (ex, ey) = (
            err.position_um.tolist(),
            err.velocity_um_per_s.tolist(),
            err.extent_um.tolist(),
        )
        obs[:OBS_SPEED] += (
            px / cnom_um, py / cnom_um, vx * t / cnom_um, vy * t / cnom_um, ex / cnom_um, ey / cnom_um
        )  # fmt: skip

    def _info(self) -> dict:
        ep, integ, model = self._ep, self._integ, self._ep.model
        b = ep.bearing
        s = self._plant_state()
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
            "unbalance_um": b.micrometres(u.magnitude) if (u := self._rotor_unbalance()) is not None else 0.0,
            "shocks": len(ep.shocks),
            "shock_peak_g": max((e.peak_g for e in ep.shocks), default=0.0),
            "probe_x_um": float(ep.probe_readings_um[0]),
            "probe_y_um": float(ep.probe_readings_um[1]),
            "speed_rpm": b.speed_rpm_at(lam),
            **_journal_physical(b, xi, eta, xi_dot, eta_dot, eps),
            "min_film_thickness": ep.min_film_thickness,
            "min_film_thickness_um": b.micrometres(ep.min_film_thickness),
            "whirl_amplitude": ep.whirl_amplitude,
            "whirl_amplitude_um": b.micrometres(ep.whirl_amplitude),
            "bearing_force_n": (b.newtons(float(force[0])), b.newtons(float(force[1]))),
            # kept for the info's stability: the objective has no hold counter (its certificate's window
            # is the config's hold_steps)
            "hold_steps": 0,
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
        info.update(
            self.objective.info(ep.command, ep.step, lam, ep.termination is TerminationReason.SUCCESS)
        )
        if self.config.privileged_info:  # opt-in only: nothing added, nothing computed, by default
            info["privileged"] = {
                **self.privileged_quantities(),
                "hidden_parameters": self.hidden_parameters(),
            }
        return info

    # ------------------------------------------------------------------------------------------
    # snapshots
    def get_state(self) -> dict:
        """Exact snapshot of the episode: integrator, episode state and the ``np_random`` state."""
        if self._integ is None or self._ep is None:
            raise RuntimeError("call reset() first")
        if self._pending is not None:
            raise RuntimeError("get_state: a step is planned and not finished (finish_step first)")
        return {
            "integrator": self._integ.snapshot(),
            "episode": copy.deepcopy(self._ep),
            "np_random": copy.deepcopy(self.np_random.bit_generator.state),
            "synchronous_response": copy.deepcopy(self._sync),
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
        self._sync = copy.deepcopy(snapshot.get("synchronous_response"))
        self._ep = ep
        self._pending = None
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
        return self._renderer.render(self._ep, self._plant_state(), self._integ.tau)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


# ----------------------------------------------------------------------------------------------
#: NumPy dtype kinds an action may have: bool, signed and unsigned integers, floats (not complex, not
#: strings or objects: the imaginary part would be dropped silently, a string is no number)
_REAL_KINDS = "biuf"


def _journal_physical(
    b: BearingParameters, xi: float, eta: float, xi_dot: float, eta_dot: float, eps: float
) -> dict:
    """The true journal state in physical units (``xi_um``, ``eta_um``, ``xi_dot_m_s``, ``eta_dot_m_s``,
    ``eccentricity``, ``eccentricity_um``): one owner for v1's ``info`` and the privileged quantities."""
    return {
        "xi_um": b.micrometres(xi),
        "eta_um": b.micrometres(eta),
        "xi_dot_m_s": b.micrometres(xi_dot) * 1e-6 / b.time_scale_s,
        "eta_dot_m_s": b.micrometres(eta_dot) * 1e-6 / b.time_scale_s,
        "eccentricity": eps,
        "eccentricity_um": b.micrometres(eps),
    }


def _clip_action(x: float) -> float:
    """NaN -> 0, +-inf and out-of-range -> clipped to [-1, 1] (a NaN compares unequal, so the caller's
    ``clean != raw`` reports it)."""
    if x != x:
        return 0.0
    return 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)


def _tuple(x: Any) -> tuple[float, ...]:
    return tuple(float(v) for v in x)


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
    # (ndarray.dot of two vectors: the BLAS dot that @ calls, without the matmul ufunc's layer)
    dot = t.dot
    denom = float(dot(t))
    if denom <= 0:
        return float("nan")
    xd = xi - add(xi) / n - t * (float(dot(xi)) / denom)
    ed = eta - add(eta) / n - t * (float(dot(eta)) / denom)
    xd *= xd
    ed *= ed
    xd += ed
    return math.sqrt(float(np.maximum.reduce(xd)))


def viscoelastic_model(
    grid: Grid, bearing: BearingParameters, foil_stiffness: float | None = None
) -> GFBModel:
    """The viscoelastic plant (D_W is an action, so the foil is always viscoelastic)."""
    return GFBModel(Structure.VISCOELASTIC, grid, bearing=bearing, foil_stiffness=foil_stiffness)
