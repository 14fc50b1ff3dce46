"""Audit: play naive, hold, oracle_v1, margin_aim_1x_05 and committed learned policies on hidden seeds
(9_100_000..) of gfb_env/RunUpRandomized-v2 with the project's own runner (run_episode), one env per agent
as benchmark_agents.play_chunk does.  Writes one JSON line per (seed, agent) to episodes.jsonl."""
import dataclasses, json, sys, time
from pathlib import Path

import gfb_env.envs  # noqa: F401
from gfb_env.envs import make_env
from gfb_agents.ladder import build
from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
from gfb_agents.seeds import SPLITS, TRAIN, DEV, LEGACY_V0

TASK = "gfb_env/RunUpRandomized-v2"
POL = Path("/work/main/agents/policies")
start, n = int(sys.argv[1]), int(sys.argv[2])
agents = sys.argv[3].split(",")
out = Path(sys.argv[4])
seeds = list(range(start, start + n))
for s in seeds:
    assert all(s not in r for r in (*SPLITS.values(), TRAIN, DEV, LEGACY_V0)), s

def make(name):
    env = make_env(TASK)
    if "/" in name:  # a committed learned policy folder, e.g. RunUpRandomized-v2_ppo_fs4/seed2
        pol = LearnedPolicy(POL / name, name=name)
    else:
        pol = build(name, env)
    return env, pol

built = {a: make(a) for a in agents}
with open(out, "a") as fh:
    for s in seeds:
        for a in agents:
            env, pol = built[a]
            t0 = time.perf_counter()
            r = run_episode(env, pol, s)
            d = dataclasses.asdict(r)
            d.update(agent=a, wall_s=time.perf_counter() - t0)
            fh.write(json.dumps(d) + "\n"); fh.flush()
            print(f"{s} {a:40s} R={r.episode_return:8.2f} {r.termination_reason} dD={r.damping_command_change:.4f} {d['wall_s']:.1f}s", flush=True)
