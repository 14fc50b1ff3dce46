"""Tests of ``margin_aim_1x`` (issue 19 s.3): the audit's rule, adopted into the ladder."""

from __future__ import annotations

import gymnasium as gym
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_agents.learned.evaluate import run_episode
from gfb_agents.rules.margin_aim_1x import MarginAim1xAgent

RU2, RUR2 = "gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2"
SEED = 5001  # a DEV seed whose command lies above the boundary estimate


@pytest.mark.parametrize("margin", [-0.01, 0.5, float("nan")])
def test_bad_margin_is_refused_naming_the_field(margin):
    env = gym.make(RU2)
    with pytest.raises(ValueError, match="margin"):
        MarginAim1xAgent(env.unwrapped, margin=margin)


def test_ladder_has_both_margins_on_the_run_up_tasks_only():
    for task in (RU2, RUR2):
        names = {e.name for e in ladder.ladder_for(task)}
        assert {"margin_aim_1x", "margin_aim_1x_05"} <= names
    assert "margin_aim_1x" not in {e.name for e in ladder.ladder_for("gfb_env/WhirlRecovery-v2")}
    env = gym.make(RU2)
    assert ladder.build("margin_aim_1x_05", env).margin == 0.005


def test_set_point_aims_at_the_posterior_boundary_and_is_bolder_than_margin_search_1x():
    # every refined decision sets min(command, cap, (1 - margin) E_post[Lambda_c]); margin_search_1x, with
    # the same estimates, ends lower on the same seed (its decision asks a 2 % sd and a decay margin)
    env = gym.make(RU2)
    aim = ladder.build("margin_aim_1x", env)
    seen = []
    decide = aim._decide

    def spy(m, obs):
        decide(m, obs)
        if m.refined and m.table is not None:
            lam_set = m.bearing.bearing_number_at(m.setpoint)
            seen.append((lam_set, aim.last_boundary, m.cap))

    aim._decide = spy
    r_aim = run_episode(env, aim, SEED)
    assert seen
    for lam_set, lc, cap in seen:
        assert lam_set <= (1 - aim.margin) * lc * (1 + 1e-9)
        assert lam_set <= cap * (1 + 1e-9)
    # the aim binds (not the command) on this seed: the set-point is the boundary estimate less 1 %
    lam_set, lc, _ = seen[-1]
    assert lam_set == pytest.approx(0.99 * lc, rel=1e-9)
    ms = ladder.build("margin_search_1x", env)
    r_ms = run_episode(env, ms, SEED)
    assert r_aim.final_speed_rpm > r_ms.final_speed_rpm
