"""The parallel batch call's work claiming (issue 20): the threads take the envs one at a time from an
atomic work index, the costliest of the last call first; neither the order nor the thread count changes
a bit of any result.  No timing here (``python -m gfb_experiments.bench_env`` measures)."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from numba import njit

from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import BatchAdvance, TrapezoidalIntegrator
from gfb_env.integrator.batch import _COST_OF_COUNT, _claim
from gfb_env.model import GFBModel


@njit
def _claims(counter, k):
    out = np.empty(k, np.int64)
    for i in range(k):
        out[i] = _claim(counter)
    return out


def test_claim_returns_the_index_before_adding_one():
    counter = np.array([5], np.int64)
    assert _claims(counter, 4).tolist() == [5, 6, 7, 8]
    assert counter[0] == 9


def _fleet() -> list[TrapezoidalIntegrator]:
    m = GFBModel("viscoelastic", grid="31x7", foil_stiffness=1.0)
    s = find_equilibrium(m, 0.5)
    L = m.layout
    return [
        TrapezoidalIntegrator(m, s, 0.5, 1.0),
        TrapezoidalIntegrator(m, L.with_rotor(s, 0.1, 0.3, 0.05, -0.1), 0.5, 1.2),  # costlier: a transient
        TrapezoidalIntegrator(m, s, 0.5, 0.8, unbalance=Unbalance(2e-3, 0.4)),
        TrapezoidalIntegrator(m, s, 0.5, 1.0),
        TrapezoidalIntegrator(m, L.with_rotor(s, -0.2, 0.1, 0.0, 0.1), 0.5, 1.0),
    ]


def _run(threads: int, scramble: bool) -> list:
    its = _fleet()
    batch = BatchAdvance(num_threads=threads)
    out = []
    for call in range(3):
        lam = [0.5 + 0.03 * call + 0.01 * k for k in range(len(its))]
        res = batch.advance(its, [it.tau + 4.0 for it in its], lam, [None] * len(its), record_interval=0.2)
        ws = batch._ws
        # the cost the next call orders its claims by: the counts of this call
        assert np.array_equal(ws.cost[: len(its)], ws.stacked.stats[: len(its)] @ _COST_OF_COUNT)
        if scramble:  # any order of claims: the same bits
            ws.cost[: len(its)] = np.random.default_rng(call).permutation(len(its))
        out += [(r.steps, r.trajectory.xi.tobytes(), it.state.tobytes(), it.tau) for r, it in zip(res, its)]
    return out


def test_the_order_of_claims_and_the_threads_change_no_bit():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba sees one core")
    one = _run(1, False)
    assert one == _run(2, False) == _run(2, True)
    assert len({steps for steps, *_ in one}) > 1  # the envs did cost different amounts
