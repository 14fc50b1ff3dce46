"""recovery_detect (issue 19 s.3): the sub-synchronous CUSUM alarms on a growing mode and not on noise or
a shock's ring-down; the rule acts within the action space on a short episode with regime changes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401
from gfb_agents import ladder
from gfb_agents.learned.evaluate import run_episode
from gfb_agents.rules.recovery_detect import SubsyncCusum
from gfb_experiments.regime_change_detection import score_alarms

FLOOR = 0.00155  # the band's documented noise floor on WhirlRecovery-v2 (units of C_nom)


def _noise(rng, n):
    # the band level of pure noise: sqrt(chi^2_8 / 8) x floor (rank 8, docs/machine.md)
    return FLOOR * np.sqrt(rng.chisquare(8, n) / 8)


def _alarms(levels, **kw):
    det = SubsyncCusum(floor0=FLOOR, **kw)
    return [k for k, x in enumerate(levels) if det.update(x)]


def test_cusum_is_silent_on_noise_alone():
    rng = np.random.default_rng(0)
    assert _alarms(_noise(rng, 2000)) == []


@pytest.mark.parametrize("rate", [0.1, 0.3, 0.7])
def test_cusum_alarms_soon_after_the_mode_starts_growing(rate):
    rng = np.random.default_rng(1)
    k0 = 60
    n = np.arange(200)
    grow = FLOOR * np.exp(rate * np.clip(n - k0, 0, None))
    levels = np.sqrt(_noise(rng, 200) ** 2 + grow**2 - FLOOR**2 * (n >= k0))
    al = _alarms(levels)
    assert al, rate
    # from the floor to 3x the floor takes ln 3 / rate steps; the CUSUM (threshold 0.5 over the drift
    # 0.03 from 2x the floor on) adds a few; at least three rises in a row
    assert k0 < al[0] <= k0 + 1 + max(np.log(3) / rate + 0.5 / (rate - 0.03), 3), (rate, al)


def test_cusum_ignores_a_shock_that_rings_down():
    rng = np.random.default_rng(2)
    levels = _noise(rng, 120)
    # a shock's pulse over three steps, then the stable mode's decay (-0.1 per step, the slowest seen)
    levels[50:53] = FLOOR * np.array([8.0, 18.0, 20.0])
    levels[53:] = np.maximum(levels[53:], 20 * FLOOR * np.exp(-0.1 * np.arange(1, 68)))
    assert _alarms(levels) == []
    # without the jump rule the same ring-down's pulse alarms (the test would catch its removal)
    assert _alarms(levels, jump=50.0) != []


def test_cusum_rejects_bad_settings():
    with pytest.raises(ValueError, match="alarm_level"):
        SubsyncCusum(arm=4.0, alarm_level=3.0)
    with pytest.raises(ValueError, match="floor0"):
        SubsyncCusum(floor0=0.0)


def test_score_alarms_delays_false_and_repeats():
    sc = score_alarms([5, 30, 34, 90], [20, 60], 120)
    assert sc["delays"] == [30 - 21, 90 - 61]
    assert sc["false_alarms"] == [5] and sc["repeat_alarms"] == [34]
    assert score_alarms([], [20], 50)["delays"] == [None]


def test_rule_acts_within_the_action_space_with_regime_changes():
    env = gym.make(
        "gfb_env/WhirlRecovery-v2",
        max_episode_steps=24,
        damping_regime_changes={"rate_per_s": 1.0, "factor_range": [1.5, 2.5]},
    )
    (entry,) = ladder.ladder_for("gfb_env/WhirlRecovery-v2", ["recovery_detect"])
    pol = entry.build(env)
    pol.reset()
    obs, _ = env.reset(seed=101)  # DEV seed: changes at steps 16 and 20, the whirl grows at once
    acts = []
    state, start = None, True
    for _ in range(24):
        a, state = pol.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        start = False
        acts.append(np.asarray(a, dtype=float))
        obs, _, term, trunc, _ = env.step(a)
        if term or trunc:
            break
    acts = np.array(acts)
    assert acts.shape[1] == 2 and np.all(np.isfinite(acts)) and np.all(np.abs(acts) <= 1)
    # the whirl after the changes at steps 16 and 20 is detected within the episode's first 24 steps
    assert pol.alarms(0), "no alarm"
    res = run_episode(env, pol, seed=101)
    assert res.steps == 24
