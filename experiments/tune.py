"""Grid search of training hyperparameters on the validation seeds: the command line of
:mod:`gfb_agents.learned.tune` (issue 21).

    python -m gfb_experiments.tune --algo ppo --env gfb_env/RunUpRandomized-v2 [--frame-stack K]
        --grid "learning_rate=lin_3e-4,lin_1e-3;n_epochs=5,10" --timesteps N [--seeds 0-1]
        [--eval-episodes E] [--eval-freq N] [--checkpoint-freq N] [--hyperparams BASE.yml] [--n-envs K]
        [--env-kwargs JSON] [--rule {best,final}] [--n-jobs J | --scheduler ADDRESS] [--tensorboard]
        --out DIR

Every grid point x training seed is a full training run (``DIR/<point>/seed<r>``, the point's merged YAML
in ``DIR/<point>/hyperparams.yml``); rerunning the same command continues unfinished runs and skips
finished ones.  Scored on the first ``--eval-episodes`` VALIDATION seeds only (never TEST).  Writes
``DIR/tune.csv`` (one row per point and seed), ``DIR/tune.json`` (grid, budget, the chosen point and the
rule) and ``DIR/tune.png``; the last stdout line is one JSON object.  Bad arguments: exit code 2 and one
line, before any run starts; a failed run: exit code 1 (the others are still scored).
"""

from __future__ import annotations

import json
import os
import shlex
import sys

from gfb_agents.learned.train import ALGOS, MAX_FRAME_STACK, TrainConfig
from gfb_agents.learned.tune import RULES, TuneConfig, check_tune, parse_grid, run_tune
from gfb_env._threads import set_thread_defaults
from gfb_env.scripting import OneLineParser, check_output_dir
from gfb_experiments.train import _parse_seeds

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.tune", description=__doc__.splitlines()[0])
    ap.add_argument("--algo", required=True, choices=ALGOS)
    ap.add_argument("--env", default="gfb_env/RunUpRandomized-v2", help="registered env id")
    ap.add_argument(
        "--grid",
        required=True,
        help="NAME=V1,V2;NAME=... (the Cartesian product; names: the algorithm's keyword arguments, "
        "n_envs, normalize, policy)",
    )
    ap.add_argument("--timesteps", type=int, required=True, help="env steps per run (the budget)")
    ap.add_argument("--seeds", default="0-1", help="training seeds of every point, e.g. 0-1")
    ap.add_argument("--eval-episodes", type=int, default=20, help="validation seeds per validation")
    ap.add_argument("--eval-freq", type=int, default=20_000, help="env steps between validations")
    ap.add_argument("--checkpoint-freq", type=int, default=20_000, help="env steps between checkpoints")
    ap.add_argument("--keep-checkpoints", type=int, default=2)
    ap.add_argument(
        "--frame-stack", type=int, default=1, help=f"stack the last k observations (k <= {MAX_FRAME_STACK})"
    )
    ap.add_argument("--hyperparams", default=None, help="base YAML (default agents/hyperparams/<algo>.yml)")
    ap.add_argument("--n-envs", type=int, default=None, help="parallel envs (default: the YAML's n_envs)")
    ap.add_argument("--env-kwargs", default=None, help="JSON dict of keyword arguments for gymnasium.make")
    ap.add_argument(
        "--rule",
        choices=sorted(RULES),
        default="best",
        help="choose on the mean over seeds of the best (default) or the last validation mean return",
    )
    ap.add_argument("--n-jobs", type=int, default=1, help="runs trained in parallel on this machine")
    ap.add_argument("--scheduler", default=None, help="Dask scheduler address: train on that cluster")
    ap.add_argument("--tensorboard", action="store_true", help="write TensorBoard logs (off: disk)")
    ap.add_argument("--out", required=True, help="the search's folder")
    a = ap.parse_args(argv)
    set_thread_defaults()
    if a.timesteps <= 0:
        ap.error(f"--timesteps must be a positive integer, got {a.timesteps}")
    env_kwargs = None
    if a.env_kwargs:
        try:
            env_kwargs = json.loads(a.env_kwargs)
        except json.JSONDecodeError as exc:
            ap.error(f"--env-kwargs is not valid JSON: {exc}")
        if not isinstance(env_kwargs, dict):
            ap.error("--env-kwargs must be a JSON object")
    cpus = os.cpu_count() or 1
    if a.scheduler is None and not (a.n_jobs == -1 or 1 <= a.n_jobs <= cpus):
        ap.error(f"--n-jobs must be -1 or lie in [1, {cpus}] (this machine's cores), got {a.n_jobs}")
    from gfb_env.envs import RETIRED_IDS
    from gfb_env.envs.retired import retired_message

    if a.env in RETIRED_IDS:
        ap.error(f"--env {retired_message(a.env)}")
    cmd = "python -m gfb_experiments.tune " + " ".join(
        shlex.quote(x) for x in (argv if argv is not None else sys.argv[1:])
    )
    try:
        seeds = _parse_seeds(a.seeds)
        grid = parse_grid(a.grid)
        check_output_dir(a.out, "--out")
        base = TrainConfig(
            algo=a.algo,
            env_id=a.env,
            timesteps=a.timesteps,
            n_envs=a.n_envs,
            hyperparams=a.hyperparams,
            env_kwargs=env_kwargs,
            eval_freq=a.eval_freq,
            eval_episodes=a.eval_episodes,
            checkpoint_freq=a.checkpoint_freq,
            keep_checkpoints=a.keep_checkpoints,
            frame_stack=a.frame_stack,
            progress_bar=False,
            tensorboard=a.tensorboard,
        )
        config = TuneConfig(base=base, grid=grid, seeds=tuple(seeds), out=a.out, rule=a.rule)
        check_tune(config, a.scheduler)  # everything a run would fail on, before any starts
    except (ValueError, FileNotFoundError) as exc:
        ap.error(str(exc))
    rec = run_tune(config, n_jobs=a.n_jobs, scheduler=a.scheduler, command=cmd)
    for s in rec["per_point"]:
        print(
            f"point {s['index']} {s['name']}: {s['seeds_scored']}/{len(seeds)} seeds, validation mean "
            f"return best {s['mean_best_return']} last {s['mean_final_return']}, success best "
            f"{s['mean_best_success_rate']} last {s['mean_final_success_rate']}"
        )
    for out in rec["failed_runs"]:
        print(f"run {out}: FAILED or interrupted (not scored)", file=sys.stderr)
    chosen = rec["chosen"]
    print(
        json.dumps(
            {
                "out": str(config.out),
                "points": rec["points"],
                "runs": rec["budget"]["runs"],
                "env_steps": rec["budget"]["env_steps"],
                "run_wall_time_s": rec["budget"]["run_wall_time_s"],
                "rule": a.rule,
                "chosen": None if chosen is None else chosen["settings"],
                "chosen_hyperparams": None if chosen is None else chosen["hyperparams"],
                "score": None if chosen is None else chosen[RULES[a.rule]],
                "failed_runs": len(rec["failed_runs"]),
                "csv": str(config.out / "tune.csv"),
                "json": str(config.out / "tune.json"),
                "png": str(config.out / "tune.png"),
            }
        )
    )
    return 1 if rec["failed_runs"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
