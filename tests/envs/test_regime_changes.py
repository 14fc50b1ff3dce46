"""Friction-regime changes of the damping effectiveness g (``damping_regime_changes``, issue 19 s.3's
redesign, ``docs/task_redesign.md``): the component's validation, its draws, the plant's D_W following
the schedule, the privileged channel holding it, and nothing of it in the observation or the info."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import record_short_episode

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents.oracles.commanded import CommandedOracle, DelayedGainOracle
from gfb_env.envs.config import EnvConfig
from gfb_env.envs.contract import hidden_value_matches, unclassified_keys
from gfb_env.machine import DampingActuatorState, DampingRegimeChanges, FoilDampingActuator
from gfb_env.machine.regime import reflect_log

WR2 = "gfb_env/WhirlRecovery-v2"
#: many changes in a short episode (one per ~2 control steps of 9.5 ms)
BUSY = {"rate_per_s": 50.0, "factor_range": (1.5, 2.5)}


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"rate_per_s": -1.0}, "rate_per_s"),
        ({"rate_per_s": math.nan}, "rate_per_s"),
        ({"factor_range": (0.5, 2.0)}, "factor_range"),
        ({"factor_range": (2.0, 1.5)}, "factor_range"),
        ({"gain_bounds": (1.0, 1.0)}, "gain_bounds"),
        ({"gain_bounds": (0.0, 2.0)}, "gain_bounds"),
    ],
)
def test_a_bad_field_is_refused_naming_it(kw, field):
    with pytest.raises(ValueError, match=field):
        DampingRegimeChanges(**kw)


def test_off_by_default_and_bounds_needed_without_a_gain_range():
    assert EnvConfig().damping_regime_changes.is_off
    with pytest.raises(ValueError, match="damping_regime_changes needs gain_bounds"):
        EnvConfig(damping_regime_changes={"rate_per_s": 1.0})
    cfg = EnvConfig(damping_regime_changes={"rate_per_s": 1.0, "gain_bounds": [0.5, 2.0]})
    assert cfg.damping_regime_changes.gain_bounds == (0.5, 2.0)
    with pytest.raises(ValueError, match="damping_regime_changes"):
        gym.make(WR2, damping_regime_changes={"rate": 1.0})


def test_the_draws_chain_stay_in_bounds_and_repeat_per_seed():
    comp = DampingRegimeChanges(rate_per_s=20.0, factor_range=(1.5, 2.5))
    a = comp.draw(np.random.default_rng(3), 0.0, 2.0, 1.0, (0.6, 1.8))
    b = comp.draw(np.random.default_rng(3), 0.0, 2.0, 1.0, (0.6, 1.8))
    assert a == b and len(a) > 10
    g = 1.0
    for c in a:
        assert c.gain_before == g and 0.6 <= c.gain_after <= 1.8
        assert c.factor == pytest.approx(c.gain_after / c.gain_before)
        g = c.gain_after
    assert [c.time_s for c in a] == sorted(c.time_s for c in a)
    # unreflected changes have a size in the factor range
    free = comp.draw(np.random.default_rng(4), 0.0, 2.0, 1.0, (1e-30, 1e30))
    assert all(1.5 <= max(c.factor, 1 / c.factor) <= 2.5 for c in free)
    # off: no draw at all (the generator's state is untouched)
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    assert DampingRegimeChanges.none().draw(rng, 0.0, 2.0, 1.0, (0.6, 1.8)) == []
    assert rng.bit_generator.state == state


def test_reflection_in_log_gain():
    assert reflect_log(1.0, 0.5, 2.0) == pytest.approx(1.0)
    assert reflect_log(4.0, 0.5, 2.0) == pytest.approx(1.0)  # 2 x 2 reflected at 2
    assert reflect_log(0.125, 0.5, 2.0) == pytest.approx(2.0)  # 0.5 / 4 reflected twice
    assert reflect_log(0.3, 0.6, 1.8) == pytest.approx(1.2)


def test_a_change_keeps_the_actuator_setting():
    s = DampingActuatorState(foil_damping=3.0, gain=1.5)
    t = s.with_gain(0.75)
    assert t.gain == 0.75 and t.indicated_damping == pytest.approx(s.indicated_damping)
    assert t.foil_damping == pytest.approx(1.5)
    act = FoilDampingActuator()
    assert act.step(t, 2.0, 1.0).foil_damping == pytest.approx(1.5)  # long after: g x command


def _run(seed: int, steps: int, regimes: dict | None, privileged: bool = True):
    kw = {"privileged_info": privileged}
    if regimes is not None:
        kw["damping_regime_changes"] = regimes
    env = gym.make(WR2, **kw)
    u = env.unwrapped
    obs, info = env.reset(seed=seed)
    rec = [(obs, info, u.hidden_parameters())]
    for k in range(steps):
        # a fixed action sequence (slow down, damping swept): the same in every run
        obs, _, term, trunc, info = env.step(np.array([-1.0, 0.3 * math.sin(0.4 * k)]))
        rec.append((obs, info, u.hidden_parameters()))
        if term or trunc:
            break
    env.close()
    return rec


@pytest.fixture(scope="module")
def busy():
    return _run(7, 20, BUSY)


def test_the_schedule_is_deterministic_per_seed(busy):
    again = _run(7, 20, BUSY)
    sched = [h["damping_regime_changes"] for _, _, h in busy]
    assert sched == [h["damping_regime_changes"] for _, _, h in again]
    assert len(sched[-1]["changes"]) >= 5
    other = _run(8, 20, BUSY)[-1][2]["damping_regime_changes"]
    assert other != sched[-1]


def test_the_plant_follows_the_schedule(busy):
    _, _, h0 = busy[0]
    g0 = h0["damping_regime_changes"]["gain_start"]
    assert h0["damping_gain"] == g0 and h0["damping_regime_changes"]["changes"] == []
    seen_jump = False
    for _, info, h in busy[1:]:
        changes = h["damping_regime_changes"]["changes"]
        g = g0 * math.prod(c["factor"] for c in changes)
        assert h["damping_gain"] == pytest.approx(g, rel=1e-12)  # the current g: start x factors
        assert info["privileged"]["hidden_parameters"]["damping_gain"] == h["damping_gain"]
        # the plant's actual D_W is the current g times the actuator's setting (what it indicates)
        actual = info["privileged"]["foil_damping"]
        assert actual == pytest.approx(h["damping_gain"] * info["damping_indicated"], rel=1e-6)
        seen_jump |= bool(changes) and changes[-1]["gain_after"] != g0
    assert seen_jump
    # the certificate's plant is the final one: its achievable actual damping is the current g's
    # (checked through the oracle's re-plan below)


def test_nothing_of_the_schedule_reaches_the_observation_or_the_info(busy):
    calm = _run(7, 20, None)
    lay = gym.make(WR2).unwrapped.observation_layout
    for _, info, h in busy:
        assert unclassified_keys(WR2, info) == [] and "damping_gain" not in info
        assert hidden_value_matches(info, h) == {}  # no jump time, factor or g in any info value
    # the indicated damping (observation and info) is the same as without changes: the actuator is not
    # what changed, so its position feedback shows nothing (the steps both runs took whole: a step
    # ending in a touchdown stops inside the step)
    n = 0
    for (o1, i1, _), (o0, i0, _) in zip(busy, calm, strict=False):
        if "termination_reason" in i1 or "termination_reason" in i0:  # (the last info only)
            break
        assert i1["damping_indicated"] == i0["damping_indicated"]
        assert o1[lay.damping] == o0[lay.damping]
        n += 1
    assert n >= 5
    assert "damping_regime_changes" not in calm[-1][2]  # off: the v2 dict as before


def test_the_contract_holds_over_an_episode_with_changes():
    infos, hidden, _, _ = record_short_episode(WR2, 3, damping_regime_changes=BUSY)
    assert hidden[-1]["damping_regime_changes"]["changes"]
    for info, hp in zip(infos, hidden, strict=True):
        assert unclassified_keys(WR2, info) == []
        assert hidden_value_matches(info, hp) == {}


def test_the_oracle_replans_at_the_current_gain():
    env = gym.make(WR2, damping_regime_changes=BUSY)
    u = env.unwrapped
    pol = CommandedOracle(env)
    obs, info = env.reset(seed=11)
    pol.reset()
    pol.observe_reset_info(info)
    replans = 0
    for _ in range(15):
        before = pol.planned_gain
        a, _ = pol.predict(obs)
        if pol.planned_gain != before:
            replans += 1
        # the damping it commands is the best point's command for the plant as it is now
        assert pol.planned_gain == u.damping_gain
        best = u.best_stable_operating_point()
        assert best.commanded_damping == pytest.approx(best.foil_damping / u.damping_gain)
        assert a[1] == pytest.approx(u.action_from_damping(best.commanded_damping), abs=1e-6)
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    assert replans >= 2
    env.close()


def test_the_native_vector_env_draws_the_changes_as_single_envs():
    kw = {"damping_regime_changes": BUSY}
    vec = gym.make_vec(WR2, num_envs=2, **kw)
    obs_v, _ = vec.reset(seed=21)
    singles = [gym.make(WR2, **kw) for _ in range(2)]
    obs_s = [e.reset(seed=21 + i)[0] for i, e in enumerate(singles)]
    np.testing.assert_array_equal(obs_v, np.stack(obs_s))
    for k in range(4):
        a = np.array([[-1.0, 0.05 * k], [-1.0, -0.05 * k]], dtype=np.float32)
        obs_v, r_v, term_v, *_ = vec.step(a)
        for i, e in enumerate(singles):
            o, r, *_ = e.step(a[i])
            np.testing.assert_array_equal(obs_v[i], o)
            assert r_v[i] == r
        if term_v.any():  # (a touchdown: the vector env resets that one)
            break
    gains = vec.get_attr("damping_gain")
    assert list(gains) == [e.unwrapped.damping_gain for e in singles]
    assert any(e.unwrapped.hidden_parameters()["damping_regime_changes"]["changes"] for e in singles)
    vec.close()


def test_the_delayed_oracle_commands_for_the_gain_of_d_steps_ago():
    env = gym.make(WR2, damping_regime_changes=BUSY)
    u = env.unwrapped
    pol = DelayedGainOracle(env, 3)
    assert pol.name == "oracle_delay3"
    with pytest.raises(ValueError, match="delay_steps"):
        DelayedGainOracle(env, -1)
    obs, info = env.reset(seed=11)
    pol.reset()
    pol.observe_reset_info(info)
    gains, lagged = [], 0
    for k in range(12):
        gains.append(u.damping_gain)
        a, _ = pol.predict(obs)
        known = gains[max(0, k - 3)]
        d_opt = u.best_stable_operating_point().foil_damping
        assert a[1] == pytest.approx(u.action_from_damping(d_opt / known), abs=1e-6)
        lagged += known != gains[-1]
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    assert lagged >= 2  # it did command for an old g while the plant had another
    env.close()


def test_the_headroom_script_stays_on_dev_seeds_and_pairs_the_seeds():
    from gfb_experiments import regime_change_headroom as rch

    with pytest.raises(SystemExit) as e:
        rch.main(["--rate", "1", "--seeds", "10", "--seed-offset", "9995"])
    assert e.value.code == 2
    rng = np.random.default_rng(0)
    seeds = list(range(20))
    ret = {"naive": rng.normal(0, 1, 20), "hold": rng.normal(-1, 1, 20), "rule": rng.normal(5, 1, 20)}
    ret["oracle_v1"] = ret["rule"] + 5.0
    rec = {
        "episodes": {
            n: [
                {"seed": s, "return": float(r[s]), "success": False, "touchdown": False, "changes": 1}
                for s in seeds
            ]
            for n, r in ret.items()
        }
    }
    st = rch.statistics(rec, seeds, reps=200)
    assert st["best_rule"] == "rule" and st["reference"]["mean"]["reference"] == "naive"
    gap = np.mean(ret["oracle_v1"]) - np.mean(ret["naive"])
    # a constant per-seed difference: the paired CI is a point
    assert st["headroom"]["mean"] == pytest.approx(5.0 / gap)
    assert st["headroom"]["mean_low"] == pytest.approx(5.0 / gap)
