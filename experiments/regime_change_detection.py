"""How fast and how reliably ``recovery_detect`` detects the friction-regime changes of the damping gain
(``docs/task_redesign.md``, "A change-detecting rule"), on DEV seeds (0-9999; never validation or test).

    python -m gfb_experiments.regime_change_detection --rate 1.0 [--seeds 100] [--seed-offset 0]
        [--factor-range 1.5,2.5] [--out results/task_redesign]

``--rate 0``: the plain task (no regime changes; every alarm is a false one).  The rule plays through the
benchmark's episode runner and sees only observations; after each episode the privileged schedule
(``hidden_parameters()["damping_regime_changes"]``) scores its alarms, never inside the rule.

The delay is counted as ``oracle_delay<N>``'s ``N``: a change within control step ``j`` is known to
``oracle_v1`` before action ``j + 1``; an alarm raised before action ``k`` has delay ``k - (j + 1)``.  A
change is *detected* by the first alarm after it and before the next change (or the episode's end);
*missed* otherwise (a change that leaves the plant stable at the operating point shows no growth to
detect); further alarms in the same regime are *repeats*; alarms before the first change are *false*
(on seeds without any change every alarm is one).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_agents.learned.evaluate import run_episode
from gfb_experiments.regime_change_headroom import checked_factors_and_seeds

TASK = "gfb_env/WhirlRecovery-v2"
AGENT = "recovery_detect"


def score_alarms(alarms: list[int], change_steps: list[int], steps: int) -> dict:
    """Match ``alarms`` (action indices) to ``change_steps`` (the control step each change fell in) in an
    episode of ``steps`` actions.  Change ``i``'s window is actions ``j_i + 1 .. j_{i+1}`` (the next
    change shows first at ``j_{i+1} + 1``; the last window ends with the episode); its first alarm there
    detects it (delay ``k - (j_i + 1)``; None: missed), later ones in the window are repeats; alarms
    before the first change's window are false."""
    delays: list[int | None] = []
    repeat: list[int] = []
    for i, j in enumerate(change_steps):
        end = change_steps[i + 1] if i + 1 < len(change_steps) else steps - 1
        hit = [k for k in alarms if j + 1 <= k <= end]
        delays.append(hit[0] - (j + 1) if hit else None)
        repeat += hit[1:]
    first = change_steps[0] + 1 if change_steps else steps
    false = [k for k in alarms if k < first]
    return {"delays": delays, "false_alarms": false, "repeat_alarms": repeat}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, required=True, help="regime changes per second (0: the plain task)")
    ap.add_argument("--factor-range", default="1.5,2.5")
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--seed-offset", type=int, default=0)
    ap.add_argument("--out", default="results/task_redesign")
    a = ap.parse_args(argv)
    lo, hi = checked_factors_and_seeds(ap, a)
    if a.rate < 0:
        ap.error(f"--rate must be >= 0, got {a.rate}")
    kw = {"damping_regime_changes": {"rate_per_s": a.rate, "factor_range": [lo, hi]}} if a.rate > 0 else {}
    env = gym.make(TASK, **kw)
    u = env.unwrapped
    step_s = u.control_clock.step_s(u.nominal_bearing)
    pol = ladder.build(AGENT, env)
    episodes = []
    for s in range(a.seed_offset, a.seed_offset + a.seeds):
        r = run_episode(env, pol, s)
        sched = u.hidden_parameters().get("damping_regime_changes") or {"changes": []}
        changes = [int(math.floor(c["time_s"] / step_s)) for c in sched["changes"]]
        alarms = pol.alarms(0)
        sc = score_alarms(alarms, changes, r.steps)
        episodes.append(
            {"seed": s, "steps": r.steps, "success": r.success, "changes": changes, "alarms": alarms, **sc}
        )
        print(f"seed {s}: changes {changes} alarms {alarms} delays {sc['delays']}", flush=True)
    delays = [d for e in episodes for d in e["delays"] if d is not None]
    n_changes = sum(len(e["changes"]) for e in episodes)
    quiet = [e for e in episodes if not e["changes"]]
    stats = {
        "seeds": a.seeds,
        "changes": n_changes,
        "detected": len(delays),
        "delay_median": float(np.median(delays)) if delays else None,
        "delay_p90": float(np.quantile(delays, 0.9)) if delays else None,
        "seeds_without_change": len(quiet),
        "false_alarms_per_episode_without_change": (
            float(np.mean([len(e["alarms"]) for e in quiet])) if quiet else None
        ),
        "false_alarms_per_episode": float(np.mean([len(e["false_alarms"]) for e in episodes])),
        "repeat_alarms_per_episode": float(np.mean([len(e["repeat_alarms"]) for e in episodes])),
    }
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    name = f"detection_{TASK.split('/')[-1]}_rate{a.rate:g}" + (f"_f{lo:g}-{hi:g}" if a.rate > 0 else "")
    path = out / f"{name}_seeds{a.seed_offset}-{a.seed_offset + a.seeds - 1}.json"
    path.write_text(
        json.dumps({"task": TASK, "env_kwargs": kw, "statistics": stats, "episodes": episodes}, indent=1)
    )
    print(json.dumps(stats, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
