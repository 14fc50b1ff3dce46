"""The native vector env's throughput under numba's threading layers (issue 13).

The compiled batch (:class:`gfb_env.integrator.BatchAdvance`) selects numba's ``workqueue`` layer unless
``NUMBA_THREADING_LAYER`` is set (``docs/envs.md`` says why: GNU OpenMP's workers spin under load, and a
process forked after an OpenMP batch dies).  This measures what that costs on an idle machine: for each
layer, in a fresh process (the layer is fixed at the first parallel call), RunUp-v2 near equilibrium,
N = 16 envs, env steps/s with 1 and 2 threads, alternating.  Run on an idle machine::

    OMP_NUM_THREADS=1 python -m gfb_experiments.bench_threading_layer

The last line is one JSON object: layer -> {threads: [env steps/s per repetition]}.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

LAYERS = ("workqueue", "omp")


def measure(num_envs: int, batches: int, reps: int) -> dict[int, list[float]]:
    """Env steps/s of the native vector env with 1 and 2 threads, ``reps`` alternations."""
    import gymnasium as gym
    import numpy as np

    import gfb_env  # noqa: F401  (registers the ids)

    env = gym.make_vec("gfb_env/RunUp-v2", num_envs=num_envs)
    u = env.unwrapped
    env.reset(seed=0)
    a = np.zeros((num_envs, 2), dtype=np.float32)  # hold the start speed: near equilibrium
    out: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(reps):
        for t in (1, 2):
            u.num_threads = t
            for _ in range(5):
                env.step(a)
            t0 = time.perf_counter()
            for _ in range(batches):
                env.step(a)
            out[t].append(num_envs * batches / (time.perf_counter() - t0))
    env.close()
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--num-envs", type=int, default=16)
    ap.add_argument("--batches", type=int, default=60, help="batch steps per measurement")
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.num_envs < 1 or a.batches < 1 or a.reps < 1:
        ap.error("--num-envs, --batches and --reps must be >= 1")
    if a.child:
        print(json.dumps(measure(a.num_envs, a.batches, a.reps)))
        return 0
    results = {}
    for layer in LAYERS:
        env = {**os.environ, "NUMBA_THREADING_LAYER": layer}
        cmd = [sys.executable, "-m", "gfb_experiments.bench_threading_layer", "--child"]
        cmd += ["--num-envs", str(a.num_envs), "--batches", str(a.batches), "--reps", str(a.reps)]
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        res = {int(k): v for k, v in json.loads(run.stdout.strip().splitlines()[-1]).items()}
        results[layer] = res
        print(
            f"{layer:10} N = {a.num_envs}: 1 thread "
            + ", ".join(f"{x:.0f}" for x in res[1])
            + "; 2 threads "
            + ", ".join(f"{x:.0f}" for x in res[2])
            + f" env steps/s (load {os.getloadavg()[0]:.2f})",
            flush=True,
        )
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
