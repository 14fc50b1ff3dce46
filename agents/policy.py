"""The one policy interface of every agent (naive, rules, oracles, learned), in SB3's ``predict`` shape.

Every agent implements::

    policy.reset()                                           # forget every env's memory (a new episode)
    action, state = policy.predict(obs, state=None, episode_start=None, deterministic=True)

``obs`` is the env's documented observation (one of shape ``(n_obs,)`` or a batch ``(n_envs, n_obs)``);
``episode_start`` (a bool or an array of them, as SB3 passes it) resets the memory of the matching env;
``state`` is a recurrent policy's hidden state (returned, passed back by the caller), None otherwise.  An
oracle (:class:`PrivilegedPolicy`) is also handed the reset ``info`` of each episode
(:meth:`PrivilegedPolicy.observe_reset_info`): the one privileged channel; every other policy sees only
observations.

Scripted agents (:class:`ScriptedPolicy`) read only the documented observation, the env's documented
configuration (:class:`ControlSpec`: action mapping, motor limit, control interval, nominal task target)
and the nominal map (:class:`~gfb_agents.nominal_map.NominalMap`); never the drawn parameters nor the
simulator state.  The observation and action units have one owner, :mod:`gfb_env.envs.units`
(``env.observation_layout`` and ``env.actions``); the agents decode observations and encode actions only
through it.

The agents themselves: :mod:`gfb_agents.rules` (naive ramp, schedules, the v1 rules),
:mod:`gfb_agents.oracles`, :mod:`gfb_agents.learned`; the benchmark's ladder builds them
(:mod:`gfb_agents.ladder`, the one factory).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_env.envs.units import ActionMap, ObservationLayout

__all__ = ["Policy", "PrivilegedPolicy", "ControlSpec", "TrackerMemory", "ScriptedPolicy"]


class Policy(abc.ABC):
    """The policy interface shared by every agent (module docstring).

    Attributes:
        name: the agent's name (the benchmark table's ``agent`` column; the ladder sets it).
        kind: ``"scripted"`` (naive and rules), ``"oracle"`` or ``"learned"``.
    """

    name: str = "policy"
    kind: str = "scripted"

    def reset(self) -> None:  # noqa: B027 - a policy without memory needs no reset
        """Forget the episode memory of every env (called before each ``env.reset``)."""

    @abc.abstractmethod
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action(s) for ``observation`` (shape ``(n_obs,)`` or ``(n_envs, n_obs)``).

        Returns ``(action, state)`` with ``action`` of shape ``(2,)`` or ``(n_envs, 2)`` in ``[-1, 1]``."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class PrivilegedPolicy(Policy):
    """A policy that is handed each episode's reset ``info`` (the hidden draw): the oracles, and only they.

    The evaluation (:func:`gfb_agents.learned.evaluate.run_episode`) calls ``reset()`` before
    ``env.reset`` and :meth:`observe_reset_info` after it, before the first ``predict``."""

    kind = "oracle"

    @abc.abstractmethod
    def observe_reset_info(self, info: Mapping[str, Any]) -> None:
        """Take the episode's reset ``info`` (what makes this policy an oracle)."""


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

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
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
