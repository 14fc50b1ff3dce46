"""Training envs in worker processes (``--num-processes``, issue 20 item 3): refused where it cannot
apply, and the SB3 adapter over a sharded native vector env steps the same envs."""

from __future__ import annotations

import numpy as np
import pytest

from gfb_agents.learned.train import TrainConfig, make_vec_env_for


def test_num_processes_needs_the_native_vector_env():
    with pytest.raises(ValueError, match="num_processes"):
        TrainConfig(algo="ppo", env_id="gfb_env/RunUp-v2", vec_env="dummy", num_processes=2)
    with pytest.raises(ValueError, match="num_processes"):
        TrainConfig(algo="ppo", env_id="gfb_env/RunUp-v2", num_processes=0)
    with pytest.raises(ValueError, match="num_processes"):
        make_vec_env_for("gfb_env/RunUp-v2", 2, 0, vec_env="subproc", num_processes=2)


def test_sb3_adapter_over_worker_processes():
    """Two envs in two workers against the same two in this process: the reset and two steps bit for
    bit, and the adapter reaches the remote envs' methods."""
    out = []
    for p in (1, 2):
        venv = make_vec_env_for("gfb_env/RunUp-v2", 2, 1_000_000, num_processes=p)
        obs = [venv.reset()]
        for _ in range(2):
            o, r, d, _ = venv.step(np.array([[0.5, 0.0], [1.0, -0.5]], np.float32))
            obs += [o, r]
        out.append(obs)
        assert len(venv.env_method("hidden_parameters")) == 2
        venv.close()
    for x, y in zip(*out, strict=True):
        assert np.array_equal(x, y)
