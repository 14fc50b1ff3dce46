"""The rule that identifies the drawn bearing from the first observation and flies the published table's
schedule at the estimate (:class:`IdentifyingAgent`; capped at the command: ``identify_map_v1``).  What it
may read: :mod:`gfb_agents.estimation.identification`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gfb_agents.estimation.identification import BearingEstimate, BearingIdentifier
from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec, ScriptedPolicy, TrackerMemory
from gfb_agents.rules.map_informed import MapInformedAgent

__all__ = ["IdentifyingMemory", "IdentifyingAgent"]


@dataclass
class IdentifyingMemory(TrackerMemory):
    """:class:`IdentifyingAgent`'s memory: the schedule of this episode and the estimate it rests on."""

    setpoint: float = 0.0
    damping: float = 1.0
    estimate: BearingEstimate | None = None


class IdentifyingAgent(ScriptedPolicy):
    """Identify the drawn bearing from the first observation, then fly the
    map-informed schedule for it (the env's published table at the estimate).

    Reads only the observation and the env's documented configuration and table (module docstring);
    it keeps no reference to the env.  On tasks without a drawn bearing it is the map-informed rule.
    """

    def __init__(
        self, env, spec: ControlSpec | None = None, nmap: NominalMap | None = None, name: str = "identify_map"
    ):
        u = getattr(env, "unwrapped", env)
        nmap = nmap or NominalMap.from_env(u)
        super().__init__(name, spec or ControlSpec.from_env(u, nmap))
        # the nominal schedule, the fallback and the whole rule on nominal tasks: map_informed's own
        nominal = MapInformedAgent(self.spec, nmap)
        self.nominal_damping, self.nominal_setpoint_rpm = nominal.damping, nominal.setpoint_rpm
        self.randomized = all(
            hasattr(u, k) for k in ("table", "clearance_range_m", "stiffness_factor_range", "load_range_n")
        )
        self.identifier = BearingIdentifier(u) if self.randomized else None
        self.table = u.table if self.randomized else None  # the published BestStableSpeedTable
        self.target_fraction = float(getattr(u, "target_fraction", 0.95))
        self.max_speed_rpm = float(u.speed_range_rpm[1])
        self.control_interval = float(u.control_interval)
        self.control_clock = u.control_clock  # the plant's tau per step of a bearing (v2: fixed seconds)
        self.nominal = u.nominal_bearing
        self.last_estimate: BearingEstimate | None = None

    def _new_memory(self) -> IdentifyingMemory:
        return IdentifyingMemory(
            rate=self.spec.rpm_per_step, setpoint=self.nominal_setpoint_rpm, damping=self.nominal_damping
        )

    def _estimate(self, obs: np.ndarray, m: IdentifyingMemory) -> BearingEstimate | None:
        """The bearing of this episode (None: the nominal schedule)."""
        return self.identifier.fit(obs) if self.identifier is not None else None

    def schedule_for(self, est: BearingEstimate) -> tuple[float, float, float]:
        """``(hold speed rpm, damping, rpm per control step)`` of the map-informed schedule on ``est``:
        the published table's ``target_fraction * lambda_best`` (capped at 98 % of the top speed, as the
        env caps its target) and ``d_opt``."""
        b = self.nominal.replace(clearance_m=est.clearance_m, external_load_per_bearing_n=est.load_n)
        row = self.table(est.clearance_m, est.stiffness_factor, est.load_n)
        lam = min(self.target_fraction * row["lambda_best"], 0.98 * b.bearing_number_at(self.max_speed_rpm))
        return (
            b.speed_rpm_at(lam),
            row["d_opt"],
            self.spec.actions.rpm_per_step(b, self.control_clock.step_tau(b)),
        )

    def _act(self, obs, rpm, m: IdentifyingMemory):
        if m.k == 0:
            est = self._estimate(obs, m)
            if est is not None:
                m.setpoint, m.damping, m.rate = self.schedule_for(est)
            m.estimate = self.last_estimate = est
        return [self.track(m, rpm, m.setpoint), self.spec.damping_action(m.damping)]
