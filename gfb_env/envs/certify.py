"""Certification of the v1 tasks: is the operating point reached at the horizon linearly stable?

A hold window of small whirl amplitude does not certify stability: just above the critical bearing
number ``Lambda_c`` the growth rate of the whirl mode is tiny (at ``1.003 Lambda_c`` the amplitude stays
below the stable threshold for far longer than any hold window).  The v1 tasks therefore judge the end
of an episode on the *actual* plant, as a stability analyst would (paper Sect. 3.2): the drawn bearing's
model, the actual foil damping ``D_W`` (the actuator's actual value, gain included) and the final
bearing number ``Lambda``.  The static equilibrium is solved (warm-started from the current state) and
the rightmost eigenvalue of its Jacobian must have a negative real part
(:func:`gfb_env.analysis.stability.linear_stability`, ~6 ms on 31x7).

:func:`best_stable_operating_point` is the exact best stable speed of a plant for an achievable damping
range, ``lambda_best = max_{D in [D_lo, D_hi]} Lambda_c(D)``, and its damping: the root in ``Lambda`` of
``h(Lambda) = min_D max Re(eig J(Lambda, D))`` (the static equilibrium does not depend on ``D_W``, so
one equilibrium per ``Lambda`` serves every damping; the inner minimum by bounded Brent in ``log D``,
the root by Brent).  ~0.3 s on 31x7 (about 50 eigenvalue solves).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from gfb_env.analysis.stability import jacobian_eigenvalues, linear_stability
from gfb_env.envs.config import check_positive
from gfb_env.equilibrium import EquilibriumError, find_equilibrium
from gfb_env.model import GFBModel

__all__ = [
    "Certificate",
    "StabilityCertificate",
    "linear_certificate",
    "BestStablePoint",
    "best_stable_operating_point",
    "least_growth_rate",
    "below_best_stable_speed",
]


@dataclass(frozen=True)
class Certificate:
    """The verdict on the end of an episode.

    Attributes:
        certified: the whirl stayed small over the window and the equilibrium is linearly stable.
        reason: ``"stable"``, ``"whirl_in_window"`` (the amplitude exceeded the threshold in the window),
            ``"unstable_equilibrium"`` (growth rate >= 0), ``"no_equilibrium"`` (none found) or
            ``"not_judged"`` (the episode ended by touchdown or solver failure).
        growth_rate: ``max Re(lambda_i)`` of the actual plant's equilibrium (NaN if not computed).
    """

    certified: bool
    reason: str
    growth_rate: float


@dataclass(frozen=True)
class StabilityCertificate:
    """Certify the operating point at the horizon (module docstring).

    Attributes:
        stable_amplitude: whirl amplitude (units of C) that every step of the window must stay below.
        hold_steps: length of the window (control steps).
    """

    stable_amplitude: float = 0.05
    hold_steps: int = 10

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "stable_amplitude", check_positive("stable_amplitude", self.stable_amplitude)
        )
        if isinstance(self.hold_steps, bool) or not isinstance(self.hold_steps, int) or self.hold_steps < 1:
            raise ValueError(f"hold_steps must be a positive integer, got {self.hold_steps!r}")

    def certify(
        self, window_amplitudes: list[float], plant: Any, bearing_number: float, foil_damping: float
    ) -> Certificate:
        """:meth:`judge` of the objective's window and plant (a
        :class:`~gfb_env.envs.commanded.CertifiedPlant`: its model and state)."""
        return self.judge(window_amplitudes, plant.model, bearing_number, foil_damping, plant.state)

    def judge(
        self,
        window_amplitudes: list[float],
        model: GFBModel,
        bearing_number: float,
        foil_damping: float,
        state: np.ndarray,
    ) -> Certificate:
        """The certificate of the window (its last ``hold_steps`` whirl amplitudes) and the plant
        ``model`` at ``bearing_number`` with the actual ``foil_damping`` (``state``: the warm start)."""
        window = window_amplitudes[-self.hold_steps :]
        if len(window) < self.hold_steps or not all(
            math.isfinite(a) and a <= self.stable_amplitude for a in window
        ):
            return Certificate(False, "whirl_in_window", math.nan)
        return linear_certificate(model, bearing_number, foil_damping, state)


def linear_certificate(
    model: GFBModel, bearing_number: float, foil_damping: float, state: np.ndarray
) -> Certificate:
    """The plant's half of every certificate: the static equilibrium of ``model`` at ``bearing_number``
    with the actual ``foil_damping`` (warm-started from ``state``) must be linearly stable."""
    try:
        st = linear_stability(model, bearing_number, foil_damping, guess=state)
    except (EquilibriumError, FloatingPointError, np.linalg.LinAlgError):
        return Certificate(False, "no_equilibrium", math.nan)
    g = st.growth_rate
    if not (math.isfinite(g) and g < 0.0):
        return Certificate(False, "unstable_equilibrium", g)
    return Certificate(True, "stable", g)


@dataclass(frozen=True)
class BestStablePoint:
    """The best stable operating point of an episode's plant for its achievable damping.

    Attributes:
        bearing_number: ``lambda_best`` (max over the achievable actual damping of ``Lambda_c``).
        foil_damping: the actual ``D_W`` that achieves it.
        commanded_damping: the command that gives it (``foil_damping / g``).
        speed_rpm: the rotor speed at ``lambda_best`` for the episode's bearing.
    """

    bearing_number: float
    foil_damping: float
    commanded_damping: float
    speed_rpm: float


def _growth(model: GFBModel, s: np.ndarray, lam: float, d: float) -> float:
    return float(jacobian_eigenvalues(model, s, lam, d)[0].real)


def least_growth_rate(
    model: GFBModel, bearing_number: float, damping_range: tuple[float, float], state: np.ndarray
) -> tuple[float, float]:
    """``(min_D max Re eig J, argmin D)`` over ``D in damping_range`` at the static equilibrium of
    ``bearing_number`` (given: ``state``).  Negative iff some damping of the range makes that equilibrium
    linearly stable, i.e. iff ``bearing_number < max_D Lambda_c(D)`` (for a unimodal ``Lambda_c(D)``):
    one such evaluation decides whether a speed lies below the best stable speed (~17 eigenvalue
    solves, ~0.1 s on 31x7)."""
    d_lo, d_hi = damping_range
    x_lo, x_hi = math.log(d_lo), math.log(d_hi)
    if x_hi - x_lo < 1e-9:
        return _growth(model, state, bearing_number, d_lo), d_lo
    r = minimize_scalar(
        lambda x: _growth(model, state, bearing_number, math.exp(x)),
        bounds=(x_lo, x_hi),
        method="bounded",
        options={"xatol": 1e-3},
    )
    # the bounded search never evaluates the ends exactly: the optimum may sit on one
    best_x, best_g = float(r.x), float(r.fun)
    for x in (x_lo, x_hi):
        gx = _growth(model, state, bearing_number, math.exp(x))
        if gx < best_g:
            best_x, best_g = x, gx
    return best_g, math.exp(best_x)


def best_stable_operating_point(
    model: GFBModel,
    damping_range: tuple[float, float],
    bearing_number_guess: float,
    xtol: float = 1e-5,
) -> tuple[float, float]:
    """``(lambda_best, D_opt)``: the largest ``Lambda`` whose equilibrium some actual damping in
    ``damping_range`` makes linearly stable, and that damping (module docstring).

    ``bearing_number_guess`` starts the bracket (e.g. a table value); the bracket widens by 2 % steps
    until ``h`` changes sign.  The result is ``max_D Lambda_c(D)`` when ``Lambda_c(D)`` is unimodal in
    ``log D`` (the stability map, paper Fig. 4), which holds on the tasks' bearings (tested against
    :func:`~gfb_env.analysis.stability.critical_bearing_number`).

    Raises:
        ValueError: a bad range or guess; RuntimeError: no bracket within a factor 2 of the guess.
    """
    d_lo, d_hi = (check_positive("damping_range", float(x)) for x in damping_range)
    if not d_lo <= d_hi:
        raise ValueError(f"damping_range must satisfy low <= high, got {damping_range!r}")
    lam0 = check_positive("bearing_number_guess", bearing_number_guess)
    cache: dict[float, np.ndarray] = {}
    argmin: dict[float, float] = {}

    def h(lam: float) -> float:
        near = min(cache, key=lambda x: abs(x - lam)) if cache else None
        s = find_equilibrium(model, lam, guess=cache[near] if near is not None else None)
        cache[lam] = s
        g, d = least_growth_rate(model, lam, (d_lo, d_hi), s)
        argmin[lam] = d
        return g

    # bracket: h < 0 below lambda_best, >= 0 above
    a = b = lam0
    ha = hb = h(lam0)
    for _ in range(40):
        if ha < 0 <= hb and a != b:
            break
        if ha >= 0:
            b, hb = a, ha
            a = a / 1.02
            ha = h(a)
        else:
            a, ha = b, hb
            b = b * 1.02
            hb = h(b)
        if not 0.5 * lam0 <= a <= b <= 2.0 * lam0:
            raise RuntimeError(f"no stability boundary within a factor 2 of Lambda = {lam0:g}")
    else:  # pragma: no cover - 40 steps of 2 % span more than the factor 2
        raise RuntimeError(f"no stability boundary near Lambda = {lam0:g}")
    lam = brentq(h, a, b, xtol=xtol)
    if lam not in argmin:
        h(lam)
    return float(lam), float(argmin[lam])


def below_best_stable_speed(
    model: GFBModel, bearing_number: float, damping_range: tuple[float, float], guess: np.ndarray
) -> bool:
    """Whether ``bearing_number < max_{D in damping_range} Lambda_c(D)``, decided exactly by one
    :func:`least_growth_rate` (the equilibrium solved from ``guess``); False where no equilibrium is found."""
    try:
        s = find_equilibrium(model, bearing_number, guess=guess)
    except EquilibriumError:
        return False
    return least_growth_rate(model, bearing_number, damping_range, s)[0] < 0.0
