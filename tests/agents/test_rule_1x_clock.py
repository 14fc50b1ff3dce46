"""margin_search_1x under the v2 control clock (a step of 9.54 ms on every bearing): its probe runs where the
vibration monitor's record holds its minimum revolutions."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_env.envs import NOMINAL_BEARING

#: 60 tau of the nominal bearing (the v2 step); DEV seeds with C = 52.7 and 41.7 um
STEP_S = 60.0 * NOMINAL_BEARING.time_scale_s
SEEDS = (0, 3)


def test_margin_search_1x_probes_where_the_monitor_reads_a_1x_vector():
    """RunUpRandomized-v2 starts at 20 600 rpm, below the 22 010 rpm at which a 9.54 ms record holds the
    monitor's 3.5 revolutions: margin_search_1x runs its probe 3 % above that speed (RunUp-v2's start,
    27 000 rpm, is above it: its probe stays at the start speed)."""
    env = gym.make("gfb_env/RunUpRandomized-v2")
    pol = ladder.build("margin_search_1x", env)
    u = env.unwrapped
    floor = 1.03 * u.interface.monitor.min_revolutions * 60.0 / STEP_S
    assert pol.probe_floor_rpm == pytest.approx(floor, rel=1e-12) and u.start_speed_rpm < floor
    assert gym.make("gfb_env/RunUp-v2").unwrapped.start_speed_rpm > floor
    # held at that speed, the monitor's record is valid on the bearings of both seeds
    for seed in SEEDS:
        obs, _ = env.reset(seed=seed)
        valid = []
        for _ in range(12):
            rpm = float(obs[u.observation_layout.speed]) * u.speed_scale_rpm
            a0 = float(np.clip((floor - rpm) / (u.max_acceleration_rpm_per_s * STEP_S), -1.0, 1.0))
            obs = env.step(np.array([a0, 0.0], dtype=np.float32))[0]
            valid.append(float(obs[u.observation_layout.index("monitor_valid")]))
        assert valid[-1] == 1.0 and valid[0] == 0.0
