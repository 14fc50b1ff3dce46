# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""A practical estimator of g from the float64 round-off of info['damping_indicated'] (no privileged
access): replay the public actuator for candidate gains on a log grid and take the candidate whose
replay matches the most steps exactly.  Also the per-step match fraction against the offset."""

import math
import sys

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401

env_id = sys.argv[1] if len(sys.argv) > 1 else "gfb_env/RunUp-v2"
seeds = (
    range(int(sys.argv[2]), int(sys.argv[2]) + int(sys.argv[3]))
    if len(sys.argv) > 3
    else range(7_000_400, 7_000_406)
)
n_steps = 40
env = gym.make(env_id)
u = env.unwrapped
act = u.damping_actuator
lo, hi = act.gain_range
grid = np.exp(np.linspace(math.log(lo), math.log(hi), 1500))
errs, prof, gs, ghs = [], {}, [], []
for s in seeds:
    rng = np.random.default_rng(s)
    obs, info = env.reset(seed=s)
    dt = u.nominal_bearing.seconds(u.control_interval)
    g = u.hidden_parameters()["damping_gain"]
    d = [info["damping_indicated"]]
    cmds = []
    for _ in range(n_steps):
        obs, r, te, tr, info = env.step(np.array([0.0, rng.uniform(-1, 1)], np.float32))
        cmds.append(u.damping_from_action(float(u.episode.last_action[1])))
        d.append(info["damping_indicated"])
        if te or tr:
            break

    def frac(gc):
        st = act.start(d[0] * gc, gc)
        m = 0
        for k, c in enumerate(cmds):
            st = act.step(st, c, dt)
            m += (st.foil_damping / gc) == d[k + 1]
        return m / len(cmds)

    sc = np.array([frac(x) for x in grid])
    ghat = grid[np.argmax(sc)]
    errs.append(math.log(ghat) - math.log(g))
    gs.append(math.log(g))
    ghs.append(math.log(ghat))
    for k in (1, 2, 3, 4, 6):
        prof.setdefault(k, []).append(
            np.mean([frac(g * math.exp(10.0**-k * sg)) for sg in (-1, 1, -0.5, 0.5)])
        )
    print(
        f"{s}: g={g:.4f} ghat={ghat:.4f} best frac {sc.max():.2f} median frac {np.median(sc):.2f} steps {len(cmds)}"
    )
e = np.array(errs)
print(
    f"{env_id}: ln g error of the argmax-match estimator: median |e| {np.median(np.abs(e)):.3f}, rms {np.sqrt(np.mean(e**2)):.3f}"
    f" (prior sd of ln g {math.log(hi / lo) / math.sqrt(12):.3f}), n={len(e)}"
)
gs, ghs = np.array(gs), np.array(ghs)
perm = [np.sqrt(np.mean((ghs - np.random.default_rng(i).permutation(gs)) ** 2)) for i in range(200)]
print(
    f"  baseline (ghat vs shuffled g): rms {np.mean(perm):.3f}; corr(ln g, ln ghat) {np.corrcoef(gs, ghs)[0, 1]:.2f}"
)
print(
    "per-step match fraction at |ln offset| 1e-k:", {k: round(float(np.mean(v)), 2) for k, v in prof.items()}
)
