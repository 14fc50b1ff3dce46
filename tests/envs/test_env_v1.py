"""The v1 tasks: the instrumented machine (actuator, sensors, base shocks, residual unbalance) wired
into the environments; the classes alone keep the ideal machine.  The v1 ids are retired (issue 19; the
refusals: tests/envs/test_retired.py): their envs are built for the record by ``make_retired``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_env.envs import (
    MACHINE_V1,
    RETIRED_V1_IDS,
    RunUpEnv,
    RunUpRandomizedEnv,
    WhirlRecoveryEnv,
    make_retired,
)
from gfb_env.forcing import Unbalance
from gfb_env.machine import RotorBalance, ShockArrivals
from gfb_env.params import BearingParameters

FAST = {"control_interval": 20.0}
V1_IDS = RETIRED_V1_IDS


def test_rotor_balance_draws_an_iso_grade_and_a_phase():
    b = BearingParameters()
    rb = RotorBalance(grade_range_mm_s=(1.0, 6.3))
    rng = np.random.default_rng(0)
    grades, phases = [], []
    for _ in range(2000):
        u, g = rb.draw(rng, b, 60_000.0)
        assert 1.0 <= g <= 6.3 and 0 <= u.phase_rad < 2 * math.pi
        # U = e / C with e = G / omega at the reference speed (ISO 21940-11)
        assert u.magnitude == pytest.approx(g * 1e-3 / (60_000 * math.pi / 30) / b.clearance_m, rel=1e-12)
        grades.append(g)
        phases.append(u.phase_rad)
    # log-uniform: ln G uniform on [0, ln 6.3], mean ln(6.3)/2, standard error 0.012 (4 sigma here)
    assert np.mean(np.log(grades)) == pytest.approx(0.5 * math.log(6.3), abs=0.048)
    assert np.mean(phases) == pytest.approx(math.pi, abs=4 * 2 * math.pi / math.sqrt(12 * 2000))
    u, g = RotorBalance(grade_range_mm_s=(2.5, 2.5), reference_speed_rpm=30_000.0).draw(rng, b, 60_000.0)
    assert u.magnitude == pytest.approx(Unbalance.from_iso1940(b, 2.5, 30_000.0).magnitude)
    state = rng.bit_generator.state
    assert RotorBalance.perfect().draw(rng, b, 60_000.0) == (None, 0.0)
    assert rng.bit_generator.state == state  # a perfect rotor draws nothing
    with pytest.raises(ValueError, match="grade_range_mm_s"):
        RotorBalance(grade_range_mm_s=(3.0, 1.0))
    with pytest.raises(ValueError, match="reference_speed_rpm"):
        RotorBalance(reference_speed_rpm=-1.0)


@pytest.mark.parametrize("env_id", V1_IDS)
def test_v1_episode_carries_its_unbalance_into_the_integrator(env_id):
    env = make_retired(env_id, **FAST)
    u = env.unwrapped
    _, info = env.reset(seed=4)
    grade = info["balance_grade_mm_s"]
    assert 1.0 <= grade <= 6.3
    ub = u._integ.unbalance
    expect = Unbalance.from_iso1940(u.bearing, grade, u.speed_range_rpm[1])
    assert ub.magnitude == pytest.approx(expect.magnitude, rel=1e-12)
    assert info["unbalance_um"] == pytest.approx(u.bearing.micrometres(ub.magnitude))
    # a new episode draws another one; the same seed the same one
    _, info2 = env.reset(seed=5)
    assert info2["balance_grade_mm_s"] != grade
    _, info3 = env.reset(seed=4)
    assert info3["balance_grade_mm_s"] == grade


@pytest.mark.parametrize("cls", [RunUpEnv, RunUpRandomizedEnv, WhirlRecoveryEnv])
def test_the_class_alone_is_the_ideal_machine_without_unbalance_or_shocks(cls):
    env = cls(**FAST)
    env.action_space.seed(0)
    _, info = env.reset(seed=0)
    for _ in range(3):
        _, _, term, _, info = env.step(env.action_space.sample())
        if term:
            break
    assert env._integ.unbalance is None and info["damping_gain"] == 1.0
    assert info["balance_grade_mm_s"] == 0.0 and info["unbalance_um"] == 0.0 and info["shocks"] == 0


def test_shocks_arrive_reach_the_integrator_and_move_the_rotor():
    kw = {**FAST, "rotor_balance": RotorBalance.perfect()}
    quiet = make_retired("gfb_env/RunUp-v1", shock_arrivals=ShockArrivals.none(), **kw).unwrapped
    shaken = make_retired("gfb_env/RunUp-v1", shock_arrivals={"rate_per_s": 300.0}, **kw).unwrapped
    a = np.array([0.0, 0.0], dtype=np.float32)
    quiet.reset(seed=0)
    shaken.reset(seed=0)
    n, amp_q, amp_s = 0, 0.0, 0.0
    for _ in range(4):
        _, _, tq, _, iq = quiet.step(a)
        _, _, ts, _, i_s = shaken.step(a)
        n += i_s["shocks"]
        amp_q, amp_s = max(amp_q, iq["whirl_amplitude"]), max(amp_s, i_s["whirl_amplitude"])
        assert i_s["shocks"] == 0 or i_s["shock_peak_g"] >= 2.0
        if tq or ts:
            break
    # 300 per second over 4 steps of 3.2 ms: ~4 expected
    assert n >= 1 and shaken.episode.shock_count == n
    assert amp_s > 10 * amp_q  # the pulses shake the journal (the quiet rotor only sheds its start kick)


def test_kicks_and_shocks_exclude_each_other():
    with pytest.raises(ValueError, match="disturbance_probability"):
        make_retired("gfb_env/RunUp-v1", disturbance_probability=0.1)
    assert MACHINE_V1["disturbance_probability"] == 0.0
