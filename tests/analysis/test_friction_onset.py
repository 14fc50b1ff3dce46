"""What sets the frictional foil's Lambda_c for 0 < mu_C < K_T/(K_W + K_T) (issue 22,
``gfb_experiments.friction_onset``): the slider offsets the scan's loading history leaves, and the set
of sliders on their Coulomb limit."""

from __future__ import annotations

from scipy.optimize import brentq

from gfb_env.analysis.stability import critical_bearing_number, linear_stability
from gfb_env.model import GFBModel

KW, KT = 1.0, 0.5
STUCK_FOIL_LC = 0.565238  # elastic K_W + K_T on 21x5 (tests/core/test_friction.py)


def n_held(m: GFBModel, s) -> int:
    """Sliders the linearisation drops (stuck, off the Coulomb limit by more than the slip band)."""
    return m.layout.size - len(m.linearised_states(s, 1.0))


#: the study's history and linearisation (the library's default is the spin-up with the sliders held)
SCAN = {"history": "scan", "sliders_on_limit": "slip"}


def frictional(mu: float) -> GFBModel:
    return GFBModel("frictional", grid="21x5", foil_stiffness=KW, stick_stiffness=KT, friction_coefficient=mu)


def test_all_stuck_critical_point_is_the_held_foil_with_the_scans_slider_offsets():
    """mu_C = 0.1: every slider sticks at Lambda_c, yet Lambda_c is 0.0093 above the stuck foil's; holding
    the sliders where the scan left them (mu_C = 1e6) gives the same Lambda_c, so the offsets S (a built-in
    deflection K_T S/(K_W + K_T)) are what moves it."""
    m = frictional(0.1)
    cp = critical_bearing_number(m, **SCAN)
    lc = cp.critical_bearing_number
    assert n_held(m, cp.state) == m.grid.n_columns == 20
    assert lc - STUCK_FOIL_LC > 5e-3
    held = frictional(1e6)
    lc_held = brentq(
        lambda lam: linear_stability(held, lam, guess=cp.state).growth_rate, lc - 0.02, lc + 0.02
    )
    assert abs(lc_held - lc) < 1e-5, (lc_held, lc)


def test_lambda_c_jumps_where_the_stuck_set_changes():
    """mu_C 0.24 -> 0.26: the sliders at Lambda_c go from all 20 stuck to 9 stuck (11 on their limit,
    linearised on the slip branch) and Lambda_c jumps up by 3.5e-3."""
    out = {}
    for mu in (0.24, 0.26):
        m = frictional(mu)
        cp = critical_bearing_number(m, **SCAN)
        out[mu] = (cp.critical_bearing_number, n_held(m, cp.state))
    assert out[0.24][1] == 20 and out[0.26][1] < 12, out
    assert out[0.26][0] - out[0.24][0] > 2e-3, out


def test_monotone_spinup_gives_a_definite_lambda_c_the_default_scan_does_not():
    """mu_C = 0.1: along a monotone spin-up (each equilibrium warm-started from the previous Lambda only)
    Lambda_c is the same at steps 0.004 and 0.002 (0.58039, 7 sliders stuck); the default scan's history
    (0.05 load stages and brent's iterates warm-started from above and below) gives 0.57456, all stuck."""
    from gfb_experiments.friction_onset import spinup_critical

    up = {h: spinup_critical(frictional(0.1), step=h)[:2] for h in (0.004, 0.002)}
    assert abs(up[0.004][0] - up[0.002][0]) < 1e-4 and up[0.004][1] == up[0.002][1] == 7, up
    scan = critical_bearing_number(frictional(0.1), **SCAN).critical_bearing_number
    assert up[0.002][0] - scan > 3e-3, (up, scan)


def test_friction_onset_refuses_bad_input_before_any_work(tmp_path, capsys):
    import pytest

    from gfb_experiments.friction_onset import main

    for argv in (["--grid", "foo"], ["--delta", "-1"], ["--transient-mu", "x"]):
        with pytest.raises(SystemExit) as exc:
            main([*argv, "--out", str(tmp_path / "o")])
        assert exc.value.code == 2
        assert len(capsys.readouterr().err.strip().splitlines()[-1]) > 0
    assert not (tmp_path / "o").exists()
