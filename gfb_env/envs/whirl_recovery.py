"""``gfb_env/WhirlRecovery-v0``: bring a whirling GFB rotor back to a stable equilibrium, losing as
little speed as possible."""

from __future__ import annotations

import math

import numpy as np

from gfb_env.envs.base import DEFAULT_GRID, EpisodeSetup, GFBEnv, StepOutcome, viscoelastic_model
from gfb_env.envs.rewards import WhirlRecoveryReward
from gfb_env.envs.run_up import nominal_constants
from gfb_env.model import Grid

__all__ = ["WhirlRecoveryEnv"]


class WhirlRecoveryEnv(GFBEnv):
    """Recover from a fully developed whirl (a stable limit cycle above the critical speed).

    ## Description

    Same plant, actions and observations as ``gfb_env/RunUp-v0`` (nominal bearing, ``K_W = 0.50``). The
    episode starts on the developed whirl limit cycle at ``Lambda_w = 1.03 lambda_best = 0.7225`` (43.4 krpm
    on the default grid) with the optimum damping ``D_W = 2.24``: above the best critical
    bearing number ``lambda_best = 0.7014`` no damping stabilises the equilibrium. The orbit reaches
    an eccentricity of 1.11 C and a min film of 0.27 C; a damping far from the optimum (0.1 or 10)
    grows it into a touchdown within 460-1000 tau (8-16 control steps). Because the Hopf bifurcation
    is subcritical, the whirl persists below ``Lambda_c`` down to the fold of the limit cycles
    (hysteresis): the agent has to slow down into the band where the cycle no longer exists (and
    choose the damping that shrinks that band), then may speed up again to just below ``Lambda_c`` as
    long as the equilibrium stays stable. Bad damping can grow the orbit into a touchdown.

    ## Action Space

    As RunUp-v0: ``Box(-1, 1, (2,), float32)``, [speed ramp in units of ``max_acceleration_rpm_per_s``
    (30 000 rpm/s), log-scaled foil damping in ``damping_range`` ([0.1, 10])]; NaN/inf sanitised.

    ## Observation Space

    As RunUp-v0: ``Box(float32)`` of size ``8 + n_pressure_probes``: xi, eta [-3, 3]; xi', eta'
    [-3, 3]; orbit extents of xi, eta over the last control step [0, 6]; speed n / 60 000 rpm [0, 1];
    damping on the action scale [-1, 1]; midplane pressures P [0, 10].

    ## Rewards

    Per control step::

        r = -time_penalty - whirl_penalty * min(A, 1.5)
            - speed_loss_weight * max(0, Lambda_w - Lambda) / Lambda_w
            + success_bonus * Lambda / Lambda_w         [on success]
            - touchdown_penalty                         [on touchdown or solver failure]

    with the whirl amplitude ``A`` (units of C, see RunUp-v0).  Defaults: ``time_penalty = 0.02``,
    ``whirl_penalty = 0.5``, ``speed_loss_weight = 2``, ``success_bonus = 50``,
    ``touchdown_penalty = 200``.  The success bonus grows with the speed kept at the end.

    ## Starting State

    The stored limit-cycle state (``data/task_constants.json``) advanced by a random phase, uniform
    over one whirl period (25.6 tau), at ``Lambda_w`` and ``D_W = d_opt``.

    ## Episode End

    * ``terminated``, ``"success"``: whirl amplitude below ``stable_amplitude`` (0.05 C) for
      ``hold_steps`` (10) consecutive control steps at any speed (disturbance kicks, probability 0.1
      and 0.005 C/T by default, test the stability of the equilibrium reached);
    * ``terminated``, ``"touchdown"`` (min film < 0.02 C) or ``"solver_failure"``;
    * ``truncated`` by the TimeLimit after ``max_episode_steps = 200`` control steps.

    ## Arguments

    ``gymnasium.make("gfb_env/WhirlRecovery-v0", time_penalty=0.02, whirl_penalty=0.5,
    speed_loss_weight=2, success_bonus=50, touchdown_penalty=200, **base)`` with the base arguments of
    :class:`~gfb_env.envs.base.GFBEnv` (grid, control_interval, ..., render_mode).

    ## Version History

    * v0: initial version.
    """

    def __init__(
        self,
        time_penalty: float = 0.02,
        whirl_penalty: float = 0.5,
        speed_loss_weight: float = 2.0,
        success_bonus: float = 50.0,
        touchdown_penalty: float = 200.0,
        grid: str | Grid = DEFAULT_GRID,
        **kwargs,
    ):
        super().__init__(grid=grid, **kwargs)
        self.reward = WhirlRecoveryReward(
            time_penalty, whirl_penalty, speed_loss_weight, success_bonus, touchdown_penalty
        )
        self.constants = nominal_constants(self.grid, self.nominal_bearing)
        w = self.constants["whirl"]
        self._model_nominal = viscoelastic_model(self.grid, self.nominal_bearing)
        self.whirl_bearing_number = float(w["bearing_number"])
        self.whirl_damping = float(w["foil_damping"])
        self.whirl_period = (
            float(w["period"]) if math.isfinite(w["period"]) else 4 * math.pi / w["bearing_number"]
        )
        self._whirl_state = np.asarray(w["state"], dtype=float)
        dmin, dmax = self.damping_range
        if not dmin <= self.whirl_damping <= dmax:
            raise ValueError(
                f"damping_range {self.damping_range} must contain the whirl damping {self.whirl_damping:.3g}"
            )

    def _setup_episode(self, options) -> EpisodeSetup:
        model = self._model_nominal
        phase = float(self.np_random.uniform(0.0, self.whirl_period))
        integ = self.new_integrator(model, self._whirl_state, self.whirl_bearing_number, self.whirl_damping)
        integ.advance(phase)
        b = self.nominal_bearing
        info = {
            "whirl_bearing_number": self.whirl_bearing_number,
            "whirl_speed_rpm": b.speed_rpm_at(self.whirl_bearing_number),
            "best_stable_bearing_number": self.constants["lambda_best"],
            "best_stable_speed_rpm": b.speed_rpm_at(self.constants["lambda_best"]),
        }
        return EpisodeSetup(model, integ.state, self.whirl_bearing_number, self.whirl_damping, b, info)

    def _reward_terms(self, out: StepOutcome, success: bool) -> dict[str, float]:
        return self.reward.terms(out, success, self.whirl_bearing_number)

    def scripted_action(self) -> np.ndarray:
        """A simple expert: optimum damping; slow down while whirling, hold speed once it has calmed."""
        ep = self.episode
        a0 = -1.0 if ep.whirl_amplitude > self.stable_amplitude or ep.step == 0 else 0.0
        return np.array([a0, self.action_from_damping(self.constants["d_opt"])], dtype=np.float32)
