"""The machine inside the envs: the ideal defaults are the arithmetic from before gfb_env.machine, bit for
bit over long runs; a realistic machine is deterministic, snapshots restore it exactly, and each component
acts where it should."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from gfb_env.envs import ENV_IDS, RunUpEnv, RunUpRandomizedEnv, WhirlRecoveryEnv
from gfb_env.envs.units import N_ROTOR_OBS, OBS_DAMPING, OBS_ETA, OBS_XI
from gfb_env.machine import FoilDampingActuator, PressureTaps, ProximityProbes

FAST = {"control_interval": 20.0}
REALISTIC = {
    "damping_actuator": FoilDampingActuator(gain_range=(0.5, 2.0)),
    "proximity_probes": ProximityProbes(),
    "pressure_taps": PressureTaps(),
}


class _V0Machine:
    """The command, verbatim from before gfb_env.machine (v0's): the reference code path."""

    def _command(self, a):
        b = self._ep.bearing
        lam0 = self._integ.bearing_number
        lam_lo, lam_hi = self.bearing_number_limits(b)
        lam1 = float(np.clip(lam0 + a[0] * self.max_rate(b) * self.control_interval, lam_lo, lam_hi))
        return lam1, self.actions.damping_from_action(a[1])


_CLASSES = (RunUpEnv, RunUpRandomizedEnv, WhirlRecoveryEnv)


def _episode(env, seed: int, policy: str, steps: int = 40) -> list:
    """An episode of ``steps`` control steps (or to termination): observations, rewards, ends, the
    plant's Lambda and D_W."""
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


@pytest.mark.parametrize("cls", _CLASSES)
@pytest.mark.parametrize(
    "kwargs", [{}, {"observation_noise": 0.01, "disturbance_probability": 0.5}], ids=["plain", "noisy"]
)
def test_ideal_machine_reproduces_the_pre_machine_arithmetic_bit_for_bit(cls, kwargs):
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
            runs.append(_episode(env, seed, policy))
        assert runs[1] == runs[0] and runs[2] == runs[0], (cls, seed, policy)


@pytest.mark.parametrize("cls", _CLASSES)
def test_realistic_machine_is_deterministic_and_snapshots_restore_it(cls):
    env = cls(disturbance_probability=0.5, **REALISTIC, **FAST)
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
    e2 = cls(disturbance_probability=0.5, **REALISTIC, **FAST)
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
    # the start is a damping command (the plant's D_W is g times it): both report the same command, the
    # gain shows only in the plant (its actual D_W twice the reference's)
    assert ref.episode.actuator.indicated_damping == pytest.approx(want / 2.0, rel=1e-12)
    assert obs_ref[OBS_DAMPING] == pytest.approx(obs[OBS_DAMPING], abs=1e-6)
    assert info["foil_damping"] == pytest.approx(2.0 * ref._integ.foil_damping, rel=1e-12)


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
    taps = slice(N_ROTOR_OBS, N_ROTOR_OBS + ideal.n_pressure_probes)  # the objective's entries follow
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
        assert np.allclose(o[1][taps] - o[0][taps], 0.01, atol=2e-6)  # 1.01325 kPa / p0
        dxi.append(o[2][OBS_XI] - out[2][4]["xi_um"] / 50.0)
        dp.append(o[2][taps] - noisy._integ.state[noisy._probe_idx])
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
    env = gym.make("gfb_env/WhirlRecovery-v2", max_episode_steps=6, **REALISTIC, **FAST)
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
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_machine_arguments_are_refused_by_name(env_id, kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make(env_id, **kwargs)
