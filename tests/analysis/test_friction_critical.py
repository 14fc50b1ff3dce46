"""The frictional foil's one Lambda_c (issue 22): the equilibrium of a quasi-static spin-up, linearised
with the sliders on their Coulomb limit held, and transients that confirm it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gfb_env.analysis.stability import critical_bearing_number, spinup_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel

KW, KT = 1.0, 0.5


def frictional(mu: float, grid: str = "21x5") -> GFBModel:
    return GFBModel("frictional", grid=grid, foil_stiffness=KW, stick_stiffness=KT, friction_coefficient=mu)


def test_spinup_lambda_c_is_step_independent_and_its_state_is_the_spinups():
    """mu_C = 0.1, 21x5: the same Lambda_c (0.574849) at spin-up steps 0.004 and 0.002, 0.0055 below the
    slip-branch linearisation of the same equilibria (0.580387); the state it reports is
    :func:`spinup_equilibrium`'s at Lambda_c, bit for bit."""
    m = frictional(0.1)
    cp = {h: critical_bearing_number(m, spinup_step=h) for h in (0.004, 0.002)}
    assert abs(cp[0.004].critical_bearing_number - cp[0.002].critical_bearing_number) < 1e-5
    lc = cp[0.002].critical_bearing_number
    assert lc == pytest.approx(0.574849, abs=2e-5)
    slip = critical_bearing_number(m, sliders_on_limit="slip").critical_bearing_number
    assert slip - lc > 5e-3, (slip, lc)
    np.testing.assert_array_equal(cp[0.002].state, spinup_equilibrium(m, lc))


@pytest.mark.slow  # 8-16 s: in `make test-slow` (the default run's 10-minute budget)
def test_spinup_lambda_c_is_where_a_small_perturbation_starts_to_grow():
    """15x5, mu_C = 0.1 (Lambda_c = 0.554627): a rotor kick xi' = 1e-4 from the spin-up's equilibrium,
    600 tau: the peak-to-peak of xi - xi_0 over the last 100 tau against tau 50-150 shrinks at
    0.97 Lambda_c (0.25 measured) and grows at 1.03 Lambda_c (4.2)."""
    m = frictional(0.1, "15x5")
    L = m.layout
    lc = critical_bearing_number(m).critical_bearing_number
    assert lc == pytest.approx(0.554627, abs=1e-4)
    for f, grows in ((0.97, False), (1.03, True)):
        lam = f * lc
        s = spinup_equilibrium(m, lam)
        it = TrapezoidalIntegrator(m, L.with_rotor(s, *(L.rotor(s)[:2] + [1e-4, 0.0])), lam)
        res = it.advance(600.0, record_interval=1.0)
        assert res.status == "done"
        x = res.trajectory.xi - L.rotor(s)[0]
        ratio = np.ptp(x[-100:]) / np.ptp(x[50:150])
        assert (ratio > 2.0) if grows else (ratio < 0.5), (f, ratio)


def test_other_structures_ignore_the_frictional_keywords():
    m = GFBModel("viscoelastic", grid="21x5", foil_stiffness=1.0)
    a = critical_bearing_number(m, 1.0)
    b = critical_bearing_number(m, 1.0, history="scan", sliders_on_limit="slip", spinup_step=0.01)
    assert a.critical_bearing_number == b.critical_bearing_number


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"history": "monotone"}, "history"),
        ({"sliders_on_limit": "half"}, "sliders_on_limit"),
        ({"spinup_step": 0.0}, "spinup_step"),
    ],
)
def test_bad_frictional_keywords_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        critical_bearing_number(frictional(0.1), **kwargs)


def test_cli_critical_uses_the_spinup_and_says_so(capsys):
    from gfb_env.cli import main

    argv = ["critical", "--structure", "frictional", "--foil-stiffness", "1", "--stick-stiffness", "0.5"]
    assert main([*argv, "--friction-coefficient", "0.1", "--grid", "21x5", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    lc = critical_bearing_number(frictional(0.1), bearing_range=(0.1, 3.0)).critical_bearing_number
    assert d["critical_bearing_number"] == pytest.approx(lc, abs=1e-12)
    assert d["equilibrium_history"].startswith("quasi-static spin-up") and d["sliders_on_limit"] == "stick"
