# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""Channels outside observation/reward/info that a policy can still reach: (a) the env's public
random generator (``env.np_random``, Gymnasium API, through every wrapper) predicts the next step's
base shocks; (b) the wall-clock time of ``env.step`` vs the integrator's work (v1 counted it GROUND_TRUTH)."""

import copy
import time

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401

env = gym.make("gfb_env/RunUp-v2", privileged_info=True)
u = env.unwrapped
hits = total = false_alarm = 0
for seed in range(7_001_000, 7_001_004):
    env.reset(seed=seed)
    for _ in range(250):
        rng = copy.deepcopy(env.np_random)  # public: gymnasium.Env.np_random (wrappers forward it)
        t0 = u.episode.bearing.seconds(u._integ.tau)  # noqa: SLF001 (the clock = step x nominal step: public)
        t0_pub = u.episode.step * u.nominal_bearing.seconds(u.control_interval)
        pred = u.config.shock_arrivals.draw(
            rng, t0_pub, t0_pub + u.nominal_bearing.seconds(u.control_interval)
        )
        obs, r, te, tr, info = env.step(np.array([0.0, 0.3], np.float32))
        actual = info["privileged"]["shocks_in_step"]
        if actual:
            total += 1
            hits += int(len(pred) == actual)
        elif pred:
            false_alarm += 1
        if te or tr:
            break
print(
    f"(a) RunUp-v2, 4 episodes: steps with a shock {total}, predicted from a copy of env.np_random {hits}, false alarms {false_alarm}"
)

# (b) timing
env.reset(seed=7_001_010)
dts, nint, amp = [], [], []
prev = 0
rng = np.random.default_rng(1)
for k in range(250):
    a = np.array([1.0 if k < 120 else 0.0, rng.uniform(-1, 1)], np.float32)
    t = time.perf_counter()
    obs, r, te, tr, info = env.step(a)
    dts.append(time.perf_counter() - t)
    pv = info["privileged"]
    nint.append(pv["integrator_steps"] - prev)
    prev = pv["integrator_steps"]
    amp.append(pv["whirl_amplitude"])
    if te or tr:
        break
dts, nint, amp = map(np.array, (dts, nint, amp))
print(
    f"(b) {len(dts)} steps: integrator steps per step {nint.min()}-{nint.max()}; corr(step wall time, integrator steps) "
    f"{np.corrcoef(dts, nint)[0, 1]:.2f}; Spearman-ish corr(rank time, rank true whirl amplitude) "
    f"{np.corrcoef(np.argsort(np.argsort(dts)), np.argsort(np.argsort(amp)))[0, 1]:.2f}"
)
