"""Audit (point 4): per-step damping-command moves of one episode per policy on hidden seed 9_100_040:
fraction of steps at the slew limit and number of direction reversals (chattering)."""
import numpy as np
import gfb_env.envs  # noqa
from gfb_env.envs import make_env
from gfb_agents.ladder import build
from gfb_agents.learned.evaluate import LearnedPolicy

POL = "/work/main/agents/policies/"
for name in ("RunUpRandomized-v2_ppo_fs4/seed2", "RunUpRandomized-v2_student/seed0", "RunUpRandomized-v2_sac/seed0", "margin_aim_1x_05"):
    env = make_env("gfb_env/RunUpRandomized-v2")
    pol = build(name, env) if "/" not in name else LearnedPolicy(POL + name)
    pol.reset()
    obs, info = env.reset(seed=9_100_040)
    prev = float(obs[env.unwrapped.observation_layout.damping]); moves = []; start = True; done = False
    while not done:
        a, _ = pol.predict(obs, episode_start=np.array([start]), deterministic=True); start = False
        a1 = float(np.clip(np.asarray(a, dtype=np.float64).reshape(-1)[1], -1, 1))
        moves.append(a1 - prev); prev = a1
        obs, r, t, tr, info = env.step(a); done = t or tr
    m = np.array(moves); nz = m[np.abs(m) > 1e-6]
    rev = int(np.sum(np.sign(nz[1:]) != np.sign(nz[:-1])))
    print(f"{name}: steps {len(m)} mean|d| {np.abs(m).mean():.4f} max|d| {np.abs(m).max():.4f} "
          f"at limit (>=0.0269) {np.mean(np.abs(m) >= 0.0269):.0%} moving {np.mean(np.abs(m) > 1e-6):.0%} reversals {rev} net {m.sum():+.3f}")
