"""The oracle as DAgger's teacher (issue 21, gfb_agents.learned.oracle_teacher): its labels are the
oracle's actions on every env of a batch, across autoresets; the distillation takes its observation
statistics from the first iteration, resumes, and deploys a student that reads only the observation."""

from __future__ import annotations

import json
import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
import yaml
from test_cli_agents import _refused
from test_privileged_training import distill_killed_after_first_checkpoint

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import seeds
from gfb_agents.learned import teacher_student as ts
from gfb_agents.learned.asymmetric import DeployedActor
from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
from gfb_agents.learned.export_policy import export_policy
from gfb_agents.learned.oracle_teacher import OracleTeacher
from gfb_agents.learned.train import load_hyperparams, make_vec_env_for
from gfb_agents.learned.vec_env import DampingSlewVecEnv
from gfb_agents.oracles.commanded import CommandedOracle
from gfb_experiments.train import main as train_main


@pytest.mark.parametrize("vec_env", ["dummy", "native"])
@pytest.mark.parametrize("env_id", ["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2"])
def test_the_labels_are_the_oracles_actions_on_every_env_across_autoresets(env_id, vec_env):
    n = 2
    venv = make_vec_env_for(env_id, n, 4242, None, {"max_episode_steps": 5}, vec_env)
    teacher = OracleTeacher(env_id, n)
    # the oracle bound to each env the vector env steps (DummyVecEnv's envs; the native adapter's)
    envs = venv.envs if vec_env == "dummy" else venv._envs(None)
    refs = [CommandedOracle(e) for e in envs]
    o = venv.reset()
    starts = np.ones(n, dtype=bool)
    setpoints = set()
    for _ in range(12):  # two autoresets per env
        teacher.plan_episodes(venv, np.flatnonzero(starts))
        label = teacher.act(o, None, starts)
        for i, ref in enumerate(refs):
            if starts[i]:
                ref.reset()
            want, _ = ref.predict(o[i], episode_start=np.array([starts[i]]))
            np.testing.assert_allclose(label[i], want, rtol=0, atol=1e-6)
            setpoints.add(round(float(teacher.plan[i, 0]), 9))
        o, _, dones, _ = venv.step(label)
        starts = np.asarray(dones, dtype=bool)
    # a new plan per episode: the drawn g (and bearing) move the setpoint
    assert len(setpoints) >= 3
    venv.close()


@pytest.mark.parametrize("vec_env", ["dummy", "native"])
def test_the_probe_holds_the_speed_and_steps_the_damping_then_the_oracle_takes_over(vec_env):
    env_id, n = "gfb_env/RunUp-v2", 2
    venv = make_vec_env_for(env_id, n, 777, None, {"max_episode_steps": 6}, vec_env)
    teacher = OracleTeacher(env_id, n, probe=[[0.3, 2], [7.0, 1]])
    u = gym.make(env_id).unwrapped
    want_probe = [u.action_from_damping(0.3)] * 2 + [u.action_from_damping(7.0)]
    o = venv.reset()
    starts = np.ones(n, dtype=bool)
    k = 0
    for _ in range(9):  # an autoreset at step 6: the probe again
        teacher.plan_episodes(venv, np.flatnonzero(starts))
        label = teacher.act(o, None, starts)
        step = k % 6
        if step < 3:
            np.testing.assert_array_equal(label[:, 0], 0.0)
            np.testing.assert_allclose(label[:, 1], want_probe[step], atol=1e-6)
        else:  # the oracle's plan: its damping command, the ramp toward its setpoint
            np.testing.assert_allclose(label[:, 1], teacher.plan[:, 1], atol=1e-6)
            assert np.all(label[:, 0] > 0)
        o, _, dones, _ = venv.step(label)
        starts = np.asarray(dones, dtype=bool)
        k += 1
    assert k == 9 and teacher.k.tolist() == [3, 3]
    venv.close()


@pytest.mark.parametrize(
    "probe, fragment",
    [([[0.3]], "pairs"), ([[-1.0, 3]], "positive number"), ([[0.3, 0]], "positive integer")],
)
def test_a_bad_probe_is_refused_naming_oracle_probe(probe, fragment):
    with pytest.raises(ValueError, match=f"oracle_probe.*{fragment}"):
        OracleTeacher("gfb_env/RunUp-v2", 2, probe=probe)


def test_the_oracle_teacher_refuses_whirl_recovery_and_a_missing_env(tmp_path, capsys):
    with pytest.raises(ValueError, match="covers the run-up tasks"):
        ts.DistillConfig(teacher="oracle", env_id="gfb_env/WhirlRecovery-v2")
    with pytest.raises(ValueError, match="needs the task"):
        ts.DistillConfig(teacher="oracle")
    argv = ["--algo", "teacher_student", "--teacher", "oracle", "--out", str(tmp_path / "exp")]
    _refused(train_main, argv, "--teacher oracle needs --env ID", capsys, within_s=15.0)
    _refused(
        train_main,
        [*argv, "--env", "gfb_env/WhirlRecovery-v2"],
        "covers the run-up tasks",
        capsys,
        within_s=15.0,
    )
    assert not (tmp_path / "exp").exists()


def test_the_oracles_student_takes_its_statistics_from_the_first_iteration_resumes_and_deploys(
    tmp_path, monkeypatch
):
    env_id = "gfb_env/RunUp-v2"
    hs = load_hyperparams("teacher_student", env_id)
    hs.update(n_envs=2, steps_per_iteration=32, epochs=2, batch_size=16, history=3, hidden=[8])
    hp = tmp_path / "s.yml"
    hp.write_text(yaml.safe_dump({env_id: hs}))
    cfg = ts.DistillConfig(
        teacher="oracle",
        env_id=env_id,
        env_kwargs={"max_episode_steps": 8},
        damping_slew=0.028,
        timesteps=64,
        out=tmp_path / "s",
        hyperparams=hp,
        eval_episodes=1,
    )
    distill_killed_after_first_checkpoint(cfg, monkeypatch)
    out = tmp_path / "s"
    with open(out / "vecnormalize.pkl", "rb") as fh:
        vn = pickle.load(fh)
    # the statistics are those of the first iteration's observations (the oracle's own episodes),
    # replayed independently: same env seed, the oracle's labels under the same slew limit
    data = np.load(out / "checkpoints" / "iter_00001" / "data.npz")
    env_seed = seeds.train_env_seed(0, 0, 0)
    venv = make_vec_env_for(env_id, 2, env_seed, None, {"max_episode_steps": 8}, "native")
    venv = DampingSlewVecEnv(venv, 0.028, None)
    teacher = OracleTeacher(env_id, 2)
    o, starts, raws = venv.reset(), np.ones(2, bool), []
    for _ in range(16):
        teacher.plan_episodes(venv, np.flatnonzero(starts))
        raws.append(o.copy())
        o, _, d, _ = venv.step(teacher.act(o, None, starts))
        starts = np.asarray(d, bool)
    raw = np.concatenate(raws)
    np.testing.assert_allclose(vn.obs_rms.mean, raw.mean(0), rtol=1e-6, atol=1e-9)  # float32 rows
    np.testing.assert_allclose(vn.obs_rms.var, raw.var(0), rtol=1e-5, atol=1e-12)
    n_obs = raw.shape[1]
    x0 = data["x"][0]  # the first state: two zero frames, then the normalised first observation
    assert np.all(x0[: 2 * n_obs] == 0)
    want = np.clip((raw[0] - raw.mean(0)) / np.sqrt(raw.var(0) + 1e-8), -10, 10)
    np.testing.assert_allclose(x0[2 * n_obs :], want, rtol=0, atol=1e-4)  # float32 rows, small sds
    assert data["x"].shape == (32, 3 * n_obs)
    out = ts.distill(cfg)  # resumes: the statistics are read back, not recomputed
    meta = json.loads((out / "run.json").read_text())
    assert meta["teacher_kind"] == "oracle" and meta["damping_slew"] == 0.028 and meta["timesteps"] == 64
    assert [s["ended"] for s in meta["sessions"]] == ["killed", "finished"]
    with open(out / "vecnormalize.pkl", "rb") as fh:
        np.testing.assert_array_equal(pickle.load(fh).obs_rms.mean, vn.obs_rms.mean)
    pol = LearnedPolicy(out)
    assert isinstance(pol.model, DeployedActor) and pol.model.obs_dim == 3 * n_obs
    assert pol.damping_slew == 0.028
    res = run_episode(gym.make(env_id, max_episode_steps=4), pol, seed=seeds.VALIDATION.first(1)[0])
    assert res.steps == 4 and math.isfinite(res.episode_return)
    # exported, it says who taught it
    dest = export_policy(out, "oracle_student", root=tmp_path / "policies")
    exported = json.loads((dest / "policy.json").read_text())
    assert exported["teacher_kind"] == "oracle" and exported["teacher"] == "oracle"
    assert LearnedPolicy(dest).damping_slew == 0.028


def test_a_dropped_input_is_not_read_by_the_deployed_student(tmp_path):
    env_id = "gfb_env/RunUp-v2"
    hs = load_hyperparams("teacher_student", env_id)
    hs.update(n_envs=2, steps_per_iteration=16, epochs=2, batch_size=8, history=2, hidden=[8])
    hs["drop_inputs"] = ["damping"]
    hp = tmp_path / "s.yml"
    hp.write_text(yaml.safe_dump({env_id: hs}))
    kw = dict(teacher="oracle", env_id=env_id, env_kwargs={"max_episode_steps": 8}, timesteps=32)
    out = ts.distill(ts.DistillConfig(**kw, out=tmp_path / "s", hyperparams=hp, eval_episodes=1))
    actor = DeployedActor.load(out / "actor.pt")
    j = list(gym.make(env_id).unwrapped.observation_layout.names).index("damping")
    n_obs = actor.obs_dim // 2
    w = actor.policy_net[0].weight.detach().numpy()
    assert np.all(w[:, [j, n_obs + j]] == 0) and np.count_nonzero(w) > 0
    x = np.random.default_rng(0).normal(size=(4, actor.obs_dim)).astype(np.float32)
    y = x.copy()
    y[:, [j, n_obs + j]] += 5.0
    np.testing.assert_array_equal(actor.predict(x)[0], actor.predict(y)[0])
    hs["drop_inputs"] = ["no_such_entry"]
    hp.write_text(yaml.safe_dump({env_id: hs}))
    with pytest.raises(ValueError, match="drop_inputs"):
        ts.DistillConfig(**kw, out=tmp_path / "t", hyperparams=hp).plan()
