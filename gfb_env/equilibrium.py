"""Static equilibrium ``k(s0, Lambda) = 0`` of the coupled model (the start of every run and of the
stability analysis).

Damped Newton with the analytic sparse Jacobian, continued in the load from the centred journal when no
guess is given (see :func:`find_equilibrium`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse.linalg as spla

from gfb_env.model import GFBModel

__all__ = ["EquilibriumError", "equilibrium_summary", "find_equilibrium"]


class EquilibriumError(RuntimeError):
    """No static equilibrium was found."""


def find_equilibrium(
    model: GFBModel,
    bearing_number: float,
    guess: np.ndarray | None = None,
    tol: float = 1e-10,
    max_iterations: int = 50,
) -> np.ndarray:
    """Static equilibrium ``k(s0, Lambda) = 0`` by damped Newton with the analytic sparse Jacobian.

    Without a ``guess`` it starts from the centred journal and continues in the load (a quarter of
    M G, a half, ..., all of it), warm-starting each stage; a failed stage is retried with smaller
    load increments before :class:`EquilibriumError` is raised.  The equilibrium does not depend on
    D_W (Q' = 0).  Returns the state (rotor velocities zero).

    Frictional foil: the sliders start at the guess's positions (the centred start: S = 0, the unloaded
    foil) and each load stage moves them only as far as the Coulomb limit forces them (see
    :meth:`GFBModel.equilibrium_residual`): the state a quasi-static loading reaches.
    """
    model.check_operating_point(bearing_number, 1.0)
    if bearing_number <= 0:
        raise ValueError("bearing_number must be positive for a gas-film equilibrium")
    if guess is not None:
        s = np.array(model.layout.check(guess), dtype=float, copy=True)
        try:
            return _newton_equilibrium(model, bearing_number, s, 1.0, tol, max_iterations)
        except EquilibriumError:
            pass  # fall back to load continuation from the centre
    s = model.layout.centred_state()
    load = 0.0
    step = 0.25
    while load < 1.0:
        target = min(1.0, load + step)
        try:
            s = _newton_equilibrium(model, bearing_number, s, target, tol, max_iterations)
            load = target
            step = min(step * 2, 0.5)
        except EquilibriumError:
            step /= 4
            if step < 1e-3:
                raise EquilibriumError(
                    f"no equilibrium found at Lambda={bearing_number:g} ({model}); load continuation "
                    f"stalled at {load:.3f} M G"
                ) from None
    return s


def _newton_equilibrium(
    model: GFBModel, lam: float, s: np.ndarray, load_fraction: float, tol: float, max_iterations: int
) -> np.ndarray:
    L = model.layout
    s = s.copy()
    s[L.xi_dot_index] = 0.0
    s[L.eta_dot_index] = 0.0
    # frictional foil: the sliders move from where this stage starts only as far as the Coulomb limit
    # forces them (GFBModel.equilibrium_residual); k(s) itself for the other foils
    slider_reference = None if L.foil_state(s) is None else L.foil_state(s).copy()

    def residual(x):  # the same model with the gravity scaled by the load fraction
        return model.equilibrium_residual(x, lam, slider_reference, gravity_scale=load_fraction)

    r, mn = residual(s)
    if not mn > 0:
        raise EquilibriumError("inadmissible starting state")
    rn = np.linalg.norm(r, np.inf)
    for _ in range(max_iterations):
        if rn < tol:
            return s
        J = model.equilibrium_jacobian(
            s, lam, slider_reference
        )  # G is a constant of k: J is load-independent
        try:
            ds = spla.spsolve(J.tocsc(), -r)
        except RuntimeError as exc:  # singular
            raise EquilibriumError(str(exc)) from None
        if not np.all(np.isfinite(ds)):
            raise EquilibriumError("singular Jacobian")
        alpha = 1.0
        while alpha > 1e-4:
            x = s + alpha * ds
            rx, mn = residual(x)
            if mn > 0 and np.all(np.isfinite(rx)):
                rxn = np.linalg.norm(rx, np.inf)
                if rxn < (1 - 0.25 * alpha) * rn or rxn < tol:
                    break
            alpha *= 0.5
        else:
            raise EquilibriumError("line search failed")
        s, r, rn = x, rx, rxn
    if rn < tol * 100:
        return s
    raise EquilibriumError(f"Newton did not converge (residual {rn:.3g})")


def equilibrium_summary(model: GFBModel, s: np.ndarray, bearing_number: float) -> dict:
    """What ``gfb equilibrium`` reports of the equilibrium ``s`` at ``bearing_number``: eccentricity,
    attitude angle, film, peak pressure and the load balance, nondimensional and in the bearing's units."""
    b = model.bearing
    force = model.bearing_force(s)
    eps = model.eccentricity(s)
    hmin = model.min_film_thickness(s)
    fmag = float(np.hypot(*force))
    return {
        "structure": model.structure.value,
        "grid": str(model.grid),
        "bearing_number": bearing_number,
        "speed_rpm": b.speed_rpm_at(bearing_number),
        "foil_stiffness": model.foil_stiffness,
        "eccentricity": eps,
        "attitude_angle_deg": math.degrees(model.attitude_angle(s)),
        "min_film_thickness": hmin,
        "max_pressure": float(model.layout.pressure(s).max()),
        "bearing_force": fmag,
        "load": model.load,
        "eccentricity_um": b.micrometres(eps),
        "min_film_thickness_um": b.micrometres(hmin),
        "bearing_force_N": b.newtons(fmag),
    }
