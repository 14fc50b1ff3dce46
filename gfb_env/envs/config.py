"""The environments' configuration as one frozen, validated object (the :class:`BearingParameters` style).

Every argument that ``gym.make("gfb_env/...", **kwargs)`` passes to the common machinery lands in
:class:`EnvConfig`; a bad value is refused at construction with a ``ValueError`` naming the argument.
Units are in the names (rpm, rpm/s) or nondimensional as in the paper (tau = t / T, lengths / C).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.envs.synchronous_plant import SYNCHRONOUS_RESPONSES
from gfb_env.integrator import IntegratorOptions
from gfb_env.machine import (
    DampingRegimeChanges,
    FoilDampingActuator,
    Motor,
    PressureTaps,
    ProximityProbes,
    RotorBalance,
    ShockArrivals,
)
from gfb_env.machine._checks import component
from gfb_env.model import Grid
from gfb_env.params import BearingParameters

__all__ = ["EnvConfig", "DEFAULT_GRID", "CONTROL_INTERVAL_RANGE", "CONTROL_CLOCKS", "ControlClock"]

#: Default training grid, chosen by the measured accuracy/speed trade-off in ``docs/envs.md``
#: (``experiments/env_grid_tradeoff.py``): Lambda_c within 1 % of the paper grid 79 x 7.
DEFAULT_GRID = "31x7"

#: Allowed control step in tau.  Below 1 tau (0.16 ms for the nominal bearing) a step spans under a
#: twentieth of a whirl period and the envelope says nothing; above 1000 tau (0.16 s, ~40 whirl
#: periods) one step costs up to ~30 ms in a whirl and a controller cannot react to a growing orbit.
CONTROL_INTERVAL_RANGE = (1.0, 1000.0)

#: What ``control_interval`` counts (:attr:`~gfb_env.envs.interface_v2.MonitorInterface.control_clock`):
#: ``"seconds"``, tau of the task's *nominal* bearing, i.e. a fixed period in seconds (a real machine's
#: controller runs at a fixed period: the v2 ids, 60 tau = 9.54 ms), or ``"plant"``, tau of the episode's
#: own plant (v1: a step's seconds scale with the plant's T, so on a drawn bearing with the hidden C).
CONTROL_CLOCKS = ("seconds", "plant")


@dataclass(frozen=True)
class ControlClock:
    """The duration of one control step, in the plant's tau and in seconds.

    Attributes:
        control_interval: the configured step (:attr:`EnvConfig.control_interval`), tau of ``reference``.
        reference: the bearing whose time scale ``control_interval`` counts in (``"seconds"`` clock: the
            nominal bearing, so a step lasts ``control_interval x T_nom`` seconds whatever the plant);
            None (``"plant"`` clock, v1): the episode's own plant (``control_interval x T`` seconds).

    Everything a task defines per control step follows from :meth:`step_tau` and :meth:`step_s`: the
    integration span and the record grid (:attr:`SAMPLES_PER_STEP` samples), the motor's ramp and the
    actuator's response over a step, the window in which base shocks arrive, the certificate's window.
    """

    control_interval: float
    reference: BearingParameters | None = None

    #: the probes' samples recorded per control step (>= 30 per whirl period at 60 tau)
    SAMPLES_PER_STEP = 120

    def step_tau(self, bearing: BearingParameters) -> float:
        """One control step in tau of the plant ``bearing``."""
        if self.reference is None:
            return self.control_interval
        # the ratio is exactly 1.0 for the reference bearing itself: its step is control_interval
        return self.control_interval * (self.reference.time_scale_s / bearing.time_scale_s)

    def step_s(self, bearing: BearingParameters) -> float:
        """One control step in seconds on the plant ``bearing`` (the same for every plant with a
        reference)."""
        return (self.reference or bearing).seconds(self.control_interval)

    def record_interval(self, bearing: BearingParameters) -> float:
        """The record grid's spacing, tau of the plant ``bearing`` (:attr:`SAMPLES_PER_STEP` per step)."""
        return self.step_tau(bearing) / self.SAMPLES_PER_STEP

    def record_interval_s(self, bearing: BearingParameters) -> float:
        """The record grid's spacing in seconds (the probes' sampling period)."""
        return (self.reference or bearing).seconds(self.record_interval(self.reference or bearing))


def _is_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))


def check_positive(name: str, v: Any) -> float:
    if not (_is_number(v) and math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite positive number, got {v!r}")
    return float(v)


def check_nonnegative(name: str, v: Any) -> float:
    if not (_is_number(v) and math.isfinite(v) and v >= 0):
        raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")
    return float(v)


def check_in(
    name: str, v: Any, lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False
) -> float:
    """``v`` as a float inside ``[lo, hi]`` (or the open ends asked for), else a ValueError naming it."""
    ok = _is_number(v) and math.isfinite(v)
    if ok:
        ok = (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        left, right = "(" if lo_open else "[", ")" if hi_open else "]"
        raise ValueError(f"{name} must lie in {left}{lo:g}, {hi:g}{right}, got {v!r}")
    return float(v)


def check_range(name: str, r: Any) -> tuple[float, float]:
    """A pair ``(low, high)`` of finite numbers with ``low < high``."""
    try:
        lo, hi = r
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high), got {r!r}") from None
    if not (_is_number(lo) and _is_number(hi) and math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{name} must be a finite pair with low < high, got {r!r}")
    return float(lo), float(hi)


def check_bool(name: str, v: Any) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {v!r}")
    return bool(v)


def check_int(name: str, v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
    return int(v)


@dataclass(frozen=True)
class EnvConfig:
    """Configuration of the common machinery of the GFB tasks (:class:`~gfb_env.envs.base.GFBEnv`).

    Attributes:
        grid: finite-difference grid (``"N_phi x N_Z"`` or a :class:`~gfb_env.model.Grid`).
        control_interval: tau per control step, in :data:`CONTROL_INTERVAL_RANGE` (default 60: ~3
            whirl periods at Lambda = 0.7, 9.5 ms for the nominal bearing).
        max_acceleration_rpm_per_s: motor acceleration limit; ``a_speed = +-1`` ramps at it (default
            30 000 rpm/s, a small high-speed motor).  The same as ``motor.max_acceleration_rpm_per_s``:
            give either (or both, equal).
        speed_range_rpm: allowed rotor speeds; the commanded speed is clipped into it.
        damping_range: ``(D_min, D_max)`` of the foil damping D_W; ``a_damping`` maps log-linearly.
        n_pressure_probes: midplane pressure probes equally spaced in phi from phi = 0.
        observation_noise: standard deviation of additive Gaussian noise on the measured observations
            (rotor, envelope, pressures; in their observation units), 0 = none.
        touchdown_film_thickness: min film thickness H (units of C) that counts as touchdown; the one
            threshold used by the integrator's touchdown event and the episode end.
        stable_amplitude: whirl amplitude (units of C) below which a control step counts as stable.
        hold_steps: consecutive stable control steps at the target that make a success.
        disturbance_probability: chance per control step of a random disturbance kick.
        disturbance_magnitude: journal velocity impulse of a kick (units of C/T, random direction).
        speed_scale_rpm: observation scale of the speed (``obs = rpm / speed_scale_rpm``).
        nominal_bearing: the task's nominal bearing (observation scales; the plant unless randomised).
        integrator: settings of the trapezoidal integrator (a dict of its keyword arguments or an
            :class:`~gfb_env.integrator.IntegratorOptions`).
        motor: the drive (:class:`~gfb_env.machine.Motor` or a dict of its fields); default: a
            ``Motor(max_acceleration_rpm_per_s)``.
        damping_actuator: lag, rate limit and effectiveness gain between the commanded and the actual
            D_W (:class:`~gfb_env.machine.FoilDampingActuator` or a dict); default ideal (the
            command is the plant's D_W at the step's end).
        proximity_probes: the X/Y displacement probes (:class:`~gfb_env.machine.ProximityProbes` or a
            dict); default ideal (exact positions, velocities and envelopes).
        pressure_taps: the midplane pressure taps (:class:`~gfb_env.machine.PressureTaps` or a dict);
            default ideal (exact pressures).
        shock_arrivals: random base shocks (:class:`~gfb_env.machine.ShockArrivals` or a dict), half-sine
            pulses through the rotor equations; default none.  Exclusive with the legacy velocity
            kick (``disturbance_probability``): a task uses one or the other.
        rotor_balance: the rotor's residual unbalance, an ISO balance grade drawn per episode
            (:class:`~gfb_env.machine.RotorBalance` or a dict); default perfectly balanced.
        damping_regime_changes: friction-regime changes of the foil's damping effectiveness ``g``
            within the episode (:class:`~gfb_env.machine.DampingRegimeChanges` or a dict); default none
            (``g`` constant, nothing drawn).  Needs its ``gain_bounds`` or the actuator's ``gain_range``.
        privileged_info: add ``info["privileged"]`` (the true quantities and every hidden draw,
            :meth:`~gfb_env.envs.base.GFBEnv.privileged_quantities`) at every reset and step; default
            False (for oracles, teacher-student training and debugging: a benchmarked policy must not
            read it; ``docs/envs.md``, "Information contract").
        interface: the information interface (None: v1's observation, reward, costs and info; the v2
            ids pass a :class:`~gfb_env.envs.interface_v2.MonitorInterface`: the vibration monitor's
            observation, the reward and costs from the measurements, the sensor-only info).
        raw_probe_samples: (v2 only) put the step's measured probe samples under
            ``info["probe_samples"]``; default False (nothing is computed then).
        synchronous_response: how the plant carries the rotor's residual unbalance: ``"stepped"``
            (default: the forcing through the integrator, steps of at most 1/32 revolution) or
            ``"superposed"`` (opt-in: the analytic 1x response added to an unforced plant where the
            linear regime holds, stepped elsewhere; :mod:`gfb_env.envs.synchronous_plant`).  No effect
            on a balanced rotor.
    """

    grid: Grid = field(default_factory=lambda: Grid.parse(DEFAULT_GRID))
    control_interval: float = 60.0
    max_acceleration_rpm_per_s: float | None = None
    speed_range_rpm: tuple[float, float] = (12_000.0, 60_000.0)
    damping_range: tuple[float, float] = (0.1, 10.0)
    n_pressure_probes: int = 8
    observation_noise: float = 0.0
    touchdown_film_thickness: float = 0.02
    stable_amplitude: float = 0.05
    hold_steps: int = 10
    disturbance_probability: float = 0.1
    disturbance_magnitude: float = 0.005
    speed_scale_rpm: float = 60_000.0
    nominal_bearing: BearingParameters = NOMINAL_BEARING
    integrator: IntegratorOptions = field(default_factory=IntegratorOptions)
    motor: Motor | None = None
    damping_actuator: FoilDampingActuator = field(default_factory=FoilDampingActuator.ideal)
    proximity_probes: ProximityProbes = field(default_factory=ProximityProbes.ideal)
    pressure_taps: PressureTaps = field(default_factory=PressureTaps.ideal)
    shock_arrivals: ShockArrivals = field(default_factory=ShockArrivals.none)
    rotor_balance: RotorBalance = field(default_factory=RotorBalance.perfect)
    damping_regime_changes: DampingRegimeChanges = field(default_factory=DampingRegimeChanges.none)
    privileged_info: bool = False
    interface: Any = None
    raw_probe_samples: bool = False
    synchronous_response: str = "stepped"

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        g = self.grid
        if isinstance(g, str):
            put("grid", Grid.parse(g))
        elif not isinstance(g, Grid):
            raise ValueError(f"grid must be a string like '31x7' or a Grid, got {g!r}")
        put("control_interval", check_in("control_interval", self.control_interval, *CONTROL_INTERVAL_RANGE))
        self._resolve_motor(put)
        lo, hi = check_range("speed_range_rpm", self.speed_range_rpm)
        if lo <= 0:
            raise ValueError(f"speed_range_rpm must be positive, got {self.speed_range_rpm!r}")
        put("speed_range_rpm", (lo, hi))
        dmin, dmax = check_range("damping_range", self.damping_range)
        if dmin <= 0:
            raise ValueError(f"damping_range must be positive, got {self.damping_range!r}")
        put("damping_range", (dmin, dmax))
        put(
            "n_pressure_probes",
            check_int("n_pressure_probes", self.n_pressure_probes, 1, self.grid.n_columns),
        )
        put("observation_noise", check_nonnegative("observation_noise", self.observation_noise))
        put(
            "touchdown_film_thickness",
            check_in("touchdown_film_thickness", self.touchdown_film_thickness, 0.0, 1.0, hi_open=True),
        )
        put("stable_amplitude", check_positive("stable_amplitude", self.stable_amplitude))
        put("hold_steps", check_int("hold_steps", self.hold_steps, 1, 10_000))
        put(
            "disturbance_probability",
            check_in("disturbance_probability", self.disturbance_probability, 0.0, 1.0),
        )
        put("disturbance_magnitude", check_nonnegative("disturbance_magnitude", self.disturbance_magnitude))
        put("speed_scale_rpm", check_positive("speed_scale_rpm", self.speed_scale_rpm))
        if self.nominal_bearing is None:
            put("nominal_bearing", NOMINAL_BEARING)
        elif not isinstance(self.nominal_bearing, BearingParameters):
            kind = type(self.nominal_bearing).__name__
            raise ValueError(f"nominal_bearing must be a BearingParameters or None, got {kind}")
        put("integrator", IntegratorOptions.from_mapping(self.integrator))
        put("damping_actuator", component("damping_actuator", FoilDampingActuator, self.damping_actuator))
        put("proximity_probes", component("proximity_probes", ProximityProbes, self.proximity_probes))
        put("pressure_taps", component("pressure_taps", PressureTaps, self.pressure_taps))
        put("shock_arrivals", component("shock_arrivals", ShockArrivals, self.shock_arrivals))
        put("rotor_balance", component("rotor_balance", RotorBalance, self.rotor_balance))
        regimes = component("damping_regime_changes", DampingRegimeChanges, self.damping_regime_changes)
        put("damping_regime_changes", regimes)
        if not regimes.is_off and regimes.gain_bounds is None and self.damping_actuator.gain_range is None:
            raise ValueError(
                "damping_regime_changes needs gain_bounds when the damping_actuator has no gain_range"
            )
        put("privileged_info", check_bool("privileged_info", self.privileged_info))
        from gfb_env.envs.interface_v2 import MonitorInterface  # the interface imports this module

        if self.interface is not None and not isinstance(self.interface, MonitorInterface):
            raise ValueError(f"interface must be a MonitorInterface or None, got {self.interface!r}")
        put("raw_probe_samples", check_bool("raw_probe_samples", self.raw_probe_samples))
        if self.raw_probe_samples and self.interface is None:
            raise ValueError("raw_probe_samples needs the v2 interface (a -v2 id); v1 has no sample record")
        if not (
            isinstance(self.synchronous_response, str) and self.synchronous_response in SYNCHRONOUS_RESPONSES
        ):
            raise ValueError(
                f"synchronous_response must be one of {list(SYNCHRONOUS_RESPONSES)}, "
                f"got {self.synchronous_response!r}"
            )
        if self.shock_arrivals.rate_per_s > 0 and self.disturbance_probability > 0:
            raise ValueError(
                "shock_arrivals and disturbance_probability > 0 exclude each other: physical shocks replace "
                "the legacy velocity kick (set disturbance_probability=0)"
            )

    def _resolve_motor(self, put: Any) -> None:
        """One acceleration limit: ``motor`` and ``max_acceleration_rpm_per_s`` agree (either may be
        omitted; neither: 30 000 rpm/s)."""
        acc = self.max_acceleration_rpm_per_s
        if acc is not None:
            acc = check_positive("max_acceleration_rpm_per_s", acc)
        if self.motor is None:
            motor = Motor() if acc is None else Motor(acc)
        else:
            motor = component("motor", Motor, self.motor)
            if acc is not None and acc != motor.max_acceleration_rpm_per_s:
                raise ValueError(
                    f"max_acceleration_rpm_per_s={acc!r} contradicts motor.max_acceleration_rpm_per_s="
                    f"{motor.max_acceleration_rpm_per_s!r}; give one of them"
                )
        put("motor", motor)
        put("max_acceleration_rpm_per_s", motor.max_acceleration_rpm_per_s)

    @classmethod
    def from_kwargs(cls, kwargs: Mapping[str, Any]) -> EnvConfig:
        """From ``gym.make`` keyword arguments (``integrator_options`` -> ``integrator``); an unknown
        keyword is refused with the list of allowed ones."""
        known = set(cls.__dataclass_fields__) - {"integrator"} | {"integrator_options"}
        for key in kwargs:
            if key not in known:
                raise ValueError(f"unknown environment argument {key!r}; allowed: {sorted(known)}")
        kw = dict(kwargs)
        if "integrator_options" in kw:
            kw["integrator"] = kw.pop("integrator_options")
        return cls(**kw)
