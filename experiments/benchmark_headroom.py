"""The oracle's headroom over the best rule, with paired bootstrap CIs, from a benchmark's JSON (no episode
is re-played): ``benchmark_agents.json`` keeps every episode's normalised score per agent and seed.

    python -m gfb_experiments.benchmark_headroom [results/benchmark_agents.json] [--out DIR] [--reps N]

Writes ``benchmark_headroom.csv`` (``benchmark_headroom_<split>.csv`` for a split other than test; the
columns of :data:`gfb_experiments.benchmark_agents.HEADROOM_COLUMNS`, then ``split``, ``reference``,
``reference_mean`` and ``established``) beside the JSON or into ``--out``, exactly as a fresh ``python -m
gfb_experiments.benchmark_agents`` run writes it: the best rule is the rule with the highest normalised IQM
on the table's own (test) seeds (:func:`gfb_experiments.benchmark_agents.best_rule`: choosing on the seeds
the headroom is measured on biases it DOWN, conservative for a headroom claim), the headroom IQM(oracle) -
IQM(rule) on the IQM columns' scale and mean(oracle) - mean(rule) on the mean columns' scale with 95 % CIs
from one bootstrap over the evaluation seeds shared by both agents
(:func:`gfb_experiments.benchmark_stats.paired_headroom`).  A headroom claim needs both lower bounds >= 0.2
(issue 19; ``established``).

It also writes ``benchmark_learned_vs_rule.csv`` (issue 21) where a task has learned agents: per learned
agent, its normalised score minus the best rule's, IQM and mean, with the same paired bootstrap (a learned
agent's per-seed score is the mean over its training seeds first, :func:`paired_headroom`).  Every learned
agent gets its row (none is chosen on the test seeds); ``beats_rule`` is the issue's claim, both lower
bounds above 0.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from gfb_env.scripting import OneLineParser, check_output_dir
from gfb_experiments.benchmark_agents import (
    best_rule,
    headroom_csv_name,
    headroom_of,
    paired_difference,
    write_headroom_csv,
)
from gfb_experiments.benchmark_stats import DEFAULT_REPS

__all__ = ["LEARNED_COLUMNS", "headroom_from_table", "learned_vs_rule", "main"]

#: the columns of ``benchmark_learned_vs_rule.csv``
LEARNED_COLUMNS = [
    "task", "learned", "training_seeds", "best_rule", "test_seeds", "difference_iqm", "difference_ci_low",
    "difference_ci_high", "difference_mean", "difference_mean_ci_low", "difference_mean_ci_high",
    "beats_rule",
]  # fmt: skip


def headroom_from_table(table: dict, reps: int = DEFAULT_REPS) -> dict[str, dict]:
    """``{task: {"headroom": {...}}}`` from a ``benchmark_agents.json`` document (its ``rows`` and its
    per-task ``agents`` scores); a task without its oracle or a rule has no entry."""
    if not isinstance(table, dict) or "rows" not in table or "tasks" not in table:
        raise ValueError("table: not a benchmark_agents.json document (no 'rows' and 'tasks')")
    out: dict[str, dict] = {}
    for task, info in table["tasks"].items():
        agents = info.get("agents", {})
        oracle = info.get("oracle")
        best = best_rule(table["rows"], task, agents)
        if oracle not in agents or best is None or info.get("no_headroom"):
            continue
        out[task] = {"headroom": headroom_of(info, best, reps)}
    return out


def learned_vs_rule(table: dict, reps: int = DEFAULT_REPS) -> list[dict]:
    """One record per (task, learned agent) of a ``benchmark_agents.json`` document: the learned agent's
    normalised score minus the task's best rule's (:func:`best_rule`), paired over the evaluation seeds
    (:func:`paired_headroom` with the learned agent in the oracle's place); empty without learned agents."""
    if not isinstance(table, dict) or "rows" not in table or "tasks" not in table:
        raise ValueError("table: not a benchmark_agents.json document (no 'rows' and 'tasks')")
    out = []
    for task, info in table["tasks"].items():
        agents = info.get("agents", {})
        best = best_rule(table["rows"], task, agents)
        if best is None:
            continue
        learned = [r["agent"] for r in table["rows"] if r["task"] == task and r["kind"] == "learned"]
        for name in learned:
            if name not in agents:
                continue
            h = paired_difference(agents, name, best["agent"], reps)
            a = agents[name]
            out.append(
                {
                    "task": task,
                    "learned": name,
                    "training_seeds": len(a["normalized"]) if np.ndim(a["normalized"]) == 2 else 1,
                    "best_rule": best["agent"],
                    **h,
                    "beats_rule": bool(h["iqm_low"] > 0 and h["mean_low"] > 0),
                }
            )
    return out


def write_learned_csv(records: list[dict], path: Path) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(LEARNED_COLUMNS)
        for h in records:
            w.writerow(
                [h["task"], h["learned"], h["training_seeds"], h["best_rule"], h["seeds"]]
                + [repr(float(h[k])) for k in ("iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high")]
                + [h["beats_rule"]]
            )


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(
        prog="python -m gfb_experiments.benchmark_headroom", description=__doc__.splitlines()[0]
    )
    ap.add_argument("table", nargs="?", default="results/benchmark_agents.json", help="benchmark JSON")
    ap.add_argument("--out", default=None, help="folder of the CSV (default: the JSON's folder)")
    ap.add_argument(
        "--reps", type=int, default=DEFAULT_REPS, help="bootstrap resamples (default %(default)s)"
    )
    a = ap.parse_args(argv)
    path = Path(a.table)
    if not path.is_file():
        ap.error(f"table {a.table}: no such file")
    try:
        out = check_output_dir(a.out if a.out is not None else str(path.parent), "--out")
        table = json.loads(path.read_text())
        per_task = headroom_from_table(table, a.reps)
        learned = learned_vs_rule(table, a.reps)
    except (ValueError, json.JSONDecodeError) as exc:
        ap.error(" ".join(str(exc).split()))
    if not per_task:
        ap.error(f"table {a.table}: no task has both its oracle and a rule")
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / headroom_csv_name(table.get("split", "test"))
    write_headroom_csv(per_task, csv_path)
    for task, info in per_task.items():
        h = info["headroom"]
        claim = "holds" if h["established"] else "NOT established (lower bound < 0.2)"
        print(
            f"{task}: best rule {h['best_rule']}, n = {h['seeds']}: headroom IQM {h['iqm']:.3f} "
            f"[{h['iqm_low']:.3f}, {h['iqm_high']:.3f}], mean {h['mean']:.3f} [{h['mean_low']:.3f}, "
            f"{h['mean_high']:.3f}]; headroom >= 0.2: {claim}"
        )
    print(f"wrote {csv_path}")
    if learned:
        lpath = out / "benchmark_learned_vs_rule.csv"
        write_learned_csv(learned, lpath)
        for h in learned:
            print(
                f"{h['task']}: {h['learned']} ({h['training_seeds']} training seeds) minus {h['best_rule']}, "
                f"n = {h['seeds']}: IQM {h['iqm']:+.3f} [{h['iqm_low']:+.3f}, {h['iqm_high']:+.3f}], mean "
                f"{h['mean']:+.3f} [{h['mean_low']:+.3f}, {h['mean_high']:+.3f}]"
            )
        print(f"wrote {lpath}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
