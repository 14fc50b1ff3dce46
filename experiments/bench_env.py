"""Benchmark of the Gymnasium environments (``docs/envs.md``).

Prints, for each registered task on one core, env steps per second and simulated (rotor) seconds per
wall-clock second under a seeded random policy, a vector env on two cores (``gymnasium.make_vec``,
async), and the wall time of one full default RunUp-v0 episode with the scripted ramp policy
(``RunUpEnv.scripted_action``: full motor rate toward the target at the optimum damping), plus the
worst case (full speed with the least damping: whirl to touchdown).

Vector throughput near equilibrium (RunUp-v0, the speed held at the start, D_W = 1): env steps per
second of one env, Gymnasium's SyncVectorEnv, AsyncVectorEnv (2 worker processes) and the native vector
env (:class:`gfb_env.envs.vector.GFBVectorEnv`) at N = 2, 8, 16, 32, with their ratios to one env.
``--profile`` adds a cProfile of single-env steps near equilibrium (the top functions by own time).

The last line is JSON (``single_steps_per_s``, ``async_vector_steps_per_s``, ``native_vector_steps_per_s``
at N = 16, and everything else), also written with the load average to ``results/bench_env/summary.json``.
Run::

    OMP_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.bench_env [--steps 40] [--vec-steps 40] [--profile]
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env import jsonio
from gfb_env._cli_common import OneLineParser, check_output_dir
from gfb_env.envs import ENV_IDS


def _episode(env: gym.Env, policy, seed: int, max_steps: int | None = None) -> dict:
    u = env.unwrapped
    t0 = time.perf_counter()
    env.reset(seed=seed)
    t_reset = time.perf_counter() - t0
    n, ret, info = 0, 0.0, {}
    t0 = time.perf_counter()
    while True:
        _, r, term, trunc, info = env.step(policy(u))
        n += 1
        ret += float(r)
        if term or trunc or (max_steps is not None and n >= max_steps):
            break
    wall = time.perf_counter() - t0
    sim_s = info["time_s"]
    return {
        "steps": n,
        "wall_s": wall,
        "reset_s": t_reset,
        "steps_per_s": n / wall,
        "sim_s": sim_s,
        "sim_s_per_wall_s": sim_s / wall,
        "return": ret,
        "reason": info["termination_reason"] or ("time_limit" if n >= env.spec.max_episode_steps else "cut"),
        "speed_rpm": info["speed_rpm"],
    }


VECTOR_NS = (2, 8, 16, 32)


def _equilibrium_rate(envs, steps: int, seed: int) -> float:
    """Env steps per second of a vector env holding the start (speed action 0, D_W = 1) near equilibrium."""
    n = envs.num_envs
    a = np.zeros((n, 2), np.float32)
    envs.reset(seed=seed)
    envs.step(a)  # warm-up
    t0 = time.perf_counter()
    for _ in range(steps):
        envs.step(a)
    return n * steps / (time.perf_counter() - t0)


def _single_rate(steps: int, seed: int) -> float:
    env = gym.make("gfb_env/RunUp-v0")
    a = np.zeros(2, np.float32)
    env.reset(seed=seed)
    env.step(a)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


def vector_throughput(steps: int, seed: int) -> dict:
    """Steps/s near equilibrium: one env, SyncVectorEnv and the native vector env at each N, and
    AsyncVectorEnv with 2 workers; ratios to one env."""
    env_id = "gfb_env/RunUp-v0"
    single = _single_rate(steps, seed)
    out: dict = {"task": env_id, "single": single, "sync": {}, "native": {}}
    for n in VECTOR_NS:
        # the same number of env steps per vector env: steps of the batch = steps / N (at least 3)
        k = max(3, steps * 4 // n)
        sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync")
        out["sync"][n] = _equilibrium_rate(sync, k, seed)
        sync.close()
        native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
        out["native"][n] = _equilibrium_rate(native, k, seed)
        native.close()
    asyn = gym.make_vec(env_id, num_envs=2, vectorization_mode="async")
    out["async_2"] = _equilibrium_rate(asyn, steps, seed)
    asyn.close()
    return out


def profile_single_step(steps: int, seed: int, top: int = 25) -> str:
    """cProfile of ``steps`` single-env steps near equilibrium: the top functions by own time."""
    import cProfile
    import io
    import pstats

    env = gym.make("gfb_env/RunUp-v0")
    a = np.zeros(2, np.float32)
    env.reset(seed=seed)
    env.step(a)
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(top)
    return buf.getvalue()


def main() -> None:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=40, help="control steps per random-policy run")
    ap.add_argument(
        "--vec-steps", type=int, default=40, help="env steps per env at N = 4 in the vector throughput runs"
    )
    ap.add_argument("--profile", action="store_true", help="also profile single-env steps near equilibrium")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("results/bench_env"), help="output folder")
    args = ap.parse_args()
    if args.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(args.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    results: dict = {"single_core": {}, "vector_2_cores": {}}

    rng = np.random.default_rng(args.seed)

    def random_policy(u):
        return rng.uniform(-1, 1, 2).astype(np.float32)

    rows = []
    for env_id in ENV_IDS:
        env = gym.make(env_id)
        _episode(env, random_policy, args.seed, 2)  # warm-up (numba caches, constants)
        r = _episode(env, random_policy, args.seed, args.steps)
        results["single_core"][env_id] = r
        rows.append((env_id, "random", r))
        env.close()

    env = gym.make("gfb_env/RunUp-v0")
    full = _episode(env, lambda u: u.scripted_action(), args.seed)
    rows.append(("gfb_env/RunUp-v0", "scripted (full)", full))
    results["runup_scripted_episode"] = full
    worst = _episode(env, lambda u: np.array([1.0, -1.0], np.float32), args.seed)
    rows.append(("gfb_env/RunUp-v0", "a=[1,-1] (full)", worst))
    results["runup_worst_episode"] = worst
    env.close()

    env = gym.make("gfb_env/WhirlRecovery-v0")
    rec = _episode(env, lambda u: u.scripted_action(), args.seed)
    rows.append(("gfb_env/WhirlRecovery-v0", "scripted (full)", rec))
    results["whirl_recovery_scripted_episode"] = rec
    # worst case for wall time: a developed whirl for a whole episode (speed held, optimum damping)
    whirl = _episode(
        env, lambda u: np.array([0.0, u.action_from_damping(u.whirl_damping)], np.float32), args.seed
    )
    rows.append(("gfb_env/WhirlRecovery-v0", "hold whirl (full)", whirl))
    results["whirl_held_episode"] = whirl
    env.close()

    for env_id in ("gfb_env/RunUp-v0", "gfb_env/WhirlRecovery-v0"):
        envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="async")
        envs.reset(seed=args.seed)
        envs.step(envs.action_space.sample())
        t0 = time.perf_counter()
        sim = 0.0
        for _ in range(args.steps):
            _, _, _, _, info = envs.step(rng.uniform(-1, 1, (2, 2)).astype(np.float32))
        wall = time.perf_counter() - t0
        sim = (
            2
            * args.steps
            * envs.get_attr("control_interval")[0]
            * envs.get_attr("nominal_bearing")[0].time_scale_s
        )
        results["vector_2_cores"][env_id] = {
            "env_steps": 2 * args.steps,
            "wall_s": wall,
            "steps_per_s": 2 * args.steps / wall,
            "sim_s_per_wall_s": sim / wall,
        }
        envs.close()

    vt = vector_throughput(args.vec_steps, args.seed)
    results["vector_near_equilibrium"] = vt
    results["single_steps_per_s"] = vt["single"]
    results["async_vector_steps_per_s"] = vt["async_2"]
    results["native_vector_steps_per_s"] = vt["native"][16]
    results["sync_vector_steps_per_s"] = vt["sync"][16]
    if args.profile:
        print(profile_single_step(200, args.seed))

    print(
        f"{'task':28} {'policy':18} {'steps':>5} {'wall s':>7} {'steps/s':>8} {'sim s/wall s':>12} "
        f"{'return':>8} {'end':>14}"
    )
    for env_id, pol, r in rows:
        print(
            f"{env_id:28} {pol:18} {r['steps']:5d} {r['wall_s']:7.2f} {r['steps_per_s']:8.1f} "
            f"{r['sim_s_per_wall_s']:12.3f} {r['return']:8.2f} {r['reason']:>14}"
        )
    for env_id, r in results["vector_2_cores"].items():
        print(
            f"{env_id:28} {'random, 2 async':18} {r['env_steps']:5d} {r['wall_s']:7.2f} "
            f"{r['steps_per_s']:8.1f} {r['sim_s_per_wall_s']:12.3f}"
        )
    print(f"\nnear equilibrium ({vt['task']}), env steps/s (ratio to one env {vt['single']:.0f}/s):")
    print(f"{'N':>4} {'SyncVectorEnv':>15} {'native':>15}")
    for n in VECTOR_NS:
        sy, na = vt["sync"][n], vt["native"][n]
        print(f"{n:4d} {sy:9.0f} ({sy / vt['single']:4.2f}) {na:9.0f} ({na / vt['single']:4.2f})")
    print(f"AsyncVectorEnv, 2 workers: {vt['async_2']:.0f} ({vt['async_2'] / vt['single']:.2f})")
    results["load_average_1min_at_end"] = os.getloadavg()[0]
    args.out.mkdir(parents=True, exist_ok=True)
    jsonio.write_json(args.out / "summary.json", results)
    print(jsonio.dumps(results))


if __name__ == "__main__":
    main()
