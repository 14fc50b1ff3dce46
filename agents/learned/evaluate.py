"""Evaluate scripted and learned policies alike on gfb_env tasks.

* :class:`LearnedPolicy` wraps a committed SB3 model (``model.zip``) and its VecNormalize statistics
  (``vecnormalize.pkl``) behind the :class:`~gfb_agents.policy.Policy` interface: ``predict`` normalises the
  raw observation with the saved statistics and calls the model.  A policy trained with the privileged
  vector (:data:`ACTOR_ONLY_ALGOS`: the asymmetric actor-critic, the distilled student) is its actor alone
  (:class:`~gfb_agents.learned.asymmetric.DeployedActor`, from ``actor.pt`` or the run's ``model.zip``),
  which takes the public observation only.
* :func:`run_episode` plays one seeded episode and returns an :class:`EpisodeResult` (return, success,
  time to target, final speed, max whirl amplitude, touchdown, the (Lambda, D_W) path).
* :func:`evaluate` plays a fixed list of seeds and :func:`summarise` reduces the results to the benchmark
  row (success rate, mean return with a 95 % confidence interval, ...).

A policy trained with a slew limit on its damping command (``damping_slew`` in ``run.json`` /
``policy.json``; :mod:`gfb_agents.learned.slew`) applies it here as in training: its damping action is a
set-point the command follows by at most ``damping_slew`` per step, from its own previous command.

Learned policies may have memory: a recurrent policy (sb3-contrib ``RecurrentPPO``) gets its state back at
every step (``run_episode`` passes ``state`` through, as SB3's own evaluation does), and a frame-stack
policy (``frame_stack > 1`` in ``run.json``) keeps its last observations per env, as SB3's
``VecFrameStack`` does in training.
"""

from __future__ import annotations

import json
import math
import pickle
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gfb_agents import POLICIES_DIR
from gfb_agents.policy import Policy

__all__ = [
    "LearnedPolicy",
    "EpisodeResult",
    "run_episode",
    "evaluate",
    "summarise",
    "load_learned_policies",
    "run_dirs",
    "run_env_id",
    "POLICIES_DIR",
    "LEARNED_ALGOS",
    "ACTOR_ONLY_ALGOS",
    "algo_class",
]


#: algorithms a learned policy may come from (``gfb_agents.learned.train --algo``)
LEARNED_ALGOS = ("ppo", "sac", "recurrentppo", "asymmetric_ppo", "teacher_student")
#: algorithms trained with the privileged vector (:mod:`gfb_agents.learned.privileged`) beside the
#: observation: their deployed policy is the actor alone
#: (:class:`~gfb_agents.learned.asymmetric.DeployedActor`), which takes the public observation only
ACTOR_ONLY_ALGOS = ("asymmetric_ppo", "teacher_student")
#: the teacher of the teacher-student scheme (:mod:`gfb_agents.learned.teacher_student`): its actor reads
#: the privileged vector, so it is no deployable policy
TEACHER_ALGO = "privileged_ppo"


def algo_class(algo: str):
    """The SB3 / sb3-contrib class of ``algo`` (one of :data:`LEARNED_ALGOS`)."""
    if algo in ("asymmetric_ppo", TEACHER_ALGO):
        from stable_baselines3 import PPO

        return PPO
    if algo == "recurrentppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    from stable_baselines3 import PPO, SAC

    if algo not in ("ppo", "sac"):
        raise ValueError(f"algo must be one of {LEARNED_ALGOS}, got {algo!r}")
    return {"ppo": PPO, "sac": SAC}[algo]


def _model_file(d: Path) -> Path | None:
    """``d/model.zip`` (an SB3 model), else ``d/actor.pt`` (a deployed actor alone), else None."""
    from gfb_agents.learned.asymmetric import ACTOR_FILE

    for name in ("model.zip", ACTOR_FILE):
        if (d / name).exists():
            return d / name
    return None


def _obs_statistics(vn) -> tuple[np.ndarray, np.ndarray] | None:
    """The observation's running mean and variance of a ``VecNormalize`` (its ``"obs"`` entry where the
    training observation was the privileged ``Dict``), None if it did not normalise observations."""
    if not vn.norm_obs:
        return None
    rms = vn.obs_rms
    if isinstance(rms, dict):
        from gfb_agents.learned.privileged import OBS_KEY

        rms = rms[OBS_KEY]
    return np.array(rms.mean, dtype=np.float64), np.array(rms.var, dtype=np.float64)


def _find_meta(*dirs: Path) -> dict:
    for d in dirs:
        for mp in (d / "run.json", d / "policy.json"):
            if mp.exists():
                return json.loads(mp.read_text())
    return {}


def _load_model(path: Path, algo: str):
    """What :class:`LearnedPolicy` calls: the SB3 model of ``path``, or for :data:`ACTOR_ONLY_ALGOS` the
    deployed actor alone (from ``actor.pt``, or taken out of the SB3 model of a training run)."""
    if algo in ACTOR_ONLY_ALGOS:
        from gfb_agents.learned.asymmetric import ACTOR_FILE, DeployedActor

        if path.name == ACTOR_FILE:
            return DeployedActor.load(path)
        return DeployedActor.from_policy(algo_class(algo).load(str(path), device="cpu").policy)
    return algo_class(algo).load(str(path), device="cpu")


class LearnedPolicy(Policy):
    """An SB3 model with its observation normalisation (the files ``gfb_agents.learned.train`` writes).

    Args:
        path: a directory with ``model.zip`` or ``actor.pt`` (+ ``vecnormalize.pkl``, + ``run.json`` or
            ``policy.json`` naming the algo and
            env id), a training run's directory (then ``which`` picks ``best/``, the checkpoint selected on
            the validation seeds, or the final ``model.zip``), or the ``.zip`` itself.
        algo: ``"ppo"``, ``"sac"`` or ``"recurrentppo"`` (default: from ``run.json``).
        name: display name (default: the directory name).
        which: ``"best"`` (default: ``best/model.zip`` where it exists, else the final model) or
            ``"final"``.
    """

    kind = "learned"

    def __init__(
        self, path: str | Path, algo: str | None = None, name: str | None = None, which: str = "best"
    ):
        if which not in ("best", "final"):
            raise ValueError(f"which must be 'best' or 'final', got {which!r}")
        p = Path(path)
        if p.is_dir() and which == "best" and _model_file(p / "best") is not None:
            zip_path = _model_file(p / "best")
        else:
            zip_path = (_model_file(p) or p / "model.zip") if p.is_dir() else p
        d = zip_path.parent
        if not zip_path.exists():
            raise FileNotFoundError(f"no model at {zip_path}")
        meta = _find_meta(d, d.parent) if d.name == "best" else _find_meta(d)
        self.meta = meta
        algo = (algo or meta.get("algo") or "").lower()
        if algo == TEACHER_ALGO:
            raise ValueError(
                f"{zip_path}: a {TEACHER_ALGO} teacher reads the privileged vector, it is not a deployable "
                "policy (distil its student: --algo teacher_student --teacher RUN)"
            )
        if algo not in LEARNED_ALGOS:
            raise ValueError(f"cannot tell the algorithm of {zip_path}; pass algo= one of {LEARNED_ALGOS}")
        self.algo = algo
        self.env_id: str | None = meta.get("env_id")
        self.frame_stack = int(meta.get("frame_stack", 1) or 1)
        self.recurrent = algo == "recurrentppo"
        self.model = _load_model(zip_path, algo)
        self.model_path = zip_path
        # the frozen observation statistics only (the unpickled VecNormalize has no venv and cannot be
        # pickled again, e.g. to a joblib worker)
        self.obs_mean = self.obs_var = None
        self.epsilon, self.clip_obs = 1e-8, 10.0
        vn = d / "vecnormalize.pkl"
        if vn.exists():
            with open(vn, "rb") as fh:
                v = pickle.load(fh)
            stats = _obs_statistics(v)
            if stats is not None:
                self.obs_mean, self.obs_var = stats
                self.epsilon, self.clip_obs = float(v.epsilon), float(v.clip_obs)
        self._args = (str(path), algo, name, which)
        self.name = name or (p.name if p.is_dir() else zip_path.stem)
        self._stack: np.ndarray | None = None  # (n_envs, frame_stack * n_obs), VecFrameStack's layout
        self._set_damping_slew(meta.get("damping_slew"), meta.get("damping_slew_reserve"))

    def _set_damping_slew(self, rate: float | None, reserve: float | None = None) -> None:
        """The slew limit of the damping command the policy was trained with (``damping_slew`` and
        ``damping_slew_reserve`` of its ``run.json`` / ``policy.json``; None: none):
        :mod:`gfb_agents.learned.slew`, part of the policy."""
        from gfb_agents.learned.slew import DampingSlew, check_damping_slew, check_damping_slew_reserve

        self.damping_slew = check_damping_slew(rate)
        self.damping_slew_reserve = check_damping_slew_reserve(reserve, self.damping_slew)
        self._slew = (
            None if self.damping_slew is None else DampingSlew(self.damping_slew, self.damping_slew_reserve)
        )

    @classmethod
    def from_model(
        cls,
        model,
        algo: str,
        vec_normalize=None,
        frame_stack: int = 1,
        name: str = "snapshot",
        damping_slew: float | None = None,
        damping_slew_reserve: float | None = None,
    ) -> LearnedPolicy:
        """A policy of an in-memory model (a training run's current state, for its validation): the
        observation statistics of ``vec_normalize`` are copied (frozen), nothing is read from disk;
        ``damping_slew``, ``damping_slew_reserve``: the run's slew limit of the damping command.
        Not picklable (use the saved files for that)."""
        self = cls.__new__(cls)
        if algo in ACTOR_ONLY_ALGOS:
            from gfb_agents.learned.asymmetric import DeployedActor

            model = DeployedActor.from_policy(model.policy)  # a copy of the actor now: the snapshot
        self.model, self.algo, self.name, self.meta = model, algo, name, {}
        self.model_path = None
        self.env_id, self.frame_stack, self.recurrent = None, int(frame_stack), algo == "recurrentppo"
        self.obs_mean = self.obs_var = None
        self.epsilon, self.clip_obs = 1e-8, 10.0
        stats = None if vec_normalize is None else _obs_statistics(vec_normalize)
        if stats is not None:
            self.obs_mean, self.obs_var = stats
            self.epsilon, self.clip_obs = float(vec_normalize.epsilon), float(vec_normalize.clip_obs)
        self._args = None
        self._stack = None
        self._set_damping_slew(damping_slew, damping_slew_reserve)
        return self

    @classmethod
    def from_actor(
        cls,
        actor,
        vec_normalize_path: str | Path | None,
        frame_stack: int,
        algo: str = "teacher_student",
        damping_slew: float | None = None,
        damping_slew_reserve: float | None = None,
    ) -> LearnedPolicy:
        """A policy of an in-memory :class:`~gfb_agents.learned.asymmetric.DeployedActor` (a student's
        validation) with the observation statistics of a saved ``vecnormalize.pkl``.  Not picklable."""
        vn = None
        if vec_normalize_path is not None and Path(vec_normalize_path).exists():
            with open(vec_normalize_path, "rb") as fh:
                vn = pickle.load(fh)
        self = cls.from_model(
            None,
            algo="",
            vec_normalize=vn,
            frame_stack=frame_stack,
            name="validation",
            damping_slew=damping_slew,
            damping_slew_reserve=damping_slew_reserve,
        )
        self.model, self.algo = actor, algo
        return self

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the model saw it in training (VecNormalize statistics, frozen)."""
        if self.obs_mean is None:
            return np.asarray(obs, dtype=np.float32)
        x = (np.asarray(obs, dtype=np.float64) - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon)
        return np.clip(x, -self.clip_obs, self.clip_obs).astype(np.float32)

    def __reduce__(self):
        # pickled by path (a joblib worker reloads the files)
        if self._args is None:
            raise TypeError("a LearnedPolicy.from_model snapshot cannot be pickled; save the model first")
        return (LearnedPolicy, self._args)

    def reset(self) -> None:
        self._stack = None
        if self._slew is not None:
            self._slew.reset()

    def _stacked(self, x: np.ndarray, episode_start) -> np.ndarray:
        """SB3's ``VecFrameStack`` (channels last): the last ``frame_stack`` normalised observations side
        by side, the oldest first, zeros before the episode's first one."""
        single = x.ndim == 1
        x2 = x[None, :] if single else x
        n, k = x2.shape[0], x2.shape[1]
        starts = (
            np.zeros(n, dtype=bool)
            if episode_start is None
            else np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,))
        )
        if self._stack is None or self._stack.shape[0] != n:
            self._stack = np.zeros((n, self.frame_stack * k), dtype=np.float32)
            starts = np.ones(n, dtype=bool)
        self._stack[starts] = 0.0
        self._stack = np.roll(self._stack, -k, axis=1)
        self._stack[:, -k:] = x2
        return self._stack[0].copy() if single else self._stack.copy()

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | bool | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        x = self.normalize(observation)
        if self.frame_stack > 1:
            x = self._stacked(x, episode_start)
        if self.recurrent and episode_start is not None:
            # RecurrentPPO wants one flag per env, as an array
            n = 1 if x.ndim == 1 else x.shape[0]
            episode_start = np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,)).copy()
        action, state = self.model.predict(
            x, state=state, episode_start=episode_start, deterministic=deterministic
        )
        if self._slew is not None:
            action = self._slewed(observation, action, episode_start)
        return action, state

    def _slewed(self, observation: np.ndarray, action: np.ndarray, episode_start) -> np.ndarray:
        """The commands of the model's actions under the run's slew limit (the transform training applied
        in :class:`~gfb_agents.learned.vec_env.DampingSlewVecEnv`): the previous command is this policy's
        own, from each episode's first (raw) observation on."""
        from gfb_agents.learned.slew import slewed_actions

        return slewed_actions(self._slew, observation, action, episode_start)


def run_dirs(agent_dir: str | Path) -> list[Path]:
    """The model directories of one learned agent's folder, sorted: the folder itself (``model.zip``) or
    its ``seed*/`` / ``run*/`` subfolders with a model (``model.zip`` or ``best/model.zip``; ``actor.pt``,
    a deployed actor alone, counts as a model), one per
    independent training seed (as ``gfb_agents.learned.train --seeds`` and ``export_policy`` write them)."""
    d = Path(agent_dir)
    if _model_file(d) is not None:
        return [d]
    return [
        s
        for s in sorted(d.iterdir())
        if s.is_dir() and (_model_file(s) is not None or _model_file(s / "best") is not None)
    ]


def run_env_id(run_dir: str | Path) -> str | None:
    """The task id a model directory was trained on (its ``run.json`` or ``policy.json``), None if neither."""
    for p in (Path(run_dir) / "run.json", Path(run_dir) / "policy.json"):
        if p.exists():
            return json.loads(p.read_text()).get("env_id")
    return None


def load_learned_policies(root: str | Path = POLICIES_DIR) -> list[LearnedPolicy]:
    """Every committed policy under ``root``: one :class:`LearnedPolicy` per model, sorted by name --
    ``<agent>/model.zip`` (named ``<agent>``) and every training seed of a multi-seed agent
    ``<agent>/seed<r>/`` (named ``<agent>/seed<r>``), the folders :func:`gfb_agents.ladder.learned_entries`
    registers.

    Default ``root``: the policies shipped as package data (``gfb_agents/policies``).  A missing folder
    raises FileNotFoundError (a broken install or a wrong path must not read as "no policies"); an
    existing folder without any model gives ``[]``."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(
            f"no policies folder {root} (expected <name>/model.zip or <name>/seed<r>/model.zip inside; the "
            "committed policies ship with gfb_agents as gfb_agents/policies)"
        )
    out = []
    for d in sorted(root.iterdir()):
        if d.is_dir():
            for r in run_dirs(d):
                out.append(LearnedPolicy(r, name=d.name if r == d else f"{d.name}/{r.name}"))
    return out


@dataclass
class EpisodeResult:
    """Outcome of one episode."""

    seed: int
    episode_return: float
    steps: int
    success: bool
    termination_reason: str | None
    truncated: bool
    time_to_target_s: float
    final_speed_rpm: float
    final_stable: bool
    max_whirl_amplitude: float
    touchdown: bool
    episode_cost: float = math.nan
    damping_command_change: float = math.nan
    path_bearing_number: list[float] = field(default_factory=list)
    path_damping: list[float] = field(default_factory=list)
    path_whirl: list[float] = field(default_factory=list)


def _truth(u: Any, info: dict) -> Mapping[str, Any]:
    """The judge's true quantities of the step: ``info["privileged"]`` where the env was made with
    ``privileged_info=True``, v1's ``info`` (it carries them), else the env's privileged channel
    (``env.unwrapped.privileged_quantities()``: a v2 id; the policy never sees it)."""
    if "privileged" in info:
        return info["privileged"]
    if "whirl_amplitude" in info:
        return info
    return u.privileged_quantities()


def run_episode(
    env: gym.Env, policy: Policy, seed: int, record_path: bool = False, max_steps: int | None = None
) -> EpisodeResult:
    """Play one episode of ``env`` (reset with ``seed``) with ``policy`` (deterministic).

    A policy with an ``observe_reset_info(info)`` method (an oracle:
    :class:`~gfb_agents.oracles.commanded.CommandedOracle`) is handed the reset ``info`` before its first
    action; every other policy sees only observations.

    ``time_to_target_s`` is the rotor time at which the speed first came within the task's tolerance of
    its target (RunUp tasks) or, for tasks without a speed target, the time of success; NaN if never.
    ``episode_cost`` is the sum of ``info["cost"]`` over the steps (NaN for a task without costs);
    ``damping_command_change`` is the mean ``|a_damping(k) - a_damping(k-1)|`` of the *commanded* damping
    (action scale, log D_W: 2 is the whole range; step 0 against the damping of the reset observation),
    the chattering a real actuator would have to follow.
    """
    policy.reset()
    obs, info = env.reset(seed=seed)
    # only an oracle (it says so in its name and docstring) takes the reset info, i.e. the hidden draw
    observe = getattr(policy, "observe_reset_info", None)
    if observe is not None:
        observe(info)
    u = env.unwrapped
    lam_t = info.get("target_bearing_number")
    tol = getattr(u, "target_tolerance", None)
    ret, steps, t_target, max_amp = 0.0, 0, math.nan, 0.0
    # the judge's true quantities: v1's info, or a v2 id's privileged channel (its info carries none)
    tru = _truth(u, info)
    lams, dws, amps = [tru["bearing_number"]], [tru["foil_damping"]], [tru["whirl_amplitude"]]
    start = True
    terminated = truncated = False
    state = None
    prev_a1 = float(obs[u.observation_layout.damping])
    cost, has_cost, dmove = 0.0, False, 0.0
    while True:
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        start = False
        a1 = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[1], -1.0, 1.0))
        dmove += abs(a1 - prev_a1)
        prev_a1 = a1
        obs, r, terminated, truncated, info = env.step(action)
        ret += float(r)
        steps += 1
        if "cost" in info:
            has_cost = True
            cost += float(info["cost"])
        tru = _truth(u, info)
        amp = float(tru["whirl_amplitude"])
        max_amp = max(max_amp, amp if math.isfinite(amp) else 0.0)
        if record_path:
            lams.append(tru["bearing_number"])
            dws.append(tru["foil_damping"])
            amps.append(amp)
        if (
            lam_t is not None
            and tol is not None
            and math.isnan(t_target)
            and abs(tru["bearing_number"] - lam_t) <= tol * lam_t
        ):
            t_target = float(tru["time_s"] if "time_s" in tru else info.get("time_s", math.nan))
        if terminated or truncated or (max_steps is not None and steps >= max_steps):
            break
    reason = info.get("termination_reason")
    success = reason == "success"
    if lam_t is None and success:
        t_target = float(tru["time_s"] if "time_s" in tru else info.get("time_s", math.nan))
    touchdown = reason in ("touchdown", "solver_failure")
    stable = (not touchdown) and float(tru["whirl_amplitude"]) <= u.stable_amplitude
    return EpisodeResult(
        seed,
        ret,
        steps,
        success,
        reason,
        bool(truncated),
        t_target,
        float(info["speed_rpm"]),
        stable,
        max_amp,
        touchdown,
        cost if has_cost else math.nan,
        dmove / steps,
        lams if record_path else [],
        dws if record_path else [],
        amps if record_path else [],
    )


def evaluate(
    env_id: str,
    policy: Policy,
    seeds: list[int],
    env_kwargs: dict | None = None,
    record_path_seeds: tuple[int, ...] = (),
    progress: Any = None,
) -> list[EpisodeResult]:
    """Play ``policy`` on ``env_id`` once per seed (a fresh env, deterministic policy; a retired v1 id, for
    the committed v1 policies' record, on the env ``gfb_env.envs.retired.make_retired`` builds)."""
    from gfb_env.envs import make_env

    env = make_env(env_id, **(env_kwargs or {}))
    out = []
    try:
        for s in seeds:
            out.append(run_episode(env, policy, int(s), record_path=s in record_path_seeds))
            if progress is not None:
                progress.update(1)
    finally:
        env.close()
    return out


def summarise(results: list[EpisodeResult]) -> dict[str, float]:
    """Benchmark row: success rate, mean return and its 95 % CI half-width (Student t), mean time to
    target (over episodes that reached it), mean final speed of episodes that ended stable, mean of the
    per-episode max whirl amplitude (units of C), touchdown count."""
    from scipy import stats

    n = len(results)
    rets = np.array([r.episode_return for r in results])
    ci = float(stats.t.ppf(0.975, n - 1) * rets.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan
    ttt = [r.time_to_target_s for r in results if math.isfinite(r.time_to_target_s)]
    fin = [r.final_speed_rpm for r in results if r.final_stable]
    return {
        "episodes": n,
        "success_rate": float(np.mean([r.success for r in results])) if n else math.nan,
        "mean_return": float(rets.mean()) if n else math.nan,
        "return_ci95": ci,
        "time_to_target_s": float(np.mean(ttt)) if ttt else math.nan,
        "final_speed_rpm": float(np.mean(fin)) if fin else math.nan,
        "final_stable_rate": float(np.mean([r.final_stable for r in results])) if n else math.nan,
        "max_whirl_amplitude": float(np.mean([r.max_whirl_amplitude for r in results])) if n else math.nan,
        "touchdowns": int(sum(r.touchdown for r in results)),
        "mean_steps": float(np.mean([r.steps for r in results])) if n else math.nan,
        "mean_cost": _nanmean([r.episode_cost for r in results]),
        "mean_damping_change": _nanmean([r.damping_command_change for r in results]),
    }


def _nanmean(x: list[float]) -> float:
    a = np.asarray(x, dtype=np.float64)
    return float(a.mean()) if a.size and np.isfinite(a).all() else math.nan
