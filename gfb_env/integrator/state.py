"""The one snapshot type of the integrator: :class:`StepperState` (``TrapezoidalIntegrator.snapshot``
/ ``restore``; ``as_dict`` / ``from_dict`` for JSON)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_env import forcing as F
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.integrator.results import IntegratorStatistics
from gfb_env.model import GFBModel

__all__ = ["StepperState"]


@dataclass(frozen=True)
class StepperState:
    """Everything the continuation of a run depends on: the one owner of the integrator's saved state.

    The arrays are updated in place by the compiled loop (so "frozen" means: the fields are not
    rebound); :meth:`TrapezoidalIntegrator.snapshot` hands out a :meth:`copy`.  ``history`` counts the
    earlier accepted states the predictor may use (0, 1 or 2).
    """

    s: np.ndarray  # the state s_n at tau
    f: np.ndarray  # k(s_n)
    fprev: np.ndarray  # k(s_{n-1})
    sprev: np.ndarray  # s_{n-1}
    sprev2: np.ndarray  # s_{n-2}
    tau: float
    step: float  # the step size the next step will try
    previous_step: float  # h_{n-1}
    previous_step2: float  # h_{n-2}
    history: int
    bearing_number: float  # Lambda at tau
    foil_damping: float  # D_W at tau
    statistics: IntegratorStatistics
    last_record_tau: float  # the last recorded sample (each grid time is recorded once)
    rotation_angle: float = 0.0  # theta at tau (carried exactly, reduced to [0, 2 pi))
    rotation_acceleration: float = 0.0  # theta'' = dLambda/dtau that f's unbalance term was taken at
    unbalance: Unbalance | None = None  # the rotor's unbalance (f includes its forcing)
    shocks: tuple[HalfSineShock, ...] = ()  # base shocks not yet over at tau
    growth_window: tuple = ()  # WhirlGrowthControl's measurement window (options.py; () when off)

    ARRAYS = ("s", "f", "fprev", "sprev", "sprev2")

    @classmethod
    def start(
        cls,
        model: GFBModel,
        s: np.ndarray,
        bearing_number: float,
        foil_damping: float,
        tau: float,
        first_step: float,
        rotation_angle: float = 0.0,
        unbalance: Unbalance | None = None,
    ) -> StepperState:
        """A fresh start from ``s`` (no step history), with the rotation angle theta and the
        unbalance (whose forcing at ``tau`` enters ``f``)."""
        f = model.rhs(s, bearing_number, foil_damping)
        if unbalance is not None and unbalance.magnitude != 0.0:
            # at a fresh start the speed is taken as constant (theta'' = 0): the ramp of the next
            # advance call enters from its first step on
            a = F.unbalance_acceleration(
                unbalance.magnitude, rotation_angle + unbalance.phase_rad, float(bearing_number), 0.0
            )
            f[model.layout.xi_dot_index] += a[0]
            f[model.layout.eta_dot_index] += a[1]
        return cls(
            s=s,
            f=f,
            fprev=np.zeros_like(s),
            sprev=s.copy(),
            sprev2=s.copy(),
            tau=float(tau),
            step=float(first_step),
            previous_step=0.0,
            previous_step2=0.0,
            history=0,
            bearing_number=float(bearing_number),
            foil_damping=float(foil_damping),
            statistics=IntegratorStatistics(),
            last_record_tau=-math.inf,
            rotation_angle=float(rotation_angle),
            unbalance=unbalance,
        )

    def copy(self) -> StepperState:
        """A copy with copied arrays."""
        return dataclasses.replace(self, **{k: getattr(self, k).copy() for k in self.ARRAYS})

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(s, f, fprev, sprev, sprev2)``: the compiled loop's ``y``."""
        return self.s, self.f, self.fprev, self.sprev, self.sprev2

    @property
    def clock(self) -> tuple[float, float, float, float, int]:
        """``(tau, step, previous_step, previous_step2, history)``: the compiled loop's ``clock``."""
        return (
            float(self.tau),
            float(self.step),
            float(self.previous_step),
            float(self.previous_step2),
            int(self.history),
        )

    def with_clock(self, clock: tuple[float, float, float, float, int]) -> StepperState:
        """The same arrays with the clock the compiled loop returned."""
        tau, step, previous_step, previous_step2, history = clock
        return dataclasses.replace(
            self,
            tau=float(tau),
            step=float(step),
            previous_step=float(previous_step),
            previous_step2=float(previous_step2),
            history=int(history),
        )

    def advanced(
        self,
        clock: tuple[float, float, float, float, int],
        *,
        bearing_number: float,
        foil_damping: float,
        counts: list[int],
        last_record_tau: float,
        rotation_angle: float,
        rotation_acceleration: float,
        shocks: tuple[HalfSineShock, ...],
        growth_window: tuple = (),
    ) -> StepperState:
        """The state after a compiled call: the same (advanced in place) arrays, the loop's ``clock``
        and the rest as given (one constructor call: two ``dataclasses.replace`` cost ~10 us)."""
        tau, step, previous_step, previous_step2, history = clock
        # the frozen dataclass's __init__ sets its 18 fields one object.__setattr__ at a time (~3 us);
        # the instance dict filled at once holds the same fields (no __post_init__, no defaults left)
        new = object.__new__(StepperState)
        new.__dict__.update(
            s=self.s, f=self.f, fprev=self.fprev, sprev=self.sprev, sprev2=self.sprev2, tau=float(tau),
            step=float(step), previous_step=float(previous_step), previous_step2=float(previous_step2),
            history=int(history), bearing_number=bearing_number, foil_damping=foil_damping,
            statistics=self.statistics.plus(counts), last_record_tau=last_record_tau,
            rotation_angle=rotation_angle, rotation_acceleration=rotation_acceleration,
            unbalance=self.unbalance, shocks=shocks, growth_window=growth_window,
        )  # fmt: skip
        return new

    def as_dict(self) -> dict[str, Any]:
        """The fields as plain JSON values (arrays and the statistics, unbalance and shocks as lists
        and dicts; every float exact through ``json``, ``last_record_tau`` may be ``-Infinity``)."""
        d: dict[str, Any] = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        for k in self.ARRAYS:
            d[k] = d[k].tolist()
        d["statistics"] = dataclasses.asdict(self.statistics)
        d["unbalance"] = None if self.unbalance is None else dataclasses.asdict(self.unbalance)
        d["shocks"] = [dataclasses.asdict(q) for q in self.shocks]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StepperState:
        """Inverse of :meth:`as_dict` (a dict from before the forcing existed has theta = 0, no
        unbalance and no shocks)."""
        kw = {f.name: d[f.name] for f in dataclasses.fields(cls) if f.name in d}
        kw |= {k: np.array(kw[k], dtype=float, copy=True) for k in cls.ARRAYS}
        st = kw["statistics"]
        kw["statistics"] = st if isinstance(st, IntegratorStatistics) else IntegratorStatistics(**st)
        ub = kw.get("unbalance")
        kw["unbalance"] = Unbalance(**ub) if isinstance(ub, dict) else ub
        kw["shocks"] = tuple(
            q if isinstance(q, HalfSineShock) else HalfSineShock(**q) for q in kw.get("shocks", ())
        )
        kw["growth_window"] = tuple(kw.get("growth_window", ()))
        return cls(**kw)
