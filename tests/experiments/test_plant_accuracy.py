"""``python -m gfb_experiments.plant_accuracy`` (issue 20's accuracy contract): bad input is one line and
exit code 2 before any episode; a one-step run writes the per-entry numbers."""

import json

import pytest

from gfb_experiments import plant_accuracy


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--integrator-options", "[1]"], "--integrator-options must be a JSON object"),
        (["--env-kwargs", "{bad"], "--env-kwargs must be a JSON object"),
        (["--integrator-options", '{"rtol": -1}'], "rtol must be a finite positive number"),
        (
            ["--integrator-options", '{"whirl_growth_control": {"decay_rate": 0}}'],
            "whirl_growth_control.decay_rate",
        ),
        (["--seeds", "10000"], "DEV seeds"),
        (["--policies", "oracle"], "--policies: unknown"),
    ],
)
def test_bad_input_is_exit_code_2(argv, message, capsys, tmp_path):
    assert plant_accuracy.main([*argv, "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err


def test_a_one_step_run_reports_every_entry(tmp_path):
    argv = ["--tasks", "gfb_env/RunUp-v2", "--seeds", "0", "--policies", "hold", "--max-steps", "1"]
    argv += ["--integrator-options", '{"whirl_growth_control": {}}', "--out", str(tmp_path), "--name", "t"]
    assert plant_accuracy.main(argv) == 0
    d = json.loads((tmp_path / "t.json").read_text())
    (task,) = d["tasks"]
    assert task["verdicts_identical"] and len(task["episodes"]) == 1
    noisy = [e for e in task["entries"] if e["noise_rms"] > 0]
    assert {"xi", "eta", "pressure_0"} <= {e["entry"] for e in noisy}
    assert all(e["ratio_to_noise"] < 1 for e in noisy)  # one step from the same start
    assert (tmp_path / "t.csv").read_text().startswith("env_id,entry,noise_rms")
