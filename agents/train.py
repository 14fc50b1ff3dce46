"""Train a Stable-Baselines3 agent (PPO or SAC) on a gfb_env task.

    python -m gfb_agents.train --algo {ppo,sac} --env gfb_env/RunUpRandomized-v0 [--timesteps N] [--seed S]
                           [--n-envs K] [--resume CHECKPOINT.zip] [--out DIR] [--hyperparams FILE]
                           [--env-kwargs JSON] [--eval-freq N] [--eval-episodes N]
                           [--checkpoint-freq N] [--no-progress-bar] [--vec-env {dummy,subproc,native}]

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` in rl-zoo3's layout (top-level keys are env
ids; besides the algorithm's keyword arguments the zoo's ``n_timesteps``, ``policy``, ``n_envs`` and
``normalize`` are understood; ``policy_kwargs`` may be a string like ``"dict(net_arch=[64, 64])"`` and
``learning_rate`` may be ``lin_3e-4`` for a linear schedule, as in the zoo).

Everything lands in ``--out`` (default ``runs/<task>_<algo>_s<seed>``, gitignored)::

    model.zip, vecnormalize.pkl      final model and its observation-normalisation statistics
    checkpoints/                     periodic model + VecNormalize (+ SAC replay buffer) snapshots
    eval/                            EvalCallback: evaluations.npz, best_model.zip (+ best_vecnormalize.pkl)
    monitor/                         Monitor CSVs of the training envs
    tb/                              TensorBoard logs
    learning_curve.png, run.json     learning curve; command, seed, wall time, timesteps, final evaluation

Seeding is deterministic: ``set_random_seed(seed)`` (Python, NumPy, torch), training env ``i`` is seeded
with ``seed + i`` and the evaluation env with ``seed + 10_000``.  ``--resume`` continues from a checkpoint
zip and the VecNormalize statistics saved next to it (same step count), keeping the step counter.
"""

from __future__ import annotations

import ast
import json
import re
import shlex
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from gfb_env import jsonio
from gfb_env._cli_common import OneLineParser, check_output_dir
from gfb_env._threads import set_thread_defaults

__all__ = [
    "ALGOS",
    "TrainConfig",
    "VEC_ENVS",
    "importable_env_id",
    "load_hyperparams",
    "make_vec_env_for",
    "train",
    "main",
    "plot_learning_curve",
]

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
ALGOS = ("ppo", "sac")
#: keys of the zoo files that are not algorithm keyword arguments
ZOO_KEYS = ("n_timesteps", "policy", "n_envs", "normalize", "env_wrapper", "frame_stack", "callback")


def _algo_class(algo: str):
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[algo]


def _linear_schedule(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _eval_policy_kwargs(text: str) -> dict:
    """Evaluate a zoo-style ``policy_kwargs`` string with a restricted namespace (``dict``, ``nn``)."""
    import torch.nn as nn

    tree = ast.parse(text, mode="eval")
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id not in ("dict", "nn", "True", "False", "None"):
            raise ValueError(f"policy_kwargs may only use dict(...) and nn.*, got name {node.id!r}")
    return eval(compile(tree, "<policy_kwargs>", "eval"), {"__builtins__": {}}, {"dict": dict, "nn": nn})


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The hyperparameter block of ``env_id`` in the zoo-style YAML of ``algo`` (a fresh dict)."""
    p = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    if not p.exists():
        raise FileNotFoundError(f"no hyperparameter file {p}")
    table = yaml.safe_load(p.read_text()) or {}
    if env_id not in table:
        raise ValueError(f"{p} has no entry for {env_id!r}; known: {sorted(table)}")
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
        norm = ast.literal_eval(norm)
    if norm is True:
        norm = {"norm_obs": True, "norm_reward": True}
    zoo["normalize"] = norm or {}
    return zoo, kwargs


VEC_ENVS = ("dummy", "subproc", "native")


def importable_env_id(env_id: str) -> str:
    """``env_id`` in gymnasium's ``"module:id"`` form for the gfb_env tasks (``"gfb_env:gfb_env/RunUp-v0"``).

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
    vec_env: str = "dummy",
):
    """A vector env of ``n_envs`` Monitor-wrapped copies of ``env_id`` seeded ``seed, seed+1, ...``.

    ``vec_env="dummy"`` (default): SB3's ``DummyVecEnv``, all copies in this process (the control step is
    a stiff integration in compiled code and the cores are few and shared; set ``n_envs`` to 1 or 2).
    ``vec_env="subproc"``: ``SubprocVecEnv``, one worker process per copy.  The workers get the id in the
    ``"module:id"`` form (:func:`importable_env_id`), so this works from ``python -c`` and stdin too, and
    one copy is made, reset and stepped here first so that numba compiles (or loads) the kernels once and
    writes its on-disk cache before the workers start: they load the kernels instead of compiling them
    all at once.
    ``vec_env="native"``: the task's native vector env (``gymnasium.make_vec``'s vector_entry_point,
    :class:`gfb_env.envs.vector.GFBVectorEnv`) behind SB3's API (:class:`gfb_agents.vec_env.GFBSB3VecEnv`),
    the same bits as ``"dummy"``, with one ``VecMonitor`` (``native.monitor.csv``) instead of one
    ``Monitor`` per copy."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    import gfb_env.envs  # noqa: F401  (registers the ids)

    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}")
    env_kwargs = dict(env_kwargs or {})
    if vec_env == "native":
        from gfb_agents.vec_env import GFBSB3VecEnv

        native = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", **env_kwargs)
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


def _find_vecnormalize(checkpoint: Path) -> Path | None:
    """VecNormalize statistics saved with a checkpoint: CheckpointCallback's
    ``<prefix>_vecnormalize_<N>_steps.pkl``, EvalCallback's ``best_vecnormalize.pkl`` or a
    ``vecnormalize.pkl`` in the same folder."""
    m = re.fullmatch(r"(.*)_(\d+)_steps\.zip", checkpoint.name)
    cands = []
    if m:
        cands.append(checkpoint.with_name(f"{m.group(1)}_vecnormalize_{m.group(2)}_steps.pkl"))
    if checkpoint.name == "best_model.zip":
        cands.append(checkpoint.with_name("best_vecnormalize.pkl"))
    cands.append(checkpoint.with_name("vecnormalize.pkl"))
    return next((c for c in cands if c.exists()), None)


def _replay_buffer_for(checkpoint: Path) -> Path | None:
    m = re.fullmatch(r"(.*)_(\d+)_steps\.zip", checkpoint.name)
    if not m:
        return None
    p = checkpoint.with_name(f"{m.group(1)}_replay_buffer_{m.group(2)}_steps.pkl")
    return p if p.exists() else None


def _tqdm_progress_callback(total: int):
    """A tqdm progress bar over environment steps (SB3's own ``progress_bar=True`` needs ``rich``, which
    is not a dependency of this project)."""
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class TqdmProgress(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=total, desc="training", unit="step", dynamic_ncols=True)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return TqdmProgress()


def _save_vecnormalize_callback():
    """EvalCallback ``callback_on_new_best``: store the VecNormalize statistics next to best_model.zip."""
    from stable_baselines3.common.callbacks import BaseCallback

    class SaveVecNormalizeOnBest(BaseCallback):
        def __init__(self, path: Path):
            super().__init__()
            self.path = path

        def _on_step(self) -> bool:
            venv = self.model.get_vec_normalize_env()
            if venv is not None:
                venv.save(str(self.path))
            return True

    return SaveVecNormalizeOnBest


def _check_count(name: str, v: Any, allow_none: bool = False) -> None:
    if v is None and allow_none:
        return
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ValueError(f"{name} must be a positive integer, got {v!r}")


@dataclass(frozen=True)
class TrainConfig:
    """One training run, validated when made (every field is a ``python -m gfb_agents.train`` option).

    Attributes:
        algo: ``"ppo"`` or ``"sac"``.
        env_id: a registered ``gfb_env/...`` id.
        timesteps: total env steps (None: ``n_timesteps`` of the YAML).
        seed: seeds Python, NumPy, torch; training env ``i`` gets ``seed + i``, evaluation ``seed + 10 000``.
        n_envs: parallel training envs (None: the YAML's ``n_envs``).
        out: output directory (None: ``runs/<task>_<algo>_s<seed>``).
        resume: checkpoint ``.zip`` to continue from (its VecNormalize statistics saved next to it).
        hyperparams: zoo-style YAML (None: ``hyperparams/<algo>.yml`` of the package).
        env_kwargs: keyword arguments of ``gymnasium.make``.
        eval_freq, eval_episodes, checkpoint_freq: evaluation and checkpoint cadence in env steps.
        progress_bar, tensorboard, verbose: output.
        torch_threads: torch CPU threads (1: the env is the bottleneck and cores are shared).
        vec_env: ``"dummy"``, ``"subproc"`` or ``"native"`` for the training envs (:func:`make_vec_env_for`).
    """

    algo: str
    env_id: str = "gfb_env/RunUpRandomized-v0"
    timesteps: int | None = None
    seed: int = 0
    n_envs: int | None = None
    out: Path | None = None
    resume: Path | None = None
    hyperparams: Path | None = None
    env_kwargs: dict = field(default_factory=dict)
    eval_freq: int = 5_000
    eval_episodes: int = 10
    checkpoint_freq: int = 20_000
    progress_bar: bool = True
    tensorboard: bool = True
    verbose: int = 0
    torch_threads: int = 1
    vec_env: str = "dummy"

    def __post_init__(self) -> None:
        algo = str(self.algo).lower()
        if algo not in ALGOS:
            raise ValueError(f"algo must be one of {ALGOS}, got {self.algo!r}")
        object.__setattr__(self, "algo", algo)
        import gfb_env.envs  # noqa: F401  (registers the ids)

        if self.env_id not in gym.registry:
            raise ValueError(
                f"unknown env id {self.env_id!r}; registered gfb_env ids: "
                f"{sorted(k for k in gym.registry if k.startswith('gfb_env/'))}"
            )
        _check_count("timesteps", self.timesteps, allow_none=True)
        _check_count("n_envs", self.n_envs, allow_none=True)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        for name in ("eval_freq", "eval_episodes", "checkpoint_freq", "torch_threads"):
            _check_count(name, getattr(self, name))
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {self.vec_env!r}")
        for name in ("out", "resume", "hyperparams"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, Path(v))
        if self.env_kwargs is None:
            object.__setattr__(self, "env_kwargs", {})
        elif not isinstance(self.env_kwargs, dict):
            raise ValueError(f"env_kwargs must be a dict, got {type(self.env_kwargs).__name__}")

    @property
    def task(self) -> str:
        """``RunUp`` of ``gfb_env/RunUp-v0``."""
        return self.env_id.split("/")[-1].split("-v")[0]

    def as_dict(self) -> dict[str, Any]:
        return {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self).items()}


def train(config: TrainConfig, command: str | None = None) -> Path:
    """Train and save; returns the output directory (see the module docstring for its contents)."""
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize

    c = config
    algo, env_id, seed, env_kwargs, task = c.algo, c.env_id, c.seed, c.env_kwargs, c.task
    hp = load_hyperparams(algo, env_id, c.hyperparams)
    zoo, kwargs = _split_hyperparams(hp)
    total = int(c.timesteps if c.timesteps is not None else zoo.get("n_timesteps", 100_000))
    n_envs = int(c.n_envs if c.n_envs is not None else zoo.get("n_envs", 1))
    if total <= 0:
        raise ValueError(f"timesteps must be positive, got {total}")
    if n_envs < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    out = c.out if c.out is not None else Path("runs") / f"{task}_{algo}_s{seed}"
    resume, tensorboard, verbose = c.resume, c.tensorboard, c.verbose
    out.mkdir(parents=True, exist_ok=True)
    for sub in ("checkpoints", "eval", "monitor"):
        (out / sub).mkdir(exist_ok=True)

    import torch

    torch.set_num_threads(c.torch_threads)
    set_random_seed(seed)
    monitor_dir = out / "monitor"
    if resume is not None:
        # keep the earlier runs' logs for the learning curve: new Monitor files in a subfolder, the
        # earlier evaluations under another name (EvalCallback rewrites evaluations.npz)
        monitor_dir = out / "monitor" / f"resumed_{int(time.time())}"
        monitor_dir.mkdir(parents=True, exist_ok=True)
        ev = out / "eval" / "evaluations.npz"
        if ev.exists():
            ev.rename(out / "eval" / f"evaluations_before_{int(time.time())}.npz")
    venv = make_vec_env_for(env_id, n_envs, seed, monitor_dir, env_kwargs, vec_env=c.vec_env)
    eval_base = make_vec_env_for(env_id, 1, seed + 10_000, None, env_kwargs)
    norm = zoo["normalize"]
    cls = _algo_class(algo)
    if resume is not None:
        if not resume.exists():
            raise FileNotFoundError(f"--resume checkpoint {resume} does not exist")
        vn = _find_vecnormalize(resume)
        if norm:
            if vn is None:
                raise FileNotFoundError(f"no VecNormalize statistics saved next to {resume}")
            venv = VecNormalize.load(str(vn), venv)
            venv.training = True
        model = cls.load(
            str(resume), env=venv, device="cpu", tensorboard_log=str(out / "tb") if tensorboard else None
        )
        rb = _replay_buffer_for(resume)
        if rb is not None and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(str(rb))
        done = int(model.num_timesteps)
    else:
        if norm:
            venv = VecNormalize(venv, gamma=kwargs.get("gamma", 0.99), **norm)
        model = cls(
            zoo.get("policy", "MlpPolicy"),
            venv,
            seed=seed,
            device="cpu",
            verbose=verbose,
            tensorboard_log=str(out / "tb") if tensorboard else None,
            **kwargs,
        )
        done = 0
    if norm:
        eval_env = VecNormalize(
            eval_base, training=False, norm_obs=norm.get("norm_obs", True), norm_reward=False
        )
    else:
        eval_env = eval_base

    per_env = max(1, n_envs)
    on_best = _save_vecnormalize_callback()(out / "eval" / "best_vecnormalize.pkl") if norm else None
    remaining = total - done
    if remaining <= 0:
        raise ValueError(f"the checkpoint already has {done} >= {total} timesteps; raise --timesteps")
    callbacks = CallbackList(
        [
            CheckpointCallback(
                save_freq=max(1, c.checkpoint_freq // per_env),
                save_path=str(out / "checkpoints"),
                name_prefix=f"{task}_{algo}",
                save_vecnormalize=bool(norm),
                save_replay_buffer=algo == "sac",
            ),
            EvalCallback(
                eval_env,
                callback_on_new_best=on_best,
                n_eval_episodes=c.eval_episodes,
                eval_freq=max(1, c.eval_freq // per_env),
                log_path=str(out / "eval"),
                best_model_save_path=str(out / "eval"),
                deterministic=True,
                verbose=verbose,
            ),
        ]
        + ([_tqdm_progress_callback(remaining)] if c.progress_bar else [])
    )
    t0 = time.perf_counter()
    interrupted = False
    try:
        model.learn(
            total_timesteps=remaining,
            callback=callbacks,
            reset_num_timesteps=resume is None,
            tb_log_name=f"{task}_{algo}",
        )
    except KeyboardInterrupt:
        # Ctrl-C / SIGINT ends a long run cleanly: the model so far, its statistics and run.json are
        # saved as for a finished run (with "interrupted": true), so it can be exported or resumed
        interrupted = True
        print(f"interrupted at {model.num_timesteps} timesteps; saving", file=sys.stderr)
    wall = time.perf_counter() - t0
    model.save(str(out / "model.zip"))
    if norm:
        model.get_vec_normalize_env().save(str(out / "vecnormalize.pkl"))
    final = _final_eval(out)
    info = {
        "algo": algo,
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "seed": seed,
        "n_envs": n_envs,
        "timesteps": int(model.num_timesteps),
        "wall_time_s": round(wall, 1),
        "resumed_from": str(resume) if resume else None,
        "command": command or "python -m gfb_agents.train " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        "hyperparams": {
            k: (v if isinstance(v, (int, float, str, bool)) or v is None else repr(v)) for k, v in hp.items()
        },
        "config": c.as_dict(),
        "final_eval": final,
        "interrupted": interrupted,
    }
    prev = out / "run.json"
    if resume is not None and prev.exists():
        info["previous_runs"] = [json.loads(prev.read_text())]
    prev.write_text(jsonio.dumps(info, indent=2))
    plot_learning_curve(out, out / "learning_curve.png", title=f"{algo.upper()} on {env_id} (seed {seed})")
    venv.close()
    eval_env.close()
    return out


def _final_eval(out: Path) -> dict:
    p = out / "eval" / "evaluations.npz"
    if not p.exists():
        return {}
    d = np.load(p)
    r = d["results"]
    if len(r) == 0:
        return {}
    means = r.mean(axis=1)
    i = int(np.argmax(means))
    return {
        "last_mean_return": float(means[-1]),
        "last_std_return": float(r[-1].std()),
        "best_mean_return": float(means[i]),
        "best_timesteps": int(d["timesteps"][i]),
        "eval_episodes": int(r.shape[1]),
    }


def plot_learning_curve(run_dir: str | Path, path: str | Path, title: str = "") -> Path:
    """Learning curve from the Monitor CSVs (episode returns, rolling mean) and the EvalCallback log."""
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
    files = sorted((run_dir / "eval").glob("evaluations_before_*.npz")) + [
        run_dir / "eval" / "evaluations.npz"
    ]
    ts, res = [], []
    for p in files:
        if p.exists():
            d = np.load(p)
            if len(d["results"]):
                ts.append(d["timesteps"])
                res.append(d["results"])
    if ts:
        widths = {r.shape[1] for r in res}
        if len(widths) == 1:
            d = {"timesteps": np.concatenate(ts), "results": np.concatenate(res)}
        else:
            d = {"timesteps": ts[-1], "results": res[-1]}
        if len(d["results"]):
            m, s = d["results"].mean(axis=1), d["results"].std(axis=1)
            ax.errorbar(
                d["timesteps"],
                m,
                yerr=s,
                fmt="o-",
                color="C3",
                ms=3,
                capsize=2,
                label="evaluation (deterministic)",
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


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_agents.train", description=__doc__.splitlines()[0])
    ap.add_argument("--algo", required=True, choices=ALGOS)
    ap.add_argument("--env", default="gfb_env/RunUpRandomized-v0", help="registered env id")
    ap.add_argument(
        "--timesteps", type=int, default=None, help="total env steps (default: n_timesteps of the YAML)"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n-envs", type=int, default=None, help="parallel envs (default: the YAML's n_envs)")
    ap.add_argument(
        "--resume", default=None, help="checkpoint .zip to continue from (VecNormalize stats next to it)"
    )
    ap.add_argument("--out", default=None, help="output directory (default runs/<task>_<algo>_s<seed>)")
    ap.add_argument(
        "--hyperparams", default=None, help="zoo-style YAML (default agents/hyperparams/<algo>.yml)"
    )
    ap.add_argument("--env-kwargs", default=None, help="JSON dict of keyword arguments for gymnasium.make")
    ap.add_argument("--eval-freq", type=int, default=5_000, help="env steps between evaluations")
    ap.add_argument("--eval-episodes", type=int, default=10)
    ap.add_argument("--checkpoint-freq", type=int, default=20_000, help="env steps between checkpoints")
    ap.add_argument("--no-progress-bar", action="store_true")
    ap.add_argument("--no-tensorboard", action="store_true")
    ap.add_argument("--verbose", type=int, default=0)
    ap.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="torch CPU threads (default 1: the env is the bottleneck and cores are shared)",
    )
    ap.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default="dummy",
        help="training envs in this process (dummy), one worker process each (subproc), or the task's "
        "native vector env (native)",
    )
    a = ap.parse_args(argv)
    set_thread_defaults()  # single-threaded BLAS in the subproc workers (see gfb_env._threads)
    env_kwargs = None
    if a.env_kwargs:
        try:
            env_kwargs = json.loads(a.env_kwargs)
        except json.JSONDecodeError as exc:
            ap.error(f"--env-kwargs is not valid JSON: {exc}")
        if not isinstance(env_kwargs, dict):
            ap.error("--env-kwargs must be a JSON object")
    if a.out is not None:
        try:  # before any training: an unwritable --out fails now, not at the first checkpoint
            check_output_dir(a.out, "--out")
        except ValueError as exc:
            ap.error(str(exc))
    cmd = "python -m gfb_agents.train " + " ".join(
        shlex.quote(x) for x in (argv if argv is not None else sys.argv[1:])
    )
    try:
        config = TrainConfig(
            algo=a.algo,
            env_id=a.env,
            timesteps=a.timesteps,
            seed=a.seed,
            n_envs=a.n_envs,
            out=a.out,
            resume=a.resume,
            hyperparams=a.hyperparams,
            env_kwargs=env_kwargs,
            eval_freq=a.eval_freq,
            eval_episodes=a.eval_episodes,
            checkpoint_freq=a.checkpoint_freq,
            progress_bar=not a.no_progress_bar,
            tensorboard=not a.no_tensorboard,
            verbose=a.verbose,
            torch_threads=a.torch_threads,
            vec_env=a.vec_env,
        )
        out = train(config, cmd)
    except (ValueError, FileNotFoundError) as exc:
        ap.error(str(exc))
    print(f"saved to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
