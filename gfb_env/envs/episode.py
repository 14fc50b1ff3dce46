"""The state of one episode (brax's ``State``): everything an environment changes between ``reset``
calls lives in one :class:`Episode`, so a snapshot is one copy."""

from __future__ import annotations

import copy
import enum
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gfb_env.machine import DampingActuatorState
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters

__all__ = ["TerminationReason", "StepOutcome", "Episode", "EpisodeSetup", "History"]


class TerminationReason(enum.StrEnum):
    """Why an episode terminated (``info["termination_reason"]``; ``None`` while it runs)."""

    SUCCESS = "success"
    TOUCHDOWN = "touchdown"
    #: the integrator could not continue (step below its minimum); counted like a touchdown.
    SOLVER_FAILURE = "solver_failure"
    #: the episode reached its fixed horizon without success (``info["certified"]`` says why).
    HORIZON = "horizon"


@dataclass(frozen=True)
class StepOutcome:
    """What the plant did in one control step (the input of the task's judge and reward).

    Attributes:
        bearing_number_start, bearing_number: Lambda at the start and the end of the step.
        foil_damping: D_W at the end of the step.
        whirl_amplitude: largest distance of the journal from its linear trend (units of C).
        min_film_thickness: smallest film thickness H over the step (units of C).
        touchdown: H fell below the touchdown threshold.
        solver_failure: the integrator could not continue.
    """

    bearing_number_start: float
    bearing_number: float
    foil_damping: float
    whirl_amplitude: float
    min_film_thickness: float
    touchdown: bool
    solver_failure: bool


@dataclass
class EpisodeSetup:
    """What a task decides at ``reset``: the plant, where it starts, and the task's own constants.

    ``task`` is the task's frozen record of the episode (e.g. its target); ``info`` the entries it adds
    to every ``info`` dict.  ``foil_damping`` is the plant's actual D_W at the start; ``damping_gain``
    fixes this episode's actuator effectiveness (None: the actuator's own, or its draw from
    ``gain_range``).  ``command``: the objective's per-episode state
    (:class:`~gfb_env.envs.commanded.CommandedEpisode`: the speed command).  ``hidden``: the task's own
    hidden draws at the start, units in the keys (the privileged channel's
    :attr:`~gfb_env.envs.privileged.HiddenParameters.task`)."""

    model: GFBModel
    state: np.ndarray
    bearing_number: float
    foil_damping: float
    bearing: BearingParameters
    info: dict
    task: Any = None
    damping_gain: float | None = None
    command: Any = None
    hidden: dict | None = None


@dataclass
class History:
    """Per control step: time, Lambda, D_W and whirl amplitude (for rendering and analysis)."""

    tau: list[float] = field(default_factory=list)
    bearing_number: list[float] = field(default_factory=list)
    foil_damping: list[float] = field(default_factory=list)
    whirl_amplitude: list[float] = field(default_factory=list)

    def append(self, tau: float, bearing_number: float, foil_damping: float, whirl_amplitude: float) -> None:
        self.tau.append(tau)
        self.bearing_number.append(bearing_number)
        self.foil_damping.append(foil_damping)
        self.whirl_amplitude.append(whirl_amplitude)


@dataclass
class Episode:
    """Everything that changes within an episode (the integrator's own state is snapshotted by it).

    Attributes:
        model, bearing: the plant of this episode (shared, not copied, by snapshots: never mutated).
        task: the task's frozen record (target, draw, ...); ``task_info`` its entries of ``info``.
        position_scale, velocity_scale: physical-to-observation factors of this bearing
            (``C / C_nom`` and ``(C / T) / (C_nom / T_nom)``).
        step: control steps taken.
        termination: why it ended (``None`` while running).
        xi_range, eta_range: journal extremes over the last control step (NaN before the first).
        whirl_amplitude, min_film_thickness: of the last control step.
        orbit: journal samples (xi, eta) of the last control step.
        last_action, action_sanitised: the applied action and whether NaN/inf/out-of-range was mended.
        disturbance: a kick was applied in the last step.
        reward: of the last step; episode_return: their sum; reward_terms: the last reward's terms.
        integrator_steps: accepted integrator steps since reset (kicks do not reset it).
        actuator: the foil-damping actuator's state (actual D_W at the end of the last step, this
            episode's effectiveness gain).
        probe_bias_um, tap_bias_kpa: this episode's sensor offsets ((X, Y) in um; one per tap in kPa).
        probe_readings_um: the (X, Y) probe readings of the last observation, um.
        balance_grade_mm_s: this episode's ISO balance grade (0: perfectly balanced); the unbalance
            itself lives in the integrator (part of its snapshot).
        shocks: base shocks that started in the last control step (:class:`~gfb_env.machine.ShockEvent`).
        shock_count: base shocks since reset.
        command: the commanded-speed objective's state of the episode
            (:class:`~gfb_env.envs.commanded.CommandedEpisode`).
        task_hidden: the task's hidden draws at the start (:attr:`EpisodeSetup.hidden`).
        shock_schedule: every base shock drawn since reset, in time order (the privileged channel).
        damping_gain_start: the effectiveness ``g`` at reset; regime_changes: every friction-regime
            change of ``g`` since reset, in time order (:class:`~gfb_env.machine.DampingRegimeChange`;
            the privileged channel; always empty without ``damping_regime_changes``).
        probe_errors: the probes' :class:`~gfb_env.machine.ProbeErrors` of the last observation (None:
            ideal probes); tap_errors_kpa: the taps' errors of the last observation, kPa (None: ideal);
            observation_noise_draw: the legacy additive noise of the last observation (None: none).
            Kept references of what the observation computes anyway, for the privileged channel.
        orbit_tau: the times (tau) of ``orbit``'s samples (None: no record, e.g. a failed step).
        record_start: (tau, rotation angle theta, Lambda) at the last step's start (the key of the v2
            vibration monitor).
        interface: the information interface's state of the episode (None on v1;
            :class:`~gfb_env.envs.interface_v2.InterfaceEpisode` on v2).
    """

    model: GFBModel
    bearing: BearingParameters
    task: Any
    task_info: dict
    position_scale: float
    velocity_scale: float
    min_film_thickness: float
    orbit: tuple[np.ndarray, np.ndarray]
    history: History
    step: int = 0
    termination: TerminationReason | None = None
    xi_range: tuple[float, float] = (math.nan, math.nan)
    eta_range: tuple[float, float] = (math.nan, math.nan)
    whirl_amplitude: float = 0.0
    last_action: np.ndarray = field(default_factory=lambda: np.zeros(2))
    action_sanitised: bool = False
    disturbance: bool = False
    reward: float = 0.0
    episode_return: float = 0.0
    reward_terms: dict = field(default_factory=dict)
    integrator_steps: int = 0
    actuator: DampingActuatorState | None = None
    probe_bias_um: np.ndarray = field(default_factory=lambda: np.zeros(2))
    tap_bias_kpa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    probe_readings_um: np.ndarray = field(default_factory=lambda: np.zeros(2))
    balance_grade_mm_s: float = 0.0
    shocks: tuple = ()
    shock_count: int = 0
    command: Any = None
    task_hidden: dict = field(default_factory=dict)
    shock_schedule: tuple = ()
    damping_gain_start: float = math.nan
    regime_changes: tuple = ()
    probe_errors: Any = None
    tap_errors_kpa: np.ndarray | None = None
    observation_noise_draw: np.ndarray | None = None
    orbit_tau: np.ndarray | None = None
    record_start: tuple[float, float, float] = (math.nan, 0.0, math.nan)
    interface: Any = None

    @property
    def done(self) -> bool:
        return self.termination is not None

    def __deepcopy__(self, memo: dict) -> Episode:
        # the model and the bearing are immutable for the episode: share them, copy the rest
        out = copy.copy(self)
        for name, value in vars(self).items():
            if name not in ("model", "bearing"):
                setattr(out, name, copy.deepcopy(value, memo))
        return out
