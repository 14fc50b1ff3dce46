"""The benchmark's method: seed splits, the ladder registry, per-episode normalisation and the rliable
statistics (on synthetic score matrices with known answers)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from gfb_agents import seeds
from gfb_experiments.benchmark_stats import interval_estimates, iqm, normalized_scores


# ------------------------------------------------------------------------------------------ seeds
def test_seed_splits_are_disjoint_and_documented():
    ranges = [seeds.TRAIN, seeds.VALIDATION, seeds.TEST, seeds.LEGACY_V0, seeds.DEV]
    for a, b in itertools.combinations(ranges, 2):
        assert not a.overlaps(b), (a, b)
        assert not set(range(a.start, min(a.stop, a.start + 1000))) & set(
            range(b.start, min(b.stop, b.start + 1000))
        )
    assert len(seeds.TEST) >= seeds.MIN_TEST_EPISODES
    # the seeds used earlier in the project are not test or validation seeds
    for s in [*range(150), *range(10_000, 10_050), *range(20_000, 20_020)]:
        assert s not in seeds.TEST and s not in seeds.VALIDATION and s not in seeds.TRAIN
    assert seeds.split_seeds("test", 3) == [seeds.TEST.start, seeds.TEST.start + 1, seeds.TEST.start + 2]
    with pytest.raises(ValueError, match="split"):
        seeds.split_seeds("train", 3)  # training seeds never go to the benchmark
    with pytest.raises(ValueError, match="legacy_v0"):
        seeds.split_seeds("legacy_v0", 51)


def test_training_env_seeds_stay_in_train_and_never_repeat():
    got = {
        seeds.train_env_seed(r, i, k)
        for r in (0, 1, seeds.MAX_TRAIN_RUNS - 1)
        for i in (0, 1, seeds.MAX_TRAIN_ENVS - 1)
        for k in (0, 1, seeds.MAX_TRAIN_SESSIONS - 1)
    }
    assert len(got) == 27 and all(s in seeds.TRAIN for s in got)
    with pytest.raises(ValueError, match="env_index"):
        seeds.train_env_seed(0, seeds.MAX_TRAIN_ENVS)
    with pytest.raises(ValueError, match="run"):
        seeds.train_env_seed(-1, 0)


# ---------------------------------------------------------------------------------- normalisation
def test_normalisation_is_exact_on_constructed_returns():
    naive = np.array([10.0, -5.0, 0.0, 3.0])  # mean 2
    oracle = np.array([50.0, 15.0, 40.0, 13.0])  # mean 29.5: the scale is 27.5
    frac = np.array([[0.0, 0.5, 1.0, -0.25], [0.3, 0.3, 0.3, 0.3]])
    ret = 2.0 + frac * 27.5
    s, info = normalized_scores(ret, naive, oracle)
    np.testing.assert_allclose(s, frac, rtol=0, atol=1e-12)
    assert info["mean_gap"] == 27.5 and info["oracle_lost_seeds"] == 0 and not info["no_headroom"]
    s_n, _ = normalized_scores(naive, naive, oracle)
    s_o, _ = normalized_scores(oracle, naive, oracle)
    assert np.mean(s_n) == pytest.approx(0.0) and np.mean(s_o) == pytest.approx(1.0)
    # the mean score is the normalised mean return (so both rank agents alike)
    r = np.array([12.0, 0.0, 30.0, 5.0])
    assert np.mean(normalized_scores(r, naive, oracle)[0]) == pytest.approx((r.mean() - 2.0) / 27.5)


def test_normalisation_survives_a_tie_on_one_seed_and_flags_no_headroom():
    naive = np.array([0.0, 0.0, 0.0, 0.0, 0.0])
    oracle = np.array([10.0, 10.0, 10.0, 10.0, 0.001])  # the last seed: a tie
    s, info = normalized_scores(np.array([5.0, 5.0, 5.0, 5.0, 0.5]), naive, oracle)
    # on the task's scale (mean gap 8.0002), not 0.5 / 0.001 = 500 on the tied seed
    np.testing.assert_allclose(s, np.array([5.0, 5.0, 5.0, 5.0, 0.5]) / 8.0002)
    s, info = normalized_scores(np.array([1.0, 2.0]), np.array([5.0, 5.0]), np.array([4.0, 5.0]))
    assert info["no_headroom"] and info["oracle_lost_seeds"] == 1 and np.isnan(s).all()
    tie = np.array([58.9, 58.9, 58.9])
    s, info = normalized_scores(tie, tie, tie + 1e-12)  # a tie up to rounding: no scale
    assert info["no_headroom"] and np.isnan(s).all()
    with pytest.raises(ValueError, match="episodes"):
        normalized_scores(np.zeros(3), np.zeros(4), np.ones(4))


# ------------------------------------------------------------------------------------- statistics
def test_iqm_of_a_known_matrix():
    # 8 values: the IQM drops the lowest and highest two and averages the middle four
    x = np.array([[-100.0, 0.0, 1.0, 2.0], [3.0, 4.0, 5.0, 100.0]])
    assert iqm(x) == pytest.approx(np.mean([1.0, 2.0, 3.0, 4.0]))
    est = interval_estimates(x, reps=2000)
    assert est["iqm"] == pytest.approx(2.5) and est["mean"] == pytest.approx(np.mean(x))
    assert est["iqm_low"] <= est["iqm"] <= est["iqm_high"]


def test_bootstrap_ci_covers_the_truth_and_is_reproducible():
    """Normal scores with known mean: the 95 % CI of the IQM (= the mean of a symmetric law) holds the
    truth in about 95 % of independent synthetic benchmarks, and shrinks with more episodes."""
    rng = np.random.default_rng(7)
    truth, hits, widths = 0.4, 0, []
    for _ in range(40):
        x = truth + 0.3 * rng.standard_normal((1, 100))
        est = interval_estimates(x, reps=500)
        hits += est["iqm_low"] <= truth <= est["iqm_high"]
        widths.append(est["iqm_high"] - est["iqm_low"])
    assert hits >= 34  # P(X >= 34 | Bin(40, 0.95)) > 0.99
    wide = interval_estimates(truth + 0.3 * rng.standard_normal((1, 25)), reps=1000)
    assert wide["iqm_high"] - wide["iqm_low"] > np.mean(widths)
    x = truth + 0.3 * rng.standard_normal((1, 100))
    assert interval_estimates(x, reps=500) == interval_estimates(x, reps=500)  # seeded


def test_bootstrap_over_training_seeds_includes_their_spread():
    """Five training seeds whose means differ: resampling the seeds widens the interval beyond the
    within-seed (episode) bootstrap; a seed-level shift is not hidden by many episodes."""
    rng = np.random.default_rng(3)
    seed_means = np.array([0.0, 0.2, 0.4, 0.6, 0.8])
    x = seed_means[:, None] + 0.05 * rng.standard_normal((5, 200))
    est = interval_estimates(x, reps=2000)
    assert est["mean"] == pytest.approx(x.mean())
    assert est["mean_high"] - est["mean_low"] > 0.2  # seed spread (~0.28 / sqrt 5 x 2 x 1.96 ~ 0.5)
    one = interval_estimates(x[2], reps=2000)
    assert one["mean_high"] - one["mean_low"] < 0.05


def test_profile_equals_rliables_score_distribution(tmp_path):
    from rliable import library as rly

    from gfb_experiments.benchmark_stats import _score_distribution, performance_profile_png

    x = np.random.default_rng(1).normal(size=(3, 40))
    x[0, :5] = 0.25  # ties at a threshold
    taus = np.linspace(-2, 2, 17)
    np.testing.assert_allclose(_score_distribution(x, taus), rly.score_distributions(x, taus), atol=1e-12)
    p = performance_profile_png({"a": x, "b": x + 0.5, "nan": np.full((1, 4), np.nan)}, tmp_path / "p.png")
    assert p is not None and p.stat().st_size > 5_000
    assert performance_profile_png({"nan": np.full((1, 4), np.nan)}, tmp_path / "q.png") is None


def test_statistics_refuse_bad_input_and_pass_nan_through():
    with pytest.raises(ValueError, match="reps"):
        interval_estimates(np.zeros((1, 5)), reps=10)
    with pytest.raises(ValueError, match="scores"):
        interval_estimates(np.zeros((0, 0)))
    est = interval_estimates(np.array([[0.1, math.nan, 0.3]]))
    assert all(math.isnan(v) for v in est.values())


# ------------------------------------------------------------------------------------------ ladder
def test_every_task_has_one_naive_and_one_oracle_and_kinds_are_valid():
    from gfb_agents import ladder

    assert ladder.V1_TASKS and ladder.V2_TASKS
    for task in ladder.V2_TASKS + ladder.V1_TASKS:  # the current tasks, and the retired ones' record
        entries = ladder.ladder_for(task)
        assert ladder.naive_for(task).name == "naive" and ladder.oracle_for(task) is not None, task
        assert all(e.kind in ladder.KINDS for e in entries)
        kinds = [e.kind for e in entries]
        assert kinds == sorted(kinds, key=ladder.KINDS.index)  # ladder order
        # the rules of gfb_agents.rules
        assert sum(k == "rule" for k in kinds) >= 2, task


def test_register_refuses_duplicates_and_bad_entries_and_scoped_undoes():
    from gfb_agents import ladder

    e = ladder.AgentEntry("test_rule", "rule", ("gfb_env/RunUp-v1",), ladder.make_naive)
    with ladder.scoped():
        ladder.register(e)
        assert "test_rule" in ladder.registered()
        with pytest.raises(ValueError, match="already registered"):
            ladder.register(e)
        ladder.register(e, replace=True)
        # a second naive agent for the task is an error where the benchmark asks for it
        ladder.register(ladder.AgentEntry("naive2", "naive", ("gfb_env/RunUp-v1",), ladder.make_naive))
        with pytest.raises(ValueError, match="2 naive agents"):
            ladder.naive_for("gfb_env/RunUp-v1")
    assert "test_rule" not in ladder.registered() and "naive2" not in ladder.registered()
    with pytest.raises(ValueError, match="kind"):
        ladder.AgentEntry("x", "scripted", ("t",), ladder.make_naive)
    with pytest.raises(ValueError, match="run_paths"):
        ladder.AgentEntry("x", "learned", ("t",))
    with pytest.raises(ValueError, match="factory"):
        ladder.AgentEntry("x", "rule", ("t",))
    with pytest.raises(ValueError, match="name"):
        ladder.AgentEntry("a|b", "rule", ("t",), ladder.make_naive)


def test_a_v1_reference_supersedes_the_builtin_on_its_tasks_only():
    from gfb_agents import ladder

    assert ladder.oracle_for(ladder.V2_TASKS[0]).name == "oracle_v1"
    with ladder.scoped():
        ladder.register(
            ladder.AgentEntry("my_oracle", "oracle", ladder.V2_TASKS[:1], ladder.make_commanded_oracle),
            supersede=True,
        )
        assert ladder.oracle_for(ladder.V2_TASKS[0]).name == "my_oracle"
        for t in ladder.V2_TASKS[1:] + ladder.V1_TASKS:
            assert ladder.oracle_for(t).name == "oracle_v1"
        ladder.set_tasks("margin_search", [])
        assert "margin_search" not in ladder.registered()
    assert ladder.oracle_for(ladder.V2_TASKS[0]).name == "oracle_v1"
    assert "margin_search" in ladder.registered()


def test_naive_ramp_reads_the_speed_command_where_the_task_has_one():
    import gymnasium as gym

    from gfb_agents import ladder
    from gfb_agents.nominal_map import NominalMap
    from gfb_agents.policy import ControlSpec

    env = gym.make("gfb_env/RunUp-v2")
    nmap = NominalMap.from_env(env)
    spec = ControlSpec.from_env(env, nmap)

    class CommandedLayout:  # the v1 layout's interface: has() and the command decoder
        def __init__(self, inner, cmd_rpm):
            self.inner, self.cmd_rpm = inner, cmd_rpm

        def has(self, name):
            return name == "speed_command"

        def speed_command_rpm(self, obs):
            return self.cmd_rpm

        def __getattr__(self, k):
            return getattr(self.inner, k)

    for cmd, expect in ((30_000.0, 30_000.0), (60_000.0, None)):
        agent = ladder.NaiveRampAgent(
            dataclasses.replace(spec, observations=CommandedLayout(spec.observations, cmd)), nmap
        )
        cap = nmap.rpm(0.95 * nmap.critical_at(1.0))
        assert agent.setpoint_rpm(np.zeros(16)) == pytest.approx(expect if expect is not None else cap)
    env.close()


def test_naive_ramp_holds_below_lambda_c_of_damping_one():
    import gymnasium as gym

    from gfb_agents import ladder
    from gfb_agents.nominal_map import NominalMap

    env = gym.make("gfb_env/RunUp-v2")
    nmap = NominalMap.from_env(env)
    agent = ladder.make_naive(env)
    assert agent.kind == "scripted" and agent.damping == 1.0
    cap = nmap.rpm(0.95 * nmap.critical_at(1.0))
    obs, _ = env.reset(seed=seeds.DEV.start)
    cmd = agent.spec.observations.speed_command_rpm(obs)
    assert agent.setpoint_rpm(obs) == pytest.approx(min(cap, cmd))
    a, _ = agent.predict(obs, episode_start=True)
    assert a[0] == pytest.approx(1.0)  # full motor rate from the start speed
    assert env.unwrapped.damping_from_action(float(a[1])) == pytest.approx(1.0, rel=1e-6)
    env.close()


def test_learned_entries_find_single_and_multi_seed_folders(tmp_path):
    import json

    from gfb_agents import ladder

    one = tmp_path / "RunUp_ppo"
    one.mkdir()
    (one / "model.zip").write_bytes(b"")
    (one / "run.json").write_text(json.dumps({"env_id": "gfb_env/RunUp-v1", "algo": "ppo"}))
    multi = tmp_path / "RunUp_sac5"
    for k in range(3):
        d = multi / f"seed{k}" / "best"
        d.mkdir(parents=True)
        (d / "model.zip").write_bytes(b"")
        (d.parent / "run.json").write_text(json.dumps({"env_id": "gfb_env/RunUp-v1", "algo": "sac"}))
    (tmp_path / "empty").mkdir()
    got = {e.name: e for e in ladder.learned_entries(tmp_path)}
    assert set(got) == {"RunUp_ppo", "RunUp_sac5"}
    assert got["RunUp_ppo"].runs == 1 and got["RunUp_ppo"].tasks == ("gfb_env/RunUp-v1",)
    assert got["RunUp_sac5"].runs == 3 and got["RunUp_sac5"].tasks == ("gfb_env/RunUp-v1",)
    with pytest.raises(FileNotFoundError):
        ladder.register_learned(tmp_path / "empty")


# ------------------------------------------------------------------------- the table from episodes
def test_table_rows_from_constructed_episodes():
    """reduce_results on hand-made episodes: per-seed normalisation, one row per agent, learned agents
    stratified by training seed."""
    from gfb_agents import ladder
    from gfb_agents.learned.evaluate import EpisodeResult
    from gfb_experiments.benchmark_agents import Chunk, reduce_results

    task = "gfb_env/RunUp-v1"
    sd = seeds.split_seeds("test", 8)
    naive_r = np.linspace(-10.0, 4.0, 8)
    oracle_r = naive_r + np.linspace(20.0, 40.0, 8)

    def episodes(ss, rets):
        return [
            dataclasses.asdict(
                EpisodeResult(s, float(r), 10, r > 0, None, True, math.nan, 1.0, True, 0.0, False)
            )
            for s, r in zip(ss, rets, strict=True)
        ]

    entries = {
        "naive": ladder.naive_for(task),
        "oracle": ladder.oracle_for(task),
        "half": ladder.AgentEntry("half", "rule", (task,), ladder.make_naive),
        "learn": ladder.AgentEntry("learn", "learned", (task,), run_paths=("a", "b")),
    }
    frac = {"naive": [0.0], "oracle": [1.0], "half": [0.5], "learn": [0.2, 0.6]}
    chunks, results = [], {}
    for name, e in entries.items():
        for run, f in enumerate(frac[name]):
            for i in (0, 4):
                c = Chunk(task, e, run, tuple(sd[i : i + 4]), "test", {}, None)
                # an agent at f on the task's scale (naive mean + f x (oracle mean - naive mean)), every
                # episode the same; naive and oracle vary over the seeds
                ref = naive_r.mean() + f * (oracle_r.mean() - naive_r.mean()) + 0 * naive_r
                rets = {"naive": naive_r, "oracle": oracle_r}.get(name, ref)[i : i + 4]
                chunks.append(c)
                results[c] = {"episodes": episodes(c.seeds, rets), "wall_s": 1.0}
    rows, per_task, _ = reduce_results(chunks, results, reps=500)
    by = {r["agent"]: r for r in rows}
    assert [r["kind"] for r in rows] == ["naive", "rule", "oracle", "learned"]
    assert by["naive"]["normalized_iqm"] == pytest.approx(0.0)
    assert by["oracle_v1"]["normalized_iqm"] == pytest.approx(1.0)
    assert by["half"]["normalized_iqm"] == pytest.approx(0.5)
    assert by["half"]["normalized_ci_low"] == pytest.approx(0.5)  # no spread, no interval
    assert by["learn"]["normalized_score"] == pytest.approx(0.4) and by["learn"]["training_seeds"] == 2
    assert by["learn"]["normalized_ci_low"] < 0.4 < by["learn"]["normalized_ci_high"]
    assert by["half"]["mean_return"] == pytest.approx(np.mean(naive_r + 0.5 * (oracle_r - naive_r)))
    assert by["half"]["wall_s"] == 2.0 and by["half"]["episodes"] == 8
    assert per_task[task]["oracle_lost_seeds"] >= 0
    np.testing.assert_allclose(per_task[task]["agents"]["learn"]["normalized"], [[0.2] * 8, [0.6] * 8])
    assert [r["path"] for r in per_task[task]["agents"]["learn"]["training"]] == ["a", "b"]
    assert per_task[task]["agents"]["half"]["training"] == []


def test_chunks_on_a_dask_cluster_equal_the_local_run_and_are_cached(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    from gfb_agents import ladder
    from gfb_experiments.benchmark_agents import plan, run_chunks

    kw = {"gfb_env/RunUp-v1": {"max_episode_steps": 4}}
    with ladder.scoped():
        chunks = plan(["gfb_env/RunUp-v1"], "validation", 2, 1, {"naive"}, kw)
    # naive, hold and oracle always play (they define the normalisation's zero and one)
    assert {c.entry.name for c in chunks} == {"naive", "hold", "oracle_v1"} and len(chunks) == 6
    assert all(s in seeds.VALIDATION for c in chunks for s in c.seeds)
    local = run_chunks(chunks, tmp_path / "local", progress=False)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cl:
        remote = run_chunks(chunks, tmp_path / "dask", scheduler=cl, progress=False)
    for c in chunks:
        a = [e["episode_return"] for e in local[c]["episodes"]]
        b = [e["episode_return"] for e in remote[c]["episodes"]]
        assert a == b and len(a) == 1
    assert len(list((tmp_path / "dask").rglob("run0_*.json"))) == 6
