"""Measure the rules on training seeds, and the identification's accuracy (the numbers in docs/agents.md).

    python -m gfb_experiments.rules_check --env gfb_env/RunUp-v2 --rule margin_search --seeds 0 50 \
        [--safe-growth-rate X] [--rows] [--out FILE.json]
    python -m gfb_experiments.rules_check --identify --seeds 0 50 [--out results/rules_v1/identification.json]

Training / validation seeds only (< 10000: the benchmark's test seeds are refused).  A retired v1 id
(``--env gfb_env/RunUp-v1``) reproduces the record in ``results/rules_v1`` on the env
``gfb_env.envs.retired.make_retired`` builds (not a benchmark); ``--identify`` measures on the retired
RunUpRandomized-v1's draws, the record behind docs/agents.md's numbers.  The rules are built by
the ladder (:func:`gfb_agents.ladder.build`); the evaluation reads the env's hidden quantities after each
episode, for the measurement only (the final speed against the actual best stable speed, the drawn gain).
"""

from __future__ import annotations

import math

import numpy as np

from gfb_agents import ladder
from gfb_agents.estimation.identification import BearingIdentifier, identify_bearing, refine_bearing
from gfb_agents.rules.margin_search import MarginSearchAgent
from gfb_agents.rules.recovery import RecoveryAgent

__all__ = ["RULE_NAMES", "evaluate_rule", "summarise_rows", "identification_accuracy", "main"]

#: the rules (and the naive agent, for comparisons) this script measures
RULE_NAMES = ("naive", "map_informed_v1", "identify_map_v1", "margin_search", "recovery")


def evaluate_rule(env_id: str, name: str, seeds: range, **rule_kwargs) -> list[dict]:
    """Play ``name`` on ``env_id`` for ``seeds``; one row per episode: return, success, certificate,
    touchdown, the final speed relative to ``min(command, lambda_best of the actual plant)`` (read from
    the env after the episode, for the evaluation only) and the hidden gain."""
    from gfb_env.envs import make_env  # a current id, or a retired v1 id for the record

    env = make_env(env_id)
    u = env.unwrapped
    if rule_kwargs:  # a variant of a rule's settings (a tuning run): built by its class
        classes = {"margin_search": MarginSearchAgent, "recovery": RecoveryAgent}
        pol = classes[name](u, **rule_kwargs)
    else:
        pol = ladder.build(name, env)
    rows = []
    for seed in seeds:
        pol.reset()
        obs, info = env.reset(seed=seed)
        ret, k, done = 0.0, 0, False
        while not done:
            a, _ = pol.predict(obs, episode_start=(k == 0))
            obs, r, term, trunc, info = env.step(a)
            ret, k, done = ret + float(r), k + 1, term or trunc
        best = u.best_stable_operating_point().bearing_number
        cmd = float(info["speed_command_bearing_number"])
        rows.append(
            {
                "seed": seed,
                "return": ret,
                "success": bool(info["is_success"]),
                "certified": bool(info["certified"]),
                "touchdown": str(info["termination_reason"]) in ("touchdown", "solver_failure"),
                "final_over_best": float(info["bearing_number"]) / min(cmd, best),
                "gain": float(u.hidden_parameters()["damping_gain"]),
            }
        )
    env.close()
    return rows


def summarise_rows(rows: list[dict]) -> dict:
    r = np.array([x["return"] for x in rows])
    cert = np.array([x["certified"] for x in rows])
    return {
        "episodes": len(rows),
        "mean_return": float(r.mean()),
        "return_se": float(r.std(ddof=1) / math.sqrt(len(r))) if len(r) > 1 else 0.0,
        "success_rate": float(np.mean([x["success"] for x in rows])),
        "certified_rate": float(cert.mean()),
        "touchdowns": int(sum(x["touchdown"] for x in rows)),
        # the certified final speed relative to min(command, lambda_best_actual); 0 when not certified
        "certified_final_over_best": float(np.mean([x["final_over_best"] * x["certified"] for x in rows])),
    }


def identification_accuracy(seeds: range, ramp_steps: int = 28) -> dict:
    """Relative errors of :func:`identify_bearing` (6 observations at the start speed) and of
    :func:`refine_bearing` (plus ``ramp_steps`` observations of a full-rate run-up in 4-step averages)
    on RunUpRandomized-v1 draws, and of the published table's ``lambda_best`` at each estimate."""
    from gfb_env.envs import make_retired

    env = make_retired("gfb_env/RunUpRandomized-v1")  # the record of docs/agents.md
    u = env.unwrapped
    lay = u.observation_layout
    idf = BearingIdentifier(u)
    errs: dict[str, list] = {"start": [], "refined": []}
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        start = [obs]
        for _ in range(5):
            obs, *_ = env.step(np.zeros(2, dtype=np.float32))
            start.append(obs)
        est0 = identify_bearing(idf, start)
        ramp = []
        for _ in range(ramp_steps):
            obs, *_ = env.step(np.array([1.0, 0.0], dtype=np.float32))
            ramp.append(obs)
        pts = [(lay.speed_rpm(start[0]), np.mean(start, axis=0), len(start))]
        for j in range(0, ramp_steps, 4):
            grp = ramp[j : j + 4]
            pts.append((float(np.mean([lay.speed_rpm(o) for o in grp])), np.mean(grp, axis=0), len(grp)))
        est1 = refine_bearing(idf, pts, est0)
        drawn = u.hidden_parameters()["bearing"]  # the privileged channel (not the info)
        true = np.array([drawn["clearance_um"] * 1e-6, drawn["stiffness_factor"], drawn["load_n"]])
        lb_true = u.table(*true)["lambda_best"]
        for key, est in (("start", est0), ("refined", est1)):
            p = np.array([est.clearance_m, est.stiffness_factor, est.load_n])
            errs[key].append(np.r_[p / true - 1, u.table(*p)["lambda_best"] / lb_true - 1])
    env.close()
    out = {}
    for key, e in errs.items():
        e = np.array(e)
        out[key] = {
            name: {"rms": float(np.sqrt(np.mean(e[:, i] ** 2))), "max_abs": float(np.abs(e[:, i]).max())}
            for i, name in enumerate(("clearance", "stiffness_factor", "load", "lambda_best_table"))
        }
    return {"draws": len(seeds), **out}


def main(argv: list[str] | None = None) -> int:
    """``python -m gfb_experiments.rules_check --env gfb_env/RunUp-v2 --rule margin_search --seeds 0 50``:
    measure a rule on training seeds (< 10000; the benchmark's test seeds are refused)."""
    import argparse
    import json

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--env")
    ap.add_argument("--rule", choices=RULE_NAMES)
    ap.add_argument(
        "--identify", action="store_true", help="measure the identification on RunUpRandomized-v1 draws"
    )
    ap.add_argument("--seeds", nargs=2, type=int, default=(0, 50), metavar=("FIRST", "STOP"))
    ap.add_argument("--safe-growth-rate", type=float, default=None)
    ap.add_argument("--rows", action="store_true", help="print every episode")
    ap.add_argument("--out", default=None, help="write the summary and the rows to this JSON file")
    args = ap.parse_args(argv)
    if not 0 <= args.seeds[0] < args.seeds[1] <= 10_000:
        print("--seeds: training/validation seeds only, 0 <= FIRST < STOP <= 10000", flush=True)
        return 2
    if args.identify:
        res = identification_accuracy(range(*args.seeds))
        print(json.dumps(res))
        if args.out:
            from pathlib import Path

            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(json.dumps(res, indent=1) + "\n")
        return 0
    if not (args.env and args.rule):
        print("--env and --rule are required (or --identify)", flush=True)
        return 2
    kw = {} if args.safe_growth_rate is None else {"safe_growth_rate": args.safe_growth_rate}
    rows = evaluate_rule(args.env, args.rule, range(*args.seeds), **kw)
    if args.rows:
        for x in rows:
            print(json.dumps(x))
    summary = {"env": args.env, "rule": args.rule, "seeds": list(args.seeds), **kw, **summarise_rows(rows)}
    print(json.dumps(summary))
    if args.out:
        from pathlib import Path

        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"summary": summary, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
