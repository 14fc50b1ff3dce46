"""The retired ids (v0: issue 18; v1: issue 19) refuse with one clear error naming the v2 id, in
gym.make and gym.make_vec (every vectorization mode); the current tasks are the v2 ids; the record maker
``make_retired`` builds the v1 env gym.make gave, bit for bit (the full v1 trajectories, rewards and infos are
pinned through it by tests/integrator/test_integrator_digests.py's ``envs_v1`` case)."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import gymnasium.error
import numpy as np
import pytest

from gfb_env.envs import (
    _V1_SPECS,
    ENV_IDS,
    RETIRED_IDS,
    RETIRED_V1_IDS,
    V1_TASK,
    V2_ENV_IDS,
    RetiredTaskError,
    make_env,
    make_retired,
    make_retired_vec,
)

GOLDEN = Path(__file__).parents[1] / "integrator" / "data" / "integrator_golden.json"


def test_the_current_tasks_are_the_v2_ids_and_every_older_id_is_retired():
    assert ENV_IDS == V2_ENV_IDS and all(i.endswith("-v2") for i in ENV_IDS) and len(ENV_IDS) == 3
    assert RETIRED_V1_IDS == tuple(_V1_SPECS) == tuple(i.replace("-v2", "-v1") for i in ENV_IDS)
    assert set(RETIRED_IDS) == {i.replace("-v2", v) for i in ENV_IDS for v in ("-v0", "-v1")}
    for old, new in RETIRED_IDS.items():
        assert new in ENV_IDS and new.split("-v")[0] == old.split("-v")[0]


def _makers(env_id: str) -> list:
    return [
        lambda: gym.make(env_id),
        lambda: gym.make(env_id, control_interval=20.0),
        lambda: gym.make_vec(env_id, num_envs=2),
        lambda: gym.make_vec(env_id, num_envs=2, vectorization_mode="sync"),
        lambda: gym.make_vec(env_id, num_envs=2, vectorization_mode="async"),
        lambda: gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point"),
    ]


@pytest.mark.parametrize("env_id", sorted(RETIRED_IDS))
def test_a_retired_id_raises_one_clear_error_naming_its_v2_id(env_id):
    new = RETIRED_IDS[env_id]
    for make in _makers(env_id):
        with pytest.raises(RetiredTaskError) as err:
            make()
        msg = str(err.value)
        assert isinstance(err.value, gymnasium.error.Error) and isinstance(err.value, ValueError)
        assert msg.startswith(f"{env_id} is retired") and f"Use {new}:" in msg and "-v2" in new
        assert "CHANGELOG.md" in msg and "docs/envs.md" in msg and "information contract" in msg
        if env_id.endswith("-v0"):
            assert "issue 18" in msg and "identifiable" in msg
        else:  # why: the audit of issue 19
            assert "issue 19" in msg and "info and reward hand the hidden plant" in msg
            assert ("reset observation tells g" in msg) == ("WhirlRecovery" in env_id)


def test_make_retired_refuses_what_is_not_a_retired_v1_id():
    for bad in ("gfb_env/RunUp-v0", "gfb_env/RunUp-v2", "CartPole-v1"):
        with pytest.raises(ValueError, match="not a retired v1 id"):
            make_retired(bad)
        with pytest.raises(ValueError, match="not a retired v1 id"):
            make_retired_vec(bad, num_envs=2)


@pytest.mark.parametrize("env_id", RETIRED_V1_IDS)
def test_make_retired_is_the_env_gym_make_gave(env_id):
    """The spec gymnasium.register made before the retirement (entry points, horizon, the v1 kwargs, the
    wrappers, the id the oracle's margin reads), and the reset observation the v1 golden values recorded
    before issue 18 (tests/integrator/data/integrator_golden.json, seed 3)."""
    env = make_retired(env_id)
    assert env.spec.id == env_id and env.spec.max_episode_steps == (200 if "Whirl" in env_id else 250)
    assert env.spec.entry_point == _V1_SPECS[env_id][0] and "interface" not in env.spec.kwargs
    assert env.spec.kwargs.keys() == V1_TASK.keys() and env.spec.order_enforce
    assert env.spec.disable_env_checker is False
    assert type(env).__name__ == "TimeLimit" and env.unwrapped.interface is None
    obs, info = env.reset(seed=3)
    assert "damping_gain" in info  # the v1 info: ground truth, which is why it is retired
    golden = json.loads(GOLDEN.read_text())["envs_v1"][f"{env_id}.observation.0"]
    assert obs.size == golden["size"]
    got = np.asarray(obs, dtype=float)[golden["index"]]
    np.testing.assert_allclose(got, golden["values"], rtol=0, atol=golden["rel"] * golden["scale"])
    env.close()


def test_make_retired_vec_is_the_native_vector_env_of_the_v1_task():
    env_id = RETIRED_V1_IDS[0]
    single = make_retired(env_id)
    o1, _ = single.reset(seed=5)
    for mode in (None, "sync"):
        venv = make_retired_vec(env_id, num_envs=2, vectorization_mode=mode)
        assert venv.spec.id == env_id and venv.num_envs == 2
        obs, info = venv.reset(seed=5)
        np.testing.assert_array_equal(obs[0], o1)  # env 0 of reset(seed=5) is the single env's seed 5
        assert "damping_gain" in info
        venv.close()
    assert type(make_retired_vec(env_id, num_envs=2)).__name__ == "RunUpVectorEnv"


def test_make_env_plays_a_current_id_and_replays_a_retired_v1_id():
    """The tools that replay records (benchmark runner, evaluation, digests) take either; a v0 id still
    refuses, since its code is gone."""
    current = make_env(ENV_IDS[0])
    assert current.spec.id == ENV_IDS[0] and current.unwrapped.interface is not None
    record = make_env(RETIRED_V1_IDS[0], max_episode_steps=3)
    assert record.spec.id == RETIRED_V1_IDS[0] and record.unwrapped.interface is None
    assert record.spec.max_episode_steps == 3
    with pytest.raises(RetiredTaskError, match="Use gfb_env/RunUp-v2"):
        make_env("gfb_env/RunUp-v0")
