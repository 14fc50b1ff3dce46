"""Play one agent on one task over a seed range with the project's own episode runner
(``gfb_agents.learned.evaluate.run_episode``, as ``benchmark_agents.play_chunk`` does); append one JSON line
per episode to ``--out`` (resumable: seeds already in the file are skipped).

    python results/audit_v2_rules/play.py --task gfb_env/RunUpRandomized-v2 --agent margin_search_1x \
        --seeds 8000000-8000099 --out results/audit_v2_rules/episodes.jsonl

``--agent``: a ladder name (``gfb_agents.ladder.build``) or ``audit:<module>:<Class>`` for a rule of this
folder (built as ``Class(env)``).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import sys
import time
from pathlib import Path

from gfb_agents import ladder
from gfb_agents.learned.evaluate import run_episode
from gfb_env.envs import make_env

HERE = Path(__file__).resolve().parent


def build(name: str, env):
    if name.startswith("audit:"):
        _, mod, cls = name.split(":")
        spec = importlib.util.spec_from_file_location(mod, HERE / f"{mod}.py")
        m = importlib.util.module_from_spec(spec)
        sys.modules[mod] = m
        spec.loader.exec_module(m)
        return getattr(m, cls)(env)
    return ladder.build(name, env)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--task", required=True)
    ap.add_argument("--agent", required=True, action="append")
    ap.add_argument("--seeds", required=True, help="a-b inclusive")
    ap.add_argument("--out", required=True)
    ap.add_argument("--label", action="append", default=None, help="one per --agent (default: the agent)")
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    out = Path(a.out)
    done = set()
    if out.exists():
        for line in out.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done.add((r["task"], r["agent"], r["seed"]))
    env = make_env(a.task)
    labels = a.label if a.label is not None else a.agent
    if len(labels) != len(a.agent):
        raise SystemExit("give one --label per --agent")
    for agent, label in zip(a.agent, labels):
        pol = build(agent, env)
        for s in range(lo, hi + 1):
            if (a.task, label, s) in done:
                continue
            t0 = time.process_time()
            ep = run_episode(env, pol, s)
            rec = {"task": a.task, "agent": label, "seed": s, "cpu_s": time.process_time() - t0}
            rec.update(dataclasses.asdict(ep))
            with out.open("a") as f:
                f.write(json.dumps(rec, default=float) + "\n")
            print(label, s, round(ep.episode_return, 2), ep.termination_reason, flush=True)
    env.close()


if __name__ == "__main__":
    main()
