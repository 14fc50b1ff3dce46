"""Audit (point 1): a committed learned policy's actions are a function of the observation sequence only.
Play one episode on a hidden seed while recording (obs, episode_start, action); then feed the recorded
observations to a FRESH LearnedPolicy with no env at all and compare the actions bit for bit.  Also scan
every observation entry against every hidden draw of the episode (float32 equality and rel. 1e-6)."""
import numpy as np
import gfb_env.envs  # noqa
from gfb_env.envs import make_env
from gfb_env.envs.privileged import flatten_numbers
from gfb_agents.learned.evaluate import LearnedPolicy

POL = "/work/main/agents/policies/"
for name, seed in (("RunUpRandomized-v2_ppo_fs4/seed2", 9_100_030), ("RunUpRandomized-v2_student/seed0", 9_100_031),
                   ("RunUpRandomized-v2_sac/seed0", 9_100_032)):
    env = make_env("gfb_env/RunUpRandomized-v2")
    pol = LearnedPolicy(POL + name)
    pol.reset()
    obs, info = env.reset(seed=seed)
    hidden = [(p, v) for p, v in flatten_numbers(env.unwrapped.hidden_parameters())
              if np.isfinite(v) and not float(v).is_integer() and p.split(".")[0] not in ("shocks",)]
    O, S, A, hits = [], [], [], set()
    start, done = True, False
    while not done:
        a, _ = pol.predict(obs, episode_start=np.array([start]), deterministic=True)
        O.append(np.array(obs)); S.append(start); A.append(np.array(a))
        for j, x in enumerate(np.asarray(obs, dtype=np.float64)):
            for p, v in hidden:
                if x != 0 and (np.float32(v) == np.float32(x) or abs(x - v) <= 1e-6 * abs(v)):
                    hits.add((j, p))
        start = False
        obs, r, term, trunc, info = env.step(a)
        done = term or trunc
    fresh = LearnedPolicy(POL + name)   # no env anywhere
    fresh.reset()
    B = [fresh.predict(o, episode_start=np.array([s]), deterministic=True)[0] for o, s in zip(O, S)]
    same = all(np.array_equal(x, y) for x, y in zip(A, B))
    print(f"{name} seed {seed}: {len(O)} steps, offline replay identical: {same}; "
          f"obs entries equal to a hidden draw (index, draw): {sorted(hits) or 'none'}")
