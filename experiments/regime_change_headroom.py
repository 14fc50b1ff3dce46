"""The oracle's headroom over the best rule on a task with friction-regime changes of the damping
effectiveness (``damping_regime_changes``, :class:`~gfb_env.machine.DampingRegimeChanges`;
``docs/task_redesign.md``), on DEV seeds (0-9999: exploration, never the validation or test split).

    python -m gfb_experiments.regime_change_headroom --task gfb_env/WhirlRecovery-v2 --rate 1.0
        [--factor-range 1.5,2.5] [--seeds 40] [--seed-offset 0] [--agents naive,hold,recovery,...]
        [--out results/task_redesign] [--reps 10000]

Each agent plays the same seeds (``reset(seed=s)``, s = offset .. offset + n - 1) through the benchmark's
episode runner (:func:`gfb_agents.learned.evaluate.run_episode`); the returns are stored per agent as they
finish (``<out>/<task>_rate<r>_f<lo>-<hi>.json``; a rerun resumes, skipping the (agent, seed) pairs it
has).  The statistics are the benchmark's (:mod:`gfb_experiments.benchmark_stats`, ``--normalise
consistent``): the zero is the better of ``naive`` and ``hold`` per aggregate, the IQM columns scaled by
the zero's and the oracle's IQMs, the mean columns by their means, the best rule the one with the highest
normalised IQM, and the paired bootstrap headroom (oracle minus best rule) with 95 % CIs.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder as ladder_mod
from gfb_agents.learned.evaluate import run_episode
from gfb_agents.oracles.commanded import DelayedGainOracle
from gfb_experiments.benchmark_stats import (
    DEFAULT_REPS,
    iqm,
    normalized_scores,
    paired_headroom,
    reference_plan,
)

#: the DEV seed range (``gfb_agents.seeds``): exploration only
DEV_STOP = 10_000
#: the best rules per task (the v2 table's, ``results/benchmark_agents.md``) and the references
DEFAULT_AGENTS = {
    "gfb_env/WhirlRecovery-v2": ("naive", "hold", "recovery", "recovery_reset", "oracle_v1"),
    "gfb_env/RunUp-v2": ("naive", "hold", "margin_search", "margin_search_1x", "oracle_v1"),
    "gfb_env/RunUpRandomized-v2": ("naive", "hold", "margin_search", "margin_search_1x", "oracle_v1"),
}
REFERENCES = ("naive", "hold")
ORACLE = "oracle_v1"
#: the name prefix of the delayed oracles (``oracle_delay10``: 10 control steps late)
DELAYED = "oracle_delay"


def build(name: str, env):
    """A ladder agent, or ``oracle_delay<N>``: the oracle that learns of a regime change N control steps
    late (:class:`~gfb_agents.oracles.commanded.DelayedGainOracle`, a diagnostic reference)."""
    if name.startswith(DELAYED):
        return DelayedGainOracle(env, int(name[len(DELAYED) :]))
    return ladder_mod.build(name, env)


def result_path(out: Path, task: str, rate: float, factor_range: tuple[float, float]) -> Path:
    name = task.split("/")[-1]
    return out / f"{name}_rate{rate:g}_f{factor_range[0]:g}-{factor_range[1]:g}.json"


def play(task: str, env_kwargs: dict, agents: list[str], seeds: list[int], path: Path) -> dict:
    """Play every (agent, seed) not yet in ``path``; store after each episode.  Returns the record."""
    rec = json.loads(path.read_text()) if path.exists() else {"task": task, "env_kwargs": env_kwargs}
    if rec.get("env_kwargs") != env_kwargs:
        raise ValueError(f"{path} holds another configuration: {rec.get('env_kwargs')}")
    rec.setdefault("episodes", {})
    for name in agents:
        done = {e["seed"] for e in rec["episodes"].get(name, [])}
        todo = [s for s in seeds if s not in done]
        if not todo:
            continue
        env = gym.make(task, **env_kwargs)
        pol = build(name, env)
        for s in todo:
            t0 = time.process_time()
            r = run_episode(env, pol, int(s))
            h = env.unwrapped.hidden_parameters()["damping_regime_changes"]
            rec["episodes"].setdefault(name, []).append(
                {
                    "seed": int(s),
                    "return": r.episode_return,
                    "success": r.success,
                    "touchdown": r.touchdown,
                    "steps": r.steps,
                    "changes": len(h["changes"]),
                    "cpu_s": time.process_time() - t0,
                }
            )
            path.write_text(json.dumps(rec, indent=1))
            print(f"{name} seed {s}: return {r.episode_return:.1f} success {r.success} changes "
                  f"{len(h['changes'])}", flush=True)  # fmt: skip
        env.close()
    return rec


def statistics(rec: dict, seeds: list[int], reps: int = DEFAULT_REPS) -> dict:
    """The benchmark's normalised scores (consistent) and the paired headroom on ``seeds``."""
    ret = {}
    for name, eps in rec["episodes"].items():
        by_seed = {e["seed"]: e for e in eps}
        if all(s in by_seed for s in seeds):
            ret[name] = np.array([by_seed[s]["return"] for s in seeds])
    if ORACLE not in ret or not all(r in ret for r in REFERENCES):
        raise ValueError(f"need {ORACLE} and {REFERENCES} on every seed; have {sorted(ret)}")
    plan = reference_plan({k: ret[k] for k in REFERENCES}, "consistent")
    out: dict = {"seeds": len(seeds), "reference": plan, "agents": {}}
    scores = {}
    for name, r in ret.items():
        s_iqm, _ = normalized_scores(r, ret[plan["iqm"]["reference"]], ret[ORACLE], "iqm")
        s_mean, _ = normalized_scores(r, ret[plan["mean"]["reference"]], ret[ORACLE], "mean")
        scores[name] = (s_iqm, s_mean)
        eps = {e["seed"]: e for e in rec["episodes"][name]}
        out["agents"][name] = {
            "normalised_iqm": iqm(s_iqm),
            "normalised_mean": float(np.mean(s_mean)),
            "mean_return": float(np.mean(r)),
            "success": float(np.mean([eps[s]["success"] for s in seeds])),
            "touchdowns": int(sum(eps[s]["touchdown"] for s in seeds)),
        }
    rules = [n for n in scores if n not in (*REFERENCES, ORACLE) and not n.startswith(DELAYED)]
    if rules:
        best = max(rules, key=lambda n: out["agents"][n]["normalised_iqm"])
        (o_i, o_m), (r_i, r_m) = scores[ORACLE], scores[best]
        out["best_rule"] = best
        out["headroom"] = paired_headroom(o_i, r_i, reps=reps, oracle_mean=o_m, rule_mean=r_m)
    # what an idealised change detector with a delay of N steps leaves: oracle minus oracle_delay<N>
    out["delayed"] = {
        n: paired_headroom(scores[ORACLE][0], s[0], reps=reps, oracle_mean=scores[ORACLE][1], rule_mean=s[1])
        for n, s in scores.items()
        if n.startswith(DELAYED)
    }
    changes = [e["changes"] for e in rec["episodes"][ORACLE] if e["seed"] in set(seeds)]
    out["changes_per_episode"] = float(np.mean(changes))
    out["share_with_change"] = float(np.mean(np.asarray(changes) > 0))
    return out


def checked_factors_and_seeds(ap: argparse.ArgumentParser, a: argparse.Namespace) -> tuple[float, float]:
    """``--factor-range`` as (f_min, f_max) and the seeds checked to lie in DEV (``ap.error`` otherwise):
    the refusals this script and :mod:`gfb_experiments.regime_change_detection` share."""
    try:
        lo, hi = (float(x) for x in a.factor_range.split(","))
    except ValueError:
        ap.error(f"--factor-range must be f_min,f_max, got {a.factor_range!r}")
    if not (0 <= a.seed_offset and a.seed_offset + a.seeds <= DEV_STOP and a.seeds >= 1):
        ap.error(f"seeds must lie in the DEV range 0-{DEV_STOP - 1}")
    return lo, hi


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="gfb_env/WhirlRecovery-v2", choices=sorted(DEFAULT_AGENTS))
    ap.add_argument("--rate", type=float, required=True, help="regime changes per second")
    ap.add_argument("--factor-range", default="1.5,2.5", help="f_min,f_max of one change")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--seed-offset", type=int, default=0)
    ap.add_argument("--agents", default=None, help="comma-separated (default: the task's ladder subset)")
    ap.add_argument("--out", default="results/task_redesign")
    ap.add_argument("--reps", type=int, default=DEFAULT_REPS)
    ap.add_argument(
        "--stats-only", action="store_true", help="play nothing; the statistics of what is stored"
    )
    a = ap.parse_args(argv)
    lo, hi = checked_factors_and_seeds(ap, a)
    agents = a.agents.split(",") if a.agents else list(DEFAULT_AGENTS[a.task])
    kw = {"damping_regime_changes": {"rate_per_s": a.rate, "factor_range": [lo, hi]}}
    gym.make(a.task, **kw).close()  # a bad configuration: one line before any episode
    seeds = list(range(a.seed_offset, a.seed_offset + a.seeds))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = result_path(out, a.task, a.rate, (lo, hi))
    rec = json.loads(path.read_text()) if a.stats_only else play(a.task, kw, agents, seeds, path)
    stats = statistics(rec, seeds, a.reps)
    rec["statistics"] = stats
    path.write_text(json.dumps(rec, indent=1))
    print(json.dumps(stats, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
