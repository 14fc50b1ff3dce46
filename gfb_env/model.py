"""The fully coupled fluid-structure-rotor model of a gas foil bearing (paper Sect. 2).

Nondimensional equations (tau = t/T, lengths / C, pressures / p0):

* Film (Eq. 2), rotor in Cartesian coordinates ``xi = eps sin(gamma)`` (horizontal) and
  ``eta = eps cos(gamma)`` (vertical, along gravity)::

      H(phi, tau) = 1 - xi sin(phi) - eta cos(phi) - Q(phi, tau)

  The polar form of the paper is singular at eps = 0 (every centred start); eps and gamma are
  derived outputs here.
* Reynolds equation (Eq. 4), solved for the expansion term P'::

      H P' + P H' = 1/2 [ d/dphi(P H^3 dP/dphi) + kappa^2 d/dZ(P H^3 dP/dZ) - Lambda d/dphi(P H) ]

  periodic in phi, ``P = 1`` at ``Z = +-1/2``.
* Foil (Sect. 2.3), loaded by the axial mean ``Pbar = int P dZ`` (trapezoid rule with the edges):
  ``rigid``: Q = 0; ``elastic`` (Eq. 6-8): ``K_W Q = -(Pbar - 1)``, so Q' depends on P' and each
  column needs a rank-one (Sherman-Morrison) solve; ``viscoelastic`` (Eq. 9-10):
  ``D_W Q' + K_W Q = -(Pbar - 1)`` with Q a state; ``frictional`` (dry friction, beyond the paper):
  K_W in parallel with a Jenkins element (stick stiffness K_T in series with a Coulomb slider at S),
  ``K_W Q + K_T (Q - S) = -(Pbar - 1)`` with the slider position S a state and
  ``eta S' = sign(F) max(|F| - mu_C |Pbar - 1|, 0)``, ``F = K_T (Q - S)`` (see :class:`Structure`).
* Rotor (Eq. 11-12, per bearing): ``f = int int (P - 1) [sin phi, cos phi] dphi dZ`` and
  ``xi'' = -f_xi / M``, ``eta'' = G - f_eta / M``.

:class:`StateLayout` owns the state vector of Eq. (13); :class:`GFBModel` evaluates k(s, Lambda, D_W)
of Eq. (14), its analytic sparse Jacobian and the derived outputs.
"""

from __future__ import annotations

import enum
import math
import re
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from gfb_env import _kernels as K
from gfb_env.params import BearingParameters, FrictionParameters, NondimensionalParameters, check_positive

__all__ = [
    "Structure",
    "Grid",
    "StateLayout",
    "GFBModel",
    "KernelParameters",
    "MAX_JACOBIAN_BYTES",
    "BYTES_PER_BLOCK_ENTRY",
]

#: Measured peak bytes per block-Jacobian entry ``(N_phi-1) m^2`` (see :class:`Grid`).
BYTES_PER_BLOCK_ENTRY = 192
#: Largest estimated Jacobian memory a :class:`Grid` may need (1 GiB; see :class:`Grid`).
MAX_JACOBIAN_BYTES = 2**30


class Structure(enum.StrEnum):
    """Foil structure model (paper Sect. 2.3; ``frictional`` is the paper's named next step).

    ``frictional``: per column the foundation K_W in parallel with a Jenkins element, a stick stiffness
    K_T in series with a Coulomb slider at S (one state per column).  Friction force
    ``F = K_T (Q - S)``, force balance ``K_W Q + F = -(Pbar - 1)`` (so Q is algebraic given S and Pbar,
    and Q' = (K_T S' - Pbar') / (K_W + K_T) keeps the elastic foil's rank-one per-column solve).
    Coulomb limit ``F_c = mu_C N`` with the normal load ``N = |Pbar - 1| = |K_W Q + F|``, the load the
    foundation carries: Eq. (6)'s foundation is bilateral (it carries a sub-ambient column's suction
    like a pressure load), and the same magnitude presses its sliding contacts.  (With
    ``max(Pbar - 1, 0)`` every sub-ambient column would be frictionless, and mu_C -> infinity would not
    be the stuck foil.)  Slider law, regularised by one parameter, the slip viscosity eta:
    ``eta S' = sign(F) max(|F| - F_c, 0)`` (Perzyna viscoplasticity): exactly stuck (S' = 0) for every
    eta while ``|F| <= F_c``; slipping with the overstress ``|F| - F_c = eta |S'|``, which vanishes as
    eta -> 0 (the rate-independent Coulomb slider).  The law is continuous with a kink at the threshold
    (piecewise linear in F); a C1 law with an exact stick zone has zero slope at the threshold and would
    linearise the mu_C = 0 foil as stuck (K_W + K_T) instead of free (K_W).
    """

    RIGID = "rigid"
    ELASTIC = "elastic"
    VISCOELASTIC = "viscoelastic"
    FRICTIONAL = "frictional"

    @property
    def code(self) -> int:
        return {
            "rigid": K.RIGID,
            "elastic": K.ELASTIC,
            "viscoelastic": K.VISCOELASTIC,
            "frictional": K.FRICTIONAL,
        }[self.value]

    @property
    def has_foil_state(self) -> bool:
        """Whether the foil has one state per column (viscoelastic: Q; frictional: the slider S)."""
        return self in (Structure.VISCOELASTIC, Structure.FRICTIONAL)

    @classmethod
    def parse(cls, value: Structure | str) -> Structure:
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"structure must be one of {[s.value for s in cls]}, got {value!r}") from None


@dataclass(frozen=True)
class Grid:
    """Finite-difference grid of the gap: ``n_phi x n_z`` points as counted in the paper.

    ``n_phi`` includes the periodic duplicate (the paper's 79 points are 78 unique columns) and
    ``n_z`` includes the two ambient edges (7 points are 5 interior rows).  ``n_z`` must be odd so
    that the midplane Z = 0 is a grid row.

    Size limit: a grid whose :attr:`jacobian_bytes` exceeds :data:`MAX_JACOBIAN_BYTES` (1 GiB) is
    refused with a ``ValueError`` before anything is allocated.  The memory of every solver grows with
    the block Jacobian, ``N_phi - 1`` columns of ``m x m`` blocks with ``m = N_Z - 1`` unknowns per
    column in the worst case (viscoelastic: ``N_Z - 2`` pressures and ``Q``): the model's
    ``jacobian_blocks`` (three ``m x m`` blocks per column), the COO index arrays and data of
    ``jacobian`` and the sparse LU of ``find_equilibrium`` all scale with ``(N_phi - 1) m^2``.
    Measured peak memory of ``find_equilibrium`` (viscoelastic, Lambda = 0.6, one thread) above the
    ~270 MB of the imported package: 625x49 (1.44e6 block entries) +270 MB in 13 s; 1001x65 (4.10e6
    entries) +760 MB in 46 s, i.e. about 190 bytes per block entry, so :attr:`jacobian_bytes` counts
    :data:`BYTES_PER_BLOCK_ENTRY` = 192.  The limit admits 1001x65 (0.79 GB) and every grid of the
    grid-convergence study (finest 313x25, 0.03 GB), and refuses e.g. 2001x201 (80e6 entries,
    15 GB estimated; it really allocated 11 GB before this check).
    """

    n_phi: int = 79
    n_z: int = 7

    def __post_init__(self) -> None:
        if isinstance(self.n_phi, bool) or not isinstance(self.n_phi, (int, np.integer)) or self.n_phi < 9:
            raise ValueError(f"n_phi must be an integer >= 9, got {self.n_phi!r}")
        if isinstance(self.n_z, bool) or not isinstance(self.n_z, (int, np.integer)) or self.n_z < 3:
            raise ValueError(f"n_z must be an integer >= 3, got {self.n_z!r}")
        if self.n_z % 2 == 0:
            raise ValueError(f"n_z must be odd (the midplane Z = 0 must be a grid row), got {self.n_z}")
        need = self.jacobian_bytes
        if need > MAX_JACOBIAN_BYTES:
            raise ValueError(
                f"grid {self} is too large: its block Jacobian needs about {need / 1e9:.3g} GB "
                f"((N_phi-1)(N_Z-1)^2 x {BYTES_PER_BLOCK_ENTRY} B), the limit is "
                f"{MAX_JACOBIAN_BYTES / 2**30:g} GiB (e.g. 1001x65 fits)"
            )

    @classmethod
    def parse(cls, text: str) -> Grid:
        """``"79x7"`` -> ``Grid(79, 7)``."""
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
        if not m:
            raise ValueError(f"grid must look like '79x7' (N_phi x N_Z), got {text!r}")
        if max(len(m.group(1)), len(m.group(2))) > 18:  # int() of thousands of digits is itself slow
            shown = text.strip() if len(text.strip()) <= 40 else text.strip()[:37] + "..."
            raise ValueError(
                f"grid {shown} is too large: the limit is {MAX_JACOBIAN_BYTES / 2**30:g} GiB of block "
                "Jacobian memory (e.g. 1001x65 fits)"
            )
        return cls(int(m.group(1)), int(m.group(2)))

    @property
    def jacobian_bytes(self) -> int:
        """Estimated peak memory of the block Jacobian and its factorisation, in bytes (see the class
        docstring); Python integers, so a huge grid cannot overflow the estimate."""
        return BYTES_PER_BLOCK_ENTRY * (int(self.n_phi) - 1) * (int(self.n_z) - 1) ** 2

    def __str__(self) -> str:
        return f"{self.n_phi}x{self.n_z}"

    @property
    def n_columns(self) -> int:
        """Unique periodic columns ``N_phi - 1``."""
        return self.n_phi - 1

    @property
    def n_rows(self) -> int:
        """Interior rows ``N_Z - 2``."""
        return self.n_z - 2

    @property
    def dphi(self) -> float:
        return 2.0 * math.pi / self.n_columns

    @property
    def dz(self) -> float:
        return 1.0 / (self.n_z - 1)

    @property
    def phi(self) -> np.ndarray:
        """Angles of the unique columns, ``phi_i = i dphi``, i = 0..N_phi-2."""
        return np.arange(self.n_columns) * self.dphi

    @property
    def z(self) -> np.ndarray:
        """Axial coordinates of all rows including the edges, from -1/2 to +1/2."""
        return np.linspace(-0.5, 0.5, self.n_z)

    @property
    def midplane_row(self) -> int:
        """Index of the interior row at Z = 0."""
        return (self.n_rows - 1) // 2


class StateLayout:
    """Owner of the state vector of Eq. (13); nothing else indexes the state by hand.

    ``s = [P (N_phi-1)*(N_Z-2), phi-major; Q (N_phi-1), viscoelastic only, or the slider positions S
    (N_phi-1), frictional only; xi, eta, xi', eta']``.
    """

    def __init__(self, grid: Grid, structure: Structure | str):
        self.grid = grid
        self.structure = Structure.parse(structure)
        self.n_pressure = grid.n_columns * grid.n_rows
        self.n_foil = grid.n_columns if self.structure.has_foil_state else 0
        self.rotor_offset = self.n_pressure + self.n_foil
        self.size = self.rotor_offset + 4
        self.pressure_slice = slice(0, self.n_pressure)
        self.foil_slice = slice(self.n_pressure, self.rotor_offset)
        self.rotor_slice = slice(self.rotor_offset, self.size)
        self.xi_index = self.rotor_offset
        self.eta_index = self.rotor_offset + 1
        self.xi_dot_index = self.rotor_offset + 2
        self.eta_dot_index = self.rotor_offset + 3

    @property
    def block_size(self) -> int:
        """Unknowns per phi column in the Jacobian's block structure."""
        return self.grid.n_rows + (1 if self.n_foil else 0)

    def pressure(self, s: np.ndarray) -> np.ndarray:
        """Interior pressures as a view of shape ``(N_phi-1, N_Z-2)``."""
        return s[self.pressure_slice].reshape(self.grid.n_columns, self.grid.n_rows)

    def foil_state(self, s: np.ndarray) -> np.ndarray | None:
        """Foil state per column: the deflection Q_i (viscoelastic) or the slider position S_i
        (frictional); None for the rigid and elastic foils."""
        return s[self.foil_slice] if self.n_foil else None

    def rotor(self, s: np.ndarray) -> np.ndarray:
        """``[xi, eta, xi', eta']`` (a view)."""
        return s[self.rotor_slice]

    def pressure_index(self, column: int, row: int) -> int:
        """State index of the interior pressure ``P[column, row]``."""
        nc, nr = self.grid.n_columns, self.grid.n_rows
        if not (0 <= row < nr):
            raise ValueError(f"row must be in [0, {nr}), got {row}")
        return (column % nc) * nr + row

    def midplane_probe_indices(self, n_probes: int) -> np.ndarray:
        """State indices of ``n_probes`` midplane pressures equally spaced in phi from phi = 0."""
        if n_probes < 1 or n_probes > self.grid.n_columns:
            raise ValueError(f"n_probes must be in [1, {self.grid.n_columns}], got {n_probes}")
        cols = np.round(np.arange(n_probes) * self.grid.n_columns / n_probes).astype(int)
        return np.array([self.pressure_index(c, self.grid.midplane_row) for c in cols], dtype=np.int64)

    def centred_state(self) -> np.ndarray:
        """Centred journal at rest, ambient pressure, undeformed foil: an exact steady solution
        of the fluid equations (the rotor still falls under G)."""
        s = np.zeros(self.size)
        s[self.pressure_slice] = 1.0
        return s

    def with_rotor(self, s: np.ndarray, xi: float, eta: float, xi_dot: float = 0.0, eta_dot: float = 0.0):
        """A copy of ``s`` with the rotor state replaced."""
        out = np.array(s, dtype=float, copy=True)
        out[self.rotor_slice] = (xi, eta, xi_dot, eta_dot)
        return out

    def check(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        if s.shape != (self.size,):
            raise ValueError(
                f"state must have shape ({self.size},) for {self.structure.value} {self.grid}, got {s.shape}"
            )
        return s


class KernelParameters(NamedTuple):
    """What the compiled kernels of :mod:`gfb_env._kernels` know about a model, by name.

    Owned by :class:`GFBModel` (:attr:`GFBModel.kernel_parameters`); :meth:`GFBModel.kernel_args` packs
    them into the arrays the kernels take, so no other module indexes those arrays.
    """

    n_columns: int
    n_rows: int
    structure_code: int
    foil_stiffness: float
    kappa: float
    mass_parameter: float
    gravity_parameter: float
    sin_phi: np.ndarray
    cos_phi: np.ndarray
    stick_stiffness: float = 0.0
    friction_coefficient: float = 0.0
    slip_viscosity: float = 1.0


#: Default slip viscosity eta of the frictional foil's regularised Coulomb law (nondimensional, the
#: overstress per unit slider rate).  The slip relaxation time eta (K_W + K_T) / (K_W K_T) is then ~1e-3
#: for K ~ 1-2, far below the whirl period (~30): the loop energy of an imposed Q = q sin(tau) is within
#: 0.2-1.2 % of the rate-independent Jenkins loop at eta = 1e-3, and the error is O(eta) (0.02-0.12 % at
#: 1e-4).  Smaller eta costs hardly any integration steps: the Newton iteration solves the slider rows on
#: their branch (``_kernels.slider_return_map``), so steps cross the slip onsets' boundary layers of
#: width ~eta (``python -m gfb_experiments.bench_friction``, 79x7, Lambda = 0.7, mu_C = 0.1, 50 time
#: units: 85 / 84 / 93 steps at eta = 1e-2 / 1e-3 / 1e-4, against 41 for the viscoelastic foil).
DEFAULT_SLIP_VISCOSITY = 1e-3
#: Default Coulomb coefficient mu_C of the frictional foil.  Identified bump-foil friction coefficients
#: are about 0.05-0.2 (the range the literature on bump-foil damping uses, e.g. the structural tests of
#: Ku and Heshmat and of DellaCorte and co-workers at NASA Glenn; cited from memory, the exact reports
#: not checked here), so 0.1 is the middle of it.
DEFAULT_FRICTION_COEFFICIENT = 0.1


class GFBModel:
    """k(s, Lambda, D_W) of Eq. (14) with its analytic Jacobian and derived outputs.

    Args:
        structure: ``"rigid"``, ``"elastic"`` or ``"viscoelastic"``.
        grid: finite-difference grid (paper: 79 x 7).
        bearing: dimensional parameters (Table 1 by default); gives M, G, kappa and K_W.
        foil_stiffness: overrides the Walowit-Anno ``K_W`` of ``bearing``.
        stick_stiffness: ``K_T`` of the frictional foil (default: equal to ``K_W``).
        friction_coefficient: Coulomb coefficient ``mu_C`` of the frictional foil (default 0.1, >= 0).
        slip_viscosity: regularisation ``eta`` of the frictional foil's slider law (default 1e-3,
            :data:`DEFAULT_SLIP_VISCOSITY`).
        friction: the frictional foil's physical inputs (a bearing file's ``[friction]`` table,
            :class:`~gfb_env.params.FrictionParameters`): its ``mu_C`` and its ``K_T`` (per unit area,
            ``K_T = k_T C / p0``, or as a ratio to K_W) where ``stick_stiffness`` and
            ``friction_coefficient`` are not given (those override it).

    The frictional parameters are refused (``ValueError``) for the other structures.
    """

    def __init__(
        self,
        structure: Structure | str = Structure.VISCOELASTIC,
        grid: Grid | str | None = None,
        bearing: BearingParameters | None = None,
        foil_stiffness: float | None = None,
        stick_stiffness: float | None = None,
        friction_coefficient: float | None = None,
        slip_viscosity: float | None = None,
        friction: FrictionParameters | None = None,
    ):
        self.structure = Structure.parse(structure)
        frictional = self.structure is Structure.FRICTIONAL
        for name, value in (
            ("stick_stiffness", stick_stiffness),
            ("friction_coefficient", friction_coefficient),
            ("slip_viscosity", slip_viscosity),
            ("friction", friction),
        ):
            if value is not None and not frictional:
                raise ValueError(
                    f"{name} is a parameter of the frictional foil, not of {self.structure.value}"
                )
        if friction is not None and not isinstance(friction, FrictionParameters):
            raise ValueError(f"friction must be a FrictionParameters, got {type(friction).__name__}")
        if stick_stiffness is not None:
            check_positive("stick_stiffness", stick_stiffness)
        if slip_viscosity is not None:
            check_positive("slip_viscosity", slip_viscosity)
        if friction_coefficient is not None and not (
            isinstance(friction_coefficient, (int, float, np.floating))
            and math.isfinite(friction_coefficient)
            and friction_coefficient >= 0
        ):
            raise ValueError(f"friction_coefficient must be finite and >= 0, got {friction_coefficient!r}")
        if grid is None:
            grid = Grid()
        elif isinstance(grid, str):
            grid = Grid.parse(grid)
        self.grid = grid
        self.bearing = bearing if bearing is not None else BearingParameters()
        if foil_stiffness is not None:
            check_positive("foil_stiffness", foil_stiffness)
        self.params: NondimensionalParameters = self.bearing.nondimensional(foil_stiffness)
        self.layout = StateLayout(grid, self.structure)
        kw = self.params.foil_stiffness
        if friction is not None:
            if stick_stiffness is None:
                stick_stiffness = friction.stick_stiffness(self.bearing, kw)
            if friction_coefficient is None:
                friction_coefficient = friction.friction_coefficient
        self.stick_stiffness = (
            float(stick_stiffness if stick_stiffness is not None else kw) if frictional else 0.0
        )
        self.friction_coefficient = (
            float(friction_coefficient if friction_coefficient is not None else DEFAULT_FRICTION_COEFFICIENT)
            if frictional
            else 0.0
        )
        self.slip_viscosity = (
            float(slip_viscosity if slip_viscosity is not None else DEFAULT_SLIP_VISCOSITY)
            if frictional
            else 1.0
        )
        phi = grid.phi
        self._kernel_parameters = KernelParameters(
            n_columns=grid.n_columns,
            n_rows=grid.n_rows,
            structure_code=self.structure.code,
            foil_stiffness=self.params.foil_stiffness,
            kappa=self.params.kappa,
            mass_parameter=self.params.mass_parameter,
            gravity_parameter=self.params.gravity_parameter,
            sin_phi=np.sin(phi),
            cos_phi=np.cos(phi),
            stick_stiffness=self.stick_stiffness,
            friction_coefficient=self.friction_coefficient,
            slip_viscosity=self.slip_viscosity,
        )
        self._kernel_args = self.kernel_args()
        self._H = np.empty(grid.n_columns)
        self._Hd = np.empty(grid.n_columns)

    @property
    def kernel_parameters(self) -> KernelParameters:
        """The model as the compiled kernels see it (read-only: the packed arguments are cached)."""
        return self._kernel_parameters

    def kernel_args(self, gravity_scale: float = 1.0, held_sliders: bool = False) -> tuple:
        """The parameter arguments of the compiled kernels (``rhs``, ``jacobian_blocks``,
        ``film_thickness``), with the gravity G scaled by ``gravity_scale`` (load continuation).
        ``held_sliders``: the frictional foil with its sliders held (slip viscosity infinite, S' = 0),
        what the static equilibrium sees."""
        kp = self.kernel_parameters
        if gravity_scale != 1.0:
            kp = kp._replace(gravity_parameter=kp.gravity_parameter * gravity_scale)
        if held_sliders:
            kp = kp._replace(slip_viscosity=math.inf)
        return K.pack_parameters(*kp)

    # ------------------------------------------------------------------------------------------
    @property
    def foil_stiffness(self) -> float:
        """``K_W``."""
        return self.params.foil_stiffness

    @property
    def load(self) -> float:
        """Static load per bearing ``M G`` (nondimensional)."""
        return self.params.load

    def __repr__(self) -> str:
        friction = ""
        if self.structure is Structure.FRICTIONAL:
            friction = (
                f"K_T={self.stick_stiffness:.4g}, mu_C={self.friction_coefficient:.4g}, "
                f"eta={self.slip_viscosity:.4g}, "
            )
        return (
            f"GFBModel(structure={self.structure.value!r}, grid='{self.grid}', "
            f"K_W={self.foil_stiffness:.4g}, {friction}M={self.params.mass_parameter:.4g}, "
            f"G={self.params.gravity_parameter:.4g})"
        )

    @staticmethod
    def check_operating_point(bearing_number: float, foil_damping: float) -> None:
        if not (math.isfinite(bearing_number) and bearing_number >= 0):
            raise ValueError(f"bearing_number must be finite and non-negative, got {bearing_number!r}")
        check_positive("foil_damping", foil_damping)

    # ------------------------------------------------------------------------------------------
    def rhs(self, s: np.ndarray, bearing_number: float, foil_damping: float = 1.0) -> np.ndarray:
        """``k(s, Lambda, D_W)`` (``foil_damping`` D_W only matters for the viscoelastic foil)."""
        return self.rhs_and_minimum(s, bearing_number, foil_damping)[0]

    def rhs_and_minimum(
        self, s: np.ndarray, bearing_number: float, foil_damping: float = 1.0, gravity_scale: float = 1.0
    ) -> tuple[np.ndarray, float]:
        """``k(s, Lambda, D_W)`` with the gravity scaled by ``gravity_scale``, and ``min(min H, min P)``
        of ``s`` (non-positive: the state is inadmissible) from the same kernel call."""
        s = self.layout.check(s)
        out = np.empty_like(s)
        args = self._kernel_args if gravity_scale == 1.0 else self.kernel_args(gravity_scale)
        mn = K.rhs(s, float(bearing_number), float(foil_damping), *args, out, self._H, self._Hd)
        return out, mn

    # ------------------------------------------------------------------------------------------
    # static equilibrium of the frictional foil
    def equilibrium_residual(
        self,
        s: np.ndarray,
        bearing_number: float,
        slider_reference: np.ndarray | None = None,
        gravity_scale: float = 1.0,
    ) -> tuple[np.ndarray, float]:
        """The residual whose root is the static equilibrium, and ``min(min H, min P)`` (see
        :meth:`rhs_and_minimum`).  ``k(s)`` itself except for the frictional foil's slider rows.

        A frictional foil is at rest for every slider position with ``|F| <= F_c`` (a continuum of
        equilibria; there ``S' = 0`` gives a singular Newton matrix).  The equilibrium is the one a
        quasi-static loading reaches from the slider positions ``slider_reference`` (``S_0``): a slider
        moves only as far as the Coulomb limit forces it, ``S = clamp(S_0, Q - F_c/K_T, Q + F_c/K_T)``,
        which is exact for a load that grows monotonically in each column (the load continuation of
        :func:`gfb_env.equilibrium.find_equilibrium`).  That residual replaces the slider rows.
        """
        if self.structure is not Structure.FRICTIONAL:
            return self.rhs_and_minimum(s, bearing_number, 1.0, gravity_scale)
        # the pressure rows with the sliders held (S' = 0, as at every admissible rest state): k itself
        # has a kink in S' at the slip limit, where the sliders of a loaded equilibrium sit
        s = self.layout.check(s)
        r = np.empty_like(s)
        mn = K.rhs(
            s, float(bearing_number), 1.0, *self.kernel_args(gravity_scale, True), r, self._H, self._Hd
        )
        target, _ = self._slider_target(s, slider_reference)
        r[self.layout.foil_slice] = self.layout.foil_state(s) - target
        return r, mn

    def equilibrium_jacobian(
        self, s: np.ndarray, bearing_number: float, slider_reference: np.ndarray | None = None
    ) -> sp.csr_matrix:
        """Jacobian of :meth:`equilibrium_residual` (sparse CSR)."""
        if self.structure is not Structure.FRICTIONAL:
            return self.jacobian(s, bearing_number, 1.0)
        J = self.jacobian(s, bearing_number, 1.0, _args=self.kernel_args(1.0, True))
        L = self.layout
        nc, nr = self.grid.n_columns, self.grid.n_rows
        _, side = self._slider_target(s, slider_reference)
        kw, kt, mu, dz = self.foil_stiffness, self.stick_stiffness, self.friction_coefficient, self.grid.dz
        pm1 = self.axial_mean_pressure(s) - 1.0
        # target = Q + side F_c / K_T on the lower/upper limit (side -1/+1), S_0 (side 0);
        # dQ/dS = K_T/(K_W+K_T), dQ/dP_l = -dz/(K_W+K_T), dF_c/dP_l = mu dz sign(Pbar - 1)
        d_s = np.where(side == 0, 1.0, 1.0 - kt / (kw + kt))
        d_p = np.where(side == 0, 0.0, dz / (kw + kt) - side * mu * dz * np.sign(pm1) / kt)
        foil_rows = L.n_pressure + np.arange(nc)
        keep = np.ones(L.size)
        keep[foil_rows] = 0.0
        rows = np.concatenate([foil_rows, np.repeat(foil_rows, nr)])
        cols = np.concatenate([foil_rows, np.arange(L.n_pressure)])
        vals = np.concatenate([d_s, np.repeat(d_p, nr)])
        new = sp.coo_matrix((vals, (rows, cols)), shape=J.shape)
        return (sp.diags(keep) @ J + new).tocsr()

    def linearised_states(self, s: np.ndarray, bearing_number: float) -> np.ndarray | None:
        """State indices the linear stability analysis keeps (None: all of them).

        Frictional foil: a stuck slider (``|F| < F_c``) has an identically zero row in ``dk/ds``
        (S' = 0 exactly), so the Jacobian is block triangular and each stuck slider adds an eigenvalue
        exactly 0 whose eigenvector is a shift of the slider: another equilibrium of the continuum
        ``|F| <= F_c``, neutral rather than unstable.  Those states are dropped; the eigenvalues of the
        rest are those of the foil with the stuck sliders held (stiffness K_W + K_T in those columns).
        Sliders at or past the slip limit (within the kernels' ``SLIP_BRANCH_BAND``) keep their rows, on
        the slip branch: at mu_C = 0 that is the free slider (the K_W foil); in general it is the tangent
        of a slider that a further load would move, not of one being unloaded (which sticks at once)."""
        if self.structure is not Structure.FRICTIONAL:
            return None
        J = self.jacobian(s, bearing_number, 1.0)
        foil = np.arange(self.layout.n_pressure, self.layout.rotor_offset)
        stuck = np.diff(J.indptr)[foil] == 0
        return np.setdiff1d(np.arange(self.layout.size), foil[stuck])

    def linearised_jacobian(
        self, s: np.ndarray, bearing_number: float, foil_damping: float = 1.0, sliders_on_limit: str = "stick"
    ) -> tuple[sp.csr_matrix, np.ndarray | None]:
        """The Jacobian the linear stability analysis uses and the state indices it keeps (None: all).

        Every structure but the frictional foil: ``(jacobian(s, ...), None)``.  Frictional foil, by where
        a slider on its Coulomb limit ``|F| = F_c`` is linearised (the regularised law
        ``eta S' = sign(F) max(|F| - F_c, 0)`` has one-sided slopes there: 0 inward, ``1/eta`` outward):

        - ``"stick"`` (default): the inward slope.  A perturbation of amplitude ``a`` at a fixed
          ``Lambda`` slips a slider on its limit by O(a) once, after which its force oscillates inside the
          elastic range ``2 F_c``, much wider than ``a`` (shakedown): as ``a -> 0`` every slider with
          ``F_c > 0`` is held.  So the Jacobian with the sliders held (``S' = 0``) and the slider states
          dropped (each would add an exact zero eigenvalue, a neutral shift along the equilibria):
          the stuck foil ``K_W + K_T`` with the sliders' offsets as a built-in deflection.  At
          ``mu_C = 0`` (``F_c = 0`` in every column: no elastic range) the slider is free: as ``"slip"``.
        - ``"slip"``: the outward slope, the tangent of a slider that a growing load keeps moving (the
          quasi-static spin-up's load path); stuck sliders dropped (:meth:`linearised_states`)."""
        if sliders_on_limit not in ("stick", "slip"):
            raise ValueError(f"sliders_on_limit must be 'stick' or 'slip', got {sliders_on_limit!r}")
        if self.structure is not Structure.FRICTIONAL:
            return self.jacobian(s, bearing_number, foil_damping), None
        if sliders_on_limit == "slip" or self.friction_coefficient == 0.0:
            return self.jacobian(s, bearing_number, 1.0), self.linearised_states(s, bearing_number)
        J = self.jacobian(s, bearing_number, 1.0, _args=self.kernel_args(1.0, True))
        keep = np.setdiff1d(
            np.arange(self.layout.size), np.arange(self.layout.n_pressure, self.layout.rotor_offset)
        )
        return J, keep

    def _slider_target(
        self, s: np.ndarray, slider_reference: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Quasi-static slider position ``clamp(S_0, Q - F_c/K_T, Q + F_c/K_T)`` and which side is active
        (-1 lower limit, +1 upper limit, 0 stuck at S_0).  With F_c = 0 (mu_C = 0) the slider follows Q."""
        s = self.layout.check(s)
        S0 = (
            np.zeros(self.grid.n_columns) if slider_reference is None else np.asarray(slider_reference, float)
        )
        Q = self.foil_deflection(s)
        half = self.friction_limit(s) / self.stick_stiffness
        lower, upper = Q - half, Q + half
        side = np.where(S0 <= lower, -1, np.where(S0 >= upper, 1, 0))
        target = np.where(side < 0, lower, np.where(side > 0, upper, S0))
        return target, side

    @property
    def sparse_offdiagonal_blocks(self) -> bool:
        """Whether the column-coupling Jacobian blocks (``Am``, ``Ap``) hold only their diagonal and
        last column.  True for the rigid and viscoelastic foils; the elastic foil's Eq. (8) (and the
        frictional foil's, the same rank-one coupling) ties every pressure of a column to its
        deflection, which fills them."""
        return self.structure not in (Structure.ELASTIC, Structure.FRICTIONAL)

    def new_blocks(self) -> dict[str, np.ndarray]:
        """Preallocated arrays for :func:`jacobian_blocks` (used by the integrator)."""
        nc, m = self.grid.n_columns, self.layout.block_size
        return {
            "Ad": np.zeros((nc, m, m)),
            "Ap": np.zeros((nc, m, m)),
            "Am": np.zeros((nc, m, m)),
            "Er": np.zeros((nc, m, 4)),
            "Rr": np.zeros((nc, 4, m)),
            "Srr": np.zeros((4, 4)),
        }

    def jacobian_blocks(
        self,
        s: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        blocks: dict[str, np.ndarray] | None = None,
        _args: tuple | None = None,
    ) -> dict[str, np.ndarray]:
        s = self.layout.check(s)
        b = blocks if blocks is not None else self.new_blocks()
        F = np.empty_like(s)
        K.jacobian_blocks(
            s,
            float(bearing_number),
            float(foil_damping),
            *(self._kernel_args if _args is None else _args),
            F,
            self._H,
            self._Hd,
            b["Ad"],
            b["Ap"],
            b["Am"],
            b["Er"],
            b["Rr"],
            b["Srr"],
        )
        return b

    @cached_property
    def _pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """Row/column indices (state layout) of the flattened blocks, in the order of
        :meth:`_block_values`."""
        L = self.layout
        nc, nr, m = self.grid.n_columns, self.grid.n_rows, L.block_size
        col_idx = np.empty((nc, m), dtype=np.int64)
        col_idx[:, :nr] = np.arange(nc * nr).reshape(nc, nr)
        if m > nr:
            col_idx[:, nr] = L.n_pressure + np.arange(nc)
        rot = np.arange(L.rotor_offset, L.size)
        ii = np.arange(nc)
        rows, cols = [], []
        for shift in (0, 1, -1):  # Ad, Ap, Am
            nb = col_idx[(ii + shift) % nc]
            rows.append(np.broadcast_to(col_idx[:, :, None], (nc, m, m)).ravel())
            cols.append(np.broadcast_to(nb[:, None, :], (nc, m, m)).ravel())
        rows.append(np.broadcast_to(col_idx[:, :, None], (nc, m, 4)).ravel())
        cols.append(np.broadcast_to(rot[None, None, :], (nc, m, 4)).ravel())
        rows.append(np.broadcast_to(rot[None, :, None], (nc, 4, m)).ravel())
        cols.append(np.broadcast_to(col_idx[:, None, :], (nc, 4, m)).ravel())
        rows.append(np.repeat(rot, 4))
        cols.append(np.tile(rot, 4))
        return np.concatenate(rows), np.concatenate(cols)

    def jacobian(
        self, s: np.ndarray, bearing_number: float, foil_damping: float = 1.0, _args: tuple | None = None
    ) -> sp.csr_matrix:
        """Analytic Jacobian dk/ds as a sparse CSR matrix (explicit zeros of the block pattern dropped).
        ``_args``: other kernel arguments (:meth:`kernel_args`), for :meth:`equilibrium_jacobian`."""
        b = self.jacobian_blocks(s, bearing_number, foil_damping, _args=_args)
        data = np.concatenate([b[k].ravel() for k in ("Ad", "Ap", "Am", "Er", "Rr", "Srr")])
        rows, cols = self._pattern
        keep = data != 0.0
        n = self.layout.size
        J = sp.coo_matrix((data[keep], (rows[keep], cols[keep])), shape=(n, n)).tocsr()
        return J

    # ------------------------------------------------------------------------------------------
    # derived outputs
    def film_thickness(self, s: np.ndarray) -> np.ndarray:
        """Film thickness ``H`` per column (uniform in Z), shape ``(N_phi-1,)``."""
        s = self.layout.check(s)
        H = np.empty(self.grid.n_columns)
        K.film_thickness(s, *self._kernel_args, H)
        return H

    def min_film_thickness(self, s: np.ndarray) -> float:
        return float(self.film_thickness(s).min())

    def foil_deflection(self, s: np.ndarray) -> np.ndarray:
        """Foil deflection ``Q`` per column (zero for the rigid foil)."""
        s = self.layout.check(s)
        if self.structure is Structure.VISCOELASTIC:
            return self.layout.foil_state(s).copy()
        if self.structure is Structure.ELASTIC:
            return -(self.axial_mean_pressure(s) - 1.0) / self.foil_stiffness
        if self.structure is Structure.FRICTIONAL:
            kt = self.stick_stiffness
            return (kt * self.layout.foil_state(s) - (self.axial_mean_pressure(s) - 1.0)) / (
                self.foil_stiffness + kt
            )
        return np.zeros(self.grid.n_columns)

    def friction_force(self, s: np.ndarray) -> np.ndarray:
        """Frictional foil: the Jenkins element's force ``F = K_T (Q - S)`` per column."""
        self._require_frictional("friction_force")
        return self.stick_stiffness * (self.foil_deflection(s) - self.layout.foil_state(s))

    def friction_limit(self, s: np.ndarray) -> np.ndarray:
        """Frictional foil: the Coulomb limit ``F_c = mu_C |Pbar - 1|`` per column."""
        self._require_frictional("friction_limit")
        return self.friction_coefficient * np.abs(self.axial_mean_pressure(s) - 1.0)

    def stuck(self, s: np.ndarray) -> np.ndarray:
        """Frictional foil: which sliders stick (``|F| < F_c``, so S' = 0 exactly) per column."""
        return np.abs(self.friction_force(s)) < self.friction_limit(s)

    def _require_frictional(self, what: str) -> None:
        if self.structure is not Structure.FRICTIONAL:
            raise ValueError(f"{what} is defined for the frictional foil only, not {self.structure.value}")

    def pressure_field(self, s: np.ndarray) -> np.ndarray:
        """Pressure on all rows including the ambient edges, shape ``(N_phi-1, N_Z)``."""
        P = self.layout.pressure(self.layout.check(s))
        out = np.ones((self.grid.n_columns, self.grid.n_z))
        out[:, 1:-1] = P
        return out

    def axial_mean_pressure(self, s: np.ndarray) -> np.ndarray:
        """``Pbar(phi) = int P dZ`` (trapezoid rule with the edges), Eq. (5)."""
        P = self.layout.pressure(self.layout.check(s))
        return self.grid.dz * (1.0 + P.sum(axis=1))

    def bearing_force(self, s: np.ndarray) -> np.ndarray:
        """Nondimensional bearing force ``[f_xi, f_eta]`` of Eq. (11)."""
        P = self.layout.pressure(self.layout.check(s))
        w = np.add.reduce(P - 1.0, axis=1) * self.grid.dphi * self.grid.dz  # = .sum(axis=1), less Python
        kp = self.kernel_parameters
        return np.array([w @ kp.sin_phi, w @ kp.cos_phi])

    def eccentricity(self, s: np.ndarray) -> float:
        """``eps = sqrt(xi^2 + eta^2)``."""
        r = self.layout.rotor(self.layout.check(s))
        return float(math.hypot(r[0], r[1]))

    def attitude_angle(self, s: np.ndarray) -> float:
        """``gamma`` in radians, measured from the load direction (eta axis): ``atan2(xi, eta)``."""
        r = self.layout.rotor(self.layout.check(s))
        return float(math.atan2(r[0], r[1]))
