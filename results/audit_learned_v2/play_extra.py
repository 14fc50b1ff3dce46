"""Audit extras: (a) the oracle with the learned agents' damping slew limit (SlewLimitedPolicy 0.027), the
expert that --teacher oracle actually demonstrates through DampingSlewVecEnv; (b) replays of three TEST
seeds for reproducibility against results/benchmark_agents.json."""
import dataclasses, json, sys
from pathlib import Path
import numpy as np
import gfb_env.envs  # noqa
from gfb_env.envs import make_env
from gfb_agents.ladder import build
from gfb_agents.learned.evaluate import LearnedPolicy, run_episode
from gfb_agents.learned.slew import SlewLimitedPolicy

TASK = "gfb_env/RunUpRandomized-v2"
out = Path("/work/audit_learned/extra.jsonl")
mode = sys.argv[1]
with open(out, "a") as fh:
    if mode == "slewed_oracle":
        seeds = range(int(sys.argv[2]), int(sys.argv[2]) + int(sys.argv[3]))
        env = make_env(TASK)
        pol = SlewLimitedPolicy(build("oracle_v1", env), 0.027)
        for s in seeds:
            r = run_episode(env, pol, s)
            d = dataclasses.asdict(r) | {"agent": "oracle_v1+slew0.027", "mode": mode}
            fh.write(json.dumps(d) + "\n"); fh.flush()
            print(s, d["agent"], round(r.episode_return, 2), r.termination_reason, round(r.damping_command_change, 4), flush=True)
    elif mode == "replay_test":
        bench = json.load(open("/work/main/results/benchmark_agents.json"))["tasks"][TASK]["agents"]
        seeds = [3_000_000, 3_000_001, 3_000_002]
        for name, run in (("naive", 0), ("hold", 0), ("oracle_v1", 0), ("RunUpRandomized-v2_ppo_fs4", 0),
                          ("RunUpRandomized-v2_student", 0), ("margin_aim_1x_05", 0)):
            env = make_env(TASK)
            pol = build(name, env, run)
            for s in seeds:
                r = run_episode(env, pol, s)
                want = bench[name]["returns"][run][bench[name]["seeds"].index(s)]
                d = {"mode": mode, "agent": name, "run": run, "seed": s, "replayed": r.episode_return, "table": want,
                     "equal": r.episode_return == want}
                fh.write(json.dumps(d) + "\n"); fh.flush()
                print(d, flush=True)
