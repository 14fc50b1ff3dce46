"""The commanded-speed objective of the tasks, a component each task holds (``env.objective``, a
:class:`CommandedObjective`), shared by RunUp, RunUpRandomized and WhirlRecovery (v2, and the retired v1)
(``docs/envs.md``, issues 11 and 18).

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
  achievable actual damping ``[g D_min, g D_max]``
  (:meth:`~gfb_env.envs.base.GFBEnv.best_stable_operating_point`, computed only when the command itself
  was not reached).
* **Reward**: :class:`~gfb_env.envs.rewards.CommandedSpeedReward` (per-step speed progress, whirl,
  the certified bonus and the on-target bonus of a successful episode).
* **Costs** (Safety-Gymnasium style, :class:`CostSpec`): ``info["cost"]`` per step.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from gfb_env.envs.certify import (
    BestStablePoint,
    Certificate,
    StabilityCertificate,
    below_best_stable_speed,
)
from gfb_env.envs.certify_v2 import AfterShockCertificate
from gfb_env.envs.config import check_in, check_int, check_nonnegative, check_positive
from gfb_env.envs.episode import StepOutcome
from gfb_env.envs.rewards import CommandedSpeedReward
from gfb_env.envs.units import SPEED_COMMAND, TIME_LEFT
from gfb_env.equilibrium import EquilibriumError
from gfb_env.model import GFBModel

__all__ = [
    "SpeedCommand",
    "CostSpec",
    "CommandedObjective",
    "CommandedEpisode",
    "CertifiedPlant",
    "V1_TARGET_TOLERANCE",
    "unconstrained_cache_key",
    "as_component",
]

#: v1 defaults (``docs/envs.md``): the relative shortfall of the window-mean speed that still counts
V1_TARGET_TOLERANCE = 0.02


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


def as_component(name: str, cls: type, value: Any, default: Any = None) -> Any:
    """``value`` as a ``cls``: an instance as is, a dict of its fields over ``default`` (default: the
    class's defaults), None: ``default``.  An unknown field or another type raises ``ValueError``."""
    base = cls() if default is None else default
    if value is None:
        return base
    if isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        known = {f.name for f in fields(cls)}
        bad = sorted(set(value) - known)
        if bad:
            raise ValueError(f"{name}: unknown field(s) {bad} (fields: {', '.join(sorted(known))})")
        return dataclasses.replace(base, **value)
    raise ValueError(f"{name} must be a {cls.__name__}, a dict of its fields or None, got {value!r}")


@dataclass(frozen=True)
class CommandedObjective:
    """The commanded-speed objective of one env (module docstring): a component the task holds.

    It owns the objective's part of every stage: the observation's last two entries
    (:meth:`observation`), the per-step bookkeeping, the certificate at the horizon and the success
    (:meth:`judge`), the reward terms (:meth:`reward_terms`), the horizon (:meth:`horizon_reached`)
    and the info entries (:meth:`info`).  The episode's state lives in a :class:`CommandedEpisode`
    (part of the snapshotted episode).

    Attributes:
        episode_steps: the fixed horizon (control steps).
        certificate: the stability certificate (``stable_amplitude``, ``hold_steps``: the window).
        target_tolerance: relative shortfall of the window-mean speed that still counts as reached.
        reward: the reward weights (a :class:`~gfb_env.envs.rewards.CommandedSpeedReward` or a dict of
            its fields).
        costs: the safety cost and its constraint (a :class:`CostSpec` or a dict of its fields).
    """

    episode_steps: int
    certificate: StabilityCertificate
    target_tolerance: float = V1_TARGET_TOLERANCE
    reward: CommandedSpeedReward = field(default_factory=CommandedSpeedReward)
    costs: CostSpec = field(default_factory=CostSpec)

    #: the names of the objective's observation entries (they end the observation)
    observation_names: ClassVar[tuple[str, str]] = (SPEED_COMMAND, TIME_LEFT)

    def __post_init__(self) -> None:
        object.__setattr__(self, "episode_steps", check_int("episode_steps", self.episode_steps, 1, 100_000))
        if not isinstance(self.certificate, (StabilityCertificate, AfterShockCertificate)):
            raise ValueError(
                "certificate must be a StabilityCertificate or an AfterShockCertificate, got "
                f"{self.certificate!r}"
            )
        object.__setattr__(
            self,
            "target_tolerance",
            check_in("target_tolerance", self.target_tolerance, 0.0, 0.5, lo_open=True, hi_open=True),
        )
        object.__setattr__(self, "reward", as_component("reward", CommandedSpeedReward, self.reward))
        object.__setattr__(self, "costs", as_component("costs", CostSpec, self.costs))
        if self.certificate.hold_steps > self.episode_steps:
            raise ValueError(
                f"hold_steps ({self.certificate.hold_steps}) must not exceed "
                f"episode_steps ({self.episode_steps})"
            )

    # ---- observation --------------------------------------------------------------------------
    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of :meth:`observation`: both entries in [0, 1]."""
        return np.zeros(2), np.ones(2)

    def observation(self, ce: CommandedEpisode, step: int, speed_scale_rpm: float) -> np.ndarray:
        """``[n_cmd / speed_scale_rpm, steps_left / episode_steps]`` after ``step`` control steps."""
        steps = self.episode_steps
        return np.array([ce.command.speed_rpm / speed_scale_rpm, (steps - step) / steps])

    # ---- judge --------------------------------------------------------------------------------
    def judge(
        self,
        ce: CommandedEpisode,
        out: StepOutcome,
        stable: bool,
        step: int,
        plant: CertifiedPlant,
    ) -> bool:
        """Book one control step (``step``: steps taken before it; ``stable``: no touchdown, no failure,
        small whirl) into ``ce``; at the horizon certify ``plant`` and decide the success (returned)."""
        n = self.certificate.hold_steps
        amp = out.whirl_amplitude if not (out.touchdown or out.solver_failure) else math.inf
        ce.stable = stable
        p = ce.command.progress(out.bearing_number)
        for lst, v in ((ce.amplitudes, amp), (ce.bearing_numbers, out.bearing_number), (ce.progresses, p)):
            lst.append(float(v))
            del lst[:-n]
        ce.costs = self.costs.terms(out)
        ce.episode_cost += ce.costs["cost"]
        if step + 1 < self.episode_steps:
            return False
        if out.touchdown or out.solver_failure:
            ce.certificate = Certificate(False, "not_judged", math.nan)
            return False
        ce.certificate = self.certificate.certify(ce.amplitudes, plant, out.bearing_number, out.foil_damping)
        ce.success = ce.certificate.certified and self._speed_reached(ce, plant)
        return ce.success

    def _speed_reached(self, ce: CommandedEpisode, plant: CertifiedPlant) -> bool:
        """Window-mean Lambda >= (1 - tol) min(Lambda_cmd, lambda_best), exactly.  Only when the command
        itself was not reached does lambda_best matter: then ``mean >= (1 - tol) lambda_best`` iff
        ``Lambda* = mean / (1 - tol)`` is NOT below the best stable speed, i.e. iff no achievable actual
        damping makes the equilibrium at Lambda* stable: one :func:`below_best_stable_speed` (~0.1 s),
        or the episode's best point where it is already known (cached, or a fixed plant's)."""
        need = 1.0 - self.target_tolerance
        mean = float(np.mean(ce.bearing_numbers))
        if mean >= need * ce.command.bearing_number:
            return True
        try:
            if plant.best_point is not None:
                best = plant.best_point().bearing_number
                return mean >= need * min(ce.command.bearing_number, best)
            return not below_best_stable_speed(
                plant.model, mean / need, plant.achievable_damping, plant.state
            )
        except _BEST_POINT_FAILURES:
            # never crash a step: without the optimum only the command counts (not seen on the tasks'
            # parameter boxes; a test forces it)
            return False

    def horizon_reached(self, steps_taken: int) -> bool:
        """Whether the episode ends (``terminated``) after ``steps_taken`` control steps."""
        return steps_taken >= self.episode_steps

    def reward_terms(self, ce: CommandedEpisode, out: StepOutcome) -> dict[str, float]:
        """The reward's named terms of the step just judged (they sum to the reward)."""
        cert = ce.certificate
        mean_p = float(np.mean(ce.progresses)) if (cert is not None and cert.certified) else None
        return self.reward.terms(out, ce.stable, ce.progresses[-1], mean_p, ce.success)

    # ---- emit ---------------------------------------------------------------------------------
    def info(self, ce: CommandedEpisode, steps_taken: int, bearing_number: float, success: bool) -> dict:
        """The objective's entries of ``info``."""
        cert = ce.certificate
        return {
            "speed_command_rpm": ce.command.speed_rpm,
            "speed_command_bearing_number": ce.command.bearing_number,
            "reference_bearing_number": ce.command.reference_bearing_number,
            "episode_steps": self.episode_steps,
            "steps_left": self.episode_steps - steps_taken,
            "speed_progress": ce.progresses[-1] if ce.progresses else ce.command.progress(bearing_number),
            "certified": bool(cert is not None and cert.certified),
            "certification": cert.reason if cert is not None else None,
            # None where not computed (a NaN would make equal infos compare unequal)
            "growth_rate": cert.growth_rate
            if (cert is not None and math.isfinite(cert.growth_rate))
            else None,
            "is_success": success,
            "episode_cost": ce.episode_cost,
            **ce.costs,
        }


@dataclass(frozen=True)
class CertifiedPlant:
    """What the certificate and the success test read of the actual (hidden) plant at the horizon.

    Attributes:
        model: the episode's plant; state: its state at the horizon.
        achievable_damping: ``[g D_min, g D_max]``, the actual damping the actuator can set.
        best_point: the episode's exact best stable point where it is known or cheap (a fixed plant's,
            cached), else None (the success is then decided by one stability test).
        shocks: every base shock of the episode so far (:class:`~gfb_env.machine.ShockEvent`);
            time_s: the time at the horizon, s; step_s, step_tau: one control step in s and in tau (for
            the v2 certificate's shock window, :class:`~gfb_env.envs.certify_v2.AfterShockCertificate`).
    """

    model: GFBModel
    state: np.ndarray
    achievable_damping: tuple[float, float]
    best_point: Callable[[], BestStablePoint] | None
    shocks: tuple = ()
    time_s: float = math.nan
    step_s: float = math.nan
    step_tau: float = math.nan


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


def unconstrained_cache_key(model: GFBModel, search: tuple[float, float]) -> tuple:
    """Cache key of a fixed plant's unconstrained optimum (grid, K_W, bearing, search range)."""
    return (str(model.grid), model.foil_stiffness, tuple(sorted(model.bearing.as_dict().items())), search)
