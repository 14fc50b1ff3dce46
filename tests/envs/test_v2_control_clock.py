"""The v2 control clock (issue 19): a control step of ``gfb_env/RunUpRandomized-v2`` is a fixed period in
seconds (60 tau of the nominal bearing, 9.54 ms), so no public quantity tells the hidden clearance C
through the step's duration.  With 60 tau of the *drawn* plant (T ~ 1 / C^2) a step lasted 6.4-13.8 ms
and the speed change per step at a known speed action, the raw probe samples' times and the step at
which the vibration monitor's record first held 3.5 revolutions all told C."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs import NOMINAL_BEARING, MonitorInterface

#: DEV seeds whose drawn clearances differ a lot (52.7 um and 41.7 um: T differs by a factor 1.6)
SEEDS = (0, 3)
#: 60 tau of the nominal bearing (the documented v2 step)
STEP_S = 60.0 * NOMINAL_BEARING.time_scale_s
DAMPING_STEPS, RAMP_STEPS = 3, 12
STEPS = DAMPING_STEPS + RAMP_STEPS


def _public_timing(seed: int) -> dict:
    """At the start speed, a damping step as far as the actuator's range allows (its rate limit is per
    second); then a ramp at the motor limit (a_speed = +1): the public speed (info and observation), the
    indicated damping, monitor_valid and the raw sample times of each step, and the drawn C."""
    env = gym.make("gfb_env/RunUpRandomized-v2", raw_probe_samples=True, privileged_info=True)
    obs, info = env.reset(seed=seed)
    layout = env.unwrapped.observation_layout
    away = -1.0 if obs[layout.damping] > 0 else 1.0  # the far end of the damping range
    actions = [(0.0, away)] * DAMPING_STEPS + [(1.0, away)] * RAMP_STEPS
    out = {
        "c_um": info["privileged"]["hidden_parameters"]["bearing"]["clearance_um"],
        "speed_rpm": [info["speed_rpm"]],
        "speed_obs": [float(obs[layout.speed])],
        "damping_obs": [float(obs[layout.damping])],
        "valid": [],
        "times": [],
        "angles": [],
        "time_s": [],
    }
    for a in actions:
        obs, _, terminated, truncated, info = env.step(np.array(a, dtype=np.float32))
        assert not (terminated or truncated)
        out["speed_rpm"].append(info["speed_rpm"])
        out["speed_obs"].append(float(obs[layout.speed]))
        out["damping_obs"].append(float(obs[layout.damping]))
        out["valid"].append(float(obs[layout.index("monitor_valid")]))
        out["times"].append(info["probe_samples"]["time_s"].copy())
        out["angles"].append(info["probe_samples"]["keyphasor_angle_rad"].copy())
        out["time_s"].append(info["privileged"]["time_s"])
    env.close()
    return {k: np.asarray(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def timings() -> tuple[dict, dict]:
    return _public_timing(SEEDS[0]), _public_timing(SEEDS[1])


def test_the_seeds_draw_very_different_clearances(timings):
    a, b = timings
    assert abs(a["c_um"] - b["c_um"]) > 8.0  # 52.7 and 41.7 um


def test_speed_change_per_step_does_not_depend_on_the_clearance(timings):
    a, b = timings
    ramp = slice(DAMPING_STEPS, None)
    np.testing.assert_allclose(np.diff(a["speed_rpm"])[ramp], np.diff(b["speed_rpm"])[ramp], rtol=1e-6)
    np.testing.assert_allclose(np.diff(a["speed_obs"])[ramp], np.diff(b["speed_obs"])[ramp], rtol=1e-6)
    # the motor's limit times the step's seconds (to float32's resolution of the speed entry)
    motor_rpm_per_s = gym.make("gfb_env/RunUpRandomized-v2").unwrapped.max_acceleration_rpm_per_s
    np.testing.assert_allclose(np.diff(a["speed_rpm"])[ramp], motor_rpm_per_s * STEP_S, atol=0.01)
    np.testing.assert_array_equal(np.diff(a["speed_rpm"])[:DAMPING_STEPS], 0.0)  # held


def test_the_actuators_rate_limited_move_per_step_does_not_depend_on_the_clearance(timings):
    a, b = timings
    # from different starts toward the far end of the range: rate-limited, so the move is the limit
    # times the step's seconds (the actuator's lag ran over the plant's 60 tau, which told C)
    moves_a = np.abs(np.diff(a["damping_obs"])[:DAMPING_STEPS])
    moves_b = np.abs(np.diff(b["damping_obs"])[:DAMPING_STEPS])
    np.testing.assert_allclose(moves_a, moves_b, rtol=1e-5)
    assert np.all(moves_a > 0.05)


def test_monitor_valid_turns_on_at_the_same_step(timings):
    a, b = timings
    np.testing.assert_array_equal(a["valid"], b["valid"])
    first = int(np.argmax(a["valid"] > 0.5))
    # 3.5 revolutions in 9.54 ms is 22 013 rpm: the start (20 600 rpm) is below, the ramp passes it
    assert a["valid"][first] == 1.0 and DAMPING_STEPS < first < STEPS - 1
    assert np.all(a["valid"][first:] == 1.0)


def test_raw_sample_times_do_not_depend_on_the_clearance(timings):
    a, b = timings
    # the same DAQ clock: 120 samples a step, STEP_S / 120 apart (float64 rounding of tau x T aside)
    np.testing.assert_allclose(a["times"], b["times"], rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(np.diff(a["times"], axis=1), STEP_S / 120.0, rtol=1e-9)
    np.testing.assert_allclose(a["times"][:, -1], STEP_S * np.arange(1, STEPS + 1), rtol=1e-12)
    # and the key's angles: the same speed profile in rpm over the same seconds
    np.testing.assert_allclose(a["angles"], b["angles"], rtol=1e-9, atol=1e-9)


def test_a_step_lasts_the_stated_seconds(timings):
    for t in timings:
        np.testing.assert_allclose(t["time_s"], STEP_S * np.arange(1, STEPS + 1), rtol=1e-12)
    assert STEP_S == pytest.approx(9.5413e-3, rel=1e-4)
    u = gym.make("gfb_env/RunUpRandomized-v2").unwrapped
    u.reset(seed=SEEDS[1])
    assert u.control_step_s == STEP_S
    # the plant's tau per step goes with its time scale instead
    assert u.step_tau == pytest.approx(60.0 * NOMINAL_BEARING.time_scale_s / u.bearing.time_scale_s)


def test_the_clocks_agree_on_the_nominal_bearing_bit_for_bit():
    from gfb_env.envs.config import ControlClock  # here: the timing tests above run on any version

    nb = NOMINAL_BEARING
    seconds, plant = ControlClock(60.0, nb), ControlClock(60.0)
    same = nb.replace(clearance_m=nb.clearance_m)
    for clock in (seconds, plant):
        assert clock.step_tau(same) == 60.0
        assert clock.step_s(same) == nb.seconds(60.0)
        assert clock.record_interval(same) == 60.0 / 120.0
        assert clock.record_interval_s(same) == nb.seconds(60.0 / 120.0)
    drawn = nb.replace(clearance_m=40e-6)
    assert plant.step_tau(drawn) == 60.0 and plant.step_s(drawn) == drawn.seconds(60.0)
    assert seconds.step_s(drawn) == nb.seconds(60.0)
    assert seconds.step_tau(drawn) == pytest.approx(60.0 * (40.0 / 50.0) ** 2, rel=1e-12)


def test_the_plant_clock_is_v1s_and_a_bad_clock_is_refused():
    env = gym.make("gfb_env/RunUpRandomized-v2", interface=MonitorInterface(control_clock="plant"))
    u = env.unwrapped
    u.reset(seed=SEEDS[1])
    assert u.step_tau == 60.0 and u.control_step_s == u.bearing.seconds(60.0)
    with pytest.raises(ValueError, match="control_clock"):
        MonitorInterface(control_clock="tau")
