"""The native vector env (issue 13): bit for bit Gymnasium's SyncVectorEnv of the same id and seeds over
whole episodes (resets, autoresets, kicks, shocks, randomised bearings, sanitised actions, solver
failures), its autoreset modes, Gymnasium's vector conventions and batch snapshots."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import same_value
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs import ENV_IDS, RETIRED_V1_IDS, GFBVectorEnv, make_retired_vec
from gfb_env.envs.episode import TerminationReason
from gfb_env.integrator import IntegrationError

FAST = {"control_interval": 20.0}
N = 3


#: the velocity kick instead of the base shocks (an option of the machine: they exclude each other)
KICKS = {"shock_arrivals": {"rate_per_s": 0.0}, "disturbance_probability": 0.5}


def _kwargs(env_id: str) -> dict:
    """Short episodes with the random base shocks made frequent, and noisy probes."""
    dist = {"shock_arrivals": {"rate_per_s": 20.0, "peak_g_range": (1.0, 5.0)}}
    return {**FAST, **dist, "observation_noise": 0.01, "max_episode_steps": 3}


def _pair(env_id: str, mode: AutoresetMode = AutoresetMode.NEXT_STEP, n: int = N, **kw):
    kw = {**_kwargs(env_id), **kw}
    # a retired v1 id through the record maker: the v1 interface's code stays, so its vector path is checked
    make_vec = make_retired_vec if env_id in RETIRED_V1_IDS else gym.make_vec
    native = make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kw)
    sync = make_vec(
        env_id, num_envs=n, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **kw
    )
    return native, sync


def _assert_same(a: tuple, b: tuple) -> None:
    """Two (obs, reward, terminated, truncated, infos) or (obs, infos) results, bit for bit."""
    assert len(a) == len(b)
    for x, y in zip(a[:-1], b[:-1], strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y)
    ia, ib = a[-1], b[-1]
    assert ia.keys() == ib.keys()
    bad = [k for k in ia if not same_value(ia[k], ib[k])]
    assert not bad, f"infos differ in {bad}"


def _actions(rng: np.random.Generator, n: int = N) -> np.ndarray:
    a = rng.uniform(-1.2, 1.2, (n, 2)).astype(np.float32)
    if rng.random() < 0.3:  # the single env's sanitising: NaN -> 0, inf and out of range clipped
        a[rng.integers(n), rng.integers(2)] = rng.choice([np.nan, np.inf, -np.inf])
    return a


def test_make_vec_returns_the_native_vector_env_for_every_task():
    for env_id in ENV_IDS:
        envs = gym.make_vec(env_id, num_envs=2, **FAST)  # no mode: the registered vector_entry_point
        assert isinstance(envs, GFBVectorEnv) and envs.num_envs == 2
        assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        assert envs.spec.id == env_id and envs.max_episode_steps == gym.spec(env_id).max_episode_steps
        single = gym.make(env_id, **FAST)
        assert envs.single_observation_space == single.observation_space
        assert envs.single_action_space == single.action_space
        assert envs.observation_space.shape == (2, *single.observation_space.shape)
        envs.close()


@pytest.mark.parametrize(
    "env_id, disturbances",
    [
        *((i, {}) for i in RETIRED_V1_IDS),
        ("gfb_env/RunUp-v2", KICKS),
        *((i, {"raw_probe_samples": True}) for i in ENV_IDS),
        # v2 episodes that end at their horizon (the final step's verdict keys, the certificate)
        ("gfb_env/WhirlRecovery-v2", {"episode_steps": 2, "hold_steps": 2}),
    ],
    ids=[*RETIRED_V1_IDS, "gfb_env/RunUp-v2-kicks", *ENV_IDS, "gfb_env/WhirlRecovery-v2-horizon"],
)
def test_native_vector_env_is_sync_vector_env_bit_for_bit(env_id, disturbances):
    """Whole episodes with autoresets (time limit 3), disturbances, noisy sensors, bad actions, a seeded
    and an unseeded reset, and a partial reset (reset_mask)."""
    native, sync = _pair(env_id, **disturbances)
    rng = np.random.default_rng(1)
    _assert_same(native.reset(seed=7), sync.reset(seed=7))
    for _ in range(8):
        a = _actions(rng)
        _assert_same(native.step(a), sync.step(a))
    _assert_same(native.reset(), sync.reset())
    for _ in range(2):
        a = _actions(rng)
        _assert_same(native.step(a), sync.step(a))
    mask = np.array([True, False, True])
    _assert_same(
        native.reset(seed=[3, None, 4], options={"reset_mask": mask}),
        sync.reset(seed=[3, None, 4], options={"reset_mask": mask.copy()}),
    )
    for _ in range(4):
        a = _actions(rng)
        _assert_same(native.step(a), sync.step(a))
    native.close()
    sync.close()


@pytest.mark.parametrize("env_id", ["gfb_env/WhirlRecovery-v2", "gfb_env/RunUpRandomized-v2"])
def test_same_step_autoreset_matches_sync_vector_env(env_id):
    native, sync = _pair(env_id, AutoresetMode.SAME_STEP)
    rng = np.random.default_rng(2)
    _assert_same(native.reset(seed=0), sync.reset(seed=0))
    for t in range(7):
        a = _actions(rng)
        res = native.step(a)
        _assert_same(res, sync.step(a))
        if t == 2:  # every env ended by the time limit: final_obs/final_info, the reset observation
            assert res[3].all() and res[4]["_final_obs"].all()
            assert all(fo.shape == native.single_observation_space.shape for fo in res[4]["final_obs"])
            assert (res[4]["step"] == 0).all() and (res[4]["final_info"]["step"] == 3).all()


def test_disabled_autoreset_refuses_to_step_an_ended_env():
    native, sync = _pair("gfb_env/RunUp-v2", AutoresetMode.DISABLED, max_episode_steps=1)
    _assert_same(native.reset(seed=0), sync.reset(seed=0))
    a = np.zeros((N, 2), np.float32)
    _assert_same(native.step(a), sync.step(a))
    with pytest.raises(RuntimeError, match="autoreset is disabled"):
        native.step(a)
    mask = np.ones(N, dtype=bool)
    _assert_same(native.reset(options={"reset_mask": mask}), sync.reset(options={"reset_mask": mask}))
    _assert_same(native.step(a), sync.step(a))


@pytest.mark.parametrize("env_id", ["gfb_env/RunUp-v2", "gfb_env/WhirlRecovery-v2"])
def test_a_solver_failure_in_one_env_is_handled_like_the_single_env(env_id, monkeypatch):
    native, sync = _pair(env_id, max_episode_steps=10)
    _assert_same(native.reset(seed=4), sync.reset(seed=4))

    def fail(*a, **k):
        raise IntegrationError("step size fell below min_step")

    # both the single env's advance and the batch prepare each call with prepare
    monkeypatch.setattr(native.envs[1]._integ, "prepare", fail)
    monkeypatch.setattr(sync.envs[1].unwrapped._integ, "prepare", fail)
    a = np.full((N, 2), 0.5, np.float32)
    res = native.step(a)
    _assert_same(res, sync.step(a))
    assert list(res[2]) == [False, True, False]
    assert res[4]["termination_reason"][1] is TerminationReason.SOLVER_FAILURE
    assert np.all(np.isfinite(res[0])) and np.all(np.isfinite(res[1]))
    # next step: env 1 is autoreset (its action ignored), the others continue
    res = native.step(a)
    _assert_same(res, sync.step(a))
    assert res[4]["step"].tolist() == [2, 0, 2] and res[1][1] == 0.0


def test_a_programming_error_in_the_plant_propagates(monkeypatch):
    native = gym.make_vec("gfb_env/RunUp-v2", num_envs=2, **FAST)
    native.reset(seed=0)

    def bug(*a, **k):
        raise TypeError("a programming error")

    monkeypatch.setattr(native.envs[0]._integ, "prepare", bug)
    with pytest.raises(TypeError, match="programming error"):
        native.step(np.zeros((2, 2), np.float32))


def test_a_failure_inside_the_compiled_batch_is_that_envs_only():
    """Env 1's compiled loop fails (tolerances below rounding: the step falls below min_step) in the
    same parallel call as the others; it ends with a solver failure, bit for bit as the single env."""
    native, sync = _pair("gfb_env/RunUp-v2", max_episode_steps=10)
    _assert_same(native.reset(seed=4), sync.reset(seed=4))
    for integ in (native.envs[1]._integ, sync.envs[1].unwrapped._integ):
        integ.options = integ.options.replace(rtol=1e-300, atol=1e-300, min_step=0.01)  # below rounding
    a = np.full((N, 2), 0.5, np.float32)
    res = native.step(a)
    _assert_same(res, sync.step(a))
    assert list(res[2]) == [False, True, False]
    assert res[4]["termination_reason"][1] is TerminationReason.SOLVER_FAILURE
    assert np.all(np.isfinite(res[0]))
    res = native.step(a)  # env 1 autoreset (its integrator kept: it fails again later)
    _assert_same(res, sync.step(a))


# RunUp-v2 with a balanced rotor: with an unbalance AND shocks, a snapshot restored into a *fresh* vector
# env differs from the original in the last bits of a reward after an autoreset (~4e-17; the same on the
# code before issue 18: the fresh env's integrator is built anew where the original's is reset; an
# integrator matter, reported); restored into the same env it is exact with both.
@pytest.mark.parametrize(
    "env_id, extra",
    [
        ("gfb_env/RunUp-v2", {"rotor_balance": {"grade_range_mm_s": (0.0, 0.0)}}),
        ("gfb_env/RunUpRandomized-v2", {}),
    ],
    ids=["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2"],
)
def test_batch_snapshot_restores_bit_for_bit(env_id, extra):
    native = gym.make_vec(env_id, num_envs=N, **_kwargs(env_id), **extra)
    rng = np.random.default_rng(5)
    native.reset(seed=9)
    for _ in range(2):
        native.step(_actions(rng))
    snap = native.get_state()
    actions = [_actions(rng) for _ in range(4)]  # through the time limit: autoresets included
    first = [native.step(a) for a in actions]
    native.set_state(snap)
    for a, r in zip(actions, first, strict=True):
        _assert_same(native.step(a), r)
    # into a fresh vector env of the same configuration, too
    other = gym.make_vec(env_id, num_envs=N, **_kwargs(env_id), **extra)
    other.set_state(snap)
    for a, r in zip(actions, first, strict=True):
        _assert_same(other.step(a), r)


def test_vector_env_conventions():
    """What Gymnasium's vector API promises: spaces, dtypes, info masks, seeding, refusals, wrappers."""
    envs = gym.make_vec("gfb_env/WhirlRecovery-v2", num_envs=2, **FAST)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros((2, 2), np.float32))
    obs, infos = envs.reset(seed=3)
    assert envs.observation_space.contains(obs)
    assert envs.np_random_seed == (3, 4)
    envs.action_space.seed(0)
    obs, r, term, trunc, infos = envs.step(envs.action_space.sample())
    assert envs.observation_space.contains(obs)
    assert r.dtype == np.float64 and term.dtype == trunc.dtype == np.bool_ and r.shape == (2,)

    def check_masks(d: dict) -> None:  # v2's info nests dicts (each with its own masks)
        for k, v in d.items():
            if not k.startswith("_"):
                assert d[f"_{k}"].dtype == np.bool_ and d[f"_{k}"].all()
                if isinstance(v, dict):
                    check_masks(v)
                else:
                    assert len(v) == 2

    check_masks(infos)
    assert envs.get_attr("control_interval") == (20.0, 20.0)
    with pytest.raises(ValueError, match="actions must have shape"):
        envs.step(np.zeros(2))
    with pytest.raises(ValueError, match="num_envs"):
        gym.make_vec("gfb_env/RunUp-v2", num_envs=0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("gfb_env/RunUp-v2", num_envs=1, autoreset_mode="sometimes")
    with pytest.raises(ValueError, match="control_interval"):
        gym.make_vec("gfb_env/RunUp-v2", num_envs=1, control_interval=-1.0)
    # Gymnasium's vector wrappers work over it
    stats = gym.wrappers.vector.RecordEpisodeStatistics(
        gym.make_vec("gfb_env/RunUp-v2", num_envs=2, max_episode_steps=2, **FAST)
    )
    stats.reset(seed=0)
    for _ in range(2):
        _, _, _, trunc, infos = stats.step(np.zeros((2, 2), np.float32))
    assert trunc.all() and infos["_episode"].all() and (infos["episode"]["l"] == 2).all()


def test_sync_vector_env_is_the_reference():
    # the reference of the comparisons is Gymnasium's own SyncVectorEnv, not the native env again
    _, sync = _pair("gfb_env/RunUp-v2")
    assert type(sync) is SyncVectorEnv


def test_the_thread_count_of_the_native_env():
    """``num_threads`` (the compiled plant stage's threads) changes no bit; bad values are refused."""
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    one = gym.make_vec("gfb_env/RunUp-v2", num_envs=N, num_threads=1, **_kwargs("gfb_env/RunUp-v2"))
    many = gym.make_vec("gfb_env/RunUp-v2", num_envs=N, **_kwargs("gfb_env/RunUp-v2"))
    assert one.num_threads == 1 and many.num_threads == top
    rng = np.random.default_rng(2)
    _assert_same(one.reset(seed=1), many.reset(seed=1))
    for _ in range(4):
        a = _actions(rng)
        _assert_same(one.step(a), many.step(a))
    many.num_threads = 1
    assert many.num_threads == 1
    for bad in (0, top + 1, 2.0):
        with pytest.raises(ValueError, match="num_threads"):
            gym.make_vec("gfb_env/RunUp-v2", num_envs=1, num_threads=bad)


# ---- defect 12 (issue 18): the exception types of Gymnasium's SyncVectorEnv ---------------------------
def _raised(f) -> BaseException:
    try:
        f()
    except Exception as exc:  # noqa: BLE001 - the type is what is compared
        return exc
    raise AssertionError("no exception")


def test_refusals_raise_what_sync_vector_env_raises():
    native, sync = _pair("gfb_env/RunUp-v2", n=2)
    native.reset(seed=0)
    sync.reset(seed=0)
    bad_calls = [
        ("reset", {"options": {"reset_mask": [True, False]}}),  # not an array: TypeError
        ("reset", {"options": {"reset_mask": np.array([1, 0])}}),  # not bool: TypeError
        ("reset", {"options": {"reset_mask": np.array([True])}}),  # shape: ValueError
        ("reset", {"options": {"reset_mask": np.zeros(2, bool)}}),  # no True: ValueError
        ("reset", {"seed": 1.5}),  # TypeError (Gymnasium: "object of type 'float' has no len()")
        ("reset", {"seed": [1, 2, 3]}),  # length: ValueError
        ("step", {"actions": 0.5}),  # a scalar: TypeError
        ("step", {"actions": np.zeros((3, 2), np.float32)}),  # envs: ValueError
        ("step", {"actions": np.zeros((2, 3), np.float32)}),  # an env's action: ValueError
    ]
    for name, kw in bad_calls:
        mine = _raised(lambda n=name, k=kw: getattr(native, n)(**k))
        ref = _raised(lambda n=name, k=kw: getattr(sync, n)(**k))
        assert type(mine) is type(ref), (name, kw, mine, ref)
    with pytest.raises(TypeError, match="seed must be None, an int or a list"):
        native.reset(seed=1.5)
    with pytest.raises(ValueError, match="actions must be real numbers"):
        native.step(np.full((2, 2), 0.5 + 1j))
