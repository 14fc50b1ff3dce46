"""The frictional foil at mu_C = 0 is the standard linear solid (Zener element), the model of issue 19's
next task candidate (experiments/zener_check.py, docs/task_redesign.md).

With ``F_c = 0`` the slider law is the linear dashpot ``eta S' = K_T (Q - S)``: per column the foundation
K_W in parallel with a Maxwell arm.  Its complex stiffness ``K_W + K_T i w tau / (1 + i w tau)`` tends to
the paper's viscoelastic ``K_W + i w D_W`` for ``K_T -> oo`` with ``D_W = eta``, and a finite arm lowers
the loss at every frequency (so Lambda_c at the optimum falls as ``r = K_T / K_W`` falls)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_experiments.zener_check import ZenerPlant, fisher


@pytest.fixture(scope="module")
def p() -> ZenerPlant:
    return ZenerPlant()


@pytest.mark.parametrize("eta", [0.5, 2.24, 6.0])
def test_stiff_arm_is_the_viscoelastic_foil(p: ZenerPlant, eta: float) -> None:
    """K_T = 1e5 K_W: tau = eta / K_T is 1e-5 of the viscoelastic foil's time scale, so Lambda_c agrees
    to O(w tau) = 1e-5 (brent's xtol is 1e-5 as well)."""
    ve, zener = p.critical(eta, math.inf), p.critical(eta, 1e5)
    assert zener == pytest.approx(ve, abs=5e-5)


def test_stiff_arm_has_the_viscoelastic_one_x_response(p: ZenerPlant) -> None:
    for lam in (0.35, 0.6):
        a, b = p.one_x(2.24, math.inf, lam), p.one_x(2.24, 1e5, lam)
        assert np.abs(b - a).max() < 1e-4 * np.abs(a).max()


def test_a_softer_arm_lowers_the_boundary_at_the_optimum(p: ZenerPlant) -> None:
    """The arm's loss ``eta / (1 + (w tau)^2)`` falls with ``w tau = w eta / (r K_W)``: Lambda_c at the
    viscoelastic optimum (D_W = 2.24) falls monotonically as r falls, by more than 5 % at r = 2."""
    lc = [p.critical(2.24, r) for r in (math.inf, 30.0, 10.0, 3.0, 2.0)]
    assert all(a > b for a, b in zip(lc, lc[1:]))
    assert lc[-1] < 0.95 * lc[0]


def test_fisher_counts_the_unbalance_as_nuisance() -> None:
    """A row whose ``d z / d ln g`` is z itself (g only scales the amplitude) is confounded with |U|: the
    information matrix is singular in (ln g, Re U); the Re U entry is n |z|^2 / sd^2."""
    z = np.array([0.3 + 0.4j, -0.2 + 0.1j])
    u, sd, n = 0.01, 1e-3, 7
    F = fisher([(n, z, z.copy(), 1j * z)], u, sd)
    assert F[2, 2] == pytest.approx(n * np.sum(np.abs(z) ** 2) / sd**2)
    assert F[0, 0] == pytest.approx(u**2 * F[2, 2])
    assert abs(np.linalg.det(F[np.ix_([0, 2], [0, 2])])) < 1e-9 * F[0, 0] * F[2, 2]
    # a g that rotates the vector as well as scaling it (a phase) is told apart from the unbalance by a
    # second row at another damping where it does not: then the full matrix is regular
    F2 = fisher([(n, z, z * (1 + 0.5j), 0.1 * z), (n, z[::-1], 0.2 * z[::-1], 1j * z[::-1])], u, sd)
    assert np.linalg.matrix_rank(F2) == 4
