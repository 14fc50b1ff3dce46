"""Reward functions of the tasks: frozen, validated weights, and terms returned by name.

As in Gymnasium's MuJoCo tasks, every reward is the sum of named terms and the terms go into ``info``
(``info["reward_<term>"]``), so that a learner's behaviour can be read term by term.  The terms are
pure functions of the :class:`~gfb_env.envs.episode.StepOutcome` of one control step.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from gfb_env.envs.config import check_nonnegative
from gfb_env.envs.episode import StepOutcome

__all__ = ["CommandedSpeedReward", "WHIRL_AMPLITUDE_CAP"]

#: The whirl term saturates at 1.5 C: larger orbits touch down anyway, and the touchdown penalty says so.
WHIRL_AMPLITUDE_CAP = 1.5


class _Weights:
    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, check_nonnegative(f.name, getattr(self, f.name)))


@dataclass(frozen=True)
class CommandedSpeedReward(_Weights):
    """The reward of the commanded-speed objective: ``r = speed + whirl + certified_speed + touchdown``
    with the speed progress ``p(Lambda) = clip((Lambda - Lambda_ref) / (Lambda_cmd - Lambda_ref), 0, 1)`` and

    * ``speed = speed_weight * p(Lambda)`` per step, only while the whirl amplitude is below the stable
      threshold (running fast while whirling earns nothing);
    * ``whirl = -whirl_penalty * min(A, 1.5)`` with the whirl amplitude A (units of C);
    * ``certified_speed = success_bonus * mean(p)`` over the last ``hold_steps`` steps, paid once at the
      horizon and only if the end is certified stable (:mod:`gfb_env.envs.certify`);
    * ``on_target = target_bonus`` once at the horizon if the episode succeeded: certified and the
      window-mean speed within the task's tolerance (2 %) of ``min(command, lambda_best)`` of the actual
      plant;
    * ``touchdown = -touchdown_penalty`` on touchdown or solver failure.

    Why these weights: the per-step term sums to at most ``speed_weight * episode_steps`` (25 over 250
    steps), half the terminal bonus (50), so a policy cannot buy more return by running an unstable
    speed with a small orbit than it loses by failing the certificate; a touchdown (100) costs more than
    the whole bonus and every step term together, so risking one is never worth it.  The on-target
    bonus (25, issue 11) pays for knowing where the boundary is: the certified bonus alone is nearly
    flat near it (ending at 0.90 instead of 0.99 ``lambda_best`` costs ~5 of 50), so the return could
    not tell a controller that finds ``Lambda_c`` to 2 % from one that stays 10 % below it.  A perfect
    episode returns about 100 (25 + 50 + 25).
    """

    speed_weight: float = 0.1
    whirl_penalty: float = 0.5
    success_bonus: float = 50.0
    touchdown_penalty: float = 100.0
    target_bonus: float = 25.0

    @staticmethod
    def progress(bearing_number: float, reference: float, command: float) -> float:
        """``clip((Lambda - Lambda_ref) / (Lambda_cmd - Lambda_ref), 0, 1)``."""
        p = (bearing_number - reference) / (command - reference)
        return 0.0 if not p > 0.0 else (1.0 if p > 1.0 else float(p))

    def terms(
        self,
        out: StepOutcome,
        stable: bool,
        progress: float,
        certified_progress: float | None,
        on_target: bool = False,
    ) -> dict[str, float]:
        """``progress``: ``p`` of this step; ``certified_progress``: the window mean of ``p`` at a
        certified horizon (None otherwise); ``on_target``: the episode succeeded (at the horizon)."""
        return {
            "speed": self.speed_weight * progress if stable else 0.0,
            "whirl": -self.whirl_penalty * min(out.whirl_amplitude, WHIRL_AMPLITUDE_CAP),
            "certified_speed": self.success_bonus * certified_progress
            if certified_progress is not None
            else 0.0,
            "on_target": self.target_bonus if on_target else 0.0,
            "touchdown": -self.touchdown_penalty if (out.touchdown or out.solver_failure) else 0.0,
        }
