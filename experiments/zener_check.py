"""Issue 19, the next task candidate checked before it is built: a foil whose loss depends on frequency.

docs/task_redesign.md ("Next candidate") proposes hiding the foil's loss *at the whirl frequency* behind a
relaxation time, so that the 1x vector a vibration monitor reads (the foil at the running frequency) no
longer tells where the whirl mode (~0.35x) loses stability.  The model for it already exists: the
frictional foil at ``mu_C = 0`` is the standard linear solid (Zener element) per column, the foundation
K_W in parallel with a Maxwell arm (stick stiffness K_T in series with the slider's viscosity eta; with
``F_c = 0`` the slider law ``eta S' = sign(F) max(|F| - F_c, 0)`` is the linear dashpot ``eta S' = F``).
Its complex stiffness ``K_W + K_T i w tau / (1 + i w tau)``, ``tau = eta / K_T``, is the paper's
viscoelastic foil ``K_W + i w D_W`` for ``K_T -> oo`` with ``D_W = eta`` (tested), and at a finite
``r = K_T / K_W`` the loss falls and the stiffness rises with ``w tau``.

The check, on the benchmark tasks' nominal plant (RunUp-v2's bearing, ``K_W = 0.50``, grid 31x7):

1. ``Lambda_best(r)`` and ``eta_opt(r)`` (the best stable speed over the damping and where it is): how far
   the hidden ``r`` moves the boundary;
2. the 1x response's sensitivity to ``ln r`` and to ``ln g`` (``eta = g x commanded``) along a run-up, and
   the Cramer-Rao bound on ``(ln g, ln r)`` from the 1x vectors of a probing run-up with the monitor's
   documented noise (docs/machine.md: 0.077 um pk-pk per step, i.e. 0.038 um per cos/sin coefficient; C =
   50 um) and the median drawn unbalance (U = 0.0077, the geometric mean of 0.003-0.02), the unbalance's
   magnitude and phase unknown (two nuisance parameters);
3. the bound carried to ``Lambda_c`` at the operating damping: whether the 1x alone pins the boundary to
   better than the 1-2 % margin the audit's rule leaves (issue 19).

Run: ``python -m gfb_experiments.zener_check [--out results/task_redesign/zener]`` (~2 min on one core).
Writes ``zener_check.json`` and ``zener_check.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from gfb_env.analysis.response import unbalance_response
from gfb_env.analysis.stability import critical_bearing_number
from gfb_env.envs._data import load_task_constants
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import GFBModel, Grid
from gfb_env.params import BearingParameters

#: the monitor's 1x noise per step, per cos/sin coefficient, zero-to-peak, in C (docs/machine.md: 0.077 um
#: pk-pk = 2 x 0.0385 um, C = 50 um)
ONE_X_SD = 0.0385 / 50.0
#: the median drawn unbalance (U = 0.003-0.02, log-uniform: docs/machine.md "Residual unbalance")
UNBALANCE = math.sqrt(0.003 * 0.02)
#: the stick-stiffness ratios r = K_T / K_W examined (oo: the viscoelastic foil)
RATIOS = (1.0, 2.0, 3.0, 5.0, 10.0, 30.0, math.inf)


def plant(grid: str = "31x7") -> tuple[BearingParameters, float, Grid]:
    c = load_task_constants()
    return BearingParameters(**c["bearing"]), float(c["foil_stiffness"]), Grid.parse(grid)


class ZenerPlant:
    """The nominal plant with a Zener foil of stick-stiffness ratio r (inf: the viscoelastic foil)."""

    def __init__(self, grid: str = "31x7"):
        self.bearing, self.fk, self.grid = plant(grid)
        self.ve = GFBModel("viscoelastic", self.grid, bearing=self.bearing, foil_stiffness=self.fk)
        self.kw = self.ve.foil_stiffness
        self._eq: dict[float, np.ndarray] = {}

    def model(self, eta: float, r: float) -> tuple[GFBModel, float]:
        """(model, foil_damping argument) for the foil's viscosity eta and ratio r."""
        if math.isinf(r):
            return self.ve, eta
        m = GFBModel(
            "frictional", self.grid, bearing=self.bearing, foil_stiffness=self.fk,
            friction_coefficient=0.0, stick_stiffness=r * self.kw, slip_viscosity=eta,
        )  # fmt: skip
        return m, 1.0

    def critical(self, eta: float, r: float) -> float:
        m, dw = self.model(eta, r)
        kw = {} if math.isinf(r) else {"history": "scan"}
        return critical_bearing_number(m, dw, bearing_range=(0.3, 1.5), **kw).critical_bearing_number

    def best(self, r: float) -> tuple[float, float]:
        """(Lambda_best, eta_opt): the highest Lambda_c over eta (golden section in ln eta)."""
        from scipy.optimize import minimize_scalar

        res = minimize_scalar(
            lambda le: -self.critical(math.exp(le), r), bounds=(math.log(0.3), math.log(30.0)),
            method="bounded", options={"xatol": 0.005},
        )  # fmt: skip
        return -float(res.fun), math.exp(float(res.x))

    def one_x(self, eta: float, r: float, lam: float) -> np.ndarray:
        """The 1x response per unit unbalance, (xi, eta) complex zero-to-peak in C."""
        m, dw = self.model(eta, r)
        key = (lam, math.isinf(r))
        if key not in self._eq:
            self._eq[key] = find_equilibrium(m, lam)  # the static state: neither eta nor K_T enters
        res = unbalance_response(m, lam, 1.0, foil_damping=dw, state=self._eq[key], stability=False)
        return np.array([res.xi, res.eta])


def sensitivities(p: ZenerPlant, eta: float, r: float, lam: float, h: float = 0.05) -> tuple:
    """(z, dz/dln g, dz/dln r) per unit unbalance by central differences in ln eta and ln r."""
    z = p.one_x(eta, r, lam)
    dg = (p.one_x(eta * math.exp(h), r, lam) - p.one_x(eta * math.exp(-h), r, lam)) / (2 * h)
    dr = (p.one_x(eta, r * math.exp(h), lam) - p.one_x(eta, r * math.exp(-h), lam)) / (2 * h)
    return z, dg, dr


def fisher(rows: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]], u: float, sd: float) -> np.ndarray:
    """Fisher information of (ln g, ln r, Re U, Im U) from ``n`` steps per row of the measured 1x vector
    ``U z + noise`` (each of the 4 real coefficients with sd ``sd``), at U real."""
    from gfb_experiments.identifiability_bound import fisher_information

    # d(U z) / d theta, complex 2-vectors
    return fisher_information([(n, [u * dg, u * dr, z, 1j * z]) for n, z, dg, dr in rows], sd)


def run(out: Path, r_true: tuple[float, ...] = (3.0, 10.0)) -> dict:
    t0 = time.time()
    p = ZenerPlant()
    # 0. the limit: the Zener foil with a stiff arm is the viscoelastic one (the check's own consistency)
    lim = {dw: (p.critical(dw, math.inf), p.critical(dw, 1e4)) for dw in (1.0, 2.24, 4.0)}
    # 1. the boundary against r
    best = {r: p.best(r) for r in RATIOS}
    curves = {}
    etas = np.geomspace(0.3, 20.0, 13)
    for r in (2.0, 5.0, 10.0, 30.0, math.inf):
        curves[r] = [p.critical(float(e), r) for e in etas]
    # 2. the 1x sensitivities along a run-up and the bound of a probing run-up
    lams = np.linspace(0.30, 0.68, 20)
    report = {}
    for r in r_true:
        lam_best, eta_opt = best[r]
        rows, sens = [], []
        for lam in lams:
            for f in (0.5, 1.0, 2.0):  # the probe's three damping commands (x the optimum)
                z, dg, dr = sensitivities(p, eta_opt * f, r, float(lam))
                rows.append((2, z, dg, dr))  # 2 steps per (speed, damping): 120 run-up steps
                if f == 1.0:
                    sens.append(
                        {
                            "bearing_number": float(lam),
                            "abs_1x_per_unbalance": np.abs(z).tolist(),
                            "dlnz_dlng": [abs(complex(v)) for v in dg / z],
                            "dlnz_dlnr": [abs(complex(v)) for v in dr / z],
                        }
                    )
        # and 100 steps at the operating point, the same three dampings
        for f in (0.5, 1.0, 2.0):
            z, dg, dr = sensitivities(p, eta_opt * f, r, 0.98 * lam_best)
            rows.append((33, z, dg, dr))
        F = fisher(rows, UNBALANCE, ONE_X_SD)
        cov = np.linalg.inv(F)
        sd_lng, sd_lnr = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
        # the boundary at the operating damping: d Lambda_c / d(ln g, ln r) by central differences
        h = 0.1
        dlc_g = (p.critical(eta_opt * math.exp(h), r) - p.critical(eta_opt * math.exp(-h), r)) / (2 * h)
        dlc_r = (p.critical(eta_opt, r * math.exp(h)) - p.critical(eta_opt, r * math.exp(-h))) / (2 * h)
        grad = np.array([dlc_g, dlc_r])
        sd_lc = math.sqrt(grad @ cov[:2, :2] @ grad) / lam_best
        report[str(r)] = {
            "lambda_best": lam_best,
            "eta_opt": eta_opt,
            "steps": int(sum(n for n, *_ in rows)),
            "crb_sd_ln_g": sd_lng,
            "crb_sd_ln_r": sd_lnr,
            "crb_corr": float(cov[0, 1] / (sd_lng * sd_lnr)),
            "dlambda_c_dln_g": dlc_g,
            "dlambda_c_dln_r": dlc_r,
            "crb_sd_lambda_c_relative": sd_lc,
            "sensitivities": sens,
        }
    lb = np.array([best[r][0] for r in RATIOS if 2.0 <= r <= 30.0])
    result = {
        "command": "python -m gfb_experiments.zener_check",
        "plant": "RunUp-v2's nominal bearing, K_W = 0.50, grid 31x7",
        "one_x_sd_C": ONE_X_SD,
        "unbalance": UNBALANCE,
        "viscoelastic_limit": {
            str(dw): {"viscoelastic": a, "zener_r_1e4": b, "relative_difference": b / a - 1}
            for dw, (a, b) in lim.items()
        },
        "best": {str(r): {"lambda_best": v[0], "eta_opt": v[1]} for r, v in best.items()},
        "lambda_best_spread_r_2_30": {"min": float(lb.min()), "max": float(lb.max())},
        "crb": report,
        "seconds": time.time() - t0,
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "zener_check.json").write_text(json.dumps(result, indent=1, default=float))
    plot(result, curves, etas, out / "zener_check.png")
    return result


def plot(result: dict, curves: dict, etas: np.ndarray, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for r, lc in curves.items():
        label = "viscoelastic (r = oo)" if math.isinf(r) else f"Zener r = {r:g}"
        a1.semilogx(etas, lc, "o-", ms=3, label=label)
    a1.set_xlabel("foil viscosity eta = D_W (nondimensional)")
    a1.set_ylabel("Lambda_c")
    a1.set_title("the boundary moves with the hidden r = K_T / K_W")
    a1.legend(fontsize=8)
    for r, rep in result["crb"].items():
        s = rep["sensitivities"]
        lam = [x["bearing_number"] for x in s]
        a2.plot(lam, [max(x["dlnz_dlng"]) for x in s], "-", label=f"|d ln z / d ln g|, r = {float(r):g}")
        a2.plot(lam, [max(x["dlnz_dlnr"]) for x in s], "--", label=f"|d ln z / d ln r|, r = {float(r):g}")
    a2.axhline(ONE_X_SD / UNBALANCE, color="k", lw=0.8, ls=":", label="1x noise / |z| per step (|z|/U = 1)")
    a2.set_xlabel("Lambda along the run-up (eta = eta_opt)")
    a2.set_ylabel("relative sensitivity of the 1x vector")
    a2.set_title("what the 1x vector tells (larger of xi, eta)")
    a2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results/task_redesign/zener"))
    a = ap.parse_args(argv)
    res = run(a.out)
    for r, rep in res["crb"].items():
        print(
            f"r = {r}: Lambda_best {rep['lambda_best']:.4f} (eta_opt {rep['eta_opt']:.3f}); CRB over "
            f"{rep['steps']} steps: sd ln g {rep['crb_sd_ln_g']:.3f}, sd ln r {rep['crb_sd_ln_r']:.3f} "
            f"(corr {rep['crb_corr']:+.2f}); sd of Lambda_c at eta_opt "
            f"{100 * rep['crb_sd_lambda_c_relative']:.2f} %"
        )
    s = res["lambda_best_spread_r_2_30"]
    print(f"Lambda_best over r in [2, 30]: {s['min']:.4f} - {s['max']:.4f}; {res['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
