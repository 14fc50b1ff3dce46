"""Audit: what the committed v2 learned policies take as input (model spaces, statistics, meta)."""
import json, pickle, zipfile
from pathlib import Path
import numpy as np
import gfb_env.envs  # noqa
from gfb_env.envs import make_env
from gfb_agents.learned.evaluate import LearnedPolicy, run_dirs

env = make_env("gfb_env/RunUpRandomized-v2")
n_obs = env.observation_space.shape[0]
print("env observation dim", n_obs, "names", getattr(env.unwrapped.observation_layout, "extra_names", None))
root = Path("/work/main/agents/policies")
for agent in ("RunUpRandomized-v2_ppo_fs4", "RunUpRandomized-v2_student", "RunUpRandomized-v2_sac"):
    for d in run_dirs(root / agent):
        meta = json.loads((d / "policy.json").read_text())
        pol = LearnedPolicy(d)
        m = pol.model
        if hasattr(m, "observation_space"):
            space = m.observation_space
            desc = f"SB3 {type(m).__name__} policy={type(m.policy).__name__} obs_space={space} env={getattr(m, 'env', None)}"
        else:
            desc = f"DeployedActor obs_dim={m.obs_dim} = {m.obs_dim / n_obs:g} x n_obs; params={[k for k, _ in m.named_parameters()]}"
        with open(d / "vecnormalize.pkl", "rb") as fh:
            vn = pickle.load(fh)
        rms = vn.obs_rms
        keys = list(rms.keys()) if isinstance(rms, dict) else ["<Box>"]
        print(f"{agent}/{d.name}: algo={meta['algo']} fs={pol.frame_stack} slew={pol.damping_slew} "
              f"reserve={pol.damping_slew_reserve} obs_mean_dim={pol.obs_mean.shape} vn_keys={keys} | {desc}")
        print("   teacher:", meta.get("teacher"), "teacher_kind:", meta.get("teacher_kind"), "val seeds:",
              min(meta["validation_seeds"]), max(meta["validation_seeds"]), len(meta["validation_seeds"]))
