# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""Outside audit of the v2 information contract (issue 19) on fresh seeds 7_000_000+.
Small: a few episodes per id.  Run: python audit/contract_v2_audit.py"""

import math
import sys

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401
from gfb_env.envs.monitor_reward import recompute_rewards
from gfb_env.envs.privileged import flatten_numbers

IDS = ["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2", "gfb_env/WhirlRecovery-v2"]
SEEDS = [7_000_000, 7_000_001]


def policy(kind, rng, k):
    if kind == "random":
        return rng.uniform(-1, 1, 2).astype(np.float32)
    if kind == "ramp":
        return np.array([1.0, 0.3], np.float32)
    return np.array([1.0, 1.0 if k % 2 else -1.0], np.float32)  # ramp + damping toggle


def run(env_id, seed, kind):
    env = gym.make(env_id)
    penv = gym.make(env_id, privileged_info=True)
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    pobs, pinfo = penv.reset(seed=seed)
    hid = env.unwrapped.hidden_parameters()
    O, R, I, P = [obs], [], [info], [pinfo]
    k, end = 0, None
    while True:
        a = policy(kind, rng, k)
        obs, r, term, trunc, info = env.step(a)
        pobs, pr, pt, ptr, pinfo = penv.step(a)
        assert np.array_equal(obs, pobs) and r == pr and term == pt and trunc == ptr, "privileged changes"
        O.append(obs)
        R.append(r)
        I.append(info)
        P.append(pinfo)
        k += 1
        if term or trunc:
            end = (k, term, trunc, info.get("termination_reason"))
            break
    cfg = env.unwrapped.public_reward_config
    rr = recompute_rewards(O, I[-1], cfg)
    return dict(
        env=env,
        hid=hid,
        O=np.array(O),
        R=np.array(R),
        I=I,
        P=P,
        end=end,
        rec_err=float(np.max(np.abs(rr - np.array(R)))),
    )


def hidden_values(hid):
    return [(p, v) for p, v in flatten_numbers(hid) if math.isfinite(v) and not float(v).is_integer()]


def near_matches(I, hid, rtol=1e-6):
    hv = hidden_values(hid)
    out = set()
    for info in I:
        for key, val in info.items():
            if key == "privileged":
                continue
            for path, v in flatten_numbers({key: val}):
                if not math.isfinite(v) or v == 0 or float(v).is_integer():
                    continue
                for hp, h in hv:
                    if abs(v - h) <= rtol * abs(h) or abs(abs(v) - abs(h)) <= rtol * abs(h):
                        out.add((path, hp, v, h))
    return out


if __name__ == "__main__":
    for env_id in IDS:
        for seed in SEEDS:
            for kind in ("random", "ramp", "toggle"):
                d = run(env_id, seed, kind)
                P, I, O = d["P"], d["I"], d["O"]
                shocks = len(d["hid"].get("shocks", []))
                td = any(i.get("touchdown") for i in I)
                keys = sorted({k for i in I for k in i})
                m = near_matches(I, d["hid"])
                # damping indication: info vs the privileged actual D_W / g
                g = d["hid"]["damping_gain"]
                print(
                    f"{env_id} seed {seed} {kind}: steps {d['end']}, shocks {shocks}, touchdown {td}, "
                    f"recompute max|dr| {d['rec_err']:.3g}, near-equal info~hidden {len(m)}, nkeys {len(keys)}"
                )
                for t in sorted(m)[:5]:
                    print("   match", t)
    sys.stdout.flush()
