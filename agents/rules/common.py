"""What every rule of the commanded-speed (v1) tasks shares: the command and the time left read from the
observation's named entries, the hold window, the nominal bearing's speed scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec, ScriptedPolicy, TrackerMemory
from gfb_env.params import BearingParameters

__all__ = ["CommandSource", "time_left_fraction", "RuleMemory", "CommandedRule"]


class CommandSource:
    """Reads the commanded operating speed (rpm) of a v1 task from the observation's named entry
    ``speed_command``; None on a task without one (the rules then run to their own set-point)."""

    def __init__(self, env):
        u = getattr(env, "unwrapped", env)
        layout = u.observation_layout
        self._index = layout.index("speed_command") if _layout_has(layout, "speed_command") else None
        self._scale = float(layout.speed_scale_rpm)

    def rpm(self, obs: np.ndarray) -> float | None:
        if self._index is None:
            return None
        return float(obs[self._index]) * self._scale


def _layout_has(layout, name: str) -> bool:
    has = getattr(layout, "has", None)
    return bool(has(name)) if callable(has) else False


def time_left_fraction(layout, obs: np.ndarray) -> float | None:
    """The observation's ``time_left`` entry (v1 interface), else None."""
    if _layout_has(layout, "time_left"):
        return float(obs[layout.index("time_left")])
    return None


@dataclass
class RuleMemory(TrackerMemory):
    """A v1 rule's memory: the tracker's, plus the task's command (read once per episode)."""

    cmd_rpm: float | None = None


class CommandedRule(ScriptedPolicy):
    """Shared plumbing: the command, the nominal bearing's Lambda <-> rpm, the hold window."""

    def __init__(self, name: str, env, spec: ControlSpec | None = None, nmap: NominalMap | None = None):
        u = getattr(env, "unwrapped", env)
        self.nmap = nmap or NominalMap.from_env(u)
        super().__init__(name, spec or ControlSpec.from_env(u, self.nmap))
        self.command = CommandSource(u)
        self.layout = u.observation_layout
        self.hold_steps = int(u.hold_steps)
        self.nominal = u.nominal_bearing
        self.control_interval = float(u.control_interval)
        #: the env's control clock (public configuration): the plant's tau per step of a bearing (v2: a
        #: fixed period in seconds, so ``60 T_nom / T`` tau on a bearing of time scale T; v1: 60 tau)
        self.control_clock = u.control_clock
        self.max_speed_rpm = float(u.speed_range_rpm[1])
        commanded = getattr(u, "commanded", None)  # the v1 objective's documented configuration
        self.episode_steps = int(commanded.episode_steps) if commanded is not None else 250
        # the speed at which the v1 progress is zero (RunUp: the start; WhirlRecovery: 0.85 lambda_best)
        self.reference_bearing_number = getattr(u, "reference_bearing_number", None)

    def _new_memory(self) -> RuleMemory:
        return RuleMemory(rate=self.spec.rpm_per_step)

    def step_tau(self, bearing: BearingParameters) -> float:
        """One control step in tau of a plant with ``bearing`` (the env's :class:`ControlClock`)."""
        return self.control_clock.step_tau(bearing)

    def command_rpm(self, obs: np.ndarray, m: RuleMemory) -> float | None:
        if m.cmd_rpm is None:
            m.cmd_rpm = self.command.rpm(obs)
        return m.cmd_rpm

    def steps_left(self, obs: np.ndarray, m: RuleMemory) -> int:
        f = time_left_fraction(self.layout, obs)
        if f is not None:
            return int(round(f * self.episode_steps))
        return self.episode_steps - m.k
