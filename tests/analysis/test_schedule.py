"""The designed run-up schedule (``gfb schedule``, gfb_env.analysis.schedule) and its policy."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from gfb_agents.learned.evaluate import run_episode
from gfb_agents.policy import ControlSpec
from gfb_agents.rules.schedule import ScheduleAgent
from gfb_env.analysis.response import unbalance_response
from gfb_env.analysis.schedule import design_run_up_schedule, verify_schedule
from gfb_env.cli import main as gfb
from gfb_env.envs import RunUpEnv
from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.forcing import Unbalance
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters


@pytest.fixture(scope="module")
def model() -> GFBModel:
    return GFBModel("viscoelastic", "31x7", foil_stiffness=1.0)


@pytest.fixture(scope="module")
def schedule_055(model):
    return design_run_up_schedule(model, 0.55, fold_dampings=0, n_dampings=9)


def test_feasible_target_is_reached_at_the_best_damping_and_verified(model, schedule_055):
    sch = schedule_055
    j = int(np.nanargmax(sch.critical_bearing_numbers))
    assert sch.foil_damping == pytest.approx(sch.dampings[j], rel=0.6)  # the parabola's optimum, on the grid
    assert sch.feasible and sch.end_bearing_number == 0.55
    assert sch.safe_bearing_number == pytest.approx(0.95 * sch.critical_bearing_number)
    assert any("hysteresis band is unknown" in n for n in sch.notes)
    p = sch.path()
    assert p["speed_rpm"][0] == pytest.approx(model.bearing.speed_rpm_at(0.275))
    assert p["speed_rpm"][-1] == pytest.approx(model.bearing.speed_rpm_at(0.55))
    assert np.all(np.diff(p["speed_rpm"]) >= 0) and np.all(p["foil_damping"] == sch.foil_damping)
    v = verify_schedule(sch)
    assert v.status == "done" and v.max_whirl_amplitude < 1e-3 and v.min_film_thickness > 0.1
    assert v.unbalance == v.synchronous_xi == v.synchronous_eta == 0.0
    assert v.max_vibration_amplitude == v.max_whirl_amplitude


def test_verification_with_unbalance_separates_the_1x_orbit_from_the_whirl(model, schedule_055):
    """With an unbalance the hold vibrates at 1x: the fitted 1x orbit is the linear unbalance response at
    the end speed, and the non-synchronous rest (the whirl) stays ~0 on a safe schedule."""
    sch = schedule_055
    u = Unbalance(0.02, 0.7)
    v = verify_schedule(sch, unbalance=u)
    lin = unbalance_response(model, sch.end_bearing_number, u, sch.foil_damping, stability=False)
    assert v.status == "done" and v.unbalance == 0.02
    assert v.synchronous_xi == pytest.approx(lin.xi_amplitude, rel=0.02)
    assert v.synchronous_eta == pytest.approx(lin.eta_amplitude, rel=0.02)
    assert v.max_vibration_amplitude >= max(v.synchronous_xi, v.synchronous_eta) * 0.99
    assert v.max_whirl_amplitude < 0.02 * v.max_vibration_amplitude
    with pytest.raises(ValueError, match="unbalance"):
        verify_schedule(sch, unbalance=0.02)


def test_infeasible_target_goes_to_the_safe_speed(model):
    sch = design_run_up_schedule(model, 0.65, fold_dampings=0, n_dampings=9)
    assert not sch.feasible
    assert sch.end_bearing_number == sch.safe_bearing_number < 0.65
    assert sch.end_bearing_number == pytest.approx(0.95 * sch.critical_bearing_number)


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_fold_makes_the_hysteresis_band_part_of_the_safe_speed(model):
    # K_W = 1: subcritical Hopf, fold ~2.5 % below Lambda_c; with a 1 % margin the fold is the limit
    sch = design_run_up_schedule(model, 0.65, margin=0.01, fold_dampings=1, n_dampings=9)
    assert math.isfinite(sch.fold_bearing_number)
    assert 0.95 * sch.critical_bearing_number < sch.fold_bearing_number < sch.critical_bearing_number
    assert sch.safe_bearing_number == sch.fold_bearing_number and not sch.feasible


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["--target-rpm", "-5"], "--target-rpm"),
        (["--target-rpm", "30000", "--margin", "0.7"], "--margin"),
        (["--target-rpm", "30000", "--damping-range", "5", "1"], "--damping-range"),
        (["--target-rpm", "30000", "--start-rpm", "40000"], "--start-rpm"),
        (["--target-rpm", "30000", "--acceleration", "1e-6"], "--acceleration"),
        (["--target-rpm", "30000", "--grid", "313x25"], "--grid"),
        (["--target-rpm", "30000", "--fold-dampings", "99"], "--fold-dampings"),
        (["--target-rpm", "30000", "--unbalance", "2"], "--unbalance"),
        (["--target-rpm", "30000", "--unbalance-g-mm", "0"], "--unbalance-g-mm"),
        (["--target-rpm", "30000", "--balance-grade", "1e4"], "--balance-grade (at 30000 rpm)"),
        (["--target-rpm", "30000", "--unbalance", "0.1", "--unbalance-g-mm", "3"], "not allowed with"),
        (["--target-rpm", "30000", "--balance-grade", "2.5", "--rotor-mass-kg", "-1"], "--rotor-mass-kg"),
    ],
)
def test_cli_refuses_bad_options_at_once(argv, fragment, tmp_path, capsys):
    t0 = time.perf_counter()
    try:
        rc = gfb(["schedule", *argv, "--out", str(tmp_path / "o")])
    except SystemExit as exc:
        rc = exc.code
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and fragment in err, err
    assert time.perf_counter() - t0 < 5 and not (tmp_path / "o").exists()


def test_cli_writes_the_schedule_map_and_summary(tmp_path, capsys):
    out = tmp_path / "sch"
    rc = gfb(
        ["schedule", "--target-rpm", "33000", "--foil-stiffness", "1", "--fold-dampings", "0"]
        + ["--n-dampings", "7", "--balance-grade", "2.5", "--out", str(out), "--json"]
    )
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    for k in ("feasible", "max_safe_speed_rpm", "margin_to_critical", "verified_max_whirl_amplitude_um"):
        assert k in d, k
    # G 2.5 at the target speed; the verified 1x orbit is the linear one, the rotor does not whirl
    u = Unbalance.from_iso1940(BearingParameters(), 2.5, 33000)
    assert d["unbalance"] == pytest.approx(u.magnitude, rel=1e-12)
    assert d["unbalance_um"] == pytest.approx(50 * u.magnitude, rel=1e-12)
    assert d["verified_1x_xi_um"] == pytest.approx(d["linear_1x_xi_um"], rel=0.03)
    assert d["verified_1x_eta_um"] == pytest.approx(d["linear_1x_eta_um"], rel=0.03)
    assert d["verified_1x_eta_um"] > 0.1
    assert d["verified_max_whirl_amplitude_um"] < 0.05 * d["verified_max_vibration_amplitude_um"]
    assert d["feasible"] and d["end_speed_rpm"] == pytest.approx(33000)
    assert d["verified_status"] == "done" and d["verified_min_film_thickness_um"] > 1.0
    assert d["margin_to_critical"] >= 0.05 and d["fold_speed_rpm"] is None
    rows = (out / "schedule.csv").read_text().splitlines()
    assert rows[0] == "time_s,speed_rpm,foil_damping" and len(rows) == 102
    assert (out / "schedule.png").stat().st_size > 10_000


def test_the_schedule_as_a_policy_succeeds_on_run_up():
    """On the ideal machine (the class alone: g = 1, exact sensors) the designed schedule to a command
    below the best stable speed is a successful (certified, on target) RunUp episode."""
    env = RunUpEnv()
    u = env
    seed = next(s for s in range(30) if (env.reset(seed=s), env.speed_command)[1].bearing_number < 0.69)
    env.reset(seed=seed)
    m = GFBModel("viscoelastic", u.grid, bearing=NOMINAL_BEARING)
    lam_t = u.speed_command.bearing_number
    sch = design_run_up_schedule(m, lam_t, margin=0.04, fold_dampings=0, rate=u.max_rate(NOMINAL_BEARING))
    assert sch.feasible
    agent = ScheduleAgent.from_schedule(ControlSpec.from_env(env), sch)
    assert agent.ramp == pytest.approx(1.0) and agent.damping == sch.foil_damping
    res = run_episode(env, agent, seed=seed)
    assert res.success, res


def test_cli_exits_1_when_the_verified_rotor_whirls(tmp_path, capsys):
    """Inside the hysteresis band (no fold computed, 0.5 % margin) a large unbalance throws the rotor onto
    the whirl: the schedule is not verified, and the exit code says so."""
    argv = ["schedule", "--foil-stiffness", "1", "--target-rpm", "36400", "--margin", "0.005"]
    argv += ["--fold-dampings", "0", "--n-dampings", "5", "--unbalance", "0.15", "--json"]
    rc = gfb([*argv, "--out", str(tmp_path / "w")])
    d = json.loads(capsys.readouterr().out)
    assert rc == 1 and d["verified_stable"] is False and d["verified_status"] == "done"
    assert d["verified_max_whirl_amplitude_um"] > 20.0  # the developed whirl: ~51 um
    rc = gfb([*argv[:-3], "--json", "--out", str(tmp_path / "q")])  # the same without unbalance
    d = json.loads(capsys.readouterr().out)
    assert rc == 0 and d["verified_stable"] is True
