# analysis only (privileged used to place the ramp and to score): how does the monitor's sub-sync band
# see the crossing of the boundary at the optimum damping?
import math
import sys

import numpy as np

from gfb_env.envs import make_env

env = make_env("gfb_env/RunUpRandomized-v2")
u = env.unwrapped
L = u.observation_layout
ix, iy = L.index("x_subsync_rms"), L.index("y_subsync_rms")
ir = L.index("subsync_ratio")
for s in [int(a) for a in sys.argv[1:]]:
    obs, info = env.reset(seed=s)
    bp = u.best_stable_operating_point()
    g = u.hidden_parameters()["damping_gain"]
    dcmd = bp.commanded_damping
    a1 = float(np.clip(2 * math.log(dcmd / 0.1) / math.log(100) - 1, -1, 1))
    rpm_best = bp.speed_rpm
    maxacc = 30000.0
    dt = u.control_step_s
    rows = []
    for k in range(250):
        rpm = float(obs[6]) * 60000
        # ramp fast to 0.96 best, then creep at 0.1 %/step
        tgt = 0.96 * rpm_best if k < 60 else 0.96 * rpm_best * (1 + 0.001 * (k - 60))
        a0 = float(np.clip((tgt - rpm) / (maxacc * dt), -1, 1))
        obs, r, term, trunc, info = env.step(np.array([a0, a1], dtype=np.float32))
        pr = u.privileged_quantities()
        rows.append(
            (k, rpm / rpm_best, obs[ix], obs[iy], obs[ir], pr["whirl_amplitude"], pr.get("growth_rate"))
        )
        if term or trunc:
            break
    print(
        "seed",
        s,
        "g",
        round(g, 3),
        "best",
        round(rpm_best),
        "dcmd",
        round(dcmd, 3),
        "reason",
        info.get("termination_reason"),
    )
    for row in rows[55::5]:
        print("  k {}  n/nbest {:.4f}  sub x {:.5f} y {:.5f} ratio {:.3f}  trueA {:.5f}".format(*row[:6]))
