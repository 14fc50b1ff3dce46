"""Issue 19: how well could ANY rule know RunUpRandomized-v2's boundary after one run-up? A Cramer-Rao bound.

RunUpRandomized-v2 hides the damping gain g and the bearing's draw (clearance C, foil-stiffness factor f_K,
load F_L).  The strongest rule on the table leaves an oracle headroom of IQM 0.29 [0.24, 0.34] (mean 0.25
[0.196, 0.30]); is that the physics (the sensors cannot tell the boundary in one episode) or the rules (they
do not use what the sensors tell)?  This bounds the answer from the sensors' side: the Fisher information of
the 1x vectors a vibration monitor reads along a probing run-up, with the monitor's documented noise, about
``theta = (ln g, ln C, ln f_K, ln F_L, Re e, Im e)`` (e the unbalance's eccentricity in um, complex:
magnitude and phase unknown), and from it the least variance any unbiased estimator can have for the
critical speed at the operating damping.

* Measurement: per control step the steady 1x vector ``e z(Lambda(n, C); C, f_K, F_L, g D)`` in um (both
  probes' cos/sin coefficients; ``z`` per unit nondimensional unbalance from
  :func:`gfb_env.analysis.unbalance_response`, ``Lambda`` from the speed n in rpm through the drawn C), each
  coefficient with the monitor's sd 0.0385 um (docs/machine.md: 0.077 um pk-pk).
* Design (a plausible probing run-up, not an optimum): 20 speeds from the task's start speed to 98 % of the
  draw's best stable speed, 2 steps at each of three damping commands (0.5, 1, 2 x the optimum, with the true
  g) per speed, then 33 steps at each at the operating point: 219 steps (the episode has 256).
* Left out, so the bound is conservative (more information only lowers it): the static equilibrium (the
  reset observation's journal position, which already tells ln C to 0.025; docs/identifiability.md), the
  pressure taps, the shocks' ring-downs.  Left in, so the bound is optimistic: the model is exact and the 1x
  is the steady response.
* ``known_bearing``: the same run-up with C, f_K, F_L known (RunUp-v2's case: g and the unbalance hidden).
* ``with_static``: the 1x bound plus the static position's ln C (rms 0.025, as an independent measurement).
* ``prior``: the bound with the task's prior added as a Gaussian precision (sd of ln g 0.665, ln C 0.117,
  ln f_K 0.200, ln F_L 0.147: the draws' uniform ranges), the Bayesian (van Trees) version.

Run: ``python -m gfb_experiments.identifiability_bound [--out results/identifiability/bound] [--random N]``
(~35 s on one core, and ~11 s per random draw of the prior).  Writes ``identifiability_bound.json``.
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

#: the monitor's 1x noise per step and cos/sin coefficient, um (docs/machine.md: 0.077 um pk-pk)
ONE_X_SD_UM = 0.0385
#: the parameters of the bound, in order
NAMES = ("ln_g", "ln_C", "ln_fK", "ln_FL", "re_e_um", "im_e_um")
#: the task's prior, as sds of the log draws (uniform ranges: (ln hi - ln lo) / sqrt 12), for the
#: Bayesian bound; the unbalance's components get none (a flat prior)
PRIOR_SD = {
    "ln_g": math.log(10.0) / math.sqrt(12.0),
    "ln_C": math.log(60 / 40) / math.sqrt(12.0),
    "ln_fK": math.log(1.4 / 0.7) / math.sqrt(12.0),
    "ln_FL": math.log(25 / 15) / math.sqrt(12.0),
}
#: what the reset observation's static journal position tells of ln C (docs/identifiability.md: the
#: regressor's rms 0.025), added as an independent measurement in ``with_static``
STATIC_LN_C_SD = 0.025
#: RunUpRandomized-v2's start speed (rpm): 85 % of the lowest critical speed of the ranges (the env's)
START_RPM_FRACTION = 0.85


def fisher_information(rows: list[tuple[int, list[np.ndarray]]], sd: float) -> np.ndarray:
    """Fisher information of a Gaussian measurement of complex vectors: per row ``(n, [dm/dtheta_k])``, n
    independent steps of a complex vector ``m`` whose real and imaginary parts have sd ``sd``."""
    k = len(rows[0][1])
    F = np.zeros((k, k))
    for n, cols in rows:
        J = np.array([np.concatenate([np.real(c), np.imag(c)]) for c in cols]).T
        F += n * J.T @ J / sd**2
    return F


class DrawnPlant:
    """RunUp-v2's bearing with the draw ``(C, f_K, F_L)`` (RunUpRandomized-v2's :meth:`_draw_bearing`)."""

    def __init__(self, grid: str = "31x7"):
        c = load_task_constants()
        self.nominal = BearingParameters(**c["bearing"])  # its foil_stiffness is the tasks' K_W = 0.50
        self.grid = Grid.parse(grid)

    def model(self, c_m: float, fk: float, fl: float) -> tuple[BearingParameters, GFBModel]:
        b = self.nominal.replace(clearance_m=c_m, external_load_per_bearing_n=fl)
        return b, GFBModel("viscoelastic", self.grid, bearing=b, foil_stiffness=fk * b.foil_stiffness)

    def one_x_um(self, p: dict, rpm: float, eta: float, e_um: complex) -> np.ndarray:
        """The steady 1x vector (xi, eta) in um, zero-to-peak complex, at ``rpm`` with actual damping eta."""
        b, m = self.model(math.exp(p["ln_C"]), math.exp(p["ln_fK"]), math.exp(p["ln_FL"]))
        lam = b.bearing_number_at(rpm)
        s0 = find_equilibrium(m, lam)
        r = unbalance_response(m, lam, 1.0, foil_damping=eta * math.exp(p["ln_g"]), state=s0, stability=False)
        return e_um * np.array([r.xi, r.eta])  # e z: the nondimensional U = e / C times C

    def critical_rpm(self, p: dict, eta: float) -> float:
        b, m = self.model(math.exp(p["ln_C"]), math.exp(p["ln_fK"]), math.exp(p["ln_FL"]))
        lam = critical_bearing_number(m, eta * math.exp(p["ln_g"]), bearing_range=(0.3, 1.5))
        return b.speed_rpm_at(lam.critical_bearing_number)

    def best(self, p: dict) -> tuple[float, float]:
        """(best stable speed in rpm, the actual damping there) of the draw (g does not enter)."""
        from scipy.optimize import minimize_scalar

        q = {**p, "ln_g": 0.0}
        res = minimize_scalar(
            lambda le: -self.critical_rpm(q, math.exp(le)), bounds=(math.log(0.3), math.log(30.0)),
            method="bounded", options={"xatol": 0.005},
        )  # fmt: skip
        return -float(res.fun), math.exp(float(res.x))


def bound(plant: DrawnPlant, draw: dict, start_rpm: float, e_um: float = 0.385, h: float = 0.02) -> dict:
    """The Cramer-Rao bound of the design (module docstring) at ``draw`` (ln g, ln C, ln fK, ln FL)."""
    p = dict(draw)
    n_best, eta_act = plant.best(p)
    cmd = eta_act / math.exp(p["ln_g"])  # the command that reaches the optimum with the true g
    speeds = np.linspace(start_rpm, 0.98 * n_best, 20)
    design = [(2, float(n), f) for n in speeds for f in (0.5, 1.0, 2.0)]
    design += [(33, 0.98 * n_best, f) for f in (0.5, 1.0, 2.0)]
    rows = []
    for n, rpm, f in design:
        m0 = plant.one_x_um(p, rpm, cmd * f, e_um)
        cols = []
        for name in NAMES[:4]:
            up, dn = dict(p), dict(p)
            up[name] += h
            dn[name] -= h
            cols.append(
                (plant.one_x_um(up, rpm, cmd * f, e_um) - plant.one_x_um(dn, rpm, cmd * f, e_um)) / (2 * h)
            )
        cols += [m0 / e_um, 1j * m0 / e_um]  # d(e z) / d Re e, d Im e
        rows.append((n, cols))
    F = fisher_information(rows, ONE_X_SD_UM)
    prior = np.diag([1.0 / PRIOR_SD[k] ** 2 for k in NAMES[:4]] + [0.0, 0.0])
    # the critical speed at the operating command, by central differences
    grad = np.zeros(len(NAMES))
    for i, name in enumerate(NAMES[:4]):
        up, dn = dict(p), dict(p)
        up[name] += 0.05
        dn[name] -= 0.05
        grad[i] = (plant.critical_rpm(up, cmd) - plant.critical_rpm(dn, cmd)) / 0.1
    nc = plant.critical_rpm(p, cmd)
    out = {"draw": draw, "best_rpm": n_best, "actual_damping_opt": eta_act, "critical_rpm": nc}
    out["steps"] = int(sum(n for n, *_ in design))
    out["dcritical_rpm_dtheta"] = dict(zip(NAMES, grad.tolist(), strict=True))
    out["prior_sd_critical_relative"] = math.sqrt(
        sum((grad[i] * PRIOR_SD[k]) ** 2 for i, k in enumerate(NAMES[:4]))
    ) / nc  # fmt: skip
    static = np.zeros_like(F)
    static[1, 1] = 1.0 / STATIC_LN_C_SD**2
    for label, M in (("crb", F), ("bayesian", F + prior), ("with_static", F + static)):
        cov = np.linalg.inv(M)
        out[label] = {
            "sd": {k: math.sqrt(cov[i, i]) for i, k in enumerate(NAMES)},
            "sd_critical_relative": math.sqrt(grad @ cov @ grad) / nc,
            "condition_number": float(np.linalg.cond(M)),
        }
    # RunUp-v2's case: the bearing known, g (and the unbalance) hidden: the information's (g, e) block
    keep = [0, 4, 5]
    cov = np.linalg.inv(F[np.ix_(keep, keep)])
    # at the optimum the critical speed is flat in ln g to first order: its expected loss from an error
    # of ln g with that sd is second order, 0.5 |d2 n_c / d ln g^2| sd^2
    up, dn = dict(p), dict(p)
    up["ln_g"] += 0.1
    dn["ln_g"] -= 0.1
    curv = (plant.critical_rpm(up, cmd) + plant.critical_rpm(dn, cmd) - 2 * nc) / 0.01
    out["known_bearing"] = {
        "sd_ln_g": math.sqrt(cov[0, 0]),
        "sd_critical_relative": abs(grad[0]) * math.sqrt(cov[0, 0]) / nc,
        "d2critical_dln_g2_relative": curv / nc,
        "expected_loss_relative": 0.5 * abs(curv) * cov[0, 0] / nc,
    }
    return out


def prior_draws(n: int, seed: int = 19) -> list[tuple[dict, float]]:
    """``n`` draws of RunUpRandomized-v2's prior (g log-uniform in [0.316, 3.16], C uniform in 40-60 um,
    f_K in 0.7-1.4, F_L in 15-25 N) with an unbalance eccentricity log-uniform in 0.15-1.0 um (the balance
    grades' G 1-6.3 at C = 50 um: U = 0.003-0.02, docs/machine.md)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        d = {
            "ln_g": float(rng.uniform(math.log(0.316), math.log(3.16))),
            "ln_C": math.log(float(rng.uniform(40e-6, 60e-6))),
            "ln_fK": math.log(float(rng.uniform(0.7, 1.4))),
            "ln_FL": math.log(float(rng.uniform(15.0, 25.0))),
        }
        out.append((d, float(np.exp(rng.uniform(math.log(0.15), math.log(1.0))))))
    return out


def run(out: Path, n_random: int = 0) -> dict:
    t0 = time.time()
    plant = DrawnPlant()
    nominal = {"ln_g": 0.0, "ln_C": math.log(50e-6), "ln_fK": math.log(1.0), "ln_FL": math.log(20.0)}
    draws = {
        "centre": nominal,
        "tight_stiff_light": {
            **nominal, "ln_C": math.log(42e-6), "ln_fK": math.log(1.3), "ln_FL": math.log(16.0)
        },
        "loose_soft_heavy_g0.4": {
            "ln_g": math.log(0.4), "ln_C": math.log(58e-6), "ln_fK": math.log(0.75), "ln_FL": math.log(24.0)
        },
    }  # fmt: skip
    # the task's start speed (RunUpRandomized-v2's default: 85 % of the lowest critical speed of the box)
    from gfb_env.envs.run_up_randomized import RunUpRandomizedEnv

    start = RunUpRandomizedEnv().start_speed_rpm
    res = {
        "command": "python -m gfb_experiments.identifiability_bound",
        "one_x_sd_um": ONE_X_SD_UM,
        "unbalance_eccentricity_um": 0.385,
        "start_rpm": start,
        "prior_sd": PRIOR_SD,
        "draws": {k: bound(plant, d, start) for k, d in draws.items()},
    }
    if n_random:
        rows = []
        for i, (d, e) in enumerate(prior_draws(n_random)):
            try:
                b = bound(plant, d, start, e_um=e)
            except Exception as exc:  # noqa: BLE001 - a draw the analysis cannot solve is counted, not fatal
                rows.append({"draw": d, "unbalance_eccentricity_um": e, "error": str(exc)})
                continue
            rows.append(
                {
                    "draw": d,
                    "unbalance_eccentricity_um": e,
                    "best_rpm": b["best_rpm"],
                    "sd_critical_relative_1x": b["crb"]["sd_critical_relative"],
                    "sd_critical_relative_with_static": b["with_static"]["sd_critical_relative"],
                    "known_bearing_expected_loss_relative": b["known_bearing"]["expected_loss_relative"],
                }
            )
            print(f"draw {i}: {rows[-1]}", flush=True)
        ok = np.array([r["sd_critical_relative_with_static"] for r in rows if "error" not in r])
        res["random"] = {
            "n": n_random,
            "seed": 19,
            "solved": int(ok.size),
            "sd_critical_with_static_quantiles": dict(
                zip(
                    ("q10", "q25", "median", "q75", "q90"),
                    np.quantile(ok, [0.1, 0.25, 0.5, 0.75, 0.9]).tolist(),
                )
            ),
            "fraction_above_2_percent": float(np.mean(ok > 0.02)),
            "rows": rows,
        }
    res["seconds"] = time.time() - t0
    out.mkdir(parents=True, exist_ok=True)
    (out / "identifiability_bound.json").write_text(json.dumps(res, indent=1))
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results/identifiability/bound"))
    ap.add_argument("--random", type=int, default=0, help="also this many draws of the task's prior")
    a = ap.parse_args(argv)
    if a.random < 0:
        ap.error(f"--random must be >= 0, got {a.random}")
    res = run(a.out, a.random)
    for k, d in res["draws"].items():
        c, bz = d["crb"], d["bayesian"]
        kb = d["known_bearing"]
        print(
            f"{k}: best {d['best_rpm']:.0f} rpm; sd of the critical speed: prior "
            f"{100 * d['prior_sd_critical_relative']:.2f} %, 1x CRB {100 * c['sd_critical_relative']:.2f} %, "
            f"with the prior {100 * bz['sd_critical_relative']:.2f} %, with the static ln C "
            f"{100 * d['with_static']['sd_critical_relative']:.2f} %; bearing known (g only): expected loss "
            f"{100 * kb['expected_loss_relative']:.3f} %; CRB sd ln g {c['sd']['ln_g']:.3f}, ln C "
            f"{c['sd']['ln_C']:.3f}, ln fK {c['sd']['ln_fK']:.3f}, ln FL {c['sd']['ln_FL']:.3f}"
        )
    if "random" in res:
        r = res["random"]
        q = r["sd_critical_with_static_quantiles"]
        print(
            f"{r['solved']} of {r['n']} prior draws: sd of the critical speed (1x + static ln C) median "
            f"{100 * q['median']:.2f} % [q10 {100 * q['q10']:.2f}, q90 {100 * q['q90']:.2f}]; above 2 %: "
            f"{100 * r['fraction_above_2_percent']:.0f} %"
        )
    print(f"{res['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
