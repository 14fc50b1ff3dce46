"""Check that the v1 (commanded-speed) tasks are well posed: the oracle against the naive ramp.

For each v1 task, on training seeds (default 0-49): the return, success, certification and episode cost
of :class:`gfb_agents.oracle.CommandedOracle` (``oracle_v1``, knows every hidden parameter) and of
:class:`gfb_agents.oracle.CommandedRamp` (``naive_v1``, the paper's constant-damping ramp to the command,
capped at 0.95 Lambda_c(D_W = 1) of the nominal bearing); also the wall time per control step.  With
``--margins`` it instead tunes the oracle's margin on the given (training) seeds.  Run::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.v1_task_check \\
        --seeds 0-49 --out results/v1_task_check/summary.json

Writes one JSON summary (per task and agent: mean return, its 95 % CI half width, success rate,
certified rate, touchdowns, mean episode cost, ms per step).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401
from gfb_agents.oracle import CommandedOracle, CommandedRamp
from gfb_env._cli_common import OneLineParser

V1_IDS = ("gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1")


def play(env: gym.Env, agent, seed: int) -> dict:
    """One episode: return, success, certificate, cost, steps and wall time of the steps."""
    obs, info = env.reset(seed=seed)
    agent.reset(env, obs, info)
    ret, steps, t = 0.0, 0, 0.0
    while True:
        a = agent.act(obs)
        t0 = time.perf_counter()
        obs, r, term, trunc, info = env.step(a)
        t += time.perf_counter() - t0
        ret += float(r)
        steps += 1
        if term or trunc:
            break
    return {
        "seed": seed,
        "return": ret,
        "success": bool(info["is_success"]),
        "certified": bool(info["certified"]),
        "reason": str(info["termination_reason"]),
        "certification": info["certification"],
        "episode_cost": float(info["episode_cost"]),
        "steps": steps,
        "step_s": t,
        "final_speed_rpm": float(info["speed_rpm"]),
        "command_rpm": float(info["speed_command_rpm"]),
    }


def summarise(rows: list[dict]) -> dict:
    r = np.array([x["return"] for x in rows])
    n = len(r)
    return {
        "episodes": n,
        "mean_return": float(r.mean()),
        "return_ci95": float(1.96 * r.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan,
        "success_rate": float(np.mean([x["success"] for x in rows])),
        "certified_rate": float(np.mean([x["certified"] for x in rows])),
        "touchdowns": int(sum(x["reason"] in ("touchdown", "solver_failure") for x in rows)),
        "mean_episode_cost": float(np.mean([x["episode_cost"] for x in rows])),
        "ms_per_step": float(1e3 * sum(x["step_s"] for x in rows) / sum(x["steps"] for x in rows)),
    }


def parse_seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        if "-" in part:
            a, b = (int(x) for x in part.split("-"))
            out.extend(range(a, b + 1))
        else:
            out.append(int(part))
    return out


def main(argv: list[str] | None = None) -> None:
    p = OneLineParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-49", help="training seeds, e.g. 0-49 (never the test seeds)")
    p.add_argument("--tasks", default=",".join(V1_IDS))
    p.add_argument("--margins", default="", help="tune the oracle's margin: comma-separated values")
    p.add_argument("--out", default="results/v1_task_check/summary.json")
    a = p.parse_args(argv)
    seeds = parse_seeds(a.seeds)
    if min(seeds) < 0 or max(seeds) > 99:
        p.error("--seeds: only training seeds 0-99")
    out: dict = {"seeds": a.seeds, "tasks": {}}
    for env_id in a.tasks.split(","):
        env = gym.make(env_id)
        res: dict = {}
        if a.margins:
            for m in (float(x) for x in a.margins.split(",")):
                res[f"oracle_margin_{m:g}"] = summarise(
                    [play(env, CommandedOracle(env, margin=m), s) for s in seeds]
                )
                print(env_id, m, res[f"oracle_margin_{m:g}"], flush=True)
        else:
            for agent in (CommandedOracle(env), CommandedRamp(env)):
                rows = [play(env, agent, s) for s in seeds]
                res[agent.name] = {**summarise(rows), "episodes_detail": rows}
                print(env_id, agent.name, summarise(rows), flush=True)
        out["tasks"][env_id] = res
        env.close()
    path = Path(a.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
