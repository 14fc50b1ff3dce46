"""``gfb_env/RunUp-v0``: run a gas foil bearing rotor up to a target speed that is stable only with the
right foil damping."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gfb_env.envs._data import nominal_task_constants
from gfb_env.envs.base import DEFAULT_GRID, EpisodeSetup, GFBEnv, StepOutcome, viscoelastic_model
from gfb_env.envs.commanded import (
    CommandedEpisode,
    CommandedSpeedMixin,
    CostSpec,
    SpeedCommand,
    build_commanded_task,
    check_task_version,
    unconstrained_cache_key,
)
from gfb_env.envs.config import check_in, check_range
from gfb_env.envs.rewards import RunUpReward
from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import Grid
from gfb_env.params import BearingParameters

__all__ = ["RunUpEnv", "RunUpTarget", "nominal_constants"]


def nominal_constants(grid: Grid, bearing: BearingParameters) -> dict:
    """Stability constants of the nominal bearing on ``grid``: see
    :func:`gfb_env.envs._data.nominal_task_constants` (table, or an explicit warned computation)."""
    return nominal_task_constants(grid, bearing)


@dataclass(frozen=True)
class RunUpTarget:
    """The task's record of a run-up episode: where it starts and where it must go (Lambda)."""

    start_bearing_number: float
    target_bearing_number: float


#: process-wide cache of the unconstrained best stable point of the fixed (nominal) plants
_BEST_POINTS: dict = {}


class RunUpEnv(CommandedSpeedMixin, GFBEnv):
    """Run a GFB rotor up from a low speed to a target speed as fast as possible and hold it stably.

    ## Description

    A rigid rotor (half of it, per bearing) runs on a first-generation bump-type gas foil bearing
    (Leister, Baum & Seemann 2017; Table 1 with a softer bump foil, ``K_W = 0.50``). Above the
    critical bearing number ``Lambda_c`` the static equilibrium loses stability through a subcritical
    Hopf bifurcation and the journal whirls at about half the rotor speed, on a limit cycle that can
    reach the foil (touchdown). ``Lambda_c`` depends on the foil damping ``D_W`` (paper Fig. 4): on
    the default grid it is 0.590 at ``D_W = 0.1``, 0.659 at ``D_W = 1`` and at most ``lambda_best =
    0.7014`` at the optimum ``D_W = 2.24`` (paper grid 79x7: 0.7074). The target is ``target_fraction
    * lambda_best`` (default 0.95: Lambda_t = 0.6663, 40 010 rpm), reachable without whirl only with a
    damping of about 1.1 to 4.0. The agent commands the speed ramp (a motor acceleration limit) and
    the foil damping (e.g. a controllable friction or squeeze-film damper).

    ## Action Space

    ``Box(-1, 1, (2,), float32)``:

    | index | action | mapping |
    |---|---|---|
    | 0 | speed ramp | ``dn/dt = a0 * max_acceleration_rpm_per_s`` (30 000 rpm/s: dLambda/dtau = 7.9e-5 a0) |
    | 1 | foil damping | ``D_W = D_min (D_max/D_min)^((a1+1)/2)``, log scale, ``[0.1, 10]``; a1 = 0: D_W = 1 |

    The commanded speed is clipped to ``speed_range_rpm`` (12 000-60 000 rpm).

    Lambda and D_W ramp linearly from their current values to the commanded ones over the control
    step.  NaN actions are replaced by 0, +-inf and out-of-range values are clipped to [-1, 1];
    ``info["action_sanitised"]`` says so.

    ## Observation Space

    ``Box(float32)`` of size ``8 + n_pressure_probes`` (always clipped into the bounds):

    | index | observation | bounds |
    |---|---|---|
    | 0, 1 | journal position xi (horizontal), eta (vertical, along gravity), units of C | [-3, 3] |
    | 2, 3 | journal velocity xi', eta', units of C/T | [-3, 3] |
    | 4, 5 | orbit envelope: extent (max - min) of xi and eta over the last control step | [0, 6] |
    | 6 | rotor speed n / 60 000 rpm (Lambda = 1.0 is 60 042 rpm) | [0, 1] |
    | 7 | foil damping D_W on the action scale, ``2 log(D_W/D_min)/log(D_max/D_min) - 1`` | [-1, 1] |
    | 8 ... | midplane pressure P = p/p0 at ``n_pressure_probes`` probes, phi = 2 pi k / n (*) | [0, 10] |

    (*) phi is measured from the direction of gravity (the eta axis), where the loaded film is thinnest.

    Optional Gaussian sensor noise (``observation_noise``) on indices 0-5 and the pressures.

    ## Rewards

    Per control step, with the progress potential ``Phi = -|Lambda - Lambda_t| / (Lambda_t - Lambda_0)``::

        r = progress_weight * (Phi_{k+1} - Phi_k) - time_penalty - whirl_penalty * min(A, 1.5)
            + success_bonus [on success] - touchdown_penalty [on touchdown or solver failure]

    ``A`` is the whirl amplitude: the largest distance (units of C) of the journal from the linear trend
    of its position over the control step.  Defaults: ``progress_weight = 10`` (a full run-up earns
    +10), ``time_penalty = 0.02``, ``whirl_penalty = 0.5``, ``success_bonus = 50``,
    ``touchdown_penalty = 200`` (more than whirling to the time limit).

    ## Starting State

    The static equilibrium at ``start_speed_rpm`` (default 27 000 rpm, Lambda_0 = 0.450, stable for
    every damping) with ``D_W`` drawn log-uniformly from the damping range, and a random journal
    velocity of magnitude up to 1e-3 C/T (both from ``np_random``).

    ## Episode End

    * ``terminated``, ``termination_reason = "success"``: speed within ``target_tolerance`` (1 %) of
      the target and whirl amplitude below ``stable_amplitude`` (0.05 C) for ``hold_steps`` (10)
      consecutive control steps.  Random disturbance kicks (probability 0.1 per step, 0.005 C/T) make
      an unstable equilibrium show itself within the hold window.
    * ``terminated``, ``"touchdown"``: min film thickness below ``touchdown_film_thickness`` (0.02 C,
      1 um).  ``"solver_failure"``: the integrator could not continue (treated like a touchdown).
    * ``truncated`` by the ``TimeLimit`` wrapper after ``max_episode_steps = 200`` control steps
      (12 000 tau = 1.9 s of rotor time).

    ## Arguments

    ``gymnasium.make("gfb_env/RunUp-v0", target_fraction=0.95, start_speed_rpm=27000, target_tolerance=0.01,
    progress_weight=10, time_penalty=0.02, whirl_penalty=0.5, success_bonus=50, touchdown_penalty=200,
    **base)`` where ``base`` are the arguments of :class:`~gfb_env.envs.base.GFBEnv`: ``grid="31x7"``,
    ``control_interval=60``, ``max_acceleration_rpm_per_s=30000``, ``speed_range_rpm=(12000, 60000)``,
    ``damping_range=(0.1, 10)``, ``n_pressure_probes=8``, ``observation_noise=0``,
    ``touchdown_film_thickness=0.02``, ``stable_amplitude=0.05``, ``hold_steps=10``,
    ``disturbance_probability=0.1``, ``disturbance_magnitude=0.005``, ``integrator_options=None``,
    ``render_mode=None``, and the machine (:mod:`gfb_env.machine`, ``docs/machine.md``): ``motor``,
    ``damping_actuator``, ``proximity_probes``, ``pressure_taps`` (defaults: v0's ideal machine).

    ## v1 (``gfb_env/RunUp-v1``, ``task_version=1``; :mod:`gfb_env.envs.commanded`, ``docs/envs.md``)

    The instrumented machine (``docs/machine.md``) with a hidden damping effectiveness ``g``
    log-uniform in [0.316, 3.16] (actual D_W = g x commanded) and a commanded-speed objective: per
    episode ``Lambda_cmd`` is drawn uniformly in ``command_fraction_range`` (0.93-1.03) x lambda_best
    (about 30 % of the commands lie above the best stable speed) and observed; the observation ends with
    ``[n_cmd / 60 000 rpm, steps_left / episode_steps]`` (names ``speed_command``, ``time_left``, bounds
    [0, 1]).  Fixed horizon ``episode_steps = 250`` (``terminated`` at the last step); touchdown and
    solver failure end earlier.  At the horizon the end is certified iff the whirl amplitude stayed below
    ``stable_amplitude`` over the last ``hold_steps`` steps and the actual plant's equilibrium at the
    final Lambda and actual D_W is linearly stable (``info["certified"]``, ``info["growth_rate"]``).
    Reward (:class:`~gfb_env.envs.rewards.CommandedSpeedReward`): ``0.1 p`` per calm step with
    ``p = clip((Lambda - Lambda_0) / (Lambda_cmd - Lambda_0), 0, 1)``, ``-0.5 min(A, 1.5)``, ``-100`` on
    touchdown, ``50 mean(p)`` over the window at a certified horizon, and ``25`` on success.  Success:
    certified and the window-mean Lambda >= (1 - 0.02) min(Lambda_cmd, lambda_best of the achievable
    actual damping).
    Costs: ``info["cost"]`` (whirl > 0.15 C, film < 0.1 C, touchdown); constraint: episode cost <= 5.
    The start damping command is drawn log-uniformly in the damping range (the plant's D_W is g times it).

    ## Version History

    * v0: initial version.
    * v1 (issue 10): v0 on the instrumented machine.  Redefined in place by issue 11 (no benchmark result
      had been published on v1): hidden damping gain in [0.316, 3.16], the observed speed command, the
      remaining-time observation, the fixed horizon of 250 steps, the stability certificate, the
      commanded-speed reward and the costs; then the on-target bonus (25 on success) added to the reward.
    """

    def __init__(
        self,
        target_fraction: float = 0.95,
        start_speed_rpm: float | None = None,
        target_tolerance: float | None = None,
        progress_weight: float = 10.0,
        time_penalty: float = 0.02,
        whirl_penalty: float = 0.5,
        success_bonus: float = 50.0,
        touchdown_penalty: float | None = None,
        task_version: int = 0,
        episode_steps: int | None = None,
        command_fraction_range: tuple[float, float] | None = None,
        speed_weight: float | None = None,
        cost_whirl_amplitude: float = 0.15,
        cost_film_thickness: float = 0.1,
        episode_cost_limit: float = 5.0,
        grid: str | Grid = DEFAULT_GRID,
        **kwargs,
    ):
        self.task_version = check_task_version(task_version)
        super().__init__(grid=grid, **kwargs)
        self.target_fraction = check_in("target_fraction", target_fraction, 0.0, 1.5, lo_open=True)
        self.target_tolerance = check_in(
            "target_tolerance",
            0.01 if target_tolerance is None else target_tolerance,
            0.0,
            0.5,
            lo_open=True,
            hi_open=True,
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
        self.commanded = build_commanded_task(
            self.task_version,
            episode_steps=episode_steps,
            default_episode_steps=250,
            target_tolerance=target_tolerance,
            speed_weight=speed_weight,
            whirl_penalty=whirl_penalty,
            success_bonus=success_bonus,
            touchdown_penalty=touchdown_penalty,
            stable_amplitude=self.stable_amplitude,
            hold_steps=self.hold_steps,
            costs=CostSpec(cost_whirl_amplitude, cost_film_thickness, episode_cost_limit),
            v1_only=self._v1_only_arguments(command_fraction_range),
        )
        if self.commanded is not None:  # one owner of the v1 tolerance
            self.target_tolerance = self.commanded.target_tolerance
        self.reward = RunUpReward(
            progress_weight,
            time_penalty,
            whirl_penalty,
            success_bonus,
            200.0 if touchdown_penalty is None else touchdown_penalty,
        )
        self.constants = nominal_constants(self.grid, self.nominal_bearing)
        self._nominal_model = viscoelastic_model(self.grid, self.nominal_bearing)
        b = self.nominal_bearing
        self.start_bearing_number = b.bearing_number_at(self.start_speed_rpm)
        self.target_bearing_number = self.target_fraction * self.constants["lambda_best"]
        if not self.start_bearing_number < self.target_bearing_number:
            raise ValueError("start_speed_rpm must be below the target speed")
        self._start_equilibrium = find_equilibrium(self._nominal_model, self.start_bearing_number)
        self._init_command_range(command_fraction_range)

    def _v1_only_arguments(self, command_range: object) -> dict:
        """The v1-only arguments of the task (v0 refuses them when given)."""
        return {"command_fraction_range": command_range}

    def _init_command_range(self, command_fraction_range: tuple[float, float] | None) -> None:
        """v1: ``Lambda_cmd / lambda_best`` is drawn uniformly from ``command_fraction_range`` (default
        0.93-1.03: about 30 % of the commands lie above the best stable speed)."""
        r = (0.93, 1.03) if command_fraction_range is None else command_fraction_range
        lo, hi = check_range("command_fraction_range", r) if r[0] != r[1] else (float(r[0]), float(r[1]))
        if not (self.start_bearing_number < lo * self.constants["lambda_best"] and hi <= 1.5):
            raise ValueError(f"command_fraction_range must lie above the start speed and <= 1.5, got {r!r}")
        self.command_fraction_range = (lo, hi)

    def _default_start_speed_rpm(self) -> float:
        """27 000 rpm: Lambda_0 = 0.450 for the nominal bearing, stable for every damping."""
        return 27_000.0

    # ------------------------------------------------------------------------------------------
    def _setup_episode(self, options) -> EpisodeSetup:
        if self.commanded is not None:
            return self._setup_commanded_episode()
        model = self._nominal_model
        L = model.layout
        dmin, dmax = self.damping_range
        dw = float(math.exp(self.np_random.uniform(math.log(dmin), math.log(dmax))))
        v = 1e-3 * self.np_random.random()
        ang = self.np_random.uniform(0, 2 * math.pi)
        s = self._start_equilibrium
        s = L.with_rotor(s, *L.rotor(s)[:2], v * math.cos(ang), v * math.sin(ang))
        target = RunUpTarget(self.start_bearing_number, self.target_bearing_number)
        return EpisodeSetup(
            model,
            s,
            target.start_bearing_number,
            dw,
            self.nominal_bearing,
            self._target_info(self.nominal_bearing, target),
            target,
        )

    def _setup_commanded_episode(self) -> EpisodeSetup:
        """v1: the hidden damping gain g, the commanded damping (log-uniform in the damping range; the
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
        )

    def _best_bearing_number_guess(self) -> float:
        return float(self.constants["lambda_best"])

    def _best_point_is_cached(self) -> bool:
        """The nominal plant is fixed: its optimum, computed once per process, serves every episode."""
        return True

    def _unconstrained_best_point(self) -> tuple[float, float]:
        """The nominal plant is fixed: its optimum is computed once per process (~0.3 s)."""
        model = self.episode.model
        search = self._damping_search_range()
        key = unconstrained_cache_key(model, search)
        if key not in _BEST_POINTS:
            _BEST_POINTS[key] = super()._unconstrained_best_point()
        return _BEST_POINTS[key]

    @staticmethod
    def _target_info(b: BearingParameters, target: RunUpTarget) -> dict:
        return {
            "target_bearing_number": target.target_bearing_number,
            "target_speed_rpm": b.speed_rpm_at(target.target_bearing_number),
            "start_bearing_number": target.start_bearing_number,
        }

    def _is_at_target(self, out: StepOutcome) -> bool:
        lam_t = self.episode.task.target_bearing_number
        return abs(out.bearing_number - lam_t) <= self.target_tolerance * lam_t

    def _reward_terms(self, out: StepOutcome, success: bool) -> dict[str, float]:
        if self.commanded is not None:
            return self._commanded_reward_terms(out)
        task = self.episode.task
        return self.reward.terms(out, success, task.start_bearing_number, task.target_bearing_number)

    def _optimum_damping(self) -> float:
        """The damping of the best stable speed of the episode's bearing (known to the simple expert)."""
        return self.constants["d_opt"]

    def scripted_action(self, ramp: float = 1.0) -> np.ndarray:
        """A simple expert: ramp at ``ramp`` of the motor limit toward the target with the optimum
        damping of the stability map (used by the benchmark and the tests)."""
        lam = self._integ.bearing_number
        step = self.max_rate() * self.control_interval
        a0 = float(np.clip((self.episode.task.target_bearing_number - lam) / step, -ramp, ramp))
        return np.array([a0, self.action_from_damping(self._optimum_damping())], dtype=np.float32)
