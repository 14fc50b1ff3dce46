"""The Cramer-Rao bound of issue 19's identifiability report (experiments/identifiability_bound.py): its
Fisher information on a measurement with a known answer, and its plant against the tasks' constants."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_env.envs._data import load_task_constants
from gfb_experiments.identifiability_bound import DrawnPlant, fisher_information


def test_fisher_information_of_a_linear_complex_measurement() -> None:
    """m = a t1 + b t2 (complex vectors), noise sd s on each real part: F_ij = n Re(a_i^H a_j) / s^2, and
    the bound on t1 alone is s / sqrt(n |a|^2)."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal(2) + 1j * rng.standard_normal(2)
    b = rng.standard_normal(2) + 1j * rng.standard_normal(2)
    n, s = 5, 0.1
    F = fisher_information([(n, [a, b])], s)
    expect = n / s**2 * np.real(np.array([[np.vdot(a, a), np.vdot(a, b)], [np.vdot(b, a), np.vdot(b, b)]]))
    np.testing.assert_allclose(F, expect, rtol=1e-12)
    (f1,) = fisher_information([(n, [a])], s).ravel()
    assert 1 / math.sqrt(f1) == pytest.approx(s / math.sqrt(n * np.sum(np.abs(a) ** 2)))
    # two rows add
    np.testing.assert_allclose(fisher_information([(2, [a, b]), (3, [a, b])], s), F)


def test_the_centre_draw_is_the_tasks_nominal_plant() -> None:
    """RunUp-v2's nominal bearing: at its optimum damping the critical speed is lambda_best's."""
    c = load_task_constants()
    nom = c["nominal"]["31x7"]
    p = DrawnPlant()
    b = p.nominal
    draw = {
        "ln_g": 0.0,
        "ln_C": math.log(b.clearance_m),
        "ln_fK": 0.0,
        "ln_FL": math.log(b.external_load_per_bearing_n),
    }
    assert p.critical_rpm(draw, nom["d_opt"]) == pytest.approx(b.speed_rpm_at(nom["lambda_best"]), rel=1e-4)
    # the 1x is linear in the eccentricity and turns with its phase
    z1 = p.one_x_um(draw, 0.9 * b.speed_rpm_at(nom["lambda_best"]), 2.0, 0.3)
    z2 = p.one_x_um(draw, 0.9 * b.speed_rpm_at(nom["lambda_best"]), 2.0, 0.6j)
    np.testing.assert_allclose(z2, 2j * z1, rtol=1e-12)
