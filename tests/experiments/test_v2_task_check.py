"""``python -m gfb_experiments.v2_task_check`` (issue 19 s.4): the oracle on v1 and v2, same trajectory."""

from __future__ import annotations

import json

import pytest

from gfb_experiments.v2_task_check import main


def test_the_check_runs_both_versions_on_the_same_trajectory(tmp_path, capsys):
    out = tmp_path / "check"
    assert main(["--seeds", "0", "--tasks", "RunUp", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())["gfb_env/RunUp-v1"]
    assert s["v2_id"] == "gfb_env/RunUp-v2" and s["same_trajectory"] is True
    # seed 0: a shock rings in the scoring window; v1's certificate fails, v2's forgives it
    assert s["shock_in_window"] == 1.0 and s["success_v1"] == 0.0 and s["success_v2"] == 1.0
    assert s["forgiven_seeds"] == [0] and s["mean_return_v2"] > s["mean_return_v1"]
    assert "RunUp-v2" in capsys.readouterr().out


@pytest.mark.parametrize("args", [["--seeds", "100"], ["--tasks", "Nope"], ["--seeds", "x"]])
def test_bad_arguments_are_refused_in_one_line(args, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main([*args, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
