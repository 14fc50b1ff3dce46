"""Basin map: the unbalance that throws the rotor from the stable equilibrium onto the whirl, in the
bistable band (issue 10, sect. 1; the paper's hysteresis made concrete for a machine with unbalance).

K_W = 1, D_W = 1 on the paper grid 79x7, where the fold of cycles is at Lambda = 0.539 and the Hopf point
at Lambda_c = 0.586 (``results/hysteresis_map``).  For each Lambda in the band the rotor starts at the
static equilibrium with the unbalance U switched on at tau = 0 (theta = 0) and runs for ``--duration``
(tau) at constant speed.  A run counts as *thrown* when the whirl line appears: the largest amplitude of
the xi spectrum in the band 0.3-0.6 Lambda over a window of 250 tau exceeds 0.3 C (the large whirl has
~1 C there, the forced synchronous orbit none; the switch-on transient of the whirl mode stays below
0.1 C), or when the journal touches down.  U* is bracketed between the largest U that stayed and the
smallest that was thrown, by geometric bisection to a ratio ``--ratio``.  U* is a threshold *within the
run time*: near U* the orbit lingers by the unstable cycle, so a longer run could lower it a little.

    python -m gfb_experiments.basin_map [--quick] [--out results/basin_map]

Writes basin_map.csv (per Lambda: U* = geometric mean of the bracket, the bracket, U* in um, g mm and as
an ISO 1940 grade at that speed), runs.csv (every run), basin_map.png and summary.json.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

from gfb_env import BearingParameters, jsonio
from gfb_env.analysis.spectrum import amplitude_spectrum
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.scripting import OneLineParser, check_output_dir

#: K_W = 1, D_W = 1 on 79x7 (results/hysteresis_map/summary.json)
FOLD_BEARING_NUMBER = 0.5392
CRITICAL_BEARING_NUMBER = 0.5864
WINDOW = 250.0  # tau per classification window
RECORD = 0.5
WHIRL_LINE = 0.3  # C: amplitude of the 0.3-0.6 Lambda band that counts as the whirl


def thrown(model: GFBModel, s0: np.ndarray, lam: float, u: float, duration: float) -> dict:
    """One run from the equilibrium with the unbalance switched on: whether (and when) the whirl starts."""
    it = TrapezoidalIntegrator(model, s0, lam, 1.0, unbalance=Unbalance(u))
    eps0 = model.eccentricity(s0)
    max_eps = eps0
    band = 0.0
    while it.tau < duration - 1e-9:
        r = it.advance(min(it.tau + WINDOW, duration), record_interval=RECORD, raise_on_failure=False)
        max_eps = max(max_eps, r.max_eccentricity)
        if r.status == "touchdown":
            return {"thrown": True, "touchdown": True, "tau": r.tau, "band": band, "max_eps": max_eps}
        if not r.ok:
            raise RuntimeError(f"Lambda={lam}, U={u}: {r.message}")
        spec = amplitude_spectrum(r.trajectory.xi, RECORD, fraction=1.0)
        k = (spec.omega > 0.3 * lam) & (spec.omega < 0.6 * lam)
        band = float(spec.amplitude[k].max())
        if band > WHIRL_LINE:
            return {"thrown": True, "touchdown": False, "tau": r.tau, "band": band, "max_eps": max_eps}
    return {"thrown": False, "touchdown": False, "tau": it.tau, "band": band, "max_eps": max_eps}


def threshold(model, lam, u_lo, u_hi, ratio, duration, runs):
    """Geometric bisection of the throwing unbalance at ``lam``: (lower, upper, whether the upper run
    ended in touchdown rather than on the whirl); None: censored."""
    s0 = find_equilibrium(model, lam)

    touchdown = {}

    def run(u):
        t0 = time.perf_counter()
        r = thrown(model, s0, lam, u, duration)
        touchdown[u] = r["touchdown"]
        runs.append({"bearing_number": lam, "unbalance": u, **r, "wall_s": time.perf_counter() - t0})
        print(f"  Lambda={lam:.4f} U={u:.4g}: {'THROWN' if r['thrown'] else 'stays'} "
              f"(tau {r['tau']:.0f}, band {r['band']:.3f})", flush=True)  # fmt: skip
        return r["thrown"]

    if not run(u_hi):
        return u_hi, None, False  # U* above the range
    if run(u_lo):
        return None, u_lo, touchdown[u_lo]  # U* below the range
    lo, hi = u_lo, u_hi
    while hi / lo > ratio:
        mid = math.sqrt(lo * hi)
        if run(mid):
            hi = mid
        else:
            lo = mid
    return lo, hi, touchdown[hi]


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one speed, coarse bracket, short runs (tests)")
    ap.add_argument("--out", default=None, help="output directory (default results/basin_map)")
    ap.add_argument("--duration", type=float, default=None, help="tau per run (default 3000; quick 1000)")
    ap.add_argument("--ratio", type=float, default=None, help="bracket ratio to stop at (default 1.05)")
    a = ap.parse_args(argv)
    out = Path(a.out or ("results/basin_map_quick" if a.quick else "results/basin_map"))
    try:
        check_output_dir(str(out), "--out")
    except ValueError as exc:
        ap.error(str(exc))
    if a.duration is not None and not (math.isfinite(a.duration) and 0 < a.duration <= 50_000):
        ap.error(f"--duration must lie in (0, 50000], got {a.duration!r}")
    if a.ratio is not None and not (math.isfinite(a.ratio) and a.ratio > 1.001):
        ap.error(f"--ratio must be > 1.001, got {a.ratio!r}")
    grid = "79x7"
    if a.quick:
        lams, duration, ratio, u_lo, u_hi = [0.575], 1000.0, 2.0, 0.01, 0.3
    else:
        lams = [0.541, 0.545, 0.55, 0.555, 0.56, 0.565, 0.57, 0.575, 0.58, 0.584]
        duration, ratio, u_lo, u_hi = 3000.0, 1.05, 1e-3, 0.5
    duration = a.duration or duration
    ratio = a.ratio or ratio
    model = GFBModel("viscoelastic", grid=grid, foil_stiffness=1.0)
    bearing = BearingParameters()
    t0 = time.perf_counter()
    runs: list[dict] = []
    rows = []
    for lam in lams:
        lo, hi, by_touchdown = threshold(model, lam, u_lo, u_hi, ratio, duration, runs)
        star = math.sqrt(lo * hi) if lo is not None and hi is not None else None
        rpm = bearing.speed_rpm_at(lam)
        ub = None if star is None else Unbalance(star)
        rows.append({
            "bearing_number": lam,
            "speed_rpm": rpm,
            "threshold_unbalance": star,
            "stays_below": lo,
            "thrown_above": hi,
            "upper_by_touchdown": int(by_touchdown),
            "threshold_um": None if ub is None else ub.eccentricity_um(bearing),
            "threshold_g_mm": None if ub is None else ub.mass_radius_g_mm(bearing),
            "threshold_iso_grade_mm_s": None if ub is None else ub.iso1940_grade_mm_s(bearing, rpm),
        })  # fmt: skip
    wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    with (out / "basin_map.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else f"{v:.6g}") for k, v in r.items()})
    with (out / "runs.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(runs[0]))
        w.writeheader()
        for r in runs:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    _plot(rows, out / "basin_map.png", grid, duration)
    summary = {
        "command": "python -m gfb_experiments.basin_map " + " ".join(sys.argv[1:] if argv is None else argv),
        "structure": "viscoelastic",
        "grid": grid,
        "foil_stiffness": 1.0,
        "foil_damping": 1.0,
        "fold_bearing_number": FOLD_BEARING_NUMBER,
        "critical_bearing_number": CRITICAL_BEARING_NUMBER,
        "duration_tau": duration,
        "bracket_ratio": ratio,
        "unbalance_range": [u_lo, u_hi],
        "whirl_line_amplitude": WHIRL_LINE,
        "points": rows,
        "runs": len(runs),
        "wall_time_s": wall,
    }
    (out / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    print(
        f"wrote {out}/basin_map.csv, runs.csv, basin_map.png, summary.json ({wall:.1f} s, {len(runs)} runs)"
    )
    return 0


def _plot(rows, path: Path, grid: str, duration: float) -> None:
    from gfb_env.plotting import plt

    lam = np.array([r["bearing_number"] for r in rows])
    lo = np.array([np.nan if r["stays_below"] is None else r["stays_below"] for r in rows])
    hi = np.array([np.nan if r["thrown_above"] is None else r["thrown_above"] for r in rows])
    star = np.sqrt(lo * hi)
    fig, ax = plt.subplots(figsize=(7.5, 5), constrained_layout=True)
    ax.fill_between(lam, np.where(np.isfinite(star), star, np.nan), 1.0, color="tab:red", alpha=0.15,
                    label="thrown onto the whirl")  # fmt: skip
    ax.fill_between(lam, 1e-4, np.where(np.isfinite(star), star, np.nan), color="tab:green", alpha=0.15,
                    label="stays at the (forced) equilibrium")  # fmt: skip
    ax.semilogy(lam, star, "k.-", label="threshold U*")
    ax.errorbar(lam, star, yerr=[star - lo, hi - star], fmt="none", ecolor="k", capsize=2)
    ax.axvline(FOLD_BEARING_NUMBER, color="tab:blue", ls="--", label=f"fold of cycles {FOLD_BEARING_NUMBER}")
    ax.axvline(
        CRITICAL_BEARING_NUMBER, color="tab:red", ls="--", label=rf"$\Lambda_c$ {CRITICAL_BEARING_NUMBER}"
    )
    ax.set_xlim(FOLD_BEARING_NUMBER - 0.003, CRITICAL_BEARING_NUMBER + 0.003)
    finite = star[np.isfinite(star)]
    ax.set_ylim(max(1e-4, (finite.min() if finite.size else 1e-3) / 3), 1.0)
    ax.set_xlabel(r"bearing number $\Lambda$")
    ax.set_ylabel(r"unbalance $U = m_u e / (m C)$")
    b = BearingParameters()
    g_mm = 2 * b.rotor_mass_per_bearing_kg * b.clearance_m * 1e6  # U -> g mm (Unbalance.mass_radius_g_mm)
    sec = ax.secondary_yaxis("right", functions=(lambda u: u * g_mm, lambda g: g / g_mm))
    sec.set_ylabel("Table-1 rotor (0.37 kg, C = 50 um): g mm")
    ax.set_title(
        "Basin map: unbalance that starts the whirl\n"
        f"viscoelastic K_W=1, D_W=1, {grid}, runs of {duration:g} tau"
    )
    ax.legend(fontsize=8, loc="lower left")
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
