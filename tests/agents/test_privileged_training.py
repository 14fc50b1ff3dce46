"""Training with what the simulator knows at training time only (issue 21): the privileged vector, the
asymmetric actor-critic PPO (critic: observation + privileged vector; actor: observation only), its resume,
its export (the actor alone) and its refusals.  Tiny budgets: 8-step episodes, 16-step rollouts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch as th
import yaml
from test_cli_agents import _refused

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import seeds
from gfb_agents.learned import train as train_mod
from gfb_agents.learned.asymmetric import ACTOR_FILE, DeployedActor
from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
from gfb_agents.learned.export_policy import export_policy
from gfb_agents.learned.privileged import (
    EPISODE_FIELDS,
    OBS_KEY,
    PRIVILEGED_KEY,
    episode_vector,
    privileged_names,
)
from gfb_agents.learned.train import TrainConfig, load_hyperparams, make_vec_env_for
from gfb_agents.learned.vec_env import PrivilegedVecEnv
from gfb_experiments.train import main as train_main

ENV = "gfb_env/RunUp-v2"
ALGO = "asymmetric_ppo"


def _expected(hidden: dict) -> list[float]:
    """The documented order, written out from ``hidden_parameters()`` independently of the code."""
    b, u, bias = hidden["bearing"], hidden["unbalance"], hidden["sensors"]["probe_bias_um"]
    return [
        math.log(hidden["damping_gain"]),
        *(
            [0.0] * 5
            if b is None
            else [1.0, b["clearance_um"], b["stiffness_factor"], b["load_n"], b["foil_stiffness"]]
        ),
        *(
            [0.0] * 5
            if u is None
            else [
                1.0,
                u["balance_grade_mm_s"],
                u["magnitude_um"],
                math.cos(u["phase_rad"]),
                math.sin(u["phase_rad"]),
            ]
        ),
        bias[0],
        bias[1],
    ]


@pytest.mark.parametrize("env_id", ["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2"])
def test_the_privileged_vector_is_hidden_parameters_in_the_documented_order(env_id):
    n = 2
    kw = {"max_episode_steps": 2, "privileged_info": True}
    venv = PrivilegedVecEnv(
        make_vec_env_for(env_id, n, seed=11, env_kwargs=kw, vec_env="native"), ("whirl_amplitude",)
    )
    assert venv.names == privileged_names(("whirl_amplitude",)) == (*EPISODE_FIELDS, "whirl_amplitude")
    twins = [gym.make(env_id, **kw) for _ in range(n)]  # the same seeds, played alongside
    o = venv.reset()
    infos = []
    for i, t in enumerate(twins):
        raw, info = t.reset(seed=11 + i)
        infos.append(info)
        assert np.array_equal(o[OBS_KEY][i], raw)
    for step in range(3):  # an autoreset (time limit 2) inside
        for i, t in enumerate(twins):
            want = _expected(t.unwrapped.hidden_parameters()) + [infos[i]["privileged"]["whirl_amplitude"]]
            np.testing.assert_allclose(o[PRIVILEGED_KEY][i], np.float32(want), rtol=1e-6)
        a = np.zeros((n, 2), dtype=np.float32)
        o, _, d, inf = venv.step(a)
        for i, t in enumerate(twins):
            before = _expected(t.unwrapped.hidden_parameters())
            raw, _, term, trunc, infos[i] = t.step(a[i])
            if d[i]:
                # the ended episode's vector goes with its last observation; the new one with the reset
                term_obs = inf[i]["terminal_observation"]
                assert np.array_equal(term_obs[OBS_KEY], raw)
                want = before + [infos[i]["privileged"]["whirl_amplitude"]]
                np.testing.assert_allclose(term_obs[PRIVILEGED_KEY], np.float32(want), rtol=1e-6)
                raw, infos[i] = t.reset()
            assert np.array_equal(o[OBS_KEY][i], raw)
        assert d.any() == (step == 1)
    venv.close()
    # the episode's draws need nothing but hidden_parameters(); the groups a task lacks are zeros
    env = gym.make(ENV)
    env.reset(seed=3)
    v = episode_vector(env.unwrapped.hidden_parameters())
    assert v.dtype == np.float32 and v.shape == (len(EPISODE_FIELDS),)
    assert v[EPISODE_FIELDS.index("bearing_drawn")] == 0.0  # RunUp-v2: the nominal bearing
    assert v[0] == pytest.approx(math.log(env.unwrapped.damping_gain), rel=1e-6)
    # step quantities need the opt-in channel: one line
    with pytest.raises(ValueError, match="privileged_info=True"):
        PrivilegedVecEnv(make_vec_env_for(ENV, 1, seed=1, vec_env="native"), ("whirl_amplitude",)).reset()
    with pytest.raises(ValueError, match="unknown"):
        PrivilegedVecEnv(make_vec_env_for(ENV, 1, seed=1, vec_env="native"), ("damping_gain",))


def _tiny_yaml(tmp_path: Path, **extra) -> Path:
    hp = load_hyperparams(ALGO, ENV)
    hp.update(n_steps=16, batch_size=16, n_epochs=1, n_envs=1)
    hp["policy_kwargs"] = "dict(net_arch=dict(pi=[8], vf=[8]))"
    hp.update(extra)
    p = tmp_path / f"{ALGO}_tiny.yml"
    p.write_text(yaml.safe_dump({ENV: hp}))
    return p


def _train_tiny(tmp_path: Path, **overrides) -> Path:
    kwargs = dict(
        timesteps=64,
        seed=0,
        n_envs=2,
        out=tmp_path / "run",
        hyperparams=_tiny_yaml(tmp_path),
        env_kwargs={"max_episode_steps": 8},
        eval_freq=32,
        eval_episodes=1,
        checkpoint_freq=32,
        frame_stack=2,
        progress_bar=False,
        tensorboard=False,
    )
    kwargs.update(overrides)
    return train_mod.train(TrainConfig(ALGO, ENV, **kwargs))


def test_asymmetric_ppo_trains_its_actor_reads_only_the_observation_and_it_exports_small(tmp_path):
    from stable_baselines3 import PPO

    out = _train_tiny(tmp_path)
    meta = json.loads((out / "run.json").read_text())
    assert meta["algo"] == ALGO and meta["timesteps"] == 64 and meta["privileged"] == list(EPISODE_FIELDS)
    assert meta["sessions"][0]["env_seed"] == seeds.train_env_seed(0, 0, 0)  # TRAIN seeds
    assert meta["sessions"][0]["env_seed"] in seeds.TRAIN
    assert meta["validation_seeds"] == seeds.VALIDATION.first(1)
    model = PPO.load(str(out / "model.zip"), device="cpu")
    pol = model.policy
    # the actor's output does not change with the privileged vector; the critic's does
    rng = np.random.default_rng(0)
    obs = {
        OBS_KEY: rng.normal(size=(5, *pol.observation_space[OBS_KEY].shape)).astype(np.float32),
        PRIVILEGED_KEY: rng.normal(size=(5, *pol.observation_space[PRIVILEGED_KEY].shape)).astype(np.float32),
    }
    other = {**obs, PRIVILEGED_KEY: 100.0 * rng.normal(size=obs[PRIVILEGED_KEY].shape).astype(np.float32)}
    with th.no_grad():
        t1, _ = pol.obs_to_tensor(obs)
        t2, _ = pol.obs_to_tensor(other)
        assert th.equal(
            pol.get_distribution(t1).distribution.mean, pol.get_distribution(t2).distribution.mean
        )
        assert not th.equal(pol.predict_values(t1), pol.predict_values(t2))
    # the deployed actor takes the observation alone and acts as the trained policy does
    deployed = LearnedPolicy(out, which="final")
    assert isinstance(deployed.model, DeployedActor) and deployed.frame_stack == 2
    a_ref, _ = model.predict(obs, deterministic=True)
    a_dep, _ = deployed.model.predict(obs[OBS_KEY], deterministic=True)
    np.testing.assert_allclose(a_dep, a_ref, rtol=0, atol=1e-6)
    # ... and plays an env made without privileged_info, through the benchmark's episode loop
    env = gym.make(ENV, max_episode_steps=5)
    assert not env.unwrapped.config.privileged_info
    res = run_episode(env, LearnedPolicy(out), seed=seeds.VALIDATION.first(1)[0])
    assert res.steps == 5 and math.isfinite(res.episode_return)
    # the exported copy: the actor alone (no critic, no optimiser state), small, loads into LearnedPolicy
    dest = export_policy(out, "asym", which="final", root=tmp_path / "policies")
    assert not (dest / "model.zip").exists() and (dest / ACTOR_FILE).stat().st_size < 20_000
    blob = th.load(str(dest / ACTOR_FILE), weights_only=True)
    assert not any("optim" in k or "value" in k or "vf" in k for k in blob["state_dict"])
    exported = LearnedPolicy(dest)
    assert exported.algo == ALGO and exported.frame_stack == 2 and exported.model_path.name == ACTOR_FILE
    raw = gym.make(ENV).reset(seed=4)[0]
    for p in (deployed, exported):
        p.reset()
    np.testing.assert_array_equal(
        exported.predict(raw, episode_start=True)[0], deployed.predict(raw, episode_start=True)[0]
    )
    from gfb_agents.ladder import learned_entries

    (entry,) = learned_entries(tmp_path / "policies")
    assert entry.name == "asym" and entry.tasks == (ENV,)


def test_asymmetric_ppo_resumes_after_a_kill_to_exactly_its_total(tmp_path, monkeypatch):
    real = train_mod._Session.checkpoint

    def killed_after_first(self, model, *args, **kwargs):
        real(self, model, *args, **kwargs)
        raise RuntimeError("killed")

    monkeypatch.setattr(train_mod._Session, "checkpoint", killed_after_first)
    with pytest.raises(RuntimeError, match="killed"):
        _train_tiny(tmp_path, eval_freq=10_000)
    monkeypatch.undo()
    assert train_mod.latest_checkpoint(tmp_path / "run")["num_timesteps"] == 32
    out = _train_tiny(tmp_path, eval_freq=10_000)
    meta = json.loads((out / "run.json").read_text())
    assert meta["timesteps"] == 64 and [s["start_timesteps"] for s in meta["sessions"]] == [0, 32]
    assert meta["sessions"][1]["env_seed"] == seeds.train_env_seed(0, 0, 1)
    with pytest.raises(ValueError, match="other settings"):  # the critic's input is part of the settings
        _train_tiny(tmp_path, timesteps=96, privileged_quantities=("whirl_amplitude",))


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--privileged-quantities", "damping_gain"], "privileged quantities ['damping_gain'] unknown"),
        (["--privileged-quantities", "whirl_amplitude", "--algo", "ppo"], "only with asymmetric_ppo"),
        (["--env-kwargs", '{"privileged_info": true}'], "privileged_info is set by the training command"),
        (["--policy", "MlpPolicy"], "policy must be 'AsymmetricActorCriticPolicy'"),
    ],
)
def test_bad_options_are_refused_with_one_line(tmp_path, capsys, extra, fragment):
    yml = _tiny_yaml(tmp_path)
    if "--policy" in extra:
        yml = _tiny_yaml(tmp_path, policy=extra[1])
        extra = []
    argv = ["--algo", ALGO, "--env", ENV, "--timesteps", "16", "--hyperparams", str(yml)]
    argv += ["--out", str(tmp_path / "exp"), "--no-progress-bar", "--no-tensorboard", *extra]
    _refused(train_main, argv, fragment, capsys, within_s=15.0)
    assert not (tmp_path / "exp").exists()


# ------------------------------------------------------------------ teacher-student (DAgger)
@pytest.fixture(scope="module")
def teacher_run(tmp_path_factory) -> Path:
    """A tiny privileged_ppo teacher (64 steps, frame stack 2, 8-step episodes)."""
    tmp = tmp_path_factory.mktemp("teacher")
    hp = load_hyperparams("privileged_ppo", ENV)
    hp.update(n_steps=16, batch_size=16, n_epochs=1, n_envs=2)
    hp["policy_kwargs"] = "dict(net_arch=dict(pi=[8], vf=[8]))"
    (tmp / "t.yml").write_text(yaml.safe_dump({ENV: hp}))
    cfg = TrainConfig(
        "privileged_ppo",
        ENV,
        timesteps=64,
        out=tmp / "teacher",
        hyperparams=tmp / "t.yml",
        env_kwargs={"max_episode_steps": 8},
        eval_freq=32,
        eval_episodes=1,
        checkpoint_freq=32,
        frame_stack=2,
        progress_bar=False,
        tensorboard=False,
    )
    return train_mod.train(cfg)


def distill_killed_after_first_checkpoint(cfg, monkeypatch) -> None:
    """Run ``distill(cfg)`` until its first checkpoint's pointer is written, then kill it (an exception
    where the process would die): what a resume starts from."""
    from gfb_agents.learned import teacher_student as ts

    real = ts._atomic_json

    def killed_after_first_checkpoint(path, obj):
        real(path, obj)
        if path.name == "latest.json":
            raise RuntimeError("killed")

    monkeypatch.setattr(ts, "_atomic_json", killed_after_first_checkpoint)
    with pytest.raises(RuntimeError, match="killed"):
        ts.distill(cfg)
    monkeypatch.undo()


def _student_yaml(tmp_path: Path, **extra) -> Path:
    hs = load_hyperparams("teacher_student", ENV)
    hs.update(n_envs=2, steps_per_iteration=32, epochs=2, batch_size=16, history=3, hidden=[8], **extra)
    p = tmp_path / "s.yml"
    p.write_text(yaml.safe_dump({ENV: hs}))
    return p


def test_the_teacher_reads_the_privileged_vector_and_is_not_deployable(teacher_run, tmp_path):
    from gfb_agents.learned.teacher_student import load_teacher

    meta = json.loads((teacher_run / "run.json").read_text())
    assert meta["algo"] == "privileged_ppo" and meta["privileged"] == list(EPISODE_FIELDS)
    assert meta["best_validation"] is not None  # validated with the hidden draws handed over
    teacher, _ = load_teacher(teacher_run)
    rng = np.random.default_rng(1)
    n_obs = gym.make(ENV).observation_space.shape[0]  # the task's observation (v2: 30 entries)
    obs = rng.normal(size=(3, n_obs)).astype(np.float32)
    priv = rng.normal(size=(3, len(EPISODE_FIELDS))).astype(np.float32)
    a1 = teacher.act(obs, priv, np.ones(3, bool))
    teacher.reset()
    a2 = teacher.act(obs, 50 * priv, np.ones(3, bool))
    assert not np.allclose(a1, a2)  # its actor does read the privileged vector
    with pytest.raises(ValueError, match="not a deployable policy"):
        LearnedPolicy(teacher_run)
    with pytest.raises(ValueError, match="not exported"):
        export_policy(teacher_run, "teacher", root=tmp_path / "policies")


def test_the_student_is_distilled_by_dagger_resumes_and_deploys_from_the_observation(
    teacher_run, tmp_path, monkeypatch
):
    from gfb_agents.learned import teacher_student as ts

    cfg = ts.DistillConfig(
        teacher=teacher_run,
        timesteps=64,
        out=tmp_path / "s",
        hyperparams=_student_yaml(tmp_path),
        eval_episodes=1,
    )
    distill_killed_after_first_checkpoint(cfg, monkeypatch)
    assert json.loads((tmp_path / "s" / "checkpoints" / "latest.json").read_text())["timesteps"] == 32
    out = ts.distill(cfg)
    meta = json.loads((out / "run.json").read_text())
    assert meta["algo"] == "teacher_student" and meta["timesteps"] == 64 and meta["frame_stack"] == 3
    assert [(s["start_timesteps"], s["end_timesteps"], s["ended"]) for s in meta["sessions"]] == [
        (0, 32, "killed"),
        (32, 64, "finished"),
    ]
    assert [s["env_seed"] for s in meta["sessions"]] == [seeds.train_env_seed(0, 0, k) for k in (0, 1)]
    hist = json.loads((out / "validation.json").read_text())["history"]
    assert [h["beta"] for h in hist] == [1.0, 0.5] and [h["samples"] for h in hist] == [32, 64]
    # a rerun of a finished distillation does nothing
    t = (out / "run.json").stat().st_mtime_ns
    ts.distill(cfg)
    assert (out / "run.json").stat().st_mtime_ns == t
    with pytest.raises(ValueError, match="other settings"):
        ts.distill(ts.DistillConfig(**{**cfg.as_dict(), "timesteps": 96}))
    # deployed: the student alone, on an env without the privileged channel; exported small
    pol = LearnedPolicy(out)
    n_obs = gym.make(ENV).observation_space.shape[0]
    assert isinstance(pol.model, DeployedActor) and pol.model.obs_dim == 3 * n_obs  # a 3-frame stack
    res = run_episode(gym.make(ENV, max_episode_steps=4), pol, seed=seeds.VALIDATION.first(1)[0])
    assert res.steps == 4 and math.isfinite(res.episode_return)
    dest = export_policy(out, "student", root=tmp_path / "policies")
    assert (dest / ACTOR_FILE).stat().st_size < 20_000 and not (dest / "model.zip").exists()
    assert LearnedPolicy(dest).frame_stack == 3


@pytest.mark.parametrize(
    "extra, fragment",
    [
        ([], "needs --teacher RUN"),
        (["--teacher", "{ppo}"], "the teacher is a privileged_ppo run"),
        (["--teacher", "{teacher}", "--frame-stack", "4"], "--frame-stack: not with --algo teacher_student"),
        (["--teacher", "{teacher}", "--hyperparams", "{bad}"], "hyperparameters ['bogus'] unknown"),
        (["--teacher", "{teacher}", "--env", "gfb_env/WhirlRecovery-v2"], "the teacher was trained on"),
    ],
)
def test_teacher_student_bad_options_are_refused_with_one_line(
    teacher_run, tmp_path, capsys, extra, fragment
):
    (tmp_path / "ppo").mkdir()
    (tmp_path / "ppo" / "run.json").write_text(json.dumps({"algo": "ppo", "env_id": ENV}))
    bad = _student_yaml(tmp_path, bogus=1)
    subs = {"{ppo}": str(tmp_path / "ppo"), "{teacher}": str(teacher_run), "{bad}": str(bad)}
    argv = ["--algo", "teacher_student", "--out", str(tmp_path / "exp")]
    argv += [subs.get(x, x) for x in extra]
    _refused(train_main, argv, fragment, capsys, within_s=15.0)
    assert not (tmp_path / "exp").exists()
