"""The compiled batch advance (issue 13): many integrators in one parallel call give, bit for bit, what
each integrator's own ``advance`` gives, over many calls, for forced and unforced integrators mixed,
shocks, different bearings of one grid, a touchdown and a solver failure in one of them, and any thread
count.  No timing here (``python -m gfb_experiments.bench_env`` measures)."""

from __future__ import annotations

import dataclasses

import numba
import numpy as np
import pytest

from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.integrator import BatchAdvance, IntegrationError, TrapezoidalIntegrator
from gfb_env.model import GFBModel

GRID = "31x7"  # the envs' grid: the compiled loop is shared with the env tests
PROBES = np.array([3, 40, 77])


def _models():
    stiff = GFBModel("viscoelastic", grid=GRID, foil_stiffness=1.0)
    soft = GFBModel("viscoelastic", grid=GRID, foil_stiffness=0.6)  # another bearing: other kernel args
    return stiff, soft


def _fleet() -> list[TrapezoidalIntegrator]:
    """Six integrators that differ in every way a batch may mix: bearing, start, unbalance, shocks,
    touchdown threshold, and one with tolerances below rounding (no step passes: it fails at once)."""
    stiff, soft = _models()
    s_stiff, s_soft = find_equilibrium(stiff, 0.5), find_equilibrium(soft, 0.5)
    L = stiff.layout
    its = [
        TrapezoidalIntegrator(stiff, s_stiff, 0.5, 1.0),
        TrapezoidalIntegrator(soft, s_soft, 0.5, 0.8, unbalance=Unbalance(2e-3, 0.4)),
        TrapezoidalIntegrator(stiff, L.with_rotor(s_stiff, 0.1, 0.3, 0.05, -0.1), 0.5, 1.2),
        TrapezoidalIntegrator(soft, s_soft, 0.5, 1.0),  # fails at once (below)
        # thrown downwards with a high touchdown threshold: touches down in the first call
        TrapezoidalIntegrator(
            stiff, L.with_rotor(s_stiff, 0.0, 0.6, 0.0, 0.4), 0.5, touchdown_film_thickness=0.3
        ),
        TrapezoidalIntegrator(stiff, s_stiff, 0.5, 1.0, unbalance=Unbalance(1e-3)),
    ]
    its[3].options = its[3].options.replace(rtol=1e-300, atol=1e-300, min_step=0.01)  # below rounding
    its[0].add_shock(HalfSineShock(start_tau=2.0, duration_tau=1.5, peak_acceleration=0.5, direction_rad=1.0))
    its[5].add_shock(HalfSineShock(start_tau=9.0, duration_tau=0.5, peak_acceleration=1.0))
    return its


def _schedule(call: int, n: int) -> tuple[list[float], list[float]]:
    """Each integrator's Lambda and D_W at the end of call ``call`` (ramps up and down, one held)."""
    lam = [0.5 + 0.04 * call * ((-1) ** k) + 0.01 * k for k in range(n)]
    dw = [None if k == 2 else 1.0 + 0.1 * ((call + k) % 3) for k in range(n)]
    return lam, dw


def _assert_same_result(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "trajectory":
            for g in dataclasses.fields(x):
                assert np.array_equal(getattr(x, g.name), getattr(y, g.name), equal_nan=True), g.name
        elif isinstance(x, float) and np.isnan(x):
            assert np.isnan(y), f.name
        else:
            assert x == y, f.name


def _assert_same_state(a: TrapezoidalIntegrator, b: TrapezoidalIntegrator) -> None:
    sa, sb = a.snapshot().as_dict(), b.snapshot().as_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        if isinstance(sa[k], np.ndarray):
            assert np.array_equal(sa[k], sb[k]), k
        else:
            assert sa[k] == sb[k] or (sa[k] != sa[k] and sb[k] != sb[k]), k


@pytest.mark.parametrize("threads", [1, 2])
def test_batch_is_bit_for_bit_the_one_by_one_advance(threads):
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"numba sees {numba.config.NUMBA_NUM_THREADS} core(s)")
    single, batched = _fleet(), _fleet()
    batch = BatchAdvance(num_threads=threads)
    n = len(single)
    statuses = set()
    for call in range(4):
        lam, dw = _schedule(call, n)
        want = [
            it.advance(it.tau + 6.0, lam[k], dw[k], record_interval=0.1, record_indices=PROBES,
                       raise_on_failure=False)
            for k, it in enumerate(single)
        ]  # fmt: skip
        got = batch.advance(
            batched, [it.tau + 6.0 for it in batched], lam, dw, record_interval=0.1, record_indices=PROBES,
            raise_on_failure=False,
        )  # fmt: skip
        for k in range(n):
            _assert_same_result(got[k], want[k])
            _assert_same_state(batched[k], single[k])
            statuses.add(str(got[k].status))
        if call == 1:  # the unbalance switched between calls, in both
            for its in (single, batched):
                its[2].set_unbalance(Unbalance(3e-3, 1.0))
    # the fleet really mixed what it claims to mix
    assert {"done", "touchdown", "failed"} <= statuses
    assert batched[3].statistics.steps == 0 and batched[0].statistics.steps > 0


def test_the_thread_count_does_not_change_any_bit():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba sees one core")
    runs = []
    for threads in (1, 2):
        its = _fleet()
        batch = BatchAdvance(num_threads=threads)
        lam, dw = _schedule(0, len(its))
        res = batch.advance(its, [8.0] * len(its), lam, dw, record_interval=0.2, raise_on_failure=False)
        runs.append((res, its))
    for a, b, ia, ib in zip(runs[0][0], runs[1][0], runs[0][1], runs[1][1], strict=True):
        _assert_same_result(a, b)
        _assert_same_state(ia, ib)


def test_integrators_of_other_grids_are_advanced_one_by_one_with_the_same_results():
    coarse = GFBModel("viscoelastic", grid=GRID, foil_stiffness=1.0)
    fine = GFBModel("viscoelastic", grid="35x7", foil_stiffness=1.0)
    make = lambda: [  # noqa: E731
        TrapezoidalIntegrator(coarse, find_equilibrium(coarse, 0.5), 0.5),
        TrapezoidalIntegrator(fine, find_equilibrium(fine, 0.5), 0.5),
    ]
    single, batched = make(), make()
    want = [it.advance(5.0, 0.55, record_interval=0.25) for it in single]
    got = BatchAdvance().advance(batched, [5.0, 5.0], [0.55, 0.55], [None, None], record_interval=0.25)
    for a, b, ia, ib in zip(got, want, batched, single, strict=True):
        _assert_same_result(a, b)
        _assert_same_state(ia, ib)


def test_a_bad_call_raises_as_one_by_one_would():
    """The integrators before the bad one are advanced, the bad one and those after are not."""
    its = _fleet()[:3]
    taus = [it.tau for it in its]
    with pytest.raises(ValueError, match="bearing_number"):
        BatchAdvance().advance(its, [5.0, 5.0, 5.0], [0.5, -1.0, 0.5], [1.0, 1.0, 1.0])
    assert its[0].tau == 5.0 and its[1].tau == taus[1] and its[2].tau == taus[2]


def test_failures_raise_after_the_whole_batch_when_asked():
    its = _fleet()[2:4]  # the second one fails
    with pytest.raises(IntegrationError, match="min_step"):
        BatchAdvance().advance(its, [4.0, 4.0], [0.5, 0.5], [1.0, 1.0])
    assert its[0].tau == 4.0  # advanced although its neighbour failed


def test_batch_argument_errors():
    its = _fleet()[:2]
    batch = BatchAdvance()
    with pytest.raises(ValueError, match="only once"):
        batch.advance([its[0], its[0]], [1.0, 1.0], [0.5, 0.5], [1.0, 1.0])
    with pytest.raises(ValueError, match="tau_end: 1 values for 2"):
        batch.advance(its, [1.0], [0.5, 0.5], [1.0, 1.0])
    assert batch.advance([], [], [], []) == []
    for bad in (0, -1, numba.config.NUMBA_NUM_THREADS + 1, True, 1.5):
        with pytest.raises(ValueError, match="num_threads"):
            BatchAdvance(num_threads=bad)
    assert BatchAdvance().num_threads == numba.config.NUMBA_NUM_THREADS
