"""The training and benchmark CLIs as a new user meets them (issue 18, section 6, defects 6-9, 13, 14).

Every refusal: exit code 2 and one line on stderr, before any env is stepped or model trained.  The
``best/`` replacement and the resume arithmetic are checked with fake models or tiny real runs.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from gfb_agents.learned import train as train_mod
from gfb_agents.learned.train import MAX_FRAME_STACK, TrainConfig, load_hyperparams
from gfb_experiments.benchmark_agents import main as bench_main
from gfb_experiments.train import main as train_main

ENV = "gfb_env/RunUp-v2"
PROC_OUT = "/proc/nonexistent/x"  # the folder: check_output_dir lets root pass, mkdir fails


def _closed_port() -> int:
    """A local TCP port nothing listens on (bound once, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _refused(main, argv: list[str], fragment: str, capsys, within_s: float = 20.0) -> str:
    """``main(argv)`` ends with exit code 2 and one stderr line ``prog: error: ...`` holding
    ``fragment``, nothing on stdout, within ``within_s`` (no heavy work first); returns the line."""
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    took = time.perf_counter() - t0
    out, err = capsys.readouterr()
    lines = [x for x in err.splitlines() if x.strip()]
    assert code == 2, (argv, code, err)
    assert len(lines) == 1 and ": error: " in lines[0] and fragment in lines[0], err
    assert "Traceback" not in err and out == ""
    assert took < within_s, took
    return lines[0]


def _tiny_yaml(tmp_path: Path, algo: str = "ppo", **extra) -> Path:
    import yaml

    hp = load_hyperparams(algo, ENV)
    if algo == "ppo":
        hp.update(n_steps=16, batch_size=16, n_epochs=1, n_envs=1)
        hp["policy_kwargs"] = "dict(net_arch=dict(pi=[8], vf=[8]))"
    else:
        hp.update(learning_starts=20, batch_size=16, buffer_size=500, train_freq=4, gradient_steps=1)
        hp["policy_kwargs"] = "dict(net_arch=[8])"
    hp.update(extra)
    p = tmp_path / f"{algo}_tiny.yml"
    p.write_text(yaml.safe_dump({ENV: hp}))
    return p


# ------------------------------------------------------------------ train: refused up front (6, 7, 9)
def test_frame_stack_is_bounded(tmp_path, capsys):
    """Defect 6: ``--frame-stack 100000`` was accepted and allocated 6.9 GiB 23 s later."""
    with pytest.raises(ValueError, match=f"frame_stack must be at most {MAX_FRAME_STACK}"):
        TrainConfig("ppo", ENV, frame_stack=MAX_FRAME_STACK + 1)
    assert TrainConfig("ppo", ENV, frame_stack=MAX_FRAME_STACK).frame_stack == MAX_FRAME_STACK
    yml = _tiny_yaml(tmp_path)
    argv = ["--algo", "ppo", "--env", ENV, "--frame-stack", "100000", "--hyperparams", str(yml)]
    argv += ["--timesteps", "16", "--out", str(tmp_path / "run"), "--no-progress-bar", "--no-tensorboard"]
    _refused(train_main, argv, f"frame_stack must be at most {MAX_FRAME_STACK}", capsys)
    assert not (tmp_path / "run").exists()


def _write_run(folder: Path, config: dict, run_json: bool) -> None:
    """A run folder as a training session leaves it: a checkpoint (and run.json if it finished)."""
    ck = folder / "checkpoints" / "step_000000016"
    ck.mkdir(parents=True)
    (ck / "model.zip").write_bytes(b"not a model")
    state = {"dir": ck.name, "num_timesteps": 16, "session": 0, "wall_s": 1.0, "validation_wall_s": 0.0}
    if not run_json:
        state["config"] = config  # a killed first session: only its checkpoint knows its settings
    (folder / "checkpoints" / "latest.json").write_text(json.dumps(state))
    if run_json:
        (folder / "run.json").write_text(
            json.dumps({"config": config, "n_envs": config["n_envs"], "timesteps": 16, "interrupted": True})
        )


@pytest.mark.parametrize("run_json", [True, False], ids=["finished-session", "killed-session"])
def test_train_refuses_a_folder_holding_a_run_with_other_settings(tmp_path, capsys, run_json):
    """Defect 9: the refusal came from inside the run (exit 1); a killed first session (no run.json)
    was not checked at all."""
    yml = _tiny_yaml(tmp_path)
    cfg = TrainConfig("ppo", ENV, seed=0, n_envs=1, hyperparams=yml, out=tmp_path / "exp" / "seed0")
    _write_run(tmp_path / "exp" / "seed0", {**cfg.as_dict(), "n_envs": 1}, run_json)
    argv = ["--algo", "ppo", "--env", ENV, "--hyperparams", str(yml), "--n-envs", "2", "--timesteps", "32"]
    argv += ["--out", str(tmp_path / "exp"), "--no-progress-bar", "--no-tensorboard"]
    _refused(train_main, argv, "holds a run with other settings (n_envs)", capsys)


@pytest.mark.parametrize(
    "case, fragment",
    [
        ("yaml", "is not valid YAML at line 3"),  # defect 7: a yaml.ParserError traceback
        ("unknown-hyperparameter", "are not keyword arguments of PPO"),  # TypeError inside the run
        ("env-kwargs", "unknown environment argument 'bogus'"),  # defect 9: exit 1 inside the run
        ("out", f"--out {PROC_OUT}: cannot write"),  # defect 9: exit 1 inside the run
        ("scheduler", "no Dask scheduler answers there"),  # defect 7: traceback after 30 s
    ],
)
def test_train_refuses_before_any_run(tmp_path, capsys, case, fragment):
    yml = _tiny_yaml(tmp_path)
    out = tmp_path / "exp"
    argv = ["--algo", "ppo", "--env", ENV, "--timesteps", "16", "--no-progress-bar", "--no-tensorboard"]
    if case == "yaml":
        yml.write_text(f"{ENV}:\n  n_steps: [16, 32\n  gamma: 0.9\n")
    if case == "unknown-hyperparameter":
        yml = _tiny_yaml(tmp_path, n_step=16)
    argv += ["--hyperparams", str(yml)]
    if case == "env-kwargs":
        argv += ["--env-kwargs", '{"bogus": 1}']
    if case == "scheduler":
        argv += ["--scheduler", f"tcp://127.0.0.1:{_closed_port()}", "--seeds", "0-1"]
    argv += ["--out", PROC_OUT if case == "out" else str(out)]
    _refused(train_main, argv, fragment, capsys, within_s=15.0)
    assert not out.exists()


# ---------------------------------------------------------- benchmark: refused up front (7, 8)
def _bench(tmp_path: Path, *extra: str) -> list[str]:
    """A benchmark command that would be short even if it were not refused (one task, two steps)."""
    argv = ["--quick", "--no-learned", "--reps", "100", "--out", str(tmp_path / "bench")]
    if "--tasks" not in extra:
        argv += ["--tasks", ENV]
    if "--env-kwargs" not in extra:
        argv += ["--env-kwargs", json.dumps({ENV: {"max_episode_steps": 2}})]
    return argv + list(extra)


@pytest.mark.parametrize(
    "extra, fragment",
    [
        # defect 7
        (["--tasks", "CartPole-v1"], "--tasks: unknown task 'CartPole-v1'; known: gfb_env/"),
        (["--env-kwargs", json.dumps({ENV: {"bogus": 1}})], "unknown environment argument 'bogus'"),
        (["--out", PROC_OUT], f"--out {PROC_OUT}: cannot write"),
        # defect 8
        (
            ["--agents", "bogus"],
            "unknown agent 'bogus'; agents of the tasks: hold, margin_aim_1x, margin_aim_1x_05, "
            "margin_search",
        ),
        (["--agents", "recovery"], "'recovery' plays none of the tasks gfb_env/RunUp-v2"),
        (["--agents", ""], "--agents names nothing"),
        (["--agents", "naive,,oracle_v1"], "--agents has an empty name"),
        (["--tasks", ""], "--tasks names nothing"),
        (
            ["--env-kwargs", json.dumps({"gfb_env/Nope-v1": {}})],
            "--env-kwargs: unknown task 'gfb_env/Nope-v1'; known: gfb_env/",
        ),
        (  # a known task outside --tasks may have kwargs (one JSON for several runs), checked all the same
            ["--env-kwargs", json.dumps({ENV: {}, "gfb_env/WhirlRecovery-v2": {"max_episode_steps": -2}})],
            "--env-kwargs of gfb_env/WhirlRecovery-v2: Expect the `max_episode_steps` to be positive",
        ),
    ],
)
def test_benchmark_refuses_before_any_episode(tmp_path, capsys, extra, fragment):
    argv = _bench(tmp_path, *extra)
    _refused(bench_main, argv, fragment, capsys)
    assert not (tmp_path / "bench").exists()


@pytest.mark.parametrize("name", ["RunUp-v1_ppo_fs4", "naive"])
def test_benchmark_refuses_a_learned_run_named_as_a_registered_agent(tmp_path, capsys, name):
    """README's quickstart trained into runs/RunUp-v1_ppo_fs4 and passed it to --learned: the run took the
    committed policy's name and silently replaced it in the table it was meant to be compared with."""
    run = tmp_path / name / "seed0"
    run.mkdir(parents=True)
    (run / "model.zip").write_bytes(b"")
    (run / "run.json").write_text(json.dumps({"env_id": ENV}))
    argv = [a for a in _bench(tmp_path, "--learned", str(tmp_path / name)) if a != "--no-learned"]
    _refused(bench_main, argv, f"its name {name!r} is already", capsys)
    assert not (tmp_path / "bench").exists()


def test_benchmark_refuses_a_scheduler_that_does_not_answer(tmp_path, capsys):
    """Defect 7: Dask waited 30 s, then a traceback."""
    argv = _bench(tmp_path, "--scheduler", f"tcp://127.0.0.1:{_closed_port()}")
    line = _refused(bench_main, argv, "no Dask scheduler answers there", capsys, within_s=10.0)
    assert "127.0.0.1" in line
    _refused(
        bench_main, _bench(tmp_path, "--scheduler", "tcp://nohostport"), "expected tcp://host:port", capsys
    )


# ------------------------------------------------------------------------- best/ atomically (13)
class _FakeModel:
    """What ``_Session.validate`` asks of a model; ``save`` writes ``payload`` (a torn write, then an
    error, where ``fail``)."""

    def __init__(self, payload: bytes, steps: int, fail: bool = False):
        self.payload, self.num_timesteps, self.fail = payload, steps, fail

    def save(self, path: str) -> None:
        Path(path).write_bytes(self.payload[: len(self.payload) // 3])
        if self.fail:
            raise OSError(28, "No space left on device")
        Path(path).write_bytes(self.payload)

    def get_vec_normalize_env(self):
        return None


def test_a_failure_while_best_is_rewritten_keeps_the_old_best_whole(tmp_path, monkeypatch):
    """Defect 13: a kill while ``best/`` was rewritten left a torn ``best/model.zip`` beside the old
    ``best.json``.  Validation improves twice; the second save fails half-way: the first best stays."""
    import gfb_agents.learned.evaluate as evaluate_mod

    returns = iter([1.0, 2.0])
    monkeypatch.setattr(evaluate_mod.LearnedPolicy, "from_model", staticmethod(lambda *a, **k: None))
    monkeypatch.setattr(
        evaluate_mod,
        "evaluate",
        lambda *a, **k: [
            SimpleNamespace(
                episode_return=next(returns), success=False, touchdown=False, damping_command_change=0.0
            )
        ],
    )
    out = tmp_path / "run"
    out.mkdir()
    sess = train_mod._Session(TrainConfig("ppo", ENV, eval_episodes=1, out=out), out, 0, None, 64)
    sess.validate(_FakeModel(b"A" * 300, 16))
    best = out / "best"
    assert (best / "model.zip").read_bytes() == b"A" * 300
    with pytest.raises(OSError, match="No space"):
        sess.validate(_FakeModel(b"B" * 300, 32, fail=True))
    assert (best / "model.zip").read_bytes() == b"A" * 300
    record = json.loads((best / "best.json").read_text())
    assert record["timesteps"] == 16 and record["mean_return"] == 1.0
    # no half-written folder left beside it
    assert sorted(p.name for p in out.iterdir()) == ["best", "validation.json"]


def test_a_kill_between_the_renames_is_finished_on_resume(tmp_path):
    """A kill after ``best`` -> ``best.old`` and before ``best.new`` -> ``best``: the complete new best
    goes in place when the run resumes; a torn ``best.new`` (no record yet) is dropped."""
    out = tmp_path / "run"
    for name, payload in (("best.old", b"A"), ("best.new", b"B")):
        (out / name).mkdir(parents=True)
        (out / name / "model.zip").write_bytes(payload)
        (out / name / "best.json").write_text(json.dumps({"model": payload.decode()}))
    train_mod._Session(TrainConfig("ppo", ENV, eval_episodes=1, out=out), out, 1, None, 64)
    assert (out / "best" / "model.zip").read_bytes() == b"B"
    assert json.loads((out / "best" / "best.json").read_text()) == {"model": "B"}
    assert sorted(p.name for p in out.iterdir()) == ["best"]
    (out / "best.new").mkdir()
    (out / "best.new" / "model.zip").write_bytes(b"C")  # torn: killed before its best.json
    train_mod._Session(TrainConfig("ppo", ENV, eval_episodes=1, out=out), out, 2, None, 64)
    assert (out / "best" / "model.zip").read_bytes() == b"B" and not (out / "best.new").exists()


# ------------------------------------------------------------------ resume bookkeeping (14)
def _train_tiny(tmp_path: Path, algo: str = "ppo", **overrides) -> Path:
    """A tiny run on RunUp-v2 (8-step episodes, 16-step PPO rollouts, one env, an 8-unit net)."""
    kwargs = dict(
        timesteps=64,
        seed=0,
        n_envs=1,
        out=tmp_path / "run",
        hyperparams=_tiny_yaml(tmp_path, algo),
        env_kwargs={"max_episode_steps": 8},
        eval_freq=10_000,
        eval_episodes=1,
        checkpoint_freq=32,
        progress_bar=False,
        tensorboard=False,
    )
    kwargs.update(overrides)
    return train_mod.train(TrainConfig(algo, ENV, **kwargs))


def test_a_killed_session_keeps_its_record_in_run_json(tmp_path, monkeypatch):
    """Defect 14: after a kill (here: an error out of ``learn`` right after the first checkpoint, which
    leaves the folder as SIGKILL does) and a resume, ``run.json`` listed only the resumed session."""
    real = train_mod._Session.checkpoint

    def killed_after_first(self, model, *args, **kwargs):
        real(self, model, *args, **kwargs)
        raise RuntimeError("killed")

    monkeypatch.setattr(train_mod._Session, "checkpoint", killed_after_first)
    with pytest.raises(RuntimeError, match="killed"):
        _train_tiny(tmp_path)
    monkeypatch.undo()
    assert not (tmp_path / "run" / "run.json").exists()
    meta = json.loads((_train_tiny(tmp_path) / "run.json").read_text())
    assert meta["timesteps"] == 64
    s = meta["sessions"]
    assert [r["session"] for r in s] == [0, 1]  # the killed session kept its record
    assert [(r["session"], r["start_timesteps"], r["end_timesteps"], r["ended"]) for r in s] == [
        (0, 0, 32, "killed"),
        (1, 32, 64, "finished"),
    ]
    assert s[0]["env_seed"] != s[1]["env_seed"]


def test_sigkill_then_resume_lists_both_sessions(tmp_path):
    """Defect 14 as the issue met it: ``python -m gfb_experiments.train`` SIGKILLed after its first
    checkpoint, then the same command (with a total just past the checkpoint): ``run.json`` lists both
    sessions."""
    yml = _tiny_yaml(tmp_path)
    out = tmp_path / "exp"
    argv = ["--algo", "ppo", "--env", ENV, "--hyperparams", str(yml), "--checkpoint-freq", "32"]
    argv += ["--eval-freq", "100000", "--eval-episodes", "1", "--env-kwargs", '{"max_episode_steps": 8}']
    argv += ["--out", str(out), "--no-progress-bar", "--no-tensorboard"]
    latest = out / "seed0" / "checkpoints" / "latest.json"
    cmd = [
        sys.executable,
        "-m",
        "gfb_experiments.train",
        *argv,
        "--timesteps",
        "1000000",
    ]  # never finishes
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not latest.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        proc.send_signal(signal.SIGKILL)
        _, err = proc.communicate()
    assert latest.exists(), err.decode()[-2000:]
    assert not (out / "seed0" / "run.json").exists()
    n = json.loads(latest.read_text())["num_timesteps"]
    assert n >= 32 and n % 16 == 0  # PPO checkpoints on whole rollouts
    assert train_main([*argv, "--timesteps", str(n + 32)]) == 0
    meta = json.loads((out / "seed0" / "run.json").read_text())
    assert meta["timesteps"] == n + 32 and len(meta["sessions"]) == 2  # it was 1: the resumed one
    assert [(r["start_timesteps"], r["ended"]) for r in meta["sessions"]] == [(0, "killed"), (n, "finished")]


def test_ppo_resumed_after_ctrl_c_mid_rollout_ends_at_exactly_the_total(tmp_path, monkeypatch, capsys):
    """Defect 14: Ctrl-C inside a rollout, then a resume, trained 4 742 of ``--timesteps 4096`` steps
    (the resumed session collected whole rollouts from the interrupted count).  Here: 16-step rollouts,
    Ctrl-C at step 40 (inside the third), total 64.  Also: a total that is not a whole number of
    rollouts is rounded up to whole rollouts and said so."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    def on_step(self):
        if self.num_timesteps >= 40:
            raise KeyboardInterrupt
        return True

    monkeypatch.setattr(
        train_mod,
        "_tqdm_progress_callback",
        lambda total, done: type("CtrlC", (BaseCallback,), {"_on_step": on_step})(),
    )
    out = _train_tiny(tmp_path, checkpoint_freq=10_000, progress_bar=True)
    meta = json.loads((out / "run.json").read_text())
    assert meta["interrupted"] is True and meta["timesteps"] == 32  # the unfinished rollout is dropped
    assert train_mod.latest_checkpoint(out)["num_timesteps"] == 32
    monkeypatch.undo()
    out = _train_tiny(tmp_path, checkpoint_freq=10_000)
    meta = json.loads((out / "run.json").read_text())
    assert meta["timesteps"] == 64 and not meta["interrupted"]
    assert PPO.load(str(out / "model.zip"), device="cpu").num_timesteps == 64
    assert [(r["start_timesteps"], r["end_timesteps"], r["ended"]) for r in meta["sessions"]] == [
        (0, 32, "interrupted"),
        (32, 64, "finished"),
    ]
    # a total of 40 with 16-step rollouts: 48, said on stderr and recorded
    capsys.readouterr()
    meta = json.loads((_train_tiny(tmp_path, timesteps=40, out=tmp_path / "r40") / "run.json").read_text())
    assert "rounded up to 48" in capsys.readouterr().err
    assert (meta["requested_timesteps"], meta["total_timesteps"], meta["timesteps"]) == (40, 48, 48)


def test_ppo_checkpoints_fall_on_learnt_rollouts_and_resume_exactly(tmp_path, monkeypatch):
    """A periodic PPO checkpoint is taken where the weights have learnt from every counted step (the
    start of the next rollout), so a run killed after it resumes to exactly its total."""
    from stable_baselines3 import PPO

    real = train_mod._Session.checkpoint

    def killed_after_first(self, model, *args, **kwargs):
        real(self, model, *args, **kwargs)
        raise RuntimeError("killed")

    monkeypatch.setattr(train_mod._Session, "checkpoint", killed_after_first)
    with pytest.raises(RuntimeError, match="killed"):
        _train_tiny(tmp_path, checkpoint_freq=40)  # not a rollout boundary: the next one, 48
    monkeypatch.undo()
    assert train_mod.latest_checkpoint(tmp_path / "run")["num_timesteps"] == 48
    out = _train_tiny(tmp_path, timesteps=80, checkpoint_freq=40)
    assert PPO.load(str(out / "model.zip"), device="cpu").num_timesteps == 80


def test_sac_resumed_after_ctrl_c_ends_at_exactly_the_total(tmp_path, monkeypatch):
    """Off-policy: SAC collects ``train_freq`` (4) steps between updates; interrupted at 26 and resumed,
    it used to stop at the first multiple of 4 from 26 past the total (66); now exactly at 64."""
    from stable_baselines3.common.callbacks import BaseCallback

    def on_step(self):
        if self.num_timesteps >= 26:
            raise KeyboardInterrupt
        return True

    monkeypatch.setattr(
        train_mod,
        "_tqdm_progress_callback",
        lambda total, done: type("CtrlC", (BaseCallback,), {"_on_step": on_step})(),
    )
    out = _train_tiny(tmp_path, "sac", checkpoint_freq=10_000, progress_bar=True)
    assert json.loads((out / "run.json").read_text())["timesteps"] == 26
    monkeypatch.undo()
    meta = json.loads((_train_tiny(tmp_path, "sac", checkpoint_freq=10_000) / "run.json").read_text())
    assert meta["timesteps"] == 64 and [r["ended"] for r in meta["sessions"]] == ["interrupted", "finished"]


@pytest.mark.parametrize("module", ["gfb_experiments.train", "gfb_experiments.export_policy"])
def test_the_training_command_lines_live_in_experiments(module, capsys):
    """The training and export CLIs are experiments (the library halves stay in gfb_agents.learned,
    which has no command line): ``--help`` names the experiments module."""
    import importlib

    import gfb_agents.learned.export_policy as export_lib
    import gfb_agents.learned.train as train_lib

    with pytest.raises(SystemExit) as exc:
        importlib.import_module(module).main(["--help"])
    assert exc.value.code == 0 and f"python -m {module}" in capsys.readouterr().out
    assert not hasattr(train_lib, "main") and not hasattr(export_lib, "main")
