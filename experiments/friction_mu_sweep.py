"""Whirl onset, collapse and amplitude of the frictional foil versus mu_C on a slow run-up and
coast-down, against the viscoelastic foil versus D_W (issue 22).

Each run (one model, one process): from the equilibrium at ``Lambda_c - 0.03`` (the frictional foil's
quasi-static spin-up equilibrium from Lambda = 0.1, :func:`gfb_env.analysis.stability.spinup_equilibrium`,
the history of its Lambda_c, ``critical_bearing_number`` with ``bearing_range=(0.1, 3)``) with a rotor
kick xi' = 1e-3, ``Lambda`` ramps up at ``RATE`` per tau in windows of ``WINDOW`` tau.  Per window: the
whirl amplitude (half the peak-to-peak of xi after removing a linear trend; whirling above
``gfb_env.analysis.runup.WHIRL_THRESHOLD`` = 0.02), max eps, min H.  The ramp turns (coast-down at the same
rate, to ``Lambda_c - 0.08``) when the amplitude exceeds ``TURN_AMPLITUDE`` or at ``Lambda_c + 0.1``;
touchdown (min H < 0.01) ends the run.  Reported: the onset (first run-up window whirling), the turn,
the settled amplitude (the top window's, when the last three windows before the turn agree to 5 %),
the collapse (last coast-down window whirling) and the band onset - collapse.  For the frictional foil
the energy-equivalent viscous damping of the whole foil over the window before the turn,
``D_eq = sum_j P_j / sum_j (omega^2 q_hat_j^2 / 2)`` (P_j the mean power of column j's slider, oint F dS per
time; q_hat_j half the peak-to-peak of Q_j; omega the whirl frequency from the zero crossings of xi): the
same average gives D_W exactly for the viscoelastic foil under a sinusoidal Q.  The collapse after a turn
at ``TURN_AMPLITUDE`` is a recovery speed of this protocol (amplitude and rate), not a fold of cycles.
Writes ``results/friction_mu_sweep/sweep.csv``, ``summary.json``, ``mu_sweep.png``.

    python -m gfb_experiments.friction_mu_sweep [--grid 79x7] [--rate 2e-5] [--foil-stiffness 2.337]
        [--stick-stiffness 2.337] [--mu 0,0.1,...] [--dw 1,2,...] [--tol 1e-6]

On 21x5 and 31x7 every whirl of either foil (K_W = 1 and 2.337, D_W up to 8) grows to touchdown: the
paper grid is the default (one frictional run 0.5-34 s at rtol 1e-6).
"""

from __future__ import annotations

import csv
import math
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from gfb_env import jsonio  # noqa: E402
from gfb_env.analysis.runup import WHIRL_THRESHOLD  # noqa: E402
from gfb_env.analysis.stability import critical_bearing_number, spinup_equilibrium  # noqa: E402
from gfb_env.integrator import TrapezoidalIntegrator  # noqa: E402
from gfb_env.model import GFBModel, Structure  # noqa: E402
from gfb_env.scripting import (  # noqa: E402
    OneLineParser,
    check_output_dir,
    float_list,
    grid_type,
    positive,
)

#: Table 1's foil (Walowit-Anno K_W) and K_T = K_W (the shipped table1_frictional bearing)
KW, KT = 2.337, 2.337
#: identified bump-foil coefficients are about 0.05-0.2 (docs/analysis.md); 0, 0.02, 0.3-1e6: the limits
MUS = (0.0, 0.02, 0.05, 0.08, 0.1, 0.15, 0.2, 0.3, 0.5, 1e6)
DWS = (0.25, 0.5, 1.0, 2.0, 4.0, 6.69, 12.0)  # 6.69: Fig. 5's optimum D_W at Table 1's K_W
RATE = 2e-5  # dLambda/dtau: ~5000 tau per 0.1 of Lambda (the whirl's e-folding near onset is ~500 tau)
WINDOW = 64.0  # about two whirl periods
#: the integrator's rtol = atol: the slow growth of the seed over thousands of tau is not converged at the
#: integrator's default 3e-4 for the frictional foil (onsets off by up to 0.01); 1e-6 agrees with 1e-7 to
#: one window (docs/analysis.md)
TOL = 1e-6
TURN_AMPLITUDE = 0.3
BELOW, ABOVE, BOTTOM = 0.03, 0.1, 0.08
KICK = 1e-3
#: the spin-up (and the Lambda_c search) start here, as ``gfb critical``'s (Lambda_c depends on it)
START = 0.1
DT = 0.1  # sampling of the frictional foil's loops
FILES = ("sweep.csv", "summary.json", "mu_sweep.png")


def _amplitude(tau: np.ndarray, x: np.ndarray) -> float:
    trend = np.polyval(np.polyfit(tau, x, 1), tau)
    return 0.5 * float(np.ptp(x - trend))


def _omega(tau: np.ndarray, x: np.ndarray) -> float:
    xm = x - np.polyval(np.polyfit(tau, x, 1), tau)
    up = np.flatnonzero((xm[:-1] < 0) & (xm[1:] >= 0))
    return 2 * math.pi * (up.size - 1) / (tau[up[-1]] - tau[up[0]]) if up.size >= 2 else math.nan


def equivalent_damping(model: GFBModel, tr) -> float:
    """The whole foil's energy-equivalent viscous damping over one recorded window (frictional)."""
    L = model.layout
    states = np.zeros((len(tr), L.size))
    states[:, : L.rotor_offset] = tr.probes
    states[:, L.rotor_slice] = np.column_stack([tr.xi, tr.eta, tr.xi_dot, tr.eta_dot])
    Q = np.array([model.foil_deflection(x) for x in states])
    F = np.array([model.friction_force(x) for x in states])
    S = states[:, L.foil_slice]
    power = (0.5 * (F[1:] + F[:-1]) * np.diff(S, axis=0)).sum(axis=0) / (tr.tau[-1] - tr.tau[0])
    q_hat = 0.5 * np.ptp(Q, axis=0)
    w = _omega(tr.tau, tr.xi)
    return float(power.sum() / (0.5 * w**2 * (q_hat**2).sum()))


def ramp_run(
    model: GFBModel, foil_damping: float, lam_c: float, rate: float, tol: float | None = None
) -> dict:
    """One run-up, turn and coast-down (see the module docstring); ``tol``: the integrator's rtol = atol
    (None: its default)."""
    L = model.layout
    frictional = model.structure is Structure.FRICTIONAL
    lo, top, bottom = lam_c - BELOW, lam_c + ABOVE, lam_c - BOTTOM
    s = spinup_equilibrium(model, lo, start=START)
    s = L.with_rotor(s, *L.rotor(s)[:2], KICK, 0.0)
    overrides = {} if tol is None else {"rtol": tol, "atol": tol}
    it = TrapezoidalIntegrator(model, s, lo, foil_damping, touchdown_film_thickness=0.01, **overrides)
    idx = np.arange(L.rotor_offset) if frictional else None
    lam, leg, rows = lo, 0, []
    out = {"status": "done", "turn": None, "turn_reason": None, "touchdown": None, "D_eq_at_turn": None}
    t0, steps = time.perf_counter(), 0
    while True:
        lam_next = min(lam + rate * WINDOW, top) if leg == 0 else max(lam - rate * WINDOW, bottom)
        res = it.advance(
            it.tau + WINDOW,
            bearing_number=lam_next,
            record_interval=DT if frictional else 0.5,
            record_indices=idx,
            raise_on_failure=False,
        )
        steps += res.steps
        tr = res.trajectory
        if res.status != "done":
            out["status"] = res.status
            if res.status == "touchdown":
                out["touchdown"] = {"bearing_number": float(it.bearing_number), "leg": leg}
            break
        amp = _amplitude(tr.tau, tr.xi)
        rows.append(
            {
                "leg": leg,
                "bearing_number": 0.5 * (lam + lam_next),
                "amplitude": amp,
                "max_eccentricity": float(np.hypot(tr.xi, tr.eta).max()),
            }
        )
        lam = lam_next
        if leg == 0 and (amp > TURN_AMPLITUDE or lam >= top):
            out["turn"], out["turn_reason"] = lam, ("amplitude" if amp > TURN_AMPLITUDE else "top")
            if frictional and amp > WHIRL_THRESHOLD:
                out["D_eq_at_turn"] = equivalent_damping(model, tr)
            leg = 1
        elif leg == 1 and lam <= bottom:
            break
    up = [r for r in rows if r["leg"] == 0]
    down = [r for r in rows if r["leg"] == 1]
    whirl_up = [r for r in up if r["amplitude"] > WHIRL_THRESHOLD]
    whirl_down = [r for r in down if r["amplitude"] > WHIRL_THRESHOLD]
    out["onset"] = whirl_up[0]["bearing_number"] if whirl_up else None
    out["collapse"] = (
        whirl_down[-1]["bearing_number"] if whirl_down and down[-1] is not whirl_down[-1] else None
    )
    out["max_amplitude_run_up"] = max(r["amplitude"] for r in up) if up else None
    last = [r["amplitude"] for r in up[-3:]]
    settled = (
        out["turn_reason"] == "top" and len(last) == 3 and min(last) > WHIRL_THRESHOLD
        and (max(last) - min(last)) < 0.05 * max(last)
    )  # fmt: skip
    out["settled_amplitude"] = last[-1] if settled else None
    out["settled_max_eccentricity"] = up[-1]["max_eccentricity"] if settled else None
    out["band"] = (
        out["onset"] - out["collapse"] if out["onset"] is not None and out["collapse"] is not None else None
    )
    out["steps"], out["wall_time_s"], out["windows"] = steps, time.perf_counter() - t0, rows
    out.update(coast_down_whirl(out, lam_c))
    return out


def coast_down_whirl(run: dict, lam_c: float) -> dict:
    """The whirl on the slow coast-down as it passes ``Lambda_c`` (the window nearest to it, while still
    whirling): its amplitude and max eps, the quasi-static large cycle there (None when the run touched
    down first or the whirl had collapsed)."""
    down = [w for w in run["windows"] if w["leg"] == 1 and w["amplitude"] > WHIRL_THRESHOLD]
    if not down:
        return {"coast_down_amplitude_at_lambda_c": None, "coast_down_max_eccentricity_at_lambda_c": None}
    w = min(down, key=lambda x: abs(x["bearing_number"] - lam_c))
    if abs(w["bearing_number"] - lam_c) > RATE * WINDOW:
        return {"coast_down_amplitude_at_lambda_c": None, "coast_down_max_eccentricity_at_lambda_c": None}
    return {
        "coast_down_amplitude_at_lambda_c": w["amplitude"],
        "coast_down_max_eccentricity_at_lambda_c": w["max_eccentricity"],
    }


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=lambda x: str(grid_type(x)), default="79x7")
    ap.add_argument("--rate", type=positive("--rate"), default=RATE)
    ap.add_argument("--foil-stiffness", type=positive("--foil-stiffness"), default=KW)
    ap.add_argument("--stick-stiffness", type=positive("--stick-stiffness"), default=KT)
    ap.add_argument("--mu", default=None, help="comma-separated mu_C >= 0 (default: MUS; none: no runs)")
    ap.add_argument("--dw", default=None, help="comma-separated D_W > 0 (default: DWS; none: no runs)")
    ap.add_argument(
        "--tol",
        type=positive("--tol"),
        default=TOL,
        help=f"the integrator's rtol = atol (default {TOL:g}: converged against 1e-7, docs/analysis.md)",
    )
    ap.add_argument("--out", default="results/friction_mu_sweep")
    a = ap.parse_args(argv)
    try:
        out = check_output_dir(a.out, files=FILES)
        mus = (
            MUS if a.mu is None else () if a.mu == "none" else tuple(float_list(a.mu, "--mu", positive=False))
        )
        if any(mu < 0 for mu in mus):
            raise ValueError(f"--mu must be >= 0, got {a.mu!r}")
        dws = DWS if a.dw is None else () if a.dw == "none" else tuple(float_list(a.dw, "--dw"))
    except ValueError as exc:
        ap.error(str(exc))
    runs = []
    kw, kt = a.foil_stiffness, a.stick_stiffness
    cases = [("frictional", mu) for mu in mus] + [("viscoelastic", dw) for dw in dws]
    for structure, par in cases:
        if structure == "frictional":
            m = GFBModel(
                structure, grid=a.grid, foil_stiffness=kw, stick_stiffness=kt, friction_coefficient=par
            )
            dw = 1.0
        else:
            m, dw = GFBModel(structure, grid=a.grid, foil_stiffness=kw), par
        lc = critical_bearing_number(m, dw, bearing_range=(START, 3.0)).critical_bearing_number
        r = ramp_run(m, dw, lc, a.rate, a.tol)
        r.update({"structure": structure, "parameter": par, "lambda_c": lc})
        runs.append(r)
        print(
            f"{structure:12s} {par:8.3g} Lc={lc:.5f} onset={r['onset']} turn={r['turn']} "
            f"({r['turn_reason']}) settled={r['settled_amplitude']} collapse={r['collapse']} "
            f"band={r['band']} touchdown={r['touchdown']} D_eq={r['D_eq_at_turn']} "
            f"{r['steps']} steps {r['wall_time_s']:.1f} s",
            flush=True,
        )
    summary = {
        "grid": a.grid,
        "K_W": kw,
        "K_T": kt,
        "slip_viscosity": 1e-3,
        "rate": a.rate,
        "tol": a.tol,
        "window": WINDOW,
        "turn_amplitude": TURN_AMPLITUDE,
        "whirl_threshold": WHIRL_THRESHOLD,
        "kick": KICK,
        "runs": runs,
    }
    write(summary, out)
    return 0


def write(summary: dict, out: Path) -> None:
    """``sweep.csv``, ``summary.json`` and ``mu_sweep.png`` of a sweep."""
    out.mkdir(parents=True, exist_ok=True)
    runs = summary["runs"]
    keys = [
        "structure", "parameter", "lambda_c", "onset", "turn", "turn_reason", "max_amplitude_run_up",
        "settled_amplitude", "settled_max_eccentricity", "coast_down_amplitude_at_lambda_c",
        "coast_down_max_eccentricity_at_lambda_c", "collapse", "band", "status", "D_eq_at_turn",
        "steps", "wall_time_s",
    ]  # fmt: skip
    with open(out / "sweep.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*keys, "touchdown_bearing_number", "touchdown_leg"])
        for r in runs:
            td = r["touchdown"] or {}
            w.writerow([r[k] for k in keys] + [td.get("bearing_number"), td.get("leg")])
    jsonio.write_json(out / "summary.json", summary)
    plot(runs, out / "mu_sweep.png", summary["grid"], summary["K_W"], summary["K_T"])
    print(f"wrote {out}/{{{','.join(FILES)}}}")


def plot(runs: list[dict], path: Path, grid: str, kw: float, kt: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    for col, (structure, xlabel) in enumerate((("frictional", "mu_C"), ("viscoelastic", "D_W"))):
        rs = [r for r in runs if r["structure"] == structure]
        # mu_C = 1e6 (the stuck foil) is drawn at x = 1
        x = np.array([min(r["parameter"], 1.0) if col == 0 else r["parameter"] for r in rs])

        def arr(k, rs=rs):
            return np.array([np.nan if r[k] is None else r[k] for r in rs], dtype=float)

        a0 = ax[0, col]
        a0.plot(x, arr("lambda_c"), "k.-", label="linear Lambda_c")
        a0.plot(x, arr("onset"), "r^-", label="whirl onset (run-up)")
        a0.plot(x, arr("collapse"), "bv-", label="whirl collapse (coast-down)")
        td = np.array([np.nan if r["touchdown"] is None else r["touchdown"]["bearing_number"] for r in rs])
        a0.plot(x, td, "mx", ms=9, label="touchdown (coast-down, no collapse)")
        a0.set_ylabel("Lambda")
        a0.set_title(f"{structure}, K_W={kw:g}" + (f", K_T={kt:g}" if col == 0 else "") + f", {grid}")
        a0.legend(fontsize=7)
        a1 = ax[1, col]
        a1.plot(x, arr("coast_down_amplitude_at_lambda_c"), "bD-", ms=7, label="coast-down whirl at Lambda_c")
        touched = np.isfinite(td)
        a1.plot(x[touched], np.full(touched.sum(), 1.2), "mx", ms=9, label="touched down: no settled whirl")
        a1.set_ylim(0.0, 1.3)
        a1.set_ylabel("whirl amplitude, half peak-to-peak xi / C")
        a1.set_xlabel(xlabel + (" (1e6 drawn at 1; band: identified bump foils)" if col == 0 else ""))
        if col == 0:
            a2 = a1.twinx()
            a2.plot(x, arr("D_eq_at_turn"), "gs:", label="D_eq of the foil at amplitude 0.3")
            a2.set_ylabel("energy-equivalent D_eq", color="g")
            a2.legend(fontsize=7, loc="lower right")
        a1.legend(fontsize=7, loc="lower left")
        for a in (a0, a1):
            if col == 0:
                a.set_xscale("symlog", linthresh=0.05)
                a.axvspan(0.05, 0.2, color="y", alpha=0.15)
            elif len(x):  # a sweep without viscoelastic runs (--dw none) has nothing to log-scale
                a.set_xscale("log")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
