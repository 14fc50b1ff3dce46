"""Frictional-foil step cost against the viscoelastic foil's (issue 22: within 1.5x on the paper grid).

Case: 79x7, Table-1 bearing (K_W its Walowit-Anno value, K_T = K_W), Lambda = 0.7 (above the critical
bearing number), from the equilibrium with a horizontal rotor kick xi' = 0.01, tau = 0..50: the whirl
grows, so the sliders stick and slip once per whirl period.  Frictional at mu_C = 0.1 (slipping) and
mu_C = 1e6 (stuck), viscoelastic at D_W = 1 on the same case.  Prints steps, microseconds per step and
microseconds per time unit, and the ratio of each against the viscoelastic run, with the integrator's
work counters (a slip onset fails the Newton iteration: its Jacobian, taken at the step start, has the
stuck slider's zero row); the last line is one JSON object.  Single process, one thread; timings only
compare on an idle machine.

    python -m gfb_experiments.bench_friction [--grid 79x7] [--duration 50] [--slip-viscosity ETA]
"""

from __future__ import annotations

import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gfb_env.equilibrium import find_equilibrium  # noqa: E402
from gfb_env.integrator import TrapezoidalIntegrator  # noqa: E402
from gfb_env.model import GFBModel  # noqa: E402
from gfb_env.scripting import OneLineParser  # noqa: E402

LAMBDA, KICK = 0.7, 0.01


def run(model: GFBModel, duration: float) -> dict:
    """Steps and wall time of one kicked run (the equilibrium and a warm-up call are not timed)."""
    L = model.layout
    s = find_equilibrium(model, LAMBDA)
    s0 = L.with_rotor(s, *L.rotor(s)[:2], KICK, 0.0)
    TrapezoidalIntegrator(model, s0, LAMBDA).advance(0.5)  # compile / warm caches
    it = TrapezoidalIntegrator(model, s0, LAMBDA)
    t0 = time.perf_counter()
    res = it.advance(duration)
    wall = time.perf_counter() - t0
    return {
        "status": res.status,
        "steps": res.steps,
        "us_per_step": 1e6 * wall / max(res.steps, 1),
        "us_per_tau": 1e6 * wall / duration,
        **{
            k: getattr(res.statistics, k)
            for k in ("rejected_steps", "newton_failures", "jacobians", "factorizations", "rhs_evaluations")
        },
    }


def main(argv: list[str] | None = None) -> dict:
    p = OneLineParser(description=__doc__.splitlines()[0])
    p.add_argument("--grid", default="79x7")
    p.add_argument("--duration", type=float, default=50.0)
    p.add_argument("--slip-viscosity", type=float, default=None)
    a = p.parse_args(argv)
    cases = {
        "viscoelastic": GFBModel("viscoelastic", grid=a.grid),
        "frictional_mu0.1": GFBModel(
            "frictional", grid=a.grid, friction_coefficient=0.1, slip_viscosity=a.slip_viscosity
        ),
        "frictional_stuck": GFBModel(
            "frictional", grid=a.grid, friction_coefficient=1e6, slip_viscosity=a.slip_viscosity
        ),
    }
    out = {name: run(m, a.duration) for name, m in cases.items()}
    ref = out["viscoelastic"]
    print(
        f"{'case':18s} {'status':8s} {'steps':>7s} {'us/step':>8s} {'x visc':>7s} "
        f"{'us/tau':>9s} {'x visc':>7s} {'newton_failures':>15s}"
    )
    for name, r in out.items():
        r["step_ratio"] = r["us_per_step"] / ref["us_per_step"]
        r["tau_ratio"] = r["us_per_tau"] / ref["us_per_tau"]
        print(
            f"{name:18s} {r['status']:8s} {r['steps']:7d} {r['us_per_step']:8.1f} {r['step_ratio']:7.2f} "
            f"{r['us_per_tau']:9.0f} {r['tau_ratio']:7.2f} {r['newton_failures']:15d}"
        )
    summary = {"grid": a.grid, "bearing_number": LAMBDA, "duration": a.duration, "cases": out}
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
