"""Where a learned policy ends its episodes against the oracle's plan (validation seeds; a diagnosis, not
the benchmark).

    python -m gfb_experiments.diagnose_policy RUN_DIR [--env ID] [--episodes N] [--out FILE.csv]

Per episode of the first ``N`` VALIDATION seeds: the policy's return, success, touchdown and its step,
its final speed against the plant's best stable speed (``best_stable_operating_point``, read through the
privileged channel after the episode: the policy never sees it), its final actual foil damping ``D_W``
against the plant's ``D_opt`` and its last damping command (``D_W / g``) against the oracle's
``D_opt / g``, and the oracle's return on the same seed.  For docs/agents.md's reading of why a
policy falls short (e.g. the oracle-taught student: an overshoot, or a damping command far from
``D_opt / g``).  Never on test seeds.
"""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

from gfb_env.scripting import OneLineParser, check_output_dir

__all__ = ["diagnose", "summarise", "main"]

FIELDS = (
    "seed",
    "return",
    "success",
    "touchdown",
    "steps",
    "final_speed_rpm",
    "best_speed_rpm",
    "final_speed_rel",
    "final_foil_damping",
    "best_foil_damping",
    "final_damping_rel",
    "final_damping_command",
    "oracle_damping_command",
    "oracle_return",
    "oracle_steps",
    "damping_reversals",
    "oracle_damping_reversals",
)


def damping_reversals(path_damping, rel_tol: float = 1e-9) -> int:
    """How often the damping path turns round: sign changes between consecutive moves of ln D_W (moves
    smaller than ``rel_tol`` relative are holds and skipped).  On a task whose gain is constant over the
    episode (every v2 id by default) these are the reversals of the damping *command* (D_W = g x
    command): the dithering an actuator would have to follow (outside audit D1, 2026-12-02)."""
    d = np.diff(np.log(np.asarray(path_damping, dtype=float)))
    moves = np.sign(d[np.abs(d) > rel_tol])
    return int(np.count_nonzero(moves[1:] != moves[:-1]))


def diagnose(run_dir: str | Path, env_id: str | None = None, episodes: int = 10) -> list[dict]:
    """The rows of the module docstring for the policy of ``run_dir`` (its ``best/`` as the benchmark
    loads it)."""
    import gymnasium as gym

    import gfb_env.envs  # noqa: F401  (registers the ids)
    from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
    from gfb_agents.oracles.commanded import CommandedOracle
    from gfb_agents.seeds import VALIDATION

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    pol = LearnedPolicy(run_dir)
    env_id = env_id or pol.env_id
    if env_id is None:
        raise ValueError(f"--env: {run_dir} does not name its task; pass --env ID")
    rows = []
    for seed in VALIDATION.first(episodes):
        env = gym.make(env_id)
        r = run_episode(env, pol, seed, record_path=True)
        best = env.unwrapped.best_stable_operating_point()  # privileged, after the episode
        g = float(env.unwrapped.hidden_parameters()["damping_gain"])
        # the path's damping is the judge's true D_W (actual = g x command), not the command
        d_end = float(r.path_damping[-1]) if r.path_damping else float("nan")
        oenv = gym.make(env_id)
        ro = run_episode(oenv, CommandedOracle(oenv), seed, record_path=True)
        rows.append(
            {
                "seed": seed,
                "return": round(r.episode_return, 3),
                "success": r.success,
                "touchdown": r.touchdown,
                "steps": r.steps,
                "final_speed_rpm": round(r.final_speed_rpm, 1),
                "best_speed_rpm": round(best.speed_rpm, 1),
                "final_speed_rel": round(r.final_speed_rpm / best.speed_rpm - 1.0, 4),
                "final_foil_damping": round(d_end, 4),
                "best_foil_damping": round(best.foil_damping, 4),
                "final_damping_rel": round(math.log(d_end / best.foil_damping), 4),
                "final_damping_command": round(d_end / g, 4),
                "oracle_damping_command": round(best.commanded_damping, 4),
                "oracle_return": round(ro.episode_return, 3),
                "oracle_steps": ro.steps,
                "damping_reversals": damping_reversals(r.path_damping),
                "oracle_damping_reversals": damping_reversals(ro.path_damping),
            }
        )
        env.close()
        oenv.close()
    return rows


def summarise(rows: list[dict]) -> dict:
    """What docs/agents.md quotes of a diagnosis: successes and touchdowns, the median (and range) of the
    final speed's relative distance below the best over the episodes that did not touch down, the
    correlation of the logarithms of the policy's final command and the oracle's, and the mean and
    median of |ln(D_W / D_opt)|, and the damping path's reversals per 100 control steps (the policy's and
    the oracle's on the same seeds)."""
    cmd = np.log([r["final_damping_command"] for r in rows])
    ora = np.log([r["oracle_damping_command"] for r in rows])
    rel = np.sort([r["final_speed_rel"] for r in rows if not r["touchdown"]])
    dr = np.abs([r["final_damping_rel"] for r in rows])
    return {
        "episodes": len(rows),
        "successes": int(sum(bool(r["success"]) for r in rows)),
        "touchdowns": int(sum(bool(r["touchdown"]) for r in rows)),
        "final_speed_rel_median": float(np.median(rel)) if rel.size else float("nan"),
        "final_speed_rel_range": [float(rel[0]), float(rel[-1])] if rel.size else [],
        "command_log_correlation": float(np.corrcoef(cmd, ora)[0, 1]) if len(rows) > 1 else float("nan"),
        "abs_log_damping_error_mean": float(dr.mean()),
        "abs_log_damping_error_median": float(np.median(dr)),
        "mean_return": float(np.mean([r["return"] for r in rows])),
        "damping_reversals_per_100_steps": _per_100(rows, "damping_reversals", "steps"),
        "oracle_damping_reversals_per_100_steps": _per_100(rows, "oracle_damping_reversals", "oracle_steps"),
    }


def _per_100(rows: list[dict], key: str, steps: str) -> float:
    if any(key not in r for r in rows):
        return float("nan")
    n = sum(int(r[steps]) for r in rows)
    return 100.0 * sum(int(r[key]) for r in rows) / n if n else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.diagnose_policy", description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", help="a training run (seed<r> folder) or an exported policy folder")
    ap.add_argument("--env", default=None, help="task id (default: the policy's)")
    ap.add_argument("--episodes", type=int, default=10, help="first N VALIDATION seeds (default 10)")
    ap.add_argument("--out", default=None, help="CSV file to write (default: stdout only)")
    a = ap.parse_args(argv)
    if a.episodes < 1:
        ap.error(f"--episodes must be a positive integer, got {a.episodes}")
    if not Path(a.run_dir).is_dir():
        ap.error(f"run_dir: no such folder: {a.run_dir}")
    if a.out is not None:
        try:
            check_output_dir(str(Path(a.out).parent), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    try:
        rows = diagnose(a.run_dir, a.env, a.episodes)
    except (ValueError, FileNotFoundError) as exc:
        ap.error(str(exc))
    w = csv.DictWriter(sys.stdout, fieldnames=FIELDS)
    w.writeheader()
    w.writerows(rows)
    print(json.dumps(summarise(rows)), file=sys.stderr)  # the numbers the docs quote
    if a.out is not None:
        with open(a.out, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=FIELDS)
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
