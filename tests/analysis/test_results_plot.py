"""The analysis results own their derived quantities and figures (issue 18, section 4; ROSS's shape:
``campbell_diagram(...)`` -> results object -> ``.plot()``): a Python user gets the numbers and the very
figures ``gfb`` writes (the PNG files compared byte for byte)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from gfb_env.analysis.campbell import campbell_diagram
from gfb_env.analysis.response import response_curve
from gfb_env.analysis.runup import RunUpAnalysis, analyse_run_up, bearing_number_rate, run_up
from gfb_env.analysis.schedule import STABLE_WHIRL_AMPLITUDE, design_run_up_schedule, verify_schedule
from gfb_env.cli import main
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel

GRID = "21x5"


def gfb(capsys, *argv) -> dict:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_campbell_results_and_figure_are_the_commands(tmp_path, capsys):
    d = gfb(capsys, "campbell", "--grid", GRID, "--n-speeds", "6", "--out", tmp_path / "cli", "--json")
    model = GFBModel("viscoelastic", GRID)
    cd = campbell_diagram(model, np.linspace(0.1, 1.2, 6), 1.0, 2)
    for key, value in cd.summary().items():
        assert d[key] == value, key
    assert cd.onset_frequency_hz == pytest.approx(model.bearing.frequency_hz(cd.onset_eigenvalue.imag), rel=0)
    assert 0.3 < cd.onset_whirl_frequency_ratio < 0.6
    fig = cd.plot()
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    cd.plot(tmp_path / "campbell.png")
    assert (tmp_path / "campbell.png").read_bytes() == (tmp_path / "cli" / "campbell.png").read_bytes()
    cd.write_csv(tmp_path / "campbell.csv")
    assert (tmp_path / "campbell.csv").read_bytes() == (tmp_path / "cli" / "campbell.csv").read_bytes()


def test_run_up_analysis_owns_onset_collapse_and_dominant_order(tmp_path, capsys):
    argv = [
        "--grid",
        GRID,
        "--acceleration",
        "50000",
        "--window",
        "64",
        "--coast-down",
        "--foil-damping",
        "1",
    ]
    d = gfb(capsys, "runup", *argv, "--out", tmp_path / "cli", "--json")
    model = GFBModel("viscoelastic", GRID)
    lo, hi = 0.5, 0.833
    res = run_up(
        model, 1.0, (lo, hi), bearing_number_rate(model, 50000.0), coast_down=True, record_interval=0.5
    )
    ru = analyse_run_up(res, model.bearing, 64.0, critical_bearing_number=None)
    assert isinstance(ru, RunUpAnalysis)
    s = ru.summary()
    for key in (
        "whirl_onset_speed_rpm",
        "whirl_collapse_speed_rpm",
        "top_speed_dominant_order",
        "max_1x_speed_rpm",
        "max_whirl_amplitude_um",
        "status",
        "steps",
    ):
        assert s[key] == d[key], key
    # the derived quantities are what their definitions say
    env, rpm = ru.envelope, ru.envelope_speed_rpm
    whirling_up = (env["whirl"] > ru.whirl_threshold) & (env["leg"] == 0)
    assert ru.whirl_onset_speed_rpm == (float(rpm[np.argmax(whirling_up)]) if whirling_up.any() else None)
    if ru.whirl_onset_speed_rpm is not None:
        assert ru.whirl_onset_speed_rpm > model.bearing.speed_rpm_at(lo)
    n_legs = len(np.unique(ru.waterfall.leg))  # a touchdown on the run-up leaves no coast-down
    for kind, n_axes in (("envelope", 4), ("waterfall", n_legs), ("orbits", 4)):
        fig = ru.plot(kind)
        assert isinstance(fig, Figure) and len(fig.axes) == n_axes, kind
    with pytest.raises(ValueError, match="kind must be one of"):
        ru.plot("bode")
    title = f"viscoelastic foil, K_W={model.foil_stiffness:.3g}, D_W=1, 50000 rpm/s"
    ru.plot_waterfall(tmp_path / "waterfall.png", title=title)
    assert (tmp_path / "waterfall.png").read_bytes() == (tmp_path / "cli" / "waterfall.png").read_bytes()
    ru.write_envelope_csv(tmp_path / "envelope.csv")
    assert (tmp_path / "envelope.csv").read_bytes() == (tmp_path / "cli" / "envelope.csv").read_bytes()


def test_response_curve_owns_its_peak_and_instability(tmp_path, capsys):
    d = gfb(
        capsys,
        "response",
        "--grid",
        GRID,
        "--unbalance",
        "0.01",
        "--n-speeds",
        "5",
        "--out",
        tmp_path / "cli",
        "--json",
    )
    model = GFBModel("viscoelastic", GRID)
    curve = response_curve(model, np.linspace(0.1, 1.0, 5), Unbalance(0.01), 1.0)
    assert len(curve) == 5 and curve[0].bearing_number == pytest.approx(0.1) and list(curve)[-1] is curve[-1]
    assert curve.peak.bearing_number == d["bearing_number"] and curve.peak.semi_major == d["semi_major"]
    assert curve.first_unstable_bearing_number == d["first_unstable_bearing_number"]
    assert all(r.stable for r in curve if r.bearing_number < (curve.first_unstable_bearing_number or np.inf))
    curve.plot(path=tmp_path / "response.png")
    assert (tmp_path / "response.png").read_bytes() == (tmp_path / "cli" / "response.png").read_bytes()
    assert isinstance(curve.plot(), Figure)


def test_schedule_owns_its_margins_and_the_verification_its_verdict(tmp_path, capsys):
    argv = [
        "--grid",
        GRID,
        "--target-rpm",
        "30000",
        "--fold-dampings",
        "0",
        "--n-dampings",
        "3",
        "--hold",
        "500",
    ]
    d = gfb(capsys, "schedule", *argv, "--out", tmp_path / "cli", "--json")
    model = GFBModel("viscoelastic", GRID)
    b = model.bearing
    sch = design_run_up_schedule(
        model,
        b.bearing_number_at(30000),
        rate=bearing_number_rate(model, 2500.0),
        n_dampings=3,
        fold_dampings=0,
        hold_tau=500.0,
    )
    assert (
        sch.margin_to_critical == d["margin_to_critical"]
        and sch.margin_to_fold is None is d["margin_to_fold"]
    )
    ver = verify_schedule(sch)
    assert ver.stable == d["verified_stable"] == (ver.max_whirl_amplitude < STABLE_WHIRL_AMPLITUDE)
    assert [row[0] for row in sch.stability_curve()] == pytest.approx(sch.dampings.tolist())
    sch.plot(tmp_path / "schedule.png")
    assert (tmp_path / "schedule.png").read_bytes() == (tmp_path / "cli" / "schedule.png").read_bytes()
