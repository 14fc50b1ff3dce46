"""Tolerance convergence study of the limit-cycle amplitude (chooses the integrator's default tolerance).

Case (the benchmark case of ``bench_integrator.py``): paper grid 79x7, viscoelastic foil K_W = 1,
D_W = 1, Lambda = 0.6, from the equilibrium displaced by 0.01 C, tau = 0..3000.  For each
``rtol = atol`` it reports the maximum eccentricity over tau in [2500, 3000] (the limit-cycle amplitude),
the minimum film thickness there, the step count and the wall time, and the relative amplitude error
against the tightest tolerance.  Writes ``results/convergence_study/convergence.csv`` and ``.png``.

    python -m gfb_experiments.convergence_study [--quick]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from gfb_env import jsonio
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.scripting import OneLineParser, check_output_dir


def benchmark_case(grid: str = "79x7"):
    """Model and initial state of the integrator benchmark (shared with bench_integrator.py)."""
    m = GFBModel("viscoelastic", grid=grid, foil_stiffness=1.0)
    s0 = find_equilibrium(m, 0.6)
    r = m.layout.rotor(s0)
    s0 = m.layout.with_rotor(s0, r[0] + 0.01, r[1])
    return m, s0


def amplitude(m: GFBModel, s0: np.ndarray, tol: float, tau_end: float, window: float) -> dict:
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0, rtol=tol, atol=tol)
    t0 = time.perf_counter()
    res = it.advance(tau_end, record_interval=0.05, raise_on_failure=False)
    wall = time.perf_counter() - t0
    tr = res.trajectory
    sel = tr.tau >= tau_end - window
    if res.status != "done" or not sel.any():  # a loose tolerance may end in a (spurious) touchdown
        print(f"rtol={tol:g}: {res.status} at tau={res.tau:.1f} {res.message}")
    return {
        "rtol": tol,
        "status": res.status,
        "amplitude": float(tr.eccentricity[sel].max()) if sel.any() else float("nan"),
        "min_film_thickness": float(tr.min_film_thickness[sel].min()) if sel.any() else float("nan"),
        "steps": res.steps,
        "wall_s": wall,
    }


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="coarse grid and a short run (for tests)")
    p.add_argument("--out", default="results/convergence_study")
    a = p.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            p.error(str(exc))
    grid, tau_end, window = ("31x5", 800.0, 200.0) if a.quick else ("79x7", 3000.0, 500.0)
    tols = [1e-2, 1e-3] if a.quick else [3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5]
    m, s0 = benchmark_case(grid)
    if a.quick:  # the coarse grid is stable at Lambda = 0.6 with these foil values: use the rigid foil
        m = GFBModel("rigid", grid=grid)
        s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.3, 0.3)
    TrapezoidalIntegrator(m, s0, 0.6, 1.0).advance(1.0)  # compile outside the timings
    rows = [amplitude(m, s0, tol, tau_end, window) for tol in tqdm(tols, desc="tolerances")]
    ref = rows[-1]["amplitude"]
    for r in rows:
        r["relative_amplitude_error"] = abs(r["amplitude"] - ref) / ref
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0])
    with open(out / "convergence.csv", "w") as fh:
        fh.write(",".join(keys) + "\n")
        for r in rows:
            fh.write(",".join(r[k] if isinstance(r[k], str) else f"{r[k]:.8g}" for k in keys) + "\n")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    ok = [r for r in rows[:-1] if r["status"] == "done"]
    ax[0].loglog([r["rtol"] for r in ok], [max(r["relative_amplitude_error"], 1e-9) for r in ok], "o-")
    ax[0].set_xlabel("rtol = atol")
    ax[0].set_ylabel(f"relative error of the limit-cycle amplitude\n(vs rtol = {rows[-1]['rtol']:g})")
    ax[0].grid(True, which="both", alpha=0.3)
    done = [r for r in rows if r["status"] == "done"]
    stopped = [r for r in rows if r["status"] != "done"]
    ax[1].semilogx([r["rtol"] for r in done], [r["steps"] for r in done], "s-", label="whole run")
    if stopped:
        ax[1].semilogx(
            [r["rtol"] for r in stopped],
            [r["steps"] for r in stopped],
            "rx",
            ms=9,
            label="stopped early: spurious touchdown",
        )
        ax[1].legend()
    ax[1].set_xlabel("rtol = atol")
    ax[1].set_ylabel("accepted steps")
    ax[1].grid(True, which="both", alpha=0.3)
    fig.suptitle(f"viscoelastic K_W=1, D_W=1, Lambda=0.6, grid {grid}, tau 0..{tau_end:g}")
    fig.savefig(out / "convergence.png", dpi=110)
    for r in rows:
        print(jsonio.dumps(r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
