"""Issue 19's statistics: each aggregate normalised by its own statistic, the zero the better of naive and
hold, the paired headroom in the table and its CSV, the vectorised bootstrap equal to rliable's, learned
agents skipped (and said so) on a task without any, and the chunk cache resuming a 200-seed run."""

from __future__ import annotations

import csv
import dataclasses
import math

import numpy as np
import pytest

from gfb_agents import ladder, seeds
from gfb_agents.learned.evaluate import EpisodeResult
from gfb_env.envs import make_env
from gfb_experiments import benchmark_agents as bench
from gfb_experiments.benchmark_stats import (
    _seeded_global_rng,
    interval_estimates,
    iqm,
    normalized_scores,
    paired_headroom,
    reference_plan,
    rescale_estimates,
)

TASK = "gfb_env/RunUp-v1"
#: the issue's columns of benchmark_headroom.csv, literally
ISSUE_COLUMNS = [
    "task",
    "best_rule",
    "test_seeds",
    "headroom_iqm",
    "headroom_ci_low",
    "headroom_ci_high",
    "headroom_mean",
    "headroom_mean_ci_low",
    "headroom_mean_ci_high",
]


def _episodes(ss, rets):
    return [
        dataclasses.asdict(EpisodeResult(s, float(r), 10, r > 0, None, True, math.nan, 1.0, True, 0.0, False))
        for s, r in zip(ss, rets, strict=True)
    ]


def _table(returns: dict[str, np.ndarray], n: int, reps: int = 500, normalise: str = "consistent"):
    """reduce_results on hand-made episodes of ``TASK``: ``returns`` name -> per-seed returns; names other
    than naive / hold / oracle_v1 are rules."""
    sd = seeds.split_seeds("test", n)
    entries = {
        "naive": ladder.naive_for(TASK),
        "hold": bench.hold_for(TASK),
        "oracle_v1": ladder.oracle_for(TASK),
    }
    chunks, results = [], {}
    for name, rets in returns.items():
        e = entries.get(name) or ladder.AgentEntry(name, "rule", (TASK,), ladder.make_naive)
        for i in range(0, n, 10):
            c = bench.Chunk(TASK, e, 0, tuple(sd[i : i + 10]), "test", {}, None)
            chunks.append(c)
            results[c] = {"episodes": _episodes(c.seeds, rets[i : i + 10]), "wall_s": 0.1}
    rows, per_task, _ = bench.reduce_results(chunks, results, reps=reps, normalise=normalise)
    return {r["agent"]: r for r in rows}, rows, per_task


def _returns(n: int = 40, seed: int = 0) -> dict[str, np.ndarray]:
    g = np.random.default_rng(seed)
    crash = g.random(n) < 0.3  # the naive ramp's touchdowns: its mean far below its IQM
    naive = np.where(crash, -100.0, g.normal(15.0, 3.0, n))
    hold = g.normal(-2.0, 0.2, n)
    oracle = g.normal(88.0, 4.0, n) - 60.0 * (g.random(n) < 0.08)
    rule = 0.5 * oracle + g.normal(20.0, 5.0, n)
    return {"naive": naive, "hold": hold, "oracle_v1": oracle, "rule": rule}


def test_each_aggregate_puts_its_reference_at_exactly_0_and_the_oracle_at_exactly_1():
    by, _, per_task = _table(_returns(), 40)
    info = per_task[TASK]
    z_iqm, z_mean = info["reference"], info["reference_mean"]
    assert (z_iqm, z_mean) == ("naive", "hold")  # naive's IQM beats hold's; its crashes sink its mean
    assert by[z_iqm]["normalized_iqm"] == pytest.approx(0.0, abs=1e-12)
    assert by["oracle_v1"]["normalized_iqm"] == pytest.approx(1.0, abs=1e-12)
    assert by[z_mean]["normalized_score"] == pytest.approx(0.0, abs=1e-12)
    assert by["oracle_v1"]["normalized_score"] == pytest.approx(1.0, abs=1e-12)
    # the v1 table's way (means for both) leaves the oracle's IQM off 1: the inconsistency removed
    old, _, _ = _table(_returns(), 40, normalise="mean")
    assert abs(old["oracle_v1"]["normalized_iqm"] - 1.0) > 0.01
    assert all(r["reference"] == z_iqm and r["reference_mean"] == z_mean for r in by.values())
    # the intervals are the normalised scores' own (the returns' bootstrap mapped by the fixed scale)
    s = np.asarray(info["agents"]["rule"]["normalized"])
    est = interval_estimates(s, reps=500)
    assert by["rule"]["normalized_ci_low"] == pytest.approx(est["iqm_low"], abs=1e-9)
    assert by["rule"]["normalized_ci_high"] == pytest.approx(est["iqm_high"], abs=1e-9)
    sm = np.asarray(info["agents"]["rule"]["normalized_mean"])
    est_m = interval_estimates(sm, reps=500)
    assert by["rule"]["normalized_mean_ci_low"] == pytest.approx(est_m["mean_low"], abs=1e-9)


def test_hold_is_the_zero_where_it_beats_the_naive_ramp():
    r = _returns()
    r["hold"] = r["hold"] + 40.0  # holding scores above the naive ramp by IQM and by mean
    by, _, per_task = _table(r, 40)
    assert per_task[TASK]["reference"] == "hold" and per_task[TASK]["reference_mean"] == "hold"
    assert by["hold"]["normalized_iqm"] == pytest.approx(0.0, abs=1e-12)
    assert by["hold"]["normalized_score"] == pytest.approx(0.0, abs=1e-12)
    assert by["naive"]["normalized_iqm"] < 0.0 and by["naive"]["reference"] == "hold"


def test_reference_plan_chooses_by_the_aggregate_being_normalised():
    naive = np.array([-100.0] + [20.0] * 7)  # IQM 20, mean 5
    hold = np.full(8, 8.0)  # IQM 8, mean 8
    p = reference_plan({"naive": naive, "hold": hold})
    assert p == {
        "iqm": {"reference": "naive", "statistic": "iqm"},
        "mean": {"reference": "hold", "statistic": "mean"},
    }
    assert reference_plan({"naive": naive, "hold": hold}, "mean")["iqm"] == {
        "reference": "hold",
        "statistic": "mean",
    }
    assert reference_plan({"naive": hold, "hold": hold.copy()})["iqm"]["reference"] == "naive"  # tie
    with pytest.raises(ValueError, match="normalise must be one of"):
        reference_plan({"naive": naive}, "median")


def test_identical_agents_have_zero_headroom_and_their_ci_contains_0():
    r = _returns()
    r["twin"] = r["oracle_v1"].copy()  # a rule that plays exactly as the oracle
    _, _, per_task = _table(r, 40)
    h = per_task[TASK]["headroom"]
    assert h["best_rule"] == "twin"
    for k in ("iqm", "mean"):
        assert h[k] == pytest.approx(0.0, abs=1e-12)
        assert h[f"{k}_low"] <= 0.0 <= h[f"{k}_high"]
    assert not h["established"]


def test_the_mean_headroom_is_on_the_mean_scale():
    g = np.random.default_rng(4)
    o, r = g.normal(1.0, 0.1, 50), g.normal(0.6, 0.1, 50)
    h = paired_headroom(o, r, reps=500, oracle_mean=2.0 * o, rule_mean=2.0 * r)
    ref = paired_headroom(o, r, reps=500)
    assert h["iqm"] == ref["iqm"] and h["iqm_low"] == ref["iqm_low"]
    assert h["mean"] == pytest.approx(2.0 * ref["mean"]) and h["mean_low"] == pytest.approx(
        2.0 * ref["mean_low"]
    )
    with pytest.raises(ValueError, match="both or neither"):
        paired_headroom(o, r, oracle_mean=o)


def test_paired_ci_is_narrower_than_unpaired_for_a_known_difference():
    g = np.random.default_rng(9)
    hard = g.normal(0.0, 1.0, 200)  # a shared per-seed difficulty
    rule, oracle = hard + g.normal(0, 0.05, 200), hard + 0.3 + g.normal(0, 0.05, 200)
    p = paired_headroom(oracle, rule, reps=2000)
    u = paired_headroom(oracle, rule, reps=2000, paired=False)
    assert p["mean_low"] < 0.3 < p["mean_high"] and p["iqm_low"] < 0.3 < p["iqm_high"]
    assert p["mean_high"] - p["mean_low"] < 0.2 * (u["mean_high"] - u["mean_low"])


def test_the_headroom_csv_and_the_markdown_table_carry_the_same_numbers(tmp_path):
    r = _returns(n=40)
    _, rows, per_task = _table(r, 40)
    assert bench.write_headroom_csv(per_task, tmp_path / "h.csv")
    with (tmp_path / "h.csv").open() as fh:
        reader = csv.DictReader(fh)
        assert reader.fieldnames[:9] == ISSUE_COLUMNS
        (row,) = list(reader)
    assert row["split"] == "test" and row["best_rule"] == "rule" and row["test_seeds"] == "40"
    assert row["reference"] == "naive" and row["reference_mean"] == "hold"
    md = bench.markdown_table(rows, per_task)
    line = next(x for x in md.splitlines() if x.startswith("| RunUp-v1 | test | naive; hold |"))
    f = {k: float(v) for k, v in row.items() if k.startswith("headroom")}
    want = f"{f['headroom_iqm']:.2f} [{f['headroom_ci_low']:.2f}, {f['headroom_ci_high']:.2f}]"
    assert want in line
    want_m = f"{f['headroom_mean']:.2f} [{f['headroom_mean_ci_low']:.2f}, {f['headroom_mean_ci_high']:.2f}]"
    assert want_m in line
    claim = "| established |" if row["established"] == "True" else "| not established |"
    assert line.endswith(claim)
    assert "each aggregate by its own statistic" in md  # the header says which normalisation


def test_a_claim_needs_both_lower_bounds_at_0_2():
    base = {"iqm_low": 0.25, "mean_low": 0.21}
    assert bench.established(base)
    assert not bench.established({**base, "mean_low": 0.19})
    assert not bench.established({**base, "iqm_low": 0.1999})


def test_vectorised_bootstrap_equals_rliables():
    from rliable import library as rly
    from rliable import metrics

    def agg(y):
        return np.array([metrics.aggregate_iqm(y), metrics.aggregate_mean(y)])

    for shape in ((1, 60), (3, 20)):
        x = np.random.default_rng(2).normal(size=shape)
        x[0, :3] = -50.0
        mine = interval_estimates(x, reps=300)
        with _seeded_global_rng(seeds.BOOTSTRAP_SEED):
            p, c = rly.get_interval_estimates(
                {"a": x.T}, agg, reps=300, confidence_interval_size=0.95, task_bootstrap=shape[0] >= 2
            )
        ref = [p["a"][0], c["a"][0, 0], c["a"][1, 0], p["a"][1], c["a"][0, 1], c["a"][1, 1]]
        np.testing.assert_allclose(list(mine.values()), ref, rtol=0, atol=1e-12)


def test_rescaled_return_intervals_are_the_normalised_scores_intervals():
    g = np.random.default_rng(5)
    ret = np.where(g.random((2, 30)) < 0.2, -100.0, g.normal(10.0, 3.0, (2, 30)))
    ref, orc = g.normal(5.0, 1.0, 30), g.normal(60.0, 5.0, 30)
    s, info = normalized_scores(ret, ref, orc, reference="iqm")
    assert info["reference_zero"] == pytest.approx(iqm(ref))
    a = rescale_estimates(interval_estimates(ret, reps=400), info["reference_zero"], info["reference_gap"])
    b = interval_estimates(s, reps=400)
    for k in a:
        assert a[k] == pytest.approx(b[k], abs=1e-9), k
    assert all(math.isnan(v) for v in rescale_estimates(b, 0.0, 0.0).values())


def test_a_task_without_learned_policies_is_played_without_them_and_the_table_says_so():
    with ladder.scoped():
        ladder.register(ladder.AgentEntry("naive_x", "naive", ("gfb_env/New-v2",), ladder.make_naive))
        notes = bench.learned_notes(["gfb_env/New-v2", TASK])
    assert notes == ["no learned policy is committed for New-v2: learned agents skipped on it"]
    assert bench.learned_notes([TASK]) == []  # RunUp-v1 has committed policies
    _, rows, per_task = _table(_returns(), 20)
    md = bench.markdown_table(rows, per_task, notes)
    assert "Note: no learned policy is committed for New-v2" in md
    assert "| - (none) |" in md  # the best-learned cell of a task without learned rows


def test_the_chunk_cache_resumes_a_200_seed_run_after_an_interruption(tmp_path, monkeypatch):
    chunks = bench.plan([TASK], "test", 200, 10, {"naive"})
    assert {c.entry.name for c in chunks} == {"naive", "hold", "oracle_v1"}  # the scale's agents always
    per_agent = [c for c in chunks if c.entry.name == "naive"]
    assert len(per_agent) == 20 and [s for c in per_agent for s in c.seeds] == seeds.split_seeds("test", 200)
    # extending a 100-seed run to 200 reuses its chunks (same keys)
    keys = {str(c.key()) for c in chunks}
    assert {str(c.key()) for c in bench.plan([TASK], "test", 100, 10, {"naive"})} <= keys
    played = []

    def fake(c, fail_after=None):
        if fail_after is not None and len(played) >= fail_after:
            raise KeyboardInterrupt  # the run is killed half-way
        played.append(c)
        return {"key": c.key(), "episodes": _episodes(c.seeds, [1.0] * len(c.seeds)), "wall_s": 0.0}

    sub = per_agent[:6]
    monkeypatch.setattr(bench, "play_chunk", lambda c: fake(c, fail_after=4))
    with pytest.raises(KeyboardInterrupt):
        bench.run_chunks(sub, tmp_path, progress=False)
    assert len(list((tmp_path / bench.CACHE_DIR).rglob("*.json"))) == 4  # every finished chunk kept
    played.clear()
    monkeypatch.setattr(bench, "play_chunk", fake)
    done = bench.run_chunks(sub, tmp_path, progress=False)
    assert len(played) == 2 and set(done) == set(sub)  # only the two unfinished chunks are played


def test_the_paths_figure_draws_each_tasks_own_band(tmp_path, monkeypatch):

    env = make_env(TASK)  # TASK is retired: the record path
    band = bench.plant_band(env)
    env.close()
    assert band.band_lower is not None and "31x7" in band.source  # the stored map of the task's grid
    titles, fills = [], []
    monkeypatch.setattr("matplotlib.axes.Axes.set_title", lambda ax, t, **kw: titles.append(t))
    real_fill = __import__("matplotlib").axes.Axes.fill_betweenx
    monkeypatch.setattr(
        "matplotlib.axes.Axes.fill_betweenx",
        lambda ax, *a, **kw: fills.append(kw.get("label", "")) or real_fill(ax, *a, **kw),
    )
    paths = {(TASK, "naive"): {"lam": [0.45, 0.6], "dw": [1.0, 1.0], "reason": "", "success": True}}
    bench.plot_paths(paths, {TASK: band}, tmp_path / "p.png", [TASK])
    assert (tmp_path / "p.png").stat().st_size > 10_000
    assert any(f.startswith("hysteresis band") for f in fills) and "31x7" in titles[0]
    with pytest.raises(ValueError, match="no plant band for gfb_env/WhirlRecovery-v1"):
        bench.plot_paths(paths, {TASK: band}, tmp_path / "q.png", [TASK, "gfb_env/WhirlRecovery-v1"])


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_a_run_on_a_task_without_policies_plays_the_ladder_and_notes_it(tmp_path, capsys):
    """End to end: the policies folder holds only RunUp-v1's; a WhirlRecovery-v1 run is not refused,
    plays naive, hold, its rules and the oracle, and its table and JSON say the learned agents were
    skipped."""
    import json
    import shutil

    from gfb_agents.learned.evaluate import POLICIES_DIR

    pol = tmp_path / "policies"
    shutil.copytree(POLICIES_DIR / "RunUp-v1_recurrentppo", pol / "RunUp-v1_recurrentppo")
    task = "gfb_env/WhirlRecovery-v1"
    out = tmp_path / "out"
    args = ["--quick", "--tasks", task, "--policies", str(pol), "--out", str(out), "--reps", "100"]
    args += ["--env-kwargs", json.dumps({task: {"max_episode_steps": 2}})]
    assert bench.main(args) == 0
    note = "no learned policy is committed for WhirlRecovery-v1: learned agents skipped on it"
    assert f"note: {note}" in capsys.readouterr().err
    assert f"Note: {note}" in (out / "benchmark_agents.md").read_text()
    meta = json.loads((out / "benchmark_agents.json").read_text())
    assert meta["notes"] == [note]
    kinds = {r["agent"]: r["kind"] for r in meta["rows"]}
    assert {"naive", "hold", "oracle_v1"} <= set(kinds) and "learned" not in kinds.values()
    assert all(r["split"] == "test" for r in meta["rows"])
