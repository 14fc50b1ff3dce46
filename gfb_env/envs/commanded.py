"""The commanded-speed objective of the v1 tasks, shared by RunUp-v1, RunUpRandomized-v1 and
WhirlRecovery-v1 (``docs/envs.md``, issue 11).

* **Command**: per episode an operating speed ``n_cmd`` is commanded and observed (the observation ends
  with ``[n_cmd / 60 000 rpm, steps_left / episode_steps]``, :data:`~gfb_env.envs.units.SPEED_COMMAND`,
  :data:`~gfb_env.envs.units.TIME_LEFT`).  The task: run as close to ``n_cmd`` as is stably possible.
* **Fixed horizon**: the env owns ``episode_steps``; the last step returns ``terminated=True``
  (``termination_reason`` ``"success"`` or ``"horizon"``); touchdown and solver failure end earlier.
* **Certification at the horizon** (:class:`~gfb_env.envs.certify.StabilityCertificate`): the whirl
  amplitude stayed below ``stable_amplitude`` over the last ``hold_steps`` steps *and* the actual plant
  (the episode's bearing, the actual ``D_W``, the final ``Lambda``) has a linearly stable equilibrium.
* **Success**: certified and the window-mean ``Lambda >= (1 - target_tolerance) min(Lambda_cmd,
  lambda_best)``, ``lambda_best`` the exact best stable bearing number of the episode's plant over the
  achievable actual damping ``[g D_min, g D_max]`` (:meth:`CommandedSpeedMixin.best_stable_operating_point`,
  computed only when the command itself was not reached).
* **Reward**: :class:`~gfb_env.envs.rewards.CommandedSpeedReward` (per-step speed progress, whirl,
  the certified bonus and the on-target bonus of a successful episode).
* **Costs** (Safety-Gymnasium style, :class:`CostSpec`): ``info["cost"]`` per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gfb_env.envs.certify import (
    BestStablePoint,
    Certificate,
    StabilityCertificate,
    below_best_stable_speed,
    best_stable_operating_point,
)
from gfb_env.envs.config import check_in, check_int, check_nonnegative, check_positive
from gfb_env.envs.episode import StepOutcome, TerminationReason
from gfb_env.envs.rewards import CommandedSpeedReward
from gfb_env.envs.units import SPEED_COMMAND, TIME_LEFT
from gfb_env.equilibrium import EquilibriumError
from gfb_env.model import GFBModel

__all__ = [
    "SpeedCommand",
    "CostSpec",
    "CommandedTask",
    "CommandedEpisode",
    "CommandedSpeedMixin",
    "TASK_VERSIONS",
    "V1_TARGET_TOLERANCE",
    "build_commanded_task",
    "check_task_version",
]

#: the task versions a task class implements (0: the published v0 objective; 1: this module's)
TASK_VERSIONS = (0, 1)


@dataclass(frozen=True)
class SpeedCommand:
    """The operating-speed command of one episode.

    Attributes:
        speed_rpm: ``n_cmd`` (observed as ``n_cmd / speed_scale_rpm``).
        bearing_number: ``Lambda_cmd`` of the episode's bearing at ``n_cmd``.
        reference_bearing_number: ``Lambda_ref``, where the speed progress ``p`` is zero (RunUp: the start
            speed; WhirlRecovery: a documented lower reference).
    """

    speed_rpm: float
    bearing_number: float
    reference_bearing_number: float

    def progress(self, bearing_number: float) -> float:
        """``p = clip((Lambda - Lambda_ref) / (Lambda_cmd - Lambda_ref), 0, 1)``."""
        return CommandedSpeedReward.progress(
            bearing_number, self.reference_bearing_number, self.bearing_number
        )


@dataclass(frozen=True)
class CostSpec:
    """The per-step safety cost and the constraint of the v1 tasks (Safety-Gymnasium style).

    ``cost = 1`` in a step whose whirl amplitude exceeds ``whirl_amplitude`` (units of C) or whose min film
    thickness falls below ``film_thickness`` (units of C), or that touches down / fails; else 0.  The
    constraint: expected episode cost (the sum over the episode) ``<= episode_cost_limit``.

    Why these levels: 0.15 C is three times the stable threshold (a whirl that is clearly developing,
    ~7.5 um on the nominal bearing); 0.1 C (5 um) is five times the touchdown film (0.02 C): the rotor
    runs with half its margin to the foil's rubbing gone.  The loaded static equilibrium of the tasks has
    a film of 0.23-0.61 C (the drawn bearings' corners, from the start speed to Lambda = 0.7), so stable
    operation costs nothing; a WhirlRecovery episode starts on a whirl
    and pays while it lasts.  The limit 5 allows a few transient steps (e.g. the first steps of a
    recovery), not a sustained whirl.
    """

    whirl_amplitude: float = 0.15
    film_thickness: float = 0.1
    episode_cost_limit: float = 5.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "whirl_amplitude", check_positive("cost_whirl_amplitude", self.whirl_amplitude)
        )
        object.__setattr__(
            self, "film_thickness", check_in("cost_film_thickness", self.film_thickness, 0.0, 1.0)
        )
        object.__setattr__(
            self, "episode_cost_limit", check_nonnegative("episode_cost_limit", self.episode_cost_limit)
        )

    def terms(self, out: StepOutcome) -> dict[str, float]:
        """``cost_whirl``, ``cost_film``, ``cost_touchdown`` (0/1 each) and ``cost`` (their max)."""
        a, h = out.whirl_amplitude, out.min_film_thickness
        whirl = 1.0 if (math.isfinite(a) and a > self.whirl_amplitude) else 0.0
        film = 1.0 if (not math.isfinite(h) or h < self.film_thickness) else 0.0
        touchdown = 1.0 if (out.touchdown or out.solver_failure) else 0.0
        return {
            "cost": max(whirl, film, touchdown),
            "cost_whirl": whirl,
            "cost_film": film,
            "cost_touchdown": touchdown,
        }


@dataclass(frozen=True)
class CommandedTask:
    """The v1 objective of one env (module docstring).

    Attributes:
        episode_steps: the fixed horizon (control steps).
        target_tolerance: relative shortfall of the window-mean speed that still counts as reached.
        reward: the reward weights.
        certificate: the stability certificate (``stable_amplitude``, ``hold_steps``: the window).
        costs: the safety cost and its constraint.
    """

    episode_steps: int
    target_tolerance: float
    reward: CommandedSpeedReward
    certificate: StabilityCertificate
    costs: CostSpec = field(default_factory=CostSpec)

    def __post_init__(self) -> None:
        object.__setattr__(self, "episode_steps", check_int("episode_steps", self.episode_steps, 1, 100_000))
        object.__setattr__(
            self,
            "target_tolerance",
            check_in("target_tolerance", self.target_tolerance, 0.0, 0.5, lo_open=True, hi_open=True),
        )
        if self.certificate.hold_steps > self.episode_steps:
            raise ValueError(
                f"hold_steps ({self.certificate.hold_steps}) must not exceed "
                f"episode_steps ({self.episode_steps})"
            )


@dataclass
class CommandedEpisode:
    """What the v1 objective tracks within one episode (part of the snapshotted
    :class:`~gfb_env.envs.episode.Episode`).

    Attributes:
        command: the episode's speed command.
        amplitudes, bearing_numbers, progresses: the whirl amplitude, Lambda and speed progress ``p`` of
            the last ``hold_steps`` control steps (the certification window).
        stable: whether the last step was stable (no touchdown, no failure, small whirl).
        certificate: the verdict at the horizon (None before it).
        success: the episode succeeded.
        best: the exact best stable operating point, once computed (cached for the episode).
        costs: the cost terms of the last step; episode_cost: their ``cost`` summed over the episode.
    """

    command: SpeedCommand
    amplitudes: list[float] = field(default_factory=list)
    bearing_numbers: list[float] = field(default_factory=list)
    progresses: list[float] = field(default_factory=list)
    stable: bool = True
    certificate: Certificate | None = None
    success: bool = False
    best: BestStablePoint | None = None
    costs: dict = field(
        default_factory=lambda: {"cost": 0.0, "cost_whirl": 0.0, "cost_film": 0.0, "cost_touchdown": 0.0}
    )
    episode_cost: float = 0.0


#: what the exact best-point search may raise on an odd plant (no bracket, no equilibrium, ...)
_BEST_POINT_FAILURES = (RuntimeError, ValueError, EquilibriumError, FloatingPointError, np.linalg.LinAlgError)


def check_task_version(v: Any) -> int:
    if isinstance(v, bool) or v not in TASK_VERSIONS:
        raise ValueError(f"task_version must be one of {TASK_VERSIONS}, got {v!r}")
    return int(v)


class CommandedSpeedMixin:
    """The v1 objective on top of a :class:`~gfb_env.envs.base.GFBEnv` task (put it first in the bases).

    The task sets ``self.task_version`` *before* ``GFBEnv.__init__`` (the observation space depends
    on it), ``self.commanded`` (a :class:`CommandedTask`, or None for v0) after it, and puts a
    :class:`CommandedEpisode` into ``EpisodeSetup.command``; everything else (observation, judge, reward,
    costs, info) is here.  With ``self.commanded = None`` every hook defers to the task's v0 behaviour."""

    commanded: CommandedTask | None = None

    # ---- observation ----------------------------------------------------------------------------
    def _extra_observation_bounds(self):
        base = super()._extra_observation_bounds()
        if getattr(self, "task_version", 0) != 1:
            return base
        lo, hi = (np.zeros(0), np.zeros(0)) if base is None else (np.asarray(base[0]), np.asarray(base[1]))
        return np.concatenate([lo, [0.0, 0.0]]), np.concatenate([hi, [1.0, 1.0]])

    def _extra_observation_names(self) -> tuple[str, ...]:
        base = super()._extra_observation_names()
        if getattr(self, "task_version", 0) != 1:
            return base
        return (*base, SPEED_COMMAND, TIME_LEFT)

    def _extra_observation(self):
        base = super()._extra_observation()
        if self.commanded is None:
            return base
        ep = self.episode
        steps = self.commanded.episode_steps
        own = np.array([ep.command.command.speed_rpm / self.speed_scale_rpm, (steps - ep.step) / steps])
        return own if base is None else np.concatenate([base, own])

    # ---- judge ----------------------------------------------------------------------------------
    def _step_success(self, out: StepOutcome, stable: bool) -> bool:
        if self.commanded is None:
            return super()._step_success(out, stable)
        ep, task = self.episode, self.commanded
        ce: CommandedEpisode = ep.command
        n = task.certificate.hold_steps
        amp = out.whirl_amplitude if not (out.touchdown or out.solver_failure) else math.inf
        ce.stable = stable
        p = ce.command.progress(out.bearing_number)
        for lst, v in ((ce.amplitudes, amp), (ce.bearing_numbers, out.bearing_number), (ce.progresses, p)):
            lst.append(float(v))
            del lst[:-n]
        ce.costs = task.costs.terms(out)
        ce.episode_cost += ce.costs["cost"]
        if ep.step + 1 < task.episode_steps:
            return False
        if out.touchdown or out.solver_failure:
            ce.certificate = Certificate(False, "not_judged", math.nan)
            return False
        ce.certificate = task.certificate.judge(
            ce.amplitudes, ep.model, out.bearing_number, out.foil_damping, self._integ.state
        )
        ce.success = ce.certificate.certified and self._speed_reached(ce)
        return ce.success

    def _speed_reached(self, ce: CommandedEpisode) -> bool:
        """Window-mean Lambda >= (1 - tol) min(Lambda_cmd, lambda_best), exactly.  Only when the command
        itself was not reached does lambda_best matter: then ``mean >= (1 - tol) lambda_best`` iff
        ``Lambda* = mean / (1 - tol)`` is NOT below the best stable speed, i.e. iff no achievable actual
        damping makes the equilibrium at Lambda* stable: one :func:`below_best_stable_speed` (~0.1 s),
        or the episode's best point where it is already known (cached, or a fixed plant's)."""
        need = 1.0 - self.commanded.target_tolerance
        mean = float(np.mean(ce.bearing_numbers))
        if mean >= need * ce.command.bearing_number:
            return True
        try:
            if ce.best is not None or self._best_point_is_cached():
                best = self.best_stable_operating_point().bearing_number
                return mean >= need * min(ce.command.bearing_number, best)
            g, (dmin, dmax) = self.episode.actuator.gain, self.damping_range
            return not below_best_stable_speed(
                self.episode.model, mean / need, (g * dmin, g * dmax), self._integ.state
            )
        except _BEST_POINT_FAILURES:
            # never crash a step: without the optimum only the command counts (not seen on the tasks'
            # parameter boxes; a test forces it)
            return False

    def _best_point_is_cached(self) -> bool:
        """Whether the episode's plant has its optimum cached (fixed plants: after the first time)."""
        return False

    def _horizon_reached(self) -> bool:
        if self.commanded is None:
            return super()._horizon_reached()
        return self.episode.step >= self.commanded.episode_steps

    def _commanded_reward_terms(self, out: StepOutcome) -> dict[str, float]:
        ce: CommandedEpisode = self.episode.command
        cert = ce.certificate
        mean_p = float(np.mean(ce.progresses)) if (cert is not None and cert.certified) else None
        return self.commanded.reward.terms(out, ce.stable, ce.progresses[-1], mean_p, ce.success)

    # ---- the episode's command and hidden plant (public, per episode) ---------------------------
    @property
    def speed_command(self) -> SpeedCommand:
        """The episode's speed command (observed: ``n_cmd``; here also ``Lambda_cmd``, ``Lambda_ref``)."""
        ce = self.episode.command
        if ce is None:
            raise AttributeError("speed_command: only the v1 (commanded-speed) tasks have one")
        return ce.command

    @property
    def damping_gain(self) -> float:
        """The episode's hidden damping effectiveness ``g`` (actual D_W = g x commanded; for oracles)."""
        return float(self.episode.actuator.gain)

    # ---- the episode's hidden optimum -------------------------------------------------------------
    def best_stable_operating_point(self) -> BestStablePoint:
        """The exact best stable operating point of this episode's plant for the achievable actual
        damping ``[g D_min, g D_max]`` (g: the episode's hidden damping effectiveness): ``lambda_best``,
        the actual ``D_opt``, the command ``D_opt / g`` and the speed.  Cached for the episode (~0.3 s
        for a drawn bearing, once per env for the nominal one).  For the oracle and the evaluation: it
        reads the hidden plant."""
        ep = self.episode
        ce: CommandedEpisode | None = ep.command
        if ce is not None and ce.best is not None:
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
        best = BestStablePoint(lam, d, d / g, ep.bearing.speed_rpm_at(lam))
        if ce is not None:
            ce.best = best
        return best

    def _unconstrained_best_point(self) -> tuple[float, float]:
        """``(lambda_best, D_opt)`` of the episode's plant over every actual damping any gain of the
        actuator can reach (:meth:`_damping_search_range`).  Tasks cache it where the plant is fixed."""
        return best_stable_operating_point(
            self.episode.model, self._damping_search_range(), self._best_bearing_number_guess()
        )

    def _damping_search_range(self) -> tuple[float, float]:
        act, (dmin, dmax) = self.damping_actuator, self.damping_range
        glo, ghi = act.gain_range if act.gain_range is not None else (act.gain, act.gain)
        return glo * dmin, ghi * dmax

    def _best_bearing_number_guess(self) -> float:  # pragma: no cover - task hook
        raise NotImplementedError

    # ---- info -----------------------------------------------------------------------------------
    def _info(self) -> dict:
        info = super()._info()
        if self.commanded is None:
            return info
        ep = self.episode
        ce: CommandedEpisode = ep.command
        cert = ce.certificate
        info.update(
            {
                "speed_command_rpm": ce.command.speed_rpm,
                "speed_command_bearing_number": ce.command.bearing_number,
                "reference_bearing_number": ce.command.reference_bearing_number,
                "episode_steps": self.commanded.episode_steps,
                "steps_left": self.commanded.episode_steps - ep.step,
                "speed_progress": ce.progresses[-1]
                if ce.progresses
                else ce.command.progress(info["bearing_number"]),
                "certified": bool(cert is not None and cert.certified),
                "certification": cert.reason if cert is not None else None,
                # None where not computed (a NaN would make equal infos compare unequal)
                "growth_rate": cert.growth_rate
                if (cert is not None and math.isfinite(cert.growth_rate))
                else None,
                "is_success": ep.termination is TerminationReason.SUCCESS,
                "episode_cost": ce.episode_cost,
                **ce.costs,
            }
        )
        return info


def unconstrained_cache_key(model: GFBModel, search: tuple[float, float]) -> tuple:
    """Cache key of a fixed plant's unconstrained optimum (grid, K_W, bearing, search range)."""
    return (str(model.grid), model.foil_stiffness, tuple(sorted(model.bearing.as_dict().items())), search)


#: v1 defaults (``docs/envs.md``): the relative shortfall of the window-mean speed that still counts
V1_TARGET_TOLERANCE = 0.02


def build_commanded_task(
    task_version: int,
    *,
    episode_steps: int | None,
    default_episode_steps: int,
    target_tolerance: float | None,
    speed_weight: float | None,
    whirl_penalty: float,
    success_bonus: float,
    touchdown_penalty: float | None,
    stable_amplitude: float,
    hold_steps: int,
    costs: CostSpec,
    v1_only: dict[str, Any],
) -> CommandedTask | None:
    """The :class:`CommandedTask` of ``task_version`` 1 (None for 0, which refuses every v1-only
    argument that is not None: ``episode_steps``, ``speed_weight`` and the names in ``v1_only``)."""
    if task_version == 0:
        given = {"episode_steps": episode_steps, "speed_weight": speed_weight, **v1_only}
        bad = [k for k, v in given.items() if v is not None]
        if bad:
            raise ValueError(f"{', '.join(bad)}: only for task_version=1 (the commanded-speed tasks)")
        return None
    reward = CommandedSpeedReward(
        speed_weight=0.1 if speed_weight is None else speed_weight,
        whirl_penalty=whirl_penalty,
        success_bonus=success_bonus,
        touchdown_penalty=100.0 if touchdown_penalty is None else touchdown_penalty,
    )
    return CommandedTask(
        episode_steps=default_episode_steps if episode_steps is None else episode_steps,
        target_tolerance=V1_TARGET_TOLERANCE if target_tolerance is None else target_tolerance,
        reward=reward,
        certificate=StabilityCertificate(stable_amplitude, hold_steps),
        costs=costs,
    )
