"""``python -m gfb_experiments.whirl_start_check``: the error of ln g after the reset and the first step."""

from __future__ import annotations

import pytest

from gfb_experiments.whirl_start_check import main, posterior_errors


def test_posterior_errors_on_a_few_validation_seeds():
    res = posterior_errors(4, 2)
    assert res["split"] == "validation" and res["reset"]["episodes"] == 4
    assert res["first_step"]["episodes"] == 2
    assert res["reset"]["rms_error"] < res["prior_sd"]
    assert 0.0 <= res["first_step"]["within_2sd"] <= 1.0 and res["first_step"]["seconds_per_episode"] > 0


@pytest.mark.parametrize(
    "argv, fragment",
    [(["--episodes", "0"], "--episodes must be >= 1"), (["--first-step", "300"], "--first-step in")],
)
def test_bad_arguments_are_one_line_and_exit_2(argv, fragment, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and fragment in err, err


def test_unwritable_out_is_refused_before_any_episode(tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(blocker / "x.json")])
    assert exc.value.code == 2 and "--out" in capsys.readouterr().err
