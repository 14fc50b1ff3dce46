"""The paper's schedule as an agent: a linear speed ramp at a constant foil damping to a set-point, then hold
(``ScheduleAgent.from_schedule``: the run-up that ``gfb schedule`` designed).
"""

from __future__ import annotations

from gfb_agents.policy import ControlSpec, ScriptedPolicy

__all__ = ["ScheduleAgent"]


class ScheduleAgent(ScriptedPolicy):
    """The paper's schedule: a linear ramp at ``ramp`` of the motor limit to ``setpoint_rpm`` (default the
    nominal task target) at constant damping ``damping``, then hold."""

    def __init__(
        self,
        spec: ControlSpec,
        damping: float,
        ramp: float = 0.5,
        setpoint_rpm: float | None = None,
        name: str | None = None,
    ):
        super().__init__(name or f"paper_ramp_D{damping:g}", spec)
        if not (0 < ramp <= 1):
            raise ValueError(f"ramp must lie in (0, 1], got {ramp!r}")
        self.damping, self.ramp = float(damping), float(ramp)
        self.setpoint_rpm = float(setpoint_rpm if setpoint_rpm is not None else spec.target_rpm)

    @classmethod
    def from_schedule(cls, spec: ControlSpec, schedule, name: str = "designed_schedule") -> ScheduleAgent:
        """The run-up designed by ``gfb schedule`` (:class:`gfb_env.analysis.schedule.RunUpSchedule`):
        its damping, its acceleration (as a fraction of the env's motor limit, at most 1) and its end
        speed."""
        b = schedule.model.bearing
        accel = b.rate_rpm_per_s(schedule.rate)
        ramp = min(1.0, accel / spec.actions.max_acceleration_rpm_per_s)
        return cls(spec, schedule.foil_damping, ramp, b.speed_rpm_at(schedule.end_bearing_number), name)

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm, self.ramp), self.spec.damping_action(self.damping)]
