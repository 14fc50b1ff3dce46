"""The grid search of training hyperparameters (issue 21): grid parsing, refusals before any run, scoring
on the VALIDATION seeds only, and a tiny end-to-end search that a rerun continues without retraining."""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest
import yaml

from gfb_agents.learned.train import TrainConfig, load_hyperparams
from gfb_agents.learned.tune import GridPoint, TuneConfig, choose_point, grid_points, parse_grid, score_run
from gfb_agents.seeds import TEST, VALIDATION
from gfb_experiments.tune import main as tune_main

ENV = "gfb_env/RunUp-v2"


def _tiny_yaml(tmp_path: Path) -> Path:
    hp = load_hyperparams("ppo", ENV)
    hp.update(n_steps=16, batch_size=16, n_epochs=1, n_envs=1)
    hp["policy_kwargs"] = "dict(net_arch=dict(pi=[8], vf=[8]))"
    p = tmp_path / "tiny.yml"
    p.write_text(yaml.safe_dump({ENV: hp}))
    return p


def _argv(tmp_path: Path, grid: str, out: Path, *extra: str) -> list[str]:
    return [
        "--algo", "ppo", "--env", ENV, "--hyperparams", str(_tiny_yaml(tmp_path)), "--grid", grid,
        "--timesteps", "32", "--seeds", "0", "--eval-episodes", "1", "--out", str(out), *extra,
    ]  # fmt: skip


def test_parse_grid_values_and_product():
    g = parse_grid("learning_rate=lin_3e-4,1e-3;n_epochs=5,10;policy_kwargs=dict(net_arch=[64, 64])")
    # 1e-3 is a float (YAML's reader would keep it a string), 5 an int, commas in brackets stay
    assert g == {
        "learning_rate": ["lin_3e-4", 1e-3],
        "n_epochs": [5, 10],
        "policy_kwargs": ["dict(net_arch=[64, 64])"],
    }
    pts = grid_points(g)
    assert len(pts) == 4 and pts[1].settings == {
        "learning_rate": "lin_3e-4",
        "n_epochs": 10,
        "policy_kwargs": "dict(net_arch=[64, 64])",
    }
    assert pts[0].name != pts[2].name  # the characters outside the safe set are hashed, names distinct
    assert "/" not in pts[0].name and " " not in pts[0].name
    assert GridPoint(0, {"learning_rate": 1e-3, "n_epochs": 5}).name == "learning_rate=0.001,n_epochs=5"


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("", "--grid is empty"),
        (";", "--grid is empty"),
        ("learning_rate", "is not NAME=VALUE"),
        ("learning_rate=1e-3,", "empty value"),
        ("n_epochs=5,5", "repeats a value"),
        ("n_epochs=5;n_epochs=10", "given twice"),
        ("policy_kwargs=dict(net_arch=[64", "unbalanced"),
    ],
)
def test_parse_grid_refuses(text, fragment):
    with pytest.raises(ValueError, match="--grid") as exc:
        parse_grid(text)
    assert fragment in str(exc.value)


def test_tune_config_refuses_names_the_runs_cannot_take():
    base = TrainConfig("ppo", ENV, timesteps=32)
    for grid, fragment in (
        ({"n_step": [16]}, "unknown hyperparameter 'n_step'"),
        ({"n_timesteps": [10]}, "set by --timesteps"),
        ({"seed": [1]}, "set by the training command"),
    ):
        with pytest.raises(ValueError, match=fragment):
            TuneConfig(base=base, grid=grid, seeds=(0,), out="x")
    with pytest.raises(ValueError, match="--timesteps"):
        TuneConfig(base=TrainConfig("ppo", ENV), grid={"n_epochs": [1]}, seeds=(0,), out="x")


def _refused(argv: list[str], fragment: str, capsys) -> None:
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        tune_main(argv)
    out, err = capsys.readouterr()
    lines = [x for x in err.splitlines() if x.strip()]
    assert exc.value.code == 2 and len(lines) == 1 and fragment in lines[0], err
    assert lines[0].startswith("python -m gfb_experiments.tune: error:") and out == ""
    assert time.perf_counter() - t0 < 20


@pytest.mark.parametrize(
    "grid, extra, fragment",
    [
        ("n_step=16", (), "--grid: unknown hyperparameter 'n_step'"),
        ("learning_rate=1e-3;", ("--timesteps", "0"), "--timesteps must be a positive integer"),
        ("", (), "--grid is empty"),
        ("learning_rate=lin_x", (), "--grid point"),  # a value the runs would fail on, found up front
        ("n_epochs=1", ("--env", "gfb_env/RunUp-v1"), "--env gfb_env/RunUp-v1 is retired"),
        ("n_epochs=1", ("--seeds", "0-x"), "--seeds"),
    ],
)
def test_tune_cli_refuses_before_any_run(tmp_path, capsys, grid, extra, fragment):
    out = tmp_path / "search"
    _refused(_argv(tmp_path, grid, out, *extra), fragment, capsys)
    assert not out.exists()  # nothing written, nothing trained


def _fake_run(d: Path, seeds: list[int]) -> None:
    d.mkdir(parents=True)
    rec = {"timesteps": 32, "mean_return": 1.0, "std_return": 0.0, "success_rate": 0.5}
    (d / "validation.json").write_text(json.dumps({"seeds": seeds, "history": [rec], "best": rec}))
    (d / "run.json").write_text(json.dumps({"timesteps": 32, "wall_time_s": 1.0, "env_steps_per_s": 32.0}))


def test_score_run_refuses_runs_validated_outside_validation(tmp_path):
    _fake_run(tmp_path / "ok", VALIDATION.first(2))
    assert score_run(tmp_path / "ok")["best_mean_return"] == 1.0
    _fake_run(tmp_path / "test", TEST.first(2))
    with pytest.raises(RuntimeError, match="outside the VALIDATION range"):
        score_run(tmp_path / "test")


def test_choose_point_rule_and_ties():
    def s(i, best, final, complete=True):
        return {"index": i, "mean_best_return": best, "mean_final_return": final, "complete": complete}

    pts = [s(0, 2.0, 0.0), s(1, 1.0, 1.5), s(2, 2.0, 0.5), s(3, 9.0, 9.0, complete=False)]
    assert choose_point(pts, "best")["index"] == 2  # tie on best broken by the final score
    assert choose_point(pts, "final")["index"] == 1
    assert choose_point([s(0, 1.0, 1.0), s(1, 1.0, 1.0)], "best")["index"] == 0  # then the earlier point
    assert choose_point([s(0, 1.0, 1.0, complete=False)], "best") is None


def test_tiny_search_writes_its_records_and_a_rerun_skips_finished_points(tmp_path, capsys):
    """2 grid points x 1 seed x 2 rollouts of 16 steps, 1 validation episode; then the same command."""
    out = tmp_path / "search"
    argv = _argv(tmp_path, "learning_rate=1e-3,lin_3e-4;n_epochs=1", out)
    assert tune_main(argv) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["points"] == 2 and last["runs"] == 2 and last["env_steps"] == 64 and last["failed_runs"] == 0
    rows = list(csv.DictReader((out / "tune.csv").open()))
    assert [(r["point"], r["learning_rate"], r["seed"]) for r in rows] == [
        ("0", "0.001", "0"),
        ("1", "lin_3e-4", "0"),
    ]
    assert all(r["validation_seeds"] == f"{VALIDATION.start}-{VALIDATION.start}" for r in rows)
    rec = json.loads((out / "tune.json").read_text())
    assert rec["budget"]["env_steps"] == 64 and rec["test_seeds_used"] is False
    best = max(rec["per_point"], key=lambda p: p["mean_best_return"])
    assert rec["chosen"]["index"] == best["index"] and last["chosen"] == best["settings"]
    assert (out / "tune.png").stat().st_size > 0
    # the point's YAML reproduces its runs: the base entry with the point's values and the budget
    hp = yaml.safe_load((out / rows[0]["name"] / "hyperparams.yml").read_text())[ENV]
    assert hp["learning_rate"] == 1e-3 and hp["n_steps"] == 16 and hp["n_timesteps"] == 32
    model = out / rows[0]["name"] / "seed0" / "model.zip"
    stamp = model.stat().st_mtime_ns
    t0 = time.perf_counter()
    assert tune_main(argv) == 0  # the same command again: nothing retrained
    assert time.perf_counter() - t0 < 15
    assert model.stat().st_mtime_ns == stamp
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1]) == last
    # the point folder holding other hyperparameters (another base YAML) is refused
    other = tmp_path / "other"
    other.mkdir()
    base = yaml.safe_load(_tiny_yaml(tmp_path).read_text())
    base[ENV]["gamma"] = 0.9
    (other / "tiny.yml").write_text(yaml.safe_dump(base))
    argv2 = [*argv]
    argv2[argv2.index("--hyperparams") + 1] = str(other / "tiny.yml")
    _refused(argv2, "holds other hyperparameters", capsys)
