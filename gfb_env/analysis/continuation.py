"""Static equilibria continued in the bearing number (paper Sect. 3.2).

An equilibrium ``s0`` of Eq. (14) solves ``k(s0, Lambda) = 0``; it does not depend on the foil damping
``D_W`` (``Q' = 0``).  Along a sequence of bearing numbers each solve is warm-started from the previous
solution (natural-parameter continuation, Allgower & Georg, *Introduction to Numerical Continuation
Methods*, Ch. 1) with the damped Newton method of :func:`gfb_env.equilibrium.find_equilibrium`, which
falls back to load continuation from the centred journal when the warm start fails.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gfb_env.equilibrium import EquilibriumError, find_equilibrium
from gfb_env.model import GFBModel

__all__ = ["EquilibriumBranch", "continue_equilibria"]


@dataclass(frozen=True)
class EquilibriumBranch:
    """Equilibria along a sequence of bearing numbers.

    Attributes:
        bearing_number: ``Lambda`` of each converged point, shape ``(m,)``.
        states: the equilibrium states ``s0``, shape ``(m, n)``.
        eccentricity: ``eps = sqrt(xi^2 + eta^2)``.
        attitude_angle: ``gamma`` in radians from the load direction.
        min_film_thickness: ``min H``.
        failed_at: the first requested ``Lambda`` where no equilibrium was found (``None`` if all
            converged; the branch stops there).
    """

    bearing_number: np.ndarray
    states: np.ndarray
    eccentricity: np.ndarray
    attitude_angle: np.ndarray
    min_film_thickness: np.ndarray
    failed_at: float | None = None

    def __len__(self) -> int:
        return len(self.bearing_number)


def continue_equilibria(
    model: GFBModel,
    bearing_numbers: np.ndarray | list[float],
    guess: np.ndarray | None = None,
) -> EquilibriumBranch:
    """Solve ``k(s0, Lambda_j) = 0`` for each ``Lambda_j`` in order, warm-starting from ``s0(Lambda_{j-1})``.

    Args:
        model: the coupled model.
        bearing_numbers: positive bearing numbers, in the order to follow (monotone is best).
        guess: optional starting state for the first point.

    Returns:
        The branch up to (not including) the first bearing number where Newton fails.

    Raises:
        ValueError: if ``bearing_numbers`` is empty or contains a non-positive or non-finite value.
    """
    lams = np.asarray(bearing_numbers, dtype=float).ravel()
    if lams.size == 0:
        raise ValueError("bearing_numbers must not be empty")
    if not np.all(np.isfinite(lams)) or np.any(lams <= 0):
        raise ValueError("bearing_numbers must be finite and positive")
    L = model.layout
    states: list[np.ndarray] = []
    done: list[float] = []
    failed_at = None
    s = guess
    for lam in lams:
        try:
            s = find_equilibrium(model, float(lam), guess=s)
        except EquilibriumError:
            failed_at = float(lam)
            break
        states.append(s)
        done.append(float(lam))
    S = np.array(states).reshape(len(states), L.size)
    return EquilibriumBranch(
        bearing_number=np.array(done),
        states=S,
        eccentricity=np.array([model.eccentricity(x) for x in S]),
        attitude_angle=np.array([model.attitude_angle(x) for x in S]),
        min_film_thickness=np.array([model.min_film_thickness(x) for x in S]),
        failed_at=failed_at,
    )
