# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""How finely does the float64 round-off of info['damping_indicated'] = D_W(g)/g pin g?  For offsets
|ln g_c - ln g| = 10^-k, the fraction of candidates whose replay matches every step of 30 exactly."""

import math
import sys

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401

env_id = sys.argv[1] if len(sys.argv) > 1 else "gfb_env/RunUp-v2"
env = gym.make(env_id)
u = env.unwrapped
act = u.damping_actuator
for s in (7_000_300, 7_000_301):
    rng = np.random.default_rng(s)
    obs, info = env.reset(seed=s)
    dt = u.episode.bearing.seconds(u.control_interval)  # replay with the drawn step (Randomized: from (a))
    g = u.hidden_parameters()["damping_gain"]
    d = [info["damping_indicated"]]
    cmds = []
    for _ in range(30):
        obs, r, te, tr, info = env.step(np.array([0.0, rng.uniform(-1, 1)], np.float32))
        cmds.append(u.damping_from_action(float(u.episode.last_action[1])))
        d.append(info["damping_indicated"])
        if te or tr:
            break

    def match(gc):
        st = act.start(d[0] * gc, gc)
        m = 0
        for k, c in enumerate(cmds):
            st = act.step(st, c, dt)
            m += (st.foil_damping / gc) == d[k + 1]
        return m == len(cmds)

    out = []
    for k in range(1, 16):
        offs = 10.0**-k * rng.choice([-1, 1], 40) * rng.uniform(0.5, 1.0, 40)
        out.append(f"1e-{k}:{np.mean([match(g * math.exp(o)) for o in offs]):.2f}")
    print(env_id, s, f"g={g:.5f} steps {len(cmds)}", " ".join(out))
