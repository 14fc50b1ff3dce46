"""``naive``: the benchmark's naive agent, the same on every task (0 on the normalised scale)."""

from __future__ import annotations

import math

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec, ScriptedPolicy

__all__ = ["HoldStartAgent", "NaiveRampAgent", "NAIVE_DAMPING", "NAIVE_MARGIN", "SPEED_COMMAND"]

#: name of the v1 observation entry of the commanded speed (``gfb_env.envs.units.SPEED_COMMAND``)
SPEED_COMMAND = "speed_command"


class NaiveRampAgent(ScriptedPolicy):
    """``naive``: the paper's constant-damping ramp (0 of the normalised scale).

    Commands ``D_W = damping`` (1, the paper's Fig. 5 value) throughout and ramps at the motor limit
    toward ``min(commanded speed, (1 - margin) Lambda_c(D_W) of the nominal bearing)``, then holds.  The
    commanded speed is read from the observation where the task publishes one
    (``env.observation_layout.has("speed_command")``: ``speed_command_rpm(obs)``, the v1 tasks), else the
    task's documented
    nominal target (``ControlSpec.target_rpm``).  It reads nothing else: no whirl feedback, no
    identification -- what a user who knows only the paper's map of the nominal bearing would do.
    """

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        damping: float = 1.0,
        margin: float = 0.05,
        name: str = "naive",
    ):
        super().__init__(name, spec)
        if not 0 <= margin < 0.5:
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping = float(damping)
        self.cap_rpm = float(nmap.rpm((1.0 - margin) * nmap.critical_at(self.damping)))
        # the command is an observation entry of the v1 tasks only (ObservationLayout.has / the decoder)
        lay = spec.observations
        has = getattr(lay, "has", None)
        self._command = lay.speed_command_rpm if has is not None and has(SPEED_COMMAND) else None

    def setpoint_rpm(self, obs: np.ndarray) -> float:
        cmd = float(self._command(obs)) if self._command is not None else self.spec.target_rpm
        return min(cmd, self.cap_rpm) if math.isfinite(cmd) else self.cap_rpm

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm(obs)), self.spec.damping_action(self.damping)]


class HoldStartAgent(ScriptedPolicy):
    """``hold``: a reference, not a controller -- it holds the start speed (speed action 0, no
    acceleration) at the naive's damping ``D_W = damping`` throughout (issue 19: the zero of the
    normalised scale should be the better of this and the naive ramp; on RunUpRandomized-v1 the ramp
    touches down on many draws where staying put does not).  It reads nothing of the observation."""

    def __init__(self, spec: ControlSpec, damping: float = 1.0, name: str = "hold"):
        super().__init__(name, spec)
        self.damping = float(damping)
        self._action = [0.0, spec.damping_action(self.damping)]

    def _act(self, obs, rpm, m):
        return list(self._action)


#: the naive agent's damping and margin below Lambda_c(D_W) of the nominal bearing (issue 11)
NAIVE_DAMPING = 1.0
NAIVE_MARGIN = 0.05
