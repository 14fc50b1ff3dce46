"""The linear unbalance response (the classic Bode plot) and its transient check.

At constant speed the unbalance of :mod:`gfb_env.forcing` adds the rotor acceleration
``U Lambda^2 (sin theta, cos theta)`` with ``theta = Lambda tau + theta_0``: in complex form
``Re(b e^{i theta})`` with ``b_xi' = -i U Lambda^2`` and ``b_eta' = U Lambda^2`` in the rows of xi'' and
eta'' (the velocity rows of the state).  Linearised about the equilibrium ``s0`` (``s = s0 + Re(z
e^{i theta})``) the steady synchronous orbit solves

    (i Lambda I - J) z = b,

J the analytic Jacobian at ``s0`` (sparse LU; ``n = 472`` on the paper grid).  Below ``Lambda_c`` (every
eigenvalue in the left half-plane) it is the orbit a transient run settles on for small U, which
:func:`transient_synchronous_orbit` measures: the cheap, exact check of any transient code.

The rotor position ``xi(tau) = |z_xi| cos(theta + arg z_xi)`` (and eta alike): zero-to-peak amplitudes
``|z_xi|``, ``|z_eta|`` in units of C.  Phases are given as the lag of each displacement behind the
unbalance force in the same direction (``-arg(z / b)`` per coordinate, unwrapped along a speed range): 0
in the stiffness-controlled range, 90 degrees at a resonance, 180 above it.  The orbit is an ellipse; in
the complex coordinate ``w = eta + i xi`` (the unbalance mass sits at ``e^{i theta}``: the rotation is
the positive sense of w) ``w = A_f e^{i theta} + A_b e^{-i theta}`` with ``A_f = (z_eta + i z_xi)/2`` and
``A_b = (conj z_eta + i conj z_xi)/2``: semi-axes ``|A_f| +- |A_b|``, a forward whirl (turning with the
rotation) when ``|A_f| > |A_b|``.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "UnbalanceResponse",
    "unbalance_response",
    "response_curve",
    "ResponseCurve",
    "SynchronousOrbit",
    "synchronous_components",
    "transient_synchronous_orbit",
]


def _magnitude(unbalance: float | Unbalance) -> Unbalance:
    if isinstance(unbalance, Unbalance):
        return unbalance
    return Unbalance(unbalance)


@dataclass(frozen=True)
class UnbalanceResponse:
    """The synchronous response at one speed: complex amplitudes ``xi``, ``eta`` (the displacement is
    ``Re(z e^{i theta})``, theta the rotation angle plus the unbalance phase) and the stability of the
    equilibrium it is linearised about (None if not computed)."""

    bearing_number: float
    foil_damping: float
    unbalance: float
    xi: complex
    eta: complex
    stable: bool | None = None
    growth_rate: float | None = None  # max Re(lambda) of J

    @property
    def xi_amplitude(self) -> float:
        return abs(self.xi)

    @property
    def eta_amplitude(self) -> float:
        return abs(self.eta)

    @property
    def xi_phase_deg(self) -> float:
        """Lag of xi behind the unbalance force's xi component (``-arg(z_xi / (-i))``)."""
        return -math.degrees(np.angle(self.xi / -1j))

    @property
    def eta_phase_deg(self) -> float:
        """Lag of eta behind the unbalance force's eta component (``-arg z_eta``)."""
        return -math.degrees(np.angle(self.eta))

    @property
    def forward_amplitude(self) -> float:
        return abs(self.eta + 1j * self.xi) / 2.0

    @property
    def backward_amplitude(self) -> float:
        return abs(np.conj(self.eta) + 1j * np.conj(self.xi)) / 2.0

    @property
    def semi_major(self) -> float:
        return self.forward_amplitude + self.backward_amplitude

    @property
    def semi_minor(self) -> float:
        return abs(self.forward_amplitude - self.backward_amplitude)

    @property
    def forward(self) -> bool:
        """Whether the orbit turns with the rotation (forward whirl)."""
        return self.forward_amplitude > self.backward_amplitude

    def as_dict(self) -> dict:
        return {
            "bearing_number": self.bearing_number,
            "foil_damping": self.foil_damping,
            "unbalance": self.unbalance,
            "xi_amplitude": self.xi_amplitude,
            "eta_amplitude": self.eta_amplitude,
            "xi_phase_deg": self.xi_phase_deg,
            "eta_phase_deg": self.eta_phase_deg,
            "semi_major": self.semi_major,
            "semi_minor": self.semi_minor,
            "forward": self.forward,
            "stable": self.stable,
            "growth_rate": self.growth_rate,
        }


def unbalance_response(
    model: GFBModel,
    bearing_number: float,
    unbalance: float | Unbalance,
    foil_damping: float = 1.0,
    state: np.ndarray | None = None,
    stability: bool = True,
) -> UnbalanceResponse:
    """Solve ``(i Lambda I - J) z = b`` at the equilibrium (``state``, or found) for the unbalance
    (U, or an :class:`~gfb_env.forcing.Unbalance`; z is relative to the heavy spot's angle, so its phase
    does not enter).  ``stability`` adds the
    rightmost eigenvalue of J (a dense solve) so that a response above ``Lambda_c`` is flagged."""
    model.check_operating_point(bearing_number, foil_damping)
    ub = _magnitude(unbalance)
    lam = float(bearing_number)
    s0 = find_equilibrium(model, lam) if state is None else model.layout.check(state)
    J = model.jacobian(s0, lam, foil_damping)
    L = model.layout
    n = L.size
    b = np.zeros(n, dtype=complex)
    b[L.xi_dot_index] = -1j * ub.magnitude * lam * lam
    b[L.eta_dot_index] = ub.magnitude * lam * lam
    A = (1j * lam * sp.identity(n, format="csc") - J.astype(complex)).tocsc()
    z = spla.spsolve(A, b)  # relative to the heavy spot's angle theta + phase: the phase drops out
    stable = growth = None
    if stability:
        from gfb_env.analysis.stability import jacobian_eigenvalues

        growth = float(jacobian_eigenvalues(model, s0, lam, foil_damping)[0].real)
        stable = growth < 0.0
    return UnbalanceResponse(
        lam,
        float(foil_damping),
        ub.magnitude,
        complex(z[L.xi_index]),
        complex(z[L.eta_index]),
        stable,
        growth,
    )


@dataclass(frozen=True)
class ResponseCurve(Sequence):
    """The unbalance response over speed (a sequence of :class:`UnbalanceResponse`, by increasing
    ``Lambda``) and what is read off it: its peak, where it turns unstable, the table of ``gfb
    response``'s ``response.csv`` and its figure (:meth:`plot`).

    Attributes:
        responses: one per speed; bearing: the dimensional bearing (rpm, um); unbalance: the forcing;
        structure, foil_stiffness, grid: the model.
    """

    responses: tuple[UnbalanceResponse, ...]
    bearing: BearingParameters
    unbalance: Unbalance
    structure: str
    foil_stiffness: float
    grid: str

    #: Columns of :meth:`rows` and :meth:`write_csv`.
    COLUMNS = (
        "speed_rpm", "bearing_number", "xi_amplitude", "eta_amplitude", "xi_phase_deg", "eta_phase_deg",
        "semi_major", "semi_minor", "forward", "stable", "growth_rate", "xi_amplitude_um", "eta_amplitude_um",
        "semi_major_um", "semi_minor_um",
    )  # fmt: skip

    def __len__(self) -> int:
        return len(self.responses)

    def __getitem__(self, i):  # noqa: ANN001 - an index or a slice, as a tuple takes
        return self.responses[i]

    def __iter__(self) -> Iterator[UnbalanceResponse]:
        return iter(self.responses)

    @property
    def bearing_number(self) -> np.ndarray:
        return np.array([r.bearing_number for r in self.responses])

    @property
    def speed_rpm(self) -> np.ndarray:
        return np.array([self.bearing.speed_rpm_at(r.bearing_number) for r in self.responses])

    @property
    def peak(self) -> UnbalanceResponse:
        """The largest orbit (semi-major axis) of the stable speeds (the first speed if none is stable)."""
        return max(
            (r for r in self.responses if r.stable), key=lambda r: r.semi_major, default=self.responses[0]
        )

    @property
    def first_unstable_bearing_number(self) -> float | None:
        """The lowest speed (Lambda) whose equilibrium is unstable: above it the linear response is void."""
        unstable = [r.bearing_number for r in self.responses if not r.stable]
        return min(unstable) if unstable else None

    def rows(self) -> list[tuple]:
        """One row per speed (:attr:`COLUMNS`), the phases unwrapped along the speeds (a lag growing
        through 90 degrees at a resonance)."""
        b = self.bearing
        xi_ph = np.degrees(np.unwrap(np.radians([r.xi_phase_deg for r in self.responses])))
        eta_ph = np.degrees(np.unwrap(np.radians([r.eta_phase_deg for r in self.responses])))
        return [
            (
                b.speed_rpm_at(r.bearing_number),
                r.bearing_number,
                r.xi_amplitude,
                r.eta_amplitude,
                float(pxi),
                float(peta),
                r.semi_major,
                r.semi_minor,
                int(r.forward),
                int(bool(r.stable)),
                r.growth_rate,
                b.micrometres(r.xi_amplitude),
                b.micrometres(r.eta_amplitude),
                b.micrometres(r.semi_major),
                b.micrometres(r.semi_minor),
            )  # fmt: skip
            for r, pxi, peta in zip(self.responses, xi_ph, eta_ph, strict=True)
        ]

    def write_csv(self, path: str | Path) -> Path:
        """:meth:`rows` with a header (8 significant digits): ``gfb response``'s ``response.csv``."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(self.COLUMNS)
            for row in self.rows():
                w.writerow([f"{x:.8g}" if isinstance(x, float) else x for x in row])
        return path

    def plot(self, at: UnbalanceResponse | None = None, path: str | Path | None = None) -> Figure:
        """The Bode plot and orbit axes (:func:`gfb_env.plotting.plot_response`), ``at`` (default
        :attr:`peak`) marked."""
        from gfb_env.plotting import plot_response

        return plot_response(self, at, path)


def response_curve(
    model: GFBModel,
    bearing_numbers: np.ndarray,
    unbalance: float | Unbalance,
    foil_damping: float = 1.0,
    stability: bool = True,
) -> ResponseCurve:
    """:func:`unbalance_response` over increasing bearing numbers (equilibria warm-started)."""
    out = []
    guess = None
    for lam in np.asarray(bearing_numbers, dtype=float):
        s0 = find_equilibrium(model, float(lam), guess=guess)
        guess = s0
        out.append(unbalance_response(model, float(lam), unbalance, foil_damping, s0, stability))
    return ResponseCurve(
        tuple(out), model.bearing, _magnitude(unbalance), model.structure.value, float(model.foil_stiffness),
        str(model.grid),
    )  # fmt: skip


# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SynchronousOrbit:
    """The 1x (synchronous) component of a transient run, in the convention of
    :class:`UnbalanceResponse` (``xi = mean + Re(z_xi e^{i theta})``), and the rms of what is left."""

    xi: complex
    eta: complex
    mean_xi: float
    mean_eta: float
    residual_rms: float

    def compare(self, linear: UnbalanceResponse) -> dict[str, float]:
        """This (transient) orbit against the ``linear`` one: its amplitudes, the relative errors of the
        complex amplitudes and the residual (``gfb response --verify``)."""
        return {
            "xi_amplitude": abs(self.xi),
            "eta_amplitude": abs(self.eta),
            "xi_relative_error": abs(self.xi - linear.xi) / abs(linear.xi),
            "eta_relative_error": abs(self.eta - linear.eta) / abs(linear.eta),
            "residual_rms": self.residual_rms,
        }


def synchronous_components(
    tau: np.ndarray, theta: np.ndarray, xi: np.ndarray, eta: np.ndarray
) -> SynchronousOrbit:
    """Least-squares fit of ``c + a cos theta - b sin theta`` (``z = a + i b``) to xi and eta."""
    A = np.column_stack([np.ones_like(theta), np.cos(theta), -np.sin(theta)])
    cx, rx, *_ = np.linalg.lstsq(A, xi, rcond=None)
    ce, re_, *_ = np.linalg.lstsq(A, eta, rcond=None)
    res = np.concatenate([xi - A @ cx, eta - A @ ce])
    return SynchronousOrbit(
        complex(cx[1], cx[2]),
        complex(ce[1], ce[2]),
        float(cx[0]),
        float(ce[0]),
        float(np.sqrt(np.mean(res**2))),
    )


def transient_synchronous_orbit(
    model: GFBModel,
    bearing_number: float,
    unbalance: float | Unbalance,
    foil_damping: float = 1.0,
    settle_time: float | None = None,
    periods: int = 8,
    samples_per_period: int = 32,
    rtol: float = 1e-7,
    atol: float = 1e-9,
) -> SynchronousOrbit:
    """Run the transient from the equilibrium with the unbalance switched on at tau = 0 (theta = 0),
    let it settle (default: 10 / |max Re(lambda)| of J, i.e. the slowest free mode decayed by e^-10)
    and fit the synchronous orbit over ``periods`` revolutions.  Needs a stable equilibrium."""
    from gfb_env.analysis.stability import jacobian_eigenvalues
    from gfb_env.integrator import TrapezoidalIntegrator

    lam = float(bearing_number)
    ub = _magnitude(unbalance)
    s0 = find_equilibrium(model, lam)
    if settle_time is None:
        growth = float(jacobian_eigenvalues(model, s0, lam, foil_damping)[0].real)
        if not growth < 0:
            raise ValueError(
                f"the equilibrium at Lambda={lam:g} is not stable (max Re(lambda) = {growth:.3g})"
            )
        settle_time = 10.0 / -growth
    period = 2.0 * math.pi / lam
    integ = TrapezoidalIntegrator(model, s0, lam, foil_damping, unbalance=ub, rtol=rtol, atol=atol)
    t_settle = math.ceil(settle_time / period) * period
    integ.advance(t_settle)
    dt = period / samples_per_period
    res = integ.advance(t_settle + periods * period + 0.5 * dt, record_interval=dt)
    tr = res.trajectory
    keep = tr.tau >= t_settle - 1e-9
    tau = tr.tau[keep][: periods * samples_per_period]
    theta = lam * tau + ub.phase_rad
    return synchronous_components(tau, theta, tr.xi[keep][: len(tau)], tr.eta[keep][: len(tau)])
