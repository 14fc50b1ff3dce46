"""Audit of what the v1 tasks' ``info`` hands out (issue 19 s.1, :mod:`gfb_env.envs.contract`).

Per v1 id, whole episodes (development seeds, the task's scripted expert; the audit reads the info, the
policy does not matter) are walked from reset to their end; every info key at every reset and step is
checked against the documented classification (SENSOR / PUBLIC / GROUND_TRUTH / PRIVILEGED: an
unclassified key is an error, exit code 1), and every number of every key is compared, as an exact
float, with every hidden draw of the episode (``env.unwrapped.hidden_parameters()``).  The report lists
per id the GROUND_TRUTH keys the v1 info still leaks (which the v2 ids of issue 19 must not have),
which of them equal a hidden parameter exactly, and the SENSOR / PUBLIC keys that do (a violation of
the contract: none expected, since every such key on v1 is classified GROUND_TRUTH).

The v2 ids (``gfb_env/*-v2``, :mod:`gfb_env.envs.interface_v2`) are audited the same way, with the raw
probe samples on (``raw_probe_samples=True``, so that their key is audited too): every key of their
info is listed with its class; the contract requires no GROUND_TRUTH key, no value of any key equal to
a hidden parameter, and the VERDICT keys only on the final step (exit code 1 otherwise).  Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.info_audit --out results/info_audit

Writes ``v1.md``, ``v1.json``, ``v2.md`` and ``v2.json`` into ``--out`` and prints the tables.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gfb_agents.seeds import DEV
from gfb_env.envs import RETIRED_V1_IDS, V2_ENV_IDS, make_env
from gfb_env.envs.contract import (
    INFO_CONTRACT,
    InfoClass,
    hidden_value_matches,
    leaked_ground_truth,
    unclassified_keys,
)
from gfb_env.scripting import OneLineParser, check_output_dir, int_range, write_json

__all__ = ["audit_task", "markdown", "main"]

V1_IDS = RETIRED_V1_IDS  # retired (issue 19): audited on the envs make_retired builds, for the record


def audit_task(
    env_id: str, seeds: Sequence[int], max_steps: int | None = None, **kwargs: Any
) -> dict[str, Any]:
    """Walk whole episodes of ``env_id`` (``max_steps``: cut them there; ``kwargs``: for ``gym.make``, or
    ``make_retired`` for a v1 id) for ``seeds``; the key by key classification, the hidden parameters each
    key equals (paths, over every reset and step), the keys nobody classified and the VERDICT keys seen
    before the final step."""
    env = make_env(env_id, **kwargs)
    u = env.unwrapped
    matches: dict[str, set[str]] = {}
    unclassified: set[str] = set()
    seen: set[str] = set()
    early_verdict: set[str] = set()
    table = INFO_CONTRACT[env_id]
    steps = 0
    for seed in seeds:
        _, info = env.reset(seed=seed)
        k, done = 0, False
        while True:
            seen |= set(info)
            unclassified |= set(unclassified_keys(env_id, info))
            if not done:
                early_verdict |= {x for x in info if x in table and table[x].cls is InfoClass.VERDICT}
            for key, paths in hidden_value_matches(info, u.hidden_parameters()).items():
                matches.setdefault(key, set()).update(paths)
            if done or (max_steps is not None and k >= max_steps):
                break
            _, _, term, trunc, info = env.step(u.scripted_action())
            k, done = k + 1, term or trunc
        steps += k
    env.close()
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
        "verdict_before_the_final_step": sorted(early_verdict),
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


def markdown_v2(report: dict[str, dict]) -> str:
    """One table per v2 id: every key of its info, its class and why."""
    lines = [
        "# The v2 info: every key a function of the sensors (issue 19 s.1)",
        "",
        "Made by `python -m gfb_experiments.info_audit` (`gfb_env/envs/contract.py` classifies every key;",
        "audited with `raw_probe_samples=True`).  SENSOR: a function of the measurements, the actions and",
        "the public configuration; PUBLIC: a task constant; VERDICT: the judge's verdict on the true plant,",
        "in the final step's info only (the episode is over); PRIVILEGED: the opt-in channel",
        "(`privileged_info=True`), not audited.  'equals' lists the hidden parameters",
        "(`env.unwrapped.hidden_parameters()` paths) a value of the key equalled exactly at some reset or",
        "step of the audited episodes (none allowed).",
        "",
    ]
    for env_id, r in report.items():
        leaks = r["ground_truth_leaks"]
        lines += [
            f"## {env_id}",
            "",
            f"{len(r['keys'])} info keys seen (seeds {r['seeds']}, {r['steps']} steps); "
            f"**{len(leaks)} GROUND_TRUTH**; keys equal to a hidden parameter: "
            f"{', '.join(r['equal_to_a_hidden_parameter']) or 'none'}; VERDICT keys before the final "
            f"step: {', '.join(r['verdict_before_the_final_step']) or 'none'}; "
            f"unclassified: {', '.join(r['unclassified']) or 'none'}.",
            "",
            "| key | class | why | equals |",
            "|---|---|---|---|",
        ]
        for key, e in r["keys"].items():
            eq = ", ".join(f"`{p}`" for p in e["equals_hidden"]) or "-"
            lines.append(f"| `{key}` | {e['class']} | {e['why']} | {eq} |")
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
    p.add_argument(
        "--out", default="results/info_audit", help="output folder (v1.md, v1.json, v2.md, v2.json)"
    )
    a = p.parse_args(argv)
    try:
        out = check_output_dir(a.out, "--out", ("v1.md", "v1.json", "v2.md", "v2.json"))
    except ValueError as exc:
        p.error(str(exc))
    seeds = DEV.first(a.seeds)
    report = {env_id: audit_task(env_id, seeds, a.max_steps) for env_id in V1_IDS}
    report_v2 = {
        env_id: audit_task(env_id, seeds, a.max_steps, raw_probe_samples=True) for env_id in V2_ENV_IDS
    }
    out.mkdir(parents=True, exist_ok=True)
    text, text_v2 = markdown(report), markdown_v2(report_v2)
    (out / "v1.md").write_text(text + "\n")
    write_json(out / "v1.json", report)
    (out / "v2.md").write_text(text_v2 + "\n")
    write_json(out / "v2.json", report_v2)
    print(text)
    print(text_v2)
    status = 0
    bad = {k: r["unclassified"] for k, r in {**report, **report_v2}.items() if r["unclassified"]}
    if bad:
        print(f"unclassified info keys: {bad}", file=sys.stderr)
        status = 1
    broken = {
        k: (r["ground_truth_leaks"], r["equal_to_a_hidden_parameter"], r["verdict_before_the_final_step"])
        for k, r in report_v2.items()
        if r["ground_truth_leaks"] or r["equal_to_a_hidden_parameter"] or r["verdict_before_the_final_step"]
    }
    if broken:
        print(f"v2 contract broken (ground truth, equal to hidden, early verdict): {broken}", file=sys.stderr)
        status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
