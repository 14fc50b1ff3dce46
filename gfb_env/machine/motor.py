"""The drive motor: an acceleration limit between the speed command and the rotor speed.

``a_speed in [-1, 1]`` ramps the speed at ``a_speed * max_acceleration_rpm_per_s`` over the control
step, i.e. ``dLambda/dtau = a_speed * max_acceleration_rpm_per_s / (rpm/s per unit dLambda/dtau)``
(depends on the bearing's time scale T), and the commanded speed stays inside the speed range.
"""

from __future__ import annotations

from dataclasses import dataclass

from gfb_env.machine._checks import positive
from gfb_env.params import BearingParameters

__all__ = ["Motor"]


@dataclass(frozen=True)
class Motor:
    """Acceleration-limited motor (the speed command of the first tasks, as a component).

    Attributes:
        max_acceleration_rpm_per_s: the acceleration limit; ``a_speed = +-1`` ramps at it.  Default
            30 000 rpm/s: a small high-speed motor (the nominal run-up 27 000 -> 40 000 rpm in ~0.45 s),
            dLambda/dtau = 7.9e-5 for the nominal bearing (T = 1.590e-4 s).
    """

    max_acceleration_rpm_per_s: float = 30_000.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "max_acceleration_rpm_per_s",
            positive("max_acceleration_rpm_per_s", self.max_acceleration_rpm_per_s),
        )

    def max_rate(self, bearing: BearingParameters) -> float:
        """The limit as ``dLambda/dtau`` of ``bearing``."""
        return self.max_acceleration_rpm_per_s / bearing.rate_rpm_per_s(1.0)

    def bearing_number_at_step_end(
        self,
        bearing_number: float,
        a_speed: float,
        bearing: BearingParameters,
        control_interval: float,
        limits: tuple[float, float],
    ) -> float:
        """Commanded Lambda at the end of a control step of ``control_interval`` tau that starts at
        ``bearing_number`` with the speed action ``a_speed``, clipped into ``limits`` (Lambda at the
        ends of the speed range).  The arithmetic is the first tasks', operation for operation."""
        lam_lo, lam_hi = limits
        # np.clip's min(max(x, lo), hi) in plain Python (a NaN passes as there; ~4 us less per step)
        return float(
            min(max(bearing_number + a_speed * self.max_rate(bearing) * control_interval, lam_lo), lam_hi)
        )
