"""Identifiability report (issue 19 s.3): how well the hidden quantities of a task can be inferred from the
first ``k`` steps of its interface, per channel, against the rules' own posteriors.

Per task id (``--tasks``; the current ids :data:`gfb_env.envs.ENV_IDS` (v2, the default), or a retired v1 id
of :data:`~gfb_env.envs.RETIRED_V1_IDS` to reproduce the record, on the env ``make_retired`` builds):

* **Targets** (from the privileged channel, for scoring only): ``ln_g`` (the hidden damping
  effectiveness, ``env.unwrapped.hidden_parameters()["damping_gain"]``), ``ln_lambda_best`` (the actual
  plant's best stable speed, ``env.unwrapped.best_stable_operating_point().bearing_number``); where the task
  draws the bearing also ``ln_rpm_best`` (the same point in rpm) and ``ln_clearance`` (the drawn C).
* **Data**: episodes under two policies, the same seeds for both: ``probe``, a fixed action sequence (the
  same every episode, :func:`probing_schedule`), and ``rule``, the task's best rule of the ladder
  (``margin_search`` on RunUp*, ``recovery`` on WhirlRecovery*, built by :func:`gfb_agents.ladder.build`).
  Training episodes on the last 10 000 seeds of :data:`~gfb_agents.seeds.TRAIN` (``train_env_seed``'s run 99),
  evaluation on the last 10 000 of :data:`~gfb_agents.seeds.VALIDATION` (away from the first ones that
  ``--split validation`` and the rules' tuning use); never TEST.  Only the first ``max(k)`` steps of each
  episode are simulated.
* **Channels**, each its own regressor input (:func:`channel_rows`): ``obs`` (the observation history),
  ``obs_reward`` (observation and reward history), ``info`` (every real number of ``info``, flattened by
  :func:`gfb_env.envs.privileged.flatten_numbers`, at reset and every step).  Every channel also carries
  the step's ``alive`` flag (1 while the episode runs; ``terminated`` is part of every interface): an
  episode that ended before ``k`` is padded with its last row.
* **Regressor** (:class:`RidgeCV`): ridge regression on standardised features (:class:`FeatureBuilder`:
  the rows of steps 0..k, their step-to-step differences, and the logarithm of every entry that is
  positive in all training episodes), the penalty chosen by 5-fold cross-validation on the training seeds
  only; at prediction each feature is clipped to its training range (no extrapolation).  Scored on the
  evaluation seeds: rms error and ``R^2 = 1 - mse / var_ref`` with ``var_ref`` the documented prior's
  variance (ln g: log-uniform on the actuator's ``gain_range``; ln C: uniform C on ``clearance_range_m``),
  else the training targets' variance (``reference`` in the JSON says which).
* **The rule's own estimates** after ``k`` steps (``rule`` policy only): the posterior mean of ``ln g``
  (``rule.gain_posterior()``) and the identified clearance (``rule.bearing_estimate()``; before the
  identification the prior's mean of ln C), scored the same way.

Reading it: a rule whose rms is well above the regressor's leaves information unused; a channel whose rms
is below what the sensors allow (``info`` on v1: it carries ``damping_gain``) is a leak.  Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.identifiability --out results/identifiability

Writes ``<task>.json`` per task (e.g. ``RunUp-v1.json``) into ``--out``, then remakes ``summary.md`` and
``identifiability.png`` from every task JSON there (a later run on other ids adds its tasks).
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.policy import Policy
from gfb_agents.seeds import TRAIN, VALIDATION
from gfb_env.envs import ENV_IDS, RETIRED_V1_IDS, make_env
from gfb_env.envs.privileged import flatten_numbers
from gfb_env.scripting import OneLineParser, check_output_dir, int_range, write_json

#: the ids the report runs on: the current (v2) ids, and the retired v1 ids for the record (what leaked)
KNOWN_TASKS = (*ENV_IDS, *RETIRED_V1_IDS)

__all__ = [
    "CHANNELS",
    "POLICIES",
    "TRAIN_OFFSET",
    "EVAL_OFFSET",
    "ProbingSchedule",
    "probing_schedule",
    "ProbingPolicy",
    "History",
    "channel_rows",
    "info_paths",
    "FeatureBuilder",
    "RidgeCV",
    "default_rule",
    "simulate",
    "analyse_task",
    "summary_markdown",
    "plot",
    "main",
]

CHANNELS = ("obs", "obs_reward", "info")
POLICIES = ("probe", "rule")
#: the dedicated seed sub-ranges (module docstring): the last 10 000 seeds of TRAIN and of VALIDATION
TRAIN_OFFSET = len(TRAIN) - 10_000
EVAL_OFFSET = len(VALIDATION) - 10_000
DEFAULT_KS = (0, 1, 5, 20)
#: the ridge penalties tried, times the number of training episodes (features standardised)
RIDGE_ALPHAS = tuple(float(a) for a in np.logspace(-4, 4, 17))


# -- the fixed probing policy ---------------------------------------------------------------------------
@dataclass(frozen=True)
class ProbingSchedule:
    """A fixed action sequence: ``blocks`` of ``(steps, speed action, commanded damping D_W)`` in turn, the
    last block held after the listed steps.  The same actions every episode (no feedback)."""

    blocks: tuple[tuple[int, float, float], ...]

    def __post_init__(self) -> None:
        if not self.blocks:
            raise ValueError("blocks: a probing schedule needs at least one block")
        for n, a0, d in self.blocks:
            if not (isinstance(n, int) and n >= 1 and -1.0 <= a0 <= 1.0 and d > 0):
                raise ValueError(
                    f"blocks: need (steps >= 1, speed action in [-1, 1], D_W > 0), got {(n, a0, d)}"
                )

    def command(self, k: int) -> tuple[float, float]:
        """``(speed action, D_W)`` of the ``k``-th action (0-based)."""
        for n, a0, d in self.blocks:
            if k < n:
                return a0, d
            k -= n
        return self.blocks[-1][1], self.blocks[-1][2]

    def describe(self) -> str:
        return ", ".join(f"{n} steps at speed action {a0:g}, D_W = {d:.3g}" for n, a0, d in self.blocks)


def probing_schedule(env_id: str, env) -> ProbingSchedule:
    """The task's probing schedule.  RunUp* (and any id but WhirlRecovery*): hold the start speed (speed
    action 0) and step the damping command through the unbalance probe's levels, 5 steps each:
    0.3, 1.5, 7.0, 1.5 (then 1.5 held).  WhirlRecovery*: the start is a developed whirl that touches down
    if the speed is held, so decelerate at the motor limit (speed action -1) for 20 steps, first 10 at the
    nominal map's ``d_opt`` (the prior's best damping), then 5 each at 1.3 and 3.5; then hold."""
    if "WhirlRecovery" in env_id:
        from gfb_agents.nominal_map import NominalMap

        d_opt = float(NominalMap.from_env(env.unwrapped).d_opt)
        return ProbingSchedule(((10, -1.0, d_opt), (5, -1.0, 1.3), (5, -1.0, 3.5), (1, 0.0, 3.5)))
    return ProbingSchedule(((5, 0.0, 0.3), (5, 0.0, 1.5), (5, 0.0, 7.0), (5, 0.0, 1.5)))


class ProbingPolicy(Policy):
    """:class:`ProbingSchedule` as a policy (one env): ignores the observation, counts its steps."""

    def __init__(self, env, schedule: ProbingSchedule, name: str = "probe"):
        self.name = name
        self.schedule = schedule
        self.actions = env.unwrapped.actions
        self.k = 0

    def reset(self) -> None:
        self.k = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if episode_start is not None and bool(np.any(episode_start)):
            self.k = 0
        a0, d = self.schedule.command(self.k)
        self.k += 1
        return np.array([a0, self.actions.action_from_damping(d)], dtype=np.float32), state


def default_rule(env_id: str) -> str:
    """The task's best rule of the ladder: ``recovery`` on WhirlRecovery*, ``margin_search`` otherwise."""
    return "recovery" if "WhirlRecovery" in env_id else "margin_search"


# -- one episode's interface, and the channels ----------------------------------------------------------
@dataclass
class History:
    """The first steps of one episode as the interface gave them.

    Attributes:
        obs: observations at reset and after each step, ``(steps + 1, n_obs)``.
        rewards: the rewards of the steps, ``(steps,)``.
        info: every real number of ``info`` (path -> value) at reset and after each step.
        steps: steps actually taken (fewer than asked if the episode ended).
    """

    obs: np.ndarray
    rewards: np.ndarray
    info: list[dict[str, float]]
    steps: int


def info_paths(histories: Sequence[History]) -> list[str]:
    """The info channel's schema: every path seen in ``histories`` (sorted; a path missing from a row
    reads 0)."""
    return sorted({p for h in histories for row in h.info for p in row})


def channel_rows(h: History, channel: str, n_steps: int, paths: Sequence[str] = ()) -> np.ndarray:
    """The rows of ``channel`` for steps 0..n_steps, shape ``(n_steps + 1, d)``: ``obs`` (the
    observation), ``obs_reward`` (observation and the step's reward, 0 at reset), ``info`` (the values at
    ``paths``); each with a last column ``alive`` (1 for a step the episode took).  An episode that ended
    earlier is padded with its last row (reward 0, alive 0).  Each channel reads only its own part of the
    history."""
    if channel not in CHANNELS:
        raise ValueError(f"channel must be one of {CHANNELS}, got {channel!r}")
    n = n_steps + 1
    last = min(h.steps, n_steps)
    idx = np.minimum(np.arange(n), last)
    alive = (np.arange(n) <= last).astype(float)[:, None]
    if channel == "info":
        vals = np.array([[row.get(p, 0.0) for p in paths] for row in h.info], dtype=float)
        vals = vals.reshape(len(h.info), len(paths))[idx]
        return np.hstack([vals, alive])
    obs = np.asarray(h.obs, dtype=float)[idx]
    if channel == "obs":
        return np.hstack([obs, alive])
    r = np.zeros(n)
    m = min(len(h.rewards), n_steps)
    r[1 : m + 1] = np.asarray(h.rewards, dtype=float)[:m]
    r[last + 1 :] = 0.0
    return np.hstack([obs, r[:, None], alive])


class FeatureBuilder:
    """Summary features of the rows of steps ``0..k``: the entries, their step-to-step differences and the
    logarithm of every entry that is positive in every training episode (a quantity whose log is the
    target, like a leaked gain, becomes linear).  Fitted on the training rows only."""

    def __init__(self, k: int):
        if isinstance(k, bool) or not isinstance(k, int) or k < 0:
            raise ValueError(f"k must be a non-negative integer, got {k!r}")
        self.k = k
        self.log_mask: np.ndarray | None = None

    def _raw(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.asarray(rows, dtype=float)[: self.k + 1]
        if r.shape[0] != self.k + 1:
            raise ValueError(f"rows: need at least k + 1 = {self.k + 1} rows, got {r.shape[0]}")
        return r.ravel(), np.diff(r, axis=0).ravel()

    def fit(self, rows: Sequence[np.ndarray]) -> FeatureBuilder:
        flat = np.array([self._raw(r)[0] for r in rows])
        self.log_mask = np.all(flat > 0, axis=0)
        # an evaluation entry below every training value (e.g. 0 where training saw only positives) is
        # logged at the training minimum: ln of a tiny number would be an extreme, unseen feature
        self.log_floor = flat[:, self.log_mask].min(axis=0) if len(flat) else np.zeros(0)
        return self

    def transform(self, rows: Sequence[np.ndarray]) -> np.ndarray:
        if self.log_mask is None:
            raise RuntimeError("FeatureBuilder.transform before fit")
        out = []
        for r in rows:
            flat, diff = self._raw(r)
            logs = np.log(np.maximum(flat[self.log_mask], self.log_floor))
            out.append(np.r_[flat, diff, logs])
        return np.array(out)

    def n_features(self, d: int) -> int:
        """The feature count for rows of width ``d`` (after :meth:`fit`)."""
        return (self.k + 1) * d + self.k * d + int(self.log_mask.sum())


class RidgeCV:
    """Ridge regression on standardised features, the penalty ``alpha x n_train`` chosen from ``alphas`` by
    ``folds``-fold cross-validation on the training set (contiguous folds; constant features dropped)."""

    def __init__(self, alphas: Sequence[float] = RIDGE_ALPHAS, folds: int = 5):
        if not alphas or any(not (a > 0) for a in alphas):
            raise ValueError("alphas must be positive")
        self.alphas = tuple(float(a) for a in alphas)
        self.folds = int(folds)
        self.alpha: float | None = None
        self.cv_rms: float | None = None

    @staticmethod
    def _solve(X: np.ndarray, y: np.ndarray, lams: Sequence[float]) -> list[np.ndarray]:
        U, s, Vt = np.linalg.svd(X, full_matrices=False)
        uy = U.T @ y
        return [Vt.T @ (s / (s * s + lam) * uy) for lam in lams]

    def _prep(self, X: np.ndarray) -> np.ndarray:
        return (X[:, self.keep] - self.mu) / self.sd

    def fit(self, X: np.ndarray, y: np.ndarray) -> RidgeCV:
        X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=float)
        n = len(y)
        if n < 2 or X.shape[0] != n:
            raise ValueError(f"need >= 2 training rows matching y, got X {X.shape}, y {y.shape}")
        sd = X.std(axis=0)
        self.keep = sd > 1e-12 * (1.0 + np.abs(X).max(axis=0))
        self.mu, self.sd = X[:, self.keep].mean(axis=0), sd[self.keep]
        self.y0 = float(y.mean())
        Z = self._prep(X)
        self.zlo, self.zhi = Z.min(axis=0), Z.max(axis=0)
        folds = max(2, min(self.folds, n))
        fold = np.arange(n) * folds // n
        lams = [a * n for a in self.alphas]
        if Z.shape[1] == 0:
            self.coef, self.alpha, self.cv_rms = np.zeros(0), self.alphas[0], float(np.std(y))
            return self
        err = np.zeros(len(lams))
        for f in range(folds):
            tr, te = fold != f, fold == f
            zm, ym = Z[tr].mean(axis=0), y[tr].mean()  # the fold's own centring (its intercept)
            for i, c in enumerate(self._solve(Z[tr] - zm, y[tr] - ym, lams)):
                err[i] += float(np.sum(((Z[te] - zm) @ c + ym - y[te]) ** 2))
        best = int(np.argmin(err))
        self.alpha, self.cv_rms = self.alphas[best], math.sqrt(err[best] / n)
        self.coef = self._solve(Z, y - self.y0, [lams[best]])[0]
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if self.coef.size == 0:
            return np.full(X.shape[0], self.y0)
        # a linear model must not extrapolate: each feature clipped to its training range (an episode
        # outside the training range then predicts like the nearest training ones)
        return np.clip(self._prep(X), self.zlo, self.zhi) @ self.coef + self.y0


# -- simulation ---------------------------------------------------------------------------------------
def _uniform_log_moments(lo: float, hi: float) -> tuple[float, float]:
    """Mean and variance of ln X for X uniform on ``[lo, hi]``."""

    def prim(x: float, p: int) -> float:  # antiderivatives of ln^p x
        lx = math.log(x)
        return x * (lx - 1) if p == 1 else x * (lx * lx - 2 * lx + 2)

    m1 = (prim(hi, 1) - prim(lo, 1)) / (hi - lo)
    m2 = (prim(hi, 2) - prim(lo, 2)) / (hi - lo)
    return m1, max(m2 - m1 * m1, 0.0)


def prior_references(env) -> dict[str, dict[str, float]]:
    """The documented priors' mean and variance of the targets the task documents (ln g: log-uniform on
    the actuator's ``gain_range``; ln C: uniform C on ``clearance_range_m``)."""
    u = env.unwrapped
    out: dict[str, dict[str, float]] = {}
    act = getattr(u, "damping_actuator", None)
    gr = getattr(act, "gain_range", None)
    if gr is not None:
        lo, hi = math.log(gr[0]), math.log(gr[1])
        out["ln_g"] = {"mean": 0.5 * (lo + hi), "var": (hi - lo) ** 2 / 12.0}
    cr = getattr(u, "clearance_range_m", None)
    if cr is not None:
        m, v = _uniform_log_moments(float(cr[0]), float(cr[1]))
        out["ln_clearance"] = {"mean": m, "var": v}
    return out


def _rule_estimates(policy, prior: dict[str, dict[str, float]]) -> dict[str, float]:
    """The rule's estimates now: the posterior mean of ln g, the identified ln C (else the prior mean)."""
    out: dict[str, float] = {}
    post_of = getattr(policy, "gain_posterior", None)
    post = post_of() if callable(post_of) else None
    if post is not None:
        out["ln_g"] = float(post.weights @ np.log(post.gains))
    if "ln_clearance" in prior:
        est_of = getattr(policy, "bearing_estimate", None)
        if callable(est_of):
            est = est_of()
            out["ln_clearance"] = (
                math.log(est.clearance_m) if est is not None else prior["ln_clearance"]["mean"]
            )
    return out


def simulate(
    env_id: str, policy: str, seeds: Sequence[int], n_steps: int, rule: str, targets: bool
) -> list[dict[str, Any]]:
    """Play ``seeds`` of ``env_id`` for ``n_steps`` steps (fewer if the episode ends) under ``policy``
    (``probe`` or ``rule``, the ladder's agent ``rule``).  Per episode: its :class:`History`, ``g`` (to
    check that both policies saw the same plant), where ``targets`` the targets, and for the rule its
    estimates after each observation (``rule_estimates[j]``: having seen observations 0..j)."""
    from gfb_agents.ladder import build

    env = make_env(env_id)
    u = env.unwrapped
    prior = prior_references(env)
    pol = ProbingPolicy(env, probing_schedule(env_id, env)) if policy == "probe" else build(rule, env)
    out = []
    for seed in seeds:
        t0 = time.perf_counter()
        pol.reset()
        obs, info = env.reset(seed=int(seed))
        hp = u.hidden_parameters()
        rec: dict[str, Any] = {"seed": int(seed), "ln_g": math.log(hp["damping_gain"])}
        if targets:
            t1 = time.perf_counter()
            best = u.best_stable_operating_point()
            rec["best_point_s"] = time.perf_counter() - t1
            tg = {"ln_g": rec["ln_g"], "ln_lambda_best": math.log(best.bearing_number)}
            if hp.get("bearing") is not None:
                tg["ln_rpm_best"] = math.log(best.speed_rpm)
                tg["ln_clearance"] = math.log(hp["bearing"]["clearance_m"])
            rec["targets"] = tg
        obs_l, rew_l, info_l, est_l = [np.asarray(obs, dtype=float)], [], [dict(flatten_numbers(info))], []
        steps = 0
        for k in range(n_steps + 1):
            # the action after observation k; the rule's estimates then include observation k
            action, _ = pol.predict(obs, episode_start=(k == 0))
            if policy == "rule":
                est_l.append(_rule_estimates(pol, prior))
            if k == n_steps:
                break
            obs, r, term, trunc, info = env.step(action)
            obs_l.append(np.asarray(obs, dtype=float))
            rew_l.append(float(r))
            info_l.append(dict(flatten_numbers(info)))
            steps += 1
            if term or trunc:
                break
        rec["history"] = History(np.array(obs_l), np.array(rew_l), info_l, steps)
        rec["rule_estimates"] = est_l
        rec["episode_s"] = time.perf_counter() - t0
        out.append(rec)
    env.close()
    return out


def _simulate_all(
    env_id: str, policies: Sequence[str], seeds: Sequence[int], n_steps: int, rule: str, jobs: int
) -> tuple[dict[str, list[dict]], dict[str, float]]:
    """Every policy's episodes on ``seeds`` (the first policy also computes the targets), in ``jobs``
    joblib workers; the wall time per policy."""
    from joblib import Parallel, delayed

    chunks = [list(c) for c in np.array_split(np.asarray(seeds), max(1, jobs)) if len(c)]
    res: dict[str, list[dict]] = {}
    wall: dict[str, float] = {}
    for i, pol in enumerate(policies):
        t0 = time.perf_counter()
        parts = Parallel(n_jobs=jobs)(
            delayed(simulate)(env_id, pol, [int(s) for s in c], n_steps, rule, i == 0) for c in chunks
        )
        wall[pol] = time.perf_counter() - t0
        res[pol] = [r for p in parts for r in p]
    first = res[policies[0]]
    for pol in policies[1:]:
        for a, b in zip(first, res[pol], strict=True):
            if a["seed"] != b["seed"] or a["ln_g"] != b["ln_g"]:  # the same seed must give the same plant
                raise RuntimeError(f"{env_id} seed {a['seed']}: the policies saw different plants")
            b["targets"] = a["targets"]
    return res, wall


def _score(pred: np.ndarray, y: np.ndarray, var_ref: float) -> dict[str, float]:
    mse = float(np.mean((pred - y) ** 2))
    return {"rms": math.sqrt(mse), "r2": 1.0 - mse / var_ref if var_ref > 0 else float("nan")}


def analyse_task(
    env_id: str,
    ks: Sequence[int],
    n_train: int,
    n_eval: int,
    policies: Sequence[str] = POLICIES,
    rule: str | None = None,
    jobs: int = 1,
) -> dict[str, Any]:
    """Simulate and score one task (module docstring); a JSON-serialisable report."""
    rule = rule or default_rule(env_id)
    n_steps = max(ks)
    train = TRAIN.first(n_train, TRAIN_OFFSET)
    evals = VALIDATION.first(n_eval, EVAL_OFFSET)
    env = make_env(env_id)
    prior = prior_references(env)
    schedule = probing_schedule(env_id, env)
    env.close()
    sims: dict[str, dict[str, list[dict]]] = {}
    wall: dict[str, dict[str, float]] = {}
    for split, seeds in (("train", train), ("eval", evals)):
        sims[split], wall[split] = _simulate_all(env_id, policies, seeds, n_steps, rule, jobs)
    drawn = list(sims["train"][policies[0]][0]["targets"])
    ytr = {t: np.array([r["targets"][t] for r in sims["train"][policies[0]]]) for t in drawn}
    yev = {t: np.array([r["targets"][t] for r in sims["eval"][policies[0]]]) for t in drawn}
    # a target the task does not vary (lambda_best of a nominal bearing: every gain reaches D_opt) is
    # known from the public configuration: reported as a constant, not regressed
    constant = {
        t: float(ytr[t][0]) for t in drawn if np.ptp(np.r_[ytr[t], yev[t]]) <= 1e-9 * (1 + abs(ytr[t][0]))
    }
    target_names = [t for t in drawn if t not in constant]
    reference = {}
    for t in target_names:
        if t in prior:
            reference[t] = {"var": prior[t]["var"], "source": "prior"}
        else:
            reference[t] = {"var": float(np.var(ytr[t])), "source": "training"}
    rows = []
    t_fit = time.perf_counter()
    for pol in policies:
        htr = [r["history"] for r in sims["train"][pol]]
        hev = [r["history"] for r in sims["eval"][pol]]
        paths = info_paths(htr)
        for ch in CHANNELS:
            rtr = [channel_rows(h, ch, n_steps, paths) for h in htr]
            rev = [channel_rows(h, ch, n_steps, paths) for h in hev]
            for k in ks:
                fb = FeatureBuilder(k).fit(rtr)
                Xtr, Xev = fb.transform(rtr), fb.transform(rev)
                for t in target_names:
                    var = reference[t]["var"]
                    reg = RidgeCV().fit(Xtr, ytr[t])
                    row = {
                        "policy": pol,
                        "channel": ch,
                        "k": k,
                        "target": t,
                        **_score(reg.predict(Xev), yev[t], var),
                        "alpha": reg.alpha,
                        "features": int(Xtr.shape[1]),
                        "prior_rms": _score(np.full(len(yev[t]), ytr[t].mean()), yev[t], var)["rms"],
                    }
                    if pol == "rule" and sims["eval"][pol][0]["rule_estimates"]:
                        est = [
                            r["rule_estimates"][min(k, len(r["rule_estimates"]) - 1)]
                            for r in sims["eval"][pol]
                        ]
                        if all(t in e for e in est):
                            s = _score(np.array([e[t] for e in est]), yev[t], var)
                            row["rule_rms"], row["rule_r2"] = s["rms"], s["r2"]
                    rows.append(row)
    fit_s = time.perf_counter() - t_fit
    eps = [r for split in sims.values() for p in split.values() for r in p]
    alive = {
        pol: float(np.mean([r["history"].steps >= n_steps for r in sims["eval"][pol]])) for pol in policies
    }
    return {
        "task": env_id,
        "ks": list(ks),
        "steps_simulated": n_steps,
        "train_seeds": [train[0], train[-1]],
        "eval_seeds": [evals[0], evals[-1]],
        "n_train": n_train,
        "n_eval": n_eval,
        "policies": {"probe": schedule.describe(), "rule": rule},
        "channels": list(CHANNELS),
        "targets": target_names,
        "constant_targets": constant,
        "reference": reference,
        "eval_target_sd": {t: float(np.std(yev[t])) for t in target_names},
        "eval_episodes_alive_at_max_k": alive,
        "cost": {
            "simulation_wall_s": wall,
            "episode_s_mean": {
                pol: float(np.mean([r["episode_s"] for s in sims.values() for r in s[pol]]))
                for pol in policies
            },
            "best_point_s_mean": float(np.mean([r["best_point_s"] for r in eps if "best_point_s" in r])),
            "regression_s": fit_s,
            "jobs": jobs,
        },
        "rows": rows,
    }


# -- report -----------------------------------------------------------------------------------------
def _file_name(env_id: str) -> str:
    return env_id.split("/")[-1] + ".json"


def _fmt(v: Any, nd: int = 3) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{nd}f}"


def _skill(rms: float, prior_rms: float) -> float:
    """``1 - mse / mse_no_information`` on the evaluation seeds (R^2 against the sample's own spread: a
    small evaluation set's spread differs from the prior's, e.g. sd 0.53 against 0.665)."""
    return 1.0 - (rms / prior_rms) ** 2 if prior_rms > 0 else float("nan")


def _prior_rms(rep: dict[str, Any]) -> dict[str, float]:
    """The no-information rms (the training mean as the prediction) of each target."""
    out: dict[str, float] = {}
    for r in rep["rows"]:
        out.setdefault(r["target"], r["prior_rms"])
    return out


def summary_markdown(reports: Sequence[dict[str, Any]]) -> str:
    """The summary: per task the ln g table (task, policy, channel, k, rms, R^2, the rule's rms), then
    the other targets' rms."""
    lines = [
        "# Identifiability of the hidden quantities (issue 19 s.3)",
        "",
        "Made by `python -m gfb_experiments.identifiability` (docs/identifiability.md says how to read it).",
        "rms: error of a ridge regressor trained on training seeds, on the evaluation seeds; R^2 = 1 - mse /",
        "the prior's variance; skill = 1 - mse / mse of the no-information prediction (the training mean) on",
        "the same evaluation seeds; rule's rms: the rule's own posterior mean after the same k steps.",
        "",
    ]
    for rep in reports:
        ref = rep["reference"]
        lines += [
            f"## {rep['task']}",
            "",
            f"{rep['n_train']} training / {rep['n_eval']} evaluation episodes, "
            f"{rep['steps_simulated']} steps each; probe: {rep['policies']['probe']}; "
            f"rule: `{rep['policies']['rule']}`.  "
            + "; ".join(f"{t}: reference sd {math.sqrt(ref[t]['var']):.3f} ({ref[t]['source']})" for t in ref)
            + "".join(
                f"; predicting the training mean of {t} gives rms {pr:.3f} on these evaluation seeds"
                for t, pr in _prior_rms(rep).items()
            )
            + "".join(
                f"; {t} is the same on every episode ({math.exp(v):.4g}: known from the public configuration)"
                for t, v in rep.get("constant_targets", {}).items()
            )
            + ".",
            "",
            "| task | policy | channel | k | rms ln g | R^2 | skill | rule's rms |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for r in rep["rows"]:
            if r["target"] == "ln_g":
                lines.append(
                    f"| {rep['task'].split('/')[-1]} | {r['policy']} | {r['channel']} | {r['k']} | "
                    f"{_fmt(r['rms'])} | {_fmt(r['r2'], 2)} | {_fmt(_skill(r['rms'], r['prior_rms']), 2)} | "
                    f"{_fmt(r.get('rule_rms'))} |"
                )
        others = [t for t in rep["targets"] if t != "ln_g"]
        if others:
            lines += ["", "| policy | channel | k | " + " | ".join(f"rms {t} (R^2)" for t in others) + " |"]
            lines.append("|---|---|---|" + "---|" * len(others))
            by = {(r["policy"], r["channel"], r["k"], r["target"]): r for r in rep["rows"]}
            for pol in rep["policies"]:
                for ch in rep["channels"]:
                    for k in rep["ks"]:
                        cells = []
                        for t in others:
                            r = by.get((pol, ch, k, t))
                            if r is None:
                                cells.append("-")
                                continue
                            c = f"{_fmt(r['rms'], 4)} ({_fmt(r['r2'], 2)})"
                            if "rule_rms" in r:
                                c += f"; rule {_fmt(r['rule_rms'], 4)}"
                            cells.append(c)
                        lines.append(f"| {pol} | {ch} | {k} | " + " | ".join(cells) + " |")
        c = rep["cost"]
        lines += [
            "",
            "Cost: simulation "
            + ", ".join(
                f"{pol} {sum(w[pol] for w in c['simulation_wall_s'].values()):.0f} s "
                f"({c['episode_s_mean'][pol]:.2f} s per episode)"
                for pol in rep["policies"]
            )
            + f", best point {c['best_point_s_mean']:.2f} s per episode, "
            + f"regressions {c['regression_s']:.0f} s ({c['jobs']} worker(s)).",
            "",
        ]
    return "\n".join(lines)


def plot(reports: Sequence[dict[str, Any]], path: Path) -> Path:
    """rms error of ln g against k per channel and policy (one panel per task), the rule's posterior and
    the prior's sd for comparison."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(reports), figsize=(4.6 * len(reports), 3.8), squeeze=False)
    colors = {"obs": "tab:blue", "obs_reward": "tab:orange", "info": "tab:red"}
    styles = {"probe": "-", "rule": "--"}
    for ax, rep in zip(axes[0], reports, strict=True):
        rows = [r for r in rep["rows"] if r["target"] == "ln_g"]
        for pol in rep["policies"]:
            for ch in rep["channels"]:
                sel = sorted(
                    (r for r in rows if r["policy"] == pol and r["channel"] == ch), key=lambda r: r["k"]
                )
                if sel:
                    ax.plot(
                        [r["k"] for r in sel],
                        [r["rms"] for r in sel],
                        styles.get(pol, ":"),
                        color=colors.get(ch, "k"),
                        marker="o",
                        ms=3,
                        label=f"{ch} ({pol})",
                    )
            sel = sorted((r for r in rows if r["policy"] == pol and "rule_rms" in r), key=lambda r: r["k"])
            if sel:
                ax.plot(
                    [r["k"] for r in sel],
                    [r["rule_rms"] for r in sel],
                    "k:",
                    marker="s",
                    ms=4,
                    label="the rule's own posterior mean",
                )
        sd = math.sqrt(rep["reference"]["ln_g"]["var"])
        none = _prior_rms(rep)["ln_g"]
        ax.axhline(sd, color="gray", lw=0.8)
        ax.axhline(none, color="gray", lw=0.8, ls="--")
        ax.text(0, sd, " prior sd", va="bottom", fontsize=7, color="gray")
        ax.text(max(rep["ks"]), none, "no information ", va="bottom", ha="right", fontsize=7, color="gray")
        ax.set_xscale("symlog", linthresh=1)
        ax.set_xticks(rep["ks"])
        ax.set_xticklabels([str(k) for k in rep["ks"]])
        ax.set_xlim(min(rep["ks"]) - 0.1, 1.1 * max(rep["ks"]))
        top = 1.25 * max(sd, none)
        ax.set_ylim(0, top)  # an rms above the no-information level is off the panel's top
        ax.set_xlabel("steps k")
        ax.set_ylabel("rms error of ln g (evaluation seeds)")
        ax.set_title(f"{rep['task'].split('/')[-1]} (rule: {rep['policies']['rule']})", fontsize=10)
    axes[0][0].legend(fontsize=6.5, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _load_reports(out: Path) -> list[dict[str, Any]]:
    reps = []
    for f in sorted(out.glob("*.json")):
        try:
            rep = json.loads(f.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if isinstance(rep, dict) and "rows" in rep and "task" in rep:
            reps.append(rep)
    return reps


# -- CLI -----------------------------------------------------------------------------------------------
def _task_list(text: str) -> list[str]:
    import argparse

    tasks = [t.strip() for t in text.split(",") if t.strip()]
    if not tasks:
        raise argparse.ArgumentTypeError("--tasks must name at least one task id")
    bad = [t for t in tasks if t not in KNOWN_TASKS]
    if bad:
        known = ", ".join(KNOWN_TASKS)
        raise argparse.ArgumentTypeError(f"--tasks: unknown task id {bad[0]!r}; known: {known}")
    return tasks


def _k_list(text: str) -> list[int]:
    import argparse

    try:
        ks = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--ks must be comma-separated integers, got {text!r}") from None
    if not ks or any(k < 0 or k > 250 for k in ks):
        raise argparse.ArgumentTypeError(f"--ks must be integers in [0, 250], got {text!r}")
    return sorted(set(ks))


def _policy_list(text: str) -> list[str]:
    import argparse

    pols = [t.strip() for t in text.split(",") if t.strip()]
    if not pols or any(p not in POLICIES for p in pols) or len(set(pols)) != len(pols):
        raise argparse.ArgumentTypeError(f"--policies must be a comma list of {POLICIES}, got {text!r}")
    return pols


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="gfb_experiments.identifiability", description=__doc__.splitlines()[0])
    p.add_argument(
        "--tasks",
        type=_task_list,
        default=list(ENV_IDS),
        help="comma-separated task ids (default: the current, v2 ids; a retired v1 id replays the record)",
    )
    p.add_argument("--ks", type=_k_list, default=list(DEFAULT_KS), help="steps k (default 0,1,5,20)")
    p.add_argument("--train", type=int_range("--train", 5, 10_000), default=150, help="training episodes")
    p.add_argument("--eval", type=int_range("--eval", 2, 10_000), default=50, help="evaluation episodes")
    p.add_argument("--policies", type=_policy_list, default=list(POLICIES), help="probe,rule (default both)")
    p.add_argument(
        "--rule",
        action="append",
        default=[],
        metavar="[TASK=]NAME",
        help="the ladder's rule for every task, or TASK=NAME for one (repeatable; default: recovery on "
        "WhirlRecovery*, margin_search otherwise)",
    )
    p.add_argument("--jobs", type=int_range("--jobs", 1, 2), default=1, help="joblib workers (1 or 2)")
    p.add_argument("--out", default="results/identifiability", help="output folder")
    p.add_argument(
        "--summary-only",
        action="store_true",
        help="simulate nothing: remake summary.md and identifiability.png from the task JSONs in --out",
    )
    a = p.parse_args(argv)
    names = [_file_name(t) for t in a.tasks] + ["summary.md", "identifiability.png"]
    try:
        out = check_output_dir(a.out, "--out", names)
    except ValueError as exc:
        p.error(str(exc))
    rules = {t: default_rule(t) for t in a.tasks}
    for item in a.rule:
        task, _, name = item.rpartition("=")
        if task and task not in a.tasks:
            p.error(f"--rule {item}: task {task!r} is not in --tasks")
        for t in [task] if task else a.tasks:
            rules[t] = name
    if "rule" in a.policies:
        from gfb_agents.ladder import registered

        known = registered()
        bad = [n for n in rules.values() if n not in known]
        if bad:
            p.error(f"--rule: no agent {bad[0]!r} in the ladder")
    out.mkdir(parents=True, exist_ok=True)
    for task in [] if a.summary_only else a.tasks:
        t0 = time.perf_counter()
        rep = analyse_task(task, a.ks, a.train, a.eval, a.policies, rules[task], a.jobs)
        rep["cost"]["total_s"] = time.perf_counter() - t0
        write_json(out / _file_name(task), rep)
        print(f"{task}: {rep['cost']['total_s']:.0f} s", flush=True)
    reps = _load_reports(out)
    if not reps:
        p.error(f"--out {a.out}: no task report (<task>.json) to summarise")
    text = summary_markdown(reps)
    (out / "summary.md").write_text(text + "\n")
    plot(reps, out / "identifiability.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
