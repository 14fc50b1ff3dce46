"""Linear stability of equilibria and the critical bearing number ``Lambda_c`` (paper Sect. 3.2).

By the Hartman-Grobman theorem an equilibrium ``s0`` of ``s' = k(s, Lambda)`` (Eq. 14) is asymptotically
stable when every eigenvalue ``lambda_i`` of the Jacobian ``J = dk/ds |_(s0, Lambda)`` satisfies
``Re(lambda_i) < 0``.  We use the analytic sparse Jacobian of :class:`~gfb_env.model.GFBModel`, densified
(``n = 472`` on the paper grid, a dense QR eigenvalue solve takes ~60 ms) and solved with LAPACK
``geev`` via :func:`scipy.linalg.eigvals`.

The rightmost eigenvalue ``lambda_1 = sigma + i omega`` gives the growth rate ``sigma`` and the whirl
frequency ratio ``omega / Lambda`` (whirl frequency over rotor speed; about 1/2 for oil/gas whirl).
The critical bearing number is the first root of

    g(Lambda) = max_i Re(lambda_i(Lambda))

above a stable operating point (the Poincare-Andronov-Hopf point): a coarse scan in ``Lambda`` with
warm-started equilibria brackets the sign change, then Brent's method (:func:`scipy.optimize.brentq`)
refines it to ``xtol``.  ``g`` is continuous (a maximum of continuous functions), so the bracket is
sound even when the rightmost mode changes.  The transversality (crossing speed) ``d sigma / d Lambda``
at ``Lambda_c`` is reported from a central difference.

References: Leister, Baum & Seemann (2017), Sect. 3.2; Kuznetsov, *Elements of Applied Bifurcation
Theory*, 3rd ed., Sect. 3.4-3.5 (Hopf conditions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from gfb_env.equilibrium import EquilibriumError, find_equilibrium
from gfb_env.model import GFBModel, Structure
from gfb_env.params import check_positive

__all__ = [
    "StabilityAnalysisError",
    "NoStableEquilibriumError",
    "NoCriticalPointError",
    "Stability",
    "CriticalPoint",
    "jacobian_eigenvalues",
    "check_eigen_size",
    "MAX_EIGEN_STATE_SIZE",
    "MAX_SCAN_POINTS",
    "linear_stability",
    "critical_bearing_number",
    "SPINUP_STEP",
    "spinup_equilibria",
    "spinup_equilibrium",
]


class StabilityAnalysisError(RuntimeError):
    """Base class of the stability-analysis failures."""


class NoStableEquilibriumError(StabilityAnalysisError):
    """No stable equilibrium exists in the scanned range of bearing numbers (e.g. a too-soft foil)."""


class NoCriticalPointError(StabilityAnalysisError):
    """The equilibrium stays stable up to the end of the scanned range: ``Lambda_c`` lies beyond it."""


#: Largest state size ``n`` whose dense eigenvalue solve is allowed.  Measured (scipy ``eigvals``,
#: one thread): n = 472 (paper grid 79x7) 0.08 s, n = 1000 0.45 s, n = 2000 3.9 s and 64 MB per
#: dense copy; the O(n^3) solve would take ~4 min at n = 7492 (313x25).  A ``Lambda_c`` search does
#: about 70 solves, so n = 2000 is already ~5 min.  Viscoelastic grids up to 157x13 and 79x25 fit.
MAX_EIGEN_STATE_SIZE = 2000

#: Largest number of coarse scan points of :func:`critical_bearing_number` (default: 59).
MAX_SCAN_POINTS = 1000

#: Load step in ``Lambda`` of the frictional foil's quasi-static spin-up (:func:`spinup_equilibria`):
#: 21x5, K_W = 1, K_T = 0.5, mu_C = 0.1, Lambda_c with the sliders held is the same to 1e-4 at 0.004,
#: 0.002 and 0.001 (docs/analysis.md, "Dry friction").
SPINUP_STEP = 0.002


def check_eigen_size(model: GFBModel) -> None:
    """Refuse (``ValueError`` naming ``grid``) a model too large for the dense eigenvalue solve."""
    n = model.layout.size
    if n > MAX_EIGEN_STATE_SIZE:
        raise ValueError(
            f"grid {model.grid} is too large for the dense eigenvalue analysis: state size {n} "
            f"({model.structure.value}) > {MAX_EIGEN_STATE_SIZE} (e.g. 157x13 and 79x25 fit)"
        )


def jacobian_eigenvalues(
    model: GFBModel,
    state: np.ndarray,
    bearing_number: float,
    foil_damping: float = 1.0,
    sliders_on_limit: str = "stick",
) -> np.ndarray:
    """All eigenvalues of ``J = dk/ds`` at ``state``, sorted by decreasing real part.

    ``sliders_on_limit`` (frictional foil only): how a slider on its Coulomb limit is linearised,
    ``"stick"`` (held: the small-perturbation limit) or ``"slip"`` (the spin-up's load-path tangent);
    see :meth:`GFBModel.linearised_jacobian`.

    Raises ``ValueError`` when the state size exceeds :data:`MAX_EIGEN_STATE_SIZE`."""
    check_eigen_size(model)
    J, keep = model.linearised_jacobian(state, bearing_number, foil_damping, sliders_on_limit)
    J = J.toarray()
    if keep is not None:  # frictional: held sliders are neutral (an exact zero eigenvalue each), dropped
        J = J[np.ix_(keep, keep)]
    ev = sla.eigvals(J, overwrite_a=True, check_finite=False)
    return ev[np.argsort(-ev.real, kind="stable")]


@dataclass(frozen=True)
class Stability:
    """Linear stability of one equilibrium.

    Attributes:
        bearing_number: ``Lambda``.
        foil_damping: ``D_W``.
        eigenvalues: all eigenvalues of the Jacobian, by decreasing real part.
        state: the equilibrium ``s0``.
        eccentricity: ``eps`` of the equilibrium.
    """

    bearing_number: float
    foil_damping: float
    eigenvalues: np.ndarray = field(repr=False)
    state: np.ndarray = field(repr=False)
    eccentricity: float

    @property
    def rightmost(self) -> complex:
        """Rightmost eigenvalue (the one with positive imaginary part for a complex pair)."""
        top = self.eigenvalues[0]
        return complex(top.real, abs(top.imag))

    @property
    def growth_rate(self) -> float:
        """``max Re(lambda_i)`` (negative: stable)."""
        return float(self.eigenvalues[0].real)

    @property
    def whirl_frequency(self) -> float:
        """``|Im(lambda_1)|``, the angular frequency of the rightmost mode (rad per unit tau)."""
        return float(abs(self.eigenvalues[0].imag))

    @property
    def whirl_frequency_ratio(self) -> float:
        """``|Im(lambda_1)| / Lambda``."""
        return self.whirl_frequency / self.bearing_number

    @property
    def stable(self) -> bool:
        return self.growth_rate < 0.0


def linear_stability(
    model: GFBModel,
    bearing_number: float,
    foil_damping: float = 1.0,
    state: np.ndarray | None = None,
    guess: np.ndarray | None = None,
    sliders_on_limit: str = "stick",
) -> Stability:
    """Equilibrium at ``bearing_number`` (solved unless ``state`` is given) and its eigenvalues
    (``sliders_on_limit``: frictional foil only, see :func:`jacobian_eigenvalues`).

    Raises:
        ValueError: for a non-positive ``bearing_number`` or ``foil_damping``.
        gfb_env.EquilibriumError: when no equilibrium is found.
    """
    lam = check_positive("bearing_number", bearing_number)
    dw = check_positive("foil_damping", foil_damping)
    if state is None:
        state = find_equilibrium(model, lam, guess=guess)
    ev = jacobian_eigenvalues(model, state, lam, dw, sliders_on_limit)
    return Stability(lam, dw, ev, np.asarray(state, dtype=float), model.eccentricity(state))


@dataclass(frozen=True)
class CriticalPoint:
    """The onset of self-excited whirl (Hopf point) of one bearing configuration.

    Attributes:
        critical_bearing_number: ``Lambda_c`` (max Re(lambda) = 0).
        critical_speed_rpm: rotor speed at ``Lambda_c`` for the model's dimensional parameters.
        whirl_frequency_ratio: ``Im(lambda_1) / Lambda_c`` of the critical pair.
        eccentricity_at_onset: ``eps`` of the equilibrium at ``Lambda_c``.
        whirl_frequency: ``Im(lambda_1)`` at ``Lambda_c`` (rad per unit tau).
        crossing_speed: ``d Re(lambda_1) / d Lambda`` at ``Lambda_c`` (> 0: transversal crossing).
        structure, foil_stiffness, foil_damping, grid: the configuration.
        evaluations: number of eigenvalue solves used.
        state: the equilibrium at ``Lambda_c``.
    """

    critical_bearing_number: float
    critical_speed_rpm: float
    whirl_frequency_ratio: float
    eccentricity_at_onset: float
    whirl_frequency: float
    crossing_speed: float
    structure: str
    foil_stiffness: float
    foil_damping: float
    grid: str
    evaluations: int
    state: np.ndarray = field(repr=False)

    def as_dict(self) -> dict:
        """JSON-ready dict (without the state)."""
        return {
            "critical_bearing_number": self.critical_bearing_number,
            "critical_speed_rpm": self.critical_speed_rpm,
            "whirl_frequency_ratio": self.whirl_frequency_ratio,
            "eccentricity_at_onset": self.eccentricity_at_onset,
            "whirl_frequency": self.whirl_frequency,
            "crossing_speed": self.crossing_speed,
            "structure": self.structure,
            "foil_stiffness": self.foil_stiffness,
            "foil_damping": self.foil_damping,
            "grid": self.grid,
            "evaluations": self.evaluations,
        }


def critical_bearing_number(
    model: GFBModel,
    foil_damping: float = 1.0,
    bearing_range: tuple[float, float] = (0.1, 3.0),
    scan_step: float = 0.05,
    xtol: float = 1e-5,
    *,
    history: str = "spinup",
    sliders_on_limit: str = "stick",
    spinup_step: float = SPINUP_STEP,
) -> CriticalPoint:
    """Critical bearing number ``Lambda_c``: the first ``Lambda`` above a stable equilibrium where
    ``max Re(lambda_i)`` crosses zero.

    Frictional foil: an equilibrium depends on the loading history (every slider position with
    ``|F| <= F_c`` is at rest), so the one used is that of a quasi-static spin-up (``history="spinup"``,
    the default): from the unloaded start at ``bearing_range[0]``, ``Lambda`` marched up in steps of
    ``spinup_step``, each equilibrium warm-started from the previous one only (:func:`spinup_equilibria`);
    the eigenvalues are taken every ``scan_step`` and the crossing refined by brent's method on the same
    spin-up.  Sliders on their limit are held (``sliders_on_limit="stick"``, the small-perturbation limit;
    :meth:`GFBModel.linearised_jacobian`).  ``history="scan"`` is the plain scan below with each
    equilibrium warm-started from the nearest solved one (a history of load stages and brent's iterates
    from both sides, kept to reproduce ``gfb_experiments.friction_onset``).  The other structures ignore
    the three keyword arguments (one equilibrium per ``Lambda``).

    The scan walks up from ``bearing_range[0]`` in steps of ``scan_step`` (warm-started equilibria);
    the first stable-to-unstable sign change is refined by :func:`scipy.optimize.brentq` to ``xtol``
    (default 1e-5, well inside the 1e-4 the issue asks for).

    Args:
        model: the coupled model (its structure, grid and ``K_W`` define the configuration).
        foil_damping: ``D_W`` (only the viscoelastic foil uses it).
        bearing_range: ``(Lambda_min, Lambda_max)`` scanned.
        scan_step: coarse scan step in ``Lambda``.
        xtol: absolute tolerance on ``Lambda_c``.

    Raises:
        ValueError: invalid arguments (naming the field).
        NoStableEquilibriumError: no scanned equilibrium is stable (or none exists), e.g. a too-soft
            elastic foil (paper Sect. 3.2).
        NoCriticalPointError: stable up to ``bearing_range[1]``.
    """
    dw = check_positive("foil_damping", foil_damping)
    lo, hi = (float(bearing_range[0]), float(bearing_range[1]))
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"bearing_range must satisfy 0 < min < max, got {bearing_range!r}")
    step = check_positive("scan_step", scan_step)
    check_positive("xtol", xtol)
    n_scan = (hi - lo) / step + 1
    if n_scan > MAX_SCAN_POINTS:
        raise ValueError(
            f"scan_step {step:g} over bearing_range [{lo:g}, {hi:g}] gives {n_scan:.3g} scan points, "
            f"at most {MAX_SCAN_POINTS} (scan_step >= {(hi - lo) / (MAX_SCAN_POINTS - 1):.3g})"
        )
    check_eigen_size(model)
    if model.structure is Structure.FRICTIONAL:
        if history not in ("spinup", "scan"):
            raise ValueError(f"history must be 'spinup' or 'scan', got {history!r}")
        if history == "spinup":
            return _spinup_critical(
                model, (lo, hi), step, xtol, check_positive("spinup_step", spinup_step), sliders_on_limit
            )
    else:
        sliders_on_limit = "stick"  # ignored: no sliders
    evals = 0
    cache: dict[float, np.ndarray] = {}
    last_state: list[np.ndarray | None] = [None]

    def g(lam: float) -> float:
        nonlocal evals
        # warm start from the nearest solved equilibrium
        guess = None
        if cache:
            near = min(cache, key=lambda x: abs(x - lam))
            guess = cache[near]
        st = linear_stability(model, lam, dw, guess=guess, sliders_on_limit=sliders_on_limit)
        evals += 1
        cache[lam] = st.state
        last_state[0] = st.state
        return st.growth_rate

    lams = np.arange(lo, hi + 0.5 * step, step)
    lams[-1] = min(lams[-1], hi)
    prev_lam, prev_g = None, None
    seen_stable = False
    n_eq = 0
    for lam in lams:
        try:
            gv = g(float(lam))
        except EquilibriumError:
            prev_lam, prev_g = None, None
            continue
        n_eq += 1
        if gv < 0:
            seen_stable = True
        elif seen_stable and prev_g is not None and prev_g < 0:
            a, b = prev_lam, float(lam)
            lam_c = brentq(g, a, b, xtol=xtol, rtol=4 * np.finfo(float).eps)
            return _critical_point(model, lam_c, dw, cache, evals, sliders_on_limit)
        prev_lam, prev_g = float(lam), gv
    cfg = f"{model.structure.value} K_W={model.foil_stiffness:.4g} D_W={dw:.4g} grid {model.grid}"
    if not seen_stable:
        what = "no equilibrium" if n_eq == 0 else "no stable equilibrium"
        raise NoStableEquilibriumError(
            f"{what} for Lambda in [{lo:g}, {hi:g}] ({cfg}): the system whirls at every speed"
        )
    raise NoCriticalPointError(f"the equilibrium is still stable at Lambda={hi:g} ({cfg})")


def _critical_point(
    model: GFBModel, lam_c: float, dw: float, cache: dict, evals: int, sliders_on_limit: str = "stick"
) -> CriticalPoint:
    near = min(cache, key=lambda x: abs(x - lam_c))
    kw = {"sliders_on_limit": sliders_on_limit}
    st = linear_stability(model, lam_c, dw, guess=cache[near], **kw)
    d = 1e-3
    gp = linear_stability(model, lam_c + d, dw, guess=st.state, **kw).growth_rate
    gm = linear_stability(model, lam_c - d, dw, guess=st.state, **kw).growth_rate
    return _point(model, lam_c, dw, st, gp, gm, d, evals + 3)


def _point(
    model: GFBModel, lam_c: float, dw: float, st: Stability, gp: float, gm: float, d: float, evals: int
) -> CriticalPoint:
    return CriticalPoint(
        critical_bearing_number=float(lam_c),
        critical_speed_rpm=float(model.bearing.speed_rpm_at(lam_c)),
        whirl_frequency_ratio=st.whirl_frequency_ratio,
        eccentricity_at_onset=st.eccentricity,
        whirl_frequency=st.whirl_frequency,
        crossing_speed=float((gp - gm) / (2 * d)),
        structure=model.structure.value,
        foil_stiffness=float(model.foil_stiffness),
        foil_damping=float(dw),
        grid=str(model.grid),
        evaluations=evals,
        state=st.state,
    )


def spinup_equilibria(model: GFBModel, bearing_numbers, start: np.ndarray | None = None):
    """The equilibria of a quasi-static spin-up through the increasing ``bearing_numbers``: each solved
    from the previous one only (the frictional foil's sliders see the load path of a slow run-up; one load
    stage per step), the first from ``start`` (None: the unloaded centred journal).  Yields
    ``(Lambda, state)``.  Speeds before the first equilibrium found are skipped (the spin-up starts
    there: a coarse grid may have none at low speed); after it, raises :class:`gfb_env.EquilibriumError`
    where one is not found."""
    s = start
    prev = -math.inf
    started = False
    for lam in bearing_numbers:
        lam = float(lam)
        if not lam > prev:
            raise ValueError(f"bearing_numbers must increase, got {lam:g} after {prev:g}")
        prev = lam
        try:
            s = find_equilibrium(model, lam, guess=s)
        except EquilibriumError:
            if started:
                raise
            continue
        started = True
        yield lam, s


def spinup_equilibrium(
    model: GFBModel, bearing_number: float, start: float = 0.1, step: float = SPINUP_STEP
) -> np.ndarray:
    """The equilibrium at ``bearing_number`` of the quasi-static spin-up from ``start`` in steps of
    ``step`` (the one :func:`critical_bearing_number` uses for the frictional foil with the same
    ``bearing_range[0]`` and ``spinup_step``; for the other structures simply the equilibrium)."""
    lam = check_positive("bearing_number", bearing_number)
    if not 0 < start <= lam:
        raise ValueError(f"start must lie in (0, bearing_number], got {start!r}")
    h = check_positive("step", step)
    march = [*np.arange(start, lam, h), lam] if start < lam else [lam]
    s = None
    for _, state in spinup_equilibria(model, march):
        s = state
    if s is None:
        raise EquilibriumError(f"no equilibrium on the spin-up from {start:g} to {lam:g}")
    return s


def _spinup_critical(
    model: GFBModel,
    bearing_range: tuple[float, float],
    scan_step: float,
    xtol: float,
    spinup_step: float,
    sliders_on_limit: str,
) -> CriticalPoint:
    """:func:`critical_bearing_number` of the frictional foil along its quasi-static spin-up (the march
    of :func:`spinup_equilibria`, from the first ``Lambda`` of the range with an equilibrium)."""
    lo, hi = bearing_range
    lams = np.arange(lo, hi + 0.5 * spinup_step, spinup_step)
    lams[-1] = min(lams[-1], hi)
    every = max(1, int(round(scan_step / spinup_step)))
    march_lam: list[float] = []
    march_state: list[np.ndarray] = []
    evals = 0

    def below(lam: float) -> np.ndarray:
        """The spin-up's last equilibrium strictly below ``lam`` (its history up to ``lam``)."""
        j = int(np.searchsorted(march_lam, lam, side="left")) - 1
        if j < 0:
            raise ValueError(f"Lambda={lam:g} is below the spin-up's start {march_lam[0]:g}")
        return march_state[j]

    def growth(lam: float, s: np.ndarray | None = None) -> Stability:
        nonlocal evals
        evals += 1
        if s is None:
            s = find_equilibrium(model, lam, guess=below(lam))
        return linear_stability(model, lam, state=s, sliders_on_limit=sliders_on_limit)

    cfg = f"frictional K_W={model.foil_stiffness:.4g} grid {model.grid}"
    prev: tuple[float, float] | None = None
    seen_stable = False
    s: np.ndarray | None = None
    try:
        for i, lam in enumerate(map(float, lams)):
            try:
                s = find_equilibrium(model, lam, guess=s)
            except EquilibriumError:
                if march_lam:
                    raise
                continue  # the spin-up starts at the first speed with one (low speeds may have none)
            march_lam.append(lam)
            march_state.append(s)
            if i % every and i != len(lams) - 1:
                continue
            gv = growth(lam, s).growth_rate
            if gv < 0:
                seen_stable = True
            elif seen_stable and prev is not None:
                lam_c = brentq(
                    lambda x: growth(x).growth_rate, prev[0], lam, xtol=xtol, rtol=4 * np.finfo(float).eps
                )
                d = 1e-3
                st = growth(lam_c)
                gp = growth(lam_c + d, find_equilibrium(model, lam_c + d, guess=st.state)).growth_rate
                gm = growth(lam_c - d).growth_rate
                return _point(model, lam_c, 1.0, st, gp, gm, d, evals)
            prev = (lam, gv)
    except EquilibriumError as exc:
        if not seen_stable:
            raise NoStableEquilibriumError(f"no stable equilibrium on the spin-up ({cfg}): {exc}") from None
        raise StabilityAnalysisError(f"the spin-up lost its equilibrium ({cfg}): {exc}") from None
    if not seen_stable:
        raise NoStableEquilibriumError(
            f"no stable equilibrium for Lambda in [{lo:g}, {hi:g}] ({cfg}): the system whirls at every speed"
        )
    raise NoCriticalPointError(f"the equilibrium is still stable at Lambda={hi:g} ({cfg})")
