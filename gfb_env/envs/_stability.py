"""Minimal private stability helper for the environments.

TEMPORARY: to be replaced by ``gfb_env.analysis`` (equilibrium continuation and
``critical_bearing_number``) once that module lands.  It is used only by the scripts that precompute
the task constants (``experiments/env_task_constants.py``, ``experiments/env_grid_tradeoff.py``) and by
tests; never inside ``reset()``.

Method (paper Sect. 3.2): static equilibrium ``k(s0, Lambda) = 0`` by :func:`find_equilibrium`
(warm-started along Lambda), then the spectral abscissa ``max Re(lambda_i)`` of the dense Jacobian
``J_k(s0, Lambda, D_W)``; the critical bearing number ``Lambda_c`` is the root of the spectral abscissa
in Lambda, found by a coarse scan followed by bisection.
"""

from __future__ import annotations

import math

import numpy as np

from gfb_env.integrator import EquilibriumError, find_equilibrium
from gfb_env.model import GFBModel

__all__ = [
    "spectral_abscissa",
    "critical_bearing_number",
    "best_stable_bearing_number",
    "developed_whirl_state",
    "task_constants",
]


def spectral_abscissa(
    model: GFBModel, bearing_number: float, foil_damping: float, guess: np.ndarray | None = None
) -> tuple[float, np.ndarray]:
    """``max Re(lambda_i)`` of the Jacobian at the static equilibrium, and that equilibrium."""
    s0 = find_equilibrium(model, bearing_number, guess=guess)
    J = model.jacobian(s0, bearing_number, foil_damping).toarray()
    return float(np.linalg.eigvals(J).real.max()), s0


def critical_bearing_number(
    model: GFBModel,
    foil_damping: float,
    lam_min: float = 0.2,
    lam_max: float = 2.0,
    scan_step: float = 0.05,
    tol: float = 1e-4,
) -> float:
    """Lowest ``Lambda`` in ``[lam_min, lam_max]`` where the equilibrium loses stability (``nan`` if
    it is stable on the whole range, ``lam_min`` if it is already unstable there)."""
    guess = None
    lam_prev, s_prev = None, None
    lam = lam_min
    while lam <= lam_max + 1e-12:
        try:
            a, s = spectral_abscissa(model, lam, foil_damping, guess)
        except EquilibriumError:
            return lam if lam_prev is None else lam_prev
        if a > 0:
            if lam_prev is None:
                return lam_min
            lo, hi, g = lam_prev, lam, s_prev
            while hi - lo > tol:
                mid = 0.5 * (lo + hi)
                am, sm = spectral_abscissa(model, mid, foil_damping, g)
                if am > 0:
                    hi = mid
                else:
                    lo, g = mid, sm
            return 0.5 * (lo + hi)
        lam_prev, s_prev, guess = lam, s, s
        lam += scan_step
    return math.nan


_GOLD = (math.sqrt(5) - 1) / 2


def best_stable_bearing_number(
    model: GFBModel,
    d_min: float = 0.1,
    d_max: float = 10.0,
    tol: float = 2e-4,
    n_scan: int = 9,
    n_golden: int = 8,
) -> dict:
    """``lambda_best = max over D_W in [d_min, d_max] of Lambda_c(D_W)`` and the optimum damping, by a
    scan in log D_W and a golden-section refinement around the best scan point.

    Returns ``lambda_best``, ``d_opt``, ``lambda_c_dmin``, ``lambda_c_dmax`` and the scanned curve."""

    def lc(logd: float) -> float:
        return critical_bearing_number(
            model, math.exp(logd), lam_min=0.25, lam_max=2.5, scan_step=0.05, tol=tol
        )

    logd = np.linspace(math.log(d_min), math.log(d_max), n_scan)
    vals = [lc(x) for x in logd]
    k = int(np.nanargmax(vals))
    a, b = logd[max(k - 1, 0)], logd[min(k + 1, n_scan - 1)]
    c, d = b - _GOLD * (b - a), a + _GOLD * (b - a)
    fc, fd = lc(c), lc(d)
    for _ in range(n_golden):
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - _GOLD * (b - a)
            fc = lc(c)
        else:
            a, c, fc = c, d, fd
            d = a + _GOLD * (b - a)
            fd = lc(d)
    best_logd, best = (c, fc) if fc > fd else (d, fd)
    if vals[k] > best:
        best_logd, best = logd[k], vals[k]
    return {
        "lambda_best": float(best),
        "d_opt": float(math.exp(best_logd)),
        "lambda_c_dmin": float(vals[0]),
        "lambda_c_dmax": float(vals[-1]),
        "curve_d": [float(math.exp(x)) for x in logd],
        "curve_lambda_c": [float(v) for v in vals],
    }


def developed_whirl_state(
    model: GFBModel,
    bearing_number: float,
    foil_damping: float,
    tau_develop: float = 5000.0,
    touchdown_film_thickness: float = 0.02,
) -> dict:
    """A state on the developed whirl limit cycle: from the equilibrium with a small velocity kick,
    integrate ``tau_develop`` at fixed Lambda and D_W; also the period and extremes of the cycle."""
    from gfb_env.integrator import TrapezoidalIntegrator

    L = model.layout
    s = find_equilibrium(model, bearing_number)
    s = L.with_rotor(s, *L.rotor(s)[:2], 0.01, 0.0)
    integ = TrapezoidalIntegrator(
        model, s, bearing_number, foil_damping, touchdown_film_thickness=touchdown_film_thickness
    )
    res = integ.advance(tau_develop)
    if res.status != "done":
        raise RuntimeError(
            f"no developed whirl at Lambda={bearing_number}, D_W={foil_damping} on {model.grid}: {res.status}"
        )
    res = integ.advance(tau_develop + 400.0, record_interval=0.25)
    tr = res.trajectory
    x = tr.xi - tr.xi.mean()
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    period = float(np.mean(np.diff(tr.tau[up]))) if len(up) > 2 else float("nan")
    return {
        "bearing_number": float(bearing_number),
        "foil_damping": float(foil_damping),
        "state": integ.state.tolist(),
        "period": period,
        "max_eccentricity": float(res.max_eccentricity),
        "min_film_thickness": float(res.min_film_thickness),
    }


#: Whirl start of WhirlRecovery-v0: Lambda_w = WHIRL_FACTOR * lambda_best at the optimum damping.
WHIRL_FACTOR = 1.07


def task_constants(model: GFBModel, d_min: float = 0.1, d_max: float = 10.0, tol: float = 2e-4) -> dict:
    """Everything the nominal tasks need on one grid (see ``experiments/env_task_constants.py``)."""
    entry = best_stable_bearing_number(model, d_min, d_max, tol=tol)
    lam_w = round(WHIRL_FACTOR * entry["lambda_best"], 4)
    entry["whirl"] = developed_whirl_state(model, lam_w, entry["d_opt"])
    return entry
