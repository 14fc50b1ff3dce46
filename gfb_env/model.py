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
  ``D_W Q' + K_W Q = -(Pbar - 1)`` with Q a state.
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
from gfb_env.params import BearingParameters, NondimensionalParameters, check_positive

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
    """Foil structure model (paper Sect. 2.3)."""

    RIGID = "rigid"
    ELASTIC = "elastic"
    VISCOELASTIC = "viscoelastic"

    @property
    def code(self) -> int:
        return {"rigid": K.RIGID, "elastic": K.ELASTIC, "viscoelastic": K.VISCOELASTIC}[self.value]

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

    ``s = [P (N_phi-1)*(N_Z-2), phi-major; Q (N_phi-1), viscoelastic only; xi, eta, xi', eta']``.
    """

    def __init__(self, grid: Grid, structure: Structure | str):
        self.grid = grid
        self.structure = Structure.parse(structure)
        self.n_pressure = grid.n_columns * grid.n_rows
        self.n_foil = grid.n_columns if self.structure is Structure.VISCOELASTIC else 0
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
        """Foil deflection state Q_i (viscoelastic only, else None)."""
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


class GFBModel:
    """k(s, Lambda, D_W) of Eq. (14) with its analytic Jacobian and derived outputs.

    Args:
        structure: ``"rigid"``, ``"elastic"`` or ``"viscoelastic"``.
        grid: finite-difference grid (paper: 79 x 7).
        bearing: dimensional parameters (Table 1 by default); gives M, G, kappa and K_W.
        foil_stiffness: overrides the Walowit-Anno ``K_W`` of ``bearing``.
    """

    def __init__(
        self,
        structure: Structure | str = Structure.VISCOELASTIC,
        grid: Grid | str | None = None,
        bearing: BearingParameters | None = None,
        foil_stiffness: float | None = None,
    ):
        self.structure = Structure.parse(structure)
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
        )
        self._kernel_args = self.kernel_args()
        self._H = np.empty(grid.n_columns)
        self._Hd = np.empty(grid.n_columns)

    @property
    def kernel_parameters(self) -> KernelParameters:
        """The model as the compiled kernels see it (read-only: the packed arguments are cached)."""
        return self._kernel_parameters

    def kernel_args(self, gravity_scale: float = 1.0) -> tuple:
        """The parameter arguments of the compiled kernels (``rhs``, ``jacobian_blocks``,
        ``film_thickness``), with the gravity G scaled by ``gravity_scale`` (load continuation)."""
        kp = self.kernel_parameters
        if gravity_scale != 1.0:
            kp = kp._replace(gravity_parameter=kp.gravity_parameter * gravity_scale)
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
        return (
            f"GFBModel(structure={self.structure.value!r}, grid='{self.grid}', "
            f"K_W={self.foil_stiffness:.4g}, M={self.params.mass_parameter:.4g}, "
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

    @property
    def sparse_offdiagonal_blocks(self) -> bool:
        """Whether the column-coupling Jacobian blocks (``Am``, ``Ap``) hold only their diagonal and
        last column.  True for the rigid and viscoelastic foils; the elastic foil's Eq. (8) couples
        every pressure of a column to its deflection, which fills them."""
        return self.structure is not Structure.ELASTIC

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
    ) -> dict[str, np.ndarray]:
        s = self.layout.check(s)
        b = blocks if blocks is not None else self.new_blocks()
        F = np.empty_like(s)
        K.jacobian_blocks(
            s,
            float(bearing_number),
            float(foil_damping),
            *self._kernel_args,
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

    def jacobian(self, s: np.ndarray, bearing_number: float, foil_damping: float = 1.0) -> sp.csr_matrix:
        """Analytic Jacobian dk/ds as a sparse CSR matrix (explicit zeros of the block pattern dropped)."""
        b = self.jacobian_blocks(s, bearing_number, foil_damping)
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
        return np.zeros(self.grid.n_columns)

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
