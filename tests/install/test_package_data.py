"""Package data: what the library reads at run time ships with it, and missing data is an error.

(The wheel itself is tested in ``tests/install/test_wheel.py``; the task constants' reproduction in
``tests/analysis/test_task_constants.py``.)"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gfb_env.analysis import load_hysteresis_map, optimal_foil_damping
from gfb_env.analysis.maps import MAPS_DATA_DIR
from gfb_env.envs import _data
from gfb_env.envs._data import NOMINAL_BEARING, TaskConstantsWarning, nominal_task_constants
from gfb_env.model import Grid

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    "shipped, committed",
    [
        ("stability_map.csv", "results/fig4_stability_map/stability_map.csv"),
        ("hysteresis_map.csv", "results/hysteresis_map/hysteresis_map.csv"),
        ("hysteresis_map_tasks.csv", "results/hysteresis_map_tasks/hysteresis_map.csv"),
    ],
)
def test_shipped_maps_equal_the_committed_results(shipped, committed):
    # the package copy is what installed code reads; it must be the map the experiments committed
    # (after rerunning the experiment: cp results/... gfb_env/data/...)
    assert (MAPS_DATA_DIR / shipped).read_bytes() == (REPO / committed).read_bytes(), shipped


def test_map_readers_use_package_data_and_name_the_script_when_missing(tmp_path):
    assert MAPS_DATA_DIR == Path(_data.__file__).resolve().parents[1] / "data"
    hm = load_hysteresis_map()
    assert len(hm.foil_stiffness) > 0 and np.isfinite(hm.critical_bearing_number).any()
    assert 1.0 < optimal_foil_damping(1.0) < 10.0
    with pytest.raises(FileNotFoundError, match="gfb_experiments.hysteresis_map"):
        load_hysteresis_map(tmp_path / "missing.csv")
    with pytest.raises(FileNotFoundError, match="gfb_experiments.fig4_stability_map"):
        optimal_foil_damping(1.0, tmp_path / "missing.csv")
    (tmp_path / "empty.csv").write_text("foil_stiffness,foil_damping,critical_bearing_number\n")
    with pytest.raises(ValueError, match="empty"):
        optimal_foil_damping(1.0, tmp_path / "empty.csv")


def test_nominal_map_missing_hysteresis_map_is_an_error_not_an_empty_fold(tmp_path):
    import gymnasium as gym

    from gfb_agents.nominal_map import NominalMap

    env = gym.make("gfb_env/RunUp-v2")
    nmap = NominalMap.from_env(env)  # the shipped map: it lacks K_W = 0.50, so the fold is unknown
    assert len(nmap.fold) == 0 and math.isnan(nmap.fold_at(2.0))
    with pytest.raises(FileNotFoundError, match="hysteresis"):
        NominalMap.from_env(env, hysteresis_map_path=tmp_path / "missing.csv")
    env.close()


def test_load_learned_policies_missing_folder_raises(tmp_path):
    from gfb_agents.learned.evaluate import POLICIES_DIR, load_learned_policies

    assert (POLICIES_DIR / "WhirlRecovery-v1_sac" / "seed0" / "model.zip").is_file()
    with pytest.raises(FileNotFoundError, match="no policies folder"):
        load_learned_policies(tmp_path / "none")
    assert load_learned_policies(tmp_path) == []  # existing but empty: no policies, not an error


@pytest.mark.parametrize("policies", ["none", "empty"])
def test_benchmark_refuses_to_run_without_expected_learned_policies(tmp_path, capsys, policies):
    from gfb_experiments.benchmark_agents import main

    (tmp_path / "empty").mkdir()
    assert main(["--quick", "--out", str(tmp_path / "out"), "--policies", str(tmp_path / policies)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--no-learned" in err[0] and str(tmp_path / policies) in err[0], err
    assert not (tmp_path / "out").exists()  # refused before any work
    with pytest.raises(SystemExit) as exc:
        main(["--quick", "--out", str(tmp_path / "out"), "--policies", str(tmp_path), "--no-learned"])
    assert exc.value.code == 2


def test_train_finds_its_hyperparameters_in_the_package():
    import gfb_agents.learned.train
    from gfb_agents.learned.train import HYPERPARAMS_DIR, load_hyperparams

    assert HYPERPARAMS_DIR == Path(gfb_agents.learned.train.__file__).resolve().parent.parent / "hyperparams"
    assert load_hyperparams("sac", "gfb_env/WhirlRecovery-v1")


# ------------------------------------------------------------------------------------ task constants
@pytest.fixture
def constants_file(monkeypatch, tmp_path):
    """Point the loader at a temporary file (and forget the cached table before and after)."""
    p = tmp_path / "task_constants.json"
    monkeypatch.setattr(_data, "TASK_CONSTANTS_PATH", p)
    monkeypatch.setattr(_data, "_COMPUTED", {})
    _data.load_task_constants.cache_clear()
    yield p
    _data.load_task_constants.cache_clear()


def test_missing_task_constants_file_is_an_error_not_a_recompute(constants_file):
    with pytest.raises(FileNotFoundError, match="gfb_experiments.env_task_constants"):
        nominal_task_constants(Grid(31, 7), NOMINAL_BEARING)
    with pytest.raises(FileNotFoundError, match=str(constants_file)):
        _data.randomized_task_table()


@pytest.mark.parametrize("text", ["{not json", "[]", '{"nominal": {}}'])
def test_corrupt_task_constants_file_is_an_error(constants_file, text):
    constants_file.write_text(text)
    with pytest.raises(ValueError, match="gfb_experiments.env_task_constants"):
        nominal_task_constants(Grid(31, 7), NOMINAL_BEARING)


def test_untabulated_grid_is_computed_once_with_a_warning_naming_grid_reason_and_time(
    constants_file, monkeypatch
):
    from gfb_env.analysis import task_constants as _stability

    table = json.loads(_data.DATA_DIR.joinpath("task_constants.json").read_text())
    constants_file.write_text(json.dumps(table))
    calls = []
    monkeypatch.setattr(_stability, "task_constants", lambda model: calls.append(model.grid) or {"x": 1})
    # tabulated grid and bearing: the table, no warning, no computation
    assert nominal_task_constants(Grid(31, 7), NOMINAL_BEARING) == table["nominal"]["31x7"]
    with pytest.warns(TaskConstantsWarning, match=r"33x7 is not tabulated.*31x7, 79x7.*expected ~\d+ s"):
        assert nominal_task_constants(Grid(33, 7), NOMINAL_BEARING) == {"x": 1}
    assert nominal_task_constants(Grid(33, 7), NOMINAL_BEARING) == {"x": 1}  # once per process
    other = NOMINAL_BEARING.replace(clearance_m=45e-6)
    with pytest.warns(TaskConstantsWarning, match="31x7: the bearing differs"):
        nominal_task_constants(Grid(31, 7), other)
    assert calls == [Grid(33, 7), Grid(31, 7)]
    with pytest.raises(ValueError, match="no 'randomized' table"):
        constants_file.write_text(json.dumps({k: v for k, v in table.items() if k != "randomized"}))
        _data.load_task_constants.cache_clear()
        _data.randomized_task_table()
