"""The one owner of the tasks' action and observation units, used by the environments and the agents.

An action is ``a = (a_speed, a_damping) in [-1, 1]^2``:

* ``a_speed`` is the motor's speed ramp in units of its acceleration limit: ``dn/dt = a_speed *
  max_acceleration_rpm_per_s``, i.e. ``dLambda/dtau = a_speed * max_acceleration_rpm_per_s /
  (rpm/s per unit dLambda/dtau of the bearing)``;
* ``a_damping`` is the foil damping ``D_W`` on a log scale, ``D_W = D_min (D_max / D_min)^((a + 1) / 2)``.

An observation is ``[xi, eta, xi', eta', extent(xi), extent(eta), n / n_scale, a_damping(D_W),
P(probe_0), ..., P(probe_{k-1}), task extras...]``: positions in units of the *nominal* clearance
C_nom, velocities in C_nom / T_nom, the envelope (max - min over the last control step) in C_nom, the
speed over ``speed_scale_rpm``, the damping on the action scale and the midplane pressures ``P = p / p0``.
:class:`ObservationLayout` holds the indices, the bounds and the decoders that agents need; nothing
else hard-codes an index.

The task extras have names (:attr:`ObservationLayout.extra_names`); the v1 tasks end the observation
with :data:`SPEED_COMMAND` (the commanded speed ``n_cmd / 60 000 rpm``, [0, 1]) and :data:`TIME_LEFT`
(the fraction of the episode's control steps still to come, ``steps_left / episode_steps``, [0, 1]);
agents read them with :meth:`ObservationLayout.index` or the decoders
:meth:`ObservationLayout.speed_command_rpm` and :meth:`ObservationLayout.time_left`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.params import BearingParameters

__all__ = [
    "ActionMap",
    "ObservationLayout",
    "OBS_XI",
    "OBS_ETA",
    "OBS_XI_DOT",
    "OBS_ETA_DOT",
    "OBS_XI_EXTENT",
    "OBS_ETA_EXTENT",
    "OBS_SPEED",
    "OBS_DAMPING",
    "N_ROTOR_OBS",
    "SPEED_COMMAND",
    "TIME_LEFT",
]

# observation layout (before the pressure probes)
OBS_XI, OBS_ETA, OBS_XI_DOT, OBS_ETA_DOT, OBS_XI_EXTENT, OBS_ETA_EXTENT, OBS_SPEED, OBS_DAMPING = range(8)
N_ROTOR_OBS = 8
#: |xi|, |eta| <= 3 C: eps > 1 is possible because the foil deflects.
POSITION_BOUND = 3.0
#: |xi'|, |eta'| <= 3 C/T: a developed whirl at Lambda ~ 0.7 reaches ~0.5 C/T.
VELOCITY_BOUND = 3.0
#: orbit extent <= 2 POSITION_BOUND.
EXTENT_BOUND = 2.0 * POSITION_BOUND
#: name of the v1 observation entry ``n_cmd / speed_scale_rpm`` (the commanded operating speed)
SPEED_COMMAND = "speed_command"
#: name of the v1 observation entry ``steps_left / episode_steps`` (fraction of the horizon remaining)
TIME_LEFT = "time_left"
#: 0 <= P = p / p0 <= 10: the loaded film's peak is ~2-3 p0 near touchdown.
PRESSURE_BOUND = 10.0


@dataclass(frozen=True)
class ActionMap:
    """Action ``[-1, 1]^2`` <-> (speed ramp, foil damping D_W).

    Attributes:
        damping_range: ``(D_min, D_max)`` of the foil damping D_W (nondimensional, paper Eq. 9).
        max_acceleration_rpm_per_s: the motor's acceleration limit; ``a_speed = +-1`` ramps at it.
    """

    damping_range: tuple[float, float]
    max_acceleration_rpm_per_s: float

    def damping_from_action(self, a: float) -> float:
        """``D_W = D_min (D_max / D_min)^((a + 1) / 2)`` for ``a in [-1, 1]``."""
        dmin, dmax = self.damping_range
        return float(dmin * (dmax / dmin) ** ((a + 1.0) / 2.0))

    def action_from_damping(self, d: float) -> float:
        """Inverse of :meth:`damping_from_action`, clipped to ``[-1, 1]``."""
        dmin, dmax = self.damping_range
        return float(np.clip(2.0 * math.log(d / dmin) / math.log(dmax / dmin) - 1.0, -1.0, 1.0))

    def max_rate(self, bearing: BearingParameters) -> float:
        """The motor limit as ``dLambda/dtau`` of ``bearing`` (depends on its time scale T)."""
        return self.max_acceleration_rpm_per_s / bearing.rate_rpm_per_s(1.0)

    def rpm_per_step(self, bearing: BearingParameters, control_interval: float) -> float:
        """Speed change (rpm) of one control step of ``control_interval`` tau at ``a_speed = 1``."""
        return self.max_acceleration_rpm_per_s * bearing.seconds(control_interval)


@dataclass(frozen=True)
class ObservationLayout:
    """Indices, bounds and decoders of the observation vector (see the module docstring).

    Attributes:
        n_pressure_probes: midplane pressure probes after the 8 rotor entries.
        speed_scale_rpm: ``obs[OBS_SPEED] = n / speed_scale_rpm``.
        max_speed_rpm: top of the speed range (sets the speed bound, at least 1).
        extra_low, extra_high: bounds of task-specific entries appended after the probes.
        extra_names: their names (default ``extra_0``, ``extra_1``, ...); the v1 tasks end with
            :data:`SPEED_COMMAND` and :data:`TIME_LEFT`.
    """

    n_pressure_probes: int
    speed_scale_rpm: float
    max_speed_rpm: float
    extra_low: tuple[float, ...] = ()
    extra_high: tuple[float, ...] = ()
    extra_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if len(self.extra_low) != len(self.extra_high):
            raise ValueError("extra_low and extra_high must have the same length")
        if not self.extra_names:
            object.__setattr__(self, "extra_names", tuple(f"extra_{k}" for k in range(len(self.extra_low))))
        elif len(self.extra_names) != len(self.extra_low) or len(set(self.extra_names)) != len(
            self.extra_names
        ):
            raise ValueError(f"extra_names must name each extra entry once, got {self.extra_names!r}")

    xi: int = OBS_XI
    eta: int = OBS_ETA
    xi_dot: int = OBS_XI_DOT
    eta_dot: int = OBS_ETA_DOT
    xi_extent: int = OBS_XI_EXTENT
    eta_extent: int = OBS_ETA_EXTENT
    speed: int = OBS_SPEED
    damping: int = OBS_DAMPING

    @property
    def pressure_slice(self) -> slice:
        return slice(N_ROTOR_OBS, N_ROTOR_OBS + self.n_pressure_probes)

    @property
    def size(self) -> int:
        return N_ROTOR_OBS + self.n_pressure_probes + len(self.extra_low)

    @property
    def measured_indices(self) -> np.ndarray:
        """Entries that come from sensors (they carry the observation noise): rotor, envelope, probes."""
        return np.r_[0:OBS_SPEED, N_ROTOR_OBS : N_ROTOR_OBS + self.n_pressure_probes]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` as float32 arrays."""
        n = self.size
        low, high = np.empty(n, dtype=np.float32), np.empty(n, dtype=np.float32)
        low[[OBS_XI, OBS_ETA]], high[[OBS_XI, OBS_ETA]] = -POSITION_BOUND, POSITION_BOUND
        low[[OBS_XI_DOT, OBS_ETA_DOT]], high[[OBS_XI_DOT, OBS_ETA_DOT]] = -VELOCITY_BOUND, VELOCITY_BOUND
        low[[OBS_XI_EXTENT, OBS_ETA_EXTENT]], high[[OBS_XI_EXTENT, OBS_ETA_EXTENT]] = 0.0, EXTENT_BOUND
        low[OBS_SPEED], high[OBS_SPEED] = 0.0, max(1.0, self.max_speed_rpm / self.speed_scale_rpm)
        low[OBS_DAMPING], high[OBS_DAMPING] = -1.0, 1.0
        low[self.pressure_slice], high[self.pressure_slice] = 0.0, PRESSURE_BOUND
        k = N_ROTOR_OBS + self.n_pressure_probes
        low[k:], high[k:] = self.extra_low, self.extra_high
        return low, high

    @property
    def names(self) -> tuple[str, ...]:
        """The name of every entry, in order (rotor entries, ``pressure_<k>``, the task extras)."""
        rotor = ("xi", "eta", "xi_dot", "eta_dot", "xi_extent", "eta_extent", "speed", "damping")
        probes = tuple(f"pressure_{k}" for k in range(self.n_pressure_probes))
        return rotor + probes + self.extra_names

    def index(self, name: str) -> int:
        """The index of the entry ``name`` (ValueError naming the known ones if absent)."""
        names = self.names
        if name not in names:
            raise ValueError(f"observation has no entry {name!r}; it has {', '.join(names)}")
        return names.index(name)

    def has(self, name: str) -> bool:
        """Whether the observation has an entry ``name``."""
        return name in self.names

    # decoders for agents (they read only the documented observation)
    def speed_command_rpm(self, obs: np.ndarray) -> float:
        """The commanded operating speed (rpm) of a v1 task."""
        return float(obs[self.index(SPEED_COMMAND)]) * self.speed_scale_rpm

    def time_left(self, obs: np.ndarray) -> float:
        """Fraction of the episode's control steps still to come (v1 tasks; 1 at reset, 0 at the end)."""
        return float(obs[self.index(TIME_LEFT)])

    def speed_rpm(self, obs: np.ndarray) -> float:
        """Rotor speed (rpm) from an observation."""
        return float(obs[OBS_SPEED]) * self.speed_scale_rpm

    def envelope(self, obs: np.ndarray) -> float:
        """Largest orbit extent over the last control step (units of the nominal clearance)."""
        return float(max(obs[OBS_XI_EXTENT], obs[OBS_ETA_EXTENT]))
