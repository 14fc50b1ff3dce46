"""How well ``recovery_reset`` knows WhirlRecovery's damping gain after the reset observation and after
the first control step (the numbers in docs/agents.md).

    python -m gfb_experiments.whirl_start_check [--episodes 200] [--first-step 40] [--out FILE.json]

Validation seeds only (``gfb_agents.seeds.VALIDATION``, the first ``--episodes``; the test seeds are the
benchmark's).  The rule plays the first two decisions of each episode (the dip's first action, then the
first step's update); the truth is read from the env's privileged channel after them, for the
measurement only.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np

from gfb_agents.seeds import VALIDATION

__all__ = ["posterior_errors", "main"]


def _moments(post) -> tuple[float, float]:
    w, lg = post.weights, np.log(post.gains)
    mu = float(w @ lg)
    return mu, float(math.sqrt(max(float(w @ (lg - mu) ** 2), 0.0)))


def posterior_errors(n_reset: int, n_step: int, env_id: str = "gfb_env/WhirlRecovery-v2") -> dict:
    """Error of the posterior mean of ln g (and its sd) after the reset on the first ``n_reset``
    validation seeds, and after the first step on the first ``n_step`` of them; the cost of each."""
    from gfb_agents import ladder
    from gfb_env.envs import make_env  # a current id, or the retired WhirlRecovery-v1 for the record

    env = make_env(env_id)
    u = env.unwrapped
    t0 = time.perf_counter()
    pol = ladder.build("recovery_reset", env)
    build_s = time.perf_counter() - t0
    rows = {"reset": [], "first_step": []}
    cost = {"reset": [], "first_step": []}
    for i, seed in enumerate(VALIDATION.first(max(n_reset, n_step))):
        pol.reset()
        obs, _ = env.reset(seed=seed)
        truth = math.log(u.hidden_parameters()["damping_gain"])
        t0 = time.perf_counter()
        pol.reset_posterior(obs)
        cost["reset"].append(time.perf_counter() - t0)
        if i < n_step:
            a, _ = pol.predict(obs, episode_start=True)
            post = pol._mem[0].post
            mu0, sd0 = _moments(post)
            obs, *_ = env.step(a)
            t0 = time.perf_counter()
            pol.predict(obs)
            cost["first_step"].append(time.perf_counter() - t0)
            mu1, sd1 = _moments(post)
            rows["first_step"].append((mu1 - truth, sd1))
        else:
            gains, ll = pol.reset_posterior(obs)
            w = np.exp(ll - ll.max())
            w /= w.sum()
            lg = np.log(gains)
            mu0 = float(w @ lg)
            sd0 = float(math.sqrt(w @ (lg - mu0) ** 2))
        if i < n_reset:
            rows["reset"].append((mu0 - truth, sd0))
    env.close()
    lo, hi = u.damping_actuator.gain_range
    out = {"env": env_id, "split": "validation", "prior_sd": math.log(hi / lo) / math.sqrt(12.0)}
    out["build_s"] = build_s
    for key, r in rows.items():
        if not r:
            continue
        e, s = np.array(r).T
        out[key] = {
            "episodes": len(e),
            "rms_error": float(np.sqrt(np.mean(e**2))),
            "median_abs_error": float(np.median(np.abs(e))),
            "mean_sd": float(np.mean(s)),
            "within_2sd": float(np.mean(np.abs(e) <= 2 * np.maximum(s, 0.027))),  # the grid's spacing
            "seconds_per_episode": float(np.median(cost[key])),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    from pathlib import Path

    from gfb_env.scripting import OneLineParser, check_output_dir

    ap = OneLineParser(
        prog="python -m gfb_experiments.whirl_start_check", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--episodes", type=int, default=200, help="validation seeds for the reset's error")
    ap.add_argument("--first-step", type=int, default=40, help="of them, for the first step's error")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    a = ap.parse_args(argv)
    if not (1 <= a.episodes <= len(VALIDATION)) or not (0 <= a.first_step <= a.episodes):
        ap.error("--episodes must be >= 1 and --first-step in [0, --episodes]")
    if a.out:  # before any episode: an unwritable --out fails now
        try:
            check_output_dir(str(Path(a.out).parent), "--out", files=(Path(a.out).name,))
        except ValueError as exc:
            ap.error(str(exc))
    res = posterior_errors(a.episodes, a.first_step)
    print(json.dumps(res))
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
