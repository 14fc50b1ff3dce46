"""``gfb_experiments.diagnose_policy``: a committed policy's episode against the oracle's plan (one
validation seed), and one clear line for bad input."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import pytest

from gfb_experiments.diagnose_policy import FIELDS, diagnose, main, summarise

POLICY = Path(__file__).resolve().parents[2] / "agents" / "policies" / "RunUpRandomized-v2_student" / "seed0"


def test_a_committed_student_is_diagnosed_against_the_oracles_plan(tmp_path, capsys):
    (row,) = diagnose(POLICY, episodes=1)
    assert set(row) == set(FIELDS)
    assert row["steps"] == 250 or row["touchdown"]
    # the final speed is compared with the plant's best stable speed, consistently
    assert math.isclose(
        row["final_speed_rel"], row["final_speed_rpm"] / row["best_speed_rpm"] - 1, abs_tol=2e-4
    )
    assert row["oracle_damping_command"] > 0 and math.isfinite(row["oracle_return"])
    # the path's damping is the actual D_W = g x command: the command and the ratio to D_opt follow
    assert math.isclose(
        row["final_damping_rel"], math.log(row["final_foil_damping"] / row["best_foil_damping"]), abs_tol=1e-3
    )
    # reversals: sign changes of the damping path's moves, at most one per step; the oracle's plan has few
    assert 0 <= row["damping_reversals"] <= row["steps"] - 2
    assert 0 <= row["oracle_damping_reversals"] <= 3 and row["oracle_steps"] >= 1
    ratio = row["final_damping_command"] / row["oracle_damping_command"]
    assert math.isclose(math.log(ratio), row["final_damping_rel"], abs_tol=2e-3)
    out = tmp_path / "d.csv"
    assert main([str(POLICY), "--episodes", "1", "--out", str(out)]) == 0
    printed = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    written = list(csv.DictReader(out.open()))
    assert printed == written and float(written[0]["return"]) == pytest.approx(row["return"])


@pytest.mark.parametrize(
    "argv, fragment",
    [(["/nonexistent/run"], "no such folder"), ([str(POLICY), "--episodes", "0"], "--episodes")],
)
def test_bad_input_is_one_line_and_exit_2(argv, fragment, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0]


def test_reversals_count_the_turns_of_the_damping_path_and_skip_holds():
    from gfb_experiments.diagnose_policy import damping_reversals

    assert damping_reversals([1.0, 1.0, 1.0]) == 0
    assert damping_reversals([1.0, 2.0, 3.0, 3.0, 4.0]) == 0  # a hold is not a turn
    assert damping_reversals([1.0, 2.0, 1.0, 2.0, 1.0]) == 3  # a dither at every step
    assert damping_reversals([1.0, 2.0, 2.0, 1.5, 1.5, 3.0]) == 2  # up, (hold), down, (hold), up
    assert damping_reversals([2.0]) == 0 and damping_reversals([]) == 0


def test_the_summary_is_what_the_rows_say():
    rows = [
        {
            "return": 1.0,
            "success": True,
            "touchdown": False,
            "final_speed_rel": -0.01,
            "final_damping_command": 2.0,
            "oracle_damping_command": 1.0,
            "final_damping_rel": math.log(2.0),
        },
        {
            "return": -99.0,
            "success": False,
            "touchdown": True,
            "final_speed_rel": -0.05,
            "final_damping_command": 1.0,
            "oracle_damping_command": 2.0,
            "final_damping_rel": -math.log(2.0),
        },
        {
            "return": 5.0,
            "success": False,
            "touchdown": False,
            "final_speed_rel": -0.03,
            "final_damping_command": 4.0,
            "oracle_damping_command": 4.0,
            "final_damping_rel": 0.0,
        },
    ]
    s = summarise(rows)
    assert (s["successes"], s["touchdowns"]) == (1, 1)
    assert s["final_speed_rel_median"] == pytest.approx(-0.02) and s["final_speed_rel_range"] == [
        -0.03,
        -0.01,
    ]
    assert s["abs_log_damping_error_mean"] == pytest.approx(2 * math.log(2.0) / 3)
    assert -1.0 <= s["command_log_correlation"] <= 1.0 and s["mean_return"] == pytest.approx(-31.0)
    assert math.isnan(s["damping_reversals_per_100_steps"])  # rows without the counts
    for r, (k, ko, n, no) in zip(rows, [(10, 1, 250, 250), (4, 0, 50, 250), (6, 2, 200, 250)], strict=True):
        r.update(damping_reversals=k, oracle_damping_reversals=ko, steps=n, oracle_steps=no)
    s = summarise(rows)
    assert s["damping_reversals_per_100_steps"] == pytest.approx(100 * 20 / 500)
    assert s["oracle_damping_reversals_per_100_steps"] == pytest.approx(100 * 3 / 750)
