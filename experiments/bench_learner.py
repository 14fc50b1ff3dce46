"""PPO's learner cost per env step against the env's, in one run, on a grid (n_envs, n_steps, batch, epochs).

Issue 20 (item 4): once the plant is cheap, PPO's learner (the policy's forward pass on every vector step,
VecNormalize, the rollout buffer, GAE, and ``n_epochs`` passes of minibatch gradient steps over each rollout)
can cost more CPU than the env it learns from.  This script measures both on the same machine in the same
run, CPU time (``time.process_time``, one torch thread, the plant's compiled stage on one thread as in
training), the minimum of ``--repeats`` repeats:

- for each ``n_envs`` N: the native vector env of ``--env`` (``gymnasium.make_vec(id, num_envs=N)`` through
  the project's SB3 adapter, :func:`gfb_agents.learned.train.make_vec_env_for`, under VecNormalize as
  ``python -m gfb_experiments.train`` builds it); the model is the algorithm of ``--algo`` with the
  hyperparameters of its YAML entry for ``--env`` (policy, network, gamma ...) except the grid's;
- for each ``n_steps``: whole rollouts collected by SB3's own ``collect_rollouts``; a timing wrapper just
  below VecNormalize splits their CPU time into the env's (everything below VecNormalize: plant, resets,
  the adapter, VecMonitor) and the learner's collection share (the rest: policy forward, VecNormalize,
  buffer, GAE);
- for each ``(batch_size, n_epochs)``: SB3's own ``train()`` on the last collected rollout.

Per env step: ``learner = collect + update / (N * n_steps)``; the ratio ``learner / env`` is printed for
every grid point, and ``learner / (env / --env-speedup)`` against the planned plant (issue 20 aims at 3x
cheaper env steps).  The update time is also fitted as ``c_step * gradient_steps + c_sample * samples``
(samples = n_epochs * rollout size): the fixed cost of one gradient step against the per-sample cost.
The last line is JSON (also ``<out>/bench_learner.json``, with ``bench_learner.csv`` and a figure,
``bench_learner.png``).

    python -m gfb_experiments.bench_learner --n-envs 16 --n-steps 128 256 \\
        --batch-size 128 256 512 1024 --n-epochs 5 10
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gfb_env.scripting import OneLineParser, check_output_dir

__all__ = [
    "ALGOS",
    "GridPoint",
    "RolloutCost",
    "gradient_steps",
    "grid_rows",
    "fit_update_cost",
    "measure",
    "main",
]

#: the on-policy algorithms of :mod:`gfb_agents.learned.train` whose learner this measures
ALGOS = ("ppo", "asymmetric_ppo", "privileged_ppo")
FILES = ("bench_learner.json", "bench_learner.csv", "bench_learner.png")


def gradient_steps(rollout_size: int, batch_size: int, n_epochs: int) -> int:
    """Minibatch gradient steps of one PPO update: SB3's rollout buffer yields ``ceil(rollout / batch)``
    minibatches per epoch (the last one short when the batch does not divide the rollout)."""
    for name, v in (("rollout_size", rollout_size), ("batch_size", batch_size), ("n_epochs", n_epochs)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    return n_epochs * -(-rollout_size // batch_size)


@dataclass(frozen=True)
class RolloutCost:
    """CPU seconds of one collected rollout of ``n_envs * n_steps`` env steps (the min over repeats)."""

    n_envs: int
    n_steps: int
    env_s: float  # below VecNormalize: plant, resets, adapter, VecMonitor
    collect_s: float  # the learner's share of the collection: policy forward, VecNormalize, buffer, GAE

    def __post_init__(self) -> None:
        for name in ("n_envs", "n_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        for name in ("env_s", "collect_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite time >= 0, got {v!r}")

    @property
    def rollout_size(self) -> int:
        return self.n_envs * self.n_steps


@dataclass(frozen=True)
class GridPoint:
    """One measured ``(batch_size, n_epochs)`` update on a rollout of ``cost``: CPU seconds of ``train()``."""

    cost: RolloutCost
    batch_size: int
    n_epochs: int
    update_s: float

    def __post_init__(self) -> None:
        gradient_steps(self.cost.rollout_size, self.batch_size, self.n_epochs)  # validates the counts
        if self.batch_size > self.cost.rollout_size:
            raise ValueError(f"batch_size {self.batch_size} exceeds the rollout ({self.cost.rollout_size})")
        if not (math.isfinite(self.update_s) and self.update_s >= 0):
            raise ValueError(f"update_s must be a finite time >= 0, got {self.update_s!r}")


def grid_rows(points: Iterable[GridPoint], env_speedup: float = 3.0) -> list[dict[str, Any]]:
    """One row per grid point: the costs per env step in microseconds and the ratios (module docstring)."""
    if not (math.isfinite(env_speedup) and env_speedup > 0):
        raise ValueError(f"env_speedup must be finite and positive, got {env_speedup!r}")
    rows = []
    for p in points:
        c = p.cost
        size = c.rollout_size
        env_us = 1e6 * c.env_s / size
        collect_us = 1e6 * c.collect_s / size
        update_us = 1e6 * p.update_s / size
        learner_us = collect_us + update_us
        steps = gradient_steps(size, p.batch_size, p.n_epochs)
        rows.append(
            {
                "n_envs": c.n_envs,
                "n_steps": c.n_steps,
                "rollout_size": size,
                "batch_size": p.batch_size,
                "n_epochs": p.n_epochs,
                "gradient_steps_per_rollout": steps,
                "gradient_steps_per_env_step": steps / size,
                "samples_per_env_step": p.n_epochs,  # every sample is used once per epoch
                "env_us_per_step": env_us,
                "collect_us_per_step": collect_us,
                "update_us_per_step": update_us,
                "learner_us_per_step": learner_us,
                "us_per_gradient_step": 1e6 * p.update_s / steps,
                "learner_over_env": learner_us / env_us if env_us > 0 else math.inf,
                "learner_over_planned_env": learner_us * env_speedup / env_us if env_us > 0 else math.inf,
            }
        )
    return rows


def fit_update_cost(points: Sequence[GridPoint]) -> dict[str, float] | None:
    """Least squares of ``update_s = c_step * gradient_steps + c_sample * n_epochs * rollout_size`` over
    ``points`` (microseconds; None with fewer than two distinct designs)."""
    a = np.array(
        [[gradient_steps(p.cost.rollout_size, p.batch_size, p.n_epochs), p.n_epochs * p.cost.rollout_size]
         for p in points],
        dtype=float,
    )  # fmt: skip
    if a.shape[0] < 2 or np.linalg.matrix_rank(a) < 2:
        return None
    y = np.array([p.update_s for p in points], dtype=float)
    (c_step, c_sample), *_ = np.linalg.lstsq(a, y, rcond=None)
    pred = a @ np.array([c_step, c_sample])
    rel = np.abs(pred - y) / np.maximum(y, 1e-12)
    return {
        "us_per_gradient_step": 1e6 * float(c_step),
        "us_per_sample": 1e6 * float(c_sample),
        "max_relative_residual": float(rel.max()),
    }


def _env_clock(venv, clock: Callable[[], float]):
    """``venv`` wrapped in a ``VecEnvWrapper`` that adds up the CPU time spent below it (``.seconds``)."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

    class EnvClock(VecEnvWrapper):
        def __init__(self, venv) -> None:
            super().__init__(venv)
            self.seconds = 0.0

        def reset(self):
            t = clock()
            obs = self.venv.reset()
            self.seconds += clock() - t
            return obs

        def step_async(self, actions) -> None:
            t = clock()
            self.venv.step_async(actions)
            self.seconds += clock() - t

        def step_wait(self):
            t = clock()
            out = self.venv.step_wait()
            self.seconds += clock() - t
            return out

    return EnvClock(venv)


def _check_grid(name: str, values: Sequence[int], lo: int = 1) -> list[int]:
    vals = list(values)
    if not vals:
        raise ValueError(f"{name} must list at least one value")
    for v in vals:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} values must be integers >= {lo}, got {v!r}")
    return sorted(set(vals))


def measure(
    env_id: str = "gfb_env/RunUp-v2",
    algo: str = "ppo",
    n_envs: Sequence[int] = (16,),
    n_steps: Sequence[int] = (128,),
    batch_sizes: Sequence[int] = (128, 1024),
    n_epochs: Sequence[int] = (5, 10),
    repeats: int = 3,
    seed: int = 0,
    net_arch: Sequence[int] | None = None,
    env_kwargs: dict[str, Any] | None = None,
    clock: Callable[[], float] = time.process_time,
    log: Callable[[str], None] = print,
) -> tuple[list[GridPoint], dict[str, Any]]:
    """Measure the grid (module docstring): the grid points and the settings used.

    ``net_arch``: hidden widths of both the actor and the critic instead of the YAML's; ``env_kwargs``:
    keyword arguments of ``gymnasium.make_vec`` (e.g. ``max_episode_steps``); ``clock``: the CPU clock.
    Batch sizes larger than a rollout are skipped (said in the log)."""
    import gymnasium as gym
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    import gfb_env.envs  # noqa: F401  (registers the ids)
    from gfb_agents.learned.evaluate import algo_class
    from gfb_agents.learned.train import (
        _policy_class,
        _split_hyperparams,
        load_hyperparams,
        make_vec_env_for,
    )

    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    if env_id not in gym.registry:
        raise ValueError(f"unknown env id {env_id!r}")
    ns, steps = _check_grid("n_envs", n_envs), _check_grid("n_steps", n_steps, lo=2)
    batches, epochs = _check_grid("batch_size", batch_sizes, lo=2), _check_grid("n_epochs", n_epochs)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be a positive integer, got {repeats!r}")
    if net_arch is not None:
        net_arch = list(net_arch)
        if not net_arch or any(isinstance(w, bool) or not isinstance(w, int) or w < 1 for w in net_arch):
            raise ValueError(f"net_arch must list positive integer widths, got {net_arch!r}")
    zoo, kwargs = _split_hyperparams(load_hyperparams(algo, env_id))
    if net_arch is not None:
        kwargs["policy_kwargs"] = {
            **kwargs.get("policy_kwargs", {}),
            "net_arch": dict(pi=list(net_arch), vf=list(net_arch)),
        }
    torch.set_num_threads(1)
    cls = algo_class(algo)
    policy = _policy_class(algo, zoo)
    env_kwargs = {**(env_kwargs or {}), **({"privileged_info": True} if algo == "privileged_ppo" else {})}
    points: list[GridPoint] = []
    for n in ns:
        base = make_vec_env_for(env_id, n, seed, None, env_kwargs, vec_env="native")
        if algo in ("asymmetric_ppo", "privileged_ppo"):
            from gfb_agents.learned.vec_env import PrivilegedVecEnv

            base = PrivilegedVecEnv(base)
        timed = _env_clock(base, clock)
        venv = VecNormalize(timed, gamma=kwargs.get("gamma", 0.99), **(zoo["normalize"] or {}))
        for k in steps:
            run_kwargs = {**kwargs, "n_steps": k, "batch_size": min(batches[0], n * k), "n_epochs": epochs[0]}
            model = cls(policy, venv, seed=seed, device="cpu", verbose=0, **run_kwargs)
            _, callback = model._setup_learn(total_timesteps=10 * n * k, callback=None)
            callback.on_training_start(locals(), globals())
            env_s, collect_s = math.inf, math.inf
            for r in range(repeats + 1):  # the first rollout warms up (allocations, first calls): not kept
                t0, e0 = clock(), timed.seconds
                model.collect_rollouts(venv, callback, model.rollout_buffer, n_rollout_steps=k)
                total, env = clock() - t0, timed.seconds - e0
                if r > 0:
                    env_s, collect_s = min(env_s, env), min(collect_s, max(0.0, total - env))
            cost = RolloutCost(n, k, env_s, collect_s)
            log(
                f"n_envs={n:<3d} n_steps={k:<5d} rollout {n * k:6d}: env {1e6 * env_s / (n * k):7.1f} us, "
                f"collection {1e6 * collect_s / (n * k):6.1f} us per env step"
            )
            model.train()  # warm-up (torch's first calls): not kept
            for b in batches:
                if b > n * k:
                    log(f"  batch_size {b} > rollout {n * k}: skipped")
                    continue
                for e in epochs:
                    model.batch_size, model.n_epochs = b, e
                    best = math.inf
                    for _ in range(repeats):
                        t0 = clock()
                        model.train()
                        best = min(best, clock() - t0)
                    p = GridPoint(cost, b, e, best)
                    points.append(p)
                    (row,) = grid_rows([p])
                    log(
                        f"  batch {b:5d} x {e:2d} epochs ({row['gradient_steps_per_rollout']:4d} gradient "
                        f"steps):"
                        f" update {row['update_us_per_step']:7.1f}, learner {row['learner_us_per_step']:7.1f}"
                        f" us per env step, learner/env {row['learner_over_env']:.3f}"
                    )
        venv.close()
    settings = {
        "env_id": env_id,
        "algo": algo,
        "policy": policy if isinstance(policy, str) else policy.__name__,
        "policy_kwargs": repr(kwargs.get("policy_kwargs", {})),
        "normalize": zoo["normalize"],
        "repeats": repeats,
        "seed": seed,
        "clock": getattr(clock, "__name__", repr(clock)),
        "torch_threads": torch.get_num_threads(),
        "torch": torch.__version__,
    }
    return points, settings


def plot(rows: Sequence[dict[str, Any]], path: Path, env_speedup: float, title: str) -> Path:
    """Learner cost per env step against the batch size (one panel per n_epochs; a line per
    (n_envs, n_steps)), with the env's measured cost and the planned one as horizontal lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = sorted({r["n_epochs"] for r in rows})
    fig, axes = plt.subplots(1, len(epochs), figsize=(4.2 * len(epochs), 3.8), sharey=True, squeeze=False)
    keys = sorted({(r["n_envs"], r["n_steps"]) for r in rows})
    for ax, e in zip(axes[0], epochs, strict=True):
        for i, (n, k) in enumerate(keys):
            sel = sorted((r for r in rows if r["n_epochs"] == e and (r["n_envs"], r["n_steps"]) == (n, k)),
                         key=lambda r: r["batch_size"])  # fmt: skip
            if not sel:
                continue
            x = [r["batch_size"] for r in sel]
            ax.plot(x, [r["learner_us_per_step"] for r in sel], "o-", color=f"C{i}", ms=3,
                    label=f"N={n}, n_steps={k}")  # fmt: skip
            env = sel[0]["env_us_per_step"]
            ax.axhline(env, color=f"C{i}", ls="--", lw=0.8)
            ax.axhline(env / env_speedup, color=f"C{i}", ls=":", lw=0.8)
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("batch_size")
        ax.set_title(f"n_epochs = {e}", fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("CPU us per env step (learner: solid)")
    axes[0][-1].plot([], [], "k--", lw=0.8, label="env, measured")
    axes[0][-1].plot([], [], "k:", lw=0.8, label=f"env / {env_speedup:g} (planned)")
    axes[0][-1].legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> None:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--env", default="gfb_env/RunUp-v2", help="env id (default gfb_env/RunUp-v2)")
    ap.add_argument("--algo", default="ppo", choices=ALGOS, help="the algorithm and its YAML (default ppo)")
    ap.add_argument("--n-envs", type=int, nargs="+", default=[16], help="native vector env sizes (16)")
    ap.add_argument("--n-steps", type=int, nargs="+", default=[128], help="steps per env per rollout (128)")
    ap.add_argument("--batch-size", type=int, nargs="+", default=[128, 256, 512, 1024], help="minibatches")
    ap.add_argument("--n-epochs", type=int, nargs="+", default=[5, 10], help="passes per rollout (5 10)")
    ap.add_argument("--net-arch", type=int, nargs="+", default=None,
                    help="hidden widths of actor and critic (default: the YAML's)")  # fmt: skip
    ap.add_argument("--repeats", type=int, default=3, help="repeats, the minimum kept (3)")
    ap.add_argument("--env-speedup", type=float, default=3.0,
                    help="the planned plant's speed-up for the second ratio (3: issue 20's aim)")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="results/bench_learner", help="output folder (results/bench_learner)")
    ap.add_argument("--no-plot", action="store_true", help="no figure")
    args = ap.parse_args(argv)
    try:
        for name in ("n_envs", "n_steps", "batch_size", "n_epochs"):
            _check_grid(f"--{name.replace('_', '-')}", getattr(args, name), lo=1 if "epochs" in name else 2)
        if args.repeats < 1:
            raise ValueError(f"--repeats must be positive, got {args.repeats}")
        if not (math.isfinite(args.env_speedup) and args.env_speedup > 0):
            raise ValueError(f"--env-speedup must be finite and positive, got {args.env_speedup}")
        if max(args.n_envs) > 100:
            raise ValueError(f"--n-envs must be at most 100, got {max(args.n_envs)}")
        out = check_output_dir(args.out, "--out", FILES)
    except ValueError as exc:
        ap.error(str(exc))
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        points, settings = measure(
            args.env, args.algo, args.n_envs, args.n_steps, args.batch_size, args.n_epochs,
            args.repeats, args.seed, args.net_arch, log=lambda s: print(s, flush=True),
        )  # fmt: skip
    except ValueError as exc:
        ap.error(str(exc))
    rows = grid_rows(points, args.env_speedup)
    fit = fit_update_cost(points)
    costs = {(p.cost.n_envs, p.cost.n_steps): asdict(p.cost) for p in points}
    summary = {
        **settings,
        "env_speedup": args.env_speedup,
        "load_1min_at_end": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "rollouts": list(costs.values()),
        "update_cost_fit": fit,
        "grid": rows,
        "command": "python -m gfb_experiments.bench_learner "
        + " ".join(sys.argv[1:] if argv is None else argv),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_learner.json").write_text(json.dumps(summary, indent=1) + "\n")
    with open(out / "bench_learner.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["n_envs"])
        w.writeheader()
        w.writerows(rows)
    if not args.no_plot and rows:
        title = f"{args.algo} learner vs env, CPU per env step, {args.env} (process_time, 1 torch thread)"
        plot(rows, out / "bench_learner.png", args.env_speedup, title)
    if fit is not None:
        print(
            f"update fit: {fit['us_per_gradient_step']:.0f} us per gradient step + "
            f"{fit['us_per_sample']:.2f} us per sample "
            f"(max relative residual {fit['max_relative_residual']:.2f})"
        )
    print(json.dumps({k: v for k, v in summary.items() if k != "command"}))


if __name__ == "__main__":
    main()
