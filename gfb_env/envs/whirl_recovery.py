"""``gfb_env/WhirlRecovery-v2`` (and the retired ``-v1``): bring a whirling GFB rotor back to a certified
stable equilibrium, restoring as much of the commanded speed as is stably possible."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from gfb_env.envs.base import EpisodeSetup, GFBEnv, viscoelastic_model
from gfb_env.envs.commanded import (
    V1_TARGET_TOLERANCE,
    CommandedEpisode,
    CostSpec,
    SpeedCommand,
    unconstrained_cache_key,
)
from gfb_env.envs.config import EnvConfig, check_in
from gfb_env.envs.rewards import CommandedSpeedReward
from gfb_env.envs.run_up import _BEST_POINTS, commanded_objective, nominal_constants

__all__ = ["WhirlRecoveryEnv"]

#: WhirlRecovery's constraint: a recovery at the motor limit whirls for ~10 steps
_COSTS = CostSpec(episode_cost_limit=15.0)


class WhirlRecoveryEnv(GFBEnv):
    """Recover from a fully developed whirl (a stable limit cycle above the critical speed).

    ## Description

    Same plant, actions and observations as ``gfb_env/RunUp-v1`` (nominal bearing, ``K_W = 0.50``, the
    instrumented machine). The episode starts on the developed whirl at ``Lambda_w = 1.03 lambda_best
    = 0.7225`` (43.4 krpm on the default grid), above the best critical bearing number ``lambda_best =
    0.7014``, where no damping stabilises the equilibrium, with the nominal map's optimum ``d_opt =
    2.24`` commanded.  The hidden damping gain g is log-uniform in [0.6, 1.8]
    (:data:`~gfb_env.envs.V1_WHIRL_RECOVERY_GAIN_RANGE`: the gains with which a machine can whirl
    steadily at Lambda_w with d_opt commanded; outside it the start orbit touches down within 1-3 steps
    whatever the policy does), so the actual D_W is g d_opt.  Because the Hopf bifurcation is
    subcritical, the whirl persists below ``Lambda_c`` down to the fold of the limit cycles
    (hysteresis): the agent has to slow down into the band where the cycle no longer exists (and choose
    the damping that shrinks that band), then may speed up again to just below ``Lambda_c`` as long as
    the equilibrium stays stable.  Bad damping can grow the orbit into a touchdown.

    The command is Lambda_w (observed: restore the speed as far as stably possible; it always lies above
    lambda_best); the reference of the speed progress is ``Lambda_ref = reference_fraction *
    lambda_best`` (0.85: 0.596, about Lambda_c of the worst damping, 0.590; with the optimum damping the
    whirl collapses near 0.66).

    ## Action Space, Observation Space

    As RunUp-v1 (``Box(-1, 1, (2,), float32)``; the observation ends with ``speed_command`` and
    ``time_left``).

    ## Rewards, Episode End

    As RunUp-v1 with a horizon of 200 steps (success: certified and the window-mean Lambda >= 0.98
    lambda_best of the achievable actual damping); the constraint allows an episode cost of 15.

    ## Starting State

    The stored limit-cycle state (``data/task_constants.json``, the cycle at D_W = d_opt) advanced by a
    random phase, uniform over one whirl period (25.6 tau), at Lambda_w under the actual damping g d_opt,
    so the orbit is on its way to the actual damping's cycle.  The indicated damping is d_opt whatever
    g (a start at actual D_W = d_opt would show d_opt / g and give g away).

    ## Arguments

    ``gymnasium.make("gfb_env/WhirlRecovery-v1", reference_fraction=0.85, episode_steps=200,
    target_tolerance=0.02, reward=None, costs=None, **base)``, as RunUp-v1 (``costs`` defaults to an
    episode cost limit of 15).

    ## Version History

    * v0: the whirl on an ideal machine, ending on a hold of calm steps; retired (issue 18,
      ``CHANGELOG.md``).
    * v1 (issues 10, 11): the instrumented machine, the hidden gain (narrowed from [0.316, 3.16] to
      [0.6, 1.8]), the observed command (Lambda_w), the horizon, the certificate, reward and costs.
    * v2 (issue 19): the v1 task behind the v2 information interface
      (:class:`~gfb_env.envs.interface_v2.MonitorInterface`): the vibration monitor's observation, the
      reward and costs from the measurements, an info with no ground truth.  v1 retired: its info and
      reward hand the hidden plant to any policy, and its reset observation tells g
      (``gfb_env.envs.retired``; ``make_retired`` builds it for the record only).
    """

    def __init__(
        self,
        reference_fraction: float = 0.85,
        episode_steps: int = 200,
        target_tolerance: float = V1_TARGET_TOLERANCE,
        reward: CommandedSpeedReward | Mapping[str, Any] | None = None,
        costs: CostSpec | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        config = EnvConfig.from_kwargs(kwargs)
        super().__init__(
            commanded_objective(config, episode_steps, target_tolerance, reward, costs, _COSTS),
            config,
            render_mode,
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
        #: the speed progress is zero at ``reference_fraction * lambda_best`` (default 0.85: about
        #: Lambda_c of the worst damping; a recovery with the optimum damping dips to ~0.66 only)
        self.reference_fraction = check_in(
            "reference_fraction", reference_fraction, 0.0, 1.0, lo_open=True, hi_open=True
        )
        self.reference_bearing_number = self.reference_fraction * float(self.constants["lambda_best"])

    @property
    def reference_speed_rpm(self) -> float:
        """The public speed where the progress p is zero (rpm): ``reference_fraction`` x lambda_best of
        the nominal bearing (a task constant)."""
        return self.nominal_bearing.speed_rpm_at(self.reference_bearing_number)

    def _setup_episode(self, options) -> EpisodeSetup:
        """The machine was running at Lambda_w with the nominal map's optimum commanded (d_opt); its
        actual damping is g d_opt with the hidden gain g (drawn first), the start state the stored whirl
        advanced by a random phase under it (class docstring)."""
        gain = self.damping_actuator.draw_gain(self.np_random)
        model = self._model_nominal
        dw = gain * self.whirl_damping
        phase = float(self.np_random.uniform(0.0, self.whirl_period))
        integ = self.new_integrator(model, self._whirl_state, self.whirl_bearing_number, dw)
        integ.advance(phase)
        b = self.nominal_bearing
        lam_w = self.whirl_bearing_number
        info = {"whirl_bearing_number": lam_w, "whirl_speed_rpm": b.speed_rpm_at(lam_w)}
        return EpisodeSetup(
            model,
            integ.state,
            lam_w,
            dw,
            b,
            info,
            damping_gain=gain,
            command=CommandedEpisode(
                SpeedCommand(b.speed_rpm_at(lam_w), lam_w, self.reference_bearing_number)
            ),
            hidden={"start_phase_tau": phase},
        )

    def _best_bearing_number_guess(self) -> float:
        return float(self.constants["lambda_best"])

    def _best_point_is_cached(self) -> bool:
        """The nominal plant is fixed: its optimum, computed once per process, serves every episode."""
        return True

    def _unconstrained_best_point(self) -> tuple[float, float]:
        """The nominal plant is fixed: its optimum is computed once per process (~0.3 s)."""
        model = self.episode.model
        key = unconstrained_cache_key(model, self._damping_search_range())
        if key not in _BEST_POINTS:
            _BEST_POINTS[key] = super()._unconstrained_best_point()
        return _BEST_POINTS[key]

    def scripted_action(self) -> np.ndarray:
        """A simple expert: optimum damping; slow down while whirling, hold speed once it has calmed."""
        ep = self.episode
        a0 = -1.0 if ep.whirl_amplitude > self.stable_amplitude or ep.step == 0 else 0.0
        return np.array([a0, self.action_from_damping(self.constants["d_opt"])], dtype=np.float32)
