"""Tests of the Gymnasium environments (issue 4): API conformance, vector envs, seeding, robustness
to extreme actions, snapshots and rendering.  Short episodes via constructor keyword arguments."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs import ENV_IDS, RunUpEnv, WhirlRecoveryEnv
from gfb_env.envs.base import _whirl_amplitude

# short control steps keep the tests fast; the physics is the default one
FAST = {"control_interval": 20.0}


def _make(env_id: str, **kwargs) -> gym.Env:
    return gym.make(env_id, max_episode_steps=kwargs.pop("max_episode_steps", 6), **{**FAST, **kwargs})


def _disturbed(env_id: str) -> dict:
    """The random disturbances of the tasks, frequent for the tests: physical base shocks."""
    return {"shock_arrivals": {"rate_per_s": 20.0, "peak_g_range": (1.0, 5.0)}}


def _rollout(env: gym.Env, actions, seed: int | None):
    obs, info = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append(np.r_[obs, r, term, trunc])
        if term or trunc:
            break
    return np.concatenate(out)


# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env(env_id):
    from gymnasium.utils.env_checker import check_env

    env = _make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_check_env(env_id):
    from stable_baselines3.common.env_checker import check_env

    env = _make(env_id)
    check_env(env, warn=True)
    env.close()


def test_registration_is_idempotent():
    from gfb_env.envs import register_envs

    register_envs()
    register_envs()
    for env_id in ENV_IDS:
        assert gym.spec(env_id).max_episode_steps in (200, 250)


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode):
    envs = gym.make_vec("gfb_env/RunUp-v2", num_envs=2, vectorization_mode=mode, **FAST)
    obs, _ = envs.reset(seed=3)
    assert obs.shape == (2, *envs.single_observation_space.shape)
    for _ in range(3):
        obs, r, term, trunc, info = envs.step(envs.action_space.sample())
        assert np.all(np.isfinite(obs)) and r.shape == (2,)
    envs.close()


def test_sb3_subproc_vec_env():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # "module:id" makes each (forkserver) worker import gfb_env.envs, which registers the ids
    venv = make_vec_env(
        "gfb_env.envs:gfb_env/WhirlRecovery-v2", n_envs=2, seed=1, vec_env_cls=SubprocVecEnv, env_kwargs=FAST
    )
    obs = venv.reset()
    for _ in range(3):
        obs, r, done, info = venv.step(np.array([venv.action_space.sample() for _ in range(2)]))
        assert np.all(np.isfinite(obs))
    venv.close()


# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_seeded_determinism(env_id):
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(5, 2)).astype(np.float32)
    kw = {**_disturbed(env_id), "observation_noise": 0.01}
    a = _rollout(_make(env_id, **kw), actions, seed=11)
    b = _rollout(_make(env_id, **kw), actions, seed=11)
    assert np.array_equal(a, b)
    # seeded reset followed by an unseeded reset is reproducible too
    e1, e2 = _make(env_id, **kw), _make(env_id, **kw)
    _rollout(e1, actions[:2], seed=5)
    _rollout(e2, actions[:2], seed=5)
    assert np.array_equal(_rollout(e1, actions, seed=None), _rollout(e2, actions, seed=None))
    # another seed gives another episode
    c = _rollout(_make(env_id, **kw), actions, seed=12)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_snapshot_restore_is_exact(env_id):
    env = _make(env_id, **_disturbed(env_id), observation_noise=0.01, privileged_info=True).unwrapped
    env.reset(seed=2)
    env.step(np.array([1.0, 0.3], dtype=np.float32))
    snap = env.get_state()
    actions = [np.array([0.5, -0.2], dtype=np.float32), np.array([-1.0, 1.0], dtype=np.float32)]
    first = [env.step(a) for a in actions]
    env.reset(seed=99)  # wander off, then restore
    env.step(np.array([-1.0, -1.0], dtype=np.float32))
    env.set_state(snap)
    second = [env.step(a) for a in actions]
    for (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) in zip(first, second, strict=True):
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2 and u1 == u2
        # every info entry, the true state under info["privileged"] included
        assert repr(sorted(i1.items())) == repr(sorted(i2.items()))
        assert i1["privileged"]["tau"] == i2["privileged"]["tau"] and "xi_um" in i1["privileged"]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_render_rgb_array(env_id):
    env = _make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8 and img.shape[0] > 100
    env.close()


# ------------------------------------------------------------------------------------------------
_extreme = st.sampled_from([np.nan, np.inf, -np.inf, 1e30, -1e30, 1.0, -1.0, 0.0, 5.0])
_action = st.tuples(st.one_of(st.floats(-1, 1), _extreme), st.one_of(st.floats(-1, 1), _extreme))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    env_index=st.integers(0, len(ENV_IDS) - 1),
    actions=st.lists(_action, min_size=1, max_size=6),
    seed=st.integers(0, 2**16),
)
def test_random_and_extreme_actions(env_index, actions, seed):
    env = _make(ENV_IDS[env_index], max_episode_steps=len(actions))
    obs, info = env.reset(seed=seed)
    assert env.observation_space.contains(obs)
    ended = False
    for a in actions:
        act = np.array(a, dtype=np.float32)
        obs, r, term, trunc, info = env.step(act)
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        assert math.isfinite(r)
        if not np.all(np.isfinite(act)) or np.any(np.abs(act) > 1):
            assert info["action_sanitised"]
        if term:
            assert info["termination_reason"] in ("success", "touchdown", "solver_failure", "horizon")
        if term or trunc:
            ended = True
            break
    assert ended  # the TimeLimit ends it at the latest
    env.close()


def test_full_speed_with_bad_damping_whirls_or_touches_down():
    """Running above Lambda_c(D_min) with the least damping must not count as a success."""
    env = RunUpEnv(control_interval=60.0, disturbance_probability=1.0, episode_steps=120)
    env.reset(seed=0)
    reasons, amps = [], []
    for _ in range(120):
        obs, r, term, trunc, info = env.step(np.array([1.0, -1.0], dtype=np.float32))
        amps.append(info["whirl_amplitude"])
        if term:
            reasons.append(info["termination_reason"])
            break
    assert reasons != ["success"]
    assert max(amps) > env.stable_amplitude


@pytest.mark.slow
def test_scripted_run_up_succeeds():
    """The simple expert (ramp to the command with the nominal map's optimum damping) succeeds on the
    ideal machine (g = 1) when the command lies below the best stable speed."""
    env = RunUpEnv()
    seed = next(
        s for s in range(20) if (env.reset(seed=s), env.speed_command)[1].bearing_number < 0.97 * 0.7014
    )
    env.reset(seed=seed)
    info = {}
    for _ in range(250):
        _, _, term, trunc, info = env.step(env.scripted_action())
        if term or trunc:
            break
    assert info["termination_reason"] == "success" and info["certified"]


def test_invalid_arguments_raise_value_error_naming_the_field():
    for kwargs, field in [
        ({"control_interval": -1}, "control_interval"),
        ({"grid": "10x4"}, "n_z"),
        ({"damping_range": (1, 0.5)}, "damping_range"),
        ({"n_pressure_probes": 0}, "n_pressure_probes"),
        ({"command_fraction_range": (1.0, 0.9)}, "command_fraction_range"),
        ({"episode_steps": 0}, "episode_steps"),
        ({"render_mode": "ascii"}, "render_mode"),
    ]:
        with pytest.raises(ValueError, match=field):
            RunUpEnv(**kwargs)
    with pytest.raises(ValueError, match="clearance_range_m"):
        gym.make("gfb_env/RunUpRandomized-v2", clearance_range_m=(1e-6, 2e-6))


def test_whirl_recovery_starts_whirling():
    env = WhirlRecoveryEnv(control_interval=60.0, disturbance_probability=0.0)
    obs, info = env.reset(seed=0)
    obs, r, term, trunc, info = env.step(
        np.array([0.0, env.action_from_damping(env.whirl_damping)], np.float32)
    )
    assert info["whirl_amplitude"] > 0.3 and not term
    assert obs[4] > 0.5  # orbit extent in xi


def test_whirl_amplitude_ignores_the_drift():
    t = np.linspace(0, 60, 121)
    assert _whirl_amplitude(t, 0.1 + 1e-3 * t, 0.5 - 2e-3 * t) < 1e-12
    # a circular whirl of radius 0.2 over 2.9 periods: the trend fit absorbs a little (+17 % here)
    assert 0.18 < _whirl_amplitude(t, 0.2 * np.sin(0.3 * t), 0.2 * np.cos(0.3 * t)) < 0.25


# ---- defect 10 (issue 18): an action of another shape or a complex one is refused, not reshaped -------
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_step_refuses_a_wrong_shape_or_a_non_real_action(env_id):
    env = _make(env_id)
    env.reset(seed=0)
    for bad in (np.zeros((1, 2)), np.zeros((2, 1)), np.zeros(3), np.float32(0.0), [[0.0, 0.0]]):
        with pytest.raises(ValueError, match=r"action must have shape \(2,\), got"):
            env.step(bad)
    for bad in (np.array([0.5 + 1j, 0.0]), [0.5j, 0.0], np.array(["0.1", "0.2"]), [None, 0.0]):
        with pytest.raises(ValueError, match="action must be real numbers"):
            env.step(bad)
    # none of the refusals moved the episode; plain lists, ints and bools are real numbers
    for ok in ([0.0, 0.0], np.array([0, 1]), np.array([True, False])):
        _, _, term, trunc, info = env.step(ok)
        if term or trunc:
            break
    assert info["step"] >= 1


# ---- the step as a public protocol (issue 18): plan_step, the plant, finish_step -----------------------
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_plan_and_finish_are_the_step_bit_for_bit(env_id):
    from gfb_env.envs.base import StepPlan, advance_plans
    from gfb_env.integrator import BatchAdvance

    kw = {**FAST, **_disturbed(env_id)}
    one, two = gym.make(env_id, **kw).unwrapped, gym.make(env_id, **kw).unwrapped
    o1, _ = one.reset(seed=7)
    o2, _ = two.reset(seed=7)
    assert np.array_equal(o1, o2)
    rng = np.random.default_rng(0)
    batch = BatchAdvance(num_threads=1)
    for _ in range(3):
        a = rng.uniform(-1.2, 1.2, 2).astype(np.float32)
        r1 = one.step(a)
        plan = two.plan_step(a)
        assert isinstance(plan, StepPlan) and plan.call is not None and plan.failure is None
        assert plan.action_sanitised == bool(np.any(np.abs(a) > 1))
        r2 = two.finish_step(plan, advance_plans(batch, [plan])[0])
        assert np.array_equal(r1[0], r2[0]) and r1[1:4] == r2[1:4]
        assert repr(sorted(r1[4].items())) == repr(sorted(r2[4].items()))
        if r1[2]:
            break


def test_a_plan_is_finished_once_by_its_own_env():
    from gfb_env.envs.base import advance_plans
    from gfb_env.integrator import BatchAdvance

    env, other = RunUpEnv(**FAST), RunUpEnv(**FAST)
    env.reset(seed=0)
    other.reset(seed=0)
    plan = env.plan_step(np.zeros(2))
    with pytest.raises(RuntimeError, match="planned and not finished"):
        env.plan_step(np.zeros(2))
    with pytest.raises(RuntimeError, match="planned and not finished"):
        env.get_state()
    with pytest.raises(ValueError, match="pending plan"):
        other.finish_step(plan, None)
    result = advance_plans(BatchAdvance(), [plan])[0]
    env.finish_step(plan, result)
    with pytest.raises(ValueError, match="pending plan"):
        env.finish_step(plan, result)
    env.step(np.zeros(2))  # the env steps on
    env.plan_step(np.zeros(2))
    env.reset(seed=1)  # a reset drops a pending plan
    env.step(np.zeros(2))
