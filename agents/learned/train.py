"""Train Stable-Baselines3 agents (PPO, SAC, RecurrentPPO) on a gfb_env task, the way RL papers do.

The library half (rl-zoo3's ``ExperimentManager`` apart from its CLI): :class:`TrainConfig`,
:func:`train`, :func:`train_seeds`, :func:`check_runs`.  The command line is
``python -m gfb_experiments.train`` (:mod:`gfb_experiments.train`).

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` in rl-zoo3's layout (top-level keys are env
ids; besides the algorithm's keyword arguments the zoo's ``n_timesteps``, ``policy``, ``n_envs`` and
``normalize`` are understood; ``policy_kwargs`` may be a string like ``"dict(net_arch=[64, 64])"`` and
``learning_rate`` may be ``lin_3e-4`` for a linear schedule, as in the zoo).

Seeds (:mod:`gfb_agents.seeds`): independent training run ``r`` (``--seeds 0-4``: five runs) seeds
Python / NumPy / torch with ``r`` and resets training env ``i`` with ``train_env_seed(r, i, session)``
(inside the TRAIN range); model selection plays the first ``--eval-episodes`` VALIDATION seeds; the TEST
seeds are never touched here.  Memory: ``--algo recurrentppo`` (sb3-contrib's LSTM policy) or
``--frame-stack K`` (the last K observations, SB3's ``VecFrameStack``, K <= :data:`MAX_FRAME_STACK`) for PPO.
Privileged training (issue 21): ``--algo asymmetric_ppo`` (the critic also reads the episode's privileged
vector, :mod:`gfb_agents.learned.asymmetric`) and ``--algo privileged_ppo`` (the teacher of
:mod:`gfb_agents.learned.teacher_student`: actor and critic read it) train on the observation
``{"obs", "privileged"}`` (:class:`~gfb_agents.learned.vec_env.PrivilegedVecEnv` under VecNormalize and
VecFrameStack); validation plays the deployed actor on the plain observation (the teacher: handed the
episode's draws through ``privileged_info=True``).

Realisable actuation (issue 21): ``--damping-slew R`` makes the policy's damping action a set-point that the
command follows by at most ``R`` per control step (:mod:`gfb_agents.learned.slew`:
:class:`~gfb_agents.learned.vec_env.DampingSlewVecEnv` in training, the same transform in the deployed
:class:`~gfb_agents.learned.evaluate.LearnedPolicy`; ``damping_slew`` in ``run.json``; default off).

Each run lives in ``<out>/seed<r>`` (``--out`` default ``runs/<env>_<algo>``, gitignored)::

    model.zip, vecnormalize.pkl      final model and its observation-normalisation statistics
    best/                            model + statistics with the best validation mean return (model
                                     selection; what the benchmark plays), best.json
    validation.json                  every validation: steps, mean/std return, success, damping change
    checkpoints/step_<N>/, latest.json   the last --keep-checkpoints checkpoints: model, VecNormalize,
                                     SAC replay buffer, step count, wall time so far
    monitor/, tb/                    Monitor CSVs of the training envs, TensorBoard logs
    learning_curve.png, run.json     learning curve; command, seeds, steps, wall time, throughput (env
                                     steps/s, with and without validation), sessions, best validation

Resuming: rerunning the same command continues every run from its last checkpoint (a finished run is
skipped), so a killed or Ctrl-C'd sweep loses at most ``--checkpoint-freq`` steps per run; ``run.json``
lists every session (``"ended"``: ``finished``, ``interrupted`` or ``killed``: a session that ended without
its final save, whose steps after its last checkpoint were lost).  A run ends at exactly its total:
PPO / RecurrentPPO collect whole rollouts of ``n_steps * n_envs`` steps, so their total is rounded up to
whole rollouts when the run starts (as SB3 would train anyway; said on stderr, ``requested_timesteps`` in
``run.json``), their checkpoints fall on the first rollout boundary at or after each ``--checkpoint-freq``
steps (the weights have learnt from every step counted), and a Ctrl-C drops the unfinished rollout (the
count goes back to the last whole one).  ``best/`` is replaced as a whole (written beside it, synced,
renamed), so a kill leaves the old or the new best, never a mixture.  Bad arguments (env kwargs,
hyperparameters, an unwritable ``--out``, a folder holding a run with other settings, a scheduler that does
not answer) end the command with exit code 2 and one line before any run starts.  Several runs
train in parallel with joblib (``--n-jobs``) or on a Dask cluster (``--scheduler``; the workers need this
package and a shared ``--out``).
"""

from __future__ import annotations

import ast
import json
import os
import re
import shlex
import shutil
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from gfb_agents import HYPERPARAMS_DIR
from gfb_agents import seeds as seeds_mod
from gfb_agents.learned.evaluate import TEACHER_ALGO, algo_class
from gfb_agents.seeds import VALIDATION
from gfb_env import jsonio
from gfb_env._threads import set_thread_defaults
from gfb_env.scripting import check_output_dir
from gfb_env.sweeps import check_scheduler

__all__ = [
    "ALGOS",
    "TrainConfig",
    "latest_checkpoint",
    "train_seeds",
    "VEC_ENVS",
    "importable_env_id",
    "load_hyperparams",
    "make_vec_env_for",
    "train",
    "check_runs",
    "plot_learning_curve",
]

ALGOS = ("ppo", "sac", "recurrentppo", "asymmetric_ppo", "privileged_ppo")
#: the algorithms whose training observation holds the privileged vector (the asymmetric critic; the
#: teacher of :mod:`gfb_agents.learned.teacher_student`, actor and critic)
PRIVILEGED_INPUT_ALGOS = ("asymmetric_ppo", "privileged_ppo")
#: the longest ``--frame-stack``: 64 control steps is a quarter of the longest episode (250 steps) and
#: more history than identifying the bearing needs (the rules use a few steps); the memory grows as
#: ``n_steps * n_envs * k * obs_dim * 4`` bytes in PPO's rollout buffer (6.9 GiB at k = 100 000, 4.7 MB
#: at 64).  Longer memory: ``--algo recurrentppo``.
MAX_FRAME_STACK = 64
#: keys of the zoo files that are not algorithm keyword arguments
ZOO_KEYS = ("n_timesteps", "policy", "n_envs", "normalize", "env_wrapper", "frame_stack", "callback")


def _linear_schedule(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _eval_policy_kwargs(text: str) -> dict:
    """Evaluate a zoo-style ``policy_kwargs`` string with a restricted namespace (``dict``, ``nn``)."""
    import torch.nn as nn

    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise ValueError(f"policy_kwargs is not a Python expression: {text!r} ({exc.msg})") from None
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id not in ("dict", "nn", "True", "False", "None"):
            raise ValueError(f"policy_kwargs may only use dict(...) and nn.*, got name {node.id!r}")
    try:
        value = eval(compile(tree, "<policy_kwargs>", "eval"), {"__builtins__": {}}, {"dict": dict, "nn": nn})
    except Exception as exc:  # noqa: BLE001 - e.g. nn.NoSuchLayer, dict(1): one line naming the key
        raise ValueError(f"policy_kwargs {text!r}: {type(exc).__name__}: {exc}") from None
    if not isinstance(value, dict):
        raise ValueError(f"policy_kwargs must evaluate to a dict, got {value!r}")
    return value


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The hyperparameter block of ``env_id`` in the zoo-style YAML of ``algo`` (a fresh dict)."""
    p = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    if not p.exists():
        raise FileNotFoundError(f"no hyperparameter file {p}")
    if not p.is_file():
        raise ValueError(f"hyperparameter file {p} is not a regular file")
    try:
        table = yaml.safe_load(p.read_text()) or {}
    except yaml.YAMLError as exc:
        # PyYAML's message spans several lines (the problem, then the offending line with a caret)
        mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        why = problem or " ".join(str(exc).split())
        raise ValueError(f"{p} is not valid YAML{where}: {why}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read hyperparameter file {p}: {exc}") from None
    if not isinstance(table, dict):
        raise ValueError(f"{p} must map env ids to hyperparameter blocks, got a {type(table).__name__}")
    if env_id not in table:
        raise ValueError(f"{p} has no entry for {env_id!r}; known: {sorted(table)}")
    if not isinstance(table[env_id], dict):
        raise ValueError(f"{p}: the entry of {env_id!r} must be a mapping, got {table[env_id]!r}")
    return dict(table[env_id])


def _split_hyperparams(hp: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(zoo keys, algorithm kwargs) with the zoo's string conventions resolved."""
    zoo = {k: hp[k] for k in ZOO_KEYS if k in hp}
    kwargs = {k: v for k, v in hp.items() if k not in ZOO_KEYS}
    for key in ("learning_rate", "clip_range"):
        v = kwargs.get(key)
        if isinstance(v, str):
            m = re.fullmatch(r"lin_([0-9.eE+-]+)", v)
            if not m:
                raise ValueError(f"{key} must be a number or 'lin_<number>', got {v!r}")
            kwargs[key] = _linear_schedule(float(m.group(1)))
    if isinstance(kwargs.get("policy_kwargs"), str):
        kwargs["policy_kwargs"] = _eval_policy_kwargs(kwargs["policy_kwargs"])
    norm = zoo.get("normalize", False)
    if isinstance(norm, str):
        try:
            norm = ast.literal_eval(norm)
        except (ValueError, SyntaxError):
            raise ValueError(f"normalize must be a bool or a dict literal, got {norm!r}") from None
    if not isinstance(norm, (bool, dict)) and norm is not None:
        raise ValueError(f"normalize must be a bool or a dict, got {norm!r}")
    if norm is True:
        norm = {"norm_obs": True, "norm_reward": True}
    zoo["normalize"] = norm or {}
    return zoo, kwargs


VEC_ENVS = ("dummy", "subproc", "native")


def importable_env_id(env_id: str) -> str:
    """``env_id`` in gymnasium's ``"module:id"`` form for the gfb_env tasks (``"gfb_env:gfb_env/RunUp-v2"``).

    A worker process started by ``spawn``/``forkserver`` (SB3's ``SubprocVecEnv``) is a fresh interpreter
    that never imported gfb_env, so the plain id is unknown there (``NamespaceNotFound``) unless its main
    module is a file that imports gfb_env; with the module prefix ``gymnasium.make`` imports gfb_env, which
    registers the ids.  Other ids are returned unchanged."""
    if ":" not in env_id and env_id.startswith("gfb_env/"):
        return "gfb_env:" + env_id
    return env_id


def make_vec_env_for(
    env_id: str,
    n_envs: int,
    seed: int,
    monitor_dir: str | Path | None = None,
    env_kwargs: dict | None = None,
    vec_env: str = "native",
    num_processes: int = 1,
):
    """A vector env of ``n_envs`` Monitor-wrapped copies of ``env_id`` seeded ``seed, seed+1, ...``.

    ``vec_env="dummy"``: SB3's ``DummyVecEnv``, all copies in this process (the control step is
    a stiff integration in compiled code and the cores are few and shared; set ``n_envs`` to 1 or 2).
    ``vec_env="subproc"``: ``SubprocVecEnv``, one worker process per copy.  The workers get the id in the
    ``"module:id"`` form (:func:`importable_env_id`), so this works from ``python -c`` and stdin too, and
    one copy is made, reset and stepped here first so that numba compiles (or loads) the kernels once and
    writes its on-disk cache before the workers start: they load the kernels instead of compiling them
    all at once.
    ``vec_env="native"`` (default, issue 13): the task's native vector env (``gymnasium.make_vec``'s
    vector_entry_point, :class:`gfb_env.envs.vector.GFBVectorEnv`) behind SB3's API
    (:class:`gfb_agents.learned.vec_env.GFBSB3VecEnv`), the same bits as ``"dummy"``, with one ``VecMonitor``
    (``native.monitor.csv``) instead of one ``Monitor`` per copy; ``num_processes > 1`` puts its envs in
    that many worker processes (:mod:`gfb_env.envs.shards`; the same results)."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    import gfb_env.envs  # noqa: F401  (registers the ids)

    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}")
    if num_processes != 1 and vec_env != "native":
        raise ValueError(f"num_processes: only with vec_env='native', got {num_processes!r} with {vec_env!r}")
    env_kwargs = dict(env_kwargs or {})
    if vec_env == "native":
        from gfb_agents.learned.vec_env import GFBSB3VecEnv

        native = gym.make_vec(
            env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", num_processes=num_processes,
            **env_kwargs,
        )  # fmt: skip
        # one thread for the compiled plant stage: training runs go in parallel over the seeds (one per
        # core) and the learner's update shares the core; with a busy second core two threads were
        # slower than one (docs/envs.md, bench_env).  The results do not depend on it.
        native.unwrapped.num_threads = 1
        venv = VecMonitor(
            GFBSB3VecEnv(native.unwrapped),
            filename=str(Path(monitor_dir) / "native") if monitor_dir else None,
        )
        venv.seed(seed)
        return venv
    if vec_env == "subproc":
        warm = gym.make(env_id, **env_kwargs)
        warm.reset(seed=seed)
        warm.step(warm.action_space.sample())
        warm.close()
    return make_vec_env(
        importable_env_id(env_id) if vec_env == "subproc" else env_id,
        n_envs=n_envs,
        seed=seed,
        monitor_dir=str(monitor_dir) if monitor_dir else None,
        env_kwargs=env_kwargs,
        vec_env_cls=SubprocVecEnv if vec_env == "subproc" else DummyVecEnv,
    )


# ------------------------------------------------------------------------------ checkpoints, validation
def _atomic_write_json(path: Path, obj: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(jsonio.dumps(obj, indent=2))
    os.replace(tmp, path)


def _fsync_entries(folder: Path) -> None:
    """Flush ``folder``'s own entries (names) to disk: a rename is durable only once its folder is."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_folder(folder: Path) -> None:
    """Flush every file of ``folder`` and its entries to disk (before a pointer or a rename names it)."""
    for p in folder.iterdir():
        if p.is_file():
            with open(p, "rb") as fh:
                os.fsync(fh.fileno())
    _fsync_entries(folder)


#: the file a complete ``best/`` folder is written with last (its presence in ``best.new`` marks it done)
BEST_RECORD = "best.json"


def _recover_best(best: Path) -> None:
    """Finish or undo a ``best/`` replacement that a kill interrupted (see :func:`_replace_best`).

    ``best.new`` holding :data:`BEST_RECORD` is complete (the record is written last); without it, it is a
    torn write and is dropped.  ``best.old`` is the previous best, removed once ``best/`` is in place."""
    new, old = best.with_name(best.name + ".new"), best.with_name(best.name + ".old")
    if not best.exists():
        if (new / BEST_RECORD).exists():
            os.rename(new, best)  # killed between the two renames: the new best is complete
        elif old.exists():
            os.rename(old, best)  # (not reached by _replace_best's order; a hand-made state)
    for p in (new, old):
        if p.exists():
            shutil.rmtree(p, ignore_errors=True)


def _replace_best(best: Path, write) -> None:
    """Replace the folder ``best`` by what ``write(folder)`` puts in a fresh folder beside it, as one step.

    Linux cannot rename a folder onto a non-empty one, so: write ``best.new`` (``write``, then
    :data:`BEST_RECORD` must be its last file), fsync it, rename ``best`` -> ``best.old`` and
    ``best.new`` -> ``best``, remove ``best.old``.  A failure or kill while writing leaves the old ``best``
    untouched; a kill between the renames leaves a complete ``best.new`` that :func:`_recover_best` puts in
    place.  ``best/model.zip`` and ``best/best.json`` therefore always belong together."""
    _recover_best(best)
    new, old = best.with_name(best.name + ".new"), best.with_name(best.name + ".old")
    new.mkdir()
    try:
        write(new)
        if not (new / BEST_RECORD).exists():
            raise RuntimeError(f"_replace_best: {BEST_RECORD} was not written")
        _fsync_folder(new)
    except BaseException:
        shutil.rmtree(new, ignore_errors=True)
        raise
    if best.exists():
        os.rename(best, old)
    os.rename(new, best)
    _fsync_entries(best.parent)
    shutil.rmtree(old, ignore_errors=True)


def latest_checkpoint(out: str | Path) -> dict | None:
    """The state of the run's last complete checkpoint (``checkpoints/latest.json``: ``num_timesteps``,
    ``session``, ``dir``, cumulative ``wall_s`` ...), or None.  The pointer is written last and atomically,
    so a run killed while saving falls back to the checkpoint before."""
    p = Path(out) / "checkpoints" / "latest.json"
    if not p.exists():
        return None
    try:
        state = json.loads(p.read_text())
    except json.JSONDecodeError:
        return None
    d = Path(out) / "checkpoints" / state["dir"]
    return state if (d / "model.zip").exists() else None


def _tqdm_progress_callback(total: int, done: int):
    """A tqdm progress bar over environment steps (SB3's own ``progress_bar=True`` needs ``rich``, which
    is not a dependency of this project)."""
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class TqdmProgress(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=total, initial=done, desc="training", unit="step", dynamic_ncols=True)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return TqdmProgress()


class _Session:
    """Book-keeping of one (re)start of a training run: wall time so far, validation history and best,
    checkpoint saving.  Shared by the callbacks."""

    def __init__(
        self,
        config: TrainConfig,
        out: Path,
        session: int,
        prior: dict | None,
        total: int,
        env_seed: int | None = None,
        previous_sessions: list[dict] | None = None,
        on_policy: bool = False,
        run_config: dict | None = None,
    ):
        self.c, self.out, self.session, self.total = config, out, session, total
        self.t0 = time.perf_counter()
        self.wall_before = float(prior["wall_s"]) if prior else 0.0
        self.val_wall_before = float(prior["validation_wall_s"]) if prior else 0.0
        self.val_wall = 0.0
        self.start_step = int(prior["num_timesteps"]) if prior else 0
        self.env_seed = env_seed
        self.previous_sessions = list(previous_sessions or [])
        # PPO / RecurrentPPO learn from whole rollouts: the step count the weights have learnt from (the
        # count at the start of the rollout being collected); a Ctrl-C goes back to it
        self.on_policy = on_policy
        self.trained_steps = self.start_step
        self.run_config = run_config
        _recover_best(out / "best")  # a kill while best/ was replaced: finish (or undo) it first
        vp = out / "validation.json"
        self.validation = (
            json.loads(vp.read_text()) if (prior and vp.exists()) else {"history": [], "best": None}
        )
        self.validation["seeds"] = VALIDATION.first(config.eval_episodes)

    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.t0

    def validation_wall(self) -> float:
        return self.val_wall_before + self.val_wall

    def sessions(self, steps: int, ended: str) -> list[dict]:
        """Every session's record so far: the earlier ones and this one up to ``steps`` (``ended``:
        ``"running"`` in a checkpoint, ``"finished"`` or ``"interrupted"`` at the end; a resumed run turns
        a ``"running"`` it finds into ``"killed"``)."""
        return [
            *self.previous_sessions,
            {
                "session": self.session,
                "env_seed": self.env_seed,
                "start_timesteps": self.start_step,
                "end_timesteps": int(steps),
                "wall_time_s": round(time.perf_counter() - self.t0, 1),
                "ended": ended,
            },
        ]

    def log(self, model, what: str) -> None:
        steps = int(model.num_timesteps)
        sps = (steps - self.start_step) / max(1e-9, time.perf_counter() - self.t0)
        best = self.validation["best"]
        b = f", best validation {best['mean_return']:.2f} at {best['timesteps']}" if best else ""
        print(
            f"[{self.c.env_id} {self.c.algo} run {self.c.seed}] {steps}/{self.total} steps, "
            f"{sps:.0f} steps/s this session{b} ({what})",
            file=sys.stderr,
            flush=True,
        )

    def validate(self, model) -> dict:
        """Play the validation seeds with the current policy (deterministic, frozen normalisation) through
        the benchmark's own episode loop; keep the best model in ``best/``."""
        from gfb_agents.learned.evaluate import LearnedPolicy, evaluate

        t = time.perf_counter()
        env_kwargs = self.c.env_kwargs
        if self.c.algo == TEACHER_ALGO:
            # the teacher acts on the privileged vector: handed the hidden draws by the opt-in channel
            from gfb_agents.learned.teacher_student import TeacherPolicy

            pol = TeacherPolicy(
                model,
                model.get_vec_normalize_env(),
                self.c.frame_stack,
                name="validation",
                damping_slew=self.c.damping_slew,
                damping_slew_reserve=self.c.damping_slew_reserve,
            )
            env_kwargs = {**env_kwargs, "privileged_info": True}
        else:
            pol = LearnedPolicy.from_model(
                model,
                self.c.algo,
                model.get_vec_normalize_env(),
                self.c.frame_stack,
                name="validation",
                damping_slew=self.c.damping_slew,
                damping_slew_reserve=self.c.damping_slew_reserve,
            )
        res = evaluate(self.c.env_id, pol, self.validation["seeds"], env_kwargs=env_kwargs)
        rets = np.array([r.episode_return for r in res])
        rec = {
            "timesteps": int(model.num_timesteps),
            "mean_return": float(rets.mean()),
            "std_return": float(rets.std()),
            "success_rate": float(np.mean([r.success for r in res])),
            "touchdowns": int(sum(r.touchdown for r in res)),
            "mean_damping_change": float(np.mean([r.damping_command_change for r in res])),
            # for learning curves against wall time (the run's wall time so far, this validation
            # excluded) and for statistics over the episodes of one validation
            "wall_time_s": round(self.wall() - (time.perf_counter() - t), 2),
            "returns": [float(x) for x in rets],
        }
        self.validation["history"].append(rec)
        best = self.validation["best"]
        if best is None or rec["mean_return"] > best["mean_return"]:
            self.save_best(model, rec)
            self.validation["best"] = rec
        self.val_wall += time.perf_counter() - t
        _atomic_write_json(self.out / "validation.json", self.validation)
        return rec

    def save_best(self, model, rec: dict) -> None:
        """``best/``: the model, its VecNormalize and ``best.json`` (``rec``), replaced as a whole
        (:func:`_replace_best`): a failure or kill while saving keeps the previous best intact."""

        def write(folder: Path) -> None:
            model.save(str(folder / "model.zip"))
            vn = model.get_vec_normalize_env()
            if vn is not None:
                vn.save(str(folder / "vecnormalize.pkl"))
            _atomic_write_json(folder / BEST_RECORD, {**rec, "validation_seeds": self.validation["seeds"]})

        _replace_best(self.out / "best", write)

    def checkpoint(self, model, ended: str = "running") -> None:
        """Model, VecNormalize, SAC replay buffer, the step count and the session records in
        ``checkpoints/step_<N>/``, synced, then the pointer ``latest.json``; older checkpoints beyond
        ``keep_checkpoints`` are deleted.  A folder of the same step (a Ctrl-C'd PPO run goes back to
        its last checkpointed rollout) gets a suffix: the folder the pointer names is never rewritten."""
        n = int(model.num_timesteps)
        root = self.out / "checkpoints"
        d = root / f"step_{n:09d}"
        k = 0
        while d.exists():
            k += 1
            d = root / f"step_{n:09d}_{k}"
        d.mkdir(parents=True)
        model.save(str(d / "model.zip"))
        vn = model.get_vec_normalize_env()
        if vn is not None:
            vn.save(str(d / "vecnormalize.pkl"))
        if hasattr(model, "save_replay_buffer"):
            model.save_replay_buffer(str(d / "replay_buffer.pkl"))
        state = {
            "dir": d.name,
            "num_timesteps": n,
            "session": self.session,
            "wall_s": self.wall(),
            "validation_wall_s": self.validation_wall(),
            # kept here, not only in run.json (written at the end): a killed session's record survives
            "sessions": self.sessions(n, ended),
            "config": self.run_config,
        }
        _atomic_write_json(d / "state.json", state)
        _fsync_folder(d)
        _atomic_write_json(root / "latest.json", state)
        old = sorted(p for p in root.glob("step_*") if p.is_dir() and p.name != d.name)
        for p in old[: max(0, len(old) - (self.c.keep_checkpoints - 1))]:
            shutil.rmtree(p, ignore_errors=True)


def _completes_collection(loc: dict) -> bool:
    """Whether the env step SB3 just reported (its ``collect_rollouts`` locals ``loc``) completes what it
    learns from next: the rollout of ``n_steps`` (on-policy) or the ``train_freq`` collection (off-policy)."""
    if "n_rollout_steps" in loc:  # on-policy: n_steps counts the rollout's steps before this one
        return loc["n_steps"] + 1 >= loc["n_rollout_steps"]
    tf = loc.get("train_freq")
    if tf is None:
        return True  # a loop of another shape: never cut it
    from stable_baselines3.common.type_aliases import TrainFrequencyUnit

    if tf.unit == TrainFrequencyUnit.STEP:
        return loc["num_collected_steps"] >= tf.frequency
    return loc["num_collected_episodes"] + int(np.sum(loc["dones"])) >= tf.frequency


def _session_callback(sess: _Session, total: int):
    """Validation every ``eval_freq`` and a checkpoint every ``checkpoint_freq`` env steps (validation
    first, so a checkpoint's validation history is complete); the run stops at exactly ``total`` steps.

    Off-policy (SAC) checkpoints at the step; on-policy (PPO, RecurrentPPO) ones at the start of the first
    rollout at or after it, when the weights have learnt from every step counted (mid-rollout the
    collected steps are not learnt yet, and a run resumed there would end past its total by up to one
    rollout).  A collection that would run past ``total`` (a resumed SAC run; a checkpoint of an earlier
    version) is cut at ``total``: its steps are not learnt from."""
    from stable_baselines3.common.callbacks import BaseCallback

    c = sess.c

    class SessionCallback(BaseCallback):
        def _on_training_start(self) -> None:
            n = int(self.model.num_timesteps)
            self.next_val = (n // c.eval_freq + 1) * c.eval_freq
            self.next_ckpt = (n // c.checkpoint_freq + 1) * c.checkpoint_freq

        def _checkpoint(self, n: int) -> None:
            sess.checkpoint(self.model)
            self.next_ckpt = (n // c.checkpoint_freq + 1) * c.checkpoint_freq
            sess.log(self.model, "checkpoint")

        def _on_rollout_start(self) -> None:
            n = int(self.model.num_timesteps)
            sess.trained_steps = n  # after the update of the previous rollout
            if sess.on_policy and n >= self.next_ckpt:
                self._checkpoint(n)

        def _on_step(self) -> bool:
            n = int(self.model.num_timesteps)
            if n >= self.next_val:
                sess.validate(self.model)
                self.next_val = (n // c.eval_freq + 1) * c.eval_freq
                sess.log(self.model, "validated")
            if not sess.on_policy and n >= self.next_ckpt:
                self._checkpoint(n)
            return n < total or _completes_collection(self.locals)

    return SessionCallback()


def _check_count(name: str, v: Any, allow_none: bool = False) -> None:
    if v is None and allow_none:
        return
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ValueError(f"{name} must be a positive integer, got {v!r}")


@dataclass(frozen=True)
class TrainConfig:
    """One training run, validated when made (every field is a ``python -m gfb_experiments.train`` option).

    Attributes:
        algo: ``"ppo"``, ``"sac"`` or ``"recurrentppo"`` (sb3-contrib, an LSTM policy: memory).
        env_id: a registered ``gfb_env/...`` id.
        timesteps: total env steps of the run (None: ``n_timesteps`` of the YAML).
        seed: the independent training run ``r`` (0, 1, ...): seeds Python, NumPy and torch with ``r``;
            training env ``i`` of session ``k`` is reset with ``gfb_agents.seeds.train_env_seed(r, i, k)``.
        n_envs: parallel training envs (None: the YAML's ``n_envs``).
        out: the run's directory (None: ``runs/<env>_<algo>/seed<r>``).
        hyperparams: zoo-style YAML (None: ``hyperparams/<algo>.yml`` of the package).
        env_kwargs: keyword arguments of ``gymnasium.make``.
        eval_freq: env steps between validations (on the first ``eval_episodes`` validation seeds; the
            best is kept in ``best/``).
        eval_episodes: validation episodes per validation.
        checkpoint_freq: env steps between checkpoints (model, VecNormalize, SAC replay buffer, step).
        keep_checkpoints: checkpoints kept on disk (the newest; SAC's replay buffer is large).
        frame_stack: stack the last ``k`` observations (SB3 ``VecFrameStack``; 1 = none, at most
            :data:`MAX_FRAME_STACK`): memory for PPO.
        progress_bar, tensorboard, verbose: output.
        torch_threads: torch CPU threads (1: the env is the bottleneck and cores are shared).
        privileged_quantities: ``asymmetric_ppo`` only: the step-varying true quantities appended to the
            critic's privileged vector (:data:`gfb_agents.learned.privileged.STEP_QUANTITIES`; the training
            envs are then made with ``privileged_info=True``); the episode's draws are always in it.
        vec_env: ``"native"`` (default), ``"dummy"`` or ``"subproc"`` for the training envs
            (:func:`make_vec_env_for`).
        num_processes: the native vector env's worker processes (1: none; :mod:`gfb_env.envs.shards`).
            The results do not depend on it, so a run may resume with another value.
        damping_slew: the slew limit ``r`` of the damping command (action units per control step, in
            ``(0, 2]``; None: none): the policy's damping action is a set-point that the command follows
            by at most ``r`` per step (:mod:`gfb_agents.learned.slew`), in training and in the deployed
            policy, so the benchmark's ``mean_damping_change`` is at most ``r`` by construction.
        damping_slew_reserve: with ``damping_slew``: the unused allowance (action units, in ``(0, 2]``)
            a step may save for a later one (a token bucket: the moves of steps ``0..k`` sum to at most
            ``(k + 1) r``, so a policy that holds the damping may jump as the rules do); None: none.
    """

    algo: str
    env_id: str = "gfb_env/RunUpRandomized-v2"
    timesteps: int | None = None
    seed: int = 0
    n_envs: int | None = None
    out: Path | None = None
    hyperparams: Path | None = None
    env_kwargs: dict = field(default_factory=dict)
    eval_freq: int = 20_000
    eval_episodes: int = 20
    checkpoint_freq: int = 20_000
    keep_checkpoints: int = 2
    frame_stack: int = 1
    progress_bar: bool = True
    tensorboard: bool = True
    verbose: int = 0
    torch_threads: int = 1
    vec_env: str = "native"
    privileged_quantities: tuple[str, ...] = ()
    num_processes: int = 1
    damping_slew: float | None = None
    damping_slew_reserve: float | None = None

    def __post_init__(self) -> None:
        algo = str(self.algo).lower()
        if algo not in ALGOS:
            raise ValueError(f"algo must be one of {ALGOS}, got {self.algo!r}")
        object.__setattr__(self, "algo", algo)
        from gfb_env.envs import RETIRED_IDS, RetiredTaskError
        from gfb_env.envs.retired import retired_message

        if self.env_id in RETIRED_IDS:  # before any work: why, and the id to train on instead
            raise RetiredTaskError(f"env_id: {retired_message(self.env_id)}")
        if self.env_id not in gym.registry:
            raise ValueError(
                f"unknown env id {self.env_id!r}; registered gfb_env ids: "
                f"{sorted(k for k in gym.registry if k.startswith('gfb_env/'))}"
            )
        _check_count("timesteps", self.timesteps, allow_none=True)
        _check_count("n_envs", self.n_envs, allow_none=True)
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < seeds_mod.MAX_TRAIN_RUNS
        ):
            raise ValueError(f"seed must be an integer in [0, {seeds_mod.MAX_TRAIN_RUNS}), got {self.seed!r}")
        for name in ("eval_freq", "eval_episodes", "checkpoint_freq", "torch_threads", "keep_checkpoints"):
            _check_count(name, getattr(self, name))
        _check_count("frame_stack", self.frame_stack)
        if self.frame_stack > MAX_FRAME_STACK:
            raise ValueError(
                f"frame_stack must be at most {MAX_FRAME_STACK} control steps, got {self.frame_stack} (its "
                f"memory grows as n_steps x n_envs x frame_stack x obs_dim; longer memory: recurrentppo)"
            )
        if self.frame_stack > 1 and algo == "recurrentppo":
            raise ValueError("frame_stack and recurrentppo exclude each other (the LSTM is the memory)")
        if self.frame_stack > 1 and algo == "sac":
            # SAC's replay buffer stores VecNormalize's original observations, which lie inside the
            # frame stack (unstacked): the first stored transition failed on a shape mismatch
            raise ValueError(
                "frame_stack: not with sac (its replay buffer stores the unstacked original "
                "observations); memory: --algo recurrentppo, or ppo with --frame-stack"
            )
        if self.n_envs is not None and self.n_envs > seeds_mod.MAX_TRAIN_ENVS:
            raise ValueError(f"n_envs must be at most {seeds_mod.MAX_TRAIN_ENVS}, got {self.n_envs}")
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {self.vec_env!r}")
        _check_count("num_processes", self.num_processes)
        if self.num_processes != 1 and self.vec_env != "native":
            raise ValueError(
                f"num_processes: only with vec_env='native', got {self.num_processes} with {self.vec_env!r}"
            )
        for name in ("out", "hyperparams"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, Path(v))
        from gfb_agents.learned.privileged import check_quantities

        if isinstance(self.privileged_quantities, str):
            raise ValueError("privileged_quantities must be a sequence of names, not a string")
        object.__setattr__(self, "privileged_quantities", check_quantities(self.privileged_quantities))
        if self.privileged_quantities and algo != "asymmetric_ppo":
            # the teacher's validation hands it the episode's draws only (TeacherPolicy)
            raise ValueError(f"privileged_quantities: only with asymmetric_ppo, not {algo}")
        if self.env_kwargs is None:
            object.__setattr__(self, "env_kwargs", {})
        elif not isinstance(self.env_kwargs, dict):
            raise ValueError(f"env_kwargs must be a dict, got {type(self.env_kwargs).__name__}")
        if self.env_kwargs.get("privileged_info"):
            # the validation env is made from env_kwargs: it must be the public interface
            raise ValueError("env_kwargs: privileged_info is set by the training command, not here")
        from gfb_agents.learned.slew import check_damping_slew, check_damping_slew_reserve

        object.__setattr__(self, "damping_slew", check_damping_slew(self.damping_slew))
        reserve = check_damping_slew_reserve(self.damping_slew_reserve, self.damping_slew)
        object.__setattr__(self, "damping_slew_reserve", reserve)

    @property
    def task(self) -> str:
        """``RunUp`` of ``gfb_env/RunUp-v2``."""
        return self.env_id.split("/")[-1].split("-v")[0]

    @property
    def experiment_name(self) -> str:
        """``RunUp-v2_ppo`` (``_fs4`` with a frame stack of 4): the default folder of the runs."""
        fs = f"_fs{self.frame_stack}" if self.frame_stack > 1 else ""
        slew = f"_slew{self.damping_slew:g}" if self.damping_slew is not None else ""
        if self.damping_slew_reserve is not None:
            slew += f"r{self.damping_slew_reserve:g}"
        return f"{self.env_id.split('/')[-1]}_{self.algo}{fs}{slew}"

    def run_dir(self) -> Path:
        return self.out if self.out is not None else Path("runs") / self.experiment_name / f"seed{self.seed}"

    def as_dict(self) -> dict[str, Any]:
        return {
            k: (str(v) if isinstance(v, Path) else list(v) if isinstance(v, tuple) else v)
            for k, v in asdict(self).items()
        }


def _comparable(cfg: dict) -> dict:
    """The fields a resumed run must share with the run it continues."""
    keep = ("algo", "env_id", "seed", "env_kwargs", "frame_stack", "hyperparams", "vec_env", "n_envs")
    out = {k: cfg.get(k) for k in keep}
    # asymmetric_ppo's critic input; absent from the records of runs before it (the same as none)
    out["privileged_quantities"] = list(cfg.get("privileged_quantities") or [])
    # the damping command's slew limit (part of the policy); absent from earlier records: none
    out["damping_slew"] = cfg.get("damping_slew")
    out["damping_slew_reserve"] = cfg.get("damping_slew_reserve")
    return out


def _rollout_size(algo: str, kwargs: dict[str, Any], n_envs: int) -> int | None:
    """Env steps per rollout (``n_steps * n_envs``) of an on-policy algorithm, None for SAC."""
    import inspect

    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    cls = algo_class(algo)
    if not issubclass(cls, OnPolicyAlgorithm):
        return None
    n_steps = kwargs.get("n_steps", inspect.signature(cls.__init__).parameters["n_steps"].default)
    _check_count("n_steps", n_steps)
    return int(n_steps) * n_envs


def _run_plan(c: TrainConfig) -> tuple[dict, dict, dict, int, int, int]:
    """``(hyperparameters, zoo keys, algorithm kwargs, requested total, total, n_envs)`` of run ``c``,
    checked (ValueError): the total is rounded up to whole rollouts for PPO / RecurrentPPO (SB3 collects
    whole rollouts; the run then ends at exactly its total, also when resumed)."""
    import inspect

    hp = load_hyperparams(c.algo, c.env_id, c.hyperparams)
    zoo, kwargs = _split_hyperparams(hp)
    requested = zoo.get("n_timesteps", 100_000) if c.timesteps is None else c.timesteps
    n_envs = zoo.get("n_envs", 1) if c.n_envs is None else c.n_envs
    for name, v in (("timesteps (n_timesteps)", requested), ("n_envs", n_envs)):
        if isinstance(v, float) and v.is_integer():
            v = int(v)  # YAML's 3e5 is a float
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    requested, n_envs = int(requested), int(n_envs)
    if not 1 <= n_envs <= seeds_mod.MAX_TRAIN_ENVS:
        raise ValueError(f"n_envs must lie in [1, {seeds_mod.MAX_TRAIN_ENVS}], got {n_envs}")
    params = inspect.signature(algo_class(c.algo).__init__).parameters
    unknown = sorted(k for k in kwargs if k not in params)
    if unknown:
        raise ValueError(
            f"hyperparameters {unknown} are not keyword arguments of {algo_class(c.algo).__name__} "
            f"(nor zoo keys {list(ZOO_KEYS)})"
        )
    own = sorted(k for k in kwargs if k in ("self", "env", "seed", "device", "verbose", "tensorboard_log"))
    if own:
        raise ValueError(f"hyperparameters {own} are set by the training command, not the YAML")
    _policy_class(c.algo, zoo)  # a policy the algorithm cannot take: refused before any run starts
    rollout = _rollout_size(c.algo, kwargs, n_envs)
    total = requested if rollout is None else -(-requested // rollout) * rollout
    return hp, zoo, kwargs, requested, total, n_envs


def _check_same_settings(c: TrainConfig, n_envs: int) -> tuple[dict | None, dict | None]:
    """``(last checkpoint, run.json)`` of run ``c``'s folder; ValueError if they hold a run with other
    settings (algo, env, seed, env kwargs, frame stack, hyperparameter file, vec env, n_envs)."""
    out = c.run_dir()
    prior = latest_checkpoint(out)
    try:
        prev_run = json.loads((out / "run.json").read_text()) if (out / "run.json").is_file() else None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{out / 'run.json'} cannot be read ({exc}); use another --out") from None
    if prior is not None:
        # the checkpoint's own record (since issue 18), else the run.json of an earlier session
        have_cfg = prior.get("config") or (
            {**prev_run.get("config", {}), "n_envs": prev_run.get("n_envs")} if prev_run else None
        )
        if have_cfg is not None:
            want = _comparable({**c.as_dict(), "n_envs": n_envs})
            have = _comparable(have_cfg)
            if want != have:
                diff = sorted(k for k in want if want[k] != have[k])
                raise ValueError(
                    f"{out} holds a run with other settings ({', '.join(diff)}); use another --out"
                )
    return prior, prev_run


def train(config: TrainConfig, command: str | None = None) -> Path:
    """Train one run, resuming from its last checkpoint if there is one; returns the run's directory.

    A rerun of a finished run (``run.json`` with ``timesteps >= total``, not interrupted) does nothing.
    A rerun with a different configuration (algo, env, seed, env kwargs, frame stack, n_envs) than the
    checkpoint's is refused (ValueError): delete the folder to start over."""
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    c = config
    algo, env_id, seed, env_kwargs, task = c.algo, c.env_id, c.seed, c.env_kwargs, c.task
    hp, zoo, kwargs, requested, total, n_envs = _run_plan(c)
    if total != requested:
        print(
            f"{c.run_dir()}: {algo} learns from whole rollouts of n_steps x n_envs = "
            f"{_rollout_size(algo, kwargs, n_envs)} steps: --timesteps {requested} rounded up to {total}",
            file=sys.stderr,
        )
    out = c.run_dir()
    tensorboard, verbose = c.tensorboard, c.verbose
    prior, prev_run = _check_same_settings(c, n_envs)
    if (
        prev_run is not None
        and not prev_run.get("interrupted")
        and int(prev_run.get("timesteps", 0)) >= total
    ):
        print(
            f"{out}: already trained ({prev_run['timesteps']} >= {total} steps); nothing to do",
            file=sys.stderr,
        )
        return out
    session = int(prior["session"]) + 1 if prior else 0
    previous: list[dict] = []
    if prior is not None:
        previous = prior.get("sessions")
        if previous is None:  # a checkpoint of an earlier version: the records its run.json kept
            previous = list(prev_run.get("sessions", [])) if prev_run else []
        # a session still "running" in its last checkpoint ended without its final save: killed (or
        # crashed); its record ends at that checkpoint, the steps after it were lost
        previous = [{**r, "ended": "killed"} if r.get("ended") == "running" else r for r in previous]
    out.mkdir(parents=True, exist_ok=True)
    (out / "monitor").mkdir(exist_ok=True)

    import torch

    torch.set_num_threads(c.torch_threads)
    set_random_seed(seed + session * seeds_mod.MAX_TRAIN_RUNS)  # torch / numpy / random: new per session
    monitor_dir = out / "monitor" if session == 0 else out / "monitor" / f"session{session}"
    monitor_dir.mkdir(parents=True, exist_ok=True)
    env_seed = seeds_mod.train_env_seed(seed, 0, session)  # env i: env_seed + i (train_env_seed(seed, i))
    train_kwargs = {**env_kwargs, "privileged_info": True} if c.privileged_quantities else env_kwargs
    venv = make_vec_env_for(
        env_id, n_envs, env_seed, monitor_dir, train_kwargs, vec_env=c.vec_env, num_processes=c.num_processes
    )
    if c.damping_slew is not None:
        # on the raw observations and the env's own actions: the policy's damping action is a set-point
        # (gfb_agents.learned.slew); LearnedPolicy applies the same transform when deployed
        from gfb_agents.learned.vec_env import DampingSlewVecEnv

        venv = DampingSlewVecEnv(venv, c.damping_slew, c.damping_slew_reserve)
    if algo in PRIVILEGED_INPUT_ALGOS:
        # training only: the privileged vector beside the observation (asymmetric_ppo: the critic's
        # input; the validation env and the deployed actor get the plain observation)
        from gfb_agents.learned.vec_env import PrivilegedVecEnv

        venv = PrivilegedVecEnv(venv, c.privileged_quantities)
    norm = zoo["normalize"]
    cls = algo_class(algo)
    tb = str(out / "tb") if tensorboard else None
    if prior is not None:
        ck = out / "checkpoints" / prior["dir"]
        if norm:
            venv = VecNormalize.load(str(ck / "vecnormalize.pkl"), venv)
            venv.training = True
        if c.frame_stack > 1:
            venv = VecFrameStack(venv, c.frame_stack)
        model = cls.load(str(ck / "model.zip"), env=venv, device="cpu", tensorboard_log=tb)
        if (ck / "replay_buffer.pkl").exists() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(str(ck / "replay_buffer.pkl"))
        done = int(model.num_timesteps)
        print(f"{out}: resuming from {ck.name} ({done} steps, session {session})", file=sys.stderr)
    else:
        if norm:
            venv = VecNormalize(venv, gamma=kwargs.get("gamma", 0.99), **norm)
        if c.frame_stack > 1:
            venv = VecFrameStack(venv, c.frame_stack)
        model = cls(
            _policy_class(algo, zoo),
            venv,
            seed=seed,
            device="cpu",
            verbose=verbose,
            tensorboard_log=tb,
            **kwargs,
        )
        done = 0
    sess = _Session(
        c,
        out,
        session,
        prior,
        total,
        env_seed=env_seed,
        previous_sessions=previous,
        on_policy=_rollout_size(algo, kwargs, n_envs) is not None,
        run_config={**c.as_dict(), "n_envs": n_envs},
    )
    remaining = total - done
    callbacks = [_session_callback(sess, total)]
    if c.progress_bar:
        callbacks.append(_tqdm_progress_callback(total, done))
    interrupted = False
    if remaining > 0:
        try:
            model.learn(
                total_timesteps=remaining,
                callback=callbacks,
                reset_num_timesteps=prior is None,
                tb_log_name=f"{task}_{algo}",
            )
        except KeyboardInterrupt:
            # Ctrl-C / SIGINT ends a long run cleanly: a checkpoint at this step (a rerun resumes here),
            # the model so far and run.json (with "interrupted": true)
            interrupted = True
            n = int(model.num_timesteps)
            if sess.on_policy and n > sess.trained_steps:
                # the unfinished rollout never reached the learner: count the steps learnt from, so that
                # the resumed run collects whole rollouts up to exactly its total
                model.num_timesteps = sess.trained_steps
                print(
                    f"interrupted at {n} timesteps; the unfinished rollout is dropped, saving at "
                    f"{sess.trained_steps}",
                    file=sys.stderr,
                )
            else:
                print(f"interrupted at {n} timesteps; saving", file=sys.stderr)
    if not interrupted and remaining > 0:
        # model selection needs the final policy validated too (the callback's last validation ran
        # before the last policy update, even at the same step count)
        sess.validate(model)
    sess.checkpoint(model, ended="interrupted" if interrupted else "finished")
    model.save(str(out / "model.zip"))
    if norm:
        model.get_vec_normalize_env().save(str(out / "vecnormalize.pkl"))
    wall = sess.wall()
    steps = int(model.num_timesteps)
    val_wall = sess.validation_wall()
    sessions = sess.sessions(steps, "interrupted" if interrupted else "finished")
    info = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "seed": seed,
        "n_envs": n_envs,
        "frame_stack": c.frame_stack,
        **({"privileged": list(_privileged_names(c))} if algo in PRIVILEGED_INPUT_ALGOS else {}),
        # part of the deployed policy (LearnedPolicy reads it); absent: no slew limit
        **({"damping_slew": c.damping_slew} if c.damping_slew is not None else {}),
        **({"damping_slew_reserve": c.damping_slew_reserve} if c.damping_slew_reserve is not None else {}),
        "timesteps": steps,
        "total_timesteps": total,
        "requested_timesteps": requested,
        "wall_time_s": round(wall, 1),
        "validation_wall_time_s": round(val_wall, 1),
        # throughput of the whole run (all sessions): env steps per second of wall time, and without
        # the time spent playing the validation episodes
        "env_steps_per_s": round(steps / max(wall, 1e-9), 1),
        "env_steps_per_s_excluding_validation": round(steps / max(wall - val_wall, 1e-9), 1),
        "sessions": sessions,
        "validation_seeds": sess.validation["seeds"],
        "best_validation": sess.validation["best"],
        "model": "best/model.zip is the checkpoint with the best validation mean return",
        "command": command
        or "python -m gfb_experiments.train " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        "hyperparams": {
            k: (v if isinstance(v, (int, float, str, bool)) or v is None else repr(v)) for k, v in hp.items()
        },
        "config": {**c.as_dict(), "n_envs": n_envs},
        "interrupted": interrupted,
        "cpu_count": os.cpu_count(),
    }
    _atomic_write_json(out / "run.json", info)
    plot_learning_curve(out, out / "learning_curve.png", title=f"{algo.upper()} on {env_id} (run {seed})")
    venv.close()
    sess.log(model, "done" if not interrupted else "interrupted")
    return out


def _privileged_names(c: TrainConfig) -> tuple[str, ...]:
    from gfb_agents.learned.privileged import privileged_names

    return privileged_names(c.privileged_quantities)


def _policy_class(algo: str, zoo: dict[str, Any]):
    """The ``policy`` argument of the algorithm: the YAML's name, or for ``asymmetric_ppo`` its class."""
    name = zoo.get("policy", "MlpPolicy")
    if algo == "asymmetric_ppo":
        from gfb_agents.learned.asymmetric import AsymmetricActorCriticPolicy

        if name != "AsymmetricActorCriticPolicy":
            raise ValueError(f"asymmetric_ppo: policy must be 'AsymmetricActorCriticPolicy', got {name!r}")
        return AsymmetricActorCriticPolicy
    if algo == TEACHER_ALGO and name != "MultiInputPolicy":
        raise ValueError(f"{TEACHER_ALGO}: policy must be 'MultiInputPolicy', got {name!r}")
    return name


def _train_point(**cfg: Any) -> dict:
    """One run of a multi-seed sweep (in a worker): the run's summary from its ``run.json``."""
    set_thread_defaults()
    cfg = dict(cfg)
    command = cfg.pop("command", None)
    out = train(TrainConfig(**cfg), command)
    meta = json.loads((out / "run.json").read_text())
    keep = ("seed", "timesteps", "wall_time_s", "env_steps_per_s", "best_validation", "interrupted")
    return {"out": str(out), **{k: meta.get(k) for k in keep}}


def train_seeds(
    config: TrainConfig,
    seeds: list[int],
    n_jobs: int = 1,
    scheduler: str | None = None,
    command: str | None = None,
) -> list[dict]:
    """Train ``config`` once per training seed in ``seeds`` (run ``r`` in ``<out>/seed<r>``, ``out``
    defaulting to ``runs/<env>_<algo>``), in parallel with joblib (``n_jobs``) or on a Dask cluster
    (``scheduler``: the workers need this package and a shared ``out``).  Every run resumes from its own
    checkpoint, so rerunning the same command continues an interrupted sweep.  Returns one record per
    run (``{"point", "result", "error"}`` of :func:`gfb_env.sweeps.run_sweep`); a failed run does not
    stop the others."""
    from gfb_env.sweeps import run_sweep

    root = config.out if config.out is not None else Path("runs") / config.experiment_name
    points = []
    for r in seeds:
        d = {**config.as_dict(), "seed": int(r), "out": str(Path(root) / f"seed{r}"), "command": command}
        if len(seeds) > 1 and n_jobs != 1:
            d["progress_bar"] = False  # interleaved bars from workers are unreadable; the log lines stay
        points.append(d)
    return run_sweep(_train_point, points, n_jobs=n_jobs, scheduler=scheduler, desc="training runs")


def plot_learning_curve(run_dir: str | Path, path: str | Path, title: str = "") -> Path:
    """Learning curve from the Monitor CSVs (training episode returns, rolling mean) and the validation
    history (``validation.json``: mean +- std return on the validation seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    fig, ax = plt.subplots(figsize=(7, 4))
    eps = []
    for f in sorted((run_dir / "monitor").rglob("*.monitor.csv")):
        lines = f.read_text().splitlines()
        try:
            t_start = float(json.loads(lines[0].lstrip("#"))["t_start"])
        except (IndexError, ValueError, KeyError):
            t_start = 0.0
        for line in lines[2:]:
            r, l, t = line.split(",")[:3]
            eps.append((t_start + float(t), float(r), int(l)))
    if eps:
        eps.sort()
        ret = np.array([e[1] for e in eps])
        steps = np.cumsum([e[2] for e in eps])
        ax.plot(steps, ret, ".", ms=2, alpha=0.3, color="C0", label="training episodes")
        w = max(1, min(50, len(ret) // 10))
        roll = np.convolve(ret, np.ones(w) / w, mode="valid")
        ax.plot(steps[w - 1 :], roll, "-", color="C0", label=f"rolling mean ({w})")
    vp = run_dir / "validation.json"
    if vp.exists():
        hist = sorted(json.loads(vp.read_text()).get("history", []), key=lambda h: h["timesteps"])
        if hist:
            ax.errorbar(
                [h["timesteps"] for h in hist],
                [h["mean_return"] for h in hist],
                yerr=[h["std_return"] for h in hist],
                fmt="o-",
                color="C3",
                ms=3,
                capsize=2,
                label="validation seeds (deterministic)",
            )
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _check_env_kwargs(c: TrainConfig) -> None:
    """ValueError (one line) unless ``c.env_kwargs`` build the task the way the run will: its training
    envs (``gymnasium.make_vec`` for the native vector env) and the validation env (``gymnasium.make``)."""
    import gfb_env.envs  # noqa: F401  (registers the ids)

    try:
        envs = [gym.make(c.env_id, **c.env_kwargs)]
        if c.vec_env == "native":
            envs.append(
                gym.make_vec(c.env_id, num_envs=1, vectorization_mode="vector_entry_point", **c.env_kwargs)
            )
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--env-kwargs {json.dumps(c.env_kwargs)}: {' '.join(str(exc).split())}") from None
    for env in envs:
        env.close()


def check_runs(config: TrainConfig, run_seeds: list[int], scheduler: str | None = None) -> None:
    """Refuse (ValueError, one line) what would make a run of the sweep fail after it started: the
    hyperparameters, the env kwargs, a run folder holding a run with other settings, an unwritable output
    folder (created here), a Dask scheduler that does not answer."""
    *_, n_envs = _run_plan(config)
    root = config.out if config.out is not None else Path("runs") / config.experiment_name
    for r in run_seeds:
        _check_same_settings(TrainConfig(**{**config.as_dict(), "seed": r, "out": root / f"seed{r}"}), n_envs)
    _check_env_kwargs(config)
    if scheduler is not None:
        check_scheduler(scheduler)
    check_output_dir(str(root), "--out")
