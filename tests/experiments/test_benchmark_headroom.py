"""The headroom CSV recomputed from a benchmark JSON equals what the benchmark run itself computes (the same
best rule and paired bootstrap); bad tables are refused in one line."""

import csv

import numpy as np
import pytest

from gfb_experiments.benchmark_agents import HEADROOM_COLUMNS, HEADROOM_EXTRA_COLUMNS
from gfb_experiments.benchmark_headroom import headroom_from_table, main
from gfb_experiments.benchmark_stats import paired_headroom

_NO_REF = {"reference": None, "reference_mean": None}  # the synthetic table records no zero reference


def _table(rng):
    n = 40
    oracle = 1.0 + 0.05 * rng.standard_normal(n)
    good = oracle - 0.3 + 0.02 * rng.standard_normal(n)
    weak = oracle - 0.6 + 0.02 * rng.standard_normal(n)
    rows = [
        {"task": "T", "agent": "oracle_v1", "kind": "oracle", "split": "test", "normalized_iqm": 1.0},
        {"task": "T", "agent": "good", "kind": "rule", "split": "test", "normalized_iqm": 0.7},
        {"task": "T", "agent": "weak", "kind": "rule", "split": "test", "normalized_iqm": 0.4},
        {"task": "T", "agent": "ppo", "kind": "learned", "split": "test", "normalized_iqm": 0.9},
    ]
    agents = {
        "oracle_v1": {"normalized": [oracle.tolist()]},
        "good": {"normalized": [good.tolist()]},
        "weak": {"normalized": [weak.tolist()]},
        "ppo": {"normalized": [(oracle - 0.1).tolist()]},
    }
    return (
        {"split": "test", "rows": rows, "tasks": {"T": {"oracle": "oracle_v1", "agents": agents}}},
        oracle,
        good,
    )


def test_the_best_rule_and_the_paired_headroom(rng):
    table, oracle, good = _table(rng)
    h = headroom_from_table(table, reps=2000)["T"]["headroom"]
    assert h["best_rule"] == "good"  # the best RULE: the learned agent does not count
    ph = paired_headroom([oracle], [good], reps=2000)
    assert h == {"best_rule": "good", "split": "test", **_NO_REF, **ph, "established": True}
    assert h["iqm_low"] < 0.3 < h["iqm_high"] and h["mean_low"] < 0.3 < h["mean_high"]


def test_the_command_writes_the_csv(tmp_path, rng, capsys):
    import json

    table, *_ = _table(rng)
    p = tmp_path / "benchmark_agents.json"
    p.write_text(json.dumps(table))
    assert main([str(p), "--reps", "500"]) == 0
    with (tmp_path / "benchmark_headroom.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == HEADROOM_COLUMNS + HEADROOM_EXTRA_COLUMNS and rows[1][:3] == ["T", "good", "40"]
    assert np.isfinite([float(x) for x in rows[1][3:9]]).all()
    assert rows[1][9:] == ["test", "", "", "True"]  # split, references (not in this table), the claim
    assert "headroom >= 0.2: holds" in capsys.readouterr().out


def test_a_table_that_is_not_a_benchmark_is_refused(tmp_path, capsys):
    p = tmp_path / "x.json"
    p.write_text("{}")
    with pytest.raises(SystemExit) as exc:
        main([str(p)])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1 and "not a benchmark_agents.json document" in err[0]


def test_merge_keeps_the_old_agents_scores_and_recomputes_the_headroom(rng):
    """``benchmark_agents --merge`` used to replace a re-run task's whole entry, dropping the per-episode
    scores of every agent it did not re-play (and with them the headroom's data)."""
    from gfb_experiments.benchmark_agents import merge_tasks

    table, oracle, good = _table(rng)
    old = table["tasks"]
    new = {"T": {"oracle": "oracle_v1", "agents": {"oracle_v1": old["T"]["agents"]["oracle_v1"]}}}
    new["T"]["agents"]["hold"] = {"normalized": [(oracle - 1.2).tolist()]}
    rows = [
        *table["rows"],
        {"task": "T", "agent": "hold", "kind": "rule", "split": "test", "normalized_iqm": -0.2},
    ]
    merged = merge_tasks(old, new, rows, reps=500)
    assert set(merged["T"]["agents"]) == {"oracle_v1", "good", "weak", "ppo", "hold"}
    assert merged["T"]["headroom"]["best_rule"] == "good"
    assert merged["T"]["headroom"] == {
        "best_rule": "good",
        "split": "test",
        **_NO_REF,
        **paired_headroom([oracle], [good], reps=500),
        "established": True,
    }


def test_learned_minus_the_best_rule_is_paired_per_learned_agent(rng, tmp_path):
    """Issue 21: every learned agent against the best rule, its training seeds averaged per test seed
    first; the synthetic ppo sits 0.2 above the good rule on every seed (so its CI excludes 0)."""
    import json

    from gfb_experiments.benchmark_headroom import LEARNED_COLUMNS, learned_vs_rule

    table, oracle, good = _table(rng)
    runs = [(good + 0.2 + 0.01 * rng.standard_normal(good.size)).tolist() for _ in range(3)]
    table["tasks"]["T"]["agents"]["ppo"] = {"normalized": runs}
    (h,) = learned_vs_rule(table, reps=1000)
    assert h["learned"] == "ppo" and h["best_rule"] == "good" and h["training_seeds"] == 3
    assert h == {**h, **paired_headroom(runs, [good], reps=1000)}
    assert 0.15 < h["iqm_low"] < 0.2 < h["iqm_high"] < 0.25 and h["beats_rule"]
    # a learned agent below the rule does not beat it
    table["tasks"]["T"]["agents"]["ppo"] = {"normalized": [(good - 0.05).tolist()]}
    (h2,) = learned_vs_rule(table, reps=1000)
    assert h2["iqm"] == pytest.approx(-0.05) and not h2["beats_rule"]
    # the command writes the CSV beside the headroom's
    p = tmp_path / "benchmark_agents.json"
    p.write_text(json.dumps(table))
    assert main([str(p), "--reps", "500"]) == 0
    with (tmp_path / "benchmark_learned_vs_rule.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == LEARNED_COLUMNS and rows[1][:5] == ["T", "ppo", "1", "good", "40"]
    assert rows[1][-1] == "False"
