"""``gfb_env/RunUp-v2`` (and the retired ``gfb_env/RunUp-v1``): run a gas foil bearing rotor up to a
commanded speed, as close to it as is stably possible, with a foil damping whose effectiveness is hidden."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from gfb_env.envs._data import nominal_task_constants
from gfb_env.envs.base import EpisodeSetup, GFBEnv, viscoelastic_model
from gfb_env.envs.certify import StabilityCertificate
from gfb_env.envs.commanded import (
    V1_TARGET_TOLERANCE,
    CommandedEpisode,
    CommandedObjective,
    CostSpec,
    SpeedCommand,
    as_component,
    unconstrained_cache_key,
)
from gfb_env.envs.config import EnvConfig, check_range
from gfb_env.envs.rewards import CommandedSpeedReward
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import Grid
from gfb_env.params import BearingParameters

__all__ = ["RunUpEnv", "RunUpTarget", "nominal_constants", "commanded_objective"]


def nominal_constants(grid: Grid, bearing: BearingParameters) -> dict:
    """Stability constants of the nominal bearing on ``grid``: see
    :func:`gfb_env.envs._data.nominal_task_constants` (table, or an explicit warned computation)."""
    return nominal_task_constants(grid, bearing)


def commanded_objective(
    config: EnvConfig,
    episode_steps: int,
    target_tolerance: float,
    reward: CommandedSpeedReward | Mapping[str, Any] | None,
    costs: CostSpec | Mapping[str, Any] | None,
    default_costs: CostSpec | None = None,
) -> CommandedObjective:
    """The objective of a task: its horizon, tolerance, reward and costs (an instance, a dict of fields
    over the defaults, or None: the defaults; ``default_costs``: the task's), and the certificate of
    the configuration's ``stable_amplitude`` over its ``hold_steps``."""
    certificate = (
        StabilityCertificate(config.stable_amplitude, config.hold_steps)
        if config.interface is None
        else config.interface.certificate(config.stable_amplitude, config.hold_steps)
    )
    return CommandedObjective(
        episode_steps=episode_steps,
        certificate=certificate,
        target_tolerance=target_tolerance,
        reward=as_component("reward", CommandedSpeedReward, reward),
        costs=as_component("costs", CostSpec, costs, default_costs),
    )


@dataclass(frozen=True)
class RunUpTarget:
    """The task's record of a run-up episode: where it starts and where it is commanded to (Lambda)."""

    start_bearing_number: float
    target_bearing_number: float


#: process-wide cache of the unconstrained best stable point of the fixed (nominal) plants
_BEST_POINTS: dict = {}


class RunUpEnv(GFBEnv):
    """Run a GFB rotor up from a low speed to a commanded speed and end there, certified stable.

    ## Description

    A rigid rotor (half of it, per bearing) runs on a first-generation bump-type gas foil bearing
    (Leister, Baum & Seemann 2017; Table 1 with a softer bump foil, ``K_W = 0.50``). Above the
    critical bearing number ``Lambda_c`` the static equilibrium loses stability through a subcritical
    Hopf bifurcation and the journal whirls at about half the rotor speed, on a limit cycle that can
    reach the foil (touchdown). ``Lambda_c`` depends on the foil damping ``D_W`` (paper Fig. 4): on
    the default grid it is 0.590 at ``D_W = 0.1``, 0.659 at ``D_W = 1`` and at most ``lambda_best =
    0.7014`` at the optimum ``D_W = 2.24`` (paper grid 79x7: 0.7074).  The agent commands the speed ramp
    (a motor acceleration limit) and the foil damping (e.g. a controllable friction or squeeze-film
    damper) on the instrumented machine (``docs/machine.md``: actuator lag and rate limit, noisy biased
    probes and taps, random base shocks, a residual unbalance) whose damping effectiveness ``g`` is
    hidden: actual D_W = g x commanded, g log-uniform in [0.316, 3.16] (paper Eq. 15: D_W is known only
    to an order of magnitude).  Per episode a speed ``Lambda_cmd`` is commanded, uniform in
    ``command_fraction_range`` (0.93-1.03) x lambda_best (about 30 % of the commands lie above the best
    stable speed), and observed.  The objective (:class:`~gfb_env.envs.commanded.CommandedObjective`,
    ``env.objective``): run as close to the command as is stably possible.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``:

    | index | action | mapping |
    |---|---|---|
    | 0 | speed ramp | ``dn/dt = a0 * max_acceleration_rpm_per_s`` (30 000 rpm/s: dLambda/dtau = 7.9e-5 a0) |
    | 1 | foil damping command | ``D_min (D_max/D_min)^((a1+1)/2)``, log scale, ``[0.1, 10]``; a1 = 0: 1 |

    The commanded speed is clipped to ``speed_range_rpm`` (12 000-60 000 rpm).  Lambda and D_W ramp over
    the control step.  NaN actions are replaced by 0, +-inf and out-of-range values are clipped to
    [-1, 1] (``info["action_sanitised"]``); an action of another shape than ``(2,)`` or of a complex or
    non-numeric dtype raises ``ValueError``.

    ## Observation Space

    ``Box(float32)`` of size ``10 + n_pressure_probes`` (always clipped into the bounds; from the
    sensors, so noisy and biased):

    | index | observation | bounds |
    |---|---|---|
    | 0, 1 | journal position xi (horizontal), eta (vertical, along gravity), units of C | [-3, 3] |
    | 2, 3 | journal velocity xi', eta', units of C/T | [-3, 3] |
    | 4, 5 | orbit envelope: extent (max - min) of xi and eta over the last control step | [0, 6] |
    | 6 | rotor speed n / 60 000 rpm (Lambda = 1.0 is 60 042 rpm) | [0, 1] |
    | 7 | the damping command the actuator reports, on the action scale | [-1, 1] |
    | 8 ... | midplane pressure P = p/p0 at ``n_pressure_probes`` probes, phi = 2 pi k / n (*) | [0, 10] |
    | -2 | ``speed_command``: n_cmd / 60 000 rpm | [0, 1] |
    | -1 | ``time_left``: steps left / episode_steps | [0, 1] |

    (*) phi is measured from the direction of gravity (the eta axis), where the loaded film is thinnest.

    ## Rewards

    :class:`~gfb_env.envs.rewards.CommandedSpeedReward`: ``0.1 p`` per calm step with ``p = clip((Lambda
    - Lambda_0) / (Lambda_cmd - Lambda_0), 0, 1)``, ``-0.5 min(A, 1.5)`` (A: the whirl amplitude, units
    of C), ``-100`` on touchdown, ``50 mean(p)`` over the window at a certified horizon, and ``25`` on
    success.  Costs (Safety-Gymnasium style): ``info["cost"]`` (whirl > 0.15 C, film < 0.1 C,
    touchdown); constraint: episode cost <= 5.

    ## Starting State

    The static equilibrium at ``start_speed_rpm`` (default 27 000 rpm, Lambda_0 = 0.450, stable for
    every damping), the damping command drawn log-uniformly in the damping range (the plant's D_W is g
    times it), and a random journal velocity of magnitude up to 1e-3 C/T (all from ``np_random``).

    ## Episode End

    Fixed horizon ``episode_steps = 250`` (``terminated`` at the last step); touchdown (min film
    below 0.02 C) and solver failure end earlier.  At the horizon the end is certified iff the whirl
    amplitude stayed below ``stable_amplitude`` over the last ``hold_steps`` steps and the actual
    plant's equilibrium at the final Lambda and actual D_W is linearly stable (``info["certified"]``,
    ``info["growth_rate"]``).  Success (``termination_reason = "success"``): certified and the
    window-mean Lambda >= (1 - 0.02) min(Lambda_cmd, lambda_best of the achievable actual damping).

    ## Arguments

    ``gymnasium.make("gfb_env/RunUp-v1", start_speed_rpm=27000, command_fraction_range=(0.93, 1.03),
    episode_steps=250, target_tolerance=0.02, reward=None, costs=None, **base)``: ``reward`` a
    :class:`~gfb_env.envs.rewards.CommandedSpeedReward` or a dict of its fields (``speed_weight``,
    ``whirl_penalty``, ``success_bonus``, ``touchdown_penalty``, ``target_bonus``), ``costs`` a
    :class:`~gfb_env.envs.commanded.CostSpec` or a dict of its fields; ``base`` the arguments of
    :class:`~gfb_env.envs.config.EnvConfig` (``grid="31x7"``, ``control_interval=60``, ...,
    the machine) and ``render_mode``.  The registered id adds the instrumented machine
    (:data:`~gfb_env.envs.MACHINE_V1`, the hidden gain); the class alone defaults to the ideal machine.

    ## Version History

    * v0: the plant on an ideal machine with a fixed target; retired (issue 18: its plant is exactly
      identifiable from the first observation; ``CHANGELOG.md``).
    * v1 (issues 10, 11): the instrumented machine, the hidden damping gain, the observed speed
      command, the fixed horizon, the stability certificate, the commanded-speed reward and the costs.
    * v2 (issue 19): the v1 task behind the v2 information interface
      (:class:`~gfb_env.envs.interface_v2.MonitorInterface`): the vibration monitor's observation, the
      reward and costs from the measurements, an info with no ground truth.  v1 retired: its info and
      reward hand the hidden plant to any policy (``gfb_env.envs.retired``; ``make_retired`` builds
      it for the record only).
    """

    def __init__(
        self,
        start_speed_rpm: float | None = None,
        command_fraction_range: tuple[float, float] = (0.93, 1.03),
        episode_steps: int = 250,
        target_tolerance: float = V1_TARGET_TOLERANCE,
        reward: CommandedSpeedReward | Mapping[str, Any] | None = None,
        costs: CostSpec | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        config = EnvConfig.from_kwargs(kwargs)
        super().__init__(
            commanded_objective(config, episode_steps, target_tolerance, reward, costs), config, render_mode
        )
        if start_speed_rpm is None:  # the task's default, from the validated configuration
            start_speed_rpm = self._default_start_speed_rpm()
        lo, hi = self.speed_range_rpm
        if not (
            isinstance(start_speed_rpm, (int, float))
            and math.isfinite(start_speed_rpm)
            and lo <= start_speed_rpm <= hi
        ):
            raise ValueError(
                f"start_speed_rpm must lie in speed_range_rpm {self.speed_range_rpm}, got {start_speed_rpm!r}"
            )
        self.start_speed_rpm = float(start_speed_rpm)
        self.constants = nominal_constants(self.grid, self.nominal_bearing)
        self._init_plant()
        self._init_command_range(command_fraction_range)

    def _init_plant(self) -> None:
        """The nominal plant and its start equilibrium (a drawn plant: per episode instead)."""
        self._nominal_model = viscoelastic_model(self.grid, self.nominal_bearing)
        self.start_bearing_number = self.nominal_bearing.bearing_number_at(self.start_speed_rpm)
        self._start_equilibrium = find_equilibrium(self._nominal_model, self.start_bearing_number)

    def _init_command_range(self, command_fraction_range: tuple[float, float]) -> None:
        """``Lambda_cmd / lambda_best`` is drawn uniformly from ``command_fraction_range`` (default
        0.93-1.03: about 30 % of the commands lie above the best stable speed)."""
        r = command_fraction_range
        try:
            equal = r[0] == r[1]
        except (TypeError, IndexError, KeyError):
            raise ValueError(f"command_fraction_range must be a pair (low, high), got {r!r}") from None
        lo, hi = check_range("command_fraction_range", r) if not equal else (float(r[0]), float(r[1]))
        if not (self.start_bearing_number < lo * self.constants["lambda_best"] and hi <= 1.5):
            raise ValueError(f"command_fraction_range must lie above the start speed and <= 1.5, got {r!r}")
        self.command_fraction_range = (lo, hi)

    @property
    def reference_speed_rpm(self) -> float:
        """The public speed where the progress p is zero (rpm): the start speed (a task constant)."""
        return self.start_speed_rpm

    def _default_start_speed_rpm(self) -> float:
        """27 000 rpm: Lambda_0 = 0.450 for the nominal bearing, stable for every damping."""
        return 27_000.0

    # ------------------------------------------------------------------------------------------
    def _setup_episode(self, options) -> EpisodeSetup:
        """The hidden damping gain g, the commanded damping (log-uniform in the damping range; the
        plant's D_W is g times it), the start velocity, then the speed command."""
        rng = self.np_random
        model = self._nominal_model
        L = model.layout
        gain = self.damping_actuator.draw_gain(rng)
        dmin, dmax = self.damping_range
        d_cmd = float(math.exp(rng.uniform(math.log(dmin), math.log(dmax))))
        v = 1e-3 * rng.random()
        ang = rng.uniform(0, 2 * math.pi)
        s = self._start_equilibrium
        s = L.with_rotor(s, *L.rotor(s)[:2], v * math.cos(ang), v * math.sin(ang))
        b = self.nominal_bearing
        lam_cmd = float(rng.uniform(*self.command_fraction_range)) * self.constants["lambda_best"]
        command = SpeedCommand(b.speed_rpm_at(lam_cmd), lam_cmd, self.start_bearing_number)
        target = RunUpTarget(self.start_bearing_number, lam_cmd)
        return EpisodeSetup(
            model,
            s,
            self.start_bearing_number,
            gain * d_cmd,
            b,
            {"start_bearing_number": self.start_bearing_number},
            target,
            damping_gain=gain,
            command=CommandedEpisode(command),
            hidden={"start_velocity_c_per_t": v, "start_velocity_angle_rad": ang},
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

    def _optimum_damping(self) -> float:
        """The damping of the nominal map's best stable speed (known to the simple expert)."""
        return self.constants["d_opt"]

    def scripted_action(self, ramp: float = 1.0) -> np.ndarray:
        """A simple expert: ramp at ``ramp`` of the motor limit toward the command with the optimum
        damping command of the nominal stability map (used by the benchmark and the tests)."""
        lam = self._integ.bearing_number
        step = self.max_rate() * self.step_tau
        a0 = float(np.clip((self.episode.task.target_bearing_number - lam) / step, -ramp, ramp))
        return np.array([a0, self.action_from_damping(self._optimum_damping())], dtype=np.float32)
