"""The native vector env over worker processes (``num_processes``, :mod:`gfb_env.envs.shards`).

Bit for bit between 2 and 3 worker processes and this process (1).  Workers always load numba's
on-disk cache, while this test process may have compiled the kernels itself (a clean clone's first run):
that the two give the same bits is the point of ``tests/install/test_cache_determinism.py``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs.shards import RemoteEnv
from gfb_env.envs.vector import GFBVectorEnv, RunUpVectorEnv

ID = "gfb_env/RunUp-v2"


def _play(env: GFBVectorEnv, steps: int) -> tuple[list[np.ndarray], list[dict]]:
    obs, info = env.reset(seed=41)
    rng = np.random.default_rng(5)
    arrays, infos = [obs], [info]
    for _ in range(steps):
        a = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
        o, r, te, tr, inf = env.step(a)
        arrays += [o, r, te, tr]
        infos.append(inf)
    return arrays, infos


def _same(x, y) -> bool:
    if isinstance(x, dict):
        return list(x) == list(y) and all(_same(x[k], y[k]) for k in x)
    if isinstance(x, np.ndarray):
        if x.dtype == object:
            return x.shape == y.shape and all(_same(u, v) for u, v in zip(x, y, strict=True))
        return x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True)
    return x == y or (x != x and y != y)


def test_results_do_not_depend_on_the_number_of_processes():
    """3 envs over 2 and over 3 processes, episodes of 6 steps (autoresets inside): every
    observation, reward, flag and info entry bit for bit, and the same as the envs in this process."""
    runs = {}
    for p in (1, 2, 3):
        env = gym.make_vec(ID, num_envs=3, vectorization_mode="vector_entry_point", num_processes=p,
                           max_episode_steps=6)  # fmt: skip
        assert env.num_processes == p
        # shard 0 (the first ceil(3 / p) envs) lives here, the others in workers
        assert [isinstance(e, RemoteEnv) for e in env.envs] == [i >= -(-3 // p) for i in range(3)]
        runs[p] = _play(env, 14)
        env.close()
    (a2, i2), (a3, i3) = runs[2], runs[3]
    assert len(a2) == len(a3)
    assert all(_same(x, y) for x, y in zip(a2, a3, strict=True))
    assert all(_same(x, y) for x, y in zip(i2, i3, strict=True))
    # autoresets happened (steps 7 and 14 return reset observations) and the runs are not trivial
    assert not np.array_equal(a2[1], a2[5])
    a1, i1 = runs[1]
    assert all(_same(x, y) for x, y in zip(a1, a2, strict=True))
    assert all(_same(x, y) for x, y in zip(i1, i2, strict=True))


def test_remote_envs_read_call_set_and_snapshot():
    env = gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", num_processes=2)
    try:
        env.reset(seed=3)
        hidden = env.unwrapped.call("hidden_parameters")
        assert len(hidden) == 2 and hidden[0]["damping_gain"] != hidden[1]["damping_gain"]
        assert env.unwrapped.np_random_seed == (3, 4)
        env.unwrapped.set_attr("marker_attribute", [7, 8])
        assert env.unwrapped.get_attr("marker_attribute") == (7, 8)
        a = np.zeros((2, 2), np.float32)
        env.step(a)
        state = env.unwrapped.get_state()
        after = [env.step(a)[0] for _ in range(3)]
        env.unwrapped.set_state(state)
        again = [env.step(a)[0] for _ in range(3)]
        assert all(np.array_equal(x, y) for x, y in zip(after, again, strict=True))
    finally:
        env.close()
    assert all(s.process.poll() is not None for s in env.unwrapped._shards)  # the workers ended


@pytest.mark.parametrize("bad", [0, 4, 1.5, True, "2"])
def test_bad_num_processes_is_refused_before_any_process_starts(bad):
    with pytest.raises(ValueError, match="num_processes"):
        RunUpVectorEnv(3, num_processes=bad)


def test_bad_env_arguments_are_refused_in_this_process():
    with pytest.raises((ValueError, TypeError), match="no_such_argument"):
        gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", num_processes=2,
                     no_such_argument=1)  # fmt: skip
