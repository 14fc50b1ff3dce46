"""The v2 interface's compiled probe arithmetic (``MonitorInterface._read_noisy_probes``, issue 20 s.3)
against its numpy path (``_read_probes_numpy``): the same draw, the same observation, probe readings, errors
and monitor samples over the first steps of RunUp-v2 and WhirlRecovery-v2."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401
from gfb_env.envs.interface_v2 import MonitorInterface


def run(task: str, steps: int) -> list:
    env = gym.make(task, raw_probe_samples=True)
    obs, _ = env.reset(seed=4)
    u = env.unwrapped
    rng = np.random.default_rng(4)
    rows = [(obs, None, None, None)]
    for _ in range(steps):
        obs, _r, term, trunc, info = env.step(rng.uniform(-1, 1, 2))
        err = u.episode.probe_errors
        rows.append(
            (
                obs,
                info["probe_samples"],
                (info["probe_x_um"], info["probe_y_um"]),
                np.concatenate([err.position_um, err.velocity_um_per_s, err.extent_um, err.noise_um]),
            )
        )
        if term or trunc:
            break
    return rows


@pytest.mark.parametrize("task", ["gfb_env/RunUp-v2", "gfb_env/WhirlRecovery-v2"])
def test_compiled_probe_arithmetic_is_the_numpy_path(task, monkeypatch):
    got = run(task, 6)
    monkeypatch.setattr(MonitorInterface, "_read_noisy_probes", MonitorInterface._read_probes_numpy)
    want = run(task, 6)
    assert len(got) == len(want) > 2
    for (o1, s1, p1, e1), (o2, s2, p2, e2) in zip(got, want, strict=True):
        np.testing.assert_array_equal(o1, o2)
        if s1 is None:
            continue
        for k in s2:
            np.testing.assert_allclose(s1[k], s2[k], rtol=1e-14, atol=0, equal_nan=True)
        np.testing.assert_allclose(p1, p2, rtol=1e-14)
        np.testing.assert_allclose(e1, e2, rtol=1e-12, atol=1e-14)
