"""The slew limit of the learned damping command (issue 21, "Realisable actuation";
:mod:`gfb_agents.learned.slew`): the bound by construction on a v2 env, the same transform in training
(``--damping-slew``) and in the deployed / exported policy (bit for bit), its resume and its refusals.
Tiny budgets: 8-step episodes, 16-step rollouts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from test_cli_agents import _refused

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.learned import train as train_mod
from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
from gfb_agents.learned.export_policy import export_policy
from gfb_agents.learned.slew import (
    DampingSlew,
    SlewLimitedPolicy,
    check_damping_slew,
    check_damping_slew_reserve,
    slew_damping,
)
from gfb_agents.learned.train import TrainConfig, load_hyperparams, make_vec_env_for
from gfb_agents.learned.vec_env import DampingSlewVecEnv
from gfb_agents.policy import Policy
from gfb_agents.seeds import VALIDATION
from gfb_env.envs.units import OBS_DAMPING
from gfb_experiments.train import main as train_main

ENV = "gfb_env/RunUp-v2"


class _RandomPolicy(Policy):
    """Uniform random actions: the worst chattering a policy can ask for."""

    name = "random"

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return self.rng.uniform(-1.0, 1.0, 2).astype(np.float32), state


class _Recorder(gym.Wrapper):
    """The actions the env is given and the observations it returns, per episode."""

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.actions, self.observations = [], [obs]
        return obs, info

    def step(self, action):
        self.actions.append(np.array(action, copy=True))
        out = self.env.step(action)
        self.observations.append(out[0])
        return out


# the three v2 tasks' limits (docs/agents.md: 3x the best rule's mean |change| of the test table)
@pytest.mark.parametrize("env_id, rate", [(ENV, 0.028), ("gfb_env/WhirlRecovery-v2", 0.0058)])
def test_a_random_policy_through_the_slew_limit_moves_the_command_at_most_r_per_step(env_id, rate):
    env = _Recorder(gym.make(env_id, max_episode_steps=40))
    free = run_episode(env, _RandomPolicy(), seed=VALIDATION.first(1)[0])
    assert free.damping_command_change > 20 * rate  # without it: ~0.7 (2/3 for uniform draws)
    free_speed = [a[0] for a in env.actions]
    limited = run_episode(env, SlewLimitedPolicy(_RandomPolicy(), rate), seed=VALIDATION.first(1)[0])
    assert limited.steps > 1
    assert limited.damping_command_change <= rate  # the benchmark's measure, by construction
    a = np.array(env.actions, dtype=np.float64)
    start = float(env.observations[0][OBS_DAMPING])  # run_episode's reference for step 0
    moves = np.abs(np.diff(np.r_[start, a[:, 1]]))
    assert moves.max() <= rate and np.median(moves) > 0.99 * rate  # mostly at the limit, never past it
    # the speed action passes unchanged (the same random stream)
    assert np.array_equal(a[: len(free_speed), 0], np.array(free_speed, dtype=np.float64)[: len(a)])
    # the indicated damping of the observation follows the command within the actuator's lag
    indicated = np.array([o[OBS_DAMPING] for o in env.observations[1:]], dtype=np.float64)
    assert np.abs(indicated - a[:, 1]).max() < rate


class _HoldAndJump(Policy):
    """A rule's hold-and-jump: ask for the reset damping for ``hold`` steps, then for the far side."""

    name = "hold-and-jump"

    def __init__(self, hold: int):
        self.hold, self.k, self.start = hold, 0, 0.0

    def reset(self):
        self.k = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self.k == 0:
            self.start = float(observation[OBS_DAMPING])
        self.k += 1
        far = -0.8 if self.start > 0 else 0.8
        return np.float32([0.5, self.start if self.k <= self.hold else far]), state


@pytest.mark.parametrize("policy", [_RandomPolicy(), _HoldAndJump(30)], ids=["random", "hold-and-jump"])
def test_a_reserve_lets_a_held_command_jump_and_keeps_every_prefix_mean_within_r(policy):
    rate, steps = 0.028, 60
    env = _Recorder(gym.make(ENV, max_episode_steps=steps))
    res = run_episode(env, SlewLimitedPolicy(policy, rate, reserve=1.0), seed=VALIDATION.first(1)[0])
    a = np.array(env.actions, dtype=np.float64)[:, 1]
    moves = np.abs(np.diff(np.r_[float(env.observations[0][OBS_DAMPING]), a]))
    k = np.arange(1, len(moves) + 1)
    assert np.all(np.cumsum(moves) <= k * rate)  # an episode ending at any step: mean <= r
    assert res.damping_command_change <= rate
    if isinstance(policy, _HoldAndJump):
        assert moves.max() > 20 * rate  # after holding, a jump the plain slew limit would spread out
    # the plain limit (no reserve) is the same code with nothing saved: every move at most r
    plain = DampingSlew(rate)
    with_reserve = DampingSlew(rate, reserve=1.0)
    obs = np.zeros((1, 30), dtype=np.float32)
    plain.start(obs)
    with_reserve.start(obs)
    for _ in range(10):  # hold 10 steps, then ask for 0.5
        plain(np.float32([[0, 0]]))
        with_reserve(np.float32([[0, 0]]))
    one = float(plain(np.float32([[0, 0.5]]))[0, 1])
    assert one <= rate and one == pytest.approx(rate, rel=1e-7)
    eleven = float(with_reserve(np.float32([[0, 0.5]]))[0, 1])
    assert eleven <= 11 * rate and eleven == pytest.approx(11 * rate, rel=1e-7)


def test_the_filter_reaches_a_near_set_point_holds_it_and_rounds_inside_the_limit():
    s = DampingSlew(0.125)  # binary fractions: exact arithmetic
    obs = np.zeros((3, 30), dtype=np.float32)
    obs[:, OBS_DAMPING] = [0.0, 0.5, -1.0]
    s.start(obs)
    a = s(np.array([[0.3, 0.0625], [-0.7, 1.0], [1.0, -1.0]], dtype=np.float32))
    assert a.dtype == np.float32 and np.array_equal(a[:, 0], np.float32([0.3, -0.7, 1.0]))  # speed: as is
    assert np.array_equal(a[:, 1], np.float32([0.0625, 0.625, -1.0]))  # within r: reached; beyond: r
    assert np.array_equal(s(a)[:, 1], a[:, 1])  # asking for the level holds it
    s.start(obs, np.array([False, True, False]))  # one env's new episode
    assert np.array_equal(s.previous, np.float32([0.0625, 0.5, -1.0]))
    assert np.array_equal(s(np.float32([[0, 0.375]] * 3))[:, 1], np.float32([0.1875, 0.375, -0.875]))
    # 0.5 + 0.1 rounds to float32 0.6, 2.4e-8 past the limit: one float32 step back
    assert slew_damping(np.float32([0.5]), np.float32([1.0]), 0.1)[0] == np.nextafter(np.float32(0.6), 0)
    # float32 rounding never lands past the limit (float64 arithmetic, as run_episode measures)
    rng = np.random.default_rng(3)
    for r in (0.0058, 0.027, 0.028, 1e-7, 2.0):
        p = rng.uniform(-1, 1, 20_000).astype(np.float32)
        u = rng.uniform(-1, 1, 20_000).astype(np.float32)
        out = slew_damping(p, u, r)
        d = np.abs(out.astype(np.float64) - p.astype(np.float64))
        assert d.max() <= r and np.all(np.abs(out) <= 1.0)
        near = np.abs(u.astype(np.float64) - p) <= r
        assert np.array_equal(out[near], u[near])
    assert check_damping_slew(None) is None and check_damping_slew(2) == 2.0


@pytest.mark.parametrize("bad", [0, -0.1, math.nan, math.inf, 2.5, True, "0.1"])
def test_a_bad_slew_limit_is_one_line_naming_the_option(bad):
    with pytest.raises(ValueError, match="--damping-slew") as exc:
        TrainConfig("ppo", ENV, damping_slew=bad)
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match="--damping-slew-reserve") as exc:
        TrainConfig("ppo", ENV, damping_slew=0.1, damping_slew_reserve=bad)
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match="--damping-slew-reserve.*only with --damping-slew"):
        check_damping_slew_reserve(1.0, None)


@pytest.mark.parametrize(
    "extra, fragment",
    [
        *[(["--damping-slew", v], "--damping-slew") for v in ("0", "-0.1", "nan", "inf", "2.5")],
        (["--damping-slew", "0.1", "--damping-slew-reserve", "0"], "--damping-slew-reserve"),
        (["--damping-slew-reserve", "1"], "--damping-slew-reserve (damping_slew_reserve): only with"),
    ],
)
def test_the_cli_refuses_a_bad_slew_limit_with_exit_2(tmp_path, capsys, extra, fragment):
    argv = ["--algo", "ppo", "--env", ENV, "--timesteps", "16", *extra]
    argv += ["--out", str(tmp_path / "exp"), "--no-progress-bar", "--no-tensorboard"]
    _refused(train_main, argv, fragment, capsys, within_s=15.0)
    assert not (tmp_path / "exp").exists()


def test_the_student_takes_its_teachers_limit_and_refuses_its_own(tmp_path, capsys):
    argv = ["--algo", "teacher_student", "--teacher", str(tmp_path), "--damping-slew", "0.02"]
    _refused(train_main, argv, "--damping-slew: not with --algo teacher_student", capsys, within_s=15.0)


# ------------------------------------------------------------------ training with the limit
RATE = 0.01  # binds at nearly every step of an untrained policy


def _tiny_yaml(tmp_path: Path, algo: str) -> Path:
    hp = load_hyperparams(algo, ENV)
    if algo == "sac":
        hp.update(learning_starts=8, batch_size=8, buffer_size=200, train_freq=4, gradient_steps=1, n_envs=2)
        hp["policy_kwargs"] = "dict(net_arch=[8])"
    else:
        hp.update(n_steps=16, batch_size=16, n_epochs=1, n_envs=2)
        hp["policy_kwargs"] = (
            "dict(net_arch=dict(pi=[8], vf=[8]), lstm_hidden_size=8)"
            if algo == "recurrentppo"
            else "dict(net_arch=dict(pi=[8], vf=[8]))"
        )
    p = tmp_path / f"{algo}_tiny.yml"
    p.write_text(yaml.safe_dump({ENV: hp}))
    return p


def _config(tmp_path: Path, algo: str = "ppo", **overrides) -> TrainConfig:
    kwargs = dict(
        timesteps=64,
        seed=0,
        n_envs=2,
        out=tmp_path / "run",
        hyperparams=_tiny_yaml(tmp_path, algo),
        env_kwargs={"max_episode_steps": 8},
        eval_freq=32,
        eval_episodes=1,
        checkpoint_freq=32,
        frame_stack=2 if algo in ("ppo", "asymmetric_ppo", "privileged_ppo") else 1,
        progress_bar=False,
        tensorboard=False,
        damping_slew=RATE,
    )
    kwargs.update(overrides)
    return TrainConfig(algo, ENV, **kwargs)


def _spy_commands(monkeypatch) -> list[np.ndarray]:
    """The batches the training wrapper sends to the envs, with each env's previous command."""
    seen: list[np.ndarray] = []
    real = DampingSlewVecEnv.step_async

    def step_async(self, actions):
        before = self.slew.previous.copy()
        real(self, actions)
        seen.append(np.abs(self.commands[:, 1].astype(np.float64) - before.astype(np.float64)))

    monkeypatch.setattr(DampingSlewVecEnv, "step_async", step_async)
    return seen


def test_ppo_trains_with_the_limit_resumes_and_refuses_another_one(tmp_path, monkeypatch):
    moves = _spy_commands(monkeypatch)
    real = train_mod._Session.checkpoint

    def killed_after_first(self, model, *args, **kwargs):
        real(self, model, *args, **kwargs)
        raise RuntimeError("killed")

    monkeypatch.setattr(train_mod._Session, "checkpoint", killed_after_first)
    with pytest.raises(RuntimeError, match="killed"):
        train_mod.train(_config(tmp_path, eval_freq=10_000))
    monkeypatch.setattr(train_mod._Session, "checkpoint", real)
    state = train_mod.latest_checkpoint(tmp_path / "run")
    assert state["num_timesteps"] == 32 and state["config"]["damping_slew"] == RATE
    out = train_mod.train(_config(tmp_path, eval_freq=10_000))
    meta = json.loads((out / "run.json").read_text())
    assert meta["timesteps"] == 64 and [s["start_timesteps"] for s in meta["sessions"]] == [0, 32]
    assert meta["damping_slew"] == RATE and meta["config"]["damping_slew"] == RATE
    assert len(moves) >= 32 and max(m.max() for m in moves) <= RATE  # every training step's command
    (val,) = json.loads((out / "validation.json").read_text())["history"]
    assert val["mean_damping_change"] <= RATE  # validation plays the limited policy
    for other in (None, 0.02):  # the limit is part of the policy: another one is another run
        with pytest.raises(ValueError, match=r"other settings \(damping_slew\)"):
            train_mod.train(_config(tmp_path, timesteps=96, damping_slew=other))
    with pytest.raises(ValueError, match=r"other settings \(damping_slew_reserve\)"):
        train_mod.train(_config(tmp_path, timesteps=96, damping_slew_reserve=0.5))
    assert TrainConfig("ppo", ENV, damping_slew=0.02).experiment_name == "RunUp-v2_ppo_slew0.02"


def test_a_run_recorded_before_the_option_resumes_without_a_limit(tmp_path, monkeypatch):
    """Runs of the earlier code have no ``damping_slew`` in their records: no limit, and they resume."""
    real = train_mod._Session.checkpoint

    def killed_after_first(self, model, *args, **kwargs):
        real(self, model, *args, **kwargs)
        raise RuntimeError("killed")

    monkeypatch.setattr(train_mod._Session, "checkpoint", killed_after_first)
    with pytest.raises(RuntimeError, match="killed"):
        train_mod.train(_config(tmp_path, eval_freq=10_000, damping_slew=None))
    monkeypatch.setattr(train_mod._Session, "checkpoint", real)
    for p in (tmp_path / "run" / "checkpoints").rglob("*.json"):
        state = json.loads(p.read_text())
        del state["config"]["damping_slew"]  # as the earlier code wrote it
        p.write_text(json.dumps(state))
    with pytest.raises(ValueError, match=r"other settings \(damping_slew\)"):
        train_mod.train(_config(tmp_path, timesteps=64, damping_slew=RATE))
    out = train_mod.train(_config(tmp_path, eval_freq=10_000, damping_slew=None))
    meta = json.loads((out / "run.json").read_text())
    assert meta["timesteps"] == 64 and "damping_slew" not in meta
    assert LearnedPolicy(out).damping_slew is None


@pytest.mark.parametrize("algo", ["sac", "recurrentppo", "asymmetric_ppo", "privileged_ppo"])
def test_every_algorithm_trains_and_validates_with_the_limit(tmp_path, monkeypatch, algo):
    moves = _spy_commands(monkeypatch)
    out = train_mod.train(_config(tmp_path, algo, timesteps=32, checkpoint_freq=10_000))
    meta = json.loads((out / "run.json").read_text())
    assert meta["damping_slew"] == RATE and meta["timesteps"] >= 32
    assert len(moves) >= 16 and max(m.max() for m in moves) <= RATE
    hist = json.loads((out / "validation.json").read_text())["history"]
    assert hist and all(h["mean_damping_change"] <= RATE for h in hist)
    if algo != "privileged_ppo":  # the teacher is no deployable policy
        res = run_episode(
            gym.make(ENV, max_episode_steps=12), LearnedPolicy(out), seed=VALIDATION.first(1)[0]
        )
        assert res.steps == 12 and res.damping_command_change <= RATE


# ------------------------------------------------------------ the exported policy: the same commands
@pytest.mark.parametrize("reserve", [None, 0.5], ids=["slew", "slew-with-reserve"])
def test_the_exported_policy_sends_the_commands_the_training_wrapper_sends_bit_for_bit(tmp_path, reserve):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    cfg = _config(tmp_path, timesteps=32, checkpoint_freq=10_000, damping_slew_reserve=reserve)
    out = train_mod.train(cfg)
    dest = export_policy(out, "slewed", which="final", root=tmp_path / "policies")
    info = json.loads((dest / "policy.json").read_text())
    assert info["damping_slew"] == RATE and "slew-limited" in (dest / "README.md").read_text()
    assert info.get("damping_slew_reserve") == reserve
    steps, seed = 30, VALIDATION.first(1)[0]
    # deployed: the benchmark's episode loop over the exported files
    env = _Recorder(gym.make(ENV, max_episode_steps=steps))
    pol = LearnedPolicy(dest)
    assert pol.damping_slew == RATE and pol.damping_slew_reserve == reserve and pol.frame_stack == 2
    res = run_episode(env, pol, seed=seed)
    deployed = np.array(env.actions)
    # training: the run's own env stack (the native vector env, the wrapper, frozen VecNormalize, stack)
    base = make_vec_env_for(ENV, 1, seed, env_kwargs={"max_episode_steps": steps}, vec_env="native")
    wrapper = DampingSlewVecEnv(base, RATE, reserve)
    vn = VecNormalize.load(str(dest / "vecnormalize.pkl"), wrapper)
    vn.training, vn.norm_reward = False, False
    venv = VecFrameStack(vn, 2)
    model = PPO.load(str(dest / "model.zip"), device="cpu")
    obs, trained = venv.reset(), []
    for _ in range(steps):
        a, _ = model.predict(obs, deterministic=True)
        obs, _, done, _ = venv.step(a)
        trained.append(wrapper.commands[0].copy())
        if done[0]:
            break
    venv.close()
    assert res.steps == len(trained) == steps
    assert deployed.dtype == np.float32 and np.array_equal(deployed, np.array(trained))
    assert res.damping_command_change <= RATE
    assert np.abs(np.diff(deployed[:, 1].astype(np.float64))).max() > 0.9 * RATE  # the limit binds here
    # ... and a policy reloaded after a reset (the stateful part) repeats the episode exactly
    res2 = run_episode(env, pol, seed=seed)
    assert np.array_equal(np.array(env.actions), deployed) and res2.episode_return == res.episode_return


def test_the_student_is_distilled_and_deployed_under_its_teachers_limit(tmp_path, monkeypatch):
    from gfb_agents.learned import teacher_student as ts

    teacher = train_mod.train(_config(tmp_path, "privileged_ppo", timesteps=32, checkpoint_freq=10_000))
    hs = load_hyperparams("teacher_student", ENV)
    hs.update(n_envs=2, steps_per_iteration=16, epochs=1, batch_size=8, history=2, hidden=[8])
    (tmp_path / "s.yml").write_text(yaml.safe_dump({ENV: hs}))
    moves = _spy_commands(monkeypatch)
    cfg = ts.DistillConfig(
        teacher=teacher, timesteps=16, out=tmp_path / "s", hyperparams=tmp_path / "s.yml", eval_episodes=1
    )
    out = ts.distill(cfg)
    assert len(moves) >= 8 and max(m.max() for m in moves) <= RATE  # DAgger's envs: the teacher's limit
    meta = json.loads((out / "run.json").read_text())
    assert meta["damping_slew"] == RATE
    assert json.loads((out / "validation.json").read_text())["history"][0]["mean_damping_change"] <= RATE
    dest = export_policy(out, "student", root=tmp_path / "policies")
    pol = LearnedPolicy(dest)
    assert pol.damping_slew == RATE
    res = run_episode(gym.make(ENV, max_episode_steps=12), pol, seed=VALIDATION.first(1)[0])
    assert res.steps == 12 and res.damping_command_change <= RATE
