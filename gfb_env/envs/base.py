"""Base Gymnasium environment: speed and foil-damping control of a gas foil bearing (GFB) rotor.

The plant is the viscoelastic GFB rotor model of Leister, Baum & Seemann (paper Sect. 2,
:class:`~gfb_env.model.GFBModel`), advanced by the adaptive trapezoidal integrator
(:class:`~gfb_env.integrator.TrapezoidalIntegrator`).  One control step spans ``control_interval``
units of tau (several whirl periods ``~4 pi / Lambda``) and many integrator steps; over a control step
the bearing number Lambda and the foil damping D_W ramp linearly from their current values to the
commanded ones.

Subclasses define the task (:meth:`GFBEnv._setup_episode` and :meth:`GFBEnv._task_reward`); see
``run_up.py``, ``run_up_randomized.py`` and ``whirl_recovery.py``, and ``docs/envs.md``.

Scaling of the observations: the sensors measure in physical units and the observation divides them
by the scales of the *nominal* bearing of the task (clearance C_nom, time scale T_nom, ``speed_scale_rpm``).
For the nominal bearing this is exactly the nondimensional state of the paper (xi, eta in units of C,
velocities in C / T); for a randomised bearing (other C) the observation does not reveal the drawn
clearance except through the physics.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.integrator import IntegrationError, TrapezoidalIntegrator
from gfb_env.model import GFBModel, Grid, Structure
from gfb_env.params import BearingParameters

__all__ = ["GFBEnv", "EpisodeSetup", "StepOutcome", "DEFAULT_GRID"]

#: Default training grid, chosen by the measured accuracy/speed trade-off in ``docs/envs.md``
#: (``experiments/env_grid_tradeoff.py``): Lambda_c within 1 % of the paper grid 79 x 7.
DEFAULT_GRID = "31x7"

# observation layout (before the pressure probes)
OBS_XI, OBS_ETA, OBS_XI_DOT, OBS_ETA_DOT, OBS_XI_EXTENT, OBS_ETA_EXTENT, OBS_SPEED, OBS_DAMPING = range(8)
N_ROTOR_OBS = 8
POSITION_BOUND = 3.0  # |xi|, |eta| <= 3 C (eps > 1 is possible: the foil deflects)
VELOCITY_BOUND = 3.0  # |xi'|, |eta'| <= 3 C/T
EXTENT_BOUND = 6.0  # orbit extent <= 2 * POSITION_BOUND
PRESSURE_BOUND = 10.0  # 0 <= P = p / p0 <= 10


@dataclass
class EpisodeSetup:
    """What a task decides at ``reset``: the plant and where it starts."""

    model: GFBModel
    state: np.ndarray
    bearing_number: float
    foil_damping: float
    bearing: BearingParameters
    info: dict


@dataclass
class StepOutcome:
    """Measured quantities of one control step (input of the task reward)."""

    bearing_number_start: float
    bearing_number: float
    foil_damping: float
    whirl_amplitude: float
    min_film_thickness: float
    touchdown: bool
    solver_failure: bool


class GFBEnv(gym.Env):
    """Common machinery of the GFB tasks (actions, observations, integration, rendering, snapshots).

    Args:
        grid: finite-difference grid ``"N_phi x N_Z"`` (default :data:`DEFAULT_GRID`).
        control_interval: tau per control step (default 60, ~3 whirl periods at Lambda = 0.7;
            0.0095 s for the nominal bearing).
        max_acceleration_rpm_per_s: motor acceleration limit; action[0] = +-1 ramps the speed at
            this rate (default 30 000 rpm/s, i.e. dLambda/dtau = 7.9e-5 for the nominal bearing).
        speed_range_rpm: allowed rotor speeds (the commanded speed is clipped into it).
        damping_range: ``(D_min, D_max)`` of the foil damping D_W; action[1] maps log-linearly onto it.
        n_pressure_probes: midplane pressure probes equally spaced in phi from phi = 0.
        observation_noise: standard deviation of additive Gaussian sensor noise on the measured
            observations (rotor, envelope, pressures; in their observation units), 0 = none.
        touchdown_film_thickness: min film thickness H (units of C) that counts as touchdown.
        stable_amplitude: whirl amplitude (units of C) below which a control step counts as stable.
        hold_steps: consecutive stable control steps that make a success.
        disturbance_probability: chance per control step of a random disturbance kick.
        disturbance_magnitude: journal velocity impulse of a kick (units of C/T, random direction).
        speed_scale_rpm: observation scale of the rotor speed (obs = rpm / speed_scale_rpm).
        integrator_options: extra keyword arguments of :class:`TrapezoidalIntegrator` (rtol, atol, ...).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}

    def __init__(
        self,
        grid: str | Grid = DEFAULT_GRID,
        control_interval: float = 60.0,
        max_acceleration_rpm_per_s: float = 30_000.0,
        speed_range_rpm: tuple[float, float] = (12_000.0, 60_000.0),
        damping_range: tuple[float, float] = (0.1, 10.0),
        n_pressure_probes: int = 8,
        observation_noise: float = 0.0,
        touchdown_film_thickness: float = 0.02,
        stable_amplitude: float = 0.05,
        hold_steps: int = 10,
        disturbance_probability: float = 0.1,
        disturbance_magnitude: float = 0.005,
        speed_scale_rpm: float = 60_000.0,
        nominal_bearing: BearingParameters | None = None,
        integrator_options: dict | None = None,
        render_mode: str | None = None,
    ):
        super().__init__()
        self.grid = _parse_grid(grid)
        _check_positive("control_interval", control_interval)
        _check_positive("max_acceleration_rpm_per_s", max_acceleration_rpm_per_s)
        _check_positive("speed_scale_rpm", speed_scale_rpm)
        lo, hi = _check_range("speed_range_rpm", speed_range_rpm)
        if lo <= 0:
            raise ValueError(f"speed_range_rpm must be positive, got {speed_range_rpm!r}")
        dmin, dmax = _check_range("damping_range", damping_range)
        if dmin <= 0:
            raise ValueError(f"damping_range must be positive, got {damping_range!r}")
        if isinstance(n_pressure_probes, bool) or int(n_pressure_probes) != n_pressure_probes:
            raise ValueError(f"n_pressure_probes must be an integer, got {n_pressure_probes!r}")
        if not 1 <= n_pressure_probes <= self.grid.n_columns:
            raise ValueError(
                f"n_pressure_probes must lie in [1, {self.grid.n_columns}], got {n_pressure_probes}"
            )
        _check_nonnegative("observation_noise", observation_noise)
        if not (math.isfinite(touchdown_film_thickness) and 0 <= touchdown_film_thickness < 1):
            raise ValueError(f"touchdown_film_thickness must lie in [0, 1), got {touchdown_film_thickness!r}")
        _check_positive("stable_amplitude", stable_amplitude)
        if isinstance(hold_steps, bool) or int(hold_steps) != hold_steps or hold_steps < 1:
            raise ValueError(f"hold_steps must be a positive integer, got {hold_steps!r}")
        if not (math.isfinite(disturbance_probability) and 0 <= disturbance_probability <= 1):
            raise ValueError(f"disturbance_probability must lie in [0, 1], got {disturbance_probability!r}")
        _check_nonnegative("disturbance_magnitude", disturbance_magnitude)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )

        self.control_interval = float(control_interval)
        self.max_acceleration_rpm_per_s = float(max_acceleration_rpm_per_s)
        self.speed_range_rpm = (lo, hi)
        self.damping_range = (dmin, dmax)
        self.n_pressure_probes = int(n_pressure_probes)
        self.observation_noise = float(observation_noise)
        self.touchdown_film_thickness = float(touchdown_film_thickness)
        self.stable_amplitude = float(stable_amplitude)
        self.hold_steps = int(hold_steps)
        self.disturbance_probability = float(disturbance_probability)
        self.disturbance_magnitude = float(disturbance_magnitude)
        self.speed_scale_rpm = float(speed_scale_rpm)
        self.nominal_bearing = nominal_bearing if nominal_bearing is not None else NOMINAL_BEARING
        self.integrator_options = dict(integrator_options or {})
        self.render_mode = render_mode
        # record the trajectory ~120 times per control step (>= 30 samples per whirl period)
        self.record_interval = self.control_interval / 120.0

        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        n = N_ROTOR_OBS + self.n_pressure_probes
        low = np.empty(n, dtype=np.float32)
        high = np.empty(n, dtype=np.float32)
        low[[OBS_XI, OBS_ETA]], high[[OBS_XI, OBS_ETA]] = -POSITION_BOUND, POSITION_BOUND
        low[[OBS_XI_DOT, OBS_ETA_DOT]], high[[OBS_XI_DOT, OBS_ETA_DOT]] = -VELOCITY_BOUND, VELOCITY_BOUND
        low[[OBS_XI_EXTENT, OBS_ETA_EXTENT]], high[[OBS_XI_EXTENT, OBS_ETA_EXTENT]] = 0.0, EXTENT_BOUND
        low[OBS_SPEED], high[OBS_SPEED] = 0.0, max(1.0, hi / self.speed_scale_rpm)
        low[OBS_DAMPING], high[OBS_DAMPING] = -1.0, 1.0
        low[N_ROTOR_OBS:], high[N_ROTOR_OBS:] = 0.0, PRESSURE_BOUND
        self._extra_obs_bounds = self._extra_observation_bounds()
        if self._extra_obs_bounds is not None:
            low = np.concatenate([low, self._extra_obs_bounds[0]]).astype(np.float32)
            high = np.concatenate([high, self._extra_obs_bounds[1]]).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

        self._model: GFBModel | None = None
        self._integ: TrapezoidalIntegrator | None = None
        self._ep: dict = {}
        self._fig = None

    # ------------------------------------------------------------------------------------------
    # task hooks
    def _setup_episode(self, options: dict | None) -> EpisodeSetup:  # pragma: no cover - abstract
        raise NotImplementedError

    def _task_reward(self, out: StepOutcome, success: bool) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def _is_at_target(self, out: StepOutcome) -> bool:
        """Whether the speed counts for a success (default: any speed)."""
        return True

    def _extra_observation_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounds of task-specific observations appended after the probes (None: none)."""
        return None

    def _extra_observation(self) -> np.ndarray | None:
        return None

    # ------------------------------------------------------------------------------------------
    # conversions
    @property
    def model(self) -> GFBModel:
        """The plant of the current episode."""
        if self._model is None:
            raise RuntimeError("call reset() first")
        return self._model

    @property
    def bearing(self) -> BearingParameters:
        """Dimensional parameters of the current episode's bearing."""
        return self._ep["bearing"]

    def damping_from_action(self, a: float) -> float:
        """``D_W = D_min (D_max / D_min)^((a + 1) / 2)`` for ``a in [-1, 1]``."""
        dmin, dmax = self.damping_range
        return float(dmin * (dmax / dmin) ** ((a + 1.0) / 2.0))

    def action_from_damping(self, d: float) -> float:
        """Inverse of :meth:`damping_from_action` (clipped to [-1, 1])."""
        dmin, dmax = self.damping_range
        return float(np.clip(2.0 * math.log(d / dmin) / math.log(dmax / dmin) - 1.0, -1.0, 1.0))

    def max_rate(self, bearing: BearingParameters | None = None) -> float:
        """Motor limit as ``dLambda/dtau`` of ``bearing`` (default: the episode's)."""
        b = bearing if bearing is not None else self.bearing
        return self.max_acceleration_rpm_per_s / b.rate_rpm_per_s(1.0)

    def bearing_number_limits(self, bearing: BearingParameters | None = None) -> tuple[float, float]:
        b = bearing if bearing is not None else self.bearing
        return b.bearing_number_at(self.speed_range_rpm[0]), b.bearing_number_at(self.speed_range_rpm[1])

    # ------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        setup = self._setup_episode(options)
        self._model = setup.model
        opts = {"touchdown_film_thickness": self.touchdown_film_thickness, **self.integrator_options}
        self._integ = TrapezoidalIntegrator(
            setup.model, setup.state, setup.bearing_number, setup.foil_damping, **opts
        )
        self._probe_idx = setup.model.layout.midplane_probe_indices(self.n_pressure_probes)
        b = setup.bearing
        self._ep = {
            "bearing": b,
            "task": dict(setup.info),
            "step": 0,
            "hold": 0,
            "done": False,
            "termination_reason": None,
            "xi_range": (float("nan"), float("nan")),
            "eta_range": (float("nan"), float("nan")),
            "whirl_amplitude": 0.0,
            "min_film_thickness": setup.model.min_film_thickness(setup.state),
            "orbit": (
                np.array([setup.model.layout.rotor(setup.state)[0]]),
                np.array([setup.model.layout.rotor(setup.state)[1]]),
            ),
            "history": {
                "tau": [self._integ.tau],
                "lam": [setup.bearing_number],
                "dw": [setup.foil_damping],
                "amp": [0.0],
            },
            "last_action": np.zeros(2),
            "action_sanitised": False,
            "kick": False,
            "episode_return": 0.0,
        }
        self._pos_scale = b.clearance_m / self.nominal_bearing.clearance_m
        self._vel_scale = self._pos_scale * self.nominal_bearing.time_scale_s / b.time_scale_s
        obs = self._observation()
        info = self._info()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict]:
        if self._integ is None:
            raise RuntimeError("call reset() before step()")
        if self._ep["done"]:
            raise RuntimeError("the episode has ended; call reset()")
        a, sanitised = self._sanitise(action)
        ep, integ, model = self._ep, self._integ, self._model
        b = ep["bearing"]
        lam0 = integ.bearing_number
        lam_lo, lam_hi = self.bearing_number_limits(b)
        lam1 = float(np.clip(lam0 + a[0] * self.max_rate(b) * self.control_interval, lam_lo, lam_hi))
        dw1 = self.damping_from_action(a[1])
        kick = self._maybe_kick()
        t_end = integ.tau + self.control_interval
        touchdown = failure = False
        try:
            res = integ.advance(
                t_end,
                lam1,
                dw1,
                record_interval=self.record_interval,
                record_indices=self._probe_idx,
                raise_on_failure=False,
            )
            touchdown = res.status == "touchdown"
            failure = res.status in ("failed", "max_steps")
            tr = res.trajectory
            amp = _whirl_amplitude(tr.tau, tr.xi, tr.eta)
            min_h = float(res.min_film_thickness)
            xr, er = res.xi_range, res.eta_range
            orbit = (tr.xi, tr.eta)
        except (IntegrationError, ValueError, FloatingPointError, ZeroDivisionError, np.linalg.LinAlgError):
            failure = True
            amp, min_h = float("nan"), float("nan")
            xr = er = (float("nan"), float("nan"))
            orbit = ep["orbit"]
        if not math.isfinite(amp):
            amp = 0.5 * max(_span(xr), _span(er)) if math.isfinite(_span(xr) + _span(er)) else 0.0
        if not math.isfinite(min_h):
            min_h = model.min_film_thickness(integ.state)
        out = StepOutcome(lam0, integ.bearing_number, integ.foil_damping, amp, min_h, touchdown, failure)
        stable = (not touchdown) and (not failure) and amp <= self.stable_amplitude
        ep["hold"] = ep["hold"] + 1 if (stable and self._is_at_target(out)) else 0
        success = ep["hold"] >= self.hold_steps
        reward = float(self._task_reward(out, success))
        ep["step"] += 1
        ep["xi_range"], ep["eta_range"] = xr, er
        ep["whirl_amplitude"], ep["min_film_thickness"] = amp, min_h
        ep["orbit"] = orbit
        h = ep["history"]
        h["tau"].append(integ.tau)
        h["lam"].append(integ.bearing_number)
        h["dw"].append(integ.foil_damping)
        h["amp"].append(amp)
        ep["last_action"], ep["action_sanitised"], ep["kick"] = a, sanitised, kick
        ep["episode_return"] += reward
        reason = None
        if failure:
            reason = "solver_failure"
        elif touchdown:
            reason = "touchdown"
        elif success:
            reason = "success"
        terminated = reason is not None
        ep["done"] = terminated
        ep["termination_reason"] = reason
        obs = self._observation()
        info = self._info()
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, False, info

    # ------------------------------------------------------------------------------------------
    def _sanitise(self, action: Any) -> tuple[np.ndarray, bool]:
        """nan -> 0, +-inf and out-of-range -> clipped to [-1, 1]; reports whether anything changed."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,):
            raise ValueError(f"action must have shape (2,), got {np.shape(action)}")
        clean = np.clip(np.nan_to_num(a, nan=0.0, posinf=1.0, neginf=-1.0), -1.0, 1.0)
        return clean, bool(np.any(clean != a) or np.any(np.isnan(a)))

    def _maybe_kick(self) -> bool:
        """Random disturbance: a journal velocity impulse (drawn from ``self.np_random``)."""
        if self.disturbance_probability <= 0 or self.disturbance_magnitude <= 0:
            return False
        u, angle = self.np_random.random(), self.np_random.uniform(0.0, 2.0 * math.pi)
        if u >= self.disturbance_probability:
            return False
        integ, L = self._integ, self._model.layout
        s = integ.state
        xi, eta, xi_dot, eta_dot = L.rotor(s)
        dv = self.disturbance_magnitude / self._vel_scale_or_one()
        s = L.with_rotor(s, xi, eta, xi_dot + dv * math.cos(angle), eta_dot + dv * math.sin(angle))
        # a discontinuity: restart the step history (deterministic, like any reset)
        integ.reset(s, integ.bearing_number, integ.foil_damping, integ.tau)
        return True

    def _vel_scale_or_one(self) -> float:
        return getattr(self, "_vel_scale", 1.0)

    def _observation(self) -> np.ndarray:
        ep, integ, L = self._ep, self._integ, self._model.layout
        s = integ.state
        xi, eta, xi_dot, eta_dot = L.rotor(s)
        n = N_ROTOR_OBS + self.n_pressure_probes
        obs = np.zeros(n, dtype=np.float64)
        obs[OBS_XI], obs[OBS_ETA] = xi * self._pos_scale, eta * self._pos_scale
        obs[OBS_XI_DOT], obs[OBS_ETA_DOT] = xi_dot * self._vel_scale, eta_dot * self._vel_scale
        obs[OBS_XI_EXTENT] = _span(ep["xi_range"]) * self._pos_scale
        obs[OBS_ETA_EXTENT] = _span(ep["eta_range"]) * self._pos_scale
        obs[N_ROTOR_OBS:] = s[self._probe_idx]
        if self.observation_noise > 0:
            measured = np.r_[0:OBS_SPEED, N_ROTOR_OBS:n]
            obs[measured] += self.observation_noise * self.np_random.standard_normal(len(measured))
        obs[OBS_SPEED] = ep["bearing"].speed_rpm_at(integ.bearing_number) / self.speed_scale_rpm
        obs[OBS_DAMPING] = self.action_from_damping(integ.foil_damping)
        extra = self._extra_observation()
        if extra is not None:
            obs = np.concatenate([obs, extra])
        obs = np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(obs, self.observation_space.low, self.observation_space.high).astype(np.float32)

    def _info(self) -> dict:
        ep, integ, model = self._ep, self._integ, self._model
        b = ep["bearing"]
        s = integ.state
        xi, eta, xi_dot, eta_dot = model.layout.rotor(s)
        force = model.bearing_force(s)
        lam = integ.bearing_number
        info = {
            "step": ep["step"],
            "tau": integ.tau,
            "time_s": b.seconds(integ.tau),
            "bearing_number": lam,
            "foil_damping": integ.foil_damping,
            "speed_rpm": b.speed_rpm_at(lam),
            "xi_um": b.micrometres(xi),
            "eta_um": b.micrometres(eta),
            "xi_dot_m_s": b.micrometres(xi_dot) * 1e-6 / b.time_scale_s,
            "eta_dot_m_s": b.micrometres(eta_dot) * 1e-6 / b.time_scale_s,
            "eccentricity": model.eccentricity(s),
            "eccentricity_um": b.micrometres(model.eccentricity(s)),
            "min_film_thickness": ep["min_film_thickness"],
            "min_film_thickness_um": b.micrometres(ep["min_film_thickness"]),
            "whirl_amplitude": ep["whirl_amplitude"],
            "whirl_amplitude_um": b.micrometres(ep["whirl_amplitude"]),
            "bearing_force_n": (b.newtons(float(force[0])), b.newtons(float(force[1]))),
            "hold_steps": ep["hold"],
            "action_applied": ep["last_action"].copy(),
            "action_sanitised": ep["action_sanitised"],
            "disturbance": ep["kick"],
            "termination_reason": ep["termination_reason"],
            "is_success": ep["termination_reason"] == "success",
            "integrator_steps": int(integ.stats[0]),
        }
        info.update(ep["task"])
        return info

    # ------------------------------------------------------------------------------------------
    # snapshots
    def get_state(self) -> dict:
        """Exact snapshot of the episode: integrator, env bookkeeping and the ``np_random`` state."""
        if self._integ is None:
            raise RuntimeError("call reset() first")
        return {
            "integrator": self._integ.get_state(),
            "model": self._model,
            "episode": copy.deepcopy(self._ep),
            "scales": (self._pos_scale, self._vel_scale),
            "np_random": copy.deepcopy(self.np_random.bit_generator.state),
            "task": copy.deepcopy(self._task_state()),
        }

    def set_state(self, snapshot: dict) -> None:
        """Restore a snapshot from :meth:`get_state`; the continuation is bit-for-bit identical."""
        model = snapshot["model"]
        if self._model is not model:
            opts = {"touchdown_film_thickness": self.touchdown_film_thickness, **self.integrator_options}
            snap = snapshot["integrator"]
            self._model = model
            self._integ = TrapezoidalIntegrator(model, snap["s"], snap["lam"], snap["dw"], **opts)
            self._probe_idx = model.layout.midplane_probe_indices(self.n_pressure_probes)
        self._integ.set_state(copy.deepcopy(snapshot["integrator"]))
        self._ep = copy.deepcopy(snapshot["episode"])
        self._pos_scale, self._vel_scale = snapshot["scales"]
        self.np_random.bit_generator.state = copy.deepcopy(snapshot["np_random"])
        self._set_task_state(copy.deepcopy(snapshot["task"]))

    def _task_state(self) -> dict:
        return {}

    def _set_task_state(self, state: dict) -> None:
        pass

    # ------------------------------------------------------------------------------------------
    # rendering
    def render(self) -> np.ndarray | None:
        """``"rgb_array"``: an (H, W, 3) uint8 image; ``"human"``: draw into a matplotlib window."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._integ is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            if self._fig is None:
                self._fig = Figure(figsize=(9.6, 3.2), dpi=80)
                FigureCanvasAgg(self._fig)
            self._draw(self._fig)
            self._fig.canvas.draw()
            return np.asarray(self._fig.canvas.buffer_rgba())[..., :3].copy()
        import matplotlib.pyplot as plt

        if self._fig is None:
            plt.ion()
            self._fig = plt.figure(figsize=(9.6, 3.2), dpi=80)
        self._draw(self._fig)
        self._fig.canvas.draw_idle()
        plt.pause(1.0 / self.metadata["render_fps"])
        return None

    def _draw(self, fig) -> None:
        ep, integ, model = self._ep, self._integ, self._model
        b = ep["bearing"]
        fig.clf()
        ax1, ax2, ax3 = fig.add_subplot(1, 3, 1), fig.add_subplot(1, 3, 2), fig.add_subplot(1, 3, 3)
        th = np.linspace(0, 2 * np.pi, 200)
        ax1.plot(np.cos(th), np.sin(th), "k-", lw=1)
        ax1.plot(ep["orbit"][0], ep["orbit"][1], "r-", lw=0.8)
        xi, eta = model.layout.rotor(integ.state)[:2]
        ax1.plot([xi], [eta], "ko", ms=4)
        lim = max(1.2, float(np.nanmax(np.abs(np.r_[ep["orbit"][0], ep["orbit"][1], 1.0]))) * 1.1)
        ax1.set(
            xlim=(-lim, lim),
            ylim=(lim, -lim),
            aspect="equal",
            xlabel="xi (C)",
            ylabel="eta (C, down)",
            title=f"orbit, H_min={ep['min_film_thickness']:.3f}",
        )
        P = model.pressure_field(integ.state)[:, model.grid.n_z // 2]
        phi = np.r_[model.grid.phi, 2 * np.pi]
        ax2.plot(np.degrees(phi), np.r_[P, P[0]], "g-")
        ax2.axhline(1.0, color="k", lw=0.5)
        ax2.set(
            xlabel="phi (deg)",
            ylabel="P (midplane)",
            title=f"tau={integ.tau:.0f} ({b.seconds(integ.tau):.3f} s)",
        )
        h = ep["history"]
        t = np.array([b.seconds(x) for x in h["tau"]])
        ax3.plot(t, [b.speed_rpm_at(x) / 1000 for x in h["lam"]], "b-", label="speed (krpm)")
        ax3.set(xlabel="t (s)", ylabel="speed (krpm)", title=ep["termination_reason"] or "")
        target = ep["task"].get("target_speed_rpm")
        if target:
            ax3.axhline(target / 1000, color="b", ls=":", lw=0.8)
        ax4 = ax3.twinx()
        ax4.semilogy(t, h["dw"], "m-", label="D_W")
        ax4.set_ylim(*self.damping_range)
        ax4.set_ylabel("D_W", color="m")
        fig.tight_layout()

    def close(self) -> None:
        if self._fig is not None and self.render_mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
        super().close()


# ----------------------------------------------------------------------------------------------
def _span(r: tuple[float, float]) -> float:
    v = float(r[1]) - float(r[0])
    return v if math.isfinite(v) and v >= 0 else 0.0


def _whirl_amplitude(tau: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> float:
    """Largest distance of the journal from its linear trend over the control interval (units of C).

    The trend is the slow drift of the equilibrium while the speed ramps; what is left is the
    vibration (the whirl).  NaN if fewer than 3 samples."""
    if len(tau) < 3:
        return float("nan")
    t = tau - tau.mean()
    denom = float(t @ t)
    if denom <= 0:
        return float("nan")
    xd = xi - xi.mean() - t * (float(t @ xi) / denom)
    ed = eta - eta.mean() - t * (float(t @ eta) / denom)
    return float(np.sqrt(xd * xd + ed * ed).max())


def _parse_grid(grid: str | Grid) -> Grid:
    if isinstance(grid, Grid):
        return grid
    if isinstance(grid, str):
        return Grid.parse(grid)
    raise ValueError(f"grid must be a string like '31x7' or a Grid, got {grid!r}")


def _check_positive(name: str, v: float) -> None:
    if (
        isinstance(v, bool)
        or not isinstance(v, (int, float, np.floating, np.integer))
        or not (math.isfinite(v) and v > 0)
    ):
        raise ValueError(f"{name} must be a finite positive number, got {v!r}")


def _check_nonnegative(name: str, v: float) -> None:
    if (
        isinstance(v, bool)
        or not isinstance(v, (int, float, np.floating, np.integer))
        or not (math.isfinite(v) and v >= 0)
    ):
        raise ValueError(f"{name} must be a finite non-negative number, got {v!r}")


def _check_range(name: str, r: tuple[float, float]) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in r)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high), got {r!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"{name} must be a finite pair with low < high, got {r!r}")
    return lo, hi


def viscoelastic_model(
    grid: Grid, bearing: BearingParameters, foil_stiffness: float | None = None
) -> GFBModel:
    """The viscoelastic plant (D_W is an action, so the foil is always viscoelastic)."""
    return GFBModel(Structure.VISCOELASTIC, grid, bearing=bearing, foil_stiffness=foil_stiffness)
