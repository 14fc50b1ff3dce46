"""Stability constants of the Gymnasium tasks, on top of the rest of :mod:`gfb_env.analysis`.

Used by the script that precomputes the task constants (``experiments/env_task_constants.py``) and,
for a grid that is not tabulated, once in an environment's constructor (with a warning); never inside
``reset()``.

Method (paper Sect. 3.2): ``Lambda_c(D_W)`` by :func:`gfb_env.analysis.critical_bearing_number`
(eigenvalues of the Jacobian at the static equilibrium, scan + Brent root of the growth rate); its
maximum over ``log D_W`` by a scan and a golden-section refinement; a developed whirl by simulation.
"""

from __future__ import annotations

import math

import numpy as np

from gfb_env.analysis.maps import optimum_from_curve
from gfb_env.analysis.stability import (
    NoCriticalPointError,
    NoStableEquilibriumError,
    critical_bearing_number,
    jacobian_eigenvalues,
)
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import GFBModel

__all__ = [
    "critical_bearing_number_or_bound",
    "critical_bearing_numbers_on_grid",
    "developed_whirl_state",
    "task_constants",
]


def critical_bearing_number_or_bound(
    model: GFBModel,
    foil_damping: float,
    lam_min: float = 0.2,
    lam_max: float = 2.0,
    scan_step: float = 0.05,
    tol: float = 1e-4,
) -> float:
    """:func:`~gfb_env.analysis.stability.critical_bearing_number` as a plain float for tables:
    ``lam_min`` if no scanned equilibrium is stable, ``nan`` if stable on the whole range (where that
    function raises)."""
    try:
        cp = critical_bearing_number(
            model, foil_damping, bearing_range=(lam_min, lam_max), scan_step=scan_step, xtol=tol
        )
    except NoStableEquilibriumError:
        return lam_min
    except NoCriticalPointError:
        return math.nan
    return cp.critical_bearing_number


def critical_bearing_numbers_on_grid(
    model: GFBModel,
    dampings: np.ndarray,
    lam_min: float = 0.3,
    lam_max: float = 2.0,
    lam_step: float = 0.02,
) -> np.ndarray:
    """``Lambda_c`` for many dampings at once (fast, for tables).

    The static equilibrium does not depend on D_W (Q' = 0), so one equilibrium per Lambda (warm-started
    along a grid of step ``lam_step``) serves every damping; the growth rate ``max Re(lambda)`` of each
    damping is evaluated on the grid and its first zero crossing is located by linear interpolation
    (error ~ curvature * lam_step^2, below 1e-3 at the default step; checked against
    :func:`gfb_env.analysis.critical_bearing_number` in ``docs/envs.md``).  The scan stops once every
    damping is unstable.  ``nan``: stable up to ``lam_max``; ``lam_min``: unstable from the start."""
    ds = np.asarray(dampings, dtype=float)
    out = np.full(ds.shape, np.nan)
    prev = np.full(ds.shape, np.nan)
    s = None
    lam_prev = None
    for lam in np.arange(lam_min, lam_max + 0.5 * lam_step, lam_step):
        s = find_equilibrium(model, float(lam), guess=s)
        g = np.array([jacobian_eigenvalues(model, s, float(lam), float(d))[0].real for d in ds])
        for j in range(len(ds)):
            if not np.isnan(out[j]):
                continue
            if g[j] >= 0:
                if lam_prev is None:
                    out[j] = lam_min
                else:
                    out[j] = lam_prev + (float(lam) - lam_prev) * prev[j] / (prev[j] - g[j])
        prev, lam_prev = g, float(lam)
        if np.all(~np.isnan(out)):
            break
    return out


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


#: Whirl start of WhirlRecovery: Lambda_w = WHIRL_FACTOR * lambda_best at the optimum damping.
#: (At 1.07 a damping outside [1.6, 3.5] touched down within 120 tau, leaving an agent no time to
#: react; at 1.03 the worst damping takes 460-1000 tau, 8-16 control steps; 31x7, measured.)
WHIRL_FACTOR = 1.03


def task_constants(model: GFBModel, d_min: float = 0.1, d_max: float = 10.0) -> dict:
    """Everything the nominal tasks need on one grid (see ``experiments/env_task_constants.py``):
    ``Lambda_c`` on 25 log-spaced dampings (Lambda step 0.01), the optimum damping ``d_opt`` and
    ``lambda_best``, and a developed whirl state at ``WHIRL_FACTOR * lambda_best``."""
    ds = np.geomspace(d_min, d_max, 25)
    lc = critical_bearing_numbers_on_grid(model, ds, lam_min=0.3, lam_step=0.01)
    d_opt, best = optimum_from_curve(ds, lc)
    entry = {
        "lambda_best": best,
        "d_opt": d_opt,
        "lambda_c_dmin": float(lc[0]),
        "lambda_c_dmax": float(lc[-1]),
        "curve_d": ds.tolist(),
        "curve_lambda_c": lc.tolist(),
    }
    lam_w = round(WHIRL_FACTOR * best, 4)
    entry["whirl"] = developed_whirl_state(model, lam_w, d_opt)
    return entry
