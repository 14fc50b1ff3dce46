"""The oracle of the v1 (commanded-speed) tasks (1 on the benchmark's normalised scale).

:class:`CommandedOracle` (``oracle_v1``) is NOT an honest rule: it knows every hidden parameter of the
episode, read through the env's privileged channel (issue 19, :mod:`gfb_env.envs.privileged`; never from
the observation or ``info``): ``env.unwrapped.hidden()`` (the actual bearing, which turns the observed
speed into the true Lambda), ``env.unwrapped.privileged_quantities()`` (the true whirl amplitude),
``env.unwrapped.best_stable_operating_point()`` (the exact ``lambda_best`` of the drawn plant over the
achievable actual damping, the actual ``D_opt`` and its command ``D_opt / g``), and the public
``env.unwrapped.speed_command`` (``Lambda_cmd``, observed as n_cmd).  It does not know future shocks.
Its plan:

* RunUp-v1 / RunUpRandomized-v1: command ``D_opt / g`` from the first step; ramp at the motor limit to
  ``min(Lambda_cmd, (1 - margin) lambda_best)``; hold.
* WhirlRecovery-v1: command ``D_opt / g`` (the damping that narrows the hysteresis band most is not
  tabulated for the tasks' foil, ``docs/agents.md``; ``D_opt`` keeps the equilibrium's margin largest);
  decelerate at the motor limit while the true whirl amplitude exceeds ``collapse_amplitude`` (the
  whirl cycle dies once the speed falls below the fold; the oracle sees the true orbit), then return at
  the motor limit to ``min(Lambda_cmd, (1 - margin) lambda_best)`` and hold.

Causal under friction-regime changes of ``g`` (``damping_regime_changes``,
:class:`~gfb_env.machine.DampingRegimeChanges`): before every action it reads the *current* ``g``
(``env.unwrapped.damping_gain``, privileged) and, when it changed since the plan, makes the plan again
for the new plant (the damping ``D_opt / g`` and the setpoint; WhirlRecovery's deceleration phase goes
on where it was).  It never knows a change before the step after it happened (the changes are drawn
step by step, like the shocks).

``margin`` (and ``collapse_amplitude``) are tuned on the training seeds 0-99 only (``docs/envs.md``).

The naive baseline (0 on that scale) is :class:`gfb_agents.ladder.NaiveRampAgent` (``naive``), the same
agent on every task.

It follows the agents' interface (:class:`gfb_agents.policy.PrivilegedPolicy`: ``reset()``,
``observe_reset_info(info)`` after the env's reset, ``predict(obs, ...)``).  One env at a time.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gfb_agents.policy import PrivilegedPolicy

__all__ = ["CommandedOracle", "DelayedGainOracle", "ORACLE_MARGIN", "ORACLE_COLLAPSE_AMPLITUDE"]

#: the oracle's relative margin below lambda_best (tuned on training seeds 0-99 of the v1 ids, now retired and
#: kept for the record; ``docs/envs.md``)
ORACLE_MARGIN = {
    "gfb_env/RunUp-v1": 0.01,
    "gfb_env/RunUpRandomized-v1": 0.01,
    "gfb_env/WhirlRecovery-v1": 0.01,
    # v2 (issue 19): the same plants and the judge's boundary as v1, so v1's margins
    "gfb_env/RunUp-v2": 0.01,
    "gfb_env/RunUpRandomized-v2": 0.01,
    "gfb_env/WhirlRecovery-v2": 0.01,
}
#: WhirlRecovery-v1: the true whirl amplitude (units of C) below which the oracle stops decelerating
ORACLE_COLLAPSE_AMPLITUDE = 0.05


class _OneEnvPolicy(PrivilegedPolicy):
    """A policy bound to one env (``predict`` takes one observation or a batch of one)."""

    def __init__(self, env: Any, name: str):
        self.env = env
        self.u = getattr(env, "unwrapped", env)
        self.name = name
        self._started = False

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        o = obs if single else obs[0]
        if not single and obs.shape[0] != 1:
            raise ValueError(f"{self.name} plays one env at a time, got a batch of {obs.shape[0]}")
        if episode_start is not None and bool(np.asarray(episode_start).reshape(-1)[0]) and not self._started:
            self._begin(o)
        a = np.asarray(self._act(o), dtype=np.float32)
        return (a if single else a[None, :]), state

    def reset(self) -> None:
        """Forget the episode (the plan is made again at the next one's start)."""
        self._started = False

    def observe_reset_info(self, info: Mapping[str, Any]) -> None:
        """Called by the evaluation after ``env.reset`` (the episode's plan is made here)."""
        self._begin(None)

    def _begin(self, obs: np.ndarray | None) -> None:
        self._started = True
        self._plan()

    def _plan(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _act(self, obs: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def _track(self, setpoint_bearing_number: float) -> float:
        """Speed action toward ``setpoint`` (dead-beat at the motor limit; the true speed)."""
        u = self.u
        bearing = u.hidden().bearing  # the actual bearing (privileged: its clearance is drawn)
        lam = bearing.bearing_number_at(u.observation_layout.speed_rpm(self._obs))
        step = u.max_rate(bearing) * u.step_tau  # the plant's tau per step (v2: a fixed period in s)
        return float(np.clip((setpoint_bearing_number - lam) / step, -1.0, 1.0))


class CommandedOracle(_OneEnvPolicy):
    """``oracle_v1`` (module docstring).  ``margin``: relative distance below ``lambda_best``;
    ``collapse_amplitude``: WhirlRecovery's end of the deceleration (true whirl amplitude, units of C)."""

    kind = "oracle"

    def __init__(
        self,
        env: Any,
        margin: float | None = None,
        collapse_amplitude: float = ORACLE_COLLAPSE_AMPLITUDE,
        name: str = "oracle_v1",
    ):
        super().__init__(env, name)
        spec_id = getattr(getattr(env, "spec", None), "id", None)
        self.margin = float(ORACLE_MARGIN.get(spec_id, 0.01) if margin is None else margin)
        if not 0.0 <= self.margin < 0.5:
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.collapse_amplitude = float(collapse_amplitude)
        self.whirl_start = hasattr(self.u, "whirl_bearing_number")

    def _plan(self) -> None:
        self._plan_plant()
        self.recovering = self.whirl_start

    def _plan_plant(self) -> None:
        """The damping command and the setpoint for the plant as it is now (its current ``g``)."""
        u = self.u
        self.planned_gain = u.damping_gain
        best = u.best_stable_operating_point()
        cmd = u.speed_command
        self.setpoint = min(cmd.bearing_number, (1.0 - self.margin) * best.bearing_number)
        self.damping_action = u.action_from_damping(best.commanded_damping)

    def _act(self, obs: np.ndarray) -> np.ndarray:
        if not self._started:
            self._begin(obs)
        elif self.u.damping_gain != self.planned_gain:  # a friction-regime change: re-plan
            self._plan_plant()
        self._obs = obs
        if self.recovering:
            first = obs[-1] == 1.0  # time_left = steps_left / episode_steps: no step taken yet
            if self.u.privileged_quantities()["whirl_amplitude"] > self.collapse_amplitude or first:
                return np.array([-1.0, self.damping_action])
            self.recovering = False
        return np.array([self._track(self.setpoint), self.damping_action])


class DelayedGainOracle(CommandedOracle):
    """``oracle_v1`` that learns of a friction-regime change ``delay_steps`` control steps late: an
    idealised change detector (exact re-identification, a fixed detection delay) for the redesign's
    question of what a rule could still do (``docs/task_redesign.md``).  Not a benchmarked agent and not
    honest (it reads the hidden g, only later).

    Before each action it plans with the g of ``delay_steps`` actions ago (the reset's g before that):
    the command ``D_opt / g_delayed`` with the actual ``D_opt`` and the setpoint of the plant as it is
    (on WhirlRecovery and RunUp the unconstrained optimum ``D_opt`` lies inside ``[g D_min, g D_max]``
    for every g of the bounds, so ``D_opt`` and ``lambda_best`` do not depend on g and only the command
    does).  ``delay_steps = 0`` is ``oracle_v1``."""

    def __init__(self, env, delay_steps: int, name: str | None = None, **kw):
        if isinstance(delay_steps, bool) or not isinstance(delay_steps, int) or delay_steps < 0:
            raise ValueError(f"delay_steps must be an integer >= 0, got {delay_steps!r}")
        super().__init__(env, name=name or f"oracle_delay{delay_steps}", **kw)
        self.delay_steps = delay_steps
        self._gains: list[float] = []

    def _plan(self) -> None:
        self._gains = []
        super()._plan()

    def _plan_plant(self) -> None:
        u = self.u
        self._gains.append(u.damping_gain)
        known = self._gains[max(0, len(self._gains) - 1 - self.delay_steps)]
        self.planned_gain = u.damping_gain
        best = u.best_stable_operating_point()
        self.setpoint = min(u.speed_command.bearing_number, (1.0 - self.margin) * best.bearing_number)
        self.damping_action = u.action_from_damping(best.foil_damping / known)

    def _act(self, obs: np.ndarray) -> np.ndarray:
        if self._started and self._gains:
            self._plan_plant()  # every step: the g it knows moves with the delay
            self.planned_gain = self.u.damping_gain
        return super()._act(obs)
