"""Frictional-foil step cost against the viscoelastic foil's (issue 22: within 1.5x on the paper grid).

Case: 79x7, Table-1 bearing (K_W its Walowit-Anno value, K_T = K_W), Lambda = 0.7 (above the critical
bearing number), from the equilibrium with a horizontal rotor kick xi' = 0.01, tau = 0..50: the whirl
grows, so the sliders stick and slip once per whirl period.  Frictional at mu_C = 0.1 (slipping) and
mu_C = 1e6 (stuck), viscoelastic at D_W = 1 on the same case.  Prints steps, microseconds per step and
microseconds per time unit, and the ratio of each against the viscoelastic run (both measures: per
integrator step, the issue's "a frictional step", and per tau of simulated time, which also counts how
many steps each foil needs), with the integrator's work counters.  Times are CPU time
(``time.process_time``, single process, one thread), the minimum over ``--repeats`` runs, so a loaded
machine inflates them less than wall time; the counters do not depend on load.  The last line is one
JSON object (``step_ratio`` and ``tau_ratio`` per case).

    python -m gfb_experiments.bench_friction [--grid 79x7] [--duration 50] [--slip-viscosity ETA]
        [--repeats 3]
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
from gfb_env.scripting import OneLineParser, int_range, positive  # noqa: E402

LAMBDA, KICK = 0.7, 0.01


def run(model: GFBModel, duration: float, repeats: int) -> dict:
    """Steps and CPU time (the minimum over ``repeats`` identical runs) of one kicked run (the
    equilibrium and a warm-up call are not timed)."""
    L = model.layout
    s = find_equilibrium(model, LAMBDA)
    s0 = L.with_rotor(s, *L.rotor(s)[:2], KICK, 0.0)
    TrapezoidalIntegrator(model, s0, LAMBDA).advance(0.5)  # compile / warm caches
    cpu = []
    for _ in range(repeats):
        it = TrapezoidalIntegrator(model, s0, LAMBDA)
        t0 = time.process_time()
        res = it.advance(duration)
        cpu.append(time.process_time() - t0)
    best = min(cpu)
    return {
        "status": res.status,
        "steps": res.steps,
        "cpu_s": best,
        "us_per_step": 1e6 * best / max(res.steps, 1),
        "us_per_tau": 1e6 * best / duration,
        **{
            k: getattr(res.statistics, k)
            for k in ("rejected_steps", "newton_failures", "jacobians", "factorizations", "rhs_evaluations")
        },
    }


def main(argv: list[str] | None = None) -> dict:
    p = OneLineParser(description=__doc__.splitlines()[0])
    p.add_argument("--grid", default="79x7")
    p.add_argument("--duration", type=positive("--duration"), default=50.0)
    p.add_argument("--slip-viscosity", type=positive("--slip-viscosity"), default=None)
    p.add_argument("--repeats", type=int_range("--repeats", 1, 100), default=3)
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
    out = {name: run(m, a.duration, a.repeats) for name, m in cases.items()}
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
    fr = out["frictional_mu0.1"]
    print(
        f"slipping frictional against viscoelastic: {fr['step_ratio']:.2f}x per step, "
        f"{fr['tau_ratio']:.2f}x per tau ({fr['steps']} against {ref['steps']} steps); target 1.5x"
    )
    summary = {
        "grid": a.grid,
        "bearing_number": LAMBDA,
        "duration": a.duration,
        "repeats": a.repeats,
        "timer": "process_time, min over repeats",
        "step_ratio": fr["step_ratio"],
        "tau_ratio": fr["tau_ratio"],
        "cases": out,
    }
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
