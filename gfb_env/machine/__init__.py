"""The instrumented machine around the bearing model: what a controller commands and what it reads.

* :class:`~gfb_env.machine.motor.Motor`: the acceleration-limited drive (speed command -> Lambda);
* :class:`~gfb_env.machine.actuator.FoilDampingActuator`: lag, rate limit and effectiveness gain
  between the commanded and the actual foil damping D_W;
* :class:`~gfb_env.machine.probes.ProximityProbes`: two eddy-current probes (X, Y at 45 degrees either
  side of the vertical), bias and noise in um;
* :class:`~gfb_env.machine.pressure_taps.PressureTaps`: midplane pressure taps, offset and noise in kPa;
* :class:`~gfb_env.machine.shocks.ShockArrivals`: random base shocks (Poisson arrivals) as
  :class:`~gfb_env.machine.shocks.ShockEvent` records;
* :class:`~gfb_env.machine.regime.DampingRegimeChanges`: friction-regime changes of the foil (abrupt
  jumps of the damping effectiveness ``g`` at Poisson times, off by default) as
  :class:`~gfb_env.machine.regime.DampingRegimeChange` records;
* :class:`~gfb_env.machine.balance.RotorBalance`: the rotor's residual unbalance, an ISO balance grade
  drawn per episode;
* :class:`~gfb_env.machine.monitor.VibrationMonitor`: the shaft-vibration monitor (direct, 1x and 2x
  vectors, sub-synchronous level) of one control step's probe samples (not yet in any observation).

Each is a small frozen, validated configuration with physical units in its field names; the defaults
are realistic and justified in ``docs/machine.md``, and each sensor/actuator has an ``ideal()`` that
is the exact instrument (the classes' default machine).  The envs take them as constructor arguments
(:class:`~gfb_env.envs.config.EnvConfig`).
"""

from __future__ import annotations

from gfb_env.machine.actuator import DampingActuatorState, FoilDampingActuator
from gfb_env.machine.balance import RotorBalance
from gfb_env.machine.monitor import MonitorReading, ProbeVibration, VibrationMonitor
from gfb_env.machine.motor import Motor
from gfb_env.machine.pressure_taps import PressureTaps
from gfb_env.machine.probes import ProbeErrors, ProximityProbes
from gfb_env.machine.regime import DampingRegimeChange, DampingRegimeChanges
from gfb_env.machine.shocks import ShockArrivals, ShockEvent

__all__ = [
    "DampingActuatorState",
    "DampingRegimeChange",
    "DampingRegimeChanges",
    "FoilDampingActuator",
    "MonitorReading",
    "Motor",
    "PressureTaps",
    "ProbeErrors",
    "ProbeVibration",
    "ProximityProbes",
    "RotorBalance",
    "ShockArrivals",
    "ShockEvent",
    "VibrationMonitor",
]
