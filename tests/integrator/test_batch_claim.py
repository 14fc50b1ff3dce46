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


def _each_run(threads: int, fail_at: int | None = None) -> tuple[list, list[int]]:
    its = _fleet()
    batch = BatchAdvance(num_threads=threads)
    out, seen = [], []
    for call in range(2):
        lam = [0.5 + 0.03 * call + 0.01 * k for k in range(len(its))]
        calls = [it.prepare(it.tau + 4.0, lam[k], None, 0.2, None, 100_000) for k, it in enumerate(its)]
        got: dict[int, object] = {}

        def each(k, r, got=got):
            if fail_at is not None and len(got) == fail_at:
                raise RuntimeError("each failed")
            assert k not in got
            got[k] = r
            seen.append(k)

        batch.run_prepared_each(its, calls, each)
        out += [
            (got[k].steps, got[k].trajectory.xi.tobytes(), it.state.tobytes()) for k, it in enumerate(its)
        ]
    return out, seen


def test_results_handed_on_as_they_come_are_the_batch_results():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba sees one core")
    one, seen_one = _each_run(1)
    assert seen_one == list(range(5)) * 2  # one thread: in order, after the whole batch
    two, seen_two = _each_run(2)
    assert two == one and sorted(seen_two) == sorted(seen_one)


def test_an_error_in_each_propagates_after_the_workers_are_done():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba sees one core")
    with pytest.raises(RuntimeError, match="each failed"):
        _each_run(2, fail_at=2)
    batch = BatchAdvance(num_threads=2)
    its = _fleet()[:2]
    calls = [it.prepare(it.tau + 2.0, 0.5, None, 0.2, None, 100_000) for it in its]
    got = []
    batch.run_prepared_each(its, calls, lambda k, r: got.append(k))
    pool = batch._pool(1)
    assert sorted(got) == [0, 1] and batch._pool(1) is pool  # the pool is kept between calls


def test_a_copy_holds_no_threads_and_close_stops_them():
    import copy
    import pickle

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba sees one core")
    batch = BatchAdvance(num_threads=2)
    pool = batch._pool(1)
    for twin in (copy.deepcopy(batch), pickle.loads(pickle.dumps(batch))):
        assert twin._workers is None and twin.num_threads == 2
    batch.close()
    assert batch._workers is None and pool._shutdown
