"""Why the frictional foil's Lambda_c is not monotone in mu_C (issue 22).

For each mu_C on a grid: ``critical_bearing_number`` of the frictional foil (its quasi-static scan
history) and, at the equilibrium it returns at Lambda_c, each column's state: stuck (|F| < F_c, the
slider dropped from the linearisation: the column is the stuck foil K_W + K_T) or on its Coulomb
limit (kept on the slip branch).  On the slip branch F = sigma mu_C |Pbar - 1| (sigma = sign F), so with
the force balance K_W Q + F = -(Pbar - 1) the column's tangent stiffness -d(Pbar - 1)/dQ is
``K_W / (1 + sigma mu_C sign(Pbar - 1))``: ``K_W / (1 - mu_C)`` for a column loaded from S = 0 (the friction
resists the load), which reaches the stuck K_W + K_T at mu_C = K_T / (K_W + K_T).  Reported per column
(with its angle and load sign) and summarised; also Lambda_c with the scan step 0.01, with every slider
held where the scan left it, and along a monotone spin-up (:func:`spinup_critical`).  Transient checks:
the rotor kicked slightly from the scan's equilibrium at Lambda_c -/+ delta (one mu_C), and from the
spin-up's equilibria (:func:`spinup_transient`).  See docs/analysis.md, "What sets Lambda_c".
Writes ``results/friction_onset/summary.json`` and ``onset.png``.

    python -m gfb_experiments.friction_onset [--grid 21x5] [--transient-mu 0.12] [--delta 0.005]
"""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

from gfb_env import jsonio  # noqa: E402
from gfb_env.analysis.stability import critical_bearing_number, linear_stability  # noqa: E402
from gfb_env.equilibrium import find_equilibrium  # noqa: E402
from gfb_env.integrator import TrapezoidalIntegrator  # noqa: E402
from gfb_env.model import GFBModel  # noqa: E402
from gfb_env.scripting import (  # noqa: E402
    OneLineParser,
    check_output_dir,
    grid_type,
    non_negative,
    positive,
)

KW, KT = 1.0, 0.5
FINE_SCAN_STEP = 0.01  # the scan's load stages (critical_bearing_number's default is 0.05)
#: spin-up transients: mu_C = 0 (control), 0.06 (the highest Lambda_c, 15 sliders on their limit), 0.1, 0.2
SPINUP_TRANSIENT_MUS = (0.0, 0.06, 0.1, 0.2)
SPINUP_STEP = 0.002  # monotone spin-up (same Lambda_c to 1e-4 at 0.004 and 0.001)
MUS = (0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1, 0.12, 0.14, 0.16, 0.18, 0.2,
       0.22, 0.24, 0.26, 0.28, 0.3, 0.32, 0.34, 0.4, 0.5)  # fmt: skip


def column_states(model: GFBModel, s: np.ndarray) -> dict:
    """Per column: stuck or slip (sign sigma of F), load sign, tangent stiffness the linearisation sees."""
    mu = model.friction_coefficient
    p = model.axial_mean_pressure(s) - 1.0
    F = model.friction_force(s)
    keep = model.linearised_states(s, 1.0)
    foil = np.arange(model.layout.n_pressure, model.layout.rotor_offset)
    stuck = ~np.isin(foil, keep)
    sigma = np.sign(F)
    k_slip = KW / (1.0 + sigma * mu * np.sign(p))
    k_eff = np.where(stuck, KW + model.stick_stiffness, k_slip)
    return {
        "phi": model.grid.phi.tolist(),
        "load": p.tolist(),
        "stuck": stuck.tolist(),
        "sigma_sign_load": (sigma * np.sign(p)).astype(int).tolist(),
        "k_eff": k_eff.tolist(),
    }


def frictional(mu: float, grid: str) -> GFBModel:
    return GFBModel("frictional", grid=grid, foil_stiffness=KW, stick_stiffness=KT, friction_coefficient=mu)


def frozen_slider_critical(state: np.ndarray, lam_c: float, grid: str, half_width: float = 0.02) -> float:
    """Lambda_c of the foil with every slider held where ``state`` has it (mu_C = 1e6: the stuck foil
    K_W + K_T with the slider offsets S as a built-in deflection K_T S / (K_W + K_T))."""
    held = frictional(1e6, grid)
    return float(
        brentq(
            lambda lam: linear_stability(held, lam, guess=state).growth_rate,
            lam_c - half_width,
            lam_c + half_width,
            xtol=1e-7,
        )
    )


def spinup_critical(model: GFBModel, step: float = SPINUP_STEP, start: float = 0.1, stop: float = 1.0):
    """Lambda_c along a monotone quasi-static spin-up: each equilibrium warm-started only from the previous
    (smaller) Lambda, so every slider sees the load path of a slow run-up; the crossing is interpolated
    linearly in the growth rate between two steps; sliders on their limit on the slip branch.
    Returns (Lambda_c, sliders held, state above)."""
    s, prev = None, None
    for lam in np.arange(start, stop, step):
        st = linear_stability(model, float(lam), guess=s, sliders_on_limit="slip")
        s, g = st.state, st.growth_rate
        if prev is not None and prev[1] < 0 <= g:
            lc = prev[0] + (lam - prev[0]) * (-prev[1]) / (g - prev[1])
            return float(lc), model.layout.size - len(model.linearised_states(s, 1.0)), s
        prev = (float(lam), g)
    raise RuntimeError(f"no crossing on the spin-up to Lambda = {stop}")


def onset(mu: float, grid: str, scan_step: float = 0.05) -> dict:
    m = frictional(mu, grid)
    cp = critical_bearing_number(
        m, scan_step=scan_step, bearing_range=(0.1, 1.0), history="scan", sliders_on_limit="slip"
    )
    cols = column_states(m, cp.state)
    st = np.array(cols["stuck"])
    load = np.array(cols["load"])
    return {
        "mu": mu,
        "lambda_c": cp.critical_bearing_number,
        "n_stuck": int(st.sum()),
        "n_slip": int((~st).sum()),
        "n_stuck_loaded": int((st & (load > 0)).sum()),
        "n_stuck_unloaded": int((st & (load <= 0)).sum()),
        "pattern": "".join("s" if a else "-" for a in st),
        "k_eff_mean": float(np.mean(cols["k_eff"])),
        "eccentricity": cp.eccentricity_at_onset,
        "slider_offset_max": float(np.abs(m.layout.foil_state(cp.state)).max()),
        "columns": cols,
        "_state": cp.state,
        "_model": m,
    }


def transient(r: dict, delta: float, duration: float = 600.0, kick: float = 1e-3) -> dict:
    """Amplitude ratio late/early of a small rotor kick from the scan's equilibrium at Lambda_c -/+ delta."""
    m = r["_model"]
    L = m.layout
    out = {}
    for lam in (r["lambda_c"] - delta, r["lambda_c"] + delta):
        s = find_equilibrium(m, lam, guess=r["_state"])
        same = bool(np.array_equal(column_states(m, s)["stuck"], r["columns"]["stuck"]))
        it = TrapezoidalIntegrator(m, L.with_rotor(s, *(L.rotor(s)[:2] + [kick, 0.0])), lam)
        x = it.advance(duration, record_interval=1.0).trajectory.xi - L.rotor(s)[0]
        ratio = float(np.abs(x[-100:]).max() / np.abs(x[50:150]).max())
        out[f"{lam:.6f}"] = {"ratio_late_early": ratio, "same_stuck_pattern": same}
    return out


def spinup_transient(
    mu: float, grid: str, offsets=(-0.02, -0.01, -0.005, 0.005), kick: float = 1e-4, duration: float = 600.0
) -> dict:
    """Small rotor kicks from the spin-up's equilibria near its Lambda_c (each reached by the same monotone
    march): amplitude ratio late/early (max |xi - xi_0| and peak-to-peak) and the late mean drift."""
    m = frictional(mu, grid)
    L = m.layout
    lc, _, _ = spinup_critical(m)
    out = {"lambda_c_spinup": lc, "kick": kick, "runs": {}}
    for d in offsets:
        lam = lc + d
        s = None
        for x in [*np.arange(0.1, lam, SPINUP_STEP), lam]:
            s = find_equilibrium(m, float(x), guess=s)
        it = TrapezoidalIntegrator(m, L.with_rotor(s, *(L.rotor(s)[:2] + [kick, 0.0])), lam)
        x = it.advance(duration, record_interval=1.0).trajectory.xi - L.rotor(s)[0]
        early, late = x[50:150], x[-100:]
        out["runs"][f"{d:+.3f}"] = {
            "bearing_number": float(lam),
            "ratio_late_early": float(np.abs(late).max() / np.abs(early).max()),
            "ratio_peak_to_peak": float(np.ptp(late) / np.ptp(early)),
            "late_mean_drift": float(late.mean()),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=lambda x: str(grid_type(x)), default="21x5")
    ap.add_argument("--transient-mu", type=non_negative("--transient-mu"), default=0.12)
    ap.add_argument("--delta", type=positive("--delta"), default=0.005)
    ap.add_argument("--no-transient", action="store_true")
    ap.add_argument("--out", default="results/friction_onset")
    a = ap.parse_args(argv)
    try:
        out = check_output_dir(a.out)
    except ValueError as exc:
        ap.error(str(exc))
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for mu in MUS:
        r = onset(mu, a.grid)
        fine = onset(mu, a.grid, scan_step=FINE_SCAN_STEP)
        r["lambda_c_fine_scan"] = fine["lambda_c"]
        r["n_stuck_fine_scan"] = fine["n_stuck"]
        m_up = frictional(mu, a.grid)
        lc_up, held_up, s_up = spinup_critical(m_up)
        r["lambda_c_spinup"], r["n_stuck_spinup"] = lc_up, int(held_up)
        r["pattern_spinup"] = "".join("s" if x else "-" for x in column_states(m_up, s_up)["stuck"])
        r["lambda_c_frozen_sliders"] = frozen_slider_critical(r["_state"], r["lambda_c"], a.grid)
        rows.append(r)
        print(f"mu={mu:5.3f} Lc={r['lambda_c']:.6f} stuck={r['n_stuck']:2d} "
              f"({r['n_stuck_loaded']} loaded) {r['pattern']} k_mean={r['k_eff_mean']:.4f} "
              f"frozen={r['lambda_c_frozen_sliders']:.6f} Smax={r['slider_offset_max']:.4f} "
              f"fine={r['lambda_c_fine_scan']:.6f} ({r['n_stuck_fine_scan']} stuck) "
              f"spinup={r['lambda_c_spinup']:.6f} {r['pattern_spinup']}", flush=True)  # fmt: skip
    summary = {
        "grid": a.grid,
        "K_W": KW,
        "K_T": KT,
        "rows": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows],
    }
    if not a.no_transient:
        r = min(rows, key=lambda x: abs(x["mu"] - a.transient_mu))
        summary["transient"] = {"mu": r["mu"], "delta": a.delta, "runs": transient(r, a.delta)}
        print(summary["transient"], flush=True)
        summary["transient_spinup"] = {}
        for mu in SPINUP_TRANSIENT_MUS:
            summary["transient_spinup"][f"{mu:g}"] = spinup_transient(mu, a.grid)
            print(mu, summary["transient_spinup"][f"{mu:g}"], flush=True)
    jsonio.write_json(out / "summary.json", summary)
    plot(rows, out / "onset.png")
    return 0


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mu = [r["mu"] for r in rows]
    fig, ax = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    ax[0].plot(mu, [r["lambda_c"] for r in rows], "o-", label="scan step 0.05 (default)")
    ax[0].plot(mu, [r["lambda_c_fine_scan"] for r in rows], "x--", label=f"scan step {FINE_SCAN_STEP}")
    ax[0].plot(mu, [r["lambda_c_spinup"] for r in rows], "k^-", label=f"monotone spin-up, step {SPINUP_STEP}")
    ax[0].plot(mu, [r["lambda_c_frozen_sliders"] for r in rows], "+", ms=10, label="sliders held at S")
    ax[0].axhline(0.565238, color="k", lw=0.8, ls=":", label="stuck foil K_W+K_T")
    ax[0].axhline(0.574771, color="gray", lw=0.8, ls=":", label="free foil K_W")
    ax[0].legend(fontsize=7)
    ax[0].set_ylabel("Lambda_c")
    ax[1].plot(mu, [r["n_stuck"] for r in rows], "s-", label="stuck columns (of 20), default scan")
    ax[1].plot(mu, [r["n_stuck_fine_scan"] for r in rows], "x--", label=f"stuck, scan step {FINE_SCAN_STEP}")
    ax[1].plot(
        mu, [r["n_stuck_loaded"] for r in rows], "^-", label="stuck and loaded (Pbar > 1), default scan"
    )
    ax[1].plot(mu, [r["n_stuck_spinup"] for r in rows], "k^-", label="stuck, monotone spin-up")
    ax[1].legend(fontsize=7)
    ax[1].set_ylabel("columns")
    ax[2].plot(mu, [r["k_eff_mean"] for r in rows], "o-", label="mean tangent stiffness, default scan")
    mm = np.linspace(0, 1 / 3, 50)
    ax[2].plot(mm, KW / (1 - mm), "--", label="K_W/(1-mu_C)")
    ax[2].legend()
    ax[2].set_ylabel("k_eff")
    ax[2].set_xlabel("mu_C")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
