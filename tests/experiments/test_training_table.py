"""The training record table of the committed policies (experiments/training_table.py)."""

import csv
import json

import pytest

from gfb_experiments.training_table import COLUMNS, main, markdown, training_rows


def _policy(folder, **kw):
    folder.mkdir(parents=True)
    rec = {
        "algo": "ppo",
        "env_id": "gfb_env/RunUp-v1",
        "seed": 0,
        "n_envs": 2,
        "frame_stack": 4,
        "timesteps": 1000,
        "wall_time_s": 120.0,
        "env_steps_per_s": 8.3,
        "best_validation": {"mean_return": 3.5, "success_rate": 0.2, "timesteps": 800},
    }
    rec.update(kw)
    (folder / "policy.json").write_text(json.dumps(rec))


def test_rows_read_every_seed_folder_and_filter_by_task(tmp_path):
    _policy(tmp_path / "A_ppo" / "seed1", seed=1)
    _policy(tmp_path / "A_ppo" / "seed0", seed=0, wall_time_s=60.0)
    _policy(tmp_path / "B_sac", algo="sac", env_id="gfb_env/WhirlRecovery-v1", seed=3)
    rows = training_rows(tmp_path)
    assert [(r["policy"], r["seed"]) for r in rows] == [("A_ppo", 0), ("A_ppo", 1), ("B_sac", 3)]
    assert rows[0]["wall_time_min"] == 1.0 and rows[1]["wall_time_min"] == 2.0
    assert rows[0]["best_validation_return"] == 3.5 and rows[0]["best_validation_at"] == 800
    assert [r["policy"] for r in training_rows(tmp_path, ("gfb_env/WhirlRecovery-v1",))] == ["B_sac"]
    md = markdown(rows).splitlines()
    assert len(md) == 2 + 3 and all(line.count("|") == len(COLUMNS) + 1 for line in md)


def test_cli_writes_the_csv_and_refuses_a_missing_folder(tmp_path, capsys):
    _policy(tmp_path / "pol" / "A_ppo" / "seed0")
    out = tmp_path / "runs.csv"
    assert main(["--policies", str(tmp_path / "pol"), "--out", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 1 and rows[0]["algo"] == "ppo" and rows[0]["timesteps"] == "1000"
    with pytest.raises(SystemExit) as e:
        main(["--policies", str(tmp_path / "missing")])
    assert e.value.code == 2
    assert "--policies" in capsys.readouterr().err


def test_the_committed_v1_policies_have_their_training_record():
    """Every committed v1 policy carries the throughput and wall time of its training run."""
    rows = training_rows(__import__("gfb_agents.learned.evaluate", fromlist=["POLICIES_DIR"]).POLICIES_DIR)
    v1 = [r for r in rows if r["env_id"] and r["env_id"].endswith("-v1")]
    assert v1
    for r in v1:
        assert r["timesteps"] > 0 and r["wall_time_min"] > 0 and r["env_steps_per_s"] > 0, r
