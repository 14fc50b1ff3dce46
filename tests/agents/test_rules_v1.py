"""Tests of the v1 rules (agents/rules/, agents/estimation/, issue 11): the plant's stability table
against the documented task constants, the posterior over the hidden damping gain, the noise-aware
identification, and short episodes of each rule (finite actions in the action space).  Training seeds
only (< 10000)."""

from __future__ import annotations

import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.estimation.decay import DecayMeter
from gfb_agents.estimation.gain import GainPosterior
from gfb_agents.estimation.identification import BearingIdentifier, identify_bearing, refine_bearing
from gfb_agents.estimation.stability import StabilityTable
from gfb_agents.ladder import build as make_rule
from gfb_agents.rules.operating_point import OperatingPointConfig, choose_operating_point
from gfb_env.envs import make_env
from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.envs.base import viscoelastic_model
from gfb_experiments.rules_check import RULE_NAMES


@pytest.fixture(scope="module")
def table() -> StabilityTable:
    model = viscoelastic_model("31x7", NOMINAL_BEARING)
    return StabilityTable.compute(model, 0.60, 0.74, n_lambda=8, damping_range=(0.3, 8.0), n_damping=9)


def test_stability_table_reproduces_the_documented_boundary(table):
    # docs/envs.md (31x7): Lambda_c(D_W = 1) = 0.6585, lambda_best = 0.7014 at D_W = 2.24
    assert table.critical(np.array(1.0)) == pytest.approx(0.6585, abs=0.004)
    ds = np.geomspace(1.0, 4.0, 15)
    lc = table.critical(ds)
    assert lc.max() == pytest.approx(0.7014, abs=0.004)
    assert 1.6 < ds[int(np.argmax(lc))] < 3.2
    # a decay-rate margin lies below the boundary
    assert float(table.critical(np.array(2.24), level=-0.004)) < float(table.critical(np.array(2.24))) - 0.01


def test_posterior_finds_the_gain_from_two_decay_rates(table):
    g_true = 2.5
    post = GainPosterior((0.316, 3.16))
    for d_cmd in (1.8, 1.8 * 1.6):
        rate = 60.0 * float(table.growth_rate(0.64, np.array([g_true * d_cmd]))[0])
        post.add_decay(table, 0.64, d_cmd, rate)
    w = post.weights
    assert abs(np.log(post.gains[int(np.argmax(w))] / g_true)) < 0.15
    assert w[post.gains < 1.0].sum() < 0.05  # the side of the optimum is resolved
    # and the operating point it implies: the damping that is optimal for that gain, near the boundary
    d, lam, _ = choose_operating_point(
        table, post, 0.45, 0.73, 0.73, OperatingPointConfig((0.1, 10.0), 0.004)
    )
    assert 0.5 < d * g_true / 2.24 < 2.0
    assert 0.66 < lam < 0.7014


def test_decay_meter_measures_a_synthetic_decay():
    meter = DecayMeter()
    for _ in range(5):
        assert meter.update(0.035, 0.6, 2.0) == []
    out = []
    env_ = [0.6, 0.5] + [0.035 + 0.4 * np.exp(-0.4 * k) for k in range(12)]
    for e in env_:
        out += meter.update(float(e), 0.6, 2.0)
    assert len(out) == 1
    rate, lam, d, n = out[0]
    assert rate == pytest.approx(-0.4, abs=0.05) and lam == 0.6 and d == 2.0 and n >= 4


@pytest.mark.parametrize("seed", [1, 2])
def test_identify_bearing_from_noisy_observations(seed):
    env = make_env("gfb_env/RunUpRandomized-v1")
    u = env.unwrapped
    obs, info = env.reset(seed=seed)
    obsl = [obs]
    for _ in range(5):
        obs, *_ = env.step(np.zeros(2, dtype=np.float32))
        obsl.append(obs)
    est = identify_bearing(BearingIdentifier(u), obsl)
    true = np.array([info["clearance_um"] * 1e-6, info["stiffness_factor"], info["load_n"]])
    got = np.array([est.clearance_m, est.stiffness_factor, est.load_n])
    # sensor biases (probes 1 um, taps 0.9 kPa) limit the accuracy: measured rms 2 % (C), 4.6 % (f_K),
    # 1.3 % (F_L) on seeds 0-5
    err = np.abs(got / true - 1)
    assert np.all(err < [0.05, 0.1, 0.05]), err
    env.close()


def test_refine_bearing_removes_the_sensor_biases_along_the_run_up():
    # seed 0: the start-speed fit is 2.9 % off in C and 6.9 % in f_K (lambda_best -5.3 %): the biases
    env = make_env("gfb_env/RunUpRandomized-v1")
    u = env.unwrapped
    lay = u.observation_layout
    obs, info = env.reset(seed=0)
    start = [obs]
    for _ in range(5):
        obs, *_ = env.step(np.zeros(2, dtype=np.float32))
        start.append(obs)
    idf = BearingIdentifier(u)
    est0 = identify_bearing(idf, start)
    ramp = []
    for _ in range(28):
        obs, *_ = env.step(np.array([1.0, 0.0], dtype=np.float32))
        ramp.append(obs)
    pts = [(lay.speed_rpm(start[0]), np.mean(start, axis=0), len(start))]
    for j in range(0, 28, 4):
        grp = ramp[j : j + 4]
        pts.append((float(np.mean([lay.speed_rpm(o) for o in grp])), np.mean(grp, axis=0), 4))
    est1 = refine_bearing(idf, pts, est0)
    true = np.array([info["clearance_um"] * 1e-6, info["stiffness_factor"], info["load_n"]])
    e0 = np.abs(np.array([est0.clearance_m, est0.stiffness_factor, est0.load_n]) / true - 1)
    e1 = np.abs(np.array([est1.clearance_m, est1.stiffness_factor, est1.load_n]) / true - 1)
    assert e1[0] < 0.6 * e0[0] and e1[1] < 0.7 * e0[1], (e0, e1)
    env.close()


@pytest.mark.parametrize(
    "env_id,rule",
    [
        ("gfb_env/RunUp-v1", "naive"),
        ("gfb_env/RunUp-v1", "margin_search"),
        ("gfb_env/RunUpRandomized-v1", "margin_search"),
        ("gfb_env/WhirlRecovery-v1", "recovery"),
    ],
)
def test_rules_run_short_episodes_with_finite_actions(env_id, rule):
    env = make_env(env_id)
    pol = make_rule(rule, env)
    obs, info = env.reset(seed=3)
    for k in range(12):
        a, _ = pol.predict(obs, episode_start=(k == 0))
        assert a.shape == (2,) and np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0)
        obs, r, term, trunc, info = env.step(a)
        assert np.isfinite(r)
        if term or trunc:
            break
    env.close()


def test_recovery_starts_from_the_prior_over_the_gain():
    """WhirlRecovery-v1's reset observation no longer reveals g: the rule's posterior is its prior."""
    env = make_env("gfb_env/WhirlRecovery-v1")
    pol = make_rule("recovery", env)
    obs, info = env.reset(seed=5)
    pol.predict(obs, episode_start=True)
    post = pol._mem[0].post
    w = np.exp(post.log_w - np.max(post.log_w))
    assert len(post.gains) > 1 and np.ptp(w) < 1e-12
    env.close()


def test_recovery_survival_weighs_down_the_gains_outside_the_window():
    """Alive after the first steps: plants whose actual damping g d_start lies outside the survival
    window (they touch down within two steps on the training seeds) lose a factor survival_odds."""
    from gfb_agents.rules.recovery import RecoveryAgent

    env = make_env("gfb_env/WhirlRecovery-v1")
    pol = RecoveryAgent(env.unwrapped)
    m = pol._new_memory()
    m.d_start = 3.2  # (the task's start command d_opt = 2.24 keeps every gain of its prior inside)
    pol._survived(m)
    post = m.post
    actual = post.gains * 3.2
    inside = (actual >= 1.2) & (actual <= 5.0)
    assert inside.any() and (~inside).any()
    lw = post.log_w - post.log_w.max()
    assert np.allclose(lw[inside], 0.0) and np.allclose(lw[~inside], np.log(0.05))
    env.close()


def test_recovery_probe_speed_keeps_every_plausible_plant_stable():
    from gfb_agents.rules.recovery import RecoveryAgent

    model = viscoelastic_model("31x7", NOMINAL_BEARING)
    table = StabilityTable.compute(model, 0.50, 0.70, n_lambda=9, damping_range=(0.1, 10.0), n_damping=11)

    env = make_env("gfb_env/WhirlRecovery-v1")
    pol = RecoveryAgent(env.unwrapped)
    m = pol._new_memory()
    m.table = table
    m.post.log_w = np.where((m.post.gains > 0.5) & (m.post.gains < 2.0), 0.0, -50.0)
    lam = pol.probe_bearing_number(m, 0.66)
    assert 0.50 < lam < 0.66
    plausible = m.post.gains[(m.post.gains > 0.5) & (m.post.gains < 2.0)]
    for d in pol.unbalance_dampings:
        # at the probe speed every plausible plant decays at the probe's rate at least (table resolution)
        assert np.all(table.growth_rate(lam, plausible * d) <= pol.probe_growth_rate + 2e-4)
    assert pol.probe_bearing_number(m, 0.55) == 0.55  # never above the present speed
    env.close()


def test_recovery_decisions_depend_only_on_the_observations():
    """The rule bound to an env whose hidden gain differs, fed the observations of another episode,
    takes the same actions as the rule that played it: it reads no hidden parameter."""
    env_a, env_b = make_env("gfb_env/WhirlRecovery-v1"), make_env("gfb_env/WhirlRecovery-v1")
    pol_a, pol_b = make_rule("recovery", env_a), make_rule("recovery", env_b)
    obs, _ = env_a.reset(seed=0)
    env_b.reset(seed=3)  # another hidden gain: 0.66 (seed 0 draws 1.21)
    assert abs(np.log(env_b.unwrapped.damping_gain / env_a.unwrapped.damping_gain)) > 0.5
    for k in range(30):
        a, _ = pol_a.predict(obs, episode_start=(k == 0))
        b, _ = pol_b.predict(obs, episode_start=(k == 0))
        assert np.array_equal(a, b), k
        obs, _, term, trunc, _ = env_a.step(a)
        assert not (term or trunc)
    env_a.close()
    env_b.close()


@pytest.mark.parametrize("seed", [0, 6])
def test_recovery_learns_the_gain_and_ends_certified(seed):
    """Training seeds 0 (g = 1.21) and 6 (g = 1.08): after the dip, the survival evidence, the decays and
    the unbalance probe, the posterior mean of ln g is within 0.2 of the truth and the end is certified
    within 5 % of lambda_best."""
    env = make_env("gfb_env/WhirlRecovery-v1")
    u = env.unwrapped
    pol = make_rule("recovery", env)
    obs, info = env.reset(seed=seed)
    k, done = 0, False
    while not done:
        a, _ = pol.predict(obs, episode_start=(k == 0))
        obs, r, term, trunc, info = env.step(a)
        k, done = k + 1, term or trunc
    post = pol._mem[0].post
    mu = float(post.weights @ np.log(post.gains))
    assert abs(mu - np.log(u.damping_gain)) < 0.2, (mu, u.damping_gain)
    assert info["certified"]
    assert info["bearing_number"] >= 0.95 * u.best_stable_operating_point().bearing_number
    env.close()


def test_make_rule_names():
    env = make_env("gfb_env/RunUp-v1")
    for name in RULE_NAMES:
        assert make_rule(name, env).name == name
    with pytest.raises(LookupError, match="no agent 'nope' in the ladder"):
        make_rule("nope", env)
    env.close()


def test_cli_refuses_test_seeds_and_missing_arguments(capsys):
    from gfb_experiments.rules_check import main

    assert main(["--env", "gfb_env/RunUp-v1", "--rule", "naive", "--seeds", "10000", "10002"]) == 2
    assert "training/validation seeds only" in capsys.readouterr().out
    assert main(["--seeds", "0", "1"]) == 2


def test_creep_raises_the_set_point_until_the_time_runs_short():
    """The optional boundary creep (off by default): from the model's set-point below the command it
    raises the set-point by creep_rate per step at a frozen damping, holds creep_margin below a whirl
    onset, and keeps the highest calm speed when the time runs short."""
    from gfb_agents.rules.margin_search import MarginSearchAgent, Mode

    env = make_env("gfb_env/RunUp-v1")
    u = env.unwrapped
    pol = MarginSearchAgent(u, creep_rate=0.01, creep_margin=0.015)
    assert MarginSearchAgent(u).creep_rate == 0.0  # the default rule does not creep
    m = pol._new_memory()
    m.setpoint, m.mode, m.d_cmd, m.cmd_rpm, m.k = 30000.0, Mode.RUN, 1.3, 40000.0, 20
    obs = np.zeros(u.observation_space.shape, dtype=np.float32)
    obs[u.observation_layout.index("time_left")] = 0.8  # 200 steps left
    pol._creep(m, obs, 30000.0)
    assert m.setpoint == pytest.approx(30300.0) and m.creep.d == 1.3
    m.d_cmd = 2.0  # a new decision may not move the damping during the search
    pol._creep(m, obs, 30300.0)
    assert m.setpoint == pytest.approx(30603.0) and m.d_cmd == 1.3
    pol._creep(m, obs, 29000.0)  # not there yet: no further rise
    assert m.setpoint == pytest.approx(30603.0)
    # out of time without an onset: the highest speed crept is the final one
    obs[u.observation_layout.index("time_left")] = 0.05
    pol._creep(m, obs, 30603.0)
    assert m.creep.final_rpm == pytest.approx(30603.0) and m.setpoint == pytest.approx(30603.0)
    # an onset (set by the whirl guard) holds creep_margin below it
    m.creep.onset_rpm, m.creep.final_rpm = 30500.0, 30500.0 * (1 - 0.015)
    m.setpoint = 33000.0
    pol._creep(m, obs, 30000.0)
    assert m.setpoint == pytest.approx(30042.5)
    env.close()
