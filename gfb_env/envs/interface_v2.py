"""The v2 information interface (issue 19 s.1-2; ``docs/envs.md``, "The v2 interface"): what an agent of
``gfb_env/RunUp-v2``, ``gfb_env/RunUpRandomized-v2`` and ``gfb_env/WhirlRecovery-v2`` receives.  A
component of the task env (``env.interface``, a :class:`MonitorInterface`; the v1 ids have none and keep
v1's observation, reward, costs and info, in :mod:`gfb_env.envs.base`).

**Observation.**  v1's entries under the same names, indices and meaning (``[xi, eta, xi', eta',
extent(xi), extent(eta), speed, damping, pressure_0..7]``), then the vibration monitor's entries of
:data:`MONITOR_ENTRIES`, then the task's extras, and ``speed_command``, ``time_left`` last.  Per control
step the probes' readings of every sample of the step are drawn once (geometry, the episode's bias and
white noise, as :meth:`~gfb_env.machine.ProximityProbes.measurement_errors` draws them), and everything
comes from that one draw: v1's position, velocity and envelope entries
(:meth:`~gfb_env.machine.ProximityProbes.errors_of_noise`), and the monitor's entries
(:meth:`~gfb_env.machine.VibrationMonitor.measure` of the step's samples with the once-per-revolution
key).  Lengths are divided by the nominal clearance in um, like the other rotor entries:

| index | name | value (lengths in um / C_nom um) | bounds |
|---|---|---|---|
| 16, 17 | ``x_direct_pp``, ``y_direct_pp`` | direct (unfiltered) pk-pk of probe X / Y, the step | [0, 6] |
| 18, 19 | ``x_1x_pp``, ``y_1x_pp`` | 1x (synchronous) amplitude, pk-pk | [0, 6] |
| 20-23 | ``x_1x_cos``, ``x_1x_sin``, ``y_1x_cos``, ``y_1x_sin`` | cos, sin of the 1x phase lag | [-1, 1] |
| 24, 25 | ``x_subsync_rms``, ``y_subsync_rms`` | rms of the 0.30-0.55x band | [0, 3] |
| 26 | ``subsync_ratio`` | dominant band frequency / running speed, probe of the larger level | [0, 1] |
| 27 | ``monitor_valid`` | 1 if the record held >= 3.5 revolutions (filtered values exist) | [0, 1] |

(indices with the default 8 pressure taps.)  Standards and practice: the direct pk-pk is the direct
radial shaft vibration API 670 protects, ``S_pp`` of ISO 7919-1 / ISO 20816-1; the 1x amplitude and
phase lag are the filtered 1x vector against a once-per-revolution keyphasor (API 670; the lag from the
key mark to the next positive peak, Bently Nevada's ``A cos(theta - lag)``), given as (cos, sin) so that
nothing wraps at 0/360; the band level and the dominant ratio are condition-monitoring practice (no
standard fixes the band); ``monitor_valid`` is a monitor's "not OK" flag below its minimum speed (0 and
every filtered entry 0 then, the phase's (cos, sin) (0, 0); the direct pk-pk is still given).
At reset there is no record yet: every monitor entry is 0 (``monitor_valid`` 0).  ``docs/machine.md``
("Vibration monitor") has the noise of each entry (a known function of the public probe model).

**Reward and costs**: :mod:`gfb_env.envs.monitor_reward` (from this observation and the public
configuration only; :func:`~gfb_env.envs.monitor_reward.recompute_rewards`).  **Certificate**:
:class:`~gfb_env.envs.certify_v2.AfterShockCertificate`.

**Info** (every key SENSOR, PUBLIC or, on the final step only, VERDICT in
:mod:`gfb_env.envs.contract`): ``step``, ``steps_left``, ``episode_steps``, ``speed_rpm``,
``speed_command_rpm``, ``reference_speed_rpm``, ``damping_indicated`` (the actuator's indicated D_W),
``probe_x_um``, ``probe_y_um`` (the last sample's readings), ``action_applied``, ``action_sanitised``,
``touchdown`` (a rub is audible: the episode ends), ``monitor_alarm`` (the direct pk-pk above the alarm
level in the step), ``monitor`` (the monitor's reading in um and degrees, a dict), after a step the
reward's terms ``reward_speed``, ``reward_whirl``, ``reward_certified_speed``, ``reward_on_target``,
``reward_touchdown``, the costs ``cost``, ``cost_alarm``, ``cost_touchdown``, ``episode_cost``; on the final
step the judge's verdict ``certified``, ``is_success``, ``termination_reason``.  With
``raw_probe_samples=True``: ``probe_samples`` (the step's measured samples: ``time_s``, ``x_um``,
``y_um``, ``keyphasor_angle_rad``; :data:`SAMPLES_PER_STEP` each, NaN after a step that ended early).
With ``privileged_info=True``: ``privileged`` (the ground truth; not for a benchmarked policy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from gfb_env.envs.certify_v2 import AfterShockCertificate
from gfb_env.envs.config import CONTROL_CLOCKS, check_positive
from gfb_env.envs.episode import TerminationReason
from gfb_env.envs.monitor_reward import (
    MonitorCosts,
    MonitorReward,
    PublicRewardConfig,
    step_costs,
    step_terms,
)
from gfb_env.envs.units import (
    EXTENT_BOUND,
)
from gfb_env.machine import VibrationMonitor
from gfb_env.machine._monitor_kernels import probe_step_kernel
from gfb_env.machine.monitor import MonitorReading, keyphasor_angles
from gfb_env.machine.probes import ProbeErrors

if TYPE_CHECKING:  # pragma: no cover
    from gfb_env.envs.base import GFBEnv

__all__ = ["MonitorInterface", "InterfaceEpisode", "MONITOR_ENTRIES", "SAMPLES_PER_STEP"]

#: the vibration monitor's observation entries, in order (after the pressure taps)
MONITOR_ENTRIES = (
    "x_direct_pp",
    "y_direct_pp",
    "x_1x_pp",
    "y_1x_pp",
    "x_1x_cos",
    "x_1x_sin",
    "y_1x_cos",
    "y_1x_sin",
    "x_subsync_rms",
    "y_subsync_rms",
    "subsync_ratio",
    "monitor_valid",
)
#: the bounds of :data:`MONITOR_ENTRIES` (pk-pk as the envelope's, rms half of it, cos/sin, ratio, flag)
_LOW = (0.0, 0.0, 0.0, 0.0, -1.0, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0)
_HIGH = (EXTENT_BOUND,) * 4 + (1.0,) * 4 + (0.5 * EXTENT_BOUND,) * 2 + (1.0, 1.0)
#: the monitor's entries after the direct pk-pk when the record is too short for the filters (0, the flag too)
_NOT_VALID = (0.0,) * (len(MONITOR_ENTRIES) - 2)
#: samples of one control step in ``info["probe_samples"]`` (the envs record 120 per step)
SAMPLES_PER_STEP = 120
#: the monitor's reading in ``info["monitor"]`` (per probe; the noise statistics and the revolutions are
#: left out: they tell the record's length in revolutions, and on a drawn bearing that is the clearance)
_READING_FIELDS = (
    "direct_um_pp",
    "synchronous_um_pp",
    "synchronous_phase_lag_deg",
    "subsynchronous_um_rms",
    "subsynchronous_ratio",
)
#: the keys of ``info["monitor"]`` per probe (x then y) and all of them in order
_READING_KEYS_BY_PROBE = tuple(tuple(f"{name}_{f}" for f in _READING_FIELDS) for name in ("x", "y"))
_READING_KEYS = _READING_KEYS_BY_PROBE[0] + _READING_KEYS_BY_PROBE[1]


@dataclass
class InterfaceEpisode:
    """The v2 interface's state of one episode (part of the snapshotted episode).

    Attributes:
        samples: the last step's measured samples ``(time_s, x_um, y_um, keyphasor_angle_rad)`` (None:
            no record, at reset or after a failed step).
        reading: the monitor's reading of them (None: none, or a record too short for the monitor).
        progresses: the speed progress p of the episode's last ``hold_steps`` steps (from the
            observations: the certified bonus averages it).
        reward_terms: the last reward's terms; costs: the last step's cost terms; episode_cost: their
            ``cost`` summed.
        truth_reward_terms: v1's reward terms of the true plant (the privileged channel only).
    """

    samples: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
    reading: MonitorReading | None = None
    progresses: list[float] = field(default_factory=list)
    reward_terms: dict = field(default_factory=dict)
    costs: dict = field(default_factory=lambda: {"cost": 0.0, "cost_alarm": 0.0, "cost_touchdown": 0.0})
    episode_cost: float = 0.0
    truth_reward_terms: dict = field(default_factory=dict)


@dataclass(frozen=True)
class MonitorInterface:
    """The v2 interface (module docstring): a component of the task env.

    Attributes:
        monitor: the vibration monitor (:class:`~gfb_env.machine.VibrationMonitor`, its defaults).
        alarm_direct_pp: the cost's alarm level of the direct pk-pk, units of C_nom (0.30).
        control_clock: what the env's ``control_interval`` counts (:data:`~gfb_env.envs.config.
            CONTROL_CLOCKS`): ``"seconds"`` (default) tau of the task's nominal bearing, so a control step
            is a fixed period, 60 tau = 9.54 ms, whatever bearing was drawn (a real controller's clock);
            ``"plant"``: tau of the episode's plant, v1's clock.  On a drawn bearing the plant's clock
            makes a step last ``60 T`` seconds with ``T ~ 1 / C^2``, so the speed change per step at a known
            speed action (the motor ramps in rpm/s), the probe samples' times and the speed at which the
            monitor's record first holds 3.5 revolutions all tell the hidden clearance.  With the nominal
            bearing (RunUp-v2, WhirlRecovery-v2) the two clocks are the same step, bit for bit.
    """

    monitor: VibrationMonitor = field(default_factory=VibrationMonitor)
    alarm_direct_pp: float = 0.30
    control_clock: str = "seconds"

    #: the interface's observation entries (they follow the pressure taps)
    observation_names: ClassVar[tuple[str, ...]] = MONITOR_ENTRIES

    def __post_init__(self) -> None:
        if not isinstance(self.monitor, VibrationMonitor):
            raise ValueError(f"monitor must be a VibrationMonitor, got {self.monitor!r}")
        object.__setattr__(self, "alarm_direct_pp", check_positive("alarm_direct_pp", self.alarm_direct_pp))
        if self.control_clock not in CONTROL_CLOCKS:
            raise ValueError(f"control_clock must be one of {CONTROL_CLOCKS}, got {self.control_clock!r}")

    def observation_bounds(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        return _LOW, _HIGH

    def certificate(self, stable_amplitude: float, hold_steps: int) -> AfterShockCertificate:
        """The judge's certificate of the v2 tasks."""
        return AfterShockCertificate(stable_amplitude, hold_steps)

    def new_episode(self) -> InterfaceEpisode:
        return InterfaceEpisode()

    def reward_config(self, env: GFBEnv) -> PublicRewardConfig:
        """The public configuration of ``env``'s reward and costs (the task's weights, its reference
        speed, the observation's indices)."""
        layout = env.observation_layout
        names = ("speed", "speed_command", *MONITOR_ENTRIES)
        return PublicRewardConfig(
            reward=MonitorReward.from_weights(env.objective.reward),
            costs=MonitorCosts(self.alarm_direct_pp, env.objective.costs.episode_cost_limit),
            reference_speed_rpm=float(env.reference_speed_rpm),
            speed_scale_rpm=env.speed_scale_rpm,
            stable_amplitude=env.stable_amplitude,
            hold_steps=env.hold_steps,
            indices={k: layout.index(k) for k in names},
        )

    # ---- sensors ------------------------------------------------------------------------------
    def read_probes(self, env: GFBEnv, obs: np.ndarray, xi: float, eta: float) -> None:
        """One draw of the probes' readings of every sample of the last step: v1's position, velocity
        and envelope errors into ``obs`` and the samples for the monitor (``ep.interface.samples``)."""
        ep, probes = env._ep, env.proximity_probes  # noqa: SLF001
        xs, taus = ep.orbit[0], ep.orbit_tau
        if probes.noise_um > 0.0 and taus is not None and len(xs) > 0:
            self._read_noisy_probes(env, obs, xi, eta)
        else:
            self._read_probes_numpy(env, obs, xi, eta)

    def _read_probes_numpy(self, env: GFBEnv, obs: np.ndarray, xi: float, eta: float) -> None:
        """:meth:`read_probes` in numpy: noise-free probes, a step without a record (and the reference
        of :meth:`_read_noisy_probes` in the tests)."""
        ep, probes = env._ep, env.proximity_probes  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        b = ep.bearing
        c_um = b.clearance_m * 1e6
        xs, es = ep.orbit
        taus = ep.orbit_tau
        if len(xs) == 0:  # a step that ended at once (touchdown in its first integrator step)
            xs, es, taus = np.array([xi]), np.array([eta]), None
        xs_um, es_um = np.asarray(xs) * c_um, np.asarray(es) * c_um
        n = len(xs_um)
        noise = probes.draw_noise(env.np_random, n)  # the draw of measurement_errors
        err = probes.errors_of_noise(noise, xs_um, es_um, env.record_interval_s, ep.probe_bias_um)
        env._apply_probe_errors(obs, err)  # noqa: SLF001
        x, y = probes.read_um(xi * c_um, eta * c_um, ep.probe_bias_um)
        if noise is not None:
            x, y = x + err.noise_um[0], y + err.noise_um[1]
        ep.probe_readings_um = np.array([x, y])
        ep.probe_errors = None if probes.is_ideal else err
        st.samples = None
        tau0, theta0, lam0 = ep.record_start
        if ep.step == 0 or taus is None or not math.isfinite(tau0):
            return
        keep = np.asarray(taus) > tau0 + 1e-9  # the step's own samples, (tau0, tau1]
        integ = env._integ  # noqa: SLF001
        if not np.any(keep) or not integ.tau > tau0:
            return
        sx, sy = probes.read_um(xs_um[keep], es_um[keep], ep.probe_bias_um)
        if noise is not None:
            tail = noise[len(noise) - n :][keep]
            sx, sy = sx + tail[:, 0], sy + tail[:, 1]
        tau = np.asarray(taus)[keep]
        theta = keyphasor_angles(tau, tau0, theta0, lam0, integ.tau, integ.bearing_number)
        st.samples = (b.seconds(tau), sx, sy, theta)

    def _read_noisy_probes(self, env: GFBEnv, obs: np.ndarray, xi: float, eta: float) -> None:
        """:meth:`read_probes` of noisy probes and a step with a record: the same draw and the same
        values (to rounding), its arithmetic in one compiled call (issue 20 s.3)."""
        ep, probes, integ = env._ep, env.proximity_probes, env._integ  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        b = ep.bearing
        xs, es = ep.orbit
        n = len(xs)
        noise = probes.draw_noise(env.np_random, n)  # the draw of measurement_errors
        tau0, theta0, lam0 = ep.record_start
        if ep.step == 0:
            tau0 = math.nan  # no keyphasor record at reset
        errors = np.empty((5, 2))
        samples = np.empty((4, n))
        ramp = np.array([tau0, theta0, lam0, integ.tau, integ.bearing_number])
        count = probe_step_kernel(
            np.asarray(xs, dtype=float), np.asarray(es, dtype=float), np.asarray(ep.orbit_tau, dtype=float),
            noise, b.clearance_m * 1e6, probes.directions, probes._inverse_directions,  # noqa: SLF001
            np.asarray(ep.probe_bias_um, dtype=float), b.seconds(env.record_interval), probes.velocity_window,
            np.array([xi, eta]), ramp, b.time_scale_s, errors, samples,
        )  # fmt: skip
        err = ProbeErrors(errors[0], errors[1], errors[2], errors[3])
        env._apply_probe_errors(obs, err)  # noqa: SLF001
        ep.probe_readings_um = errors[4]
        ep.probe_errors = None if probes.is_ideal else err
        st.samples = None if count == 0 else tuple(samples[:, :count])

    def observation(self, env: GFBEnv) -> np.ndarray:
        """The monitor's entries (:data:`MONITOR_ENTRIES`) of the last step's samples."""
        ep = env._ep  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        st.reading = None
        if st.samples is not None:
            try:
                st.reading = self.monitor.measure(*st.samples, noise_um=env.proximity_probes.noise_um)
            except ValueError:  # a record too short or odd for the monitor (a step that ended early)
                st.reading = None
        r = st.reading
        if r is None:
            return np.zeros(len(MONITOR_ENTRIES))
        # the entries as floats, converted in one call (in MONITOR_ENTRIES' order)
        cnom_um = env.nominal_bearing.clearance_m * 1e6
        px, py = r.x, r.y
        if not r.valid:
            return np.array((px.direct_um_pp / cnom_um, py.direct_um_pp / cnom_um, *_NOT_VALID), dtype=float)
        phase = []
        for p in (px, py):
            if p.synchronous_um_pp > 0:
                lag = math.radians(p.synchronous_phase_lag_deg)
                phase += (math.cos(lag), math.sin(lag))
            else:
                phase += (0.0, 0.0)
        dominant = px if px.subsynchronous_um_rms >= py.subsynchronous_um_rms else py
        return np.array(
            (
                px.direct_um_pp / cnom_um, py.direct_um_pp / cnom_um,
                px.synchronous_um_pp / cnom_um, py.synchronous_um_pp / cnom_um, *phase,
                px.subsynchronous_um_rms / cnom_um, py.subsynchronous_um_rms / cnom_um,
                dominant.subsynchronous_ratio, 1.0,
            ),
            dtype=float,
        )  # fmt: skip

    # ---- emit ---------------------------------------------------------------------------------
    def emit(self, env: GFBEnv) -> tuple[np.ndarray, dict]:
        """The observation, then the reward and costs of the step from it, and the info."""
        ep = env._ep  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        obs = env._finish_observation(env._raw_observation())  # noqa: SLF001
        verdict = None
        if ep.termination is not None:
            cert = ep.command.certificate
            verdict = {
                "certified": bool(cert is not None and cert.certified),
                "is_success": ep.termination is TerminationReason.SUCCESS,
                "termination_reason": ep.termination,
            }
        if ep.step > 0:
            config = env.public_reward_config
            terms = step_terms(obs, config, st.progresses, verdict)
            st.reward_terms = terms
            ep.reward = float(sum(terms.values()))
            ep.episode_return += ep.reward
            early = ep.termination in (TerminationReason.TOUCHDOWN, TerminationReason.SOLVER_FAILURE)
            st.costs = step_costs(obs, config, early)
            st.episode_cost += st.costs["cost"]
        return obs, self._info(env, verdict, obs)

    def _info(self, env: GFBEnv, verdict: dict | None, obs: np.ndarray) -> dict:
        ep = env._ep  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        ce = ep.command
        steps = env.objective.episode_steps
        layout = env.observation_layout
        probe_x, probe_y = ep.probe_readings_um.tolist()  # (float of each entry)
        info = {
            "step": ep.step,
            "steps_left": steps - ep.step,
            "episode_steps": steps,
            # the speed and the indicated damping as the observation carries them (float32): computed
            # in float64 from the plant (speed_rpm_at(Lambda), D_actual / g) their rounding told the
            # drawn clearance and the hidden gain (outside audit, 2026-12-02: the replay of the public
            # actuator matched every step for the true g only)
            "speed_rpm": float(obs[layout.speed]) * env.speed_scale_rpm,
            "speed_command_rpm": ce.command.speed_rpm,
            "reference_speed_rpm": float(env.reference_speed_rpm),
            # the actuator's position feedback: the damping it believes it sets (the gain is hidden)
            "damping_indicated": env.actions.damping_from_action(float(obs[layout.damping])),
            "probe_x_um": probe_x,
            "probe_y_um": probe_y,
            "action_applied": ep.last_action.copy(),
            "action_sanitised": ep.action_sanitised,
            "touchdown": ep.termination is TerminationReason.TOUCHDOWN,
            "monitor_alarm": st.costs["cost_alarm"] > 0,
            "monitor": self._reading_dict(st.reading),
        }
        info.update({f"reward_{k}": v for k, v in st.reward_terms.items()})
        info.update(st.costs)
        info["episode_cost"] = st.episode_cost
        if verdict is not None:
            info.update(verdict)
        if env.config.raw_probe_samples:
            info["probe_samples"] = self._samples_dict(st.samples)
        if env.config.privileged_info:  # opt-in only: nothing added, nothing computed, by default
            info["privileged"] = self._privileged(env)
        return info

    @staticmethod
    def _reading_dict(r: MonitorReading | None) -> dict[str, float]:
        if r is None:
            out = dict.fromkeys(_READING_KEYS, 0.0)
            out["valid"] = False
            return out
        valid = r.valid
        px, py = r.x.__dict__, r.y.__dict__
        if valid:  # every field of both probes, in _READING_KEYS' order
            out = dict(
                zip(_READING_KEYS, map(float, [*map(px.get, _READING_FIELDS), *map(py.get, _READING_FIELDS)]))
            )
        else:  # the direct pk-pk only (the filtered values are not OK)
            out = dict.fromkeys(_READING_KEYS, 0.0)
            for keys, p in zip(_READING_KEYS_BY_PROBE, (px, py), strict=True):
                out[keys[0]] = float(p["direct_um_pp"])
        out["valid"] = bool(valid)
        return out

    @staticmethod
    def _samples_dict(samples: tuple | None) -> dict[str, np.ndarray]:
        names = ("time_s", "x_um", "y_um", "keyphasor_angle_rad")
        out = {k: np.full(SAMPLES_PER_STEP, np.nan) for k in names}
        if samples is not None:
            for k, v in zip(names, samples, strict=True):
                m = min(len(v), SAMPLES_PER_STEP)
                out[k][:m] = v[len(v) - m :]
        return out

    @staticmethod
    def _privileged(env: GFBEnv) -> dict[str, Any]:
        """The ground truth of the step: v1's privileged quantities and hidden parameters, and the
        judge's true quantities (certificate, v1's reward terms and costs of the true plant, shocks)."""
        ep, integ = env._ep, env._integ  # noqa: SLF001
        st: InterfaceEpisode = ep.interface
        ce = ep.command
        cert = ce.certificate
        return {
            **env.privileged_quantities(),
            "hidden_parameters": env.hidden_parameters(),
            "tau": integ.tau,
            "time_s": ep.bearing.seconds(integ.tau),
            "integrator_steps": ep.integrator_steps,
            "shocks_in_step": len(ep.shocks),
            "shock_peak_g": max((e.peak_g for e in ep.shocks), default=0.0),
            "certified": bool(cert is not None and cert.certified),
            "certification": cert.reason if cert is not None else None,
            "growth_rate": cert.growth_rate
            if (cert is not None and math.isfinite(cert.growth_rate))
            else None,
            "true_reward_terms": dict(st.truth_reward_terms),
            "true_costs": dict(ce.costs),
            "true_episode_cost": ce.episode_cost,
            "speed_command_bearing_number": ce.command.bearing_number,
            "reference_bearing_number": ce.command.reference_bearing_number,
        }
