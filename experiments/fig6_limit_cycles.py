"""Paper Fig. 6: rotor orbits at K_W = 1, Lambda = 0.6 for a sweep of the foil damping D_W.

Elastic foil: integrated from the kicked equilibrium (the paper: the journal collides with the deformed
foil; a touchdown event, min H < 0.01, ends the run).  Viscoelastic foil: D_W ascending, each run started
from the previous run's settled whirl (the first from the kicked equilibrium), so that the whirl is
followed into the bistable band where a small kick would decay; each run integrates until the orbit
settles (:func:`gfb_env.analysis.settle_whirl`).  The final orbit is also converged by shooting
(:func:`gfb_env.analysis.periodic_orbit_from_simulation`) for its period and Floquet multipliers.

    python -m gfb_experiments.fig6_limit_cycles [--quick] [--out results/fig6_limit_cycles]
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from gfb_env import GFBModel, Grid, jsonio
from gfb_env.analysis import ShootingError, periodic_orbit_from_simulation, settle_whirl
from gfb_env.scripting import OneLineParser, check_output_dir

LAMBDA = 0.6
K_W = 1.0


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="33x7 grid, two dampings, no shooting (for tests)")
    ap.add_argument("--out", default=None, help="output directory (default results/fig6_limit_cycles)")
    a = ap.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    out = Path(a.out or ("results/fig6_limit_cycles_quick" if a.quick else "results/fig6_limit_cycles"))
    out.mkdir(parents=True, exist_ok=True)
    grid = Grid.parse("33x7" if a.quick else "79x7")
    dws = [4.0, 8.0] if a.quick else [0.5, 1.0, 2.0, 4.0, 8.0, 16.0]
    tau_max = 1500.0 if a.quick else 8000.0
    t0 = time.perf_counter()
    cases = []
    el = GFBModel("elastic", grid, foil_stiffness=K_W)
    sw = settle_whirl(el, LAMBDA, 1.0, kick=0.05, tau_max=tau_max, window=100.0)
    cases.append(("elastic", math.nan, sw, None))
    vm = GFBModel("viscoelastic", grid, foil_stiffness=K_W)
    state = None
    for dw in tqdm(dws, desc="fig6 D_W sweep"):
        sw = settle_whirl(vm, LAMBDA, dw, state=state, kick=0.3, tau_max=tau_max, window=100.0)
        orb = None
        if sw.status == "whirl" and not a.quick:
            try:
                orb = periodic_orbit_from_simulation(vm, LAMBDA, dw, sw.state, sw.period, n_steps=300)
            except ShootingError:
                orb = None
        cases.append(("viscoelastic", dw, sw, orb))
        if sw.status == "whirl":
            state = sw.state
    rows = []
    for st, dw, sw, orb in cases:
        rows.append(
            {
                "structure": st,
                "foil_damping": dw,
                "status": sw.status,
                "tau_end": sw.tau,
                "max_eccentricity": sw.max_eccentricity,
                "amplitude_xi": sw.amplitude,
                "min_film_thickness": sw.min_film_thickness,
                "period": sw.period,
                "whirl_frequency_ratio": (2 * math.pi / sw.period / LAMBDA)
                if sw.period == sw.period
                else math.nan,
                "shooting_period": orb.period if orb else math.nan,
                "shooting_max_eccentricity": orb.max_eccentricity if orb else math.nan,
                "shooting_stable": orb.stable if orb else "",
                "leading_nontrivial_multiplier": float(abs(orb.nontrivial_multipliers[0]))
                if orb
                else math.nan,
            }
        )
    with (out / "limit_cycles.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with (out / "orbits.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["structure", "foil_damping", "tau", "xi", "eta"])
        for st, dw, sw, _ in cases:
            tr = sw.trajectory
            for t, x, y in zip(tr.tau, tr.xi, tr.eta):
                w.writerow([st, dw, f"{t:.3f}", f"{x:.6f}", f"{y:.6f}"])
    _plot(cases, out / "limit_cycles.png")
    summary = {
        "grid": str(grid),
        "bearing_number": LAMBDA,
        "foil_stiffness": K_W,
        "cases": rows,
        "wall_time_s": time.perf_counter() - t0,
    }
    (out / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    for r in rows:
        print(r)
    return 0


def _plot(cases, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(cases)
    nc = min(5, n)
    nr = int(math.ceil(n / nc))
    fig, axs = plt.subplots(
        nr, nc, figsize=(3.2 * nc, 3.3 * nr + 0.6), squeeze=False, constrained_layout=True
    )
    th = np.linspace(0, 2 * np.pi, 200)
    for ax, (st, dw, sw, _) in zip(axs.ravel(), cases):
        tr = sw.trajectory
        hist_x = tr.xi
        hist_y = tr.eta
        T = sw.period if sw.period == sw.period else 25.0
        last = tr.tau >= tr.tau[-1] - T if len(tr) else slice(None)
        ax.plot(hist_x, hist_y, "-.", color="tab:red", lw=0.5, alpha=0.6)
        ax.plot(hist_x[last], hist_y[last], "-", color="tab:red", lw=2.0)
        ax.plot(np.sin(th), np.cos(th), "k:", lw=0.8)  # eps = 1 (nominal clearance circle)
        ax.set_aspect("equal")
        ax.set_xlim(-2, 2)
        ax.set_ylim(-1.5, 2.5)
        ax.invert_yaxis()  # eta points down (along gravity)
        title = "elastic" if st == "elastic" else f"viscoelastic $D_W$={dw:g}"
        ax.set_title(f"{title}\n{sw.status}, max $\\varepsilon$={sw.max_eccentricity:.3f}", fontsize=9)
        ax.set_xlabel(r"$\xi$")
        ax.set_ylabel(r"$\eta$")
    for ax in axs.ravel()[n:]:
        ax.axis("off")
    fig.suptitle(
        r"Fig. 6: orbits at $K_W=1$, $\Lambda=0.6$ (thin: last transient window, thick: last period;"
        r" dotted: $\varepsilon=1$)",
        fontsize=10,
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
