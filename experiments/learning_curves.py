"""Learning curves of training runs on the validation seeds (issue 21): normalised score and success against
env steps and wall time, mean and 95 % CI over the independent training seeds, per method::

    python -m gfb_experiments.learning_curves runs/RunUpRandomized-v2_ppo_fs4 [RUN_DIR ...] \\
        [--rules margin_aim_1x,margin_search_1x] [--out results/learning_curves_v2] [--reps 2000]

Each RUN_DIR is one method: a training folder of ``python -m gfb_experiments.train`` (``seed<r>/run.json``
and ``seed<r>/validation.json``; a single run's folder works too); its name is the method's.  What a point
is: the run's validation (``validation.json``: the first ``--eval-episodes`` VALIDATION seeds, the policy
deterministic, through the benchmark's episode runner) after that many env steps; its wall time is the
run's own (``wall_time_s`` of the record, or for records written before it, the steps over the run's mean
throughput, said in the CSV's ``wall_time_source``).

Normalisation (the table's mean columns): ``(return - zero) / (oracle - zero)`` with ``zero`` the better of
the naive's and hold's mean return and ``oracle`` the oracle's, all played here on the same validation
seeds (``references.json``, cached: a rerun with the same seeds and env arguments reuses them).  The rules
named by ``--rules`` are played on the same seeds and drawn as horizontal lines (what a learned agent must
reach).  Curves of several seeds are put on the validation steps of their first seed (linear
interpolation, only where every seed has data); the CI is a percentile bootstrap over the seeds
(``--reps``), absent for one seed.

Writes ``<out>/learning_curves.csv`` (one row per method and point: task, method, seeds, timesteps,
wall_time_s, normalised mean and CI, success mean and CI, mean return), ``<out>/references.json`` and
``<out>/learning_curves_<task>.png``.  Bad input (a folder without training runs, runs of several tasks
or validation seeds in one method, an unknown rule) exits 2 with one line before any episode.  Only
validation seeds: the test seeds are the table's.
"""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

from gfb_env.scripting import OneLineParser, check_output_dir

__all__ = ["load_method", "normalise", "aggregate", "main"]

COLUMNS = (
    "task",
    "method",
    "seeds",
    "timesteps",
    "wall_time_s",
    "wall_time_source",
    "normalised_mean",
    "normalised_ci_low",
    "normalised_ci_high",
    "success_mean",
    "success_ci_low",
    "success_ci_high",
    "return_mean",
)


def load_method(folder: Path) -> dict:
    """The runs of one method: ``{"name", "task", "seeds", "env_kwargs", "runs": [{seed, steps, wall,
    wall_source, returns, success}]}`` (ValueError naming the folder for anything inconsistent)."""
    folder = Path(folder)
    dirs = sorted(p.parent for p in folder.glob("seed*/run.json")) or (
        [folder] if (folder / "run.json").exists() else []
    )
    if not dirs:
        raise ValueError(f"{folder}: no training run (seed*/run.json or run.json) there")
    runs, tasks, seed_sets, kwargs = [], set(), set(), []
    for d in dirs:
        vp = d / "validation.json"
        if not vp.exists():
            raise ValueError(f"{d}: no validation.json (a run that never validated)")
        run, val = json.loads((d / "run.json").read_text()), json.loads(vp.read_text())
        hist = sorted(val.get("history", []), key=lambda h: h["timesteps"])
        if not hist:
            raise ValueError(f"{d}: validation.json holds no validation")
        tasks.add(run["env_id"])
        seed_sets.add(tuple(val["seeds"]))
        kwargs.append(run.get("env_kwargs") or {})
        rate = float(run.get("env_steps_per_s") or math.nan)
        has_wall = all("wall_time_s" in h for h in hist)
        runs.append(
            {
                "seed": run.get("seed"),
                "steps": np.array([h["timesteps"] for h in hist], dtype=float),
                "wall": np.array(
                    [h["wall_time_s"] if has_wall else h["timesteps"] / rate for h in hist], dtype=float
                ),
                "wall_source": "recorded" if has_wall else "steps / mean env_steps_per_s",
                "returns": np.array([h["mean_return"] for h in hist], dtype=float),
                "success": np.array([h["success_rate"] for h in hist], dtype=float),
            }
        )
    if len(tasks) != 1:
        raise ValueError(f"{folder}: runs of several tasks ({', '.join(sorted(tasks))}) in one method")
    if len(seed_sets) != 1:
        raise ValueError(f"{folder}: its runs validated on different seeds; one method, one seed set")
    if any(k != kwargs[0] for k in kwargs):
        raise ValueError(f"{folder}: its runs used different env arguments")
    (seeds,) = seed_sets
    from gfb_agents.seeds import VALIDATION

    if not all(int(s) in VALIDATION for s in seeds):
        raise ValueError(f"{folder}: validated on seeds outside VALIDATION; curves use validation seeds only")
    return {
        "name": folder.name,
        "task": tasks.pop(),
        "seeds": [int(s) for s in seeds],
        "env_kwargs": kwargs[0],
        "runs": runs,
    }


def normalise(returns: np.ndarray, ref: dict) -> np.ndarray:
    """``(returns - zero) / (oracle - zero)``, ``zero`` the better of the naive's and hold's means."""
    zero = max(ref["naive"], ref["hold"])
    return (np.asarray(returns, dtype=float) - zero) / (ref["oracle"] - zero)


def _bootstrap(rows: np.ndarray, reps: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Percentile 95 % CI over the seeds (``rows``: seeds x points) of the mean; NaN for one seed."""
    n = rows.shape[0]
    if n < 2:
        nan = np.full(rows.shape[1], math.nan)
        return nan, nan
    idx = rng.integers(0, n, size=(reps, n))
    means = rows[idx].mean(axis=1)  # reps x points
    return np.percentile(means, 2.5, axis=0), np.percentile(means, 97.5, axis=0)


def aggregate(method: dict, ref: dict, reps: int = 2000, seed: int = 0) -> list[dict]:
    """One row per point of ``method``'s curve (module docstring)."""
    runs = method["runs"]
    grid = runs[0]["steps"]
    lo = max(r["steps"][0] for r in runs)
    hi = min(r["steps"][-1] for r in runs)
    grid = grid[(grid >= lo) & (grid <= hi)]
    norm = np.array([np.interp(grid, r["steps"], normalise(r["returns"], ref)) for r in runs])
    succ = np.array([np.interp(grid, r["steps"], r["success"]) for r in runs])
    rets = np.array([np.interp(grid, r["steps"], r["returns"]) for r in runs])
    wall = np.array([np.interp(grid, r["steps"], r["wall"]) for r in runs])
    rng = np.random.default_rng(seed)
    n_lo, n_hi = _bootstrap(norm, reps, rng)
    s_lo, s_hi = _bootstrap(succ, reps, rng)
    sources = sorted({r["wall_source"] for r in runs})
    return [
        {
            "task": method["task"],
            "method": method["name"],
            "seeds": len(runs),
            "timesteps": int(grid[j]),
            "wall_time_s": float(wall[:, j].mean()),
            "wall_time_source": "; ".join(sources),
            "normalised_mean": float(norm[:, j].mean()),
            "normalised_ci_low": float(n_lo[j]),
            "normalised_ci_high": float(n_hi[j]),
            "success_mean": float(succ[:, j].mean()),
            "success_ci_low": float(s_lo[j]),
            "success_ci_high": float(s_hi[j]),
            "return_mean": float(rets[:, j].mean()),
        }
        for j in range(len(grid))
    ]


def _ref_key(task: str, seeds: list[int], env_kwargs: dict) -> str:
    return json.dumps([task, seeds, env_kwargs], sort_keys=True)


def references(task: str, seeds: list[int], env_kwargs: dict, rules: list[str], cache: dict) -> dict:
    """Mean returns of naive, hold, the oracle and ``rules`` on ``seeds`` (played unless in ``cache``)."""
    from gfb_agents import ladder
    from gfb_agents.learned.evaluate import run_episode
    from gfb_env.envs import make_env

    key = _ref_key(task, seeds, env_kwargs)
    ref = cache.setdefault(key, {"task": task, "seeds": seeds, "env_kwargs": env_kwargs, "mean_return": {}})
    names = {
        "naive": ladder.naive_for(task).name,
        "hold": "hold",
        "oracle": ladder.oracle_for(task).name,
        **{r: r for r in rules},
    }
    for label, name in names.items():
        if label in ref["mean_return"]:
            continue
        # the policy plays on the env it was built with: the oracle reads that env's privileged channel
        # (built on one env and played on another, it asked a closed env for its draw)
        env = make_env(task, **env_kwargs)
        try:
            policy = ladder.build(name, env)
            res = [run_episode(env, policy, int(s)) for s in seeds]
        finally:
            env.close()
        ref["mean_return"][label] = float(np.mean([r.episode_return for r in res]))
        print(f"  {task} {label} ({name}): mean return {ref['mean_return'][label]:.2f}", file=sys.stderr)
    return ref["mean_return"]


def _plot(task: str, rows: list[dict], ref: dict, rules: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharey="row")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for m in methods:
        pts = [r for r in rows if r["method"] == m]
        n = pts[0]["seeds"]
        for col, x in enumerate(("timesteps", "wall_time_s")):
            xs = np.array([p[x] for p in pts]) / (1e6 if x == "timesteps" else 60.0)
            for row, y in enumerate(("normalised", "success")):
                ax = axes[row, col]
                mean = np.array([p[f"{y}_mean"] for p in pts])
                (line,) = ax.plot(xs, mean, label=f"{m} ({n} seed{'s' if n > 1 else ''})")
                lo = np.array([p[f"{y}_ci_low"] for p in pts])
                hi = np.array([p[f"{y}_ci_high"] for p in pts])
                if np.all(np.isfinite(lo)):
                    ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2)
    # the rules in the legend (annotations of close lines overlapped), one dash style each
    styles = ("--", "-.", ":", (0, (5, 1, 1, 1)), (0, (1, 3)))
    for i, rule in enumerate(rules):
        v = float(normalise([ref[rule]], ref)[0])
        for col in range(2):
            axes[0, col].axhline(
                v,
                ls=styles[i % len(styles)],
                lw=1,
                color="k",
                label=f"{rule} (rule) {v:.2f}" if col == 0 else None,
            )
    for col in range(2):
        axes[0, col].axhline(1.0, ls=":", lw=1, color="g")
        axes[0, col].axhline(0.0, ls=":", lw=1, color="gray")
        axes[1, col].set_xlabel("env steps (millions)" if col == 0 else "wall time of the run (min)")
    axes[0, 0].set_ylabel("normalised score (0 = better of naive, hold; 1 = oracle)")
    axes[1, 0].set_ylabel("success rate")
    axes[0, 0].legend(fontsize=8, loc="lower right")
    fig.suptitle(f"{task}: validation seeds, mean and 95 % CI over training seeds")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.learning_curves", description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="training folders (one method each)")
    ap.add_argument("--rules", default="", help="rules drawn as reference lines, comma-separated")
    ap.add_argument("--out", default="results/learning_curves_v2")
    ap.add_argument("--reps", type=int, default=2000, help="bootstrap replications over the seeds")
    a = ap.parse_args(argv)
    if a.reps < 100:
        ap.error(f"--reps must be >= 100, got {a.reps}")
    try:
        out = check_output_dir(a.out, "--out")
    except ValueError as exc:
        ap.error(str(exc))
    methods = []
    for d in a.runs:
        try:
            methods.append(load_method(Path(d)))
        except (ValueError, KeyError, json.JSONDecodeError) as exc:
            ap.error(f"{d}: {exc}" if not str(exc).startswith(str(d)) else str(exc))
    rules = [r for r in a.rules.split(",") if r]
    from gfb_agents import ladder

    for m in methods:
        known = {e.name for e in ladder.ladder_for(m["task"]) if e.kind == "rule"}
        unknown = [r for r in rules if r not in known]
        if unknown:
            ap.error(
                f"--rules: {', '.join(unknown)} not a rule of {m['task']}; "
                f"its rules: {', '.join(sorted(known))}"
            )
    out.mkdir(parents=True, exist_ok=True)
    cache_path = out / "references.json"
    cache = json.loads(cache_path.read_text()) if cache_path.exists() else {}
    rows: list[dict] = []
    refs: dict[str, dict] = {}
    for m in methods:
        ref = references(m["task"], m["seeds"], m["env_kwargs"], rules, cache)
        cache_path.write_text(json.dumps(cache, indent=1) + "\n")
        refs[m["task"]] = ref
        rows += aggregate(m, ref, reps=a.reps)
    with open(out / "learning_curves.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    for task in dict.fromkeys(r["task"] for r in rows):
        name = task.split("/")[-1]
        _plot(
            task,
            [r for r in rows if r["task"] == task],
            refs[task],
            rules,
            out / f"learning_curves_{name}.png",
        )
    for m in methods:
        last = [r for r in rows if r["method"] == m["name"]][-1]
        print(
            f"{m['name']}: {last['seeds']} seeds, {last['timesteps']} steps, normalised "
            f"{last['normalised_mean']:.3f} "
            f"[{last['normalised_ci_low']:.3f}, {last['normalised_ci_high']:.3f}], "
            f"success {last['success_mean']:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
