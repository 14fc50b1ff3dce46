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

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from gfb_env.envs.vector import GFBVectorEnv

__all__ = ["GFBSB3VecEnv"]


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
