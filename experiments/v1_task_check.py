"""Check that the v1 (commanded-speed) tasks are well posed: the oracle against the naive ramp.

The v1 ids are retired (issue 19: their info and reward leak the hidden plant); this check replays the
record (``results/v1_task_check``) on the envs :func:`gfb_env.envs.retired.make_retired` builds.

For each v1 task, on training seeds (default 0-49): the return, success, certification and episode cost
of :class:`gfb_agents.oracles.commanded.CommandedOracle` (``oracle_v1``, knows every hidden parameter) and of
:class:`gfb_agents.ladder.NaiveRampAgent` (``naive``, the paper's constant-damping ramp to the command,
capped at 0.95 Lambda_c(D_W = 1) of the nominal bearing); also the wall time per control step.  With
``--margins`` it instead tunes the oracle's margin on the given (training) seeds.  Run::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.v1_task_check \\
        --seeds 0-49 --out results/v1_task_check/summary.json

``--agents oracle_v1,naive,margin_search`` plays v1 rules on the same seeds (the development tables of
docs/agents.md); ``--gain-window`` only scans WhirlRecovery-v1's touchdowns over a grid of hidden gains
(docs/envs.md).  Writes one JSON summary (per task and agent: mean return, its 95 % CI half width,
success rate, certified rate, touchdowns, mean episode cost, ms per step).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from gfb_agents import ladder
from gfb_agents.oracles.commanded import CommandedOracle
from gfb_env.envs import make_retired
from gfb_env.scripting import OneLineParser

V1_IDS = ("gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1")  # retired


def play(env: gym.Env, agent, seed: int) -> dict:
    """One episode (the evaluation's protocol: ``reset()``, ``env.reset``, ``observe_reset_info`` where
    the agent has it, then ``predict``): return, success, certificate, cost, steps, wall time of the steps."""
    agent.reset()
    obs, info = env.reset(seed=seed)
    if hasattr(agent, "observe_reset_info"):
        agent.observe_reset_info(info)
    ret, steps, t = 0.0, 0, 0.0
    while True:
        a, _ = agent.predict(obs, deterministic=True)
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


def command_statistics(n: int) -> dict:
    """RunUpRandomized-v1 on ``n`` draws (seeds 0..n-1): the exact best stable speed of each drawn plant
    (achievable actual damping), the share of commands above it, and the error of the v0 table's
    trilinear ``lambda_best`` (unconstrained damping) against the exact unconstrained value."""
    env = make_retired("gfb_env/RunUpRandomized-v1")
    u = env.unwrapped
    above, best_rpm, table_err, t_best, cmd_rpm = [], [], [], [], []
    for seed in range(n):
        _, info = env.reset(seed=seed)
        t0 = time.perf_counter()
        bp = u.best_stable_operating_point()
        t_best.append(time.perf_counter() - t0)
        lam_u, _ = u._unconstrained_best_point()
        task = u.hidden().bearing_draw  # the drawn bearing, through the privileged channel
        tab = u.table(task.clearance_m, task.stiffness_factor, task.load_n)["lambda_best"]
        table_err.append(tab / lam_u - 1.0)
        best_rpm.append(bp.speed_rpm)
        above.append(info["speed_command_rpm"] > bp.speed_rpm)
        cmd_rpm.append(float(info["speed_command_rpm"]))
    b = np.array(best_rpm)
    e = np.array(table_err)
    return {
        "draws": n,
        "share_of_commands_above_best": float(np.mean(above)),
        "best_speed_rpm_min_median_max": [float(b.min()), float(np.median(b)), float(b.max())],
        "table_error_mean_min_max": [float(e.mean()), float(e.min()), float(e.max())],
        "best_point_seconds_mean_max": [float(np.mean(t_best)), float(np.max(t_best))],
        "best_speed_rpm": [float(x) for x in b],
        "command_rpm": cmd_rpm,
    }


def step_cost(episodes: int = 6, steps: int = 150) -> dict:
    """Wall time per control step of RunUp-v1 on one fixed stable ramp (the same actions; the v0
    variants it was compared with are retired, issue 18), episode by episode; the horizon's last step
    (with the certificate) is timed apart.  Minimum and median over ``episodes``."""
    variants = {
        "RunUp-v1": make_retired("gfb_env/RunUp-v1", episode_steps=steps, max_episode_steps=steps),
    }
    per_step: dict = {k: [] for k in variants}
    last: list[float] = []
    for ep in range(episodes):
        for name, env in variants.items():
            u = env.unwrapped
            env.reset(seed=100 + ep)
            t = 0.0
            for k in range(steps):
                lam = u._integ.bearing_number
                a0 = float(np.clip((0.62 - lam) / (u.max_rate() * u.control_interval), -1, 1))
                a = np.array([a0, u.action_from_damping(2.0)], dtype=np.float32)
                t0 = time.perf_counter()
                env.step(a)
                dt = time.perf_counter() - t0
                if k == steps - 1:
                    if name == "RunUp-v1":
                        last.append(dt)
                    break
                t += dt
            per_step[name].append(1e3 * t / (steps - 1))
    out = {
        k: {"ms_per_step_min": min(v), "ms_per_step_median": float(np.median(v))} for k, v in per_step.items()
    }
    out["RunUp-v1"]["ms_last_step_with_certificate_median"] = 1e3 * float(np.median(last))
    return out


def gain_window(n_gains: int = 15, seeds: tuple[int, ...] = (0, 1, 2, 3), steps: int = 40) -> dict:
    """WhirlRecovery-v1 with the hidden gain fixed on a grid over the run-up tasks' prior [0.316, 3.16]:
    the control step of touchdown (0 = none within ``steps``) when the machine decelerates at the motor
    limit keeping its start command d_opt, per gain and seed -- the measurement behind
    ``V1_WHIRL_RECOVERY_GAIN_RANGE`` (docs/envs.md)."""
    import dataclasses

    from gfb_env.envs import V1_DAMPING_GAIN_RANGE, V1_TASK

    out = {}
    for g in np.geomspace(*V1_DAMPING_GAIN_RANGE, n_gains):
        act = dataclasses.replace(V1_TASK["damping_actuator"], gain=float(g), gain_range=None)
        env = make_retired("gfb_env/WhirlRecovery-v1", damping_actuator=act)
        u = env.unwrapped
        a = np.array([-1.0, u.action_from_damping(u.constants["d_opt"])], dtype=np.float32)
        steps_to_touchdown = []
        for seed in seeds:
            env.reset(seed=seed)
            k, info, done = 0, {}, False
            while k < steps and not done:
                _, _, term, trunc, info = env.step(a)
                k, done = k + 1, term or trunc
            lost = info.get("termination_reason") in ("touchdown", "solver_failure")
            steps_to_touchdown.append(k if lost else 0)
        out[f"{g:.4f}"] = steps_to_touchdown
        print(f"g = {g:.3f}: touchdown step per seed {steps_to_touchdown}", flush=True)
        env.close()
    return {"seeds": list(seeds), "steps": steps, "touchdown_step_by_gain": out}


def make_agent(name: str, env: gym.Env):
    """``oracle_v1``, ``naive`` or a v1 rule for ``env``, built by :func:`gfb_agents.ladder.build`."""
    return ladder.build(name, env)


def agent_names() -> tuple[str, ...]:
    """The agents ``--agents`` may name: the ladder's naive agent, rules and oracle."""
    return tuple(n for n, e in ladder.registered().items() if e.kind != "learned")


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
    p.add_argument(
        "--command-draws", type=int, default=0, help="only the RunUpRandomized-v1 command statistics"
    )
    p.add_argument("--step-cost", action="store_true", help="only the wall time per step of RunUp-v1")
    p.add_argument("--no-shocks", action="store_true", help="the tasks without base shocks (an ablation)")
    p.add_argument(
        "--agents", default="oracle_v1,naive", help="comma-separated: oracle_v1, naive and v1 rule names"
    )
    p.add_argument(
        "--gain-window", action="store_true", help="only WhirlRecovery-v1's touchdowns over a gain grid"
    )
    a = p.parse_args(argv)
    if a.gain_window:
        stats = gain_window()
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(stats, indent=1))
        return
    if a.step_cost:
        stats = step_cost()
        print(stats)
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(stats, indent=1))
        return
    if a.command_draws:
        stats = command_statistics(a.command_draws)
        print(stats)
        path = Path(a.out)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(stats, indent=1))
        return
    known = agent_names()
    unknown = [n for n in a.agents.split(",") if n not in known]
    if unknown:
        p.error(f"--agents: unknown {', '.join(unknown)} (known: {', '.join(known)})")
    seeds = parse_seeds(a.seeds)
    if min(seeds) < 0 or max(seeds) > 99:
        p.error("--seeds: only training seeds 0-99")
    out: dict = {"seeds": a.seeds, "shocks": not a.no_shocks, "tasks": {}}
    for env_id in a.tasks.split(","):
        env = make_retired(env_id, **({"shock_arrivals": {"rate_per_s": 0.0}} if a.no_shocks else {}))
        res: dict = {}
        if a.margins:
            for m in (float(x) for x in a.margins.split(",")):
                res[f"oracle_margin_{m:g}"] = summarise(
                    [play(env, CommandedOracle(env, margin=m), s) for s in seeds]
                )
                print(env_id, m, res[f"oracle_margin_{m:g}"], flush=True)
        else:
            for name in a.agents.split(","):
                agent = make_agent(name, env)
                rows = [play(env, agent, s) for s in seeds]
                res[name] = {**summarise(rows), "episodes_detail": rows}
                print(env_id, name, summarise(rows), flush=True)
        out["tasks"][env_id] = res
        env.close()
    path = Path(a.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
