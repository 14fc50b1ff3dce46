"""Scripted baselines for the gfb_env tasks, behind one small SB3-like policy interface.

Every agent (scripted here, learned in :mod:`gfb_agents.evaluate`) implements::

    policy.reset()                                           # forget everything (a new episode)
    action, state = policy.predict(obs, state=None, episode_start=None, deterministic=True)

``obs`` is the env's documented observation (one of shape ``(n_obs,)`` or a batch ``(n_envs, n_obs)``);
``episode_start`` (a bool or an array of them, as SB3 passes it) resets the memory of the matching env.
Scripted agents read only the documented observation (indices below), the env's documented
configuration (:class:`ControlSpec`: action mapping, motor limit, control interval, nominal task
target) and the nominal map (:class:`~gfb_agents.nominal_map.NominalMap`); never the drawn parameters nor
the simulator state.

The observation and action units have one owner, :mod:`gfb_env.envs.units` (``env.observation_layout``
and ``env.actions``); the agents decode observations and encode actions only through it.

Agents:

* :class:`ScheduleAgent`: the paper's schedule -- a linear speed ramp (half the motor limit) at a
  constant foil damping to a set-point, then hold (``ScheduleAgent.from_schedule``: the run-up that
  ``gfb schedule`` designed).
* :class:`MapInformedAgent`: damping at the map's ``argmax Lambda_c``, ramp at the motor limit, hold at
  ``(1 - margin) Lambda_c(d_opt)`` (``below_fold=True``: below the fold of cycles instead); the v1 rule
  ``map_informed_v1`` caps it at the task's command (:mod:`gfb_agents.rules_v1`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_env.envs.units import ActionMap, ObservationLayout

__all__ = [
    "Policy",
    "ControlSpec",
    "TrackerMemory",
    "ScheduleAgent",
    "MapInformedAgent",
]


class Policy:
    """SB3-like policy interface shared by scripted and learned agents."""

    name: str = "policy"
    kind: str = "scripted"

    def reset(self) -> None:
        """Forget the episode memory of every env."""

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for ``observation`` (shape ``(n_obs,)`` or ``(n_envs, n_obs)``).

        Returns ``(action, state)`` with ``action`` of shape ``(2,)`` or ``(n_envs, 2)`` in ``[-1, 1]``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


@dataclass(frozen=True)
class ControlSpec:
    """The env's documented configuration that a scripted agent may use.

    Attributes:
        actions: the env's action map (log-scaled damping, motor limit).
        observations: the env's observation layout (indices, scales, decoders).
        rpm_per_step: nominal speed change of one control step at action[0] = 1 (motor limit times the
            control step of the *nominal* bearing; for a randomised bearing the agents re-estimate it).
        target_rpm: the nominal task's target speed (``target_fraction * lambda_best`` of the nominal
            bearing; the set-point of a rule that reads no command).
        stable_amplitude: whirl amplitude (units of C) that counts as stable.
    """

    actions: ActionMap
    observations: ObservationLayout
    rpm_per_step: float
    target_rpm: float
    stable_amplitude: float

    @classmethod
    def from_env(cls, env, nmap: NominalMap | None = None) -> ControlSpec:
        u = getattr(env, "unwrapped", env)
        nmap = nmap or NominalMap.from_env(u)
        frac = float(getattr(u, "target_fraction", 0.95))
        return cls(
            actions=u.actions,
            observations=u.observation_layout,
            rpm_per_step=u.actions.rpm_per_step(u.nominal_bearing, u.control_interval),
            target_rpm=float(nmap.rpm(frac * nmap.lambda_best)),
            stable_amplitude=float(u.stable_amplitude),
        )

    @property
    def damping_range(self) -> tuple[float, float]:
        return self.actions.damping_range

    def damping_action(self, d: float) -> float:
        """Action[1] for damping ``d`` (the env's log mapping, clipped)."""
        return self.actions.action_from_damping(d)


@dataclass
class TrackerMemory:
    """The per-env memory of a scripted agent's speed tracker (subclassed by the rules for their own).

    Attributes:
        k: control steps taken in this episode.
        rate: the estimated speed change (rpm) of one control step at action[0] = 1.
        prev_rpm: the speed of the previous step (None before the first).
        prev_a0: the previous speed action.
    """

    k: int = 0
    rate: float = 0.0
    prev_rpm: float | None = None
    prev_a0: float = 0.0


class ScriptedPolicy(Policy):
    """Base of the scripted agents: per-env memory, a speed set-point tracker with an online estimate of
    the speed change per control step (the randomised clearance changes the time scale)."""

    kind = "scripted"

    def __init__(self, name: str, spec: ControlSpec):
        self.name = name
        self.spec = spec
        self._mem: list[TrackerMemory] = []

    def reset(self) -> None:
        self._mem = []

    def _new_memory(self) -> TrackerMemory:
        return TrackerMemory(rate=self.spec.rpm_per_step)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs2 = obs[None, :] if single else obs
        n = obs2.shape[0]
        starts = (
            np.zeros(n, dtype=bool)
            if episode_start is None
            else np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,))
        )
        while len(self._mem) < n:
            self._mem.append(self._new_memory())
        acts = np.empty((n, 2), dtype=np.float32)
        for i in range(n):
            if starts[i]:
                self._mem[i] = self._new_memory()
            m = self._mem[i]
            rpm = self.spec.observations.speed_rpm(obs2[i])
            self._update_rate(m, rpm)
            a = np.clip(np.asarray(self._act(obs2[i], rpm, m), dtype=np.float64), -1.0, 1.0)
            m.prev_rpm, m.prev_a0, m.k = rpm, float(a[0]), m.k + 1
            acts[i] = a
        return (acts[0] if single else acts), state

    @staticmethod
    def _update_rate(m: TrackerMemory, rpm: float) -> None:
        """Re-estimate the rpm per control step at action[0] = 1 from the last full-rate step."""
        if m.prev_rpm is not None and abs(m.prev_a0) >= 0.5:
            r = (rpm - m.prev_rpm) / m.prev_a0
            if r > 0.2 * m.rate and r < 5 * m.rate:
                m.rate = r

    @staticmethod
    def track(m: TrackerMemory, rpm: float, setpoint: float, max_rate: float = 1.0) -> float:
        """Action[0] that moves the speed to ``setpoint`` (dead-beat with the estimated step rate)."""
        return float(np.clip((setpoint - rpm) / m.rate, -max_rate, max_rate))

    def _act(
        self, obs: np.ndarray, rpm: float, m: TrackerMemory
    ) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


class ScheduleAgent(ScriptedPolicy):
    """The paper's schedule: a linear ramp at ``ramp`` of the motor limit to ``setpoint_rpm`` (default the
    nominal task target) at constant damping ``damping``, then hold."""

    def __init__(
        self,
        spec: ControlSpec,
        damping: float,
        ramp: float = 0.5,
        setpoint_rpm: float | None = None,
        name: str | None = None,
    ):
        super().__init__(name or f"paper_ramp_D{damping:g}", spec)
        if not (0 < ramp <= 1):
            raise ValueError(f"ramp must lie in (0, 1], got {ramp!r}")
        self.damping, self.ramp = float(damping), float(ramp)
        self.setpoint_rpm = float(setpoint_rpm if setpoint_rpm is not None else spec.target_rpm)

    @classmethod
    def from_schedule(cls, spec: ControlSpec, schedule, name: str = "designed_schedule") -> ScheduleAgent:
        """The run-up designed by ``gfb schedule`` (:class:`gfb_env.analysis.schedule.RunUpSchedule`):
        its damping, its acceleration (as a fraction of the env's motor limit, at most 1) and its end
        speed."""
        b = schedule.model.bearing
        accel = b.rate_rpm_per_s(schedule.rate)
        ramp = min(1.0, accel / spec.actions.max_acceleration_rpm_per_s)
        return cls(spec, schedule.foil_damping, ramp, b.speed_rpm_at(schedule.end_bearing_number), name)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm, self.ramp), self.spec.damping_action(self.damping)]


class MapInformedAgent(ScriptedPolicy):
    """Damping at the map's optimum (``argmax Lambda_c``), ramp at the motor limit, hold at
    ``(1 - margin) Lambda_c(d_opt)``; with ``below_fold=True`` hold at ``(1 - margin) Lambda_fold`` instead
    (where the map knows the fold), so that no disturbance can start a surviving whirl."""

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        margin: float = 0.05,
        below_fold: bool = False,
        name: str | None = None,
    ):
        super().__init__(name or ("map_informed_fold" if below_fold else "map_informed"), spec)
        if not (0 <= margin < 0.5):
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping = nmap.best_fold_damping() if below_fold else nmap.d_opt
        lam = nmap.critical_at(self.damping)
        if below_fold and math.isfinite(nmap.fold_at(self.damping)):
            lam = nmap.fold_at(self.damping)
        self.setpoint_rpm = nmap.rpm((1.0 - margin) * lam)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm), self.spec.damping_action(self.damping)]
