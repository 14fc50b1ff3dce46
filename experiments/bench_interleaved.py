"""Old-against-new timing of the integrator benchmark case on a shared machine.

Runs the case of :mod:`gfb_experiments.bench_integrator` (79x7 viscoelastic, tau 0..3000) alternately
with the ``gfb_env`` of two checkouts, each run in its own subprocess (numba cache warm, best of 3 in
each), and prints the median wall and CPU time and us/step of both and their ratio, with the load
average.  Alternating cancels the slow drift of a shared machine's load; CPU time is less sensitive to
it than wall time.

    python -m gfb_experiments.bench_interleaved OLD_CHECKOUT NEW_CHECKOUT [--rounds 8]

(e.g. ``git worktree add /tmp/base <commit>`` for OLD_CHECKOUT and ``.`` for NEW_CHECKOUT).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from gfb_env.scripting import OneLineParser

CHILD = r"""
import json, time
import gfb_env
from gfb_env.model import GFBModel
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
m = GFBModel("viscoelastic", grid="79x7", foil_stiffness=1.0)
s0 = find_equilibrium(m, 0.6)
r = m.layout.rotor(s0)
s0 = m.layout.with_rotor(s0, r[0] + 0.01, r[1])
TrapezoidalIntegrator(m, s0, 0.6, 1.0).advance(1.0)  # compile or load the cache outside the timing
walls, cpus = [], []
for _ in range(3):
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    t0, c0 = time.perf_counter(), time.process_time()
    res = it.advance(3000.0, record_interval=0.05)
    walls.append(time.perf_counter() - t0)
    cpus.append(time.process_time() - c0)
print(json.dumps({"wall": min(walls), "cpu": min(cpus), "steps": res.steps, "file": gfb_env.__file__}))
"""


def main() -> int:
    p = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("old", type=Path, help="checkout whose gfb_env is the reference")
    p.add_argument("new", type=Path, help="checkout whose gfb_env is measured against it")
    p.add_argument("--rounds", type=int, default=8, help="alternations (each runs both once)")
    a = p.parse_args()
    trees = {"old": a.old.resolve(), "new": a.new.resolve()}
    for k, d in trees.items():
        if not (d / "gfb_env" / "__init__.py").is_file():
            print(f"{k}: {d} has no gfb_env package", file=sys.stderr)
            return 2
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    runs: dict[str, list[dict]] = {k: [] for k in trees}
    load_start = os.getloadavg()
    for i in range(a.rounds):
        for k in ("old", "new") if i % 2 == 0 else ("new", "old"):
            out = subprocess.run(
                [sys.executable, "-c", CHILD],
                env=env | {"PYTHONPATH": str(trees[k])},
                cwd="/",
                capture_output=True,
                text=True,
                check=True,
            ).stdout
            d = json.loads(out.strip().splitlines()[-1])
            if not d["file"].startswith(str(trees[k])):  # the other checkout's package was imported
                print(f"{k}: imported {d['file']}, not from {trees[k]}", file=sys.stderr)
                return 1
            runs[k].append(d)
            print(f"{k} wall {d['wall']:.4f} s, cpu {d['cpu']:.4f} s, {d['steps']} steps", flush=True)
    med = {k: {q: statistics.median(r[q] for r in v) for q in ("wall", "cpu")} for k, v in runs.items()}
    for k, v in runs.items():
        steps = v[0]["steps"]
        print(
            f"{k}: median wall {med[k]['wall']:.4f} s ({med[k]['wall'] / steps * 1e6:.2f} us/step), "
            f"median cpu {med[k]['cpu']:.4f} s ({med[k]['cpu'] / steps * 1e6:.2f} us/step), {steps} steps"
        )
    print(
        f"new/old: wall {med['new']['wall'] / med['old']['wall']:.4f}, "
        f"cpu {med['new']['cpu'] / med['old']['cpu']:.4f}; "
        f"load average at start {load_start}, at end {os.getloadavg()}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
