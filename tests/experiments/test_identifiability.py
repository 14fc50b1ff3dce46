"""``python -m gfb_experiments.identifiability`` (issue 19 s.3): the regressor, the features, the channels and
the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gfb_experiments.identifiability import (
    CHANNELS,
    FeatureBuilder,
    History,
    ProbingSchedule,
    RidgeCV,
    channel_rows,
    info_paths,
    main,
)


def _history(steps: int = 4, n_obs: int = 6, seed: int = 0, ended: int | None = None) -> History:
    rng = np.random.default_rng(seed)
    taken = steps if ended is None else ended
    obs = rng.uniform(0.1, 1.0, (taken + 1, n_obs))
    rewards = rng.normal(size=taken)
    info = [
        {"damping_gain": 1.7, "speed_rpm": 27000.0 + j, "shocks[0].peak_g": 3.0} for j in range(taken + 1)
    ]
    return History(obs, rewards, info, taken)


def test_the_ridge_recovers_a_known_linear_target():
    rng = np.random.default_rng(1)
    # uniform features: the evaluation rows lie inside the training range (the regressor clips to it)
    X = rng.uniform(-1, 1, size=(200, 8)) * np.array([1, 10, 0.1, 3, 1, 1, 1, 1])
    beta = np.array([0.5, -0.02, 4.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    y = X @ beta + 2.0 + 0.01 * rng.normal(size=200)
    reg = RidgeCV().fit(X[:150], y[:150])
    pred = reg.predict(X[150:])
    assert np.sqrt(np.mean((pred - y[150:]) ** 2)) < 0.03  # the noise is 0.01; the target's sd ~0.7
    assert reg.alpha == min(reg.alphas)  # no noise to shrink against: the smallest penalty wins


def test_the_ridge_shrinks_pure_noise_to_the_mean():
    # more features than episodes and nothing to learn (the report's situation for a channel that tells
    # nothing): cross-validation keeps the prediction near the mean, no worse than the prior (sd 1)
    for seed in range(4):
        rng = np.random.default_rng(seed)
        X, y = rng.normal(size=(150, 300)), rng.normal(size=150)
        pred = RidgeCV().fit(X, y).predict(rng.normal(size=(400, 300)))
        yn = rng.normal(size=400)
        assert np.sqrt(np.mean((pred - yn) ** 2)) < 1.15 * np.std(yn) and np.std(pred) < 0.3


def test_the_ridge_does_not_extrapolate_and_the_logs_have_a_floor():
    # an evaluation episode outside the training range (seen on WhirlRecovery-v1 under the rule, k = 20:
    # rms 4.5 in ln g from unclipped features) predicts like the nearest training episodes
    rng = np.random.default_rng(4)
    X = rng.uniform(0, 1, (100, 2))
    y = 3 * X[:, 0]
    reg = RidgeCV().fit(X, y)
    assert abs(reg.predict(np.array([[1e6, 0.5]]))[0] - 3.0) < 0.1
    rows = [np.full((2, 1), 2.0), np.full((2, 1), 5.0)]
    fb = FeatureBuilder(1).fit(rows)
    assert np.allclose(fb.transform([np.zeros((2, 1))])[0, -2:], math.log(2.0))


def test_constant_features_are_dropped_and_a_featureless_fit_predicts_the_mean():
    X = np.ones((10, 3))
    y = np.arange(10.0)
    reg = RidgeCV().fit(X, y)
    assert np.allclose(reg.predict(np.zeros((2, 3))), 4.5)


def test_the_feature_builder_shapes_and_logs():
    h = _history(steps=4)
    rows = [channel_rows(h, "obs", 4)]
    assert rows[0].shape == (5, 7)  # n_obs + the alive column
    for k in (0, 1, 4):
        fb = FeatureBuilder(k).fit(rows)
        X = fb.transform(rows)
        d = rows[0].shape[1]
        # entries (k+1) d, differences k d, logs of the positive entries (all obs here and alive = 1)
        assert X.shape == (1, (k + 1) * d + k * d + (k + 1) * d) == (1, fb.n_features(d))
        assert np.allclose(X[0, -(k + 1) * d :], np.log(rows[0][: k + 1].ravel()))
    with pytest.raises(ValueError, match="k"):
        FeatureBuilder(-1)
    with pytest.raises(ValueError, match="rows"):
        FeatureBuilder(6).fit(rows)


def test_the_rows_of_each_channel_and_the_padding_of_an_ended_episode():
    h = _history(steps=5, ended=2)
    paths = info_paths([h])
    assert paths == ["damping_gain", "shocks[0].peak_g", "speed_rpm"]
    obs = channel_rows(h, "obs", 5)
    obr = channel_rows(h, "obs_reward", 5)
    inf = channel_rows(h, "info", 5, paths)
    assert obs.shape == (6, 7) and obr.shape == (6, 8) and inf.shape == (6, 4)
    assert np.array_equal(obs[:, -1], [1, 1, 1, 0, 0, 0])  # alive, then padded
    assert np.array_equal(obs[3:, :-1], np.repeat(h.obs[2:3], 3, axis=0))  # the last row repeated
    assert np.array_equal(obr[:, -2], np.r_[0.0, h.rewards, 0.0, 0.0, 0.0])  # no reward at reset
    assert np.array_equal(inf[:, 0], np.full(6, 1.7))
    with pytest.raises(ValueError, match="channel"):
        channel_rows(h, "privileged", 5)


def test_the_channels_never_mix():
    a = _history(seed=3)
    b = History(a.obs, a.rewards, [{k: v * 7 + 1 for k, v in row.items()} for row in a.info], a.steps)
    c = History(a.obs * 2, -a.rewards, a.info, a.steps)
    paths = info_paths([a])
    for ch in ("obs", "obs_reward"):  # the sensors' channels do not read info
        assert np.array_equal(channel_rows(a, ch, 4, paths), channel_rows(b, ch, 4, paths))
    assert np.array_equal(channel_rows(a, "info", 4, paths), channel_rows(c, "info", 4, paths))
    # the obs channel does not read the reward either, the obs_reward channel does
    d = History(a.obs, a.rewards + 5, a.info, a.steps)
    assert np.array_equal(channel_rows(a, "obs", 4), channel_rows(d, "obs", 4))
    assert not np.array_equal(channel_rows(a, "obs_reward", 4), channel_rows(d, "obs_reward", 4))


def test_the_probing_schedule_is_fixed_and_holds_its_last_block():
    s = ProbingSchedule(((2, 0.0, 0.3), (1, -1.0, 7.0)))
    assert [s.command(k) for k in range(5)] == [(0.0, 0.3), (0.0, 0.3), (-1.0, 7.0), (-1.0, 7.0), (-1.0, 7.0)]
    with pytest.raises(ValueError, match="blocks"):
        ProbingSchedule(((0, 0.0, 1.0),))


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_a_smoke_run_writes_the_report(tmp_path, capsys):
    out = tmp_path / "ident"
    args = ["--tasks", "gfb_env/WhirlRecovery-v1", "--ks", "0,1", "--train", "5", "--eval", "2"]
    args += ["--rule", "gfb_env/WhirlRecovery-v1=recovery"]  # the default, named per task
    assert main([*args, "--out", str(out)]) == 0
    rep = json.loads((out / "WhirlRecovery-v1.json").read_text())
    assert rep["task"] == "gfb_env/WhirlRecovery-v1" and rep["ks"] == [0, 1]
    assert rep["policies"]["rule"] == "recovery"
    assert rep["targets"] == ["ln_g"] and "ln_lambda_best" in rep["constant_targets"]
    assert math.isclose(rep["reference"]["ln_g"]["var"], math.log(3.0) ** 2 / 12)  # log-uniform [0.6, 1.8]
    keys = {(r["policy"], r["channel"], r["k"]) for r in rep["rows"]}
    assert keys == {(p, c, k) for p in ("probe", "rule") for c in CHANNELS for k in (0, 1)}
    assert all("rule_rms" in r for r in rep["rows"] if r["policy"] == "rule")
    assert all(math.isfinite(r["rms"]) for r in rep["rows"])
    assert rep["train_seeds"][0] >= 1_990_000 and 2_990_000 <= rep["eval_seeds"][0] < 3_000_000
    md = (out / "summary.md").read_text()
    assert "## gfb_env/WhirlRecovery-v1" in md and "| WhirlRecovery-v1 | rule | info | 1 |" in md
    assert (out / "identifiability.png").stat().st_size > 1000
    assert "WhirlRecovery-v1" in capsys.readouterr().out
    # the summary remade from the JSONs alone (a later run on other ids adds its tasks to these)
    (out / "summary.md").unlink()
    assert main(["--summary-only", "--out", str(out)]) == 0
    assert (out / "summary.md").read_text() == md
    with pytest.raises(SystemExit) as exc:
        main(["--summary-only", "--out", str(tmp_path / "empty")])
    assert exc.value.code == 2 and "no task report" in capsys.readouterr().err


@pytest.mark.parametrize(
    "args, word",
    [
        (["--tasks", "gfb_env/Nope-v9"], "--tasks"),
        (["--tasks", "gfb_env/RunUp-v0"], "--tasks"),
        (["--ks", "0,-1"], "--ks"),
        (["--ks", "one"], "--ks"),
        (["--train", "2"], "--train"),
        (["--jobs", "3"], "--jobs"),
        (["--policies", "probe,oracle"], "--policies"),
        (["--rule", "no_such_rule"], "--rule"),
        (["--rule", "gfb_env/RunUp-v1=no_such_rule"], "--rule"),
        (["--tasks", "gfb_env/RunUp-v1", "--rule", "gfb_env/WhirlRecovery-v1=recovery"], "not in --tasks"),
    ],
)
def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys, args, word):
    with pytest.raises(SystemExit) as exc:
        main([*args, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0]
    assert not (tmp_path / "o").exists()  # refused before any work


def test_the_rules_posterior_accessors_read_the_episode_memory():  # on the current task
    import gymnasium as gym

    from gfb_agents.ladder import build

    env = gym.make("gfb_env/WhirlRecovery-v2")
    rule = build("recovery", env)
    assert rule.gain_posterior() is None and rule.bearing_estimate() is None  # before the first step
    obs, _ = env.reset(seed=5)
    rule.predict(obs, episode_start=True)
    post = rule.gain_posterior()
    assert post is rule._mem[0].post and math.isclose(float(post.weights.sum()), 1.0)
    assert post.gains.min() >= 0.6 - 1e-12 and post.gains.max() <= 1.8 + 1e-12  # the task's prior
    assert rule.bearing_estimate() is None  # the nominal bearing: nothing to identify
    env.close()
