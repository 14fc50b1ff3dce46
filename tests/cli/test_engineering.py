"""``gfb campbell`` and ``gfb runup`` (issue 12): outputs, conventions and the onset validation."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_refused_at_once

from gfb_env.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "bearings"
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
    assert_refused_at_once(main, argv, option, fragment, capsys, out)


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
    assert env.shape[1] == 13 and np.all(env[:, 4] <= env[:, 5])
    # no unbalance: the whirl column is the half peak-to-peak of x, as before
    assert np.allclose(env[:, 12], 0.5 * (env[:, 5] - env[:, 4]), rtol=1e-6, atol=1e-5)
    assert d["unbalance"] == 0.0 and d["unbalance_um"] == 0.0


def test_runup_stops_at_touchdown_and_reports_the_speed(tmp_path, capsys):
    code, out, _ = run(
        capsys, "runup", "--grid", "33x7", "--foil-damping", "1", "--speed-range", "30000", "45000",
        "--acceleration", "40000", "--window", "64", "--touchdown", "0.1", "--out", tmp_path, "--json",
    )  # fmt: skip
    d = json.loads(out)
    assert code == 0 and d["status"] == "touchdown"
    assert d["whirl_onset_speed_rpm"] <= d["touchdown_speed_rpm"] < 45_000
    assert d["min_film_thickness_um"] < 0.15 * 50


def test_runup_that_touches_down_within_the_first_window_says_so(capsys):
    """A run that touches down before one waterfall window (the small turbocompressor whirls from
    10 881 rpm, the default range starts at Lambda = 0.5) is a computation's outcome: exit 1 naming the
    touchdown and its speed, not exit 2 blaming the window."""
    code, out, err = run(
        capsys, "runup", "--bearing", SMALL, "--grid", "21x5", "--foil-damping", "4", "--json"
    )
    assert code == 1 and out == ""
    assert len(err.strip().splitlines()) == 1
    assert "touchdown" in err and "rpm" in err and "--speed-range" in err


# ---------------------------------------------------------------------------- runup + unbalance
#: sub-critical run (Table 1, D_W = 4: critical ~33 300 rpm on 33x7), slow enough for the 1x orbit
#: to follow the speed (Lambda 0.30 -> 0.45 over ~2 800 tau)
UNBALANCED_RUNUP = ["--grid", "33x7", "--foil-damping", "4", "--speed-range", "18000", "27000",
                    "--acceleration", "20000", "--perturbation", "0", "0"]  # fmt: skip


def test_runup_with_unbalance_the_1x_line_is_the_linear_response(tmp_path, capsys):
    """Issue 12 with issue 10's unbalance: the order-tracked 1x amplitude of each window equals the
    linear unbalance response at the window's speed; without the unbalance the 1x line is ~0."""
    from gfb_env.analysis.response import unbalance_response
    from gfb_env.forcing import Unbalance
    from gfb_env.model import GFBModel
    from gfb_env.params import BearingParameters

    b = BearingParameters()
    code, out, _ = run(capsys, "runup", *UNBALANCED_RUNUP, "--balance-grade", "2.5", "--out",
                       tmp_path / "u", "--json")  # fmt: skip
    d = json.loads(out)
    assert code == 0 and d["status"] == "done", d
    u = Unbalance.from_iso1940(b, 2.5, 27_000)  # the grade at the top speed
    assert d["unbalance"] == pytest.approx(u.magnitude, rel=1e-12)
    assert d["unbalance_um"] == pytest.approx(u.magnitude * 50.0, rel=1e-12)
    assert d["top_speed_dominant_order"] == pytest.approx(1.0, abs=0.01)  # the 1x line dominates
    env = np.loadtxt(tmp_path / "u" / "envelope.csv", delimiter=",", skiprows=1)
    model = GFBModel("viscoelastic", "33x7")
    for j in (3, len(env) // 2, len(env) - 1):  # after the switch-on transient, mid-range, top
        lin = unbalance_response(model, env[j, 2], u, 4.0, stability=False)
        assert env[j, 10] == pytest.approx(lin.xi_amplitude * 50, rel=0.02), j
        assert env[j, 11] == pytest.approx(lin.eta_amplitude * 50, rel=0.02), j
    assert d["top_speed_1x_eta_um"] == pytest.approx(env[-1, 11], rel=1e-6)
    assert d["max_1x_amplitude_um"] >= d["top_speed_1x_eta_um"] > 0.5
    # the whirl column is the non-synchronous rest: far below the 1x orbit once settled
    assert np.all(env[3:, 12] < 0.2 * env[3:, 11]) and d["whirl_onset_speed_rpm"] is None
    code, out, _ = run(capsys, "runup", *UNBALANCED_RUNUP, "--out", tmp_path / "0", "--json")
    d0 = json.loads(out)
    assert code == 0 and d0["unbalance"] == 0.0
    assert d0["max_1x_amplitude_um"] < 1e-3 * d["max_1x_amplitude_um"]


def test_runup_waterfall_1x_line_and_the_rotation_angle():
    """The waterfall's 1x line (Hann spectrum, interpolated peak) carries the linear response, and the
    closed-form rotation angle of the samples is the one the integrator carried."""
    from gfb_env.analysis.response import unbalance_response
    from gfb_env.analysis.runup import bearing_number_rate, ramp_rotation_angle, run_up, waterfall
    from gfb_env.forcing import Unbalance
    from gfb_env.model import GFBModel

    model = GFBModel("viscoelastic", "33x7")
    rate = bearing_number_rate(model, 20_000)
    lams = (0.3, 0.45)
    res = run_up(model, 4.0, lams, rate, perturbation=(0, 0), unbalance=Unbalance(0.02, 1.0))
    assert res.status == "done"
    theta_end = ramp_rotation_angle(np.array([res.tau_ramp]), lams, rate, res.tau_ramp)[0]
    assert math.remainder(theta_end - res.final_rotation_angle, 2 * math.pi) == pytest.approx(0, abs=1e-8)
    wf = waterfall(res, 256.0)
    a1 = wf.order_amplitude(1.0)
    for j in (2, len(a1) // 2, len(a1) - 1):
        lin = unbalance_response(model, wf.bearing_number[j], 0.02, 4.0, stability=False)
        assert a1[j] == pytest.approx(lin.xi_amplitude, rel=0.04), j
    assert np.all(wf.order_amplitude(0.43)[2:] < 0.02 * a1[2:])  # no whirl line
    res0 = run_up(model, 4.0, lams, rate, perturbation=(0, 0))
    assert np.all(waterfall(res0, 256.0).order_amplitude(1.0) < 1e-4 * a1.max())


HOSTILE_RUNUP = [
    (["runup", "--out", "{out}", "--acceleration", "1"], "--acceleration", "at most 250000"),
    (["runup", "--out", "{out}", "--orbit-rpm", "90000"], "--orbit-rpm", "outside the speed range"),
    (["runup", "--out", "{out}", "--orbit-rpm", "fast"], "--orbit-rpm", "comma-separated"),
    (["runup", "--out", "{out}", "--window", "1"], "--window", "16 x --record-interval"),
    (["runup", "--out", "{out}", "--record-interval", "5"], "--record-interval", "1x line"),
    (["runup", "--out", "{out}", "--perturbation", "3", "0"], "--perturbation", "may move less than"),
    (["runup", "--out", "{out}", "--speed-range", "9", "3"], "--speed-range", "0 < MIN < MAX"),
    (["runup", "--out", "{file}/x"], "--out", "is a file"),
    (["runup", "--out", "{out}", "--unbalance", "1.5"], "--unbalance", "[0, 1)"),
    (["runup", "--out", "{out}", "--unbalance-g-mm", "-1"], "--unbalance-g-mm", "positive"),
    (["runup", "--out", "{out}", "--balance-grade", "0"], "--balance-grade", "positive"),
    (["runup", "--out", "{out}", "--balance-grade", "1000"], "--balance-grade", "must be below 1"),
    (["runup", "--out", "{out}", "--unbalance", "0.1", "--balance-grade", "2.5"], "--balance-grade",
     "not allowed with"),
    (["runup", "--out", "{out}", "--unbalance-g-mm", "1", "--rotor-mass-kg", "0"], "--rotor-mass-kg",
     "positive"),
    (["runup", "--out", "{out}", "--unbalance", "0.1", "--unbalance-phase-deg", "nan"],
     "--unbalance-phase-deg", "finite"),
]  # fmt: skip


@pytest.mark.parametrize(
    "argv,option,fragment", HOSTILE_RUNUP, ids=[" ".join(a[3:5]) for a, _, _ in HOSTILE_RUNUP]
)
def test_runup_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment):
    test_hostile_input_one_line_exit_2(tmp_path, capsys, argv, option, fragment)
