"""The Stable-Baselines3 adapter of the native vector env (issue 13): bit for bit SB3's DummyVecEnv over
the same id and seeds (autoresets, terminal observations, time-limit flags), VecNormalize over it, and a
tiny PPO run through ``gfb_agents.learned.train`` with ``vec_env="native"``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import same_value
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize
from test_agents import _tiny_yaml

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.learned.train import TrainConfig, make_vec_env_for, train
from gfb_agents.learned.vec_env import GFBSB3VecEnv

FAST = {"control_interval": 20.0}


def _kw(env_id: str) -> dict:
    dist = {"shock_arrivals": {"rate_per_s": 20.0, "peak_g_range": (1.0, 5.0)}}
    return {**FAST, **dist, "max_episode_steps": 3}


@pytest.mark.parametrize("env_id", ["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2"])
def test_adapter_is_dummy_vec_env_bit_for_bit(env_id):
    n, kw = 3, _kw(env_id)
    native = make_vec_env_for(env_id, n, seed=5, env_kwargs=kw, vec_env="native")
    dummy = make_vec_env(env_id, n_envs=n, seed=5, env_kwargs=kw, vec_env_cls=DummyVecEnv)
    assert isinstance(native, VecMonitor) and isinstance(native.venv, GFBSB3VecEnv)
    assert np.array_equal(native.reset(), dummy.reset())
    assert all(same_value(p, q) for p, q in zip(native.venv.reset_infos, dummy.reset_infos, strict=True))
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(7):  # two autoresets by the time limit per env
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        o1, r1, d1, i1 = native.step(a)
        o2, r2, d2, i2 = dummy.step(a)
        for x, y in ((o1, o2), (r1, r2), (d1, d2)):
            assert x.dtype == y.dtype and np.array_equal(x, y)
        for p, q in zip(i1, i2, strict=True):
            # "episode": Monitor's and VecMonitor's statistics (present in the same steps)
            assert ("episode" in p) == ("episode" in q)
            p, q = (
                {k: v for k, v in p.items() if k != "episode"},
                {k: v for k, v in q.items() if k != "episode"},
            )
            assert p.keys() == q.keys()
            bad = [k for k in p if not same_value(p[k], q[k])]
            assert not bad, bad
        ended += int(d1.sum())
        if d1.any():
            assert all(i1[j]["TimeLimit.truncated"] for j in np.flatnonzero(d1))
    assert ended == 2 * n


def test_vec_normalize_over_the_native_env_matches_dummy():
    env_id, n = "gfb_env/WhirlRecovery-v2", 2
    native = VecNormalize(make_vec_env_for(env_id, n, seed=1, env_kwargs=_kw(env_id), vec_env="native"))
    dummy = VecNormalize(make_vec_env(env_id, n_envs=n, seed=1, env_kwargs=_kw(env_id)))
    assert np.array_equal(native.reset(), dummy.reset())
    rng = np.random.default_rng(3)
    for _ in range(5):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        o1, r1, d1, _ = native.step(a)
        o2, r2, d2, _ = dummy.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
    assert np.array_equal(native.obs_rms.mean, dummy.obs_rms.mean)
    assert np.abs(o1).max() <= native.clip_obs and not np.array_equal(o1, native.get_original_obs())


def test_train_with_the_native_vector_env(tmp_path):
    env_id = "gfb_env/RunUp-v2"
    cfg = TrainConfig(
        "ppo",
        env_id,
        timesteps=256,
        seed=1,
        n_envs=2,
        out=tmp_path / "run",
        hyperparams=_tiny_yaml(tmp_path, "ppo", env_id),
        eval_freq=10_000,
        eval_episodes=1,
        checkpoint_freq=10_000,
        progress_bar=False,
        tensorboard=False,
        vec_env="native",
        env_kwargs={**FAST, "max_episode_steps": 8},
    )
    out = train(cfg)
    meta = json.loads((out / "run.json").read_text())
    assert meta["timesteps"] >= 256 and meta["config"]["vec_env"] == "native"
    assert (out / "model.zip").exists() and (out / "vecnormalize.pkl").exists()
    # VecMonitor's log (the learning curve reads it): every episode of the run, each of 8 steps
    lines = (out / "monitor" / "native.monitor.csv").read_text().splitlines()
    rows = [r.split(",") for r in lines[2:]]
    assert len(rows) == meta["timesteps"] // 8 and all(int(r[1]) == 8 for r in rows)
    with pytest.raises(ValueError, match="vec_env"):
        TrainConfig("ppo", env_id, vec_env="threads")


def test_adapter_refuses_a_batch_that_is_not_n_by_2():
    """Defect 11 (issue 18): a (2N,), (2, N) or (1, 2N) batch was reshaped to (N, 2), mixing the envs'
    actions (a transposed batch gave env 0 the speed actions of envs 0 and 1)."""
    n = 3
    adapter = GFBSB3VecEnv(gfb_env.envs.GFBVectorEnv(n, env_class=gfb_env.envs.RunUpEnv, **FAST))
    adapter.reset()
    for bad in (np.zeros(2 * n), np.zeros((2, n)), np.zeros((1, 2 * n)), np.zeros((n, 2, 1))):
        adapter.step_async(bad)
        with pytest.raises(ValueError, match=rf"actions must have shape \({n}, 2\)"):
            adapter.step_wait()
    adapter.step_async(np.zeros((n, 2), np.float32))
    obs, rewards, dones, infos = adapter.step_wait()
    assert obs.shape == (n, adapter.observation_space.shape[0]) and [i["step"] for i in infos] == [1] * n
