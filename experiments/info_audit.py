"""Audit of what the v1 tasks' ``info`` hands out (issue 19 s.1, :mod:`gfb_env.envs.contract`).

Per v1 id, whole episodes (development seeds, the task's scripted expert; the audit reads the info, the
policy does not matter) are walked from reset to their end; every info key at every reset and step is
checked against the documented classification (SENSOR / PUBLIC / GROUND_TRUTH / PRIVILEGED: an
unclassified key is an error, exit code 1), and every number of every key is compared, as an exact
float, with every hidden draw of the episode (``env.unwrapped.hidden_parameters()``).  The report lists
per id the GROUND_TRUTH keys the v1 info still leaks (which the v2 ids of issue 19 must not have),
which of them equal a hidden parameter exactly, and the SENSOR / PUBLIC keys that do (a violation of
the contract: none expected, since every such key on v1 is classified GROUND_TRUTH).  Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.info_audit --out results/info_audit

Writes ``v1.md`` (one Markdown table per id) and ``v1.json`` into ``--out`` and prints the tables.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import gymnasium as gym

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.seeds import DEV
from gfb_env.envs import ENV_IDS
from gfb_env.envs.contract import (
    INFO_CONTRACT,
    InfoClass,
    hidden_value_matches,
    leaked_ground_truth,
    unclassified_keys,
)
from gfb_env.scripting import OneLineParser, check_output_dir, int_range, write_json

__all__ = ["audit_task", "markdown", "main"]

V1_IDS = tuple(i for i in ENV_IDS if i.endswith("-v1"))


def audit_task(env_id: str, seeds: Sequence[int], max_steps: int | None = None) -> dict[str, Any]:
    """Walk whole episodes of ``env_id`` (``max_steps``: cut them there) for ``seeds``; the key by key
    classification, the hidden parameters each key equals (paths, over every reset and step) and the
    keys nobody classified."""
    env = gym.make(env_id)
    u = env.unwrapped
    matches: dict[str, set[str]] = {}
    unclassified: set[str] = set()
    seen: set[str] = set()
    steps = 0
    for seed in seeds:
        _, info = env.reset(seed=seed)
        k, done = 0, False
        while True:
            seen |= set(info)
            unclassified |= set(unclassified_keys(env_id, info))
            for key, paths in hidden_value_matches(info, u.hidden_parameters()).items():
                matches.setdefault(key, set()).update(paths)
            if done or (max_steps is not None and k >= max_steps):
                break
            _, _, term, trunc, info = env.step(u.scripted_action())
            k, done = k + 1, term or trunc
        steps += k
    env.close()
    table = INFO_CONTRACT[env_id]
    keys = {
        key: {
            "class": str(table[key].cls) if key in table else None,
            "why": table[key].why if key in table else None,
            "equals_hidden": sorted(matches.get(key, ())),
        }
        for key in sorted(seen)
    }
    violations = sorted(
        k for k in matches if k in table and table[k].cls in (InfoClass.SENSOR, InfoClass.PUBLIC)
    )
    return {
        "seeds": list(seeds),
        "steps": steps,
        "keys": keys,
        "ground_truth_leaks": list(leaked_ground_truth(env_id)),
        "equal_to_a_hidden_parameter": sorted(matches),
        "sensor_or_public_equal_to_a_hidden_parameter": violations,
        "unclassified": sorted(unclassified),
    }


def markdown(report: dict[str, dict]) -> str:
    """One table per id: every GROUND_TRUTH key of its info, why, and the hidden parameters it equals."""
    lines = [
        "# What the v1 info leaks (issue 19 s.1)",
        "",
        "Made by `python -m gfb_experiments.info_audit` (`gfb_env/envs/contract.py` classifies every key).",
        "GROUND_TRUTH: a hidden draw, the true state or a judge's true quantity; the v2 ids must have none.",
        "'equals' lists the hidden parameters (`env.unwrapped.hidden_parameters()` paths) that a value of",
        "the key equalled exactly, as a float, at some reset or step of the audited episodes.",
        "",
    ]
    for env_id, r in report.items():
        leaks = r["ground_truth_leaks"]
        lines += [
            f"## {env_id}",
            "",
            f"{len(leaks)} of {len(r['keys'])} info keys are GROUND_TRUTH "
            f"(seeds {r['seeds']}, {r['steps']} steps); "
            f"SENSOR/PUBLIC keys equal to a hidden parameter: "
            f"{', '.join(r['sensor_or_public_equal_to_a_hidden_parameter']) or 'none'}; "
            f"unclassified: {', '.join(r['unclassified']) or 'none'}.",
            "",
            "| key | why it is ground truth | equals |",
            "|---|---|---|",
        ]
        for key in leaks:
            e = r["keys"].get(key, {"why": "(not seen)", "equals_hidden": []})
            eq = ", ".join(f"`{p}`" for p in e["equals_hidden"]) or "-"
            lines.append(f"| `{key}` | {e['why']} | {eq} |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="gfb_experiments.info_audit", description=__doc__.splitlines()[0])
    p.add_argument(
        "--seeds", type=int_range("--seeds", 1, 100), default=3, help="episodes per id (DEV seeds)"
    )
    p.add_argument(
        "--max-steps",
        type=int_range("--max-steps", 1, 100_000),
        default=None,
        help="cut episodes (default: whole)",
    )
    p.add_argument("--out", default="results/info_audit", help="output folder (v1.md, v1.json)")
    a = p.parse_args(argv)
    try:
        out = check_output_dir(a.out, "--out", ("v1.md", "v1.json"))
    except ValueError as exc:
        p.error(str(exc))
    report = {env_id: audit_task(env_id, DEV.first(a.seeds), a.max_steps) for env_id in V1_IDS}
    out.mkdir(parents=True, exist_ok=True)
    text = markdown(report)
    (out / "v1.md").write_text(text + "\n")
    write_json(out / "v1.json", report)
    print(text)
    bad = {k: r["unclassified"] for k, r in report.items() if r["unclassified"]}
    if bad:
        print(f"unclassified info keys: {bad}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
