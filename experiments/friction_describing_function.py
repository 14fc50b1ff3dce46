"""Describing-function check of the frictional foil against the paper's Eq. 15 (issue 22).

The paper estimates dry friction as an equivalent viscous damping by an energy balance (Eq. 15): a
Coulomb contact of normal load N moved as ``q_hat sin(omega t)`` dissipates ``4 mu_C N q_hat`` per cycle,
a damper ``pi D omega q_hat^2``, so ``D_W ~ (4/pi) mu_C N / (q_hat omega)``.  Here the whirl of the
coupled model is run (from the equilibrium with a rotor kick, above the critical bearing number) and
over one whirl period late in the run each column's

* slider dissipation ``E = oint F dS`` (F = K_T (Q - S), the energy the Coulomb slider takes;
  ``oint F dQ`` differs by the change of the stored spring energy, reported too),
* amplitude ``q_hat`` (half the peak-to-peak of Q) and mean normal load ``N = mean |Pbar - 1|``,
* equivalent damping ``D_eq = E / (pi omega q_hat^2)``,

is compared with Eq. 15's ``D_15 = 4 mu_C N / (pi q_hat omega)`` and with the Jenkins element's own
describing function ``D_J = D_15 (1 - F_c / (K_T q_hat))`` (zero while ``q_hat < F_c / K_T``), F_c = mu_C N.
Writes ``results/friction_describing_function/summary.json`` and ``columns.png``.

    python -m gfb_experiments.friction_describing_function [--grid 21x5] [--mu 0.1] [--duration 400]
        [--slip-viscosity ETA]
"""

from __future__ import annotations

import math
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from gfb_env import jsonio  # noqa: E402
from gfb_env.equilibrium import find_equilibrium  # noqa: E402
from gfb_env.integrator import TrapezoidalIntegrator  # noqa: E402
from gfb_env.model import GFBModel  # noqa: E402
from gfb_env.scripting import OneLineParser, check_output_dir  # noqa: E402

DT = 0.02  # sampling interval of the loops


def whirl_period(tau: np.ndarray, x: np.ndarray) -> tuple[float, float, float]:
    """The last two full periods of ``x`` (its last three upward mean crossings): (t0, t1, t2)."""
    xm = x - x.mean()
    up = np.flatnonzero((xm[:-1] < 0) & (xm[1:] >= 0))
    if up.size < 4:
        raise RuntimeError("fewer than two whirl periods recorded")
    t = tau[up] - xm[up] * (tau[up + 1] - tau[up]) / (xm[up + 1] - xm[up])
    return float(t[-3]), float(t[-2]), float(t[-1])


def describing_function(model: GFBModel, bearing_number: float, duration: float, kick: float = 0.01) -> dict:
    """Run the kicked whirl and evaluate every column's loop over the last whirl period."""
    L = model.layout
    s = find_equilibrium(model, bearing_number)
    it = TrapezoidalIntegrator(model, L.with_rotor(s, *L.rotor(s)[:2], kick, 0.0), bearing_number)
    idx = np.arange(L.rotor_offset)  # pressures and sliders
    res = it.advance(duration, record_interval=DT, record_indices=idx)
    if res.status != "done":
        raise RuntimeError(f"whirl run ended with {res.status} at tau = {it.tau:.1f}")
    tr = res.trajectory
    tm, t0, t1 = whirl_period(tr.tau, tr.xi)
    ecc = np.hypot(tr.xi, tr.eta)
    sel = (tr.tau >= t0) & (tr.tau <= t1)
    # a settled whirl has the same orbit in consecutive periods; this one may still grow
    growth = float(ecc[sel].max() / ecc[(tr.tau >= tm) & (tr.tau <= t0)].max())
    states = np.zeros((int(sel.sum()), L.size))
    states[:, idx] = tr.probes[sel]
    states[:, L.rotor_slice] = np.column_stack([tr.xi, tr.eta, tr.xi_dot, tr.eta_dot])[sel]
    Q = np.array([model.foil_deflection(x) for x in states])
    F = np.array([model.friction_force(x) for x in states])
    N = np.abs(np.array([model.axial_mean_pressure(x) for x in states]) - 1.0)
    S = states[:, L.foil_slice]
    omega = 2 * math.pi / (t1 - t0)
    dS, dQ = np.diff(S, axis=0), np.diff(Q, axis=0)
    Fm = 0.5 * (F[1:] + F[:-1])
    e_slider = (Fm * dS).sum(axis=0)
    e_loop = (Fm * dQ).sum(axis=0)
    q_hat = 0.5 * (Q.max(axis=0) - Q.min(axis=0))
    n_mean = N.mean(axis=0)
    fc = model.friction_coefficient * n_mean
    d_eq = e_slider / (math.pi * omega * q_hat**2)
    d_15 = 4 * fc / (math.pi * q_hat * omega)
    d_j = d_15 * np.clip(1 - fc / (model.stick_stiffness * q_hat), 0.0, None)
    return {
        "period": [t0, t1],
        "omega": omega,
        "whirl_ratio": omega / bearing_number,
        "max_eccentricity": float(ecc[sel].max()),
        "eccentricity_growth_per_period": growth,
        "q_hat": q_hat,
        "normal_load": n_mean,
        "slider_energy": e_slider,
        "loop_energy": e_loop,
        "D_eq": d_eq,
        "D_eq15": d_15,
        "D_jenkins": d_j,
        "loops": (Q, F),
    }


def main(argv: list[str] | None = None) -> dict:
    p = OneLineParser(description=__doc__.splitlines()[0])
    p.add_argument("--grid", default="21x5")
    p.add_argument("--foil-stiffness", type=float, default=1.0)
    p.add_argument("--stick-stiffness", type=float, default=0.5)
    p.add_argument("--mu", type=float, default=0.1)
    p.add_argument("--bearing-number", type=float, default=0.6)
    p.add_argument("--duration", type=float, default=400.0)
    p.add_argument("--slip-viscosity", type=float, default=None)
    p.add_argument("--out", default="results/friction_describing_function")
    a = p.parse_args(argv)
    try:
        out = check_output_dir(a.out, files=("summary.json", "columns.png"))
        model = GFBModel(
            "frictional",
            grid=a.grid,
            foil_stiffness=a.foil_stiffness,
            stick_stiffness=a.stick_stiffness,
            friction_coefficient=a.mu,
            slip_viscosity=a.slip_viscosity,
        )
    except ValueError as exc:
        p.error(str(exc))
    r = describing_function(model, a.bearing_number, a.duration)
    out.mkdir(parents=True, exist_ok=True)
    Q, F = r.pop("loops")
    slipping = r["slider_energy"] > 1e-3 * r["slider_energy"].max()
    ratio15 = r["D_eq"][slipping] / r["D_eq15"][slipping]
    jenkins_slips = r["D_jenkins"] > 0
    ratio_j = r["D_eq"][slipping & jenkins_slips] / r["D_jenkins"][slipping & jenkins_slips]
    # N varies over the cycle, so F_c = mu_C N dips and a column may slip below q_hat = F_c / K_T
    summary = {
        "grid": a.grid,
        "foil_stiffness": a.foil_stiffness,
        "stick_stiffness": a.stick_stiffness,
        "friction_coefficient": a.mu,
        "slip_viscosity": model.slip_viscosity,
        "bearing_number": a.bearing_number,
        "duration": a.duration,
        **{k: v for k, v in r.items() if not isinstance(v, np.ndarray)},
        "columns": {k: v.tolist() for k, v in r.items() if isinstance(v, np.ndarray)},
        "slipping_columns": int(slipping.sum()),
        "slipping_below_the_constant_load_threshold": int((slipping & ~jenkins_slips).sum()),
        "D_eq_over_D_eq15": {
            "min": float(ratio15.min()),
            "median": float(np.median(ratio15)),
            "max": float(ratio15.max()),
        },
        "D_eq_over_D_jenkins": {
            "min": float(ratio_j.min()),
            "median": float(np.median(ratio_j)),
            "max": float(ratio_j.max()),
        },
        "total_slider_energy_per_cycle": float(r["slider_energy"].sum()),
    }
    jsonio.write_json(out / "summary.json", summary)
    _plot(out / "columns.png", r, Q, F, summary)
    print(
        f"whirl omega/Lambda {r['whirl_ratio']:.3f}, max eps {r['max_eccentricity']:.3f} "
        f"(x{r['eccentricity_growth_per_period']:.3f} per period), "
        f"{int(slipping.sum())}/{slipping.size} columns slip "
        f"({summary['slipping_below_the_constant_load_threshold']} below q_hat = F_c/K_T); D_eq/D_15 median "
        f"{summary['D_eq_over_D_eq15']['median']:.3f} [{ratio15.min():.3f}, {ratio15.max():.3f}], "
        f"D_eq/D_Jenkins median {summary['D_eq_over_D_jenkins']['median']:.3f} "
        f"[{ratio_j.min():.3f}, {ratio_j.max():.3f}]"
    )
    return summary


def _plot(path: Path, r: dict, Q: np.ndarray, F: np.ndarray, summary: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    j = np.arange(r["D_eq"].size)
    a1.semilogy(j, r["D_eq"], "o", label="model: E_slider / (pi omega q^2)")
    a1.semilogy(j, r["D_eq15"], "x", label="Eq. 15: 4 mu N / (pi q omega)")
    a1.semilogy(
        j,
        np.where(r["D_jenkins"] > 0, r["D_jenkins"], np.nan),
        "+",
        label="Jenkins: Eq. 15 (1 - F_c/(K_T q))",
    )
    a1.set_xlabel("column j")
    a1.set_ylabel("equivalent damping D")
    a1.set_title(
        f"mu_C={summary['friction_coefficient']}, K_T={summary['stick_stiffness']}, "
        f"Lambda={summary['bearing_number']} ({summary['grid']})"
    )
    a1.legend(fontsize=8)
    for k in np.argsort(r["slider_energy"])[-3:]:
        a2.plot(Q[:, k], F[:, k], label=f"column {k}")
    a2.set_xlabel("foil deflection Q")
    a2.set_ylabel("friction force F = K_T (Q - S)")
    a2.set_title("loops of the three most dissipative columns")
    a2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
