"""``python -m gfb_experiments.learning_curves`` (issue 21): the curves' arithmetic against a hand computation
on fake runs (references from the cache: no episode is played), and its refusals."""

from __future__ import annotations

import csv
import json
import math

import pytest

from gfb_agents.seeds import TEST, VALIDATION
from gfb_experiments import learning_curves as lc

TASK = "gfb_env/RunUp-v2"


def _run(folder, seed, steps, returns, success, seeds, walls=None, task=TASK):
    d = folder / f"seed{seed}"
    d.mkdir(parents=True)
    (d / "run.json").write_text(
        json.dumps({"env_id": task, "seed": seed, "env_kwargs": {}, "env_steps_per_s": 100.0})
    )
    hist = []
    for j, (s, r, p) in enumerate(zip(steps, returns, success, strict=True)):
        h = {"timesteps": s, "mean_return": r, "success_rate": p}
        if walls is not None:
            h["wall_time_s"] = walls[j]
        hist.append(h)
    (d / "validation.json").write_text(json.dumps({"history": hist, "best": None, "seeds": seeds}))


def _cache(out, seeds, means):
    out.mkdir(parents=True, exist_ok=True)
    key = lc._ref_key(TASK, seeds, {})
    ref = {"task": TASK, "seeds": seeds, "env_kwargs": {}, "mean_return": means}
    (out / "references.json").write_text(json.dumps({key: ref}))


def test_curves_normalise_interpolate_and_bootstrap_over_seeds(tmp_path, capsys):
    seeds = VALIDATION.first(2)
    exp = tmp_path / "exp_ppo"
    _run(exp, 0, [100, 200, 300], [0.0, 10.0, 20.0], [0.0, 0.5, 1.0], seeds, walls=[1.0, 2.0, 3.0])
    _run(exp, 1, [110, 210, 310], [10.0, 20.0, 30.0], [0.0, 0.0, 0.5], seeds, walls=[2.0, 4.0, 6.0])
    out = tmp_path / "out"
    # zero = the better of naive (-5) and hold (0) = 0; oracle 40
    _cache(out, seeds, {"naive": -5.0, "hold": 0.0, "oracle": 40.0})
    assert lc.main([str(exp), "--out", str(out), "--reps", "200"]) == 0
    rows = list(csv.DictReader(open(out / "learning_curves.csv")))
    # the grid: seed 0's steps where both seeds have data: 200 (110 <= s <= 300)
    assert [int(r["timesteps"]) for r in rows] == [200, 300]
    r = rows[0]
    # seed 1 at 200: interpolated 19.0; normalised (10 / 40 + 19 / 40) / 2
    assert float(r["normalised_mean"]) == pytest.approx((10 / 40 + 19 / 40) / 2)
    assert float(r["wall_time_s"]) == pytest.approx((2.0 + 3.8) / 2)
    assert r["wall_time_source"] == "recorded"
    lo, hi = float(r["normalised_ci_low"]), float(r["normalised_ci_high"])
    assert 10 / 40 - 1e-12 <= lo <= float(r["normalised_mean"]) <= hi <= 19 / 40 + 1e-12
    assert float(rows[1]["success_mean"]) == pytest.approx((1.0 + 0.45) / 2)
    assert (out / "learning_curves_RunUp-v2.png").stat().st_size > 0
    assert "exp_ppo: 2 seeds" in capsys.readouterr().out


def test_one_seed_has_no_ci_and_old_records_estimate_wall_time(tmp_path):
    seeds = VALIDATION.first(2)
    exp = tmp_path / "one"
    _run(exp, 0, [100, 200], [0.0, 20.0], [0.0, 1.0], seeds)  # no wall_time_s: steps / 100 per s
    out = tmp_path / "out"
    _cache(out, seeds, {"naive": 0.0, "hold": -1.0, "oracle": 40.0})
    assert lc.main([str(exp), "--out", str(out), "--reps", "100"]) == 0
    rows = list(csv.DictReader(open(out / "learning_curves.csv")))
    assert float(rows[1]["wall_time_s"]) == pytest.approx(2.0)
    assert rows[1]["wall_time_source"] == "steps / mean env_steps_per_s"
    assert math.isnan(float(rows[1]["normalised_ci_low"]))
    assert float(rows[1]["normalised_mean"]) == pytest.approx(0.5)


@pytest.mark.parametrize("case", ["empty", "test-seeds", "two-tasks", "rule"])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, case):
    exp = tmp_path / "exp"
    seeds = VALIDATION.first(2)
    extra = []
    if case == "empty":
        exp.mkdir()
        fragment = "no training run"
    elif case == "test-seeds":
        _run(exp, 0, [100], [1.0], [0.0], TEST.first(2))
        fragment = "outside VALIDATION"
    elif case == "two-tasks":
        _run(exp, 0, [100], [1.0], [0.0], seeds)
        _run(exp, 1, [100], [1.0], [0.0], seeds, task="gfb_env/WhirlRecovery-v2")
        fragment = "several tasks"
    else:
        _run(exp, 0, [100], [1.0], [0.0], seeds)
        extra = ["--rules", "recovery"]
        fragment = "not a rule of gfb_env/RunUp-v2"
    with pytest.raises(SystemExit) as e:
        lc.main([str(exp), "--out", str(tmp_path / "out"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and fragment in err[0], err
    assert not (tmp_path / "out" / "learning_curves.csv").exists()


def test_references_play_the_oracle_on_its_own_env():
    """The oracle reads the privileged channel of the env it was built with; the references used to build
    it on one env and play it on another (RuntimeError: call reset() first).  One seed of RunUp-v2: the
    oracle's return is the benchmark runner's on the same seed."""
    from gfb_agents import ladder
    from gfb_agents.learned.evaluate import run_episode
    from gfb_agents.seeds import VALIDATION
    from gfb_env.envs import make_env
    from gfb_experiments.learning_curves import references

    task, seed = "gfb_env/RunUp-v2", VALIDATION.start
    ref = references(task, [seed], {}, [], {})
    env = make_env(task)
    try:
        expect = run_episode(env, ladder.build(ladder.oracle_for(task).name, env), seed).episode_return
    finally:
        env.close()
    assert ref["oracle"] == expect and ref["oracle"] > ref["naive"]
