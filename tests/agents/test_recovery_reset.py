"""``recovery_reset`` (issue 19): the reset observation's likelihood of the damping gain, from public
information only, in the WhirlRecovery rule."""

from __future__ import annotations

import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_agents.estimation.whirl_start import (
    FirstStepUpdate,
    ResetSensorModel,
    reset_log_likelihood,
    whirl_start_table,
)
from gfb_env.envs import make_env

ENV = "gfb_env/WhirlRecovery-v1"
#: DEV seeds (unit tests): their gains span the prior
SEEDS = range(8)
#: the prior's sd of ln g: log-uniform over [0.6, 1.8]
PRIOR_SD = np.log(3.0) / np.sqrt(12.0)

#: what a benchmarked rule must never touch: the privileged channel and the episode's true state
_FORBIDDEN = {
    "hidden",
    "hidden_parameters",
    "privileged_quantities",
    "episode",
    "damping_gain",
    "model",
    "bearing",
    "speed_command",
    "best_stable_operating_point",
    "get_state",
    "set_state",
    "step",
    "reset",
    "plan_step",
    "finish_step",
    "np_random",
}


class PublicView:
    """The env as a rule may see it: its documented configuration; a private attribute or the episode's
    hidden state raises (at construction and during the whole episode, since the rule keeps this)."""

    def __init__(self, env):
        object.__setattr__(self, "_env", env)

    def __getattr__(self, name):
        if name.startswith("_") or name in _FORBIDDEN:
            raise AssertionError(f"the rule read {name!r}")
        if name == "unwrapped":
            return self
        return getattr(object.__getattribute__(self, "_env"), name)


def _posterior_means_and_truth(pol, seed: int, env) -> tuple[float, float, float]:
    """ln g's posterior mean after the rule's first decision (the reset observation) and after its
    second (the first step's), and the truth (read for the test only)."""
    pol.reset()
    obs, _ = env.reset(seed=seed)
    a, _ = pol.predict(obs, episode_start=True)
    post = pol._mem[0].post
    m0 = float(post.weights @ np.log(post.gains))
    obs, *_ = env.step(a)
    pol.predict(obs)
    m1 = float(post.weights @ np.log(post.gains))
    return m0, m1, float(np.log(env.unwrapped.hidden_parameters()["damping_gain"]))


def test_posterior_is_much_sharper_than_the_prior_at_reset_and_sharper_still_after_one_step():
    """The posterior mean of ln g after the reset observation errs by far less than the prior's sd (a
    rule that ignored the reset observation would keep the prior: its rms error ~0.3 on these draws),
    and after the first step's particle update by less again."""
    env = make_env(ENV)
    pol = ladder.build("recovery_reset", env)  # one rule: its stability table is computed once
    m0, m1, truth = np.array([_posterior_means_and_truth(pol, s, env) for s in SEEDS]).T
    err0, err1, prior_err = m0 - truth, m1 - truth, 0.5 * np.log(0.6 * 1.8) - truth
    rms0, rms1 = float(np.sqrt(np.mean(err0**2))), float(np.sqrt(np.mean(err1**2)))
    rms_prior = float(np.sqrt(np.mean(prior_err**2)))
    assert rms_prior > 0.2, rms_prior  # the draws are not all near the prior's centre
    assert rms0 < 0.5 * PRIOR_SD and rms0 < 0.6 * rms_prior, (rms0, rms_prior, err0)
    assert rms1 < 0.08 and rms1 < 0.7 * rms0, (rms1, rms0, err1)
    env.close()


def test_reset_likelihood_peaks_at_the_truth_for_an_exact_observation():
    """The table's noise-free observation at a (gain, phase) of the grid, with the sensor model's mean
    error, has its likelihood's maximum at that gain."""
    env = make_env(ENV)
    table = whirl_start_table(env)
    sensors = ResetSensorModel.from_env(env)
    for i, j in ((5, 300), (20, 900), (35, 1500)):
        ll = reset_log_likelihood(table, sensors, table.mean[i, j] + sensors.offset)
        assert int(np.argmax(ll)) == i
    with pytest.raises(ValueError, match="values must have shape"):
        reset_log_likelihood(table, sensors, np.zeros(3))
    env.close()


def test_rule_reads_no_private_or_hidden_state_and_plays_a_whole_episode():
    """Built on a view of the env that raises on anything private or hidden, fed only observations (no
    info), the rule plays a whole episode with finite actions in [-1, 1]."""
    env = make_env(ENV)
    pol = ladder.build("recovery_reset", PublicView(env.unwrapped))
    pol.reset()
    obs, _ = env.reset(seed=2)
    k, done = 0, False
    while not done:
        a, _ = pol.predict(obs, episode_start=(k == 0))
        assert a.shape == (2,) and np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0), (k, a)
        obs, r, term, trunc, _ = env.step(a)
        assert np.isfinite(r) and np.all(np.isfinite(obs))
        k, done = k + 1, term or trunc
    assert k == 200 or term
    assert np.all(np.isfinite(pol.last_reset_log_likelihood))
    assert np.all(np.isfinite(pol.last_first_step_log_likelihood))
    env.close()


def test_rule_is_deterministic_with_the_seed():
    """Two fresh envs on one seed, the rule reset between them: the same actions, bit for bit (through
    the reset's and the first step's updates and the dip)."""
    env0 = make_env(ENV)
    pol = ladder.build("recovery_reset", env0)
    runs = []
    for _ in range(2):
        env = make_env(ENV)
        pol.reset()
        obs, _ = env.reset(seed=4)
        acts = []
        for k in range(15):
            a, _ = pol.predict(obs, episode_start=(k == 0))
            acts.append(np.asarray(a, dtype=np.float64).copy())
            obs, _, term, trunc, _ = env.step(a)
            if term or trunc:
                break
        runs.append((np.array(acts), pol._mem[0].post.log_w.copy()))
        env.close()
    assert runs[0][0].shape == runs[1][0].shape and runs[0][0].tobytes() == runs[1][0].tobytes()
    assert runs[0][1].tobytes() == runs[1][1].tobytes()
    env0.close()


def test_reset_entries_are_read_by_name():
    """The rule finds its entries through the observation's layout (v2 adds entries before the last two)."""
    env = make_env(ENV)
    pol = ladder.build("recovery_reset", env)
    layout = env.unwrapped.observation_layout
    assert [layout.names[i] for i in pol._entries] == list(pol.start_table.names)
    assert [layout.names[i] for i in pol._entries1] == list(pol.first_step.names1)
    with pytest.raises(ValueError, match="temper"):
        type(pol)(env.unwrapped, temper=0.0)
    with pytest.raises(ValueError, match="phases_per_gain"):
        FirstStepUpdate(env.unwrapped, pol.start_table, phases_per_gain=0)
    env.close()


def test_probe_is_skipped_only_when_the_posterior_is_sharp():
    """After the dip the unbalance probe runs while the posterior sd of ln g is >= probe_sd (0.06), and
    is skipped below; probe_sd = 0 probes always, as recovery."""
    env = make_env(ENV)
    pol = ladder.build("recovery_reset", env)
    m = pol._new_memory()
    assert pol._wants_probe(m)  # the prior: sd 0.32
    lg = np.log(m.post.gains)
    m.post.log_w = -0.5 * ((lg - lg[20]) / 0.02) ** 2  # sd ~0.02
    assert not pol._wants_probe(m)
    m.post.log_w = -0.5 * ((lg - lg[20]) / 0.1) ** 2  # sd ~0.1
    assert pol._wants_probe(m)
    m.post.log_w = -0.5 * ((lg - lg[20]) / 0.02) ** 2
    always = type(pol)(env.unwrapped, probe_sd=0.0, first_step=False)
    assert always._wants_probe(m) and always.first_step is None
    env.close()
