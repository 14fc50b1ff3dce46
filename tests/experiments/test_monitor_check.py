"""``python -m gfb_experiments.monitor_check`` (issue 19 s.2): the vibration monitor on the real plant."""

from __future__ import annotations

import json

import pytest

from gfb_experiments.monitor_check import main


def test_the_monitor_reads_the_linear_1x_and_the_developed_whirl(tmp_path, capsys):
    out = tmp_path / "check"
    assert main(["--seeds", "0", "--fractions", "0.8", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert len(s["one_x"]) == 4  # (constant speed, largest ramp) x (X, Y)
    # the monitor's 1x of the exact readings is the linear unbalance response (results/monitor_check: 3.6e-4)
    assert s["one_x_max_exact_relative_error_constant_speed"] < 1e-3
    assert s["one_x_max_exact_relative_error"] < 5e-3
    for r in s["one_x"]:
        assert abs(r["noisy_amplitude_z"]) < 5 and r["exact_subsynchronous_um_rms"] < 0.05
    # a developed whirl: a large band level at the limit cycle's frequency ratio, little 1x
    (w,) = s["whirl"]
    for p in ("x", "y"):
        q = w[p]
        assert q["subsynchronous_um_rms"] > 100 * q["noise_floor_um_rms"]
        assert q["subsynchronous_um_rms"] == pytest.approx(w["true_orbit_um_rms"][p], rel=0.05)
        assert abs(q["subsynchronous_ratio"] - w["limit_cycle_ratio"]) < 0.02
        assert q["synchronous_um_pp"] < 0.2 * q["direct_um_pp"]
    assert "whirl seed 0" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "word"),
    [
        (["--seeds", "a"], "--seeds"),
        (["--seeds", "20000"], "--seeds"),
        (["--fractions", "1.2"], "--fractions"),
    ],
)
def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys, args, word):
    with pytest.raises(SystemExit) as exc:
        main([*args, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0]
