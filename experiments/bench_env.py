"""Benchmark of the Gymnasium environments and their vector envs (``docs/envs.md``).

Vector throughput, in one run on the same tasks, seeds and held action: env steps per second of one env,
Gymnasium's SyncVectorEnv, AsyncVectorEnv (2 worker processes), SB3's SubprocVecEnv (2 workers) and the
native vector env (:class:`gfb_env.envs.vector.GFBVectorEnv`, default threads) at N = 2, 8, 16, 32, with
their ratios to one env, at two operating points: near equilibrium (the start of RunUp-v2, speed held,
D_W = 1) and in a developed whirl (the start of WhirlRecovery-v2, speed and the whirl's damping held).
Then what limits the native env (N = 16: wall time of its compiled batch call per env step with 1 and 2
threads, the Python around it, the parallel efficiency) and PPO's training throughput (RunUp-v2, the zoo's
hyperparameters) on SB3's DummyVecEnv and on the native vector env, with the wall time of 1M steps.
Without ``--quick`` also, per registered task on one core, env steps/s and simulated seconds per wall
second under a seeded random policy, and full scripted and worst-case episodes.

Every measurement prints the 1-minute load average: on a shared machine the numbers are under load.
The last line is JSON (``single_steps_per_s``, ``async_vector_steps_per_s`` with 2 workers,
``native_vector_steps_per_s`` at N = 16, near equilibrium, and everything else), also written to
``results/bench_env/summary.json``.  Run::

    OMP_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.bench_env [--quick] [--env-steps 800]
        [--ppo-steps 20000] [--profile]
    OMP_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.bench_env --against OLD_CHECKOUT [--rounds 3]
        [--env-steps 800] [--ppo-steps 8192]      # this checkout against another, alternating
                                                   # (gfb_experiments.bench_against; issue 20)
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env import jsonio
from gfb_env.envs import ENV_IDS
from gfb_env.scripting import OneLineParser, check_output_dir


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
    # the simulated time of the actual plant (the v2 info carries no true time: it tells the clearance)
    sim_s = u.episode.bearing.seconds(u._integ.tau)
    return {
        "steps": n,
        "wall_s": wall,
        "reset_s": t_reset,
        "steps_per_s": n / wall,
        "sim_s": sim_s,
        "sim_s_per_wall_s": sim_s / wall,
        "return": ret,
        "reason": info.get("termination_reason")
        or ("time_limit" if n >= env.spec.max_episode_steps else "cut"),
        "speed_rpm": info["speed_rpm"],
    }


VECTOR_NS = (2, 8, 16, 32)
#: the two operating points of the vector throughput runs: (task, what is held)
SCENARIOS = {
    # the start of RunUp-v2 (equilibrium at the lowest speed), speed held, D_W = 1 (action 0)
    "equilibrium": "gfb_env/RunUp-v2",
    # the start of WhirlRecovery-v2 (a developed whirl above Lambda_c), speed and the whirl's damping held
    "whirl": "gfb_env/WhirlRecovery-v2",
}


def _load() -> float:
    return os.getloadavg()[0]


def _hold_action(scenario: str, seed: int) -> np.ndarray:
    """The action of one env that holds the scenario's operating point."""
    if scenario == "equilibrium":
        return np.zeros(2, np.float32)
    env = gym.make(SCENARIOS[scenario])
    u = env.unwrapped
    env.reset(seed=seed)
    a = np.array([0.0, u.action_from_damping(u.whirl_damping)], np.float32)
    env.close()
    return a


def _vector_rate(envs, action: np.ndarray, env_steps: int, seed: int) -> float:
    """Env steps per second of a Gymnasium vector env holding ``action`` in every env (autoreset on)."""
    n = envs.num_envs
    a = np.tile(action, (n, 1))
    envs.reset(seed=seed)
    envs.step(a)  # warm-up
    batches = max(3, env_steps // n)
    t0 = time.perf_counter()
    for _ in range(batches):
        envs.step(a)
    return n * batches / (time.perf_counter() - t0)


def _single_rate(env_id: str, action: np.ndarray, env_steps: int, seed: int) -> float:
    env = gym.make(env_id)
    env.reset(seed=seed)
    env.step(action)
    t0 = time.perf_counter()
    for _ in range(env_steps):
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()
    rate = env_steps / (time.perf_counter() - t0)
    env.close()
    return rate


def _single_rate_worker(args: tuple) -> float:
    env_id, action, env_steps, seed = args
    return _single_rate(env_id, action, env_steps, seed)


def two_process_control(env_id: str, action: np.ndarray, env_steps: int, seed: int) -> dict:
    """One env alone, then two independent one-env processes at the same time: whether the machine's
    cores give 2x to independent work (the yardstick of the native env's parallel efficiency)."""
    import multiprocessing as mp

    alone = _single_rate(env_id, action, env_steps, seed)
    with mp.get_context("spawn").Pool(2) as pool:
        pool.map(_single_rate_worker, [(env_id, action, 20, seed)] * 2)  # warm the workers' kernels
        both = pool.map(_single_rate_worker, [(env_id, action, env_steps, seed)] * 2)
    return {"alone": alone, "two_processes": both, "aggregate_over_alone": sum(both) / alone}


def _subproc_rate(env_id: str, action: np.ndarray, n: int, env_steps: int, seed: int) -> float:
    """SB3's SubprocVecEnv (one worker process per env, SB3's own autoreset)."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from gfb_agents.learned.train import importable_env_id

    venv = make_vec_env(importable_env_id(env_id), n_envs=n, seed=seed, vec_env_cls=SubprocVecEnv)
    a = np.tile(action, (n, 1))
    venv.reset()
    venv.step(a)
    batches = max(3, env_steps // n)
    t0 = time.perf_counter()
    for _ in range(batches):
        venv.step(a)
    rate = n * batches / (time.perf_counter() - t0)
    venv.close()
    return rate


class _CompiledClock:
    """Wall time spent in the compiled batch call (``BatchAdvance._launch``: numba's launch of
    :func:`gfb_env.integrator.batch._advance_batch` and the envs' compiled loops)."""

    def __init__(self) -> None:
        from gfb_env.integrator import BatchAdvance

        self.cls, self.original = BatchAdvance, BatchAdvance.__dict__["_launch"]
        self.seconds = self.cpu_seconds = 0.0

    def __enter__(self) -> _CompiledClock:
        launch = self.original.__func__

        def timed(*args):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return launch(*args)
            finally:
                self.seconds += time.perf_counter() - t0
                self.cpu_seconds += time.process_time() - c0

        self.cls._launch = staticmethod(timed)
        return self

    def __exit__(self, *exc) -> None:
        self.cls._launch = self.original


def _native_profile(env_id: str, action: np.ndarray, n: int, env_steps: int, seed: int) -> dict:
    """What limits the native vector env: per env step, the wall time of the compiled batch call with
    1 and 2 threads and the Python around it; the prange's parallel efficiency t1 / (2 t2).  With one
    thread also the process's CPU time (the compiled call runs in the calling thread): unlike the wall
    time it does not grow with other processes' load."""
    out: dict = {"num_envs": n}
    for threads in (1, 2):
        envs = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", num_threads=threads)
        a = np.tile(action, (n, 1))
        batches = max(3, env_steps // n)
        with _CompiledClock() as clock:
            envs.reset(seed=seed)
            envs.step(a)  # warm-up
            clock.seconds = clock.cpu_seconds = 0.0
            t0, c0 = time.perf_counter(), time.process_time()
            for _ in range(batches):
                envs.step(a)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rate = n * batches / wall
        compiled_us = clock.seconds / (batches * n) * 1e6
        out[f"threads_{threads}"] = {
            "steps_per_s": rate,
            "us_per_env_step": 1e6 / rate,
            "compiled_us_per_env_step": compiled_us,
            "python_us_per_env_step": 1e6 / rate - compiled_us,
            "load_1min": _load(),
        }
        if threads == 1:
            per = 1e6 / (batches * n)
            out["threads_1"]["cpu_us_per_env_step"] = cpu * per
            out["threads_1"]["compiled_cpu_us_per_env_step"] = clock.cpu_seconds * per
            out["threads_1"]["python_cpu_us_per_env_step"] = (cpu - clock.cpu_seconds) * per
    t1, t2 = out["threads_1"]["compiled_us_per_env_step"], out["threads_2"]["compiled_us_per_env_step"]
    out["parallel_efficiency_2_threads"] = t1 / (2.0 * t2)
    out["single_cpu"] = _single_cpu_profile(env_id, action, env_steps, seed)
    return out


def _single_cpu_profile(env_id: str, action: np.ndarray, env_steps: int, seed: int) -> dict:
    """One env's CPU time per step: the compiled call (``gfb_env.integrator.stepper._call_compiled``)
    and the Python around it."""
    import gfb_env.integrator.stepper as integrator  # (its advance calls _call_compiled)

    original, spent = integrator._call_compiled, [0.0]

    def timed(*args):
        c0 = time.process_time()
        try:
            return original(*args)
        finally:
            spent[0] += time.process_time() - c0

    env = gym.make(env_id)
    env.reset(seed=seed)
    env.step(action)
    integrator._call_compiled = timed
    try:
        c0 = time.process_time()
        for _ in range(env_steps):
            _, _, term, trunc, _ = env.step(action)
            if term or trunc:
                env.reset()
        cpu = time.process_time() - c0
    finally:
        integrator._call_compiled = original
    env.close()
    per = 1e6 / env_steps
    return {
        "cpu_us_per_env_step": cpu * per,
        "compiled_cpu_us_per_env_step": spent[0] * per,
        "python_cpu_us_per_env_step": (cpu - spent[0]) * per,
    }


def vector_throughput(scenario: str, env_steps: int, seed: int, ns: tuple[int, ...], sync_ns, log) -> dict:
    """Env steps/s at the scenario's operating point (same task, seeds and action everywhere): one env,
    SyncVectorEnv, AsyncVectorEnv and SB3 SubprocVecEnv with 2 workers, the native vector env at each N
    (default threads), with the load average of each measurement."""
    env_id = SCENARIOS[scenario]
    action = _hold_action(scenario, seed)
    out: dict = {"task": env_id, "scenario": scenario, "env_steps_per_measurement": env_steps}

    def record(key: str, rate: float) -> None:
        out[key] = {"steps_per_s": rate, "load_1min": _load()}
        log(f"  {scenario:11} {key:14} {rate:9.0f} env steps/s   (load {out[key]['load_1min']:.2f})")

    record("single", _single_rate(env_id, action, env_steps, seed))
    for n in sync_ns:
        sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync")
        record(f"sync_{n}", _vector_rate(sync, action, env_steps, seed))
        sync.close()
    asyn = gym.make_vec(env_id, num_envs=2, vectorization_mode="async")
    record("async_2", _vector_rate(asyn, action, env_steps, seed))
    asyn.close()
    record("subproc_2", _subproc_rate(env_id, action, 2, env_steps, seed))
    for n in ns:
        native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
        record(f"native_{n}", _vector_rate(native, action, env_steps, seed))
        native.close()
    single = out["single"]["steps_per_s"]
    out["ratios_to_single"] = {k: v["steps_per_s"] / single for k, v in out.items() if isinstance(v, dict)}
    if "native_16" in out:
        out["native_16_over_async_2"] = out["native_16"]["steps_per_s"] / out["async_2"]["steps_per_s"]
    return out


def ppo_throughput(vec_env: str, n_envs: int, timesteps: int, seed: int) -> dict:
    """PPO (the zoo's RunUp-v2 hyperparameters, VecNormalize, one torch thread as ``agents.train``)
    for ``timesteps`` env steps on ``vec_env``: env steps/s of the whole training loop (rollouts and
    updates) and the extrapolated wall time of 1M steps."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from gfb_agents.learned.train import _split_hyperparams, load_hyperparams, make_vec_env_for

    env_id = "gfb_env/RunUp-v2"
    torch.set_num_threads(1)
    zoo, kwargs = _split_hyperparams(load_hyperparams("ppo", env_id))
    venv = make_vec_env_for(env_id, n_envs, seed, None, {}, vec_env=vec_env)
    venv = VecNormalize(venv, gamma=kwargs.get("gamma", 0.99), **zoo["normalize"])
    model = PPO(zoo["policy"], venv, seed=seed, device="cpu", verbose=0, **kwargs)
    t0 = time.perf_counter()
    model.learn(total_timesteps=timesteps)
    wall = time.perf_counter() - t0
    venv.close()
    steps = int(model.num_timesteps)
    return {
        "vec_env": vec_env,
        "n_envs": n_envs,
        "timesteps": steps,
        "wall_s": wall,
        "steps_per_s": steps / wall,
        "hours_per_1M_steps": 1e6 / (steps / wall) / 3600.0,
        "load_1min": _load(),
    }


def profile_single_step(steps: int, seed: int, top: int = 25) -> str:
    """cProfile of ``steps`` single-env steps near equilibrium: the top functions by own time."""
    import cProfile
    import io
    import pstats

    env = gym.make("gfb_env/RunUp-v2")
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
        "--env-steps",
        type=int,
        default=None,
        help="env steps per vector throughput measurement near equilibrium (the whirl gets half; "
        "default 800, --quick 160)",
    )
    ap.add_argument(
        "--ppo-steps",
        type=int,
        default=None,
        help="PPO timesteps per training throughput run (default 20000, --quick 2048; 0: skip)",
    )
    ap.add_argument(
        "--quick",
        action="store_true",
        help="short runs: no per-task episodes, SyncVectorEnv at N = 2, 16 only, fewer steps",
    )
    ap.add_argument("--profile", action="store_true", help="also profile single-env steps near equilibrium")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("results/bench_env"), help="output folder")
    ap.add_argument(
        "--against",
        type=Path,
        default=None,
        metavar="OLD_CHECKOUT",
        help="compare with another checkout instead, alternating in one run (gfb_experiments.bench_against; "
        "issue 20's reference is 09cb50e: git worktree add /tmp/base 09cb50e)",
    )
    ap.add_argument("--rounds", type=int, default=3, help="with --against: alternations (median reported)")
    args = ap.parse_args()
    for name in ("steps", "env_steps", "ppo_steps"):
        v = getattr(args, name)
        if v is not None and (v < 0 or (v == 0 and name != "ppo_steps")):
            ap.error(f"--{name.replace('_', '-')} must be positive, got {v}")
    if args.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(args.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    env_steps = args.env_steps if args.env_steps is not None else (160 if args.quick else 800)
    ppo_steps = args.ppo_steps if args.ppo_steps is not None else (2048 if args.quick else 20_000)
    if args.against is not None:
        from gfb_experiments import bench_against

        if args.rounds < 1:
            ap.error(f"--rounds must be positive, got {args.rounds}")
        here = Path(__file__).resolve().parents[1]
        try:
            bench_against.check_checkout(args.against)
            bench_against.check_checkout(here)
        except ValueError as exc:
            ap.error(f"{exc} (--against compares two checkouts: run it from one)")
        summary = bench_against.against(
            args.against, here, args.rounds, env_steps, ppo_steps,
            args.seed, args.out,
        )  # fmt: skip
        print(json.dumps({k: v for k, v in summary.items() if k not in ("rounds_raw",)}))
        return
    sync_ns = (2, 16) if args.quick else VECTOR_NS

    def log(line: str) -> None:
        print(line, flush=True)

    import numba

    results: dict = {
        "cores": os.cpu_count(),
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "load_1min_at_start": _load(),
        "quick": bool(args.quick),
    }
    log(
        f"cores {results['cores']}, numba threads {results['numba_threads']}, load {_load():.2f} at the start"
    )
    rows = []
    if not args.quick:
        results["single_core"] = {}
        rng = np.random.default_rng(args.seed)

        def random_policy(u):
            return rng.uniform(-1, 1, 2).astype(np.float32)

        for env_id in ENV_IDS:
            env = gym.make(env_id)
            _episode(env, random_policy, args.seed, 2)  # warm-up (numba caches, constants)
            r = _episode(env, random_policy, args.seed, args.steps)
            results["single_core"][env_id] = r
            rows.append((env_id, "random", r))
            env.close()
        env = gym.make("gfb_env/RunUp-v2")
        full = _episode(env, lambda u: u.scripted_action(), args.seed)
        rows.append(("gfb_env/RunUp-v2", "scripted (full)", full))
        results["runup_scripted_episode"] = full
        worst = _episode(env, lambda u: np.array([1.0, -1.0], np.float32), args.seed)
        rows.append(("gfb_env/RunUp-v2", "a=[1,-1] (full)", worst))
        results["runup_worst_episode"] = worst
        env.close()
        env = gym.make("gfb_env/WhirlRecovery-v2")
        rec = _episode(env, lambda u: u.scripted_action(), args.seed)
        rows.append(("gfb_env/WhirlRecovery-v2", "scripted (full)", rec))
        results["whirl_recovery_scripted_episode"] = rec
        # worst case for wall time: a developed whirl for a whole episode (speed held, optimum damping)
        whirl = _episode(
            env, lambda u: np.array([0.0, u.action_from_damping(u.whirl_damping)], np.float32), args.seed
        )
        rows.append(("gfb_env/WhirlRecovery-v2", "hold whirl (full)", whirl))
        results["whirl_held_episode"] = whirl
        env.close()
        print(
            f"{'task':28} {'policy':18} {'steps':>5} {'wall s':>7} {'steps/s':>8} {'sim s/wall s':>12} "
            f"{'return':>8} {'end':>14}"
        )
        for env_id, pol, r in rows:
            print(
                f"{env_id:28} {pol:18} {r['steps']:5d} {r['wall_s']:7.2f} {r['steps_per_s']:8.1f} "
                f"{r['sim_s_per_wall_s']:12.3f} {r['return']:8.2f} {r['reason']:>14}"
            )

    log("\nvector throughput (env steps/s; the same task, seeds and held action in every env):")
    vt = {}
    for scenario, steps in (("equilibrium", env_steps), ("whirl", max(8, env_steps // 2))):
        vt[scenario] = vector_throughput(scenario, steps, args.seed, VECTOR_NS, sync_ns, log)
    results["vector_throughput"] = vt
    log("\nratios to one env:")
    for scenario, r in vt.items():
        log(f"  {scenario:11} " + "  ".join(f"{k} {v:.2f}" for k, v in r["ratios_to_single"].items()))
        log(f"  {scenario:11} native_16 / async_2 = {r['native_16_over_async_2']:.2f}")

    log("\nwhat limits the native vector env (N = 16, near equilibrium; wall us per env step):")
    prof = _native_profile(
        SCENARIOS["equilibrium"], _hold_action("equilibrium", args.seed), 16, env_steps, args.seed
    )
    results["native_profile"] = prof
    for t in (1, 2):
        p = prof[f"threads_{t}"]
        log(
            f"  {t} thread(s): {p['steps_per_s']:7.0f} env steps/s = {p['us_per_env_step']:6.1f} us "
            f"per env step: compiled {p['compiled_us_per_env_step']:6.1f}, "
            f"Python {p['python_us_per_env_step']:6.1f} (load {p['load_1min']:.2f})"
        )
    for label, p1 in (("native, 1 thread", prof["threads_1"]), ("one env", prof["single_cpu"])):
        log(
            f"  {label}, CPU time: {p1['cpu_us_per_env_step']:6.1f} us per env step: compiled "
            f"{p1['compiled_cpu_us_per_env_step']:6.1f}, Python {p1['python_cpu_us_per_env_step']:6.1f}"
        )
    log(
        "  parallel efficiency of the compiled batch with 2 threads: "
        f"{prof['parallel_efficiency_2_threads']:.2f}"
    )
    ctl = two_process_control(
        SCENARIOS["equilibrium"], _hold_action("equilibrium", args.seed), 2 * env_steps, args.seed
    )
    results["two_process_control"] = ctl
    log(
        f"  control: one env alone {ctl['alone']:.0f} env steps/s; two independent one-env processes at "
        f"once {ctl['two_processes'][0]:.0f} + {ctl['two_processes'][1]:.0f} = "
        f"{ctl['aggregate_over_alone']:.2f}x (load {_load():.2f})"
    )

    if ppo_steps > 0:
        log(f"\nPPO training throughput (RunUp-v2, zoo hyperparameters, {ppo_steps} timesteps):")
        results["ppo"] = []
        for vec_env, n in (("dummy", 2), ("native", 2), ("native", 16)):
            r = ppo_throughput(vec_env, n, ppo_steps, args.seed)
            results["ppo"].append(r)
            log(
                f"  {vec_env:7} n_envs={n:<3d} {r['steps_per_s']:7.0f} env steps/s, "
                f"{r['hours_per_1M_steps']:5.2f} h per 1M steps (load {r['load_1min']:.2f})"
            )

    if args.profile:
        print(profile_single_step(200, args.seed))
    eq = vt["equilibrium"]
    results["single_steps_per_s"] = eq["single"]["steps_per_s"]
    results["async_vector_steps_per_s"] = eq["async_2"]["steps_per_s"]
    results["native_vector_steps_per_s"] = eq["native_16"]["steps_per_s"]
    results["sync_vector_steps_per_s"] = eq["sync_16"]["steps_per_s"]
    results["whirl_single_steps_per_s"] = vt["whirl"]["single"]["steps_per_s"]
    results["whirl_native_vector_steps_per_s"] = vt["whirl"]["native_16"]["steps_per_s"]
    results["load_average_1min_at_end"] = _load()
    args.out.mkdir(parents=True, exist_ok=True)
    jsonio.write_json(args.out / "summary.json", results)
    print(jsonio.dumps(results))


if __name__ == "__main__":
    main()
