"""The audit's table from the per-episode JSON lines of ``play.py``, with the project's own statistics
(``gfb_experiments.benchmark_stats``, as ``benchmark_agents.reduce_results`` uses them, ``--normalise
consistent``): the zero of each aggregate is the better of ``naive`` and ``hold`` by that aggregate, the
one the oracle; IQM and mean with stratified-bootstrap CIs; the oracle's paired headroom over each rule;
and the paired difference of every audit rule over ``margin_search_1x`` (``paired_headroom(audit, ms1x)``).

    python results/audit_v2_rules/analyse.py results/audit_v2_rules/episodes_rr.jsonl \
        --task gfb_env/RunUpRandomized-v2
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from gfb_experiments.benchmark_stats import (
    interval_estimates,
    normalized_scores,
    paired_headroom,
    reference_plan,
    rescale_estimates,
)

REFS = ("naive", "hold")
ORACLE = "oracle_v1"
PUBLISHED_BEST = "margin_search_1x"


def load(path: Path, task: str) -> dict[str, dict[int, dict]]:
    out: dict[str, dict[int, dict]] = {}
    for line in path.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            if r["task"] == task:
                out.setdefault(r["agent"], {})[int(r["seed"])] = r
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="+")
    ap.add_argument("--task", required=True)
    ap.add_argument("--reps", type=int, default=10_000)
    ap.add_argument("--out", default=None, help="JSON summary path")
    a = ap.parse_args()
    eps: dict[str, dict[int, dict]] = {}
    for f in a.files:
        for k, v in load(Path(f), a.task).items():
            eps.setdefault(k, {}).update(v)
    seeds = sorted(set.intersection(*(set(v) for v in eps.values())))
    if not seeds:
        raise SystemExit("no seed common to every agent")
    ret = {k: np.array([v[s]["episode_return"] for s in seeds]) for k, v in eps.items()}
    plan = reference_plan({k: ret[k] for k in REFS}, "consistent")
    ro = ret[ORACLE]
    scores, table = {}, []
    for name in sorted(ret, key=lambda k: (k != "naive", k != "hold", k == ORACLE, k)):
        rstat = interval_estimates(ret[name], reps=a.reps)
        row = {"agent": name, "episodes": len(seeds)}
        sc = {}
        for agg, p in plan.items():
            s, info = normalized_scores(ret[name], ret[p["reference"]], ro, reference=p["statistic"])
            est = rescale_estimates(rstat, info["reference_zero"], info["reference_gap"])
            sc[agg] = s
            key = "iqm" if agg == "iqm" else "mean"
            row[f"norm_{key}"], row[f"norm_{key}_low"], row[f"norm_{key}_high"] = (
                est[key],
                est[f"{key}_low"],
                est[f"{key}_high"],
            )
        scores[name] = sc
        e = eps[name]
        row["success"] = float(np.mean([e[s]["success"] for s in seeds]))
        row["touchdowns"] = int(sum(bool(e[s]["touchdown"]) for s in seeds))
        row["mean_return"] = float(ret[name].mean())
        row["return_low"], row["return_high"] = rstat["mean_low"], rstat["mean_high"]
        row["cpu_s_per_episode"] = float(np.mean([e[s]["cpu_s"] for s in seeds]))
        table.append(row)
    heads = {}
    for name in ret:
        if name in REFS or name == ORACLE:
            continue
        h = paired_headroom(
            scores[ORACLE]["iqm"],
            scores[name]["iqm"],
            reps=a.reps,
            oracle_mean=scores[ORACLE]["mean"],
            rule_mean=scores[name]["mean"],
        )
        h["established"] = bool(h["iqm_low"] >= 0.2 and h["mean_low"] >= 0.2)
        heads[f"{ORACLE} - {name}"] = h
        if name != PUBLISHED_BEST and PUBLISHED_BEST in ret:
            d = paired_headroom(
                scores[name]["iqm"],
                scores[PUBLISHED_BEST]["iqm"],
                reps=a.reps,
                oracle_mean=scores[name]["mean"],
                rule_mean=scores[PUBLISHED_BEST]["mean"],
            )
            heads[f"{name} - {PUBLISHED_BEST}"] = d
    print(
        f"{a.task}: {len(seeds)} seeds {seeds[0]}..{seeds[-1]}; zero: IQM {plan['iqm']['reference']}, "
        f"mean {plan['mean']['reference']}"
    )
    print(
        "| agent | normalised IQM [95% CI] | normalised mean [95% CI] | success | touchdowns | mean return"
        " | cpu s/ep |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in table:
        print(
            f"| {r['agent']} | {r['norm_iqm']:.2f} [{r['norm_iqm_low']:.2f}, {r['norm_iqm_high']:.2f}] | "
            f"{r['norm_mean']:.2f} [{r['norm_mean_low']:.2f}, {r['norm_mean_high']:.2f}] | "
            f"{100 * r['success']:.0f}% | {r['touchdowns']}/{r['episodes']} | {r['mean_return']:.1f} | "
            f"{r['cpu_s_per_episode']:.1f} |"
        )
    print()
    print("| paired difference | IQM [95% CI] | mean [95% CI] | established (>= 0.2 both) |")
    print("|---|---|---|---|")
    for k, h in heads.items():
        est = h.get("established", "")
        print(
            f"| {k} | {h['iqm']:.3f} [{h['iqm_low']:.3f}, {h['iqm_high']:.3f}] | "
            f"{h['mean']:.3f} [{h['mean_low']:.3f}, {h['mean_high']:.3f}] | {est} |"
        )
    if a.out:
        per_seed = {k: {str(s): eps[k][s]["episode_return"] for s in seeds} for k in eps}
        Path(a.out).write_text(
            json.dumps(
                {
                    "task": a.task,
                    "seeds": seeds,
                    "plan": plan,
                    "table": table,
                    "paired": heads,
                    "returns": per_seed,
                },
                indent=1,
                default=lambda x: None if isinstance(x, float) and math.isnan(x) else x,
            )
        )


if __name__ == "__main__":
    main()
