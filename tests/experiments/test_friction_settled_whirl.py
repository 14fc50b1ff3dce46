"""The describing-function check over a *settled* whirl (issue 22; slow: ~30 s): the paper grid,
Table 1's K_W = K_T = 2.337, mu_C = 0.3 (the friction that holds the run-up's whirl), Lambda = 0.57."""

from __future__ import annotations

import numpy as np
import pytest

from gfb_experiments import friction_describing_function as fdf


@pytest.mark.slow
def test_eq15_over_a_settled_whirl(tmp_path):
    s = fdf.main(
        ["--grid", "79x7", "--mu", "0.3", "--foil-stiffness", "2.337", "--stick-stiffness", "2.337",
         "--bearing-number", "0.57", "--duration", "4000", "--out", str(tmp_path)]
    )  # fmt: skip
    # settled: the orbit neither grows nor decays over the last period, a large whirl at ~0.47 x
    assert abs(s["eccentricity_growth_per_period"] - 1.0) < 1e-3
    assert 0.43 < s["whirl_ratio"] < 0.5 and s["max_eccentricity"] > 1.0
    cols = {k: np.array(v) for k, v in s["columns"].items()}
    assert np.all(cols["slider_energy"] >= -1e-12) and s["slipping_columns"] == 78
    # over the settled large whirl Eq. 15 is right in the median, within a factor 2 per column
    assert 0.8 < s["D_eq_over_D_eq15"]["median"] < 1.25
    assert 0.5 < s["D_eq_over_D_eq15"]["min"] and s["D_eq_over_D_eq15"]["max"] < 2.0
