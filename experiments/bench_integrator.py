"""Integrator benchmark: our adaptive trapezoidal rule vs scipy ``solve_ivp`` (BDF and Radau).

Case (issue 2, section 7): paper grid 79x7, viscoelastic foil K_W = 1, D_W = 1, Lambda = 0.6, from the
equilibrium displaced by 0.01 C, tau = 0..3000: the whirl grows from the unstable equilibrium and
settles into a large orbit (min film ~0.04), so both the easy and the near-contact regimes count.

Baselines get the same compiled right-hand side and the same analytic sparse Jacobian.  Their
tolerance is the loosest of ``rtol in (1e-2, 3e-3, 1e-3, 3e-4, 1e-4)`` (atol = rtol / 10) whose
maximum eccentricity over tau in [2500, 3000] matches ours within 1 %; the speed-up is the ratio of
wall times at that matched accuracy.  Single process, one thread.  The last line is one JSON object,
also written to ``results/bench_integrator/summary.json`` with the machine's load average (timings
are only comparable on an idle machine).

    python -m gfb_experiments.bench_integrator [--repeat 3] [--skip-scipy] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from gfb_env import jsonio  # noqa: E402
from gfb_env.integrator import TrapezoidalIntegrator  # noqa: E402
from gfb_env.scripting import OneLineParser, check_output_dir  # noqa: E402
from gfb_experiments.convergence_study import benchmark_case  # noqa: E402

LAMBDA, DAMPING, TAU_END, WINDOW = 0.6, 1.0, 3000.0, 500.0


def run_ours(model, s0) -> dict:
    it = TrapezoidalIntegrator(model, s0, LAMBDA, DAMPING)
    t0 = time.perf_counter()
    res = it.advance(TAU_END, record_interval=0.05)
    wall = time.perf_counter() - t0
    tr = res.trajectory
    amp = float(tr.eccentricity[tr.tau >= TAU_END - WINDOW].max())
    return {
        "wall_s": wall,
        "steps": res.steps,
        "max_eccentricity": amp,
        "jacobians": res.statistics.jacobians,
        "factorizations": res.statistics.factorizations,
        "rhs_evaluations": res.statistics.rhs_evaluations,
    }


def run_scipy(model, s0, method: str, rtol: float) -> dict:
    fun = lambda t, y: model.rhs(y, LAMBDA, DAMPING)  # noqa: E731
    jac = lambda t, y: model.jacobian(y, LAMBDA, DAMPING)  # noqa: E731
    t_eval = np.linspace(TAU_END - WINDOW, TAU_END, int(WINDOW / 0.05) + 1)
    t0 = time.perf_counter()
    sol = solve_ivp(fun, (0.0, TAU_END), s0, method=method, jac=jac, rtol=rtol, atol=rtol / 10, t_eval=t_eval)
    wall = time.perf_counter() - t0
    L = model.layout
    ok = sol.status == 0 and np.all(np.isfinite(sol.y))
    amp = float(np.hypot(sol.y[L.xi_index], sol.y[L.eta_index]).max()) if ok else float("nan")
    return {
        "method": method,
        "rtol": rtol,
        "wall_s": wall,
        "steps": int(sol.t.size and sol.nfev),
        "nfev": sol.nfev,
        "njev": sol.njev,
        "nlu": sol.nlu,
        "max_eccentricity": amp,
        "success": bool(ok),
    }


def main() -> None:
    p = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeat", type=int, default=3, help="runs of our integrator (median wall time)")
    p.add_argument("--skip-scipy", action="store_true", help="only time our integrator")
    p.add_argument("--out", type=Path, default=Path("results/bench_integrator"), help="output folder")
    a = p.parse_args()
    try:  # before any work: an unwritable --out fails now
        check_output_dir(str(a.out), "--out")
    except ValueError as exc:
        p.error(str(exc))
    load_start = os.getloadavg()[0]
    model, s0 = benchmark_case()
    t0 = time.perf_counter()
    TrapezoidalIntegrator(model, s0, LAMBDA, DAMPING).advance(1.0)  # compile outside the timing
    first_call = time.perf_counter() - t0
    print(f"first call (numba compile, or load from its on-disk cache): {first_call:.2f} s", flush=True)
    runs = [run_ours(model, s0) for _ in range(a.repeat)]
    walls = [r["wall_s"] for r in runs]
    ours = runs[0] | {"wall_s": statistics.median(walls)}
    ours["us_per_step"] = ours["wall_s"] / ours["steps"] * 1e6
    print(
        f"gfb-env trapezoidal: wall {ours['wall_s']:.3f} s (median of {a.repeat}: "
        f"{', '.join(f'{w:.3f}' for w in walls)}), {ours['steps']} steps, {ours['us_per_step']:.1f} us/step, "
        f"{ours['jacobians']} Jacobians, {ours['factorizations']} factorisations (one per "
        f"{ours['steps'] / ours['factorizations']:.1f} steps), {ours['rhs_evaluations']} right-hand sides "
        f"({ours['rhs_evaluations'] / ours['steps']:.2f} per step), "
        f"max eccentricity (last {WINDOW:g}) {ours['max_eccentricity']:.5f}",
        flush=True,
    )
    summary = {
        "wall_s": ours["wall_s"],
        "steps": ours["steps"],
        "us_per_step": ours["us_per_step"],
        "max_eccentricity": ours["max_eccentricity"],
    }
    if not a.skip_scipy:
        for method in ("BDF", "Radau"):
            chosen = None
            for rtol in (1e-2, 3e-3, 1e-3, 3e-4, 1e-4):
                r = run_scipy(model, s0, method, rtol)
                rel = abs(r["max_eccentricity"] - ours["max_eccentricity"]) / ours["max_eccentricity"]
                print(
                    f"scipy {method:5s} rtol={rtol:g}: wall {r['wall_s']:.2f} s, nfev {r['nfev']}, njev "
                    f"{r['njev']}, nlu {r['nlu']}, max eccentricity {r['max_eccentricity']:.5f} "
                    f"({100 * rel:.2f} % from ours)",
                    flush=True,
                )
                if r["success"] and rel <= 0.01:
                    chosen = r
                    break
            key = f"speedup_vs_{method.lower()}"
            if chosen is None:
                summary[key] = None
                print(f"scipy {method}: no tolerance matched within 1 %")
            else:
                summary[key] = chosen["wall_s"] / ours["wall_s"]
                summary[f"{method.lower()}_rtol"] = chosen["rtol"]
                summary[f"{method.lower()}_wall_s"] = chosen["wall_s"]
                print(
                    f"=> {method} at rtol={chosen['rtol']:g}: {summary[key]:.1f}x slower than ours",
                    flush=True,
                )
    summary["first_call_s"] = first_call
    summary["load_average_1min_at_start"] = load_start
    summary["load_average_1min_at_end"] = os.getloadavg()[0]
    summary["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    print(jsonio.dumps(summary))


if __name__ == "__main__":
    main()
