"""Tests of the agents: scripted baselines, SB3 training/saving/resuming, evaluator and the benchmark."""

from __future__ import annotations

import csv
import json
import math

import gymnasium as gym
import numpy as np
import pytest

from gfb_agents.evaluate import LearnedPolicy, run_episode, summarise
from gfb_agents.nominal_map import NominalMap
from gfb_agents.scripted import ControlSpec, MapInformedAgent, make_scripted_agents
from gfb_agents.train import TrainConfig, load_hyperparams, train
from gfb_agents.train import main as train_main
from gfb_env.envs import ENV_IDS

TASKS = ENV_IDS  # the task list has one owner
SHORT = 25  # control steps per test episode


def _make(task: str, **kw):
    return gym.make(task, max_episode_steps=SHORT, **kw)  # a task that cannot be built fails the test


@pytest.mark.parametrize("task", TASKS)
def test_every_baseline_completes_an_episode(task):
    env = _make(task)
    agents = make_scripted_agents(env)
    assert {"map_informed", "feedback", "damping_search"} <= set(agents)
    assert sum(n.startswith("paper_ramp_D") for n in agents) >= 3
    for name, agent in agents.items():
        res = run_episode(env, agent, seed=3)
        assert 1 <= res.steps <= SHORT, name
        assert math.isfinite(res.episode_return), name
        assert res.truncated or res.termination_reason is not None, name
    env.close()


def test_scripted_interface_batch_and_reset():
    env = gym.make("gfb_env/RunUp-v0")
    agent = make_scripted_agents(env)["feedback"]
    obs, _ = env.reset(seed=0)
    a1, state = agent.predict(obs, episode_start=True)
    assert a1.shape == (2,) and a1.dtype == np.float32 and state is None
    assert np.all(np.abs(a1) <= 1)
    batch, _ = agent.predict(np.stack([obs, obs]), episode_start=np.array([True, True]))
    assert batch.shape == (2, 2)
    np.testing.assert_array_equal(batch[0], batch[1])
    agent.reset()
    a2, _ = agent.predict(obs, episode_start=True)
    np.testing.assert_array_equal(a1, a2)
    env.close()


def test_map_informed_uses_the_nominal_optimum():
    env = gym.make("gfb_env/RunUp-v0")
    nmap = NominalMap.from_env(env)
    u = env.unwrapped
    assert nmap.lambda_best == pytest.approx(u.constants["lambda_best"])
    assert nmap.critical_at(nmap.d_opt) == pytest.approx(nmap.lambda_best)
    spec = ControlSpec.from_env(env, nmap)
    agent = MapInformedAgent(spec, nmap, margin=0.05)
    obs, _ = env.reset(seed=0)
    a, _ = agent.predict(obs, episode_start=True)
    assert u.damping_from_action(float(a[1])) == pytest.approx(nmap.d_opt, rel=1e-4)
    assert a[0] == pytest.approx(1.0)  # far below the set-point: full motor rate
    # the map-informed rule solves the nominal run-up
    res = run_episode(env, agent, seed=0)
    assert res.success and not res.touchdown
    env.close()


def _tiny_yaml(tmp_path, algo: str, env_id: str):
    hp = load_hyperparams(algo, env_id)
    if algo == "ppo":
        hp.update(n_steps=64, batch_size=32, n_epochs=2)
    else:
        hp.update(learning_starts=50, batch_size=32, buffer_size=2000, train_freq=4, gradient_steps=1)
    import yaml

    p = tmp_path / f"{algo}.yml"
    p.write_text(yaml.safe_dump({env_id: hp}))
    return p


def _train_quick(tmp_path, algo: str, out_name: str, **overrides):
    """``train`` on RunUp-v0 with the tiny hyperparameters, no progress bar, no TensorBoard."""
    env_id = "gfb_env/RunUp-v0"
    kwargs = dict(
        timesteps=256,
        seed=1,
        n_envs=1,
        out=tmp_path / out_name,
        hyperparams=_tiny_yaml(tmp_path, algo, env_id),
        eval_freq=10_000,
        eval_episodes=1,
        checkpoint_freq=10_000,
        progress_bar=False,
        tensorboard=False,
    )
    kwargs.update(overrides)
    return train(TrainConfig(algo, env_id, **kwargs))


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_train_save_reload_predictions_unchanged(tmp_path, algo):
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    env_id = "gfb_env/RunUp-v0"
    out = _train_quick(tmp_path, algo, "run", eval_freq=128, checkpoint_freq=128)
    for f in ("model.zip", "vecnormalize.pkl", "run.json", "learning_curve.png", "eval/evaluations.npz"):
        assert (out / f).exists(), f
    meta = json.loads((out / "run.json").read_text())
    assert meta["seed"] == 1 and meta["timesteps"] >= 256 and meta["algo"] == algo

    env = gym.make(env_id)
    obs = np.stack([env.reset(seed=s)[0] for s in range(4)])
    pol = LearnedPolicy(out)
    a1, _ = pol.predict(obs, deterministic=True)
    # reference: SB3's own loading path (model + VecNormalize.load on a venv)
    cls = {"ppo": PPO, "sac": SAC}[algo]
    model = cls.load(str(out / "model.zip"), device="cpu")
    vn = VecNormalize.load(str(out / "vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(env_id)]))
    vn.training = False
    a_ref, _ = model.predict(vn.normalize_obs(obs), deterministic=True)
    np.testing.assert_allclose(a1, a_ref, rtol=0, atol=1e-6)
    # save again, reload: identical predictions
    model.save(str(tmp_path / "again.zip"))
    a2, _ = cls.load(str(tmp_path / "again.zip"), device="cpu").predict(
        vn.normalize_obs(obs), deterministic=True
    )
    np.testing.assert_array_equal(a_ref, a2)
    # a learned policy plays an episode through the same evaluator as the scripted ones
    res = run_episode(gym.make(env_id, max_episode_steps=10), pol, seed=0)
    assert summarise([res])["episodes"] == 1
    env.close()


def test_resume_from_checkpoint(tmp_path):
    out = _train_quick(tmp_path, "ppo", "r", timesteps=128, seed=0, checkpoint_freq=128)
    ckpts = sorted((out / "checkpoints").glob("*_steps.zip"))
    assert (
        ckpts
        and (
            out
            / "checkpoints"
            / ckpts[-1].name.replace("_128_steps", "_vecnormalize_128_steps").replace(".zip", ".pkl")
        ).exists()
    )
    out2 = _train_quick(tmp_path, "ppo", "r", seed=0, resume=ckpts[-1])
    meta = json.loads((out2 / "run.json").read_text())
    assert meta["timesteps"] >= 256 and meta["resumed_from"].endswith(ckpts[-1].name)


def test_interrupted_training_is_saved_like_a_finished_run(tmp_path, monkeypatch):
    """Ctrl-C during learn(): model, statistics and run.json (interrupted, actual timesteps) are saved."""
    from stable_baselines3.common.callbacks import CheckpointCallback

    def interrupt_after_64_steps(self):
        if self.num_timesteps >= 64:
            raise KeyboardInterrupt
        return True

    monkeypatch.setattr(CheckpointCallback, "_on_step", interrupt_after_64_steps)
    env_id = "gfb_env/RunUp-v0"
    out = _train_quick(tmp_path, "sac", "run", eval_freq=1000, checkpoint_freq=1000)
    meta = json.loads((out / "run.json").read_text())
    assert meta["interrupted"] is True
    assert 64 <= meta["timesteps"] < 256
    assert (out / "model.zip").exists() and (out / "vecnormalize.pkl").exists()
    a, _ = LearnedPolicy(out).predict(gym.make(env_id).reset(seed=0)[0], deterministic=True)
    assert np.all(np.isfinite(a))


def _exit_2_one_line(main, argv, fragment, capsys):
    """``main(argv)`` exits with code 2 and one stderr line containing ``fragment``, nothing on stdout."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    out, err = capsys.readouterr()
    assert exc.value.code == 2, (argv, err)
    assert len(err.strip().splitlines()) == 1 and ": error: " in err and fragment in err, err
    assert out == ""


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["--algo", "dqn"], "argument --algo: invalid choice: 'dqn'"),
        (
            ["--algo", "ppo", "--env", "gfb_env/Nope-v0", "--timesteps", "10"],
            "unknown env id 'gfb_env/Nope-v0'",
        ),
        (["--algo", "ppo", "--timesteps", "-5"], "timesteps must be a positive integer, got -5"),
        (["--algo", "ppo", "--n-envs", "0"], "n_envs must be a positive integer"),
        (["--algo", "ppo", "--env-kwargs", "{not json"], "--env-kwargs is not valid JSON"),
        (["--algo", "ppo", "--env-kwargs", "[1]"], "--env-kwargs must be a JSON object"),
        (["--algo", "ppo", "--out", "{file}/run"], "--out"),
    ],
)
def test_train_cli_rejects_bad_arguments(capsys, tmp_path, argv, fragment):
    (tmp_path / "file.txt").write_text("")
    argv = [a.replace("{file}", str(tmp_path / "file.txt")) for a in argv]
    _exit_2_one_line(train_main, argv, fragment, capsys)


def test_benchmark_quick_writes_table_and_resumes_from_its_cache(tmp_path, capsys):
    from gfb_experiments.benchmark_agents import CACHE_DIR, COLUMNS, main

    tasks = "gfb_env/RunUp-v0,gfb_env/WhirlRecovery-v1"
    short = json.dumps({t: {"max_episode_steps": 12} for t in tasks.split(",")})
    args = ["--quick", "--out", str(tmp_path), "--no-learned", "--tasks", tasks, "--env-kwargs", short]
    assert main(args + ["--agents", "map_informed,feedback", "--reps", "200"]) == 0
    rows = list(csv.DictReader((tmp_path / "benchmark_agents.csv").open()))
    required = {
        "task",
        "agent",
        "kind",
        "split",
        "episodes",
        "training_seeds",
        "success_rate",
        "mean_return",
        "return_ci95",
        "normalized_score",
        "normalized_iqm",
        "normalized_ci_low",
        "normalized_ci_high",
        "touchdowns",
        "mean_cost",
        "mean_damping_change",
    }
    assert required <= set(rows[0]) and set(COLUMNS) == set(rows[0])
    # naive and oracle always run: they define the normalised score
    assert {(r["task"], r["agent"]) for r in rows} == {
        (t, a) for t in tasks.split(",") for a in ("naive", "map_informed", "feedback", "oracle")
    }
    assert {r["kind"] for r in rows} == {"naive", "rule", "oracle"}
    assert all(r["episodes"] == "2" and r["split"] == "test" for r in rows)
    for r in rows:
        if r["kind"] == "naive" and r["normalized_iqm"] != "":
            assert float(r["normalized_iqm"]) == 0.0
    assert "| task | agent |" in (tmp_path / "benchmark_agents.md").read_text()
    assert (tmp_path / "benchmark_agents_paths.png").stat().st_size > 10_000
    meta = json.loads((tmp_path / "benchmark_agents.json").read_text())
    assert meta["split"] == "test" and len(meta["rows"]) == len(rows)
    assert set(meta["tasks"]["gfb_env/RunUp-v0"]["agents"]) == {"naive", "map_informed", "feedback", "oracle"}
    cache = sorted((tmp_path / CACHE_DIR).rglob("*.json"))
    assert len(cache) == 2 * 2 * 4  # tasks x agents x one-seed chunks
    # a rerun plays nothing; a lost chunk (or one with another key) is played again
    capsys.readouterr()
    cache[0].unlink()
    assert main(args + ["--agents", "map_informed,feedback", "--reps", "200"]) == 0
    assert "(15 cached" in capsys.readouterr().err
    again = list(csv.DictReader((tmp_path / "benchmark_agents.csv").open()))
    assert [r["mean_return"] for r in again] == [r["mean_return"] for r in rows]
    # --merge replaces the rows of the agents it re-runs and keeps the others
    assert main(args + ["--merge", "--tasks", "gfb_env/RunUp-v0", "--agents", "map_informed"]) == 0
    rows2 = list(csv.DictReader((tmp_path / "benchmark_agents.csv").open()))
    assert len(rows2) == len(rows)
    assert sum(r["agent"] == "map_informed" and r["task"] == "gfb_env/RunUp-v0" for r in rows2) == 1


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["--episodes", "0"], "--episodes must be >= 1, got 0"),
        (["--tasks", "gfb_env/Nope-v0"], "unknown task 'gfb_env/Nope-v0'"),
        (["--n-jobs", "999"], "--n-jobs must be -1 or lie in"),
        (["--chunk", "0"], "--chunk must be >= 1"),
        (["--split", "train"], "argument --split: invalid choice"),
        (["--split", "legacy_v0", "--episodes", "51"], "the legacy_v0 split has only 50 seeds"),
        (["--env-kwargs", "{not json"], "--env-kwargs is not valid JSON"),
        (["--out", "{file}/bench"], "cannot create the folder"),
    ],
)
def test_benchmark_cli_rejects_bad_arguments(capsys, tmp_path, argv, fragment):
    from gfb_experiments.benchmark_agents import main

    (tmp_path / "file.txt").write_text("")
    argv = [a.replace("{file}", str(tmp_path / "file.txt")) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "bench")]
    _exit_2_one_line(main, argv, fragment, capsys)
    assert not (tmp_path / "bench").exists()


def test_committed_policies_load_and_act():
    from gfb_agents.evaluate import load_learned_policies

    pols = load_learned_policies()
    assert {p.env_id for p in pols} >= {"gfb_env/RunUpRandomized-v0", "gfb_env/WhirlRecovery-v0"}
    for pol in pols:
        env = gym.make(pol.env_id, max_episode_steps=5)
        assert pol.model.observation_space.shape == env.observation_space.shape, pol.name
        res = run_episode(env, pol, seed=0)
        assert res.steps >= 1 and math.isfinite(res.episode_return)
        env.close()


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"algo": "dqn"}, "algo"),
        ({"algo": "ppo", "env_id": "gfb_env/Nope-v0"}, "unknown env id"),
        ({"algo": "ppo", "timesteps": 0}, "timesteps"),
        ({"algo": "sac", "n_envs": 1.5}, "n_envs"),
        ({"algo": "sac", "eval_freq": 0}, "eval_freq"),
        ({"algo": "sac", "seed": -1}, "seed"),
        ({"algo": "sac", "env_kwargs": "x"}, "env_kwargs"),
    ],
)
def test_train_config_refuses_bad_fields_by_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        TrainConfig(**kwargs)
    cfg = TrainConfig("PPO", "gfb_env/RunUp-v0", out="runs/x")
    assert cfg.algo == "ppo" and cfg.task == "RunUp" and cfg.as_dict()["out"] == "runs/x"
