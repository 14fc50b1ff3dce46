"""The privileged vector of an episode, for learning methods that use what the simulator knows at training
time only (issue 21): the asymmetric actor-critic's critic and the teacher of the teacher-student scheme.

The vector is built from the env's privileged channel (:mod:`gfb_env.envs.privileged`):
``env.unwrapped.hidden_parameters()`` (every hidden draw of the episode) and, optionally, the true
quantities of ``info["privileged"]`` (the env made with ``privileged_info=True``).  It is never part of what
a deployed policy receives: the deployed actor (:class:`gfb_agents.learned.asymmetric.DeployedActor`) takes
the public observation only.

Entries, in this fixed order (:data:`EPISODE_FIELDS`; a group the task does not draw -- the bearing on a
task with the nominal bearing, the unbalance of a balanced rotor -- gives zeros and its ``*_drawn`` flag 0,
so one layout serves every task id):

=========================  ======================================================================
``ln_damping_gain``        ln g, the damping effectiveness (actual D_W = g x commanded)
``bearing_drawn``          1 where the task draws the bearing, else 0 (and the four below are 0)
``clearance_um``           the drawn radial clearance C, um
``stiffness_factor``       the drawn foil stiffness factor f_K
``load_n``                 the drawn static load per bearing F_L, N
``foil_stiffness``         the resulting nondimensional K_W
``unbalance_drawn``        1 where the rotor has a residual unbalance, else 0
``balance_grade_mm_s``     its ISO 1940 grade G, mm/s
``unbalance_um``           its magnitude U, um
``unbalance_cos_phase``    cos of its phase (the angle as a point on the circle: no jump at 2 pi)
``unbalance_sin_phase``    sin of its phase
``probe_bias_x_um``        the X probe's offset of the episode, um
``probe_bias_y_um``        the Y probe's offset of the episode, um
=========================  ======================================================================

These are drawn at reset and fixed for the episode, so the vector of an ended episode (for the value of
its last observation) is the one cached at its reset.  Left out: the base shocks (drawn step by step; not
known ahead even to the oracle), the sensor noise of each observation (white: nothing to learn), the task's
start draws (they act only through the first observations).

Optional step-varying entries (:data:`STEP_QUANTITIES`, names of ``info["privileged"]``, appended in the
order given; they need ``privileged_info=True``): the true noise-free journal state ``xi``, ``eta``,
``xi_dot``, ``eta_dot`` (units of C, C / T), ``eccentricity``, the judge's ``whirl_amplitude`` and
``min_film_thickness`` (units of C), the actual ``bearing_number`` Lambda and ``foil_damping`` D_W.  An
ended episode's entries are those of its last step's info.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvStepReturn, VecEnvWrapper

__all__ = [
    "EPISODE_FIELDS",
    "STEP_QUANTITIES",
    "OBS_KEY",
    "PRIVILEGED_KEY",
    "PrivilegedVecEnv",
    "episode_vector",
    "privileged_names",
    "check_quantities",
]

EPISODE_FIELDS: tuple[str, ...] = (
    "ln_damping_gain",
    "bearing_drawn",
    "clearance_um",
    "stiffness_factor",
    "load_n",
    "foil_stiffness",
    "unbalance_drawn",
    "balance_grade_mm_s",
    "unbalance_um",
    "unbalance_cos_phase",
    "unbalance_sin_phase",
    "probe_bias_x_um",
    "probe_bias_y_um",
)
STEP_QUANTITIES: tuple[str, ...] = (
    "xi",
    "eta",
    "xi_dot",
    "eta_dot",
    "eccentricity",
    "whirl_amplitude",
    "min_film_thickness",
    "bearing_number",
    "foil_damping",
)
#: the keys of the training observation (a ``gymnasium.spaces.Dict``)
OBS_KEY, PRIVILEGED_KEY = "obs", "privileged"


def check_quantities(quantities: Sequence[str]) -> tuple[str, ...]:
    """``quantities`` as a tuple, each one of :data:`STEP_QUANTITIES` and none twice (ValueError)."""
    q = tuple(quantities)
    bad = [x for x in q if x not in STEP_QUANTITIES]
    if bad:
        raise ValueError(f"privileged quantities {bad} unknown; known: {list(STEP_QUANTITIES)}")
    if len(set(q)) != len(q):
        raise ValueError(f"privileged quantities {list(q)} name one twice")
    return q


def privileged_names(quantities: Sequence[str] = ()) -> tuple[str, ...]:
    """The names of the vector's entries, in order: :data:`EPISODE_FIELDS` then ``quantities``."""
    return EPISODE_FIELDS + check_quantities(quantities)


def episode_vector(hidden: Mapping[str, Any]) -> np.ndarray:
    """The :data:`EPISODE_FIELDS` entries (float32) of one episode's ``hidden_parameters()`` dict."""
    g = float(hidden["damping_gain"])
    if not g > 0:
        raise ValueError(f"damping_gain must be positive, got {g!r}")
    b, u = hidden.get("bearing"), hidden.get("unbalance")
    bias = (hidden.get("sensors") or {}).get("probe_bias_um") or (0.0, 0.0)
    if len(bias) != 2:
        raise ValueError(f"sensors.probe_bias_um must hold the (X, Y) offsets, got {bias!r}")
    v = [math.log(g)]
    v += (
        [0.0] * 5
        if b is None
        else [1.0, b["clearance_um"], b["stiffness_factor"], b["load_n"], b["foil_stiffness"]]
    )
    if u is None:
        v += [0.0] * 5
    else:
        ph = float(u["phase_rad"])
        v += [1.0, u["balance_grade_mm_s"], u["magnitude_um"], math.cos(ph), math.sin(ph)]
    v += [float(bias[0]), float(bias[1])]
    return np.asarray(v, dtype=np.float32)


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
