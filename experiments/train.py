"""Train Stable-Baselines3 agents on a gfb_env task: the command line of :mod:`gfb_agents.learned.train`.

    python -m gfb_experiments.train --algo {ppo,sac,recurrentppo,asymmetric_ppo}
        --env gfb_env/RunUpRandomized-v2
        [--seeds 0-4 | --seed R] [--timesteps N] [--n-jobs K | --scheduler ADDRESS] [--out DIR]
        [--n-envs K] [--frame-stack K] [--hyperparams FILE] [--env-kwargs JSON] [--eval-freq N]
        [--eval-episodes N] [--checkpoint-freq N] [--keep-checkpoints N] [--no-progress-bar]
        [--vec-env {dummy,subproc,native}] [--privileged-quantities NAME,...]
        [--damping-slew R [--damping-slew-reserve C]]

``--damping-slew R``: the policy's damping action is a set-point the command follows by at most ``R``
action units per control step (:mod:`gfb_agents.learned.slew`; part of the deployed policy; default off);
``--damping-slew-reserve C``: a step may also spend up to ``C`` of the allowance earlier steps left unused.

``asymmetric_ppo``: PPO whose critic also sees the episode's privileged vector (training only; the actor,
the deployed policy, sees the observation): :mod:`gfb_agents.learned.asymmetric`.

What a run writes, how it resumes, seeds and model selection: the docstring of
:mod:`gfb_agents.learned.train`.  Every bad argument is refused before any run starts (one line, exit 2).
"""

from __future__ import annotations

import json
import os
import shlex
import sys

from gfb_agents.learned.slew import check_damping_slew, check_damping_slew_reserve
from gfb_agents.learned.teacher_student import STUDENT_ALGO, TEACHER_ALGO
from gfb_agents.learned.train import (
    ALGOS,
    MAX_FRAME_STACK,
    VEC_ENVS,
    TrainConfig,
    check_runs,
    train_seeds,
)
from gfb_agents.seeds import MAX_TRAIN_RUNS
from gfb_env._threads import set_thread_defaults
from gfb_env.scripting import OneLineParser, check_output_dir

__all__ = ["main"]


def _parse_seeds(text: str) -> list[int]:
    """``"0-4"`` or ``"0,1,7"`` -> a sorted list of distinct run indices."""
    out: set[int] = set()
    try:
        for part in text.split(","):
            if "-" in part:
                a, b = part.split("-", 1)
                out.update(range(int(a), int(b) + 1))
            else:
                out.add(int(part))
    except ValueError:
        raise ValueError(f"--seeds must look like 0-4 or 0,1,7, got {text!r}") from None
    if not out or min(out) < 0 or max(out) >= MAX_TRAIN_RUNS:
        raise ValueError(f"--seeds must name runs in [0, {MAX_TRAIN_RUNS}), got {text!r}")
    return sorted(out)


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.train", description=__doc__.splitlines()[0])
    ap.add_argument("--algo", required=True, choices=(*ALGOS, STUDENT_ALGO))
    ap.add_argument(
        "--env",
        default=None,
        help="registered env id (default gfb_env/RunUpRandomized-v2; teacher_student: the teacher's, "
        "or with --teacher oracle the task to distil on)",
    )
    ap.add_argument(
        "--teacher",
        default=None,
        help="teacher_student: the privileged_ppo training run (a seed<r> folder) to distil from, or "
        "'oracle' (the benchmark's oracle; then --env and --damping-slew are given)",
    )
    ap.add_argument(
        "--timesteps",
        type=int,
        default=None,
        help="total env steps per run (default: n_timesteps of the YAML)",
    )
    ap.add_argument("--seed", type=int, default=None, help="one training run (default 0)")
    ap.add_argument(
        "--seeds", default=None, help="several independent runs, e.g. 0-4 (each in <out>/seed<r>)"
    )
    ap.add_argument("--n-jobs", type=int, default=1, help="runs trained in parallel on this machine")
    ap.add_argument(
        "--scheduler", default=None, help="Dask scheduler address: train the runs on that cluster"
    )
    ap.add_argument("--n-envs", type=int, default=None, help="parallel envs (default: the YAML's n_envs)")
    ap.add_argument(
        "--out", default=None, help="experiment directory (default runs/<env>_<algo>); run r in <out>/seed<r>"
    )
    ap.add_argument(
        "--hyperparams", default=None, help="zoo-style YAML (default agents/hyperparams/<algo>.yml)"
    )
    ap.add_argument("--env-kwargs", default=None, help="JSON dict of keyword arguments for gymnasium.make")
    ap.add_argument("--eval-freq", type=int, default=20_000, help="env steps between validations")
    ap.add_argument("--eval-episodes", type=int, default=20, help="validation seeds per validation")
    ap.add_argument("--checkpoint-freq", type=int, default=20_000, help="env steps between checkpoints")
    ap.add_argument("--keep-checkpoints", type=int, default=2, help="checkpoints kept on disk")
    ap.add_argument(
        "--frame-stack",
        type=int,
        default=1,
        help=f"stack the last k observations (memory; PPO only, k <= {MAX_FRAME_STACK})",
    )
    ap.add_argument("--no-progress-bar", action="store_true")
    ap.add_argument("--no-tensorboard", action="store_true")
    ap.add_argument("--verbose", type=int, default=0)
    ap.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="torch CPU threads (default 1: the env is the bottleneck and cores are shared)",
    )
    ap.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default="native",
        help="training envs in this process (dummy), one worker process each (subproc), or the task's "
        "native vector env (native)",
    )
    ap.add_argument(
        "--num-processes",
        type=int,
        default=1,
        help="native vector env only: its envs in this many worker processes (default 1: none; the "
        "results do not depend on it)",
    )
    ap.add_argument(
        "--privileged-quantities",
        default=None,
        help="asymmetric_ppo: true step quantities appended to the critic's privileged vector, e.g. "
        "whirl_amplitude,min_film_thickness (gfb_agents.learned.privileged.STEP_QUANTITIES)",
    )
    ap.add_argument(
        "--damping-slew",
        type=float,
        default=None,
        help="slew limit of the damping command, action units per control step in (0, 2] (2: the whole "
        "damping range): the policy's damping action becomes a set-point the command follows by at most "
        "this much per step, in training and in the deployed policy (default: none)",
    )
    ap.add_argument(
        "--damping-slew-reserve",
        type=float,
        default=None,
        help="with --damping-slew: the unused allowance (action units, in (0, 2]) a step may save for a "
        "later one, so that holding the damping buys a jump; the mean |change| stays at most R",
    )
    a = ap.parse_args(argv)
    try:  # before anything else: a bad limit is one line (exit 2)
        check_damping_slew_reserve(a.damping_slew_reserve, check_damping_slew(a.damping_slew))
    except ValueError as exc:
        ap.error(str(exc))
    set_thread_defaults()  # single-threaded BLAS in the subproc workers (see gfb_env._threads)
    env_kwargs = None
    if a.env_kwargs:
        try:
            env_kwargs = json.loads(a.env_kwargs)
        except json.JSONDecodeError as exc:
            ap.error(f"--env-kwargs is not valid JSON: {exc}")
        if not isinstance(env_kwargs, dict):
            ap.error("--env-kwargs must be a JSON object")
    if a.seed is not None and a.seeds is not None:
        ap.error("--seed and --seeds exclude each other")
    try:
        run_seeds = _parse_seeds(a.seeds) if a.seeds is not None else [0 if a.seed is None else a.seed]
    except ValueError as exc:
        ap.error(str(exc))
    cpus = os.cpu_count() or 1
    if a.scheduler is None and not (a.n_jobs == -1 or 1 <= a.n_jobs <= cpus):
        ap.error(f"--n-jobs must be -1 or lie in [1, {cpus}] (this machine's cores), got {a.n_jobs}")
    if a.out is not None:
        try:  # before any training: an unwritable --out fails now, not at the first checkpoint
            check_output_dir(a.out, "--out")
        except ValueError as exc:
            ap.error(str(exc))
    cmd = "python -m gfb_experiments.train " + " ".join(
        shlex.quote(x) for x in (argv if argv is not None else sys.argv[1:])
    )
    if a.algo == STUDENT_ALGO:
        return _distill_main(ap, a, run_seeds, cmd)
    if a.teacher is not None:
        ap.error(f"--teacher: only with --algo {STUDENT_ALGO}")
    try:
        config = TrainConfig(
            algo=a.algo,
            env_id=a.env or "gfb_env/RunUpRandomized-v2",
            timesteps=a.timesteps,
            seed=run_seeds[0],
            n_envs=a.n_envs,
            out=a.out,
            hyperparams=a.hyperparams,
            env_kwargs=env_kwargs,
            eval_freq=a.eval_freq,
            eval_episodes=a.eval_episodes,
            checkpoint_freq=a.checkpoint_freq,
            keep_checkpoints=a.keep_checkpoints,
            frame_stack=a.frame_stack,
            progress_bar=not a.no_progress_bar,
            tensorboard=not a.no_tensorboard,
            verbose=a.verbose,
            torch_threads=a.torch_threads,
            vec_env=a.vec_env,
            privileged_quantities=tuple(q for q in (a.privileged_quantities or "").split(",") if q),
            num_processes=a.num_processes,
            damping_slew=a.damping_slew,
            damping_slew_reserve=a.damping_slew_reserve,
        )
        check_runs(config, run_seeds, a.scheduler)  # everything a run would fail on, before any starts
        recs = train_seeds(
            config,
            run_seeds,
            n_jobs=a.n_jobs,
            scheduler=a.scheduler,
            command=cmd,
        )
    except (ValueError, FileNotFoundError) as exc:
        ap.error(str(exc))
    failed = 0
    for rec in recs:
        if rec["error"] is not None:
            failed += 1
            print(f"run {rec['point']['seed']}: FAILED: {rec['error']}", file=sys.stderr)
        else:
            r = rec["result"]
            best = r["best_validation"] or {}
            print(
                f"run {r['seed']}: {r['out']} {r['timesteps']} steps, {r['wall_time_s']} s, "
                f"{r['env_steps_per_s']} steps/s, best validation {best.get('mean_return')} at "
                f"{best.get('timesteps')}"
            )
    return 1 if failed else 0


def _distill_main(ap, a, run_seeds: list[int], cmd: str) -> int:
    """``--algo teacher_student``: DAgger from ``--teacher``
    (:func:`gfb_agents.learned.teacher_student.distill`), one run per seed in ``<out>/seed<r>``, one
    after another; refusals before any run (one line, exit 2)."""
    from pathlib import Path

    from gfb_agents.learned.oracle_teacher import ORACLE_TEACHER
    from gfb_agents.learned.teacher_student import DistillConfig, distill

    if a.teacher is None:
        ap.error(
            f"--algo {STUDENT_ALGO} needs --teacher RUN (a {TEACHER_ALGO} training run) or --teacher "
            f"{ORACLE_TEACHER}"
        )
    oracle = a.teacher == ORACLE_TEACHER
    if oracle and a.env is None:
        ap.error(f"--teacher {ORACLE_TEACHER} needs --env ID (the oracle is not a training run)")
    if not oracle and (a.damping_slew is not None or a.damping_slew_reserve is not None):
        # the student's labels are its teacher's set-points: it takes the teacher's slew limit
        ap.error(
            f"--damping-slew: not with --algo {STUDENT_ALGO} (the student takes its teacher's slew limit; "
            f"train the {TEACHER_ALGO} teacher with --damping-slew)"
        )
    for flag, bad in (
        ("--frame-stack", a.frame_stack != 1),
        ("--env-kwargs", a.env_kwargs is not None),
        ("--scheduler", a.scheduler is not None),
        ("--n-jobs", a.n_jobs != 1),
        ("--privileged-quantities", a.privileged_quantities is not None),
        ("--vec-env subproc", a.vec_env == "subproc"),
    ):
        if bad:
            ap.error(
                f"{flag}: not with --algo {STUDENT_ALGO} (its history and env come from its YAML and teacher)"
            )
    try:
        configs = [
            DistillConfig(
                teacher=Path(a.teacher),
                timesteps=a.timesteps,
                seed=r,
                hyperparams=a.hyperparams,
                n_envs=a.n_envs,
                eval_episodes=a.eval_episodes,
                vec_env=a.vec_env,
                **(
                    {
                        "env_id": a.env,
                        "damping_slew": a.damping_slew,
                        "damping_slew_reserve": a.damping_slew_reserve,
                    }
                    if oracle
                    else {}
                ),
            )
            for r in run_seeds
        ]
        if not oracle and a.env is not None and a.env != configs[0].env_id:
            raise ValueError(f"--env {a.env}: the teacher was trained on {configs[0].env_id}")
        root = (
            Path(a.out)
            if a.out is not None
            else Path("runs") / f"{configs[0].env_id.split('/')[-1]}_{STUDENT_ALGO}"
        )
        configs = [DistillConfig(**{**c.as_dict(), "out": root / f"seed{c.seed}"}) for c in configs]
        for c in configs:
            c.check_folder()
        check_output_dir(str(root), "--out")
    except (ValueError, FileNotFoundError) as exc:
        ap.error(str(exc))
    for c in configs:
        out = distill(c, cmd)
        meta = json.loads((out / "run.json").read_text())
        best = meta["best_validation"] or {}
        print(
            f"run {c.seed}: {out} {meta['timesteps']} steps, {meta['wall_time_s']} s, "
            f"{meta['env_steps_per_s']} steps/s, best validation {best.get('mean_return')} at "
            f"{best.get('timesteps')}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
