"""Tests of the bearing identification (:class:`BearingIdentifier`) and the rule that flies the published
table at its estimate (:class:`IdentifyingAgent`, the core of ``identify_map_v1``) on RunUpRandomized-v1:
the fit recovers a draw from its exact observation, the rule reads only the observation."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

from gfb_agents.estimation.identification import BearingIdentifier
from gfb_agents.learned.evaluate import run_episode
from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec
from gfb_agents.rules.identify_map import IdentifyingAgent
from gfb_agents.rules.map_informed import MapInformedAgent
from gfb_env.envs import make_env

RANDOMIZED = "gfb_env/RunUpRandomized-v1"


@pytest.fixture(scope="module")
def renv():
    env = make_env(RANDOMIZED)
    yield env
    env.close()


def _draw(info: dict) -> np.ndarray:
    return np.array([info["clearance_um"] * 1e-6, info["stiffness_factor"], info["load_n"]])


@pytest.mark.parametrize(
    "draw",
    [
        (50e-6, 1.0, 20.0),
        # corners of the documented ranges: the fit must not stick inside the box
        (40e-6, 1.4, 25.0),
        (60e-6, 0.7, 15.0),
        # draws where a local fit from the best grid point alone stalls at the lowest load
        (44.98e-6, 1.268, 16.78),
        (52.18e-6, 1.178, 16.98),
    ],
)
def test_identifier_recovers_a_draw_from_its_exact_observation(renv, draw):
    idf = BearingIdentifier(renv)
    y, _ = idf.predict(*draw)  # the noise-free observation of the draw at the start speed
    est = idf.fit_measured(y.astype(np.float32).astype(float), None, 3, 6, 1e-5, x_scale=1.0, diff_step=1e-4,
                           xtol=1e-10, ftol=1e-12, max_nfev=60)  # fmt: skip
    got = np.array([est.clearance_m, est.stiffness_factor, est.load_n])
    # stated accuracy: 0.1 % of each parameter (a float32 observation; the fit reaches ~1e-6)
    np.testing.assert_allclose(got, draw, rtol=1e-3)
    assert est.residual < 1e-5 and est.solves < 400


def test_identifier_restarts_where_one_local_fit_stalls(renv):
    idf = BearingIdentifier(renv)
    y, _ = idf.predict(44.98e-6, 1.268, 16.78)
    opts = dict(x_scale=1.0, diff_step=1e-4, xtol=1e-10, ftol=1e-12, max_nfev=60)
    one = idf.fit_measured(y, None, 3, 1, 1e-5, **opts)
    assert one.residual > 1e-3 and one.load_n == pytest.approx(15.0)  # stalled at the bound
    est = idf.fit_measured(y, None, 3, 6, 1e-5, **opts)
    assert est.residual < 1e-5 and est.load_n == pytest.approx(16.78, rel=1e-3)


def _envs_in(obj, seen=None) -> list:
    """Every gymnasium env reachable from ``obj``'s attributes (recursively)."""
    seen = seen if seen is not None else set()
    if id(obj) in seen:
        return []
    seen.add(id(obj))
    if isinstance(obj, gym.Env):
        return [obj]
    found = []
    children = (
        list(obj.values())
        if isinstance(obj, dict)
        else list(obj)
        if isinstance(obj, (list, tuple))
        else list(vars(obj).values())
        if hasattr(obj, "__dict__")
        else []
    )
    for c in children:
        found += _envs_in(c, seen)
    return found


def test_identify_map_reads_only_the_observation(renv):
    """Built from an env that was never reset (no episode exists), holding no env, and fed only the
    observation of another env's episode, the rule's estimate is the fit of that observation."""
    agent = IdentifyingAgent(make_env(RANDOMIZED))
    assert _envs_in(agent) == []
    agent = pickle.loads(pickle.dumps(agent))  # no live env, no simulator state inside
    obs, info = renv.reset(seed=4)
    a, _ = agent.predict(obs, episode_start=True)
    est = agent.last_estimate
    ref = BearingIdentifier(renv).fit(obs)
    assert (est.clearance_m, est.stiffness_factor, est.load_n) == (
        ref.clearance_m,
        ref.stiffness_factor,
        ref.load_n,
    )
    # it flies the published table's schedule of the identified bearing: d_opt of the table
    d_opt = renv.unwrapped.table(est.clearance_m, est.stiffness_factor, est.load_n)["d_opt"]
    assert a[1] == pytest.approx(agent.spec.damping_action(d_opt), abs=1e-3)


def test_identify_map_is_map_informed_on_a_nominal_task():
    env = make_env("gfb_env/RunUp-v1", max_episode_steps=30)
    nmap = NominalMap.from_env(env)
    ref = run_episode(env, MapInformedAgent(ControlSpec.from_env(env, nmap), nmap), seed=3)
    agent = IdentifyingAgent(env)
    r = run_episode(env, agent, seed=3)
    assert (r.episode_return, r.steps, r.success) == (ref.episode_return, ref.steps, ref.success)
    assert agent.last_estimate is None
    env.close()
