"""Stable-Baselines3 ``VecEnv`` over the native vector env (:class:`gfb_env.envs.vector.GFBVectorEnv`).

SB3 has its own vector API: ``reset()`` returns only the observations (seeds set by ``seed()`` are used
once, env ``i`` gets ``seed + i``), ``step_wait()`` returns ``(obs, rewards, dones, infos)`` with one info
dict per env, and an env that ended is reset in the same step: its last observation is
``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` says whether the time limit
(not the task) ended it.  :class:`GFBSB3VecEnv` gives exactly what SB3's ``DummyVecEnv`` over
``gymnasium.make(id)`` copies gives (the same bits; the per-env ``Monitor`` is replaced by one
``VecMonitor``, see :func:`gfb_agents.learned.train.make_vec_env_for`), but steps the batch through the native
vector env's stages.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
    VecEnvWrapper,
)

from gfb_agents.learned.privileged import (
    EPISODE_FIELDS,
    OBS_KEY,
    PRIVILEGED_KEY,
    check_quantities,
    episode_vector,
    privileged_names,
)
from gfb_agents.learned.slew import DampingSlew
from gfb_env.envs.vector import GFBVectorEnv

__all__ = ["GFBSB3VecEnv", "PrivilegedVecEnv", "DampingSlewVecEnv"]


class GFBSB3VecEnv(VecEnv):
    """SB3's ``VecEnv`` API over a :class:`~gfb_env.envs.vector.GFBVectorEnv` (its autoreset mode is
    not used: this adapter resets ended envs itself, as SB3 expects)."""

    def __init__(self, venv: GFBVectorEnv):
        if not isinstance(venv, GFBVectorEnv):
            raise ValueError(f"venv must be a GFBVectorEnv, got {type(venv).__name__}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.render_mode = venv.render_mode
        self._actions: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        v = self.venv
        for i in range(self.num_envs):
            options = self._options[i] or None
            self.reset_infos[i] = v._reset_env(i, self._seeds[i], options)
        v._needs_reset = False
        self._reset_seeds()
        self._reset_options()
        return v._observations.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        v, n = self.venv, self.num_envs
        if v._needs_reset:
            raise RuntimeError("call reset() before step()")
        a = v.check_actions(self._actions)  # (N, 2) exactly: a reshaped batch would mix the envs' actions
        infos = v._step_envs(a, np.arange(n))
        rewards = v._rewards.astype(np.float32)  # DummyVecEnv's reward buffer is float32
        dones = v._terminations | v._truncations
        for i in range(n):
            infos[i]["TimeLimit.truncated"] = bool(v._truncations[i] and not v._terminations[i])
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = v._observations[i].copy()
            self.reset_infos[i] = v._reset_env(i)
        return v._observations.copy(), rewards, dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return list(self.venv.render())

    def _envs(self, indices: VecEnvIndices) -> list:
        return [self.venv.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(env, attr_name) for env in self._envs(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for env in self._envs(indices):
            setattr(env, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        return [getattr(env, method_name)(*method_args, **method_kwargs) for env in self._envs(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        # the envs are plain task envs (the time limit lives in the vector env)
        return [False for _ in self._envs(indices)]


def _base(venv: VecEnv) -> VecEnv:
    while isinstance(venv, VecEnvWrapper):
        venv = venv.venv
    return venv


class PrivilegedVecEnv(VecEnvWrapper):
    """A ``VecEnv`` wrapper whose observation is ``{"obs": the env's observation, "privileged": the
    episode's privileged vector}`` (module docstring), for training only.

    Wraps an SB3 ``VecEnv`` of the task (the native vector env's adapter or ``DummyVecEnv``; below any
    ``VecNormalize`` / ``VecFrameStack``).  ``terminal_observation`` of an ended env is a dict too, with the
    ended episode's vector.  ``quantities``: the step-varying entries (:data:`STEP_QUANTITIES`) to append;
    they need the envs made with ``privileged_info=True`` (checked at the first reset, one line)."""

    def __init__(self, venv: VecEnv, quantities: Sequence[str] = ()):
        self.quantities = check_quantities(quantities)
        self.names = privileged_names(self.quantities)
        if not isinstance(venv.observation_space, spaces.Box):
            raise ValueError(f"PrivilegedVecEnv wraps a Box observation, got {venv.observation_space}")
        obs_space = spaces.Dict(
            {
                OBS_KEY: venv.observation_space,
                PRIVILEGED_KEY: spaces.Box(-np.inf, np.inf, (len(self.names),), np.float32),
            }
        )
        super().__init__(venv, observation_space=obs_space)
        self._vec = np.zeros((self.num_envs, len(self.names)), dtype=np.float32)

    def _quantities(self, info: Mapping[str, Any]) -> list[float]:
        if not self.quantities:
            return []
        priv = info.get("privileged")
        if priv is None:
            raise ValueError(
                f"privileged quantities {list(self.quantities)} need the env made with privileged_info=True"
            )
        return [float(priv[q]) for q in self.quantities]

    def _episode(self, i: int) -> np.ndarray:
        (hidden,) = self.venv.env_method("hidden_parameters", indices=[i])
        return episode_vector(hidden)

    def _fill(self, i: int, reset_info: Mapping[str, Any]) -> None:
        e = self._episode(i)
        self._vec[i, : e.size] = e
        self._vec[i, e.size :] = self._quantities(reset_info)

    def _dict(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return {OBS_KEY: obs, PRIVILEGED_KEY: self._vec.copy()}

    def reset(self) -> dict[str, np.ndarray]:
        obs = self.venv.reset()
        infos = _base(self.venv).reset_infos
        for i in range(self.num_envs):
            self._fill(i, infos[i])
        return self._dict(obs)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        n_ep = len(EPISODE_FIELDS)
        reset_infos = _base(self.venv).reset_infos
        for i in range(self.num_envs):
            # the step's own quantities: for an ended env those of its last step (its info's)
            self._vec[i, n_ep:] = self._quantities(infos[i])
            if dones[i]:
                infos[i]["terminal_observation"] = {
                    OBS_KEY: infos[i]["terminal_observation"],
                    PRIVILEGED_KEY: self._vec[i].copy(),
                }
                self._fill(i, reset_infos[i])  # the new episode's draws, its reset info
        return self._dict(obs), rewards, dones, infos


class DampingSlewVecEnv(VecEnvWrapper):
    """A ``VecEnv`` wrapper that slew-limits the damping command (:mod:`gfb_agents.learned.slew`): the
    policy's damping action is a set-point, the env gets ``a_d(k-1) + clip(u - a_d(k-1), -rate, rate)``
    (the speed action unchanged), ``a_d(-1)`` being each episode's reset observation's damping.

    Wraps the task's SB3 ``VecEnv`` directly (its raw observations, below :class:`PrivilegedVecEnv`,
    ``VecNormalize`` and ``VecFrameStack``); an env that ended starts its new episode from the reset
    observation SB3 returns in its place.  ``reserve``: the unused allowance a step may save for a later
    one (:class:`~gfb_agents.learned.slew.DampingSlew`).  ``commands``: the last batch sent to the env."""

    def __init__(self, venv: VecEnv, rate: float, reserve: float | None = None):
        if not isinstance(venv.observation_space, spaces.Box):
            raise ValueError(f"DampingSlewVecEnv wraps the raw Box observation, got {venv.observation_space}")
        super().__init__(venv)
        self.slew = DampingSlew(rate, reserve)
        self.commands: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self.slew.start(obs)
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self.commands = self.slew(actions)
        self.venv.step_async(self.commands)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        if np.any(dones):
            self.slew.start(obs, np.asarray(dones, dtype=bool))
        return obs, rewards, dones, infos
