"""Fast unit tests of the environments' parts: reward functions, configuration and option refusals,
the episode object, the action/observation units, and which failures a step survives."""

from __future__ import annotations

import copy
import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

from gfb_agents.policy import ControlSpec
from gfb_env.envs import ENV_IDS, RunUpEnv
from gfb_env.envs.config import CONTROL_INTERVAL_RANGE, EnvConfig
from gfb_env.envs.episode import StepOutcome, TerminationReason
from gfb_env.envs.rewards import WHIRL_AMPLITUDE_CAP, CommandedSpeedReward
from gfb_env.envs.units import OBS_DAMPING, OBS_SPEED, ActionMap, ObservationLayout
from gfb_env.integrator import IntegrationError, IntegratorOptions

FAST = {"control_interval": 20.0}


def _outcome(lam0=0.45, lam1=0.5, amp=0.1, touchdown=False, failure=False) -> StepOutcome:
    return StepOutcome(lam0, lam1, 1.0, amp, 0.5, touchdown, failure)


# ---- reward functions -------------------------------------------------------------------------
def test_commanded_speed_reward_terms():
    r = CommandedSpeedReward()
    assert r.progress(0.5, 0.4, 0.6) == pytest.approx(0.5) and r.progress(0.3, 0.4, 0.6) == 0.0
    assert r.progress(0.7, 0.4, 0.6) == 1.0
    t = r.terms(_outcome(amp=0.1), stable=True, progress=0.5, certified_progress=None)
    assert t["speed"] == pytest.approx(0.05) and t["whirl"] == pytest.approx(-0.05)
    assert t["certified_speed"] == 0.0 and t["on_target"] == 0.0 and t["touchdown"] == 0.0
    # no speed term while whirling; the whirl term saturates; the horizon's bonuses; the touchdown
    t = r.terms(_outcome(amp=3.0), stable=False, progress=1.0, certified_progress=0.8, on_target=True)
    assert t["speed"] == 0.0 and t["whirl"] == pytest.approx(-0.5 * WHIRL_AMPLITUDE_CAP)
    assert t["certified_speed"] == pytest.approx(40.0) and t["on_target"] == 25.0
    for td, fail in ((True, False), (False, True)):
        t = r.terms(_outcome(touchdown=td, failure=fail), False, 0.0, None)
        assert t["touchdown"] == -100.0


def test_reward_weights_are_validated():
    with pytest.raises(ValueError, match="speed_weight"):
        CommandedSpeedReward(speed_weight=-1.0)
    with pytest.raises(ValueError, match="success_bonus"):
        CommandedSpeedReward(success_bonus=math.nan)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reward_terms_in_info_sum_to_the_reward(env_id):
    env = gym.make(env_id, **FAST)
    _, info = env.reset(seed=0)
    assert not any(k.startswith("reward_") for k in info)  # no step yet
    for _ in range(3):
        _, r, term, trunc, info = env.step(env.action_space.sample())
        terms = {k: v for k, v in info.items() if k.startswith("reward_")}
        assert len(terms) == 5  # CommandedSpeedReward's
        assert sum(terms.values()) == pytest.approx(r, abs=1e-12)
        assert r == env.unwrapped.episode.reward


# ---- configuration and refusals ---------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"control_interval": 1e9}, "control_interval"),
        ({"control_interval": 0.0}, "control_interval"),
        ({"nominal_bearing": "x"}, "nominal_bearing"),
        ({"hold_steps": 2.5}, "hold_steps"),
        ({"n_pressure_probes": True}, "n_pressure_probes"),
        ({"speed_range_rpm": (5.0,)}, "speed_range_rpm"),
        ({"integrator_options": {"rtl": 1e-3}}, "rtl"),
        ({"integrator_options": {"rtol": -1.0}}, "rtol"),
        ({"integrator_options": {"touchdown_film_thickness": 0.05}}, "touchdown_film_thickness"),
        ({"integrator_options": "fast"}, "integrator_options"),
        ({"no_such_argument": 1}, "no_such_argument"),
    ],
)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_constructor_arguments_are_refused_by_name(env_id, kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make(env_id, **kwargs)


def test_observe_parameters_must_be_a_bool():
    with pytest.raises(ValueError, match="observe_parameters"):
        gym.make("gfb_env/RunUpRandomized-v2", observe_parameters="no")


def test_control_interval_range_is_documented_and_enforced():
    lo, hi = CONTROL_INTERVAL_RANGE
    assert EnvConfig(control_interval=lo).control_interval == lo
    assert EnvConfig(control_interval=hi).control_interval == hi
    with pytest.raises(ValueError, match=r"\[1, 1000\]"):
        EnvConfig(control_interval=hi * 1.01)


def test_integrator_options_reach_the_integrator_and_the_touchdown_threshold_is_the_envs():
    env = gym.make(
        "gfb_env/WhirlRecovery-v2", integrator_options={"rtol": 1e-3}, touchdown_film_thickness=0.05, **FAST
    ).unwrapped
    env.reset(seed=0)
    assert env._integ.options.rtol == 1e-3
    assert env._integ.options.touchdown_film_thickness == 0.05
    assert IntegratorOptions.from_mapping({"rtol": 1e-3}).atol == IntegratorOptions().atol


@pytest.mark.parametrize("env_id", ["gfb_env/RunUp-v2", "gfb_env/WhirlRecovery-v2"])
def test_tasks_without_options_refuse_any(env_id):
    env = gym.make(env_id, **FAST)
    with pytest.raises(ValueError, match="clearance_m"):
        env.reset(seed=0, options={"clearance_m": 50e-6})
    with pytest.raises(ValueError, match="options must be a dict"):
        env.reset(seed=0, options=[1, 2])


def test_randomized_reset_options_are_checked_and_fix_the_draw():
    env = gym.make("gfb_env/RunUpRandomized-v2", **FAST)
    with pytest.raises(ValueError, match="clearence_m"):  # a typo is not silently a random draw
        env.reset(seed=0, options={"clearence_m": 50e-6})
    with pytest.raises(ValueError, match="'load_n' must lie in"):
        env.reset(seed=0, options={"load_n": 1e6})
    with pytest.raises(ValueError, match="stiffness_factor"):
        env.reset(seed=0, options={"stiffness_factor": math.nan})
    env.reset(seed=0, options={"clearance_m": 50e-6, "stiffness_factor": 1.0, "load_n": 20.0})
    b = env.unwrapped.hidden_parameters()["bearing"]  # the draw is hidden: the privileged channel tells it
    assert b["clearance_um"] == pytest.approx(50.0) and b["load_n"] == 20.0
    assert b["stiffness_factor"] == 1.0


# ---- episode, snapshots, failures -------------------------------------------------------------
def test_integrator_steps_count_the_episode_across_kicks():
    env = RunUpEnv(disturbance_probability=1.0, **FAST)  # the velocity kick (the ideal machine's option)
    _, info = env.reset(seed=0)
    assert info["integrator_steps"] == 0
    counts = []
    for _ in range(4):
        _, _, _, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
        assert info["disturbance"]
        counts.append(info["integrator_steps"])
    assert all(b > a for a, b in zip(counts, counts[1:], strict=False)), counts


def test_episode_copy_shares_the_plant_and_copies_the_rest():
    env = gym.make("gfb_env/RunUp-v2", **FAST).unwrapped
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0], dtype=np.float32))
    ep = env.episode
    cp = copy.deepcopy(ep)
    assert cp.model is ep.model and cp.bearing is ep.bearing
    assert cp.history is not ep.history and cp.history.tau == ep.history.tau
    cp.history.append(1.0, 0.5, 1.0, 0.0)
    assert len(cp.history.tau) == len(ep.history.tau) + 1


def test_step_survives_numerical_failures_only(monkeypatch):
    env = gym.make("gfb_env/RunUp-v2", **FAST).unwrapped
    env.reset(seed=0)

    def fail(*a, **k):
        raise IntegrationError("step size fell below min_step")

    monkeypatch.setattr(env._integ, "prepare", fail)
    obs, r, term, trunc, info = env.step(np.zeros(2, dtype=np.float32))
    assert term and info["termination_reason"] is TerminationReason.SOLVER_FAILURE
    assert info["termination_reason"] == "solver_failure"
    assert np.all(np.isfinite(obs)) and math.isfinite(r) and info["reward_touchdown"] == -100.0

    env.reset(seed=0)

    def bug(*a, **k):
        raise TypeError("a programming error")

    monkeypatch.setattr(env._integ, "prepare", bug)
    with pytest.raises(TypeError, match="programming error"):
        env.step(np.zeros(2, dtype=np.float32))


# ---- units: one owner, used by envs and agents ------------------------------------------------
def test_action_map_round_trip_and_ends():
    m = ActionMap((0.1, 10.0), 30_000.0)
    assert m.damping_from_action(-1.0) == pytest.approx(0.1)
    assert m.damping_from_action(1.0) == pytest.approx(10.0)
    assert m.damping_from_action(0.0) == pytest.approx(1.0)
    for a in np.linspace(-1, 1, 9):
        assert m.action_from_damping(m.damping_from_action(a)) == pytest.approx(a, abs=1e-12)
    assert m.action_from_damping(100.0) == 1.0


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_agents_use_the_envs_units(env_id):
    env = gym.make(env_id, **FAST)
    u = env.unwrapped
    spec = ControlSpec.from_env(env)
    assert spec.actions is u.actions and spec.observations is u.observation_layout
    obs, _ = env.reset(seed=0)
    assert spec.observations.speed_rpm(obs) == pytest.approx(
        u.bearing.speed_rpm_at(u._integ.bearing_number), rel=1e-6
    )
    # the damping the actuator believes it sets (its effectiveness gain, 1 unless drawn, is hidden)
    indicated = np.clip(u._integ.foil_damping / u.episode.actuator.gain, *u.damping_range)
    assert u.damping_from_action(obs[OBS_DAMPING]) == pytest.approx(indicated, rel=1e-5)
    assert spec.rpm_per_step == pytest.approx(u.max_acceleration_rpm_per_s * u.nominal_bearing.seconds(20.0))
    assert obs.shape == (u.observation_layout.size,)


def test_observation_layout_bounds():
    lay = ObservationLayout(n_pressure_probes=4, speed_scale_rpm=60_000.0, max_speed_rpm=90_000.0)
    low, high = lay.bounds()
    assert low.shape == (12,) and high[OBS_SPEED] == pytest.approx(1.5)
    assert list(lay.measured_indices) == [0, 1, 2, 3, 4, 5, 8, 9, 10, 11]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_step_that_records_no_sample_does_not_crash_the_sensors(env_id, monkeypatch):
    """A touchdown in the first integrator step leaves the control step without samples: the noisy
    probes then read the current position (no crash, finite observation)."""
    env = gym.make(env_id, **FAST).unwrapped
    env.reset(seed=0)
    finish = env.finish_step

    def no_samples(plan, res):
        tr = res.trajectory
        empty = type(tr)(**{f: getattr(tr, f)[:0] for f in tr.__dataclass_fields__})
        return finish(plan, dataclasses.replace(res, trajectory=empty))

    monkeypatch.setattr(env, "finish_step", no_samples)
    obs, r, term, trunc, info = env.step(np.zeros(2, dtype=np.float32))
    assert np.all(np.isfinite(obs)) and math.isfinite(r)
