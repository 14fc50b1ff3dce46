"""The machine inside the envs: ideal defaults are v0 bit for bit over whole episodes; a realistic
machine is deterministic, snapshots restore it exactly, and each component acts where it should."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from gfb_env.envs import V0_IDS, RunUpEnv, RunUpRandomizedEnv, WhirlRecoveryEnv
from gfb_env.envs.units import N_ROTOR_OBS, OBS_DAMPING, OBS_ETA, OBS_XI
from gfb_env.machine import FoilDampingActuator, PressureTaps, ProximityProbes

FAST = {"control_interval": 20.0}
REALISTIC = {
    "damping_actuator": FoilDampingActuator(gain_range=(0.5, 2.0)),
    "proximity_probes": ProximityProbes(),
    "pressure_taps": PressureTaps(),
}


class _V0Machine:
    """v0's command and observation, verbatim (before gfb_env.machine): the reference code path."""

    def _command(self, a):
        b = self._ep.bearing
        lam0 = self._integ.bearing_number
        lam_lo, lam_hi = self.bearing_number_limits(b)
        lam1 = float(np.clip(lam0 + a[0] * self.max_rate(b) * self.control_interval, lam_lo, lam_hi))
        return lam1, self.actions.damping_from_action(a[1])

    def _observation(self):
        from gfb_env.envs.base import _span
        from gfb_env.envs.units import (
            OBS_DAMPING,
            OBS_ETA,
            OBS_ETA_DOT,
            OBS_ETA_EXTENT,
            OBS_SPEED,
            OBS_XI,
            OBS_XI_DOT,
            OBS_XI_EXTENT,
        )

        ep, s = self._ep, self._integ.state
        xi, eta, xi_dot, eta_dot = ep.model.layout.rotor(s)
        n = N_ROTOR_OBS + self.n_pressure_probes
        obs = np.zeros(n, dtype=np.float64)
        obs[OBS_XI], obs[OBS_ETA] = xi * ep.position_scale, eta * ep.position_scale
        obs[OBS_XI_DOT], obs[OBS_ETA_DOT] = xi_dot * ep.velocity_scale, eta_dot * ep.velocity_scale
        obs[OBS_XI_EXTENT] = _span(ep.xi_range) * ep.position_scale
        obs[OBS_ETA_EXTENT] = _span(ep.eta_range) * ep.position_scale
        obs[N_ROTOR_OBS:] = s[self._probe_idx]
        if self.observation_noise > 0:
            measured = self.observation_layout.measured_indices
            obs[measured] += self.observation_noise * self.np_random.standard_normal(len(measured))
        obs[OBS_SPEED] = ep.bearing.speed_rpm_at(self._integ.bearing_number) / self.speed_scale_rpm
        obs[OBS_DAMPING] = self.actions.action_from_damping(self._integ.foil_damping)
        extra = self._extra_observation()
        if extra is not None:
            obs = np.concatenate([obs, extra])
        obs = np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
        return np.clip(obs, self.observation_space.low, self.observation_space.high).astype(np.float32)


_CLASSES = {
    "gfb_env/RunUp-v0": RunUpEnv,
    "gfb_env/RunUpRandomized-v0": RunUpRandomizedEnv,
    "gfb_env/WhirlRecovery-v0": WhirlRecoveryEnv,
}


def _episode(env, seed: int, policy: str) -> list:
    """A whole episode (to termination or the registered step limit): observations, rewards, ends,
    the plant's Lambda and D_W."""
    steps = gym.spec(env.spec_id).max_episode_steps
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [obs.tobytes()]
    for _ in range(steps):
        a = rng.uniform(-1, 1, 2).astype(np.float32) if policy == "random" else env.scripted_action()
        obs, r, term, trunc, info = env.step(a)
        out += [obs.tobytes(), r, term, info["bearing_number"], info["foil_damping"], info["tau"]]
        if term:
            break
    return out


@pytest.mark.parametrize("env_id", V0_IDS)
@pytest.mark.parametrize(
    "kwargs", [{}, {"observation_noise": 0.01, "disturbance_probability": 0.5}], ids=["plain", "noisy"]
)
def test_ideal_machine_reproduces_v0_bit_for_bit_over_whole_episodes(env_id, kwargs):
    cls = _CLASSES[env_id]
    v0_cls = type(f"V0{cls.__name__}", (_V0Machine, cls), {})
    explicit = {
        "damping_actuator": FoilDampingActuator.ideal(),
        "proximity_probes": {"noise_um": 0.0, "bias_spread_um": 0.0},
        "pressure_taps": PressureTaps.ideal(),
    }
    for seed, policy in ((0, "random"), (1, "scripted")):
        runs = []
        for make, extra in ((v0_cls, {}), (cls, {}), (cls, explicit)):
            env = make(**kwargs, **extra)
            env.spec_id = env_id
            runs.append(_episode(env, seed, policy))
        assert runs[1] == runs[0] and runs[2] == runs[0], (env_id, seed, policy)


@pytest.mark.parametrize("env_id", V0_IDS)
def test_realistic_machine_is_deterministic_and_snapshots_restore_it(env_id):
    env = gym.make(env_id, disturbance_probability=0.5, **REALISTIC, **FAST).unwrapped
    env.reset(seed=2)
    env.step(np.array([1.0, 0.3], dtype=np.float32))
    snap = env.get_state()
    actions = [np.array([0.5, -0.2], dtype=np.float32), np.array([-1.0, 1.0], dtype=np.float32)]
    first = [env.step(a) for a in actions]
    gain, bias = env.episode.actuator.gain, env.episode.probe_bias_um.copy()
    env.reset(seed=99)  # another gain, other offsets
    assert env.episode.actuator.gain != gain and not np.array_equal(env.episode.probe_bias_um, bias)
    env.step(np.array([-1.0, -1.0], dtype=np.float32))
    env.set_state(snap)
    second = [env.step(a) for a in actions]
    for (o1, r1, t1, _, i1), (o2, r2, t2, _, i2) in zip(first, second, strict=True):
        assert o1.tobytes() == o2.tobytes() and r1 == r2 and t1 == t2
        assert i1["foil_damping"] == i2["foil_damping"] and i1["probe_x_um"] == i2["probe_x_um"]
    # a fresh env with the same seed gives the same episode
    e2 = gym.make(env_id, disturbance_probability=0.5, **REALISTIC, **FAST).unwrapped
    e2.reset(seed=2)
    e2.step(np.array([1.0, 0.3], dtype=np.float32))
    assert [e2.step(a)[0].tobytes() for a in actions] == [o.tobytes() for o, *_ in first]


def test_actuator_lag_and_hidden_gain_in_the_env():
    act = FoilDampingActuator(time_constant_ms=10.0, rate_limit_decades_per_s=math.inf, gain=2.0)
    env = RunUpEnv(damping_actuator=act, disturbance_probability=0.0)
    ref = RunUpEnv(
        disturbance_probability=0.0,
        damping_actuator={"gain": 1.0, "time_constant_ms": 10.0, "rate_limit_decades_per_s": math.inf},
    )
    _, info = env.reset(seed=0)
    ref.reset(seed=0)
    d0 = info["foil_damping"]
    assert info["damping_gain"] == 2.0
    obs, *_, info = env.step(np.array([0.0, 1.0], dtype=np.float32))  # command D_W = 10
    obs_ref, *_ = ref.step(np.array([0.0, 1.0], dtype=np.float32))
    dt = env.bearing.seconds(env.control_interval)
    want = math.exp(math.log(20.0) + (math.log(d0) - math.log(20.0)) * math.exp(-dt / 10e-3))
    assert info["foil_damping"] == pytest.approx(want, rel=1e-12)
    # the observation shows the indicated damping D_W / g, not the gain
    assert obs[OBS_DAMPING] == pytest.approx(env.action_from_damping(want / 2.0), abs=1e-6)
    assert env.episode.actuator.indicated_damping == pytest.approx(want / 2.0, rel=1e-14)
    assert obs_ref[OBS_DAMPING] != obs[OBS_DAMPING]  # the start D_W differs: the episodes differ


def test_sensors_add_their_errors_to_the_observation_only():
    kw = {"disturbance_probability": 0.0, **FAST}
    ideal = RunUpEnv(**kw)
    biased = RunUpEnv(
        proximity_probes=ProximityProbes(noise_um=0.0, bias_um=(3.0, -1.0), bias_spread_um=0.0),
        pressure_taps=PressureTaps(noise_kpa=0.0, bias_kpa=1.01325, bias_spread_kpa=0.0),
        **kw,
    )
    noisy = RunUpEnv(**REALISTIC, **kw)
    envs = (ideal, biased, noisy)
    for e in envs:
        e.reset(seed=4)
    a = np.array([1.0, 0.2], dtype=np.float32)
    dxi, dp = [], []
    for _ in range(30):
        out = [e.step(a) for e in envs]
        o = [x[0] for x in out]
        # the plant is the same: sensors do not touch it (noisy has another actuator gain: skip its D_W)
        assert out[0][4]["xi_um"] == out[1][4]["xi_um"]
        # a bias is a constant offset: (xi, eta) = inverse geometry of (3, -1) um, over C_nom = 50 um
        xi_b, eta_b = biased.proximity_probes.displacement_um(3.0, -1.0)
        assert o[1][OBS_XI] - o[0][OBS_XI] == pytest.approx(xi_b / 50.0, abs=2e-7)
        assert o[1][OBS_ETA] - o[0][OBS_ETA] == pytest.approx(eta_b / 50.0, abs=2e-7)
        assert np.allclose(o[1][N_ROTOR_OBS:] - o[0][N_ROTOR_OBS:], 0.01, atol=2e-6)  # 1.01325 kPa / p0
        dxi.append(o[2][OBS_XI] - out[2][4]["xi_um"] / 50.0)
        dp.append(o[2][N_ROTOR_OBS:] - noisy._integ.state[noisy._probe_idx])
    # realistic probes: per-episode offset (1 um spread) plus 0.3 um noise, in C_nom units
    dxi = np.array(dxi)
    assert 0 < np.std(dxi) < 5 * 0.3 / 50.0 and np.abs(dxi).max() < (5 * 1.0 + 5 * 0.3) / 50.0
    dp = np.array(dp)
    assert 0 < np.std(dp - dp.mean(axis=0)) < 5 * 0.35e3 / 101_325.0
    # info reports the probe readings: ideal probes read the true displacement toward each probe
    info = ideal._info()
    s2 = math.sqrt(0.5)
    assert info["probe_x_um"] == pytest.approx(s2 * (info["xi_um"] - info["eta_um"]), rel=1e-12)
    assert info["probe_y_um"] == pytest.approx(s2 * (-info["xi_um"] - info["eta_um"]), rel=1e-12)


def test_realistic_machine_survives_extreme_actions():
    env = gym.make("gfb_env/WhirlRecovery-v0", max_episode_steps=6, **REALISTIC, **FAST)
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        for a in ([np.nan, np.inf], [-1e30, 1e30], [1.0, -1.0], [0.0, 0.0]):
            obs, r, term, trunc, _ = env.step(np.array(a, dtype=np.float32))
            assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs) and math.isfinite(r)
            if term or trunc:
                break


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"damping_actuator": {"time_constant_ms": -1.0}}, "time_constant_ms"),
        ({"damping_actuator": "slow"}, "damping_actuator"),
        ({"proximity_probes": 3}, "proximity_probes"),
        ({"proximity_probes": {"noise_um": math.nan}}, "noise_um"),
        ({"pressure_taps": {"noise": 1.0}}, "pressure_taps"),
        ({"motor": {"max_acceleration_rpm_per_s": -5.0}}, "max_acceleration_rpm_per_s"),
    ],
)
@pytest.mark.parametrize("env_id", V0_IDS)
def test_bad_machine_arguments_are_refused_by_name(env_id, kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make(env_id, **kwargs)
