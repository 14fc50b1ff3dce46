"""The retired task ids: they stay registered only to refuse, with one error that says why and which id to use
(``gymnasium.make`` and ``gymnasium.make_vec``, every vectorization mode).  The id to use is the v2 id of the
same task (``gfb_env/RunUp-v2``, ``gfb_env/RunUpRandomized-v2``, ``gfb_env/WhirlRecovery-v2``).

* **v0** (``gfb_env/RunUp-v0``, ``gfb_env/RunUpRandomized-v0``, ``gfb_env/WhirlRecovery-v0``; issue 18): the
  plant is exactly identifiable from its first observation (the nominal or drawn bearing, ideal sensors, no
  hidden damping effectiveness: inverting one snapshot with the simulator gives the optimum before the first
  action), so v0 measured identification, not control skill.  Its code is gone (git keeps it: the last commit
  with v0 is the parent of the one that added this module).
* **v1** (``gfb_env/RunUp-v1``, ``gfb_env/RunUpRandomized-v1``, ``gfb_env/WhirlRecovery-v1``; issue 19): an
  outside audit found that what every Gymnasium user receives hands the hidden plant to any policy: ``info``
  carries the damping gain g, the drawn bearing, the true state and the judge's true quantities, and the
  reward is a noise-free whirl sensor (the true whirl amplitude comes back from it to 1e-8);
  WhirlRecovery-v1's reset observation tells g besides.  A policy reading observation, reward and info
  scores the oracle, so the v1 table did not measure control skill.  The v2 ids are the same task classes,
  machine and horizons with the information contract (:mod:`gfb_env.envs.interface_v2`,
  :mod:`gfb_env.envs.contract`, ``docs/envs.md``).

The v1 code stays (v2 is v1's task classes plus :class:`~gfb_env.envs.interface_v2.MonitorInterface`), so a
v1 env can still be built **for the record** -- to replay the committed v1 policies and tables and the
regression baselines -- with :func:`make_retired` / :func:`make_retired_vec`.  They leak ground truth and are
not a benchmark.  ``CHANGELOG.md`` has the history.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NoReturn

import gymnasium as gym
from gymnasium import error
from gymnasium.envs.registration import EnvSpec

__all__ = [
    "RetiredTaskError",
    "RETIRED_IDS",
    "RETIRED_V1_IDS",
    "RetiredEntryPoint",
    "make_retired",
    "make_retired_vec",
    "make_env",
]

#: retired id -> the id to use instead (the v2 id of the same task)
RETIRED_IDS: dict[str, str] = {
    "gfb_env/RunUp-v0": "gfb_env/RunUp-v2",
    "gfb_env/RunUpRandomized-v0": "gfb_env/RunUpRandomized-v2",
    "gfb_env/WhirlRecovery-v0": "gfb_env/WhirlRecovery-v2",
    "gfb_env/RunUp-v1": "gfb_env/RunUp-v2",
    "gfb_env/RunUpRandomized-v1": "gfb_env/RunUpRandomized-v2",
    "gfb_env/WhirlRecovery-v1": "gfb_env/WhirlRecovery-v2",
}

#: the retired v1 ids, in task order (buildable for the record with :func:`make_retired`)
RETIRED_V1_IDS: tuple[str, ...] = tuple(i for i in RETIRED_IDS if i.endswith("-v1"))

_WHY_V0 = (
    "(issue 18): its plant is exactly identifiable from the first observation, so it measures "
    "identification, not control skill (CHANGELOG.md)"
)
_WHY_V1 = (
    "(issue 19): an outside audit found that its info and reward hand the hidden plant to any policy "
    "(info carries the damping gain g, the drawn bearing and the true state; the reward is a noise-free "
    "whirl sensor){extra}, so a policy that reads what Gymnasium returns scores the oracle and its table "
    "does not measure control skill (CHANGELOG.md)"
)
_USE = (
    "Use {new}: the same task with the information contract (everything an agent receives is computed from "
    "the sensors; ground truth only through the opt-in privileged channel; docs/envs.md)."
)


class RetiredTaskError(error.Error, ValueError):
    """A retired task id was made (a :class:`gymnasium.error.Error`, and a ``ValueError`` like every
    refused argument of the envs: catch either)."""


def retired_message(env_id: str) -> str:
    """The one error line of the retired ``env_id``: why it is retired and which id to use."""
    new = RETIRED_IDS[env_id]
    if env_id.endswith("-v0"):
        why = _WHY_V0
    else:
        extra = ", and its reset observation tells g" if "WhirlRecovery" in env_id else ""
        why = _WHY_V1.format(extra=extra)
    return f"{env_id} is retired {why}. {_USE.format(new=new)}"


class RetiredEntryPoint:
    """The entry point (and vector entry point) of a retired id: raises :class:`RetiredTaskError`."""

    def __init__(self, env_id: str) -> None:
        if env_id not in RETIRED_IDS:
            raise ValueError(f"env_id: not a retired id: {env_id!r} (retired: {', '.join(RETIRED_IDS)})")
        self.env_id = env_id

    def __call__(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise RetiredTaskError(retired_message(self.env_id))

    def __repr__(self) -> str:
        return f"RetiredEntryPoint({self.env_id!r})"


def _v1_spec(env_id: str) -> EnvSpec:
    """The EnvSpec ``gymnasium.register`` made for the v1 id before its retirement (same entry points,
    horizon and keyword arguments), not in the registry."""
    # imported here: gfb_env.envs imports this module to register the refusals
    from gfb_env.envs import _V1_SPECS, _VECTOR_ENTRY_POINTS

    if env_id not in _V1_SPECS:
        raise ValueError(
            f"env_id: {env_id!r} is not a retired v1 id; make_retired builds only "
            f"{', '.join(RETIRED_V1_IDS)} (the v0 code is gone; a current id is made with gymnasium.make)"
        )
    entry_point, steps, kwargs = _V1_SPECS[env_id]
    return EnvSpec(
        id=env_id,
        entry_point=entry_point,
        vector_entry_point=_VECTOR_ENTRY_POINTS[entry_point],
        max_episode_steps=steps,
        kwargs=dict(kwargs),
    )


def make_retired(env_id: str, **kwargs: Any) -> gym.Env:
    """The retired v1 task ``env_id`` (``gfb_env/RunUp-v1``, ``gfb_env/RunUpRandomized-v1``,
    ``gfb_env/WhirlRecovery-v1``), the very env ``gymnasium.make(env_id, **kwargs)`` returned before the
    retirement (bit for bit: the same spec, wrappers, defaults and ``env.spec.id``).

    **For the record only; not a benchmark.**  Its ``info`` and reward leak the ground truth (the hidden
    damping gain, the drawn bearing, the true state; module docstring), so a score on it says nothing about
    control skill.  It exists to replay the committed v1 policies and tables (``agents/policies``,
    ``results/benchmark_v1``) and the regression baselines.  New work uses the v2 id (:data:`RETIRED_IDS`).
    ValueError for any other id."""
    return gym.make(_v1_spec(env_id), **kwargs)


def make_retired_vec(
    env_id: str,
    num_envs: int = 1,
    vectorization_mode: str | None = None,
    vector_kwargs: dict[str, Any] | None = None,
    wrappers: Sequence[Callable[[gym.Env], gym.Wrapper]] | None = None,
    **kwargs: Any,
) -> gym.vector.VectorEnv:
    """:func:`make_retired`'s vector counterpart: what ``gymnasium.make_vec(env_id, num_envs, ...)`` returned
    for the v1 id before the retirement (the native vector env by default, or ``"sync"`` / ``"async"``).
    For the record only; not a benchmark (it leaks the ground truth as :func:`make_retired` does)."""
    return gym.make_vec(
        _v1_spec(env_id),
        num_envs=num_envs,
        vectorization_mode=vectorization_mode,
        vector_kwargs=vector_kwargs,
        wrappers=wrappers,
        **kwargs,
    )


def make_env(env_id: str, **kwargs: Any) -> gym.Env:
    """``gymnasium.make(env_id, **kwargs)``, or :func:`make_retired` for a retired v1 id: for the tools that
    replay records as well as play the current tasks (the benchmark runner, the evaluation of the committed
    policies, the regression digests).  A v1 env so built is a record, not a benchmark."""
    return make_retired(env_id, **kwargs) if env_id in RETIRED_V1_IDS else gym.make(env_id, **kwargs)
