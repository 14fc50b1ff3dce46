"""The training record of the committed learned policies: one row per training run.

Reads ``policy.json`` of every ``agents/policies/<name>/seed<r>/`` (or ``<name>/``) folder written by
``python -m gfb_experiments.export_policy`` and prints a Markdown table (and, with ``--out``, a CSV) of the
algorithm, task, training seed, environment steps, wall time, training throughput (env steps/s on this
machine, validation included and excluded) and the validation result that selected the model.  The
numbers are those ``gfb_agents.learned.train`` measured while training (``run.json``); nothing is re-run::

    python -m gfb_experiments.training_table [--policies DIR] [--tasks ID,ID] \\
        [--out results/training_runs.csv]
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from gfb_agents.learned.evaluate import POLICIES_DIR
from gfb_env.scripting import OneLineParser

__all__ = ["training_rows", "markdown"]

COLUMNS = (
    "policy",
    "algo",
    "frame_stack",
    "env_id",
    "seed",
    "n_envs",
    "timesteps",
    "wall_time_min",
    "env_steps_per_s",
    "env_steps_per_s_excluding_validation",
    "best_validation_return",
    "best_validation_success",
    "best_validation_at",
)


def training_rows(policies: Path, tasks: tuple[str, ...] | None = None) -> list[dict]:
    """One row per ``policy.json`` under ``policies`` (sorted by policy name and seed)."""
    rows = []
    for path in sorted(Path(policies).glob("*/policy.json")) + sorted(
        Path(policies).glob("*/seed*/policy.json")
    ):
        p = json.loads(path.read_text())
        if tasks is not None and p.get("env_id") not in tasks:
            continue
        best = p.get("best_validation") or {}
        name = path.parent.name if not path.parent.name.startswith("seed") else path.parent.parent.name
        rows.append(
            {
                "policy": name,
                "algo": p.get("algo"),
                "frame_stack": p.get("frame_stack", 1),
                "env_id": p.get("env_id"),
                "seed": p.get("seed"),
                "n_envs": p.get("n_envs"),
                "timesteps": p.get("timesteps"),
                "wall_time_min": round(float(p["wall_time_s"]) / 60.0, 1) if "wall_time_s" in p else None,
                "env_steps_per_s": p.get("env_steps_per_s"),
                "env_steps_per_s_excluding_validation": p.get("env_steps_per_s_excluding_validation"),
                "best_validation_return": best.get("mean_return"),
                "best_validation_success": best.get("success_rate"),
                "best_validation_at": best.get("timesteps"),
            }
        )
    rows.sort(key=lambda r: (r["env_id"] or "", r["policy"], r["seed"] if r["seed"] is not None else -1))
    return rows


def _fmt(v: object) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.2f}" if abs(v) < 100 else f"{v:.0f}"
    return str(v)


def markdown(rows: list[dict]) -> str:
    head = "| " + " | ".join(COLUMNS) + " |"
    sep = "|" + "---|" * len(COLUMNS)
    return "\n".join([head, sep, *("| " + " | ".join(_fmt(r[c]) for c in COLUMNS) + " |" for r in rows)])


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(description=__doc__.splitlines()[0])
    p.add_argument("--policies", default=str(POLICIES_DIR), help="folder of exported policies")
    p.add_argument("--tasks", default="", help="comma-separated env ids (default: all)")
    p.add_argument("--out", default="", help="also write the rows to this CSV")
    a = p.parse_args(argv)
    if not Path(a.policies).is_dir():
        p.error(f"--policies: no such folder {a.policies}")
    tasks = tuple(t for t in a.tasks.split(",") if t) or None
    rows = training_rows(Path(a.policies), tasks)
    print(markdown(rows))
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        with open(a.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=COLUMNS)
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
