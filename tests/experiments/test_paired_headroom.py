"""The headroom's paired bootstrap (benchmark_stats.paired_headroom) and the IQM normalisation."""

from __future__ import annotations

import numpy as np
import pytest

from gfb_experiments.benchmark_stats import iqm, normalized_scores, paired_headroom


def _correlated(n: int = 100, shift: float = 0.3, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    # a shared per-seed difficulty (large) plus small agent-own noise: the pairing should cancel the former
    g = np.random.default_rng(seed)
    hard = g.normal(0.0, 1.0, n)
    rule = 0.6 + hard + g.normal(0.0, 0.05, n)
    oracle = 0.6 + shift + hard + g.normal(0.0, 0.05, n)
    return oracle, rule


def test_paired_ci_covers_a_known_difference():
    oracle, rule = _correlated(shift=0.3)
    h = paired_headroom(oracle, rule, reps=2000, seed=3)
    assert h["seeds"] == 100
    assert h["mean_low"] < 0.3 < h["mean_high"] and h["iqm_low"] < 0.3 < h["iqm_high"]
    assert h["mean"] == pytest.approx(oracle.mean() - rule.mean())
    assert h["iqm"] == pytest.approx(iqm(oracle) - iqm(rule))


def test_a_constant_offset_has_a_zero_width_ci():
    rule = np.random.default_rng(0).normal(0.5, 0.4, 60)
    h = paired_headroom(rule + 0.25, rule, reps=1000)
    for k in ("mean", "mean_low", "mean_high", "iqm", "iqm_low", "iqm_high"):
        assert h[k] == pytest.approx(0.25, abs=1e-12), k


def test_paired_ci_is_narrower_than_unpaired_for_correlated_scores():
    oracle, rule = _correlated()
    p = paired_headroom(oracle, rule, reps=2000)
    u = paired_headroom(oracle, rule, reps=2000, paired=False)
    assert p["mean"] == u["mean"] and p["iqm"] == u["iqm"]
    assert (p["mean_high"] - p["mean_low"]) < 0.25 * (u["mean_high"] - u["mean_low"])
    assert (p["iqm_high"] - p["iqm_low"]) < 0.5 * (u["iqm_high"] - u["iqm_low"])


def test_deterministic_with_the_seed_and_training_seeds_are_averaged_first():
    oracle, rule = _correlated(n=40)
    a = paired_headroom(oracle, rule, reps=500, seed=7)
    assert a == paired_headroom(oracle, rule, reps=500, seed=7)
    assert a != paired_headroom(oracle, rule, reps=500, seed=8)
    two = np.vstack([rule - 0.1, rule + 0.1])  # two training seeds whose mean per seed is `rule`
    b = paired_headroom(oracle, two, reps=500, seed=7)
    for k in a:
        assert b[k] == pytest.approx(a[k], abs=1e-12), k


@pytest.mark.parametrize(
    "oracle,rule,kw,fragment",
    [
        (np.ones(5), np.ones(4), {}, "same seeds"),
        (np.array([1.0, np.nan, 2.0]), np.ones(3), {}, "oracle has non-finite"),
        (np.ones(3), np.array([1.0, np.inf, 2.0]), {}, "rule has non-finite"),
        (np.ones(0), np.ones(0), {}, "oracle must be a non-empty"),
        (np.ones((2, 2, 2)), np.ones(2), {}, "oracle must be"),
        (np.ones(3), np.ones(3), {"reps": 10}, "reps must be"),
        (np.ones(3), np.ones(3), {"confidence": 1.5}, "confidence must"),
    ],
)
def test_paired_headroom_refuses_bad_input(oracle, rule, kw, fragment):
    with pytest.raises(ValueError, match=fragment):
        paired_headroom(oracle, rule, **kw)


def test_iqm_normalisation_puts_naive_and_oracle_iqms_at_0_and_1():
    g = np.random.default_rng(2)
    naive = np.where(g.random(40) < 0.25, -100.0, g.normal(5.0, 1.0, 40))  # touchdowns: mean != IQM
    oracle = naive + 30.0 + g.normal(0.0, 2.0, 40)
    s_n, info = normalized_scores(naive, naive, oracle, reference="iqm")
    s_o, _ = normalized_scores(oracle, naive, oracle, reference="iqm")
    assert iqm(s_n) == pytest.approx(0.0, abs=1e-12) and iqm(s_o) == pytest.approx(1.0)
    assert info["statistic"] == "iqm" and info["reference_gap"] == pytest.approx(iqm(oracle) - iqm(naive))
    m_n, minfo = normalized_scores(naive, naive, oracle)  # the default stays the means
    assert np.mean(m_n) == pytest.approx(0.0, abs=1e-12) and minfo["reference_gap"] == minfo["mean_gap"]
    assert abs(iqm(m_n)) > 0.1  # the inconsistency the option removes
    with pytest.raises(ValueError, match="reference must be one of"):
        normalized_scores(naive, naive, oracle, reference="median")


def test_benchmark_writes_the_headroom_csv_with_paired_cis(tmp_path, capsys):
    """A tiny validation run (2 seeds, 6 steps): the headroom file is named for its split, has exactly
    the documented columns and equals paired_headroom of the JSON's per-episode scores."""
    import csv
    import json

    from gfb_experiments.benchmark_agents import HEADROOM_COLUMNS, HEADROOM_EXTRA_COLUMNS, main

    task = "gfb_env/RunUp-v1"
    args = ["--quick", "--split", "validation", "--out", str(tmp_path), "--no-learned", "--tasks", task]
    args += ["--agents", "map_informed_v1", "--reps", "200", "--normalise", "iqm"]
    args += ["--env-kwargs", json.dumps({task: {"max_episode_steps": 6}})]
    assert main(args) == 0
    assert not (tmp_path / "benchmark_headroom.csv").exists()  # not the test split: not the table's name
    with (tmp_path / "benchmark_headroom_validation.csv").open() as fh:
        reader = csv.DictReader(fh)
        assert reader.fieldnames == HEADROOM_COLUMNS + HEADROOM_EXTRA_COLUMNS  # the 9 first
        rows = list(reader)
    assert len(rows) == 1 and rows[0]["task"] == task and rows[0]["best_rule"] == "map_informed_v1"
    assert rows[0]["test_seeds"] == "2"
    meta = json.loads((tmp_path / "benchmark_agents.json").read_text())
    assert meta["normalise"] == "iqm" and meta["tasks"][task]["scales"]["iqm"]["statistic"] == "iqm"
    assert meta["tasks"][task]["scales"]["mean"]["statistic"] == "iqm"  # --normalise iqm: both by IQMs
    assert meta["tasks"][task]["reference"] in ("naive", "hold")
    ag = meta["tasks"][task]["agents"]
    assert len(ag["map_informed_v1"]["returns"][0]) == 2 and len(ag["map_informed_v1"]["seeds"]) == 2
    h = paired_headroom(ag["oracle_v1"]["normalized"], ag["map_informed_v1"]["normalized"], reps=200)
    for col, k in (
        ("headroom_iqm", "iqm"),
        ("headroom_ci_low", "iqm_low"),
        ("headroom_mean_ci_high", "mean_high"),
    ):
        assert float(rows[0][col]) == pytest.approx(h[k], abs=1e-12), col
    # merging a mean-normalised run into this iqm-normalised table says so (the cache replays the chunks)
    capsys.readouterr()
    assert main([*args[:-4], "--normalise", "mean", "--merge", *args[-2:]]) == 0
    assert "normalised by another reference" in capsys.readouterr().err
