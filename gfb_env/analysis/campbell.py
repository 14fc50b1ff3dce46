"""Campbell diagram and logarithmic decrement of the rotor whirl modes over the speed (issue 12).

At each speed the static equilibrium ``s0(Lambda)`` is solved (warm-started from the previous speed)
and the eigenvalues ``lambda_i = sigma_i + i omega_i`` and right eigenvectors ``v_i`` of the analytic
Jacobian ``J = dk/ds`` are computed (:func:`scipy.linalg.eig`, dense; ``n = 472`` on the paper grid,
~0.08 s).  The state holds hundreds of gas-film (and foil) unknowns, so most eigenvalues are film
modes; the **rotor-dominated modes** are chosen by their *rotor participation*

    p_i = |v_i[xi, eta, xi', eta']|^2 / |v_i|^2,

the share of the eigenvector in the four rotor states: among the oscillating eigenvalues
(``omega_i > 0``, one of each conjugate pair) the ``n_modes`` with the largest ``p_i`` are kept and
ordered by frequency.  On the Table-1 bearing (79x7, Lambda 0.3-1.0) the whirl mode
(``omega / Lambda ~ 0.4-0.5``, the one that becomes unstable at ``Lambda_c``) has ``p ~ 0.06-0.13``,
the second rotor mode ``p ~ 0.01-0.03`` and the film modes ``p < 0.003``; at low speed
(``Lambda ~ 0.1``) the second rotor mode is weakly coupled and its choice less sharp.  (Modes are
ordered by frequency at each speed, not tracked through crossings.)

Conventions as in ROSS (``ross.Rotor.run_campbell``): damped natural frequency ``omega_d = Im(lambda)``,
damping ratio ``zeta = -Re(lambda) / |lambda|`` and logarithmic decrement
``delta = 2 pi zeta / sqrt(1 - zeta^2) = -2 pi Re(lambda) / Im(lambda)`` (negative: unstable).  In
physical units ``f = omega / (2 pi T)`` Hz (``T`` the time scale of the bearing); ``zeta`` and
``delta`` are dimensionless and the same in both unit systems.

The **onset** (zero log decrement) is the first speed where ``max Re`` over the rotor modes changes
sign from negative to positive, refined by Brent's method to ``xtol`` in ``Lambda``: it is the
critical bearing number ``Lambda_c`` of :func:`gfb_env.analysis.stability.critical_bearing_number`
when the critical mode is rotor-dominated (the test checks 1e-4).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from gfb_env.analysis.stability import check_eigen_size
from gfb_env.equilibrium import EquilibriumError, find_equilibrium
from gfb_env.model import GFBModel
from gfb_env.params import check_positive

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["CampbellDiagram", "campbell_diagram", "rotor_modes", "MAX_CAMPBELL_SPEEDS"]

#: At most this many speeds in one diagram (~0.1 s each on 79x7, 4 s each at the eigen-size limit).
MAX_CAMPBELL_SPEEDS = 1000


def rotor_modes(
    model: GFBModel, state: np.ndarray, bearing_number: float, foil_damping: float, n_modes: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_modes`` rotor-dominated eigenvalues (``Im > 0``, by increasing frequency) at ``state``
    and their rotor participations (see the module docstring)."""
    check_eigen_size(model)
    J = model.jacobian(state, bearing_number, foil_damping).toarray()
    w, V = sla.eig(J, overwrite_a=True, check_finite=False)
    r = model.layout.rotor_offset
    part = np.sum(np.abs(V[r : r + 4]) ** 2, axis=0) / np.sum(np.abs(V) ** 2, axis=0)
    # one of each conjugate pair; the tolerance keeps real eigenvalues (no whirl) out
    osc = np.nonzero(w.imag > 1e-9 * max(1.0, float(np.max(np.abs(w)))))[0]
    keep = osc[np.argsort(-part[osc], kind="stable")[:n_modes]]
    keep = keep[np.argsort(w[keep].imag, kind="stable")]
    ev = np.full(n_modes, complex(math.nan, math.nan))
    pp = np.full(n_modes, math.nan)
    ev[: len(keep)] = w[keep]
    pp[: len(keep)] = part[keep]
    return ev, pp


@dataclass(frozen=True)
class CampbellDiagram:
    """Rotor whirl modes over the speed.

    Attributes:
        bearing_number: ``Lambda`` of each speed, shape ``(n,)``; speed_rpm: the same in rpm.
        eigenvalues: the rotor-mode eigenvalues (rad per unit tau), ``(n, n_modes)``, NaN where no
            equilibrium was found.
        participation: their rotor participations.
        eccentricity: ``eps`` of each equilibrium.
        onset_bearing_number: zero log decrement (``None``: no sign change in the range).
        time_scale_s: ``T`` of the bearing (for Hz).
        structure, foil_stiffness, foil_damping, grid: the configuration.
    """

    bearing_number: np.ndarray
    speed_rpm: np.ndarray
    eigenvalues: np.ndarray = field(repr=False)
    participation: np.ndarray = field(repr=False)
    eccentricity: np.ndarray = field(repr=False)
    onset_bearing_number: float | None
    onset_speed_rpm: float | None
    onset_eigenvalue: complex | None
    time_scale_s: float
    structure: str
    foil_stiffness: float
    foil_damping: float
    grid: str

    @property
    def frequency_hz(self) -> np.ndarray:
        """Damped natural frequencies ``Im(lambda) / (2 pi T)`` in Hz."""
        return self.eigenvalues.imag / (2.0 * math.pi * self.time_scale_s)

    @property
    def damping_ratio(self) -> np.ndarray:
        """``zeta = -Re(lambda) / |lambda|``."""
        return -self.eigenvalues.real / np.abs(self.eigenvalues)

    @property
    def log_decrement(self) -> np.ndarray:
        """``delta = -2 pi Re(lambda) / Im(lambda)`` (negative: the mode grows)."""
        return -2.0 * math.pi * self.eigenvalues.real / self.eigenvalues.imag

    @property
    def whirl_frequency_ratio(self) -> np.ndarray:
        """``Im(lambda) / Lambda``: whirl frequency over rotor speed (the 1x line is 1)."""
        return self.eigenvalues.imag / self.bearing_number[:, None]

    @property
    def n_modes(self) -> int:
        """Rotor modes kept per speed."""
        return int(self.eigenvalues.shape[1])

    @property
    def onset_frequency_hz(self) -> float | None:
        """Whirl frequency at the onset in Hz (``None``: no onset in the range)."""
        on = self.onset_eigenvalue
        return None if on is None else on.imag / (2.0 * math.pi * self.time_scale_s)

    @property
    def onset_whirl_frequency_ratio(self) -> float | None:
        """Whirl frequency over rotor speed at the onset, ``Im(lambda) / Lambda_c`` (about 0.43-0.5)."""
        on = self.onset_eigenvalue
        return None if on is None else on.imag / self.onset_bearing_number

    def _min_log_decrement_index(self) -> tuple[int, int] | None:
        delta = self.log_decrement
        ok = np.isfinite(delta)
        if not ok.any():
            return None
        j, k = np.unravel_index(np.nanargmin(np.where(ok, delta, np.inf)), delta.shape)
        return int(j), int(k)

    @property
    def min_log_decrement(self) -> float | None:
        """The smallest log decrement over speeds and modes (``None``: no equilibrium at all)."""
        jk = self._min_log_decrement_index()
        return None if jk is None else float(self.log_decrement[jk])

    @property
    def min_log_decrement_speed_rpm(self) -> float | None:
        """The speed of :attr:`min_log_decrement` in rpm."""
        jk = self._min_log_decrement_index()
        return None if jk is None else float(self.speed_rpm[jk[0]])

    @property
    def equilibria_failed(self) -> int:
        """Speeds at which no equilibrium was found (their modes are NaN)."""
        return int(np.sum(~np.isfinite(self.eccentricity)))

    def summary(self) -> dict:
        """The scalar results (the keys of ``gfb campbell --json`` but ``files`` and ``wall_time_s``)."""
        lo, hi = float(self.bearing_number[0]), float(self.bearing_number[-1])
        return {
            "structure": self.structure,
            "grid": self.grid,
            "foil_stiffness": self.foil_stiffness,
            "foil_damping": self.foil_damping,
            "modes": self.n_modes,
            "n_speeds": len(self.bearing_number),
            "bearing_number_range": [lo, hi],
            "speed_rpm_range": [float(self.speed_rpm[0]), float(self.speed_rpm[-1])],
            "onset_bearing_number": self.onset_bearing_number,
            "onset_speed_rpm": self.onset_speed_rpm,
            "onset_frequency_hz": self.onset_frequency_hz,
            "onset_whirl_frequency_ratio": self.onset_whirl_frequency_ratio,
            "min_log_decrement": self.min_log_decrement,
            "min_log_decrement_speed_rpm": self.min_log_decrement_speed_rpm,
            "equilibria_failed": self.equilibria_failed,
        }

    #: Columns of :meth:`write_csv` (one row per speed and mode).
    CSV_COLUMNS = (
        "speed_rpm", "bearing_number", "mode", "frequency_hz", "angular_frequency", "whirl_frequency_ratio",
        "growth_rate", "damping_ratio", "log_decrement", "rotor_participation", "eccentricity",
    )  # fmt: skip

    def write_csv(self, path: str | Path) -> Path:
        """Write one row per speed and mode (:attr:`CSV_COLUMNS`, 8 significant digits): ``gfb campbell``'s
        ``campbell.csv``."""
        path = Path(path)
        f_hz, zeta, delta, ratio = (
            self.frequency_hz,
            self.damping_ratio,
            self.log_decrement,
            self.whirl_frequency_ratio,
        )
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(self.CSV_COLUMNS)
            for j in range(len(self.bearing_number)):
                for k in range(self.n_modes):
                    ev = self.eigenvalues[j, k]
                    w.writerow(
                        [f"{x:.8g}" if isinstance(x, float) else x for x in (
                            float(self.speed_rpm[j]), float(self.bearing_number[j]), k + 1, float(f_hz[j, k]),
                            float(ev.imag), float(ratio[j, k]), float(ev.real), float(zeta[j, k]),
                            float(delta[j, k]), float(self.participation[j, k]), float(self.eccentricity[j]),
                        )]
                    )  # fmt: skip
        return path

    def plot(self, path: str | Path | None = None, nondimensional: bool = False) -> Figure:
        """The Campbell diagram and the log decrement (:func:`gfb_env.plotting.plot_campbell`); saved to
        ``path`` when given."""
        from gfb_env.plotting import plot_campbell

        return plot_campbell(self, path, nondimensional)


def campbell_diagram(
    model: GFBModel,
    bearing_numbers: np.ndarray | list[float],
    foil_damping: float = 1.0,
    n_modes: int = 2,
    xtol: float = 1e-6,
) -> CampbellDiagram:
    """Rotor-mode eigenvalues at the equilibria of ``bearing_numbers`` and the onset of whirl.

    Args:
        model: the coupled model (its bearing gives the rpm and Hz).
        bearing_numbers: increasing positive ``Lambda`` values.
        foil_damping: ``D_W`` (viscoelastic foil only).
        n_modes: rotor modes kept (1..6; 2: the whirl mode and the second rotor mode).
        xtol: tolerance of the onset in ``Lambda``.

    Raises:
        ValueError: bad arguments (naming them) or a model too large for the dense eigen-analysis.
    """
    lams = np.asarray(bearing_numbers, dtype=float).ravel()
    if lams.size < 2 or not np.all(np.isfinite(lams)) or np.any(lams <= 0) or np.any(np.diff(lams) <= 0):
        raise ValueError("bearing_numbers must be at least 2 increasing positive numbers")
    if lams.size > MAX_CAMPBELL_SPEEDS:
        raise ValueError(f"bearing_numbers: {lams.size} speeds, at most {MAX_CAMPBELL_SPEEDS}")
    dw = check_positive("foil_damping", foil_damping)
    if not (isinstance(n_modes, int) and 1 <= n_modes <= 6):
        raise ValueError(f"n_modes must be an integer in [1, 6], got {n_modes!r}")
    check_eigen_size(model)
    n = lams.size
    ev = np.full((n, n_modes), complex(math.nan, math.nan))
    part = np.full((n, n_modes), math.nan)
    ecc = np.full(n, math.nan)
    states: dict[int, np.ndarray] = {}
    guess = None
    for j, lam in enumerate(lams):
        try:
            s = find_equilibrium(model, float(lam), guess=guess)
        except EquilibriumError:
            guess = None
            continue
        guess = states[j] = s
        ecc[j] = model.eccentricity(s)
        ev[j], part[j] = rotor_modes(model, s, float(lam), dw, n_modes)

    def growth(lam: float, guess: np.ndarray) -> float:
        s = find_equilibrium(model, lam, guess=guess)
        return float(np.nanmax(rotor_modes(model, s, lam, dw, n_modes)[0].real))

    onset = onset_ev = None
    g = np.nanmax(np.where(np.isnan(ev.real), -np.inf, ev.real), axis=1)
    for j in range(1, n):
        if j - 1 in states and j in states and g[j - 1] < 0 <= g[j]:
            guess = states[j - 1]
            onset = float(brentq(growth, lams[j - 1], lams[j], args=(guess,), xtol=xtol))
            s = find_equilibrium(model, onset, guess=guess)
            w = rotor_modes(model, s, onset, dw, n_modes)[0]
            onset_ev = complex(w[int(np.nanargmax(w.real))])
            break
    b = model.bearing
    return CampbellDiagram(
        bearing_number=lams,
        speed_rpm=np.array([b.speed_rpm_at(x) for x in lams]),
        eigenvalues=ev,
        participation=part,
        eccentricity=ecc,
        onset_bearing_number=onset,
        onset_speed_rpm=None if onset is None else b.speed_rpm_at(onset),
        onset_eigenvalue=onset_ev,
        time_scale_s=b.time_scale_s,
        structure=model.structure.value,
        foil_stiffness=float(model.foil_stiffness),
        foil_damping=dw,
        grid=str(model.grid),
    )
