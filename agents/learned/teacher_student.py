"""Teacher-student training (issue 21): a teacher that sees the privileged vector, a student that sees only
the observation history, distilled from it by DAgger.

1. The teacher: ``--algo privileged_ppo`` (:func:`gfb_agents.learned.train.train`, every feature of the
   training runs: checkpoints, resume, validation, TRAIN seeds): PPO with SB3's ``MultiInputPolicy`` on the
   ``{"obs", "privileged"}`` observation (:class:`~gfb_agents.learned.vec_env.PrivilegedVecEnv`), actor
   and critic both reading the episode's privileged vector.  It is not a deployable policy; its validation
   plays :class:`TeacherPolicy`, handed each episode's hidden draws through the privileged channel.
2. The student: ``--algo teacher_student --teacher RUN`` (:func:`distill`): an MLP over the last
   ``history`` normalised observations (the observation-history encoder; the teacher's observation
   statistics, frozen) -> the action, trained by DAgger (Ross et al. 2011): in iteration ``i`` the training
   envs (TRAIN seeds) are played by the teacher with probability ``beta_i = beta_decay ** i`` per step and by
   the student otherwise; every visited state is labelled with the teacher's deterministic action; the
   student is fitted (mean squared error, Adam) on the aggregate of every iteration's states (the newest
   ``max_samples``).  The student is validated on the VALIDATION seeds after each iteration (the best kept
   in ``best/``), and is deployed as :class:`~gfb_agents.learned.asymmetric.DeployedActor` (``actor.pt``,
   played by :class:`~gfb_agents.learned.evaluate.LearnedPolicy` from the public observation).  The RL
   fine-tuning of the student after distillation is not done here.

A distillation run resumes after an interruption: every iteration ends with a checkpoint (the student, its
optimiser, the aggregated data set, the bookkeeping; ``checkpoints/latest.json`` written last), and the
same command continues from it (new env seeds per session, as the training runs).

Hyperparameters: ``agents/hyperparams/teacher_student.yml`` (:data:`DISTILL_KEYS`).
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import sys
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gfb_agents import seeds as seeds_mod
from gfb_agents.policy import PrivilegedPolicy
from gfb_agents.seeds import VALIDATION

__all__ = [
    "TEACHER_ALGO",
    "STUDENT_ALGO",
    "DISTILL_KEYS",
    "TeacherPolicy",
    "DistillConfig",
    "distill",
    "load_teacher",
]

TEACHER_ALGO, STUDENT_ALGO = "privileged_ppo", "teacher_student"
#: the keys of a ``teacher_student.yml`` block, with their defaults
DISTILL_KEYS: dict[str, Any] = {
    "n_timesteps": 100_000,  # env steps collected over the whole distillation
    "n_envs": 8,
    "steps_per_iteration": 4096,  # env steps (all envs) collected per DAgger iteration
    "epochs": 5,  # passes over the aggregated data per iteration
    "batch_size": 256,
    "learning_rate": 1e-3,
    "beta_decay": 0.5,  # the teacher acts with probability beta_decay ** iteration
    "max_samples": 200_000,  # the aggregated data set keeps the newest states
    "history": 8,  # observations the student's encoder reads (its frame stack)
    "hidden": [128, 128],  # the student's MLP
    # the oracle teacher's probe, [[D_W command, steps], ...] (oracle_teacher; [] = none; only with
    # --teacher oracle, and left out of a run's plan when empty)
    "oracle_probe": [],
    # observation entries (ObservationLayout names) the student may not read: their columns of its first
    # layer are held at zero, so the deployed actor ignores them exactly ([] = none; left out of a run's
    # plan when empty).  E.g. ["damping"]: the indicated damping, which under the teacher's control
    # follows the label, so a student could copy it instead of inferring g (the copycat problem)
    "drop_inputs": [],
}


def _normalise(x: np.ndarray, mean: np.ndarray, var: np.ndarray, eps: float, clip: float) -> np.ndarray:
    """VecNormalize's observation normalisation with frozen statistics."""
    return np.clip((np.asarray(x, np.float64) - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)


class _Stack:
    """SB3's ``VecFrameStack`` (channels last) for one key: the last ``k`` rows side by side, oldest first,
    zeros before an episode's first."""

    def __init__(self, k: int):
        self.k, self.buf = int(k), None

    def __call__(self, x: np.ndarray, starts: np.ndarray) -> np.ndarray:
        n, d = x.shape
        if self.buf is None or self.buf.shape[0] != n:
            self.buf = np.zeros((n, self.k * d), dtype=np.float32)
            starts = np.ones(n, dtype=bool)
        self.buf[starts] = 0.0
        self.buf = np.roll(self.buf, -d, axis=1)
        self.buf[:, -d:] = x
        return self.buf.copy()


class TeacherPolicy(PrivilegedPolicy):
    """A ``privileged_ppo`` model with its frozen statistics, acting from the observation and the episode's
    privileged vector.  For the benchmark's episode loop (its validation) it takes the vector from the reset
    info of an env made with ``privileged_info=True`` (:meth:`observe_reset_info`); DAgger calls
    :meth:`act` with both.  Never benchmarked: it reads the hidden draws."""

    kind = "oracle"

    def __init__(
        self,
        model,
        vec_normalize,
        frame_stack: int = 1,
        name: str = "teacher",
        damping_slew: float | None = None,
        damping_slew_reserve: float | None = None,
    ):
        from gfb_agents.learned.privileged import OBS_KEY, PRIVILEGED_KEY
        from gfb_agents.learned.slew import DampingSlew, check_damping_slew, check_damping_slew_reserve

        self.model, self.name, self.frame_stack = model, name, int(frame_stack)
        self.keys = (OBS_KEY, PRIVILEGED_KEY)
        self.stats = None
        if vec_normalize is not None and vec_normalize.norm_obs:
            self.stats = {
                k: (np.array(vec_normalize.obs_rms[k].mean), np.array(vec_normalize.obs_rms[k].var))
                for k in self.keys
            }
        self.eps = float(getattr(vec_normalize, "epsilon", 1e-8))
        self.clip = float(getattr(vec_normalize, "clip_obs", 10.0))
        self._stacks = {k: _Stack(self.frame_stack) for k in self.keys}
        self._vec: np.ndarray | None = None
        # the run's slew limit of the damping command: applied in the episode loop (predict), where the
        # env gets the commands; act() gives the set-points (DAgger's labels: its envs apply the limit)
        self.damping_slew = check_damping_slew(damping_slew)
        self.damping_slew_reserve = check_damping_slew_reserve(damping_slew_reserve, self.damping_slew)
        self._slew = (
            None if self.damping_slew is None else DampingSlew(self.damping_slew, self.damping_slew_reserve)
        )

    def normalise(self, key: str, x: np.ndarray) -> np.ndarray:
        if self.stats is None:
            return np.asarray(x, dtype=np.float32)
        return _normalise(x, *self.stats[key], self.eps, self.clip)

    def act(self, obs: np.ndarray, privileged: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """Deterministic actions ``(n, 2)`` for raw observations ``(n, n_obs)`` and privileged vectors
        ``(n, n_priv)``; ``starts``: the envs whose episode begins with this observation."""
        x = {}
        for k, v in zip(self.keys, (obs, privileged), strict=True):
            x[k] = self._stacks[k](self.normalise(k, v), np.asarray(starts, dtype=bool))
        a, _ = self.model.predict(x, deterministic=True)
        return np.asarray(a, dtype=np.float32)

    def reset(self) -> None:
        self._stacks = {k: _Stack(self.frame_stack) for k in self.keys}
        self._vec = None
        if self._slew is not None:
            self._slew.reset()

    def observe_reset_info(self, info: Mapping[str, Any]) -> None:
        from gfb_agents.learned.privileged import episode_vector

        priv = info.get("privileged")
        if priv is None:
            raise ValueError("the teacher needs the env made with privileged_info=True")
        self._vec = episode_vector(priv["hidden_parameters"])[None, :]

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self._vec is None:
            raise RuntimeError("TeacherPolicy.predict before observe_reset_info")
        obs = np.asarray(observation)[None, :]
        start = np.array([bool(np.all(episode_start)) if episode_start is not None else False])
        a = self.act(obs, self._vec, start)
        if self._slew is not None:
            from gfb_agents.learned.slew import slewed_actions

            a = slewed_actions(self._slew, obs, a, start)
        return a[0], state


def _teacher_files(run: Path) -> tuple[Path, Path | None]:
    """``(model.zip, vecnormalize.pkl or None)`` of a teacher run: its validation-selected ``best/``."""
    for d in (run / "best", run):
        if (d / "model.zip").exists():
            vn = d / "vecnormalize.pkl"
            return d / "model.zip", vn if vn.exists() else None
    raise FileNotFoundError(f"no teacher model in {run} (model.zip or best/model.zip)")


def load_teacher(run: str | Path) -> tuple[TeacherPolicy, dict]:
    """The teacher of a ``privileged_ppo`` training run (its ``best/`` model) and its ``run.json``."""
    from stable_baselines3 import PPO

    run = Path(run)
    meta_p = run / "run.json"
    if not meta_p.is_file():
        raise FileNotFoundError(f"--teacher {run}: no run.json (not a training run)")
    meta = json.loads(meta_p.read_text())
    if meta.get("algo") != TEACHER_ALGO:
        raise ValueError(f"--teacher {run}: a {meta.get('algo')} run; the teacher is a {TEACHER_ALGO} run")
    zip_p, vn_p = _teacher_files(run)
    model = PPO.load(str(zip_p), device="cpu")
    vn = None
    if vn_p is not None:
        with open(vn_p, "rb") as fh:
            vn = pickle.load(fh)
    return TeacherPolicy(
        model,
        vn,
        int(meta.get("frame_stack", 1) or 1),
        damping_slew=meta.get("damping_slew"),
        damping_slew_reserve=meta.get("damping_slew_reserve"),
    ), meta


@dataclass(frozen=True)
class DistillConfig:
    """One DAgger distillation run (``python -m gfb_experiments.train --algo teacher_student``).

    Attributes:
        teacher: a ``privileged_ppo`` training run's folder (its ``best/`` model is the teacher; the task,
            its env kwargs and the observation statistics come from it), or ``"oracle"``
            (:data:`~gfb_agents.learned.oracle_teacher.ORACLE_TEACHER`: the benchmark's oracle,
            :mod:`gfb_agents.learned.oracle_teacher`; then ``env_id`` and the slew limit are given).
        timesteps: env steps collected in all (None: the YAML's ``n_timesteps``).
        seed: the independent run ``r``: torch / NumPy seeds and the TRAIN env seeds
            (``train_env_seed(r, i, session)``).
        out: the run's folder (None: ``runs/<env>_teacher_student/seed<r>``).
        hyperparams: the YAML (None: ``hyperparams/teacher_student.yml``).
        n_envs: parallel envs (None: the YAML's).
        eval_episodes: validation seeds played after each iteration.
        vec_env: the training envs (``make_vec_env_for``): ``"native"`` (default) or ``"dummy"``.
        env_id: the task (only with the oracle teacher; a learned teacher's run names its own).
        damping_slew, damping_slew_reserve: the slew limit of the damping command (only with the oracle
            teacher; a learned teacher's student takes its teacher's).
    """

    teacher: Path
    timesteps: int | None = None
    seed: int = 0
    out: Path | None = None
    hyperparams: Path | None = None
    n_envs: int | None = None
    eval_episodes: int = 20
    vec_env: str = "native"
    env_kwargs: dict = field(default_factory=dict)
    env_id: str = ""
    damping_slew: float | None = None
    damping_slew_reserve: float | None = None

    @property
    def oracle(self) -> bool:
        """Whether the teacher is the benchmark's oracle (:mod:`gfb_agents.learned.oracle_teacher`)."""
        from gfb_agents.learned.oracle_teacher import ORACLE_TEACHER

        return str(self.teacher) == ORACLE_TEACHER

    def __post_init__(self) -> None:
        object.__setattr__(self, "teacher", Path(self.teacher))
        for name in ("out", "hyperparams"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, Path(v))
        for name in ("timesteps", "n_envs"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < seeds_mod.MAX_TRAIN_RUNS
        ):
            raise ValueError(f"seed must be an integer in [0, {seeds_mod.MAX_TRAIN_RUNS}), got {self.seed!r}")
        if (
            isinstance(self.eval_episodes, bool)
            or not isinstance(self.eval_episodes, int)
            or self.eval_episodes < 1
        ):
            raise ValueError(f"eval_episodes must be a positive integer, got {self.eval_episodes!r}")
        if self.vec_env not in ("native", "dummy"):
            raise ValueError(f"vec_env must be 'native' or 'dummy' for teacher_student, got {self.vec_env!r}")
        if self.oracle:
            self._check_oracle()
            return
        if self.damping_slew is not None or self.damping_slew_reserve is not None:
            raise ValueError(
                "damping_slew: only with the oracle teacher (the student takes its teacher's slew limit)"
            )
        meta_p = self.teacher / "run.json"
        if not meta_p.is_file():
            raise ValueError(f"--teacher {self.teacher}: no run.json (not a training run)")
        meta = json.loads(meta_p.read_text())
        if meta.get("algo") != TEACHER_ALGO:
            raise ValueError(
                f"--teacher {self.teacher}: a {meta.get('algo')} run; the teacher is a {TEACHER_ALGO} run"
            )
        object.__setattr__(self, "env_id", str(meta["env_id"]))
        object.__setattr__(self, "env_kwargs", dict(meta.get("env_kwargs") or {}))

    def _check_oracle(self) -> None:
        import gymnasium as gym

        from gfb_agents.learned.slew import check_damping_slew, check_damping_slew_reserve
        from gfb_env.envs import RETIRED_IDS, RetiredTaskError
        from gfb_env.envs.retired import retired_message

        if not self.env_id:
            raise ValueError("env_id: the oracle teacher needs the task (--env ID)")
        if self.env_id in RETIRED_IDS:
            raise RetiredTaskError(f"env_id: {retired_message(self.env_id)}")
        if self.env_id not in gym.registry:
            raise ValueError(f"env_id: unknown env id {self.env_id!r}")
        if "WhirlRecovery" in self.env_id:
            raise ValueError(
                f"env_id: the oracle teacher covers the run-up tasks; {self.env_id} starts in the whirl "
                "(its oracle reads the true whirl amplitude at every step)"
            )
        check_damping_slew_reserve(self.damping_slew_reserve, check_damping_slew(self.damping_slew))

    def run_dir(self) -> Path:
        name = f"{self.env_id.split('/')[-1]}_{STUDENT_ALGO}"
        return self.out if self.out is not None else Path("runs") / name / f"seed{self.seed}"

    def as_dict(self) -> dict[str, Any]:
        d = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self).items()}
        for k in ("damping_slew", "damping_slew_reserve"):  # a learned teacher's runs never had them
            if d[k] is None:
                del d[k]
        return d

    def check_folder(self) -> tuple[dict[str, Any], dict | None]:
        """``(plan, last checkpoint or None)``; ValueError if the run's folder holds a distillation with
        other settings (teacher, seed, hyperparameters, total, n_envs, ...)."""
        p = self.plan()
        prior = _latest(self.run_dir())
        if prior is not None and prior.get("config") != json.loads(json.dumps({**self.as_dict(), "plan": p})):
            raise ValueError(f"{self.run_dir()} holds a distillation with other settings; use another --out")
        return p, prior

    def plan(self) -> dict[str, Any]:
        """The hyperparameters (:data:`DISTILL_KEYS`, the YAML's block over the defaults), checked."""
        from gfb_agents.learned.train import load_hyperparams

        hp = load_hyperparams(STUDENT_ALGO, self.env_id, self.hyperparams)
        unknown = sorted(k for k in hp if k not in DISTILL_KEYS)
        if unknown:
            raise ValueError(
                f"teacher_student hyperparameters {unknown} unknown; known: {sorted(DISTILL_KEYS)}"
            )
        p = {**DISTILL_KEYS, **hp}
        if self.timesteps is not None:
            p["n_timesteps"] = self.timesteps
        if self.n_envs is not None:
            p["n_envs"] = self.n_envs
        for k in (
            "n_timesteps",
            "n_envs",
            "steps_per_iteration",
            "epochs",
            "batch_size",
            "max_samples",
            "history",
        ):
            v = p[k]
            if isinstance(v, float) and v.is_integer():
                v = int(v)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"teacher_student {k} must be a positive integer, got {p[k]!r}")
            p[k] = v
        if not 1 <= p["n_envs"] <= seeds_mod.MAX_TRAIN_ENVS:
            raise ValueError(f"n_envs must lie in [1, {seeds_mod.MAX_TRAIN_ENVS}], got {p['n_envs']}")
        from gfb_agents.learned.train import MAX_FRAME_STACK

        if p["history"] > MAX_FRAME_STACK:
            raise ValueError(f"teacher_student history must be at most {MAX_FRAME_STACK}, got {p['history']}")
        for k, hi in (("learning_rate", np.inf), ("beta_decay", 1.0)):
            v = p[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= hi:
                raise ValueError(f"teacher_student {k} must be a number in (0, {hi}], got {v!r}")
        if not isinstance(p["hidden"], list) or not all(isinstance(h, int) and h > 0 for h in p["hidden"]):
            raise ValueError(
                f"teacher_student hidden must be a list of positive layer sizes, got {p['hidden']!r}"
            )
        from gfb_agents.learned.oracle_teacher import check_probe

        probe = check_probe(p["oracle_probe"])
        if probe and not self.oracle:
            raise ValueError("oracle_probe: only with the oracle teacher (--teacher oracle)")
        if probe:
            p["oracle_probe"] = [list(e) for e in probe]
        else:  # the runs of a learned teacher, and the oracle's without a probe, never had the key
            del p["oracle_probe"]
        drop = p["drop_inputs"]
        if not isinstance(drop, list) or not all(isinstance(x, str) for x in drop):
            raise ValueError(f"teacher_student drop_inputs must be a list of observation names, got {drop!r}")
        if drop:
            import gymnasium as gym

            import gfb_env.envs  # noqa: F401  (registers the ids)

            names = gym.make(self.env_id).unwrapped.observation_layout.names
            unknown_names = [x for x in drop if x not in names]
            if unknown_names:
                raise ValueError(f"teacher_student drop_inputs {unknown_names} are not observation entries")
        else:
            del p["drop_inputs"]
        p["per_env"] = -(-p["steps_per_iteration"] // p["n_envs"])  # steps of each env per iteration
        p["iterations"] = -(-p["n_timesteps"] // (p["per_env"] * p["n_envs"]))
        return p


def _atomic_json(path: Path, obj: Any) -> None:
    from gfb_env import jsonio

    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(jsonio.dumps(obj, indent=2))
    os.replace(tmp, path)


def _latest(out: Path) -> dict | None:
    p = out / "checkpoints" / "latest.json"
    if not p.exists():
        return None
    state = json.loads(p.read_text())
    return state if (out / "checkpoints" / state["dir"] / "data.npz").exists() else None


def _dropped_columns(venv, names, history: int, n_obs: int) -> np.ndarray:
    """The student's input columns of the observation entries ``names`` in every frame of its history
    (VecFrameStack's layout: frame ``f`` holds columns ``f n_obs .. (f + 1) n_obs - 1``)."""
    if not names:
        return np.zeros(0, dtype=int)
    (layout,) = venv.get_attr("observation_layout", indices=[0])
    idx = [list(layout.names).index(x) for x in names]
    return np.array([f * n_obs + j for f in range(history) for j in idx], dtype=int)


def _zero_columns(student, cols: np.ndarray) -> None:
    """Hold the first layer's weights of ``cols`` at zero (the student does not read those inputs)."""
    if cols.size:
        import torch as th

        with th.no_grad():
            student.policy_net[0].weight[:, th.as_tensor(cols)] = 0.0


def distill(c: DistillConfig, command: str | None = None) -> Path:
    """Distil the student of ``c.teacher`` by DAgger (module docstring), resuming from the run's last
    checkpoint; returns the run's folder (``actor.pt``, ``vecnormalize.pkl`` (the teacher's), ``best/``,
    ``validation.json``, ``run.json``, ``checkpoints/``)."""
    import torch as th

    from gfb_agents.learned.asymmetric import ACTOR_FILE, DeployedActor
    from gfb_agents.learned.evaluate import LearnedPolicy, evaluate
    from gfb_agents.learned.privileged import OBS_KEY, PRIVILEGED_KEY
    from gfb_agents.learned.train import _fsync_folder, make_vec_env_for
    from gfb_agents.learned.vec_env import PrivilegedVecEnv

    p, prior = c.check_folder()
    out = c.run_dir()
    done_iters = int(prior["iteration"]) if prior else 0
    if (out / "run.json").exists() and done_iters >= p["iterations"]:
        print(f"{out}: already distilled ({done_iters} iterations); nothing to do", file=sys.stderr)
        return out
    if c.oracle:
        from gfb_agents.learned.oracle_teacher import OracleTeacher

        teacher = OracleTeacher(
            c.env_id, p["n_envs"], c.damping_slew, c.damping_slew_reserve, probe=p.get("oracle_probe", ())
        )
        tmeta: dict = {}
    else:
        teacher, tmeta = load_teacher(c.teacher)
    out.mkdir(parents=True, exist_ok=True)
    session = int(prior["session"]) + 1 if prior else 0
    th.manual_seed(c.seed + session * seeds_mod.MAX_TRAIN_RUNS)
    rng = np.random.default_rng(c.seed + session * seeds_mod.MAX_TRAIN_RUNS)
    env_seed = seeds_mod.train_env_seed(c.seed, 0, session)
    base = make_vec_env_for(c.env_id, p["n_envs"], env_seed, None, c.env_kwargs, c.vec_env)
    slew = teacher.damping_slew  # the teacher's labels are set-points under its slew limit: the student's too
    if slew is not None:
        from gfb_agents.learned.vec_env import DampingSlewVecEnv

        base = DampingSlewVecEnv(base, slew, teacher.damping_slew_reserve)
    venv = PrivilegedVecEnv(base)
    n_obs = int(venv.observation_space[OBS_KEY].shape[0])
    space = venv.action_space
    student = DeployedActor(p["history"] * n_obs, p["hidden"], "Tanh", space.low, space.high)
    opt = th.optim.Adam(student.parameters(), lr=float(p["learning_rate"]))
    dropped = _dropped_columns(venv, p.get("drop_inputs", ()), p["history"], n_obs)
    _zero_columns(student, dropped)
    vn_src = None if c.oracle else _teacher_files(c.teacher)[1]
    if vn_src is not None:
        shutil.copy2(vn_src, out / "vecnormalize.pkl")  # the student's frozen observation statistics
    elif c.oracle and prior is not None:  # the statistics of the first iteration (oracle_teacher)
        from gfb_agents.learned.evaluate import _obs_statistics

        with open(out / "vecnormalize.pkl", "rb") as fh:
            teacher.set_statistics(OBS_KEY, *_obs_statistics(pickle.load(fh)))
    if prior is not None:
        ck = out / "checkpoints" / prior["dir"]
        student = DeployedActor.load(ck / ACTOR_FILE).train()
        opt = th.optim.Adam(student.parameters(), lr=float(p["learning_rate"]))
        opt.load_state_dict(th.load(str(ck / "optimizer.pt"), weights_only=True))
        data = np.load(ck / "data.npz")
        X, Y = data["x"], data["y"]
        steps, wall_before, sessions = (
            int(prior["timesteps"]),
            float(prior["wall_s"]),
            list(prior["sessions"]),
        )
        sessions = [{**s, "ended": "killed"} if s.get("ended") == "running" else s for s in sessions]
        validation = prior["validation"]
        print(
            f"{out}: resuming after iteration {done_iters} ({steps} steps, session {session})",
            file=sys.stderr,
        )
    else:
        X = np.zeros((0, p["history"] * n_obs), dtype=np.float32)
        Y = np.zeros((0, space.shape[0]), dtype=np.float32)
        steps, wall_before, sessions, validation = 0, 0.0, [], {"history": [], "best": None}
    val_seeds = VALIDATION.first(c.eval_episodes)
    t0 = time.perf_counter()
    start_steps = steps
    stack = _Stack(p["history"])
    o = venv.reset()
    teacher.reset()
    starts = np.ones(p["n_envs"], dtype=bool)

    def norm_obs(x: np.ndarray) -> np.ndarray:
        return teacher.normalise(OBS_KEY, x)

    def record(ended: str, it: int) -> dict:
        return {
            "session": session,
            "env_seed": env_seed,
            "start_timesteps": start_steps,
            "end_timesteps": steps,
            "iterations": it,
            "wall_time_s": round(time.perf_counter() - t0, 1),
            "ended": ended,
        }

    meta_base = {
        "algo": STUDENT_ALGO,
        "env_id": c.env_id,
        "env_kwargs": c.env_kwargs,
        "seed": c.seed,
        "n_envs": p["n_envs"],
        "frame_stack": p["history"],
        "teacher": str(c.teacher),
        "teacher_frame_stack": teacher.frame_stack,
        "teacher_timesteps": tmeta.get("timesteps"),
        **({"teacher_kind": "oracle", "teacher_margin": teacher.margin} if c.oracle else {}),
        **({"damping_slew": slew} if slew is not None else {}),
        **(
            {"damping_slew_reserve": teacher.damping_slew_reserve}
            if teacher.damping_slew_reserve is not None
            else {}
        ),
    }
    for it in range(done_iters, p["iterations"]):
        beta = float(p["beta_decay"]) ** it
        xs, ys = [], []
        # the oracle teacher's first iteration: the teacher alone, its observations give the statistics
        deferred = teacher.stats is None and c.oracle
        raws: list[tuple[np.ndarray, np.ndarray]] = []
        student.eval()
        for _ in range(p["per_env"]):
            if c.oracle and starts.any():
                teacher.plan_episodes(venv, np.flatnonzero(starts))
            label = teacher.act(o[OBS_KEY], o[PRIVILEGED_KEY], starts)
            if deferred:
                raws.append((np.array(o[OBS_KEY]), starts.copy()))
                a = label
            else:
                xs_t = stack(norm_obs(o[OBS_KEY]), starts)
                own, _ = student.predict(xs_t, deterministic=True)
                use_teacher = rng.random(p["n_envs"]) < beta
                a = np.where(use_teacher[:, None], label, own).astype(np.float32)
                xs.append(xs_t)
            ys.append(np.clip(label, space.low, space.high))
            o, _, dones, _ = venv.step(a)
            starts = np.asarray(dones, dtype=bool)
            steps += p["n_envs"]
        if deferred:
            from gfb_agents.learned.oracle_teacher import observation_statistics, save_statistics

            mean, var = observation_statistics(np.concatenate([r for r, _ in raws]))
            teacher.set_statistics(OBS_KEY, mean, var)
            save_statistics(out / "vecnormalize.pkl", base, mean, var)
            xs = [stack(norm_obs(r), s0) for r, s0 in raws]  # the stack as it would have run
        X = np.concatenate([X, *xs])[-p["max_samples"] :]
        Y = np.concatenate([Y, *ys])[-p["max_samples"] :]
        student.train()
        xt, yt = th.as_tensor(X), th.as_tensor(Y)
        loss_v = float("nan")
        for _ in range(p["epochs"]):
            perm = th.randperm(xt.shape[0])
            for b in range(0, xt.shape[0], p["batch_size"]):
                idx = perm[b : b + p["batch_size"]]
                loss = th.nn.functional.mse_loss(student(xt[idx]), yt[idx])
                opt.zero_grad()
                loss.backward()
                opt.step()
                _zero_columns(student, dropped)
                loss_v = float(loss.detach())
        student.eval()
        # validation: the student as it is deployed (LearnedPolicy over the plain observation)
        pol = LearnedPolicy.from_actor(
            student,
            out / "vecnormalize.pkl",
            p["history"],
            damping_slew=slew,
            damping_slew_reserve=teacher.damping_slew_reserve,
        )
        wall_at_validation = wall_before + time.perf_counter() - t0
        res = evaluate(c.env_id, pol, val_seeds, env_kwargs=c.env_kwargs)
        rets = np.array([r.episode_return for r in res])
        rec = {
            "timesteps": steps,
            "iteration": it + 1,
            "beta": beta,
            "loss": loss_v,
            "samples": int(X.shape[0]),
            "mean_return": float(rets.mean()),
            "std_return": float(rets.std()),
            "success_rate": float(np.mean([r.success for r in res])),
            "mean_damping_change": float(np.mean([r.damping_command_change for r in res])),
            "wall_time_s": round(wall_at_validation, 2),
            "returns": [float(x) for x in rets],
        }
        validation["history"].append(rec)
        if validation["best"] is None or rec["mean_return"] > validation["best"]["mean_return"]:
            validation["best"] = rec
            best = out / "best"
            best.mkdir(exist_ok=True)
            student.save(best / (ACTOR_FILE + ".tmp"), {"algo": STUDENT_ALGO, "env_id": c.env_id})
            os.replace(best / (ACTOR_FILE + ".tmp"), best / ACTOR_FILE)
            if (out / "vecnormalize.pkl").exists():
                shutil.copy2(out / "vecnormalize.pkl", best / "vecnormalize.pkl")
            _atomic_json(best / "best.json", {**rec, "validation_seeds": val_seeds})
        _atomic_json(out / "validation.json", {**validation, "seeds": val_seeds})
        # the checkpoint: student, optimiser, data set, bookkeeping; the pointer last
        ck = out / "checkpoints" / f"iter_{it + 1:05d}"
        ck.mkdir(parents=True, exist_ok=True)
        student.save(ck / ACTOR_FILE)
        th.save(opt.state_dict(), str(ck / "optimizer.pt"))
        np.savez(ck / "data.npz", x=X, y=Y)
        state = {
            "dir": ck.name,
            "iteration": it + 1,
            "timesteps": steps,
            "session": session,
            "wall_s": wall_before + time.perf_counter() - t0,
            "sessions": [*sessions, record("running", it + 1)],
            "validation": validation,
            "config": {**c.as_dict(), "plan": p},
        }
        _atomic_json(ck / "state.json", state)
        _fsync_folder(ck)
        _atomic_json(out / "checkpoints" / "latest.json", state)
        for old in sorted((out / "checkpoints").glob("iter_*")):
            if old.name != ck.name:
                shutil.rmtree(old, ignore_errors=True)
        print(
            f"[{c.env_id} {STUDENT_ALGO} run {c.seed}] iteration {it + 1}/{p['iterations']}, {steps} steps, "
            f"beta {beta:.3f}, loss {loss_v:.4g}, validation {rec['mean_return']:.2f}",
            file=sys.stderr,
            flush=True,
        )
    venv.close()
    student.save(out / ACTOR_FILE, {"algo": STUDENT_ALGO, "env_id": c.env_id})
    wall = wall_before + time.perf_counter() - t0
    info = {
        **meta_base,
        "timesteps": steps,
        "total_timesteps": p["iterations"] * p["per_env"] * p["n_envs"],
        "requested_timesteps": p["n_timesteps"],
        "iterations": p["iterations"],
        "wall_time_s": round(wall, 1),
        "env_steps_per_s": round(steps / max(wall, 1e-9), 1),
        "sessions": [*sessions, record("finished", p["iterations"])],
        "validation_seeds": val_seeds,
        "best_validation": validation["best"],
        "hyperparams": p,
        "model": "best/actor.pt is the student with the best validation mean return",
        "command": command or "",
        "config": c.as_dict(),
        "interrupted": False,
        "cpu_count": os.cpu_count(),
    }
    _atomic_json(out / "run.json", info)
    return out
