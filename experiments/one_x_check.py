"""How well ``margin_search_1x``'s probe finds the damping gain (issue 19 s.3), on validation seeds.

Per episode: play ``margin_search_1x`` until its probe is done, then compare three posteriors over ``ln g``
(same prior, same grid of 161 points) with the episode's drawn ``g`` (read through the privileged
``hidden_parameters()`` *after* the probe, for the evaluation only; the rule never sees it):
``v1`` = margin_search's own unbalance probe on the v1 channels (its 0.6 temper), ``one_x`` = the
monitor's 1x vectors alone, ``fused`` = both (what the rule uses).  Prints the rms and median error of the
posterior mean and the rms z-score (error / posterior sd: 1 if calibrated).  Episodes whose rule skipped
the probe (the prior alone put the command below every plausible boundary) are counted apart.

Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.one_x_check --task gfb_env/RunUp-v2 --episodes 50
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_agents.seeds import split_seeds

TASKS = ("gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2")


def _stats(ll: np.ndarray, lg: np.ndarray, truth: float) -> tuple[float, float]:
    w = np.exp(ll - ll.max())
    w /= w.sum()
    mu = float(w @ lg)
    return mu - truth, math.sqrt(float(w @ (lg - mu) ** 2))


def check(task: str, episodes: int, offset: int = 0) -> dict:
    """The errors of the three posteriors over ``episodes`` validation seeds of ``task`` (module doc)."""
    env = gym.make(task)
    pol = ladder.build("margin_search_1x", env)
    rows, skipped = [], 0
    for seed in split_seeds("validation", offset + episodes)[offset:]:
        pol.reset()
        pol.last_probe = None
        obs, _ = env.reset(seed=seed)
        for _k in range(env.unwrapped.commanded.episode_steps):
            a, _ = pol.predict(obs)
            obs, _r, term, trunc, _ = env.step(a)
            if pol.last_probe is not None or term or trunc:
                break
        lp = pol.last_probe
        if lp is None:
            skipped += 1
            continue
        truth = math.log(env.unwrapped.hidden_parameters()["damping_gain"])  # evaluation only
        lg = np.log(lp["gains"])
        lls = {"v1": 0.6 * lp["ll_v1"], "one_x": lp["ll_1x"], "fused": 0.6 * lp["ll_v1"] + lp["ll_1x"]}
        rows.append(
            {"seed": seed, "ln_g": truth, "step": lp["step"]}
            | {k: _stats(v, lg, truth) for k, v in lls.items()}
        )
    out = {"task": task, "episodes": episodes, "probed": len(rows), "skipped": skipped, "rows": rows}
    for k in ("v1", "one_x", "fused"):
        e = np.array([r[k][0] for r in rows])
        s = np.array([r[k][1] for r in rows])
        out[k] = {
            "rms_error": float(np.sqrt(np.mean(e**2))) if len(e) else math.nan,
            "median_abs_error": float(np.median(np.abs(e))) if len(e) else math.nan,
            "mean_sd": float(s.mean()) if len(s) else math.nan,
            "rms_z": float(np.sqrt(np.mean((e / np.maximum(s, 1e-3)) ** 2))) if len(e) else math.nan,
        }
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m gfb_experiments.one_x_check", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--task", default=TASKS[0], choices=TASKS)
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--offset", type=int, default=0, help="skip the first validation seeds")
    ap.add_argument("--out", default=None, help="write the result as JSON here")
    a = ap.parse_args(argv)
    if a.episodes < 1 or a.offset < 0:
        ap.error(f"--episodes must be >= 1 and --offset >= 0, got {a.episodes} and {a.offset}")
    res = check(a.task, a.episodes, a.offset)
    print(f"{a.task}: {res['probed']} probed, {res['skipped']} skipped the probe (prior sd of ln g 0.665)")
    for k in ("v1", "one_x", "fused"):
        r = res[k]
        print(
            f"  {k:6s} rms err {r['rms_error']:.3f}  median |err| {r['median_abs_error']:.3f}  "
            f"mean sd {r['mean_sd']:.3f}  rms z {r['rms_z']:.2f}"
        )
    if a.out:
        with open(a.out, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
