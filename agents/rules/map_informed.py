"""Rules that fly the map: :class:`MapInformedAgent` (damping at the nominal map's ``argmax Lambda_c``, ramp
at the motor limit, hold below ``Lambda_c(d_opt)``) and :class:`CommandCappedAgent`, which caps a schedule
at the task's command: ``map_informed_v1`` (the nominal map, ``g = 1``) and ``identify_map_v1`` (the
published table at the identified bearing, :mod:`gfb_agents.rules.identify_map`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec, ScriptedPolicy, TrackerMemory
from gfb_agents.rules.common import CommandedRule, RuleMemory

__all__ = ["MapInformedAgent", "CommandCappedMemory", "CommandCappedAgent"]


class MapInformedAgent(ScriptedPolicy):
    """Damping at the map's optimum (``argmax Lambda_c``), ramp at the motor limit, hold at
    ``(1 - margin) Lambda_c(d_opt)``; with ``below_fold=True`` hold at ``(1 - margin) Lambda_fold`` instead
    (where the map knows the fold), so that no disturbance can start a surviving whirl."""

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        margin: float = 0.05,
        below_fold: bool = False,
        name: str | None = None,
    ):
        super().__init__(name or ("map_informed_fold" if below_fold else "map_informed"), spec)
        if not (0 <= margin < 0.5):
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping = nmap.best_fold_damping() if below_fold else nmap.d_opt
        lam = nmap.critical_at(self.damping)
        if below_fold and math.isfinite(nmap.fold_at(self.damping)):
            lam = nmap.fold_at(self.damping)
        self.setpoint_rpm = nmap.rpm((1.0 - margin) * lam)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm), self.spec.damping_action(self.damping)]


@dataclass
class CommandCappedMemory(RuleMemory):
    """:class:`CommandCappedAgent`'s memory: its own and the inner schedule's."""

    inner: TrackerMemory | None = None


class CommandCappedAgent(CommandedRule):
    """An older rule's schedule with the set-point capped at the task's command (the v1 reward gives
    nothing above it): ``map_informed_v1`` (nominal map, g = 1) and ``identify_map_v1``."""

    def __init__(self, env, inner: ScriptedPolicy, name: str, **kw):
        super().__init__(name, env, **kw)
        self.inner = inner

    def _new_memory(self) -> CommandCappedMemory:
        return CommandCappedMemory(rate=self.spec.rpm_per_step, inner=self.inner._new_memory())

    def _act(self, obs, rpm, m: CommandCappedMemory):
        mi = m.inner
        self.inner._update_rate(mi, rpm)
        a = np.asarray(self.inner._act(obs, rpm, mi), dtype=float)
        mi.prev_rpm, mi.prev_a0, mi.k = rpm, float(a[0]), mi.k + 1
        cmd = self.command_rpm(obs, m)
        # the inner schedule's set-point: its memory's (identify_map: the estimate's) or its own
        sp = getattr(mi, "setpoint", getattr(self.inner, "setpoint_rpm", None))
        if cmd is not None and sp is not None and cmd < sp:
            a[0] = self.track(mi, rpm, cmd)
        return a
