"""experiments/v1_task_check.py: the agent choice and the gain-window scan behind WhirlRecovery-v1's prior."""

import pytest

from gfb_experiments.v1_task_check import gain_window, main


def test_unknown_agent_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--agents", "oracle_v1,bogus", "--tasks", "gfb_env/RunUp-v1"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--agents: unknown bogus" in err[0]


def test_gain_window_ends_of_the_decade_touch_down_at_once():
    """At g = 0.316 and 3.16 (the run-up tasks' prior ends) the start whirl with d_opt kept touches down
    within 3 control steps: why WhirlRecovery-v1 draws g in [0.6, 1.8] only."""
    res = gain_window(n_gains=2, seeds=(0,), steps=5)
    steps = [s for v in res["touchdown_step_by_gain"].values() for s in v]
    assert len(steps) == 2 and all(1 <= s <= 3 for s in steps), res
