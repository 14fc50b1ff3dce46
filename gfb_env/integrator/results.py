"""What one :meth:`~gfb_env.integrator.TrapezoidalIntegrator.advance` returns: its status, trajectory,
touchdown event and statistics, and the counter and extreme vectors of the compiled loop behind them."""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass

import numpy as np

__all__ = [
    "AdvanceResult",
    "IntegrationError",
    "IntegrationStatus",
    "IntegratorStatistics",
    "TouchdownEvent",
    "Trajectory",
]


class IntegrationStatus(enum.StrEnum):
    """How one :meth:`~gfb_env.integrator.TrapezoidalIntegrator.advance` ended (a str:
    ``status == "touchdown"`` works)."""

    DONE = "done"
    TOUCHDOWN = "touchdown"
    FAILED = "failed"
    MAX_STEPS = "max_steps"


# codes of the compiled loop, in the order of IntegrationStatus
_DONE, _TOUCHDOWN, _FAILED, _MAX_STEPS = 0, 1, 2, 3
_STATUS_OF_CODE = tuple(IntegrationStatus)

# statistics (int vector of the compiled loop; named by IntegratorStatistics, in this order)
_NSTEPS, _NREJ_ERR, _NREJ_NEWTON, _NJAC, _NFACT, _NRHS, _NREC, _NBAD_H, _NDIVERGED = 0, 1, 2, 3, 4, 5, 6, 7, 8
# extremes and the touchdown event (float vector of the compiled loop)
_MINH, _XIMIN, _XIMAX, _ETAMIN, _ETAMAX, _EPSMAX, _EVT, _EVXI, _EVETA = 0, 1, 2, 3, 4, 5, 6, 7, 8


class IntegrationError(RuntimeError):
    """The integrator could not continue (step size below the minimum, or too many steps)."""


#: The extremes' start (min H, xi min/max, eta min/max, max eccentricity, touchdown time, xi, eta).
_EXTREMES_START = np.array([np.inf, np.inf, -np.inf, np.inf, -np.inf, 0.0, np.nan, np.nan, np.nan])


@dataclass(frozen=True)
class IntegratorStatistics:
    """Work counters of the compiled loop: of one call (:attr:`AdvanceResult.statistics`) or summed
    over the calls since the last reset (:attr:`TrapezoidalIntegrator.statistics`)."""

    steps: int = 0
    rejected_steps: int = 0  # by the error test
    newton_failures: int = 0  # trial steps whose Newton iteration (or factorisation) failed
    jacobians: int = 0
    factorizations: int = 0
    rhs_evaluations: int = 0
    recorded_samples: int = 0  # by the compiled loop (a sample at the very start is not counted)
    inadmissible_iterates: int = 0  # Newton iterates with H <= 0 somewhere
    diverged_iterations: int = 0  # Newton iterations stopped for a contraction rate >= 0.9

    @classmethod
    def from_counts(cls, counts: list[int]) -> IntegratorStatistics:
        """From the compiled loop's counters as a list of ints in the field order (the instance dict
        filled at once: the frozen dataclass's ``__init__`` sets one field at a time, ~3 us)."""
        new = object.__new__(cls)
        new.__dict__.update(zip(_STATISTICS_FIELDS, counts, strict=True))
        return new

    @classmethod
    def from_array(cls, a: np.ndarray) -> IntegratorStatistics:
        """From the compiled loop's counter vector (in the field order)."""
        return cls(*(int(v) for v in a))

    def as_array(self) -> np.ndarray:
        # not dataclasses.astuple: it deep-copies recursively, 10 % of an env's control step (profiled)
        return np.array([getattr(self, name) for name in _STATISTICS_FIELDS], dtype=np.int64)

    def __add__(self, other: IntegratorStatistics) -> IntegratorStatistics:
        return IntegratorStatistics.from_array(self.as_array() + other.as_array())

    def plus(self, counts: list[int]) -> IntegratorStatistics:
        """These counters plus the compiled loop's ``counts`` (a list in the field order; plain ints:
        the arrays of ``+`` cost ~8 us per control step)."""
        s = self
        return IntegratorStatistics(
            s.steps + counts[0],
            s.rejected_steps + counts[1],
            s.newton_failures + counts[2],
            s.jacobians + counts[3],
            s.factorizations + counts[4],
            s.rhs_evaluations + counts[5],
            s.recorded_samples + counts[6],
            s.inadmissible_iterates + counts[7],
            s.diverged_iterations + counts[8],
        )


_STATISTICS_FIELDS = tuple(f.name for f in dataclasses.fields(IntegratorStatistics))


@dataclass
class Trajectory:
    """Uniformly sampled output of one or more
    :meth:`~gfb_env.integrator.TrapezoidalIntegrator.advance` calls.

    Attributes: nondimensional time ``tau``; rotor ``xi``, ``eta``, ``xi_dot``, ``eta_dot``; minimum
    film thickness (linear between steps); ``probes`` (samples of the requested extra state entries,
    shape (n, k)); the schedule ``bearing_number`` and ``foil_damping`` at each sample.
    """

    tau: np.ndarray
    xi: np.ndarray
    eta: np.ndarray
    xi_dot: np.ndarray
    eta_dot: np.ndarray
    min_film_thickness: np.ndarray
    probes: np.ndarray
    bearing_number: np.ndarray
    foil_damping: np.ndarray

    @property
    def eccentricity(self) -> np.ndarray:
        return np.hypot(self.xi, self.eta)

    def __len__(self) -> int:
        return len(self.tau)

    @classmethod
    def concatenate(cls, parts: list[Trajectory]) -> Trajectory:
        if not parts:
            raise ValueError("parts must not be empty")
        names = [f for f in cls.__dataclass_fields__]
        return cls(**{k: np.concatenate([getattr(p, k) for p in parts]) for k in names})


@dataclass
class TouchdownEvent:
    """The journal touched the foil: min film thickness crossed the threshold at ``tau``."""

    tau: float
    xi: float
    eta: float
    min_film_thickness: float


@dataclass
class AdvanceResult:
    """What :meth:`~gfb_env.integrator.TrapezoidalIntegrator.advance` did."""

    status: IntegrationStatus
    tau: float
    trajectory: Trajectory
    touchdown: TouchdownEvent | None
    statistics: IntegratorStatistics  # the work of this call (the integrator's own sums them)
    min_film_thickness: float
    xi_range: tuple[float, float]
    eta_range: tuple[float, float]
    max_eccentricity: float
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.status in (IntegrationStatus.DONE, IntegrationStatus.TOUCHDOWN)

    @property
    def steps(self) -> int:
        """Accepted steps of this call (``statistics.steps``, which most callers want)."""
        return self.statistics.steps
