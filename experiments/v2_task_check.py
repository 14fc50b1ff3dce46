"""The v2 certificate on real episodes (issue 19 s.4): the oracle on each v1 id and its v2 id, same seeds.

The oracle (:class:`gfb_agents.oracles.commanded.CommandedOracle`) acts on the privileged channel and the
observed speed, which v1 and v2 share bit for bit (v2's first 16 entries are v1's, its random draws are v1's;
v2 runs on v1's plant, :data:`gfb_env.envs.PLAIN_PLANT`), so both versions run the same trajectory: every
difference of the verdict is the certificate's (v2 forgives a shock's ring-down in the scoring window,
:mod:`gfb_env.envs.certify_v2`). Per task: success and certified rates, the shock-in-window episodes, the v1
and v2 returns, the v2 episode cost.  Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.v2_task_check --seeds 0-49 --out results/v2_task_check

Writes ``summary.json`` into ``--out`` and prints one line per task.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.oracles.commanded import CommandedOracle
from gfb_env.envs import PLAIN_PLANT, RETIRED_V1_IDS, make_env
from gfb_env.scripting import OneLineParser, check_output_dir, write_json
from gfb_experiments.v1_task_check import parse_seeds

__all__ = ["run_pair", "main"]


def _episode(env_id: str, seed: int, **kw: Any) -> dict[str, Any]:
    env = make_env(env_id, **kw)  # a v1 id: retired, the env make_retired builds (the comparison's baseline)
    oracle = CommandedOracle(env)
    obs, info = env.reset(seed=seed)
    oracle.reset()
    oracle.observe_reset_info(info)
    ret, done, observations = 0.0, False, [obs]
    while not done:
        obs, r, term, trunc, info = env.step(oracle.predict(obs)[0])
        ret += float(r)
        observations.append(obs)
        done = term or trunc
    u = env.unwrapped
    ce = u.episode.command
    hold = u.hold_steps
    t_end, step_s = u.bearing.seconds(u._integ.tau), u.control_step_s  # noqa: SLF001
    in_window = any(e.time_s > t_end - hold * step_s for e in u.episode.shock_schedule)
    out = {
        "seed": seed,
        "return": ret,
        "termination_reason": str(info["termination_reason"]),
        "certification": ce.certificate.reason if ce.certificate is not None else None,
        "success": info["termination_reason"] == "success",
        "shock_in_window": bool(in_window),
        "last_obs_v1_entries": np.asarray(observations[-1][:16]).tolist(),
    }
    if "episode_cost" in info:
        out["episode_cost"] = float(info["episode_cost"])
    env.close()
    return out


def run_pair(v1_id: str, seeds: Sequence[int]) -> dict[str, Any]:
    """The oracle's episodes of ``v1_id`` and of its v2 id for ``seeds``; the summary."""
    v2_id = v1_id.replace("-v1", "-v2")
    # v2 on v1's plant (PLAIN_PLANT): the v2 ids' fast plant (issue 20) would move the last bits
    rows = {
        v: [_episode(i, s, **kw) for s in seeds]
        for v, i, kw in (("v1", v1_id, {}), ("v2", v2_id, PLAIN_PLANT))
    }
    same = all(
        a["last_obs_v1_entries"] == b["last_obs_v1_entries"]
        for a, b in zip(rows["v1"], rows["v2"], strict=True)
    )
    for v in rows:
        for r in rows[v]:
            del r["last_obs_v1_entries"]
    n = len(seeds)

    def rate(v: str, key: str) -> float:
        return sum(bool(r[key]) for r in rows[v]) / n

    forgiven = [
        a["seed"] for a, b in zip(rows["v1"], rows["v2"], strict=True) if (not a["success"]) and b["success"]
    ]
    return {
        "v1_id": v1_id,
        "v2_id": v2_id,
        "seeds": list(seeds),
        "same_trajectory": same,
        "success_v1": rate("v1", "success"),
        "success_v2": rate("v2", "success"),
        "shock_in_window": rate("v1", "shock_in_window"),
        "forgiven_seeds": forgiven,
        "mean_return_v1": float(np.mean([r["return"] for r in rows["v1"]])),
        "mean_return_v2": float(np.mean([r["return"] for r in rows["v2"]])),
        "mean_episode_cost_v2": float(np.mean([r["episode_cost"] for r in rows["v2"]])),
        "episodes": rows,
    }


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="gfb_experiments.v2_task_check", description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-9", help="training seeds, e.g. 0-49 (never the test seeds)")
    p.add_argument(
        "--tasks", default="all", help="comma-separated v1 ids' names (RunUp,...) or 'all' (default)"
    )
    p.add_argument("--out", default="results/v2_task_check", help="output folder (summary.json)")
    a = p.parse_args(argv)
    try:
        seeds = parse_seeds(a.seeds)
    except ValueError:
        p.error(f"--seeds: a list like 0-49 or 1,2,5, got {a.seeds!r}")
    if not seeds or min(seeds) < 0 or max(seeds) > 99:
        p.error("--seeds: only training seeds 0-99")
    names = {i.split("/")[1].split("-")[0]: i for i in RETIRED_V1_IDS}  # each task's v1 id, paired with v2
    wanted = list(names) if a.tasks == "all" else [t.strip() for t in a.tasks.split(",")]
    bad = [t for t in wanted if t not in names]
    if bad:
        p.error(f"--tasks: unknown {bad} (known: {', '.join(names)})")
    try:
        out = check_output_dir(a.out, "--out", ("summary.json",))
    except ValueError as exc:
        p.error(str(exc))
    summary = {names[t]: run_pair(names[t], seeds) for t in wanted}
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", summary)
    for s in summary.values():
        print(
            f"{s['v1_id']} vs {s['v2_id']} ({len(s['seeds'])} seeds, same trajectory: "
            f"{s['same_trajectory']}): "
            f"oracle success {s['success_v1']:.0%} -> {s['success_v2']:.0%}, shock in the window "
            f"{s['shock_in_window']:.0%}, forgiven seeds {s['forgiven_seeds']}, mean return "
            f"{s['mean_return_v1']:.1f} (v1) / {s['mean_return_v2']:.1f} (v2), v2 episode cost "
            f"{s['mean_episode_cost_v2']:.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
