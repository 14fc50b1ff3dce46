"""This checkout's environments against another checkout's, alternating in one run (issue 20's yardstick).

``python -m gfb_experiments.bench_env --against OLD_CHECKOUT`` runs this.  Each measurement runs in a fresh
subprocess whose ``gfb_env`` and ``gfb_agents`` come from one checkout (a folder of links to the checkout's
``gfb_env/`` and ``agents/`` put first on ``PYTHONPATH``; the numba caches are warmed outside the timing),
alternating this checkout and OLD_CHECKOUT ``--rounds`` times, so that the slow drift of a shared machine's
load falls on both alike; the median of the rounds is reported.  Both sides play the same public
interface, each on its own benchmark tasks (the newest version of RunUp and WhirlRecovery its checkout
registers: this checkout's v2 ids; the reference 09cb50e's v1 ids, retired since): ``gymnasium.make_vec(id,
num_envs=16)`` (the native vector env) near equilibrium (the start of RunUp, speed held, D_W = 1) and in a
developed whirl (the start of WhirlRecovery, speed and the whirl's damping held), one env near equilibrium,
Gymnasium's AsyncVectorEnv with 2 workers, and PPO (the same hyperparameters on both sides: the zoo's
RunUp-v2 entry of this checkout, which is its RunUp-v1 entry, VecNormalize, one torch thread) on the native
vector env through the SB3 adapter.

The machine's yardstick for two cores is measured too (``native_x2``: two independent one-process native
runs of this checkout started at once, their rates summed; ``independent_two_over_one``): on a virtual
machine two vCPUs need not give two cores' throughput, and no sharding can beat what two unrelated
processes get (``two_processes_over_independent_two`` is the share the sharded env gets).

This checkout is also measured with its native vector env in two worker processes (``num_processes=2``,
:mod:`gfb_env.envs.shards`: the env step's Python on both cores), near equilibrium, in the whirl and under
PPO; the reference has no such option.  The headline ``native_vector_steps_per_s`` / ``speedup_vs_against``
is that configuration against the reference's default native vector env (its threads on both cores); the
one-process figures are ``one_process_*``, and ``ppo_env_steps_per_s`` is the faster of the two PPO
configurations (``ppo_config`` says which).

The reference of issue 20 is commit 09cb50e (``git worktree add /tmp/base 09cb50e``).  The last line is
JSON: ``native_vector_steps_per_s``, ``against_native_vector_steps_per_s``, ``speedup_vs_against`` (near
equilibrium), ``whirl_speedup_vs_against``, ``single_speedup_vs_against``, ``async_speedup_vs_against``,
``ppo_env_steps_per_s``, ``ppo_1m_steps_minutes`` and both sides' every median, also written to
``results/bench_env/against.json``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

#: what one subprocess measures (env steps per second); ``{arg}`` are filled from JSON
CHILD = r"""
import json, os, sys, time
import numpy as np
import gymnasium as gym
from gfb_env.envs import ENV_IDS
a = json.loads(sys.argv[1])
kind, steps, seed = a["kind"], a["env_steps"], a["seed"]

def newest(task):  # each side plays its own benchmark task: the newest version its checkout registers
    ids = [i for i in ENV_IDS if i.split("/")[1].split("-v")[0] == task]
    return max(ids, key=lambda i: int(i.rsplit("-v", 1)[1]))

RU, WR = newest("RunUp"), newest("WhirlRecovery")

def hold(env_id):
    if "WhirlRecovery" not in env_id:
        return np.zeros(2, np.float32)
    env = gym.make(env_id)
    u = env.unwrapped
    env.reset(seed=seed)
    act = np.array([0.0, u.action_from_damping(u.whirl_damping)], np.float32)
    env.close()
    return act

def vector_rate(envs, action, n_steps):
    n = envs.num_envs
    acts = np.tile(action, (n, 1))
    envs.reset(seed=seed)
    envs.step(acts)  # warm-up: numba caches, constants
    batches = max(3, n_steps // n)
    t0 = time.perf_counter()
    for _ in range(batches):
        envs.step(acts)
    return n * batches / (time.perf_counter() - t0)

if kind in ("native", "whirl", "native_p2", "whirl_p2"):
    env_id = RU if kind.startswith("native") else WR
    # *_p2: the envs in two worker processes (this checkout's num_processes; the old side has none)
    extra = {"vectorization_mode": "vector_entry_point", "num_processes": 2} if kind.endswith("_p2") else {}
    envs = gym.make_vec(env_id, num_envs=16, **extra)
    rate = vector_rate(envs, hold(env_id), steps if kind.startswith("native") else max(48, steps // 2))
    envs.close()
elif kind == "async":
    envs = gym.make_vec(RU, num_envs=2, vectorization_mode="async")
    rate = vector_rate(envs, hold(RU), steps)
    envs.close()
elif kind == "single":
    env = gym.make(RU)
    act = hold(RU)
    env.reset(seed=seed)
    env.step(act)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(act)
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
elif kind in ("ppo", "ppo_p2"):
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize
    try:
        from gfb_agents.learned.vec_env import GFBSB3VecEnv
    except ImportError:  # checkouts before issue 18
        from gfb_agents.vec_env import GFBSB3VecEnv
    torch.set_num_threads(1)
    hp = a["ppo"]
    extra = {"vectorization_mode": "vector_entry_point", "num_processes": 2} if kind.endswith("_p2") else {}
    venv = VecNormalize(VecMonitor(GFBSB3VecEnv(gym.make_vec(RU, num_envs=hp["n_envs"], **extra))),
                        gamma=hp["kwargs"].get("gamma", 0.99), **hp["normalize"])
    venv.seed(seed)
    model = PPO(hp["policy"], venv, seed=seed, device="cpu", verbose=0, **hp["kwargs"])
    model.learn(total_timesteps=int(hp["n_envs"]) * int(hp["kwargs"]["n_steps"]))  # warm-up rollout
    t0 = time.perf_counter()
    n0 = model.num_timesteps
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    rate = (model.num_timesteps - n0) / (time.perf_counter() - t0)
    venv.close()
print(json.dumps({"rate": rate, "load": os.getloadavg()[0]}))
"""

KINDS = ("native", "whirl", "single", "async", "ppo", "native_p2", "whirl_p2", "ppo_p2", "native_x2")
#: the kinds only this checkout has (its vector env's ``num_processes``), and the machine's yardstick
#: (``native_x2``: two independent one-process native runs at once): measured on the new side only
NEW_ONLY = ("native_p2", "whirl_p2", "ppo_p2", "native_x2")


#: the PPO entry both sides train with: this checkout's v2 learner defaults (issue 20, item 4; measured by
#: gfb_experiments.bench_learner), n_envs included; the old side has no v2 ids, so only its settings travel
PPO_ENTRY = "gfb_env/RunUp-v2"


def _ppo_settings() -> dict:
    """The zoo's :data:`PPO_ENTRY` PPO entry of this checkout, as plain JSON (both sides train with it)."""
    from gfb_agents.learned.train import _split_hyperparams, load_hyperparams

    hp = load_hyperparams("ppo", PPO_ENTRY)
    zoo, kwargs = _split_hyperparams(hp)
    kwargs = {k: v for k, v in kwargs.items() if isinstance(v, (int, float, str, bool, dict, list))}
    n_envs = int(zoo.get("n_envs", 1))
    return {"policy": zoo["policy"], "n_envs": n_envs, "normalize": zoo["normalize"], "kwargs": kwargs}


def _links(checkout: Path, root: Path) -> Path:
    """A folder with ``gfb_env`` -> checkout/gfb_env, ``gfb_agents`` -> checkout/agents (the import
    names of that checkout's code, whatever is installed)."""
    d = Path(tempfile.mkdtemp(prefix="gfb-bench-", dir=root))
    (d / "gfb_env").symlink_to(checkout.resolve() / "gfb_env")
    (d / "gfb_agents").symlink_to(checkout.resolve() / "agents")
    return d


def check_checkout(path: Path) -> Path:
    """``path`` must be a checkout of this project (a ``gfb_env/envs`` and an ``agents`` folder)."""
    if not (path / "gfb_env" / "envs").is_dir() or not (path / "agents").is_dir():
        raise ValueError(f"--against {path}: not a gfb-env checkout (no gfb_env/envs and agents/ there)")
    return path


def _child(links: Path, args: dict) -> tuple[list[str], dict]:
    """The command line and environment of one benchmark child on ``links``' checkout."""
    env = {**os.environ, "PYTHONPATH": str(links), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    return [sys.executable, "-c", CHILD, json.dumps(args)], env


def _run(links: Path, args: dict) -> dict:
    if args["kind"] == "native_x2":
        return _run_pair(links, {**args, "kind": "native"})
    cmd, env = _child(links, args)
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"benchmark child ({args['kind']}) failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _run_pair(links: Path, args: dict) -> dict:
    """Two independent children of ``args`` started at once; their rates summed.  The machine's own
    yardstick for two cores (what two unrelated processes get: shared caches, memory bandwidth, a
    virtual machine's scheduling, the clock at two busy cores), against which ``num_processes=2``'s
    gain is judged: a sharded env cannot beat it."""
    cmd, env = _child(links, args)
    procs = [
        subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    results = []
    for p in procs:
        stdout, stderr = p.communicate()
        if p.returncode != 0:
            raise RuntimeError(f"benchmark child (native, pair) failed:\n{stderr[-2000:]}")
        results.append(json.loads(stdout.strip().splitlines()[-1]))
    return {"rate": sum(r["rate"] for r in results), "load": max(r["load"] for r in results)}


def _alternate(sides: dict, rounds: int, env_steps: int, ppo_steps: int, seed: int, log) -> dict:
    """``{side: {kind: [rate per round]}}``: every kind, both sides, alternating their order per round."""
    ppo = _ppo_settings()
    rates: dict = {side: {k: [] for k in KINDS} for side in sides}
    kinds = [k for k in KINDS if not k.startswith("ppo") or ppo_steps > 0]
    for side in sides:  # warm each checkout's numba caches outside the timing
        _run(sides[side], {"kind": "single", "env_steps": 3, "seed": seed})
    for r in range(rounds):
        for kind in kinds:
            order = ("old", "new") if r % 2 == 0 else ("new", "old")
            for side in order:
                if kind in NEW_ONLY and side != "new":
                    continue
                steps = ppo_steps if kind.startswith("ppo") else env_steps
                res = _run(sides[side], {"kind": kind, "env_steps": steps, "seed": seed, "ppo": ppo})
                rates[side][kind].append(res["rate"])
                log(
                    f"round {r + 1}/{rounds} {kind:7s} {side}: {res['rate']:9.1f} env steps/s "
                    f"(load {res['load']:.2f})"
                )
    return rates


def against(
    old: Path,
    new: Path,
    rounds: int = 3,
    env_steps: int = 800,
    ppo_steps: int = 8192,
    seed: int = 0,
    out: Path | None = Path("results/bench_env"),
    log=print,
) -> dict:
    """The alternating comparison (module docstring); returns the summary (also ``out/against.json``)."""
    with tempfile.TemporaryDirectory(prefix="gfb-against-") as scratch:
        sides = {"new": _links(new, Path(scratch)), "old": _links(old, Path(scratch))}
        rates = _alternate(sides, rounds, env_steps, ppo_steps, seed, log)
    med = {side: {k: statistics.median(v) for k, v in d.items() if v} for side, d in rates.items()}
    new, old_ = med["new"], med["old"]
    summary = {
        "against": str(old),
        "rounds": rounds,
        "env_steps": env_steps,
        "ppo_steps": ppo_steps,
        # the headline: this checkout's native vector env using both cores (two worker processes,
        # num_processes=2) against the reference's native vector env with its default (both cores'
        # threads); the one-process figures follow
        "native_vector_config": "num_processes=2",
        "native_vector_steps_per_s": new["native_p2"],
        "against_native_vector_steps_per_s": old_["native"],
        "speedup_vs_against": new["native_p2"] / old_["native"],
        "whirl_native_vector_steps_per_s": new["whirl_p2"],
        "whirl_speedup_vs_against": new["whirl_p2"] / old_["whirl"],
        "one_process_native_vector_steps_per_s": new["native"],
        "one_process_speedup_vs_against": new["native"] / old_["native"],
        "one_process_whirl_speedup_vs_against": new["whirl"] / old_["whirl"],
        "two_processes_over_one": new["native_p2"] / new["native"],
        "whirl_two_processes_over_one": new["whirl_p2"] / new["whirl"],
        # the machine's yardstick: two independent one-process runs at once over one alone, and the
        # share of it the sharded env gets
        "independent_two_over_one": new["native_x2"] / new["native"],
        "two_processes_over_independent_two": new["native_p2"] / new["native_x2"],
        "single_speedup_vs_against": med["new"]["single"] / med["old"]["single"],
        "async_speedup_vs_against": med["new"]["async"] / med["old"]["async"],
        "medians": med,
        "rounds_raw": rates,
        "load_1min_at_end": os.getloadavg()[0],
    }
    if ppo_steps > 0:
        best = max(("ppo", "ppo_p2"), key=lambda k: new[k])  # the faster of the two configurations
        summary["ppo_config"] = "num_processes=2" if best == "ppo_p2" else "one process"
        summary["ppo_env_steps_per_s"] = new[best]
        summary["one_process_ppo_env_steps_per_s"] = new["ppo"]
        summary["two_processes_ppo_env_steps_per_s"] = new["ppo_p2"]
        summary["against_ppo_env_steps_per_s"] = old_["ppo"]
        summary["ppo_speedup_vs_against"] = new[best] / old_["ppo"]
        summary["ppo_1m_steps_minutes"] = 1e6 / new[best] / 60.0
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "against.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
