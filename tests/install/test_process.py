"""Process-level behaviour: importing the library leaves the host's environment alone, and SB3's
SubprocVecEnv works from ``python -c`` (fresh worker interpreters that never imported gfb_env)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from gfb_env._threads import THREAD_VARIABLES


def _clean_env() -> dict[str, str]:
    """The current environment without the thread variables (so a setdefault on import would show)."""
    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES and k != "PYTHONPATH"}


def _run(code: str, cwd, env: dict[str, str] | None = None, timeout: float = 120):
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=cwd,
        env=env if env is not None else _clean_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_import_gfb_env_leaves_os_environ_unchanged(tmp_path):
    code = textwrap.dedent(
        """
        import json, os
        import gymnasium  # a dependency; it sets PYGAME_HIDE_SUPPORT_PROMPT itself, not our business
        before = dict(os.environ)
        import gfb_env, gfb_env.envs, gfb_env.analysis
        import gfb_agents.learned.evaluate, gfb_agents.policy, gfb_agents.learned.train
        after = dict(os.environ)
        print(json.dumps({k: [before.get(k), after.get(k)] for k in set(before) | set(after)
                          if before.get(k) != after.get(k)}))
        """
    )
    out = _run(code, tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {}


def test_entry_points_set_single_threaded_blas_defaults(tmp_path):
    code = f"import os, gfb_experiments; print([os.environ.get(v) for v in {THREAD_VARIABLES!r}])"
    out = _run(code, tmp_path, {**_clean_env(), "MKL_NUM_THREADS": "3"})  # a value set is kept
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["['1',", "'1',", "'3']"]


def test_subproc_vec_env_from_python_c(tmp_path):
    # two spawn/forkserver workers from `python -c`: the plain id would be unknown there
    # (NamespaceNotFound); make_vec_env_for passes "gfb_env:<id>" and compiles the kernels first
    code = textwrap.dedent(
        """
        import json, time
        import numpy as np
        from gfb_agents.learned.train import make_vec_env_for

        t0 = time.perf_counter()
        venv = make_vec_env_for("gfb_env/RunUp-v2", 2, seed=3, vec_env="subproc")
        obs = venv.reset()
        actions = np.stack([venv.action_space.sample() for _ in range(2)])
        obs2, rewards, dones, infos = venv.step(actions)
        print(json.dumps({"shape": list(obs.shape), "finite": bool(np.isfinite(obs2).all()),
                          "differ": bool(not np.array_equal(obs[0], obs[1])),
                          "seconds": time.perf_counter() - t0}))
        venv.close()
        """
    )
    out = _run(code, tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["shape"][0] == 2 and res["finite"]
    assert res["differ"]  # seeds 3 and 4: two different episodes, not one copied


def test_importable_env_id():
    from gfb_agents.learned.train import importable_env_id

    assert importable_env_id("gfb_env/RunUp-v2") == "gfb_env:gfb_env/RunUp-v2"
    assert importable_env_id("gfb_env:gfb_env/RunUp-v2") == "gfb_env:gfb_env/RunUp-v2"
    assert importable_env_id("CartPole-v1") == "CartPole-v1"


@pytest.mark.slow
def test_native_vector_env_compiles_from_a_cold_cache_and_then_loads_it(tmp_path):
    """numba's parallel batch integrator with cache=True: compiled in a fresh cache folder (the
    workqueue threading layer, every core numba sees), loaded from it by the next process, the same
    observations both times (~1 min: every kernel compiles once)."""
    code = textwrap.dedent(
        """
        import json
        import numba
        import numpy as np
        import gymnasium as gym
        import gfb_env.envs
        import gfb_env.integrator.batch as I

        envs = gym.make_vec("gfb_env/RunUp-v2", num_envs=4, control_interval=20.0)
        obs, _ = envs.reset(seed=0)
        for _ in range(2):
            obs, *_ = envs.step(np.full((4, 2), 0.3, np.float32))
        print(json.dumps({"obs": obs.astype(float).tolist(), "layer": numba.threading_layer(),
                          "hits": sum(I._advance_batch.stats.cache_hits.values())}))
        """
    )
    env = {**_clean_env(), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    runs = []
    for _ in range(2):
        out = _run(code, tmp_path, env=env, timeout=600)
        assert out.returncode == 0, out.stderr[-3000:]
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    assert runs[0]["hits"] == 0 and runs[1]["hits"] == 1
    assert runs[0]["obs"] == runs[1]["obs"] and runs[0]["layer"] == "workqueue"
