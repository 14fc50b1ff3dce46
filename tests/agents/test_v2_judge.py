"""The benchmark's judge on the v2 ids (issue 19): their info carries no ground truth, so
:func:`gfb_agents.learned.evaluate.run_episode` reads the true quantities from the privileged channel;
the result must not depend on whether the env was made with ``privileged_info=True``, and the policy never
receives info."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401
from gfb_agents.learned.evaluate import run_episode
from gfb_agents.policy import Policy


class _Ramp(Policy):
    """Motor limit at D_W = 1 for a few steps; records what it is given."""

    def __init__(self):
        self.seen: list[object] = []

    def reset(self) -> None:
        pass

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.seen.append(type(observation))
        return np.array([1.0, 0.0], dtype=np.float32), state


def test_v2_judge_reads_the_privileged_channel_and_gives_the_same_result():
    out = []
    for kw in ({}, {"privileged_info": True}):
        env = gym.make("gfb_env/RunUp-v2", **kw)
        pol = _Ramp()
        out.append(run_episode(env, pol, 2_000_003, record_path=True, max_steps=12))
        assert set(pol.seen) == {np.ndarray}  # observations only
        env.close()
    a, b = (dataclasses.asdict(r) for r in out)
    assert a == b
    # the path is the truth (Lambda ramps up from the start), not a sensor reading
    lam = np.array(a["path_bearing_number"])
    assert len(lam) == 13 and np.all(np.diff(lam) > 0) and np.all(np.isfinite(a["path_whirl"]))
