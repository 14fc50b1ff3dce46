"""The privileged channel of the GFB tasks (issue 19, ``docs/envs.md`` "Information contract"): every
hidden draw of an episode as one typed record, for oracles, teacher-student training and debugging.

A policy that is benchmarked must not read it.  It is reached only explicitly:

* ``env.unwrapped.hidden_parameters()``: a JSON-serialisable dict (:meth:`HiddenParameters.as_dict`) of
  every hidden draw of the current episode; ``env.unwrapped.hidden()`` the typed record behind it;
* ``gymnasium.make(id, privileged_info=True)`` (default False): ``info["privileged"]`` at every reset and
  step, the true quantities (:meth:`~gfb_env.envs.base.GFBEnv.privileged_quantities`) and
  ``hidden_parameters``.

Units are in the key names as in :class:`~gfb_env.params.BearingParameters` (``_um``, ``_m``, ``_n``,
``_kpa``, ``_s``, ``_g``, ``_deg``, ``_rad``, ``_mm_s``; ``_c`` lengths in clearances C, ``_c_per_t``
velocities in C / T, ``_tau`` times in tau = t / T); names without a unit are nondimensional.  A group
that the task does not draw is ``None`` (e.g. ``bearing`` on a task with the nominal bearing, the probe
noise of ideal probes).

What is drawn when: the task's draws (:attr:`HiddenParameters.task`: the start), the damping gain, the
bearing, the sensors' biases and the unbalance at ``reset``; the sensor noise with every observation
(the record holds the last observation's); the base shocks step by step (the schedule holds every
shock drawn so far in the episode: future shocks are not drawn yet, so nobody, not even the oracle,
knows them).  Likewise the friction-regime changes of the damping effectiveness (only with
``damping_regime_changes``, :class:`~gfb_env.machine.DampingRegimeChanges`): ``damping_gain`` is the
current ``g``, ``damping_regime_changes`` the start ``g`` and every change so far (none ahead).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gfb_env.machine import DampingRegimeChange, ShockEvent
from gfb_env.params import BearingParameters

__all__ = ["HiddenParameters", "DrawnBearing", "ResidualUnbalance", "SensorDraws", "flatten_numbers"]


@dataclass(frozen=True)
class DrawnBearing:
    """The bearing drawn for the episode (RunUpRandomized): clearance, foil stiffness factor, load.

    Attributes:
        clearance_m: radial clearance C, m.
        stiffness_factor: ``f_K``, ``K_W = f_K K_W,WA(C)``.
        load_n: external static load per bearing F_L, N.
        foil_stiffness: the resulting nondimensional foil stiffness K_W (derived from C and f_K).
    """

    clearance_m: float
    stiffness_factor: float
    load_n: float
    foil_stiffness: float

    def as_dict(self) -> dict[str, float]:
        """The fields, plus ``clearance_um`` (``clearance_m * 1e6``, the unit ``info`` uses)."""
        return {
            "clearance_m": self.clearance_m,
            "clearance_um": self.clearance_m * 1e6,
            "stiffness_factor": self.stiffness_factor,
            "load_n": self.load_n,
            "foil_stiffness": self.foil_stiffness,
        }


@dataclass(frozen=True)
class ResidualUnbalance:
    """The rotor's residual unbalance drawn for the episode (:class:`~gfb_env.machine.RotorBalance`).

    Attributes:
        balance_grade_mm_s: the ISO 1940 balance grade G, mm/s.
        magnitude_c: U, the centre-of-mass eccentricity in clearances C.
        magnitude_um: U in um (the unit of ``info["unbalance_um"]``).
        phase_rad: its angle ahead of the rotation angle, rad.
    """

    balance_grade_mm_s: float
    magnitude_c: float
    magnitude_um: float
    phase_rad: float

    def as_dict(self) -> dict[str, float]:
        return {
            "balance_grade_mm_s": self.balance_grade_mm_s,
            "magnitude_c": self.magnitude_c,
            "magnitude_um": self.magnitude_um,
            "phase_rad": self.phase_rad,
        }


@dataclass(frozen=True)
class SensorDraws:
    """The sensors' errors: the episode's biases and the noise of the last observation.

    Attributes:
        probe_bias_um: the (X, Y) probe offsets of the episode, um.
        tap_bias_kpa: the offset of each pressure tap, kPa.
        probe_noise_um: the (X, Y) noise of the last probe sample, um (None: noise-free probes).
        probe_position_error_um, probe_velocity_error_um_per_s, probe_extent_error_um: what the probes
            added to the true (xi, eta) position (bias and noise), velocity and orbit extent of the last
            observation (None: ideal probes).
        tap_error_kpa: what each tap added to the true pressure in the last observation (offset and
            noise), kPa (None: ideal taps).
        observation_noise: the legacy additive noise of the last observation on its measured entries,
            in observation units (None: ``observation_noise = 0``).
    """

    probe_bias_um: tuple[float, ...]
    tap_bias_kpa: tuple[float, ...]
    probe_noise_um: tuple[float, ...] | None
    probe_position_error_um: tuple[float, ...] | None
    probe_velocity_error_um_per_s: tuple[float, ...] | None
    probe_extent_error_um: tuple[float, ...] | None
    tap_error_kpa: tuple[float, ...] | None
    observation_noise: tuple[float, ...] | None

    def as_dict(self) -> dict[str, list[float] | None]:
        return {k: (None if v is None else list(v)) for k, v in vars(self).items()}


@dataclass(frozen=True)
class HiddenParameters:
    """Every hidden draw of the current episode (module docstring): the typed record behind
    ``env.unwrapped.hidden_parameters()``.

    Attributes:
        damping_gain: the damping effectiveness g (actual D_W = g x commanded); with regime changes
            the current one.
        bearing: the actual bearing of the episode (:class:`~gfb_env.params.BearingParameters`; the
            nominal one where the task does not draw it).
        bearing_draw: the drawn clearance, stiffness factor and load (None: the nominal bearing).
        unbalance: the residual unbalance (None: a perfectly balanced rotor).
        sensors: the sensor biases and the last observation's noise.
        shocks: every base shock drawn so far in the episode, in time order.
        task: the task's own draws at the start, with units in the keys (RunUp: the start journal
            velocity ``start_velocity_c_per_t``, ``start_velocity_angle_rad``; WhirlRecovery: the start
            phase on the whirl ``start_phase_tau``).
        damping_gain_start, regime_changes: the effectiveness at reset and every friction-regime change
            of it so far (:class:`~gfb_env.machine.DampingRegimeChange`); None where the env has no
            ``damping_regime_changes`` (then ``as_dict`` has no such key).
    """

    damping_gain: float
    bearing: BearingParameters
    bearing_draw: DrawnBearing | None
    unbalance: ResidualUnbalance | None
    sensors: SensorDraws
    shocks: tuple[ShockEvent, ...]
    task: dict[str, float]
    damping_gain_start: float | None = None
    regime_changes: tuple[DampingRegimeChange, ...] | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable: plain floats, lists, dicts and None (``json.dumps`` takes it as is)."""
        out = {
            "damping_gain": float(self.damping_gain),
            "bearing": None if self.bearing_draw is None else self.bearing_draw.as_dict(),
            "unbalance": None if self.unbalance is None else self.unbalance.as_dict(),
            "sensors": self.sensors.as_dict(),
            "shocks": [
                {
                    "time_s": e.time_s,
                    "peak_g": e.peak_g,
                    "duration_ms": e.duration_ms,
                    "direction_deg": e.direction_deg,
                }
                for e in self.shocks
            ],
            "task": {k: float(v) for k, v in self.task.items()},
        }
        if self.regime_changes is not None:  # only where the env has regime changes (v1/v2 dicts kept)
            out["damping_regime_changes"] = {
                "gain_start": float(self.damping_gain_start),
                "changes": [c.as_dict() for c in self.regime_changes],
            }
        return out


def flatten_numbers(obj: Any, prefix: str = "") -> list[tuple[str, float]]:
    """``(path, value)`` of every real number in a nested dict / list / tuple / array (bools and None
    left out), paths as ``a.b[2]``: what the contract's equality check compares."""
    out: list[tuple[str, float]] = []
    if obj is None or isinstance(obj, (bool, str)):
        return out
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.extend(flatten_numbers(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    if isinstance(obj, (list, tuple)) or hasattr(obj, "tolist"):
        seq = obj.tolist() if hasattr(obj, "tolist") else obj
        if not isinstance(seq, (list, tuple)):
            return flatten_numbers(seq, prefix)
        for i, v in enumerate(seq):
            out.extend(flatten_numbers(v, f"{prefix}[{i}]"))
        return out
    if isinstance(obj, (int, float)) or hasattr(obj, "__float__"):
        try:
            v = float(obj)
        except (TypeError, ValueError):
            return out
        if math.isfinite(v):
            out.append((prefix, v))
    return out
