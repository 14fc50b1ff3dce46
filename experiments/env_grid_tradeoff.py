"""Accuracy/speed trade-off of the environment's training grid (``docs/envs.md``).

For each grid: the critical bearing number Lambda_c of the nominal task bearing (K_W = 0.50) at
D_W = 1 and at the optimum D_W = 2.3 (relative error against the paper grid 79 x 7), and the wall time
of the two regimes an episode lives in: a near-equilibrium run-up ramp (Lambda 0.45 -> 0.666 over
2 700 tau, i.e. 30 000 rpm/s) and 600 tau of developed whirl (Lambda = 0.75, D_W = 2.3), both with the
integrator defaults.  One core; timings on a shared machine.  Run::

    python -m gfb_experiments.env_grid_tradeoff [--grids 79x7,41x7,31x7,25x7,21x7,41x5,31x5]
"""

from __future__ import annotations

import time

from gfb_env import jsonio
from gfb_env.analysis.task_constants import critical_bearing_number_or_bound
from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel, Grid
from gfb_env.scripting import OneLineParser


def measure(grid: str) -> dict:
    model = GFBModel("viscoelastic", Grid.parse(grid), bearing=NOMINAL_BEARING)
    L = model.layout
    out = {"grid": grid, "state_size": L.size}
    for d in (1.0, 2.3):
        out[f"lambda_c_d{d:g}"] = critical_bearing_number_or_bound(
            model, d, lam_min=0.5, lam_max=1.0, scan_step=0.05, tol=1e-4
        )
    s = find_equilibrium(model, 0.45)
    integ = TrapezoidalIntegrator(model, s, 0.45, 2.3)
    t0 = time.perf_counter()
    integ.advance(2700.0, 0.666, 2.3, record_interval=0.5)
    out["ramp_2700tau_s"] = time.perf_counter() - t0
    s = find_equilibrium(model, 0.75)
    s = L.with_rotor(s, *L.rotor(s)[:2], 0.01, 0.0)
    integ = TrapezoidalIntegrator(model, s, 0.75, 2.3, touchdown_film_thickness=0.02)
    r = integ.advance(3000.0, raise_on_failure=False)
    if r.status == "done":
        t0 = time.perf_counter()
        r = integ.advance(3600.0, record_interval=0.5, raise_on_failure=False)
        out["whirl_600tau_s"] = time.perf_counter() - t0
        out["whirl_max_eccentricity"] = r.max_eccentricity
        out["whirl_min_film"] = r.min_film_thickness
    else:
        out["whirl_600tau_s"] = float("nan")
        out["whirl_status"] = r.status
    return out


def main() -> None:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grids", default="79x7,41x7,31x7,25x7,21x7,41x5,31x5")
    args = ap.parse_args()
    rows = [measure(g) for g in args.grids.split(",")]
    ref = next((r for r in rows if r["grid"] == "79x7"), rows[0])
    print(
        f"{'grid':>6} {'n':>5} {'Lc(D=1)':>9} {'err%':>6} {'Lc(D=2.3)':>10} {'err%':>6} {'ramp s':>8} "
        f"{'whirl600 s':>10} {'max eps':>8} {'min H':>7}"
    )
    for r in rows:
        r["err_d1_pct"] = 100 * (r["lambda_c_d1"] / ref["lambda_c_d1"] - 1)
        r["err_d2.3_pct"] = 100 * (r["lambda_c_d2.3"] / ref["lambda_c_d2.3"] - 1)
        print(
            f"{r['grid']:>6} {r['state_size']:>5} {r['lambda_c_d1']:9.4f} {r['err_d1_pct']:6.2f} "
            f"{r['lambda_c_d2.3']:10.4f} {r['err_d2.3_pct']:6.2f} {r['ramp_2700tau_s']:8.3f} "
            f"{r['whirl_600tau_s']:10.3f} {r.get('whirl_max_eccentricity', float('nan')):8.3f} "
            f"{r.get('whirl_min_film', float('nan')):7.3f}"
        )
    print(jsonio.dumps(rows))


if __name__ == "__main__":
    main()
