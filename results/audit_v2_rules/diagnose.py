import json
import sys

import numpy as np

from gfb_agents import ladder
from gfb_agents.learned.evaluate import run_episode
from gfb_env.envs import make_env

env = make_env("gfb_env/RunUpRandomized-v2")
pol = ladder.build("margin_search_1x", env)
u = env.unwrapped
for s in range(int(sys.argv[1]), int(sys.argv[2])):
    ep = run_episode(env, pol, s)
    m = pol._mem[0]
    bp = u.best_stable_operating_point()
    hp = u.hidden_parameters()
    post = m.post
    w = post.weights
    lg = np.log(post.gains)
    gm = float(np.exp(w @ lg))
    gsd = float(np.sqrt(w @ (lg - w @ lg) ** 2))
    lc_est = float(w @ m.table.critical(post.gains * m.d_cmd, 0.0))
    rpm_c_est = m.bearing.speed_rpm_at(lc_est)
    est = m.estimate
    print(
        json.dumps(
            dict(
                seed=s,
                ret=round(ep.episode_return, 1),
                reason=ep.termination_reason,
                final_rpm=round(ep.final_speed_rpm),
                best_rpm=round(bp.speed_rpm),
                cmd=round(u.speed_command.speed_rpm) if hasattr(u, "speed_command") else None,
                rule_rpm_c=round(rpm_c_est),
                rule_setpoint=round(m.setpoint),
                g=round(hp["damping_gain"], 3),
                g_est=round(gm, 3),
                g_sd=round(gsd, 3),
                C=round(hp["bearing"]["clearance_um"], 2),
                C_est=round(est.clearance_m * 1e6, 2),
                fK=round(hp["bearing"]["stiffness_factor"], 3),
                fK_est=round(est.stiffness_factor, 3),
                FL=round(hp["bearing"]["load_n"], 2),
                FL_est=round(est.load_n, 2),
                whirls=m.whirl_count,
            )
        ),
        flush=True,
    )
