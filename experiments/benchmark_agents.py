"""Run-up benchmark: every scripted baseline and every committed learned policy on every task.

    python -m gfb_experiments.benchmark_agents [--episodes 50] [--quick] [--tasks ID,ID] [--agents NAME,NAME]
                                           [--out results] [--n-jobs 1] [--policies DIR | --no-learned]

Each (task, agent) pair plays the same fixed, seeded episodes (seeds ``10000, 10001, ...``; the env is
reset with the seed, the policy is deterministic), and the results are reduced to one row
(:func:`gfb_agents.evaluate.summarise`).  Writes ``<out>/benchmark_agents.csv``, ``<out>/benchmark_agents.md``
(the Markdown table) and ``<out>/benchmark_agents_paths.png`` (each agent's first episode as a path in the
(Lambda, D_W) plane over the stable / bistable / whirl regions of the nominal bearing's map; the paths are
also kept in ``benchmark_agents_paths.json``).  ``--quick`` plays one episode per pair (for tests);
``--merge`` replaces/adds the (task, agent) rows of this run in an existing table; ``--env-kwargs`` passes
``gymnasium.make`` arguments per task.  Learned policies that are expected but missing (no folder, or no
``<name>/model.zip`` in it) end the run at once with exit code 2; ``--no-learned`` runs without them.
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from gfb_agents.evaluate import (
    POLICIES_DIR,
    EpisodeResult,
    LearnedPolicy,
    evaluate,
    load_learned_policies,
    summarise,
)
from gfb_agents.identify import IdentifyingAgent, OracleAgent
from gfb_agents.nominal_map import NominalMap
from gfb_agents.scripted import Policy, make_scripted_agents
from gfb_env import jsonio
from gfb_env._cli_common import OneLineParser, check_output_dir
from gfb_env.envs import V0_IDS

TASKS = V0_IDS  # the task list has one owner; the v1 tasks join the rebuilt benchmark (issue 11)
SEED0 = 10_000
COLUMNS = [
    "task",
    "agent",
    "kind",
    "episodes",
    "success_rate",
    "mean_return",
    "return_ci95",
    "time_to_target_s",
    "final_speed_rpm",
    "final_stable_rate",
    "max_whirl_amplitude",
    "touchdowns",
    "mean_steps",
    "wall_s",
]


def agents_for(task: str, learned: list[LearnedPolicy], env_kwargs: dict | None = None) -> dict[str, Policy]:
    """Scripted baselines (built against ``task``'s documented configuration), the identifying rule
    ``identify_map``, the ``oracle`` (it knows the hidden draw) and the learned policies trained on
    ``task``."""
    env = gym.make(task, **(env_kwargs or {}))
    out: dict[str, Policy] = dict(make_scripted_agents(env))
    for ref in (IdentifyingAgent(env), OracleAgent(env)):
        out[ref.name] = ref
    env.close()
    for p in learned:
        if p.env_id == task:
            out[p.name] = p
    return out


def _run_pair(
    task: str, name: str, policy: Policy, seeds: list[int], env_kwargs: dict | None = None
) -> tuple[str, str, list[EpisodeResult], float]:
    t0 = time.perf_counter()
    res = evaluate(task, policy, seeds, env_kwargs=env_kwargs, record_path_seeds=(seeds[0],))
    return task, name, res, time.perf_counter() - t0


def run_benchmark(
    tasks: list[str],
    episodes: int,
    agent_filter: set[str] | None = None,
    n_jobs: int = 1,
    policies_dir: str | Path | None = None,
    env_kwargs: dict[str, dict] | None = None,
    learned: list[LearnedPolicy] | None = None,
) -> tuple[list[dict], dict]:
    """Rows of the table and the first-episode paths ``{(task, agent): {"lam", "dw", "success", "reason"}}``.

    ``env_kwargs`` maps a task id to extra ``gymnasium.make`` arguments (used by every agent of the task).
    ``learned``: the learned policies to run (default: :func:`load_learned_policies` of ``policies_dir``
    or of the shipped folder; a missing folder raises FileNotFoundError); ``[]`` runs the scripted
    baselines only."""
    from tqdm import tqdm

    env_kwargs = env_kwargs or {}
    if learned is None:
        learned = load_learned_policies(policies_dir) if policies_dir else load_learned_policies()
    seeds = [SEED0 + i for i in range(episodes)]
    jobs = []
    for task in tasks:
        for name, pol in agents_for(task, learned, env_kwargs.get(task)).items():
            if agent_filter and name not in agent_filter:
                continue
            jobs.append((task, name, pol))
    rows, paths = [], {}
    bar = tqdm(total=len(jobs), desc="benchmark (task, agent)", unit="pair")
    if n_jobs > 1:
        from joblib import Parallel, delayed

        outs = Parallel(n_jobs=n_jobs, return_as="generator")(
            delayed(_run_pair)(t, n, p, seeds, env_kwargs.get(t)) for t, n, p in jobs
        )
    else:
        outs = (_run_pair(t, n, p, seeds, env_kwargs.get(t)) for t, n, p in jobs)
    kinds = {(t, n): p.kind for t, n, p in jobs}
    for task, name, res, wall in outs:
        row = {
            "task": task,
            "agent": name,
            "kind": kinds[(task, name)],
            **summarise(res),
            "wall_s": round(wall, 1),
        }
        rows.append(row)
        r0 = res[0]
        paths[(task, name)] = {
            "lam": [float(x) for x in r0.path_bearing_number],
            "dw": [float(x) for x in r0.path_damping],
            "success": bool(r0.success),
            "reason": r0.termination_reason,
        }
        bar.set_postfix_str(f"{task.split('/')[-1]} {name}: {row['mean_return']:.1f}")
        bar.update(1)
    bar.close()
    return rows, paths


def _read_previous(out: Path) -> tuple[list[dict], dict]:
    """Rows and paths of an earlier run in ``out`` (for ``--merge``)."""
    rows, paths = [], {}
    p = out / "benchmark_agents.csv"
    if p.exists():
        for r in csv.DictReader(p.open()):
            row = dict(r)
            for k in COLUMNS[3:]:
                v = row.get(k, "")
                row[k] = math.nan if v in ("", None) else float(v)
            for k in ("episodes", "touchdowns"):
                row[k] = int(row[k])
            rows.append(row)
    pj = out / "benchmark_agents_paths.json"
    if pj.exists():
        for key, v in json.loads(pj.read_text()).items():
            task, agent = key.split("|", 1)
            paths[(task, agent)] = v
    return rows, paths


def _fmt(v, digits: int = 2) -> str:
    if isinstance(v, float):
        if not math.isfinite(v):
            return "-"
        return f"{v:.{digits}f}"
    return str(v)


def write_csv(rows: list[dict], path: Path) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(
                {
                    k: ("" if isinstance(r.get(k), float) and not math.isfinite(r[k]) else r.get(k))
                    for k in COLUMNS
                }
            )


def markdown_table(rows: list[dict], episodes: int) -> str:
    """The benchmark as Markdown (one table, grouped by task, best mean return in bold per task)."""
    head = (
        "| task | agent | kind | success | return (mean +- 95% CI) | time to target (s) | final stable "
        "speed (rpm) | max whirl (C) | touchdowns |"
    )
    lines = [
        f"Benchmark: {episodes} seeded episodes per (task, agent) (seeds {SEED0}...{SEED0 + episodes - 1}); "
        "`python -m gfb_experiments.benchmark_agents`.",
        "",
        head,
        "|" + "---|" * 9,
    ]
    for task in dict.fromkeys(r["task"] for r in rows):
        sub = [r for r in rows if r["task"] == task]
        best = max(r["mean_return"] for r in sub)
        for r in sorted(sub, key=lambda r: -r["mean_return"]):
            ret = f"{r['mean_return']:.1f} +- {_fmt(r['return_ci95'], 1)}"
            if r["mean_return"] == best:
                ret = f"**{ret}**"
            lines.append(
                f"| {task.split('/')[-1]} | {r['agent']} | {r['kind']} | {r['success_rate']:.0%} | {ret} | "
                f"{_fmt(r['time_to_target_s'], 3)} | {_fmt(r['final_speed_rpm'], 0)} | "
                f"{_fmt(r['max_whirl_amplitude'], 3)} | {r['touchdowns']}/{r['episodes']} |"
            )
    lines += [
        "",
        "Columns: success = share of episodes ending in `success`; time to target = rotor time until the "
        "speed is first within the task's tolerance of its target (WhirlRecovery: time of success), mean "
        "over the episodes that got there; final stable speed = mean end speed of the episodes that ended "
        "without whirl or touchdown; max whirl = mean over episodes of the largest whirl amplitude "
        "(units of the clearance C); touchdowns include solver failures.",
    ]
    return "\n".join(lines) + "\n"


def plot_paths(paths: dict, nmap: NominalMap, path: Path, tasks: list[str]) -> None:
    """First-episode path of every agent in the (Lambda, D_W) plane over the nominal map's regions."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(tasks)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 4.6), squeeze=False)
    d = np.geomspace(nmap.damping.min(), nmap.damping.max(), 200)
    lc = np.array([nmap.critical_at(x) for x in d])
    lf = np.array([nmap.fold_at(x) for x in d])
    names = sorted({a for (_, a) in paths})
    colors = {a: plt.cm.tab10(i % 10) for i, a in enumerate(names)}
    styles = {a: ("-", "--", ":", "-.")[i % 4] for i, a in enumerate(names)}
    for ax, task in zip(axes[0], tasks):
        lams = [x for (t, _), r in paths.items() if t == task for x in r["lam"]]
        x0 = min([0.40, *lams]) - 0.01
        x1 = max([0.80, *lams]) + 0.01
        ax.fill_betweenx(
            d, x0, np.where(np.isfinite(lf), lf, lc), color="#cfe8cf", label="stable (equilibrium only)"
        )
        if np.isfinite(lf).any():
            ax.fill_betweenx(
                d,
                np.where(np.isfinite(lf), lf, lc),
                lc,
                color="#ffe9a8",
                label="bistable (equilibrium + whirl)",
            )
        ax.fill_betweenx(d, lc, x1, color="#f6c6c6", label="whirl only (above $\\Lambda_c$)")
        ax.plot(lc, d, "k-", lw=1)
        if np.isfinite(lf).any():
            ax.plot(lf, d, "k--", lw=1)
        for (t, a), r in paths.items():
            if t != task or not r["lam"]:
                continue
            lam, dw = np.asarray(r["lam"]), np.asarray(r["dw"])
            ax.plot(
                lam,
                dw,
                styles[a],
                color=colors[a],
                lw=1.3,
                alpha=0.9,
                label=f"{a} ({r['reason'] or 'time'})",
            )
            ax.plot(lam[0], dw[0], "o", color=colors[a], ms=3)
            ax.plot(lam[-1], dw[-1], "s" if r["success"] else "x", color=colors[a], ms=5)
        ax.set_yscale("log")
        ax.set_xlim(x0, x1)
        ax.set_ylim(d.min(), d.max())
        ax.set_xlabel(r"bearing number $\Lambda$")
        ax.set_ylabel(r"foil damping $D_W$")
        title = task.split("/")[-1]
        if "Randomized" in task:
            title += " (drawn bearing's $\\Lambda$; map of the nominal bearing)"
        if not np.isfinite(lf).any():
            title += "\n(fold of cycles not mapped for this foil: bistable band not drawn)"
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=5.5, loc="lower left")
    fig.suptitle(
        "Agent paths (first benchmark episode) over the nominal bearing's stability / hysteresis map "
        "(o start, s success, x other end)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.benchmark_agents", description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50, help="seeded episodes per (task, agent) (>= 1)")
    ap.add_argument("--quick", action="store_true", help="one episode per pair (for tests)")
    ap.add_argument("--tasks", default=None, help=f"comma-separated env ids (default: {','.join(TASKS)})")
    ap.add_argument("--agents", default=None, help="comma-separated agent names (default: all)")
    ap.add_argument("--out", default="results", help="output directory")
    ap.add_argument(
        "--policies",
        default=None,
        help="directory of learned policies (default: the committed ones, shipped as gfb_agents/policies)",
    )
    ap.add_argument(
        "--no-learned",
        action="store_true",
        help="run the scripted baselines only (without it, missing learned policies are an error)",
    )
    ap.add_argument("--n-jobs", type=int, default=1, help="parallel (task, agent) pairs, at most 2")
    ap.add_argument(
        "--env-kwargs",
        default=None,
        help='JSON {task id: {gymnasium.make kwargs}}, e.g. {"gfb_env/RunUp-v0": {}}',
    )
    ap.add_argument(
        "--merge",
        action="store_true",
        help="merge into the existing table in --out (replace same task/agent)",
    )
    a = ap.parse_args(argv)
    env_kwargs: dict[str, dict] = {}
    if a.env_kwargs:
        try:
            env_kwargs = json.loads(a.env_kwargs)
        except json.JSONDecodeError as exc:
            ap.error(f"--env-kwargs is not valid JSON: {exc}")
        if not isinstance(env_kwargs, dict) or not all(isinstance(v, dict) for v in env_kwargs.values()):
            ap.error("--env-kwargs must be a JSON object mapping task ids to objects")
    episodes = 1 if a.quick else a.episodes
    if episodes < 1:
        ap.error(f"--episodes must be >= 1, got {a.episodes}")
    if not 1 <= a.n_jobs <= 2:
        ap.error(f"--n-jobs must be 1 or 2 (two shared cores), got {a.n_jobs}")
    try:  # before any episode: an unwritable --out fails now, not after the benchmark
        check_output_dir(a.out, "--out")
    except ValueError as exc:
        ap.error(str(exc))
    tasks = a.tasks.split(",") if a.tasks else list(TASKS)
    for t in tasks:
        if t not in gym.registry:
            ap.error(f"unknown task {t!r}; known: {', '.join(TASKS)}")
    if a.no_learned and a.policies:
        ap.error("--no-learned and --policies exclude each other")
    learned: list[LearnedPolicy] = []
    if not a.no_learned:
        # before any episode: a benchmark that silently lacks its learned agents is wrong, not partial
        root = Path(a.policies) if a.policies else POLICIES_DIR
        # one line on stderr, no usage text: the arguments are fine, the data are missing
        try:
            learned = load_learned_policies(root)
        except FileNotFoundError as exc:
            print(
                f"{ap.prog}: error: {exc}; pass --no-learned to run the scripted baselines only",
                file=sys.stderr,
            )
            return 2
        if not learned:
            print(
                f"{ap.prog}: error: no learned policy (<name>/model.zip) in {root}; "
                "pass --no-learned to run the scripted baselines only",
                file=sys.stderr,
            )
            return 2
    t0 = time.perf_counter()
    rows, paths = run_benchmark(
        tasks,
        episodes,
        set(a.agents.split(",")) if a.agents else None,
        a.n_jobs,
        env_kwargs=env_kwargs,
        learned=learned,
    )
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.merge:
        old_rows, old_paths = _read_previous(out)
        new = {(r["task"], r["agent"]) for r in rows}
        rows = [r for r in old_rows if (r["task"], r["agent"]) not in new] + rows
        paths = {**{k: v for k, v in old_paths.items() if k not in new}, **paths}
        if any(int(r["episodes"]) != episodes for r in rows):
            print("warning: merged rows have different episode counts")
    order = {t: i for i, t in enumerate(TASKS)}
    rows.sort(key=lambda r: order.get(r["task"], 99))
    all_tasks = sorted({r["task"] for r in rows}, key=lambda t: order.get(t, 99))
    write_csv(rows, out / "benchmark_agents.csv")
    (out / "benchmark_agents.md").write_text(markdown_table(rows, episodes))
    (out / "benchmark_agents_paths.json").write_text(
        jsonio.dumps({f"{t}|{n}": v for (t, n), v in paths.items()})
    )
    env = gym.make(tasks[0], **env_kwargs.get(tasks[0], {}))
    plot_paths(paths, NominalMap.from_env(env), out / "benchmark_agents_paths.png", all_tasks)
    env.close()
    meta = {
        "episodes": episodes,
        "seeds": [SEED0, SEED0 + episodes - 1],
        "tasks": all_tasks,
        "env_kwargs": env_kwargs,
        "wall_time_s_last_run": round(time.perf_counter() - t0, 1),
    }
    (out / "benchmark_agents.json").write_text(jsonio.dumps(meta, indent=2))
    print((out / "benchmark_agents.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
