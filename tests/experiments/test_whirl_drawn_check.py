"""``gfb_experiments.whirl_drawn_check``: a drawn plant held in WhirlRecovery's whirl (issue 19's
redesign measurement), and one clear line for bad input."""

from __future__ import annotations

import json

import pytest

from gfb_experiments.whirl_drawn_check import hold_whirl, main


def test_a_drawn_plant_whirls_steadily_at_the_start_speed_and_the_row_is_consistent():
    r = hold_whirl(0, 1.03, None, 12)
    assert r["touchdown_step"] is None  # DEV seed 0: g = 1.21, a steady whirl (results/task_redesign)
    assert 0.3 < r["orbit_after_10"] < 1.2 and abs(r["orbit_last"] - r["orbit_after_10"]) < 0.05
    assert r["speed_rpm"] == pytest.approx(1.03 * r["best_speed_rpm"], rel=2e-3)
    assert 0.6 <= r["gain"] <= 1.8


def test_the_command_writes_its_summary(tmp_path, capsys):
    out = tmp_path / "w.json"
    assert main(["--seeds", "1", "--steps", "10", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    data = json.loads(out.read_text())
    assert data["summary"] == summary and len(data["rows"]) == 1 and summary["touchdowns"] == 0


@pytest.mark.parametrize(
    "argv, fragment",
    [(["--seeds", "0"], "--seeds"), (["--factor", "-1"], "--factor"), (["--gain", "nan"], "--gain")],
)
def test_bad_input_is_one_line_and_exit_2(argv, fragment, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0]
