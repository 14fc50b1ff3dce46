"""gfb_experiments.friction_mu_sweep (issue 22): the run-up / turn / coast-down protocol and its refusals."""

from __future__ import annotations

import pytest

from gfb_env.analysis.stability import critical_bearing_number
from gfb_env.model import GFBModel


def test_viscoelastic_run_up_whirls_above_lambda_c_and_collapses_below_it():
    """Table 1's viscoelastic foil at Fig. 5's D_W = 6.69, 79x7: the whirl starts above Lambda_c on the
    slow run-up (0.599 measured vs 0.561), settles to no touchdown, and collapses well below Lambda_c on
    the coast-down (0.520): a hysteresis band of 0.078."""
    from gfb_experiments.friction_mu_sweep import ramp_run

    m = GFBModel("viscoelastic", grid="79x7", foil_stiffness=2.337)
    lc = critical_bearing_number(m, 6.69).critical_bearing_number
    r = ramp_run(m, 6.69, lc, 2e-5)
    assert r["status"] == "done" and r["touchdown"] is None
    assert lc < r["onset"] < r["turn"] and r["collapse"] < lc - 0.02
    assert r["band"] == pytest.approx(r["onset"] - r["collapse"]) and r["band"] > 0.05


@pytest.mark.parametrize(
    "argv",
    [["--grid", "foo"], ["--rate", "0"], ["--mu", "0.1,-1"], ["--mu", "x"], ["--dw", "0"], ["--dw", "1,,2"]],
)
def test_friction_mu_sweep_refuses_bad_input_before_any_work(argv, tmp_path, capsys):
    from gfb_experiments.friction_mu_sweep import main

    with pytest.raises(SystemExit) as exc:
        main([*argv, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1]
    assert not (tmp_path / "o").exists()
