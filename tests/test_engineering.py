"""``gfb campbell`` and ``gfb runup`` (issue 12): outputs, conventions and the onset validation."""

import csv
import json
import time
from pathlib import Path

import numpy as np
import pytest

from gfb_env.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "bearings"
SMALL = EXAMPLES / "small_turbocompressor.toml"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("structure", ["rigid", "viscoelastic"])
def test_campbell_onset_equals_gfb_critical(tmp_path, capsys, structure):
    """Issue 12, Sect. 4: the zero of the log decrement is `gfb critical`'s Lambda_c to 1e-4."""
    common = ["--structure", structure, "--grid", "41x7", "--foil-damping", "2", "--json"]
    code, out, _ = run(capsys, "critical", *common)
    crit = json.loads(out)
    code2, out2, _ = run(
        capsys, "campbell", *common, "--bearing-range", "0.2", "1.0", "--n-speeds", "9", "--out", tmp_path
    )
    camp = json.loads(out2)
    assert code == code2 == 0
    assert camp["onset_bearing_number"] == pytest.approx(crit["critical_bearing_number"], abs=1e-4)
    assert camp["onset_speed_rpm"] == pytest.approx(crit["critical_speed_rpm"], rel=2e-4)
    assert camp["onset_whirl_frequency_ratio"] == pytest.approx(crit["whirl_frequency_ratio"], abs=1e-3)
    assert camp["min_log_decrement"] < 0 and camp["equilibria_failed"] == 0
    assert json.loads((tmp_path / "summary.json").read_text()) == camp


def test_campbell_csv_conventions_and_physical_units(tmp_path, capsys):
    code, out, _ = run(
        capsys, "campbell", "--bearing", SMALL, "--grid", "41x7", "--speed-range", "4000", "20000",
        "--n-speeds", "5", "--out", tmp_path, "--json",
    )  # fmt: skip
    assert code == 0
    from gfb_env.params import BearingParameters

    b = BearingParameters.from_toml(SMALL)
    rows = list(csv.DictReader((tmp_path / "campbell.csv").open()))
    assert len(rows) == 5 * 2
    for r in rows:
        f = {k: float(v) for k, v in r.items()}
        sigma, omega = f["growth_rate"], f["angular_frequency"]
        assert f["speed_rpm"] == pytest.approx(b.speed_rpm_at(f["bearing_number"]), rel=1e-7)
        assert f["frequency_hz"] == pytest.approx(omega / (2 * np.pi * b.time_scale_s), rel=1e-6)
        assert f["damping_ratio"] == pytest.approx(-sigma / np.hypot(sigma, omega), rel=1e-5, abs=1e-7)
        z = f["damping_ratio"]  # ROSS: delta = 2 pi zeta / sqrt(1 - zeta^2)
        assert f["log_decrement"] == pytest.approx(2 * np.pi * z / np.sqrt(1 - z * z), rel=1e-5, abs=1e-6)
        assert f["whirl_frequency_ratio"] == pytest.approx(omega / f["bearing_number"], rel=1e-6)
    d = json.loads(out)
    assert d["speed_rpm_range"] == pytest.approx([4000, 20000])
    assert 9000 < d["onset_speed_rpm"] < 12000  # this bearing whirls early (see docs/engineering.md)
    assert (tmp_path / "campbell.png").stat().st_size > 20_000


HOSTILE = [
    (["campbell", "--out", "{out}", "--n-speeds", "2"], "--n-speeds", "[3, 1000]"),
    (["campbell", "--out", "{out}", "--modes", "7"], "--modes", "[1, 6]"),
    (["campbell", "--out", "{out}", "--speed-range", "5000", "1000"], "--speed-range", "0 < MIN < MAX"),
    (["campbell", "--out", "{out}", "--bearing-range", "0", "1"], "--bearing-range", "positive"),
    (["campbell", "--out", "{out}", "--grid", "313x25"], "--grid", "dense eigenvalue"),
    (["campbell", "--out", "{file}"], "--out", "not a folder"),
]


@pytest.mark.parametrize("argv,option,fragment", HOSTILE, ids=[" ".join(a[2:5]) for a, _, _ in HOSTILE])
def test_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment):
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    out = tmp_path / "out"
    argv = [a.replace("{out}", str(out)).replace("{file}", str(a_file)) for a in argv]
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    stdout, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"gfb {argv[0]}: error:") and option in lines[0] and fragment in lines[0]
    assert stdout == "" and not out.exists()
    assert time.perf_counter() - t0 < 20


# ------------------------------------------------------------------------------------- runup
def test_runup_ramp_outputs_and_onset_after_the_linear_critical_speed(tmp_path, capsys):
    """A quick run (49x7: coarser grids whirl into contact; fast ramp; the paper's D_W ~ optimum):
    the speed column is the requested ramp, the whirl starts above the linear critical speed, the
    waterfall's top line is subsynchronous."""
    from gfb_env.params import BearingParameters

    code, out, _ = run(
        capsys, "runup", "--grid", "49x7", "--foil-damping", "4", "--speed-range", "28000", "42000",
        "--acceleration", "30000", "--window", "128", "--touchdown", "0.001", "--orbit-rpm", "30000,41000",
        "--out", tmp_path, "--json",
    )  # fmt: skip
    d = json.loads(out)
    assert code == 0, d
    b = BearingParameters()
    assert b.rate_rpm_per_s(d["bearing_number_rate"]) == pytest.approx(30_000, rel=1e-12)
    data = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header == "tau,time_s,speed_rpm,bearing_number,leg,xi_um,eta_um,min_film_thickness_um"
    t, rpm = data[:, 1], data[:, 2]
    assert np.allclose(rpm, 28_000 + 30_000 * t, rtol=1e-6)  # the ramp: 30 000 rpm/s from 28 000
    assert rpm[-1] == pytest.approx(42_000, abs=5)
    assert d["status"] == "done" and d["touchdown_speed_rpm"] is None
    assert d["critical_speed_rpm"] < d["whirl_onset_speed_rpm"] < 42_000
    assert 0.3 < d["top_speed_dominant_order"] < 0.5  # the whirl, not the 1x line (no unbalance)
    assert d["max_whirl_amplitude_um"] > 0.02 * 50
    assert d["min_film_thickness_um"] == pytest.approx(data[:, 7].min())
    for name in ("waterfall.png", "orbits.png", "envelope.png"):
        assert 20_000 < (tmp_path / name).stat().st_size < 200_000
    env = np.loadtxt(tmp_path / "envelope.csv", delimiter=",", skiprows=1)
    assert env.shape[1] == 10 and np.all(env[:, 4] <= env[:, 5])


def test_runup_stops_at_touchdown_and_reports_the_speed(tmp_path, capsys):
    code, out, _ = run(
        capsys, "runup", "--grid", "33x7", "--foil-damping", "1", "--speed-range", "30000", "45000",
        "--acceleration", "40000", "--window", "64", "--touchdown", "0.1", "--out", tmp_path, "--json",
    )  # fmt: skip
    d = json.loads(out)
    assert code == 0 and d["status"] == "touchdown"
    assert d["whirl_onset_speed_rpm"] <= d["touchdown_speed_rpm"] < 45_000
    assert d["min_film_thickness_um"] < 0.15 * 50


HOSTILE_RUNUP = [
    (["runup", "--out", "{out}", "--acceleration", "1"], "--acceleration", "at most 250000"),
    (["runup", "--out", "{out}", "--orbit-rpm", "90000"], "--orbit-rpm", "outside the speed range"),
    (["runup", "--out", "{out}", "--orbit-rpm", "fast"], "--orbit-rpm", "comma-separated"),
    (["runup", "--out", "{out}", "--window", "1"], "--window", "16 x --record-interval"),
    (["runup", "--out", "{out}", "--record-interval", "5"], "--record-interval", "1x line"),
    (["runup", "--out", "{out}", "--perturbation", "3", "0"], "--perturbation", "may move less than"),
    (["runup", "--out", "{out}", "--speed-range", "9", "3"], "--speed-range", "0 < MIN < MAX"),
    (["runup", "--out", "{file}/x"], "--out", "is a file"),
]


@pytest.mark.parametrize(
    "argv,option,fragment", HOSTILE_RUNUP, ids=[" ".join(a[3:5]) for a, _, _ in HOSTILE_RUNUP]
)
def test_runup_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment):
    test_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment)
