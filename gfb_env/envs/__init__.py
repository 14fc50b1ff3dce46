"""Gymnasium environments of the gas foil bearing rotor (see ``docs/envs.md``).

Importing this package registers (idempotently):

* ``gfb_env/RunUp-v0`` (:class:`~gfb_env.envs.run_up.RunUpEnv`, ``max_episode_steps=200``)
* ``gfb_env/RunUpRandomized-v0`` (:class:`~gfb_env.envs.run_up_randomized.RunUpRandomizedEnv`, 250)
* ``gfb_env/WhirlRecovery-v0`` (:class:`~gfb_env.envs.whirl_recovery.WhirlRecoveryEnv`, 200)
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.envs.base import DEFAULT_GRID, GFBEnv
from gfb_env.envs.run_up import RunUpEnv
from gfb_env.envs.run_up_randomized import RunUpRandomizedEnv
from gfb_env.envs.whirl_recovery import WhirlRecoveryEnv

__all__ = [
    "GFBEnv",
    "RunUpEnv",
    "RunUpRandomizedEnv",
    "WhirlRecoveryEnv",
    "DEFAULT_GRID",
    "NOMINAL_BEARING",
    "ENV_IDS",
]

#: registered ids -> (entry point, max_episode_steps)
_SPECS = {
    "gfb_env/RunUp-v0": ("gfb_env.envs.run_up:RunUpEnv", 200),
    "gfb_env/RunUpRandomized-v0": ("gfb_env.envs.run_up_randomized:RunUpRandomizedEnv", 250),
    "gfb_env/WhirlRecovery-v0": ("gfb_env.envs.whirl_recovery:WhirlRecoveryEnv", 200),
}
ENV_IDS = tuple(_SPECS)


def register_envs() -> None:
    """Register the tasks with Gymnasium (no-op for ids already registered)."""
    for env_id, (entry_point, steps) in _SPECS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=steps)


register_envs()
