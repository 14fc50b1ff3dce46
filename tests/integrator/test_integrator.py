import dataclasses
import json
import math

import numpy as np
import pytest

from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import (
    IntegrationError,
    IntegrationStatus,
    IntegratorStatistics,
    StepperState,
    Trajectory,
    TrapezoidalIntegrator,
)
from gfb_env.model import GFBModel


@pytest.fixture(scope="module")
def small_visco():
    m = GFBModel("viscoelastic", grid="21x5", foil_stiffness=1.0)
    return m, find_equilibrium(m, 0.6)


def test_equilibrium_stays_at_rest(small_visco):
    m, s0 = small_visco
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    res = it.advance(50.0)
    assert res.status == "done"
    assert np.abs(it.state - s0).max() < 1e-7
    assert res.steps < 40  # steps grow to max_step at rest


def _fixed_step_run(m, s0, h, tau_end):
    # huge tolerances: no step is ever rejected; the Newton test uses the same weights, so its
    # tolerance must be tiny (1e-18 * 1e6) to solve every step to ~1e-12 rather than stop after one
    # correction of the predictor
    it = TrapezoidalIntegrator(
        m, s0, 0.6, 1.0, rtol=1e6, atol=1e6, first_step=h, max_step=h, newton_tol=1e-18,
        max_newton_iterations=30,
    )  # fmt: skip
    res = it.advance(tau_end)
    assert res.statistics.rejected_steps == 0 and res.statistics.newton_failures == 0
    assert res.steps == round(tau_end / h)
    return it.state


def test_trapezoidal_rule_is_second_order(small_visco):
    """Fixed steps h, h/2, h/4 from a smooth state (the stiff pressure transient of a displaced start
    has decayed): the rotor error falls by ~4 per halving."""
    m, s0 = small_visco
    it = TrapezoidalIntegrator(
        m, m.layout.with_rotor(s0, 0.2, 0.5, 0.0, 0.05), 0.6, 1.0, rtol=1e-6, atol=1e-6
    )
    it.advance(20.0)
    smooth = it.state
    rot = m.layout.rotor_slice
    ref = _fixed_step_run(m, smooth, 0.4 / 32, 8.0)[rot]
    errs = [np.abs(_fixed_step_run(m, smooth, h, 8.0)[rot] - ref).max() for h in (0.4, 0.2, 0.1)]
    ratios = [errs[0] / errs[1], errs[1] / errs[2]]
    assert all(3.3 < r < 4.7 for r in ratios), (errs, ratios)


def test_limit_cycle_amplitude_converges_as_tolerance_shrinks():
    """Rigid bearing, 31x5 grid, Lambda = 0.6: the whirl settles into a limit cycle whose max
    eccentricity converges as rtol = atol shrinks (measured 0.97803, 0.97772, 0.97755, 0.97743, 0.97739
    for 1e-2 ... 1e-4)."""
    m = GFBModel("rigid", grid="31x5")
    s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.3, 0.3)
    amp = {}
    for tol in (1e-2, 1e-3, 1e-4):
        it = TrapezoidalIntegrator(m, s0, 0.6, rtol=tol, atol=tol)
        tr = it.advance(800.0, record_interval=0.05).trajectory
        amp[tol] = tr.eccentricity[tr.tau > 600].max()
    assert 0.9 < amp[1e-4] < 1.0
    assert abs(amp[1e-3] - amp[1e-4]) < abs(amp[1e-2] - amp[1e-4])
    assert abs(amp[1e-2] - amp[1e-4]) / amp[1e-4] < 2e-3
    assert abs(amp[1e-3] - amp[1e-4]) / amp[1e-4] < 5e-4


def test_quadratic_predictor_saves_newton_iterations():
    """Work counts, not timings: in a developed whirl (rigid, 31x5, Lambda = 0.6) the quadratic state
    predictor needs 3.26 right-hand sides per step (Newton iterations plus the final one); the linear
    predictor it replaced needed 3.55 with the same settings (3.66 with its old ones)."""
    m = GFBModel("rigid", grid="31x5")
    s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.3, 0.3)
    res = TrapezoidalIntegrator(m, s0, 0.6).advance(800.0)
    assert res.status == "done"
    assert res.statistics.rhs_evaluations / res.steps < 3.4
    assert res.statistics.factorizations < 0.06 * res.steps  # reuse within a factor 2 of the factored step


def test_rigid_bearing_near_equilibrium_runs_to_2000_without_nan():
    m = GFBModel("rigid")
    s0 = find_equilibrium(m, 0.6)
    s0 = m.layout.with_rotor(s0, *(m.layout.rotor(s0)[:2] + [0.01, 0.0]))
    it = TrapezoidalIntegrator(m, s0, 0.6)
    res = it.advance(2000.0, record_interval=1.0, raise_on_failure=False)
    assert res.status in ("done", "touchdown")
    assert np.all(np.isfinite(it.state))
    tr = res.trajectory
    assert np.all(np.isfinite(tr.xi)) and np.all(np.isfinite(tr.eta))
    if res.status == "done":
        assert res.tau == pytest.approx(2000.0)
        assert res.max_eccentricity < 1.0 and res.min_film_thickness > it.options.touchdown_film_thickness
        assert tr.eccentricity[-500:].max() > 0.8  # the whirl developed (rigid Lambda_c < 0.6)
    else:
        assert res.touchdown is not None and np.isfinite(res.touchdown.tau)


def test_touchdown_is_an_event_with_time_and_position():
    m = GFBModel("rigid", grid="21x5")
    s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.0, 0.6, 0.0, 0.4)  # thrown downwards
    it = TrapezoidalIntegrator(m, s0, 0.6, touchdown_film_thickness=0.3)
    res = it.advance(100.0, record_interval=0.1)
    assert res.status == "touchdown"
    ev = res.touchdown
    assert 0 < ev.tau <= res.tau < 100
    assert np.hypot(ev.xi, ev.eta) == pytest.approx(0.7, abs=0.05)  # rigid: H_min = 1 - eps
    assert np.all(np.isfinite(it.state))


def test_same_inputs_same_trajectory_bit_for_bit(small_visco):
    m, s0 = small_visco
    s0 = m.layout.with_rotor(s0, 0.3, 0.4, 0.0, 0.0)
    runs = []
    for _ in range(2):
        it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
        tr = it.advance(100.0, bearing_number=0.7, foil_damping=2.0, record_interval=0.5).trajectory
        runs.append((it.state, tr.xi, tr.eta))
    for a, b in zip(runs[0], runs[1]):
        assert np.array_equal(a, b)


def test_snapshot_restore_continues_identically(small_visco):
    m, s0 = small_visco
    s0 = m.layout.with_rotor(s0, 0.3, 0.4)
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    it.advance(30.0, bearing_number=0.65)
    snap = it.snapshot()
    a = it.advance(60.0, bearing_number=0.7, record_interval=0.5).trajectory
    sa = it.state
    it.advance(90.0)  # wander off, then restore
    it.restore(snap)
    b = it.advance(60.0, bearing_number=0.7, record_interval=0.5).trajectory
    assert np.array_equal(sa, it.state)
    assert np.array_equal(a.xi, b.xi) and np.array_equal(a.tau, b.tau)


def test_recording_is_uniform_across_calls_and_schedule_is_linear(small_visco):
    m, s0 = small_visco
    it = TrapezoidalIntegrator(m, s0, 0.5, 1.0)
    probes = m.layout.midplane_probe_indices(3)
    parts = [
        it.advance(t, bearing_number=0.5 + t / 100, record_interval=0.25, record_indices=probes).trajectory
        for t in (3.1, 7.0, 10.0)
    ]
    whole = Trajectory.concatenate(parts)
    tau = whole.tau
    np.testing.assert_allclose(np.diff(tau), 0.25, atol=1e-9)
    assert tau[0] == 0.0 and tau[-1] == pytest.approx(10.0)
    assert whole.probes.shape == (len(tau), 3)
    lam = whole.bearing_number
    np.testing.assert_allclose(lam, 0.5 + tau / 100, atol=1e-12)
    assert parts[0].probes.shape == (len(parts[0].tau), 3)
    assert it.bearing_number == pytest.approx(0.6)


def test_failure_is_reported_never_nan(small_visco):
    m, s0 = small_visco
    s0 = m.layout.with_rotor(s0, 0.3, 0.4, 0.2, 0.0)
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0, rtol=1e-14, atol=1e-14, min_step=1e-2)
    with pytest.raises(IntegrationError, match="min_step"):
        it.advance(10.0)
    res = it.advance(10.0, raise_on_failure=False)
    assert res.status == "failed" and "min_step" in res.message
    assert np.all(np.isfinite(it.state))


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"rtol": 0.0}, "rtol"),
        ({"atol": -1.0}, "atol"),
        ({"max_step": math.nan}, "max_step"),
        ({"touchdown_film_thickness": 1.5}, "touchdown_film_thickness"),
        ({"foil_damping": 0.0}, "foil_damping"),
    ],
)
def test_invalid_integrator_arguments(small_visco, kwargs, match):
    m, s0 = small_visco
    args = {"foil_damping": 1.0} | kwargs
    with pytest.raises(ValueError, match=match):
        TrapezoidalIntegrator(m, s0, 0.6, **args)


def test_invalid_advance_arguments(small_visco):
    m, s0 = small_visco
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    it.advance(1.0)
    with pytest.raises(ValueError, match="tau_end"):
        it.advance(0.5)
    with pytest.raises(ValueError, match="record_interval"):
        it.advance(2.0, record_interval=0.0)
    with pytest.raises(ValueError, match="bearing_number"):
        it.advance(2.0, bearing_number=-0.1)
    bad = s0.copy()
    bad[0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        it.reset(bad, 0.6, 1.0)


def test_status_is_an_enum_that_compares_as_text(small_visco):
    m, s0 = small_visco
    res = TrapezoidalIntegrator(m, s0, 0.6, 1.0).advance(5.0)
    assert res.status is IntegrationStatus.DONE and res.status == "done" and res.ok
    s1 = m.layout.with_rotor(s0, 0.3, 0.4, 0.2, 0.0)
    res = TrapezoidalIntegrator(m, s1, 0.6, 1.0).advance(10.0, max_steps=3, raise_on_failure=False)
    assert res.status is IntegrationStatus.MAX_STEPS and res.status == "max_steps" and not res.ok
    assert res.steps == 3
    it = TrapezoidalIntegrator(m, s1, 0.6, 1.0, rtol=1e-14, atol=1e-14, min_step=1e-2)
    res = it.advance(10.0, raise_on_failure=False)
    assert res.status is IntegrationStatus.FAILED and not res.ok
    rigid = GFBModel("rigid", grid="21x5")
    s2 = rigid.layout.with_rotor(find_equilibrium(rigid, 0.6), 0.0, 0.6, 0.0, 0.4)
    res = TrapezoidalIntegrator(rigid, s2, 0.6, touchdown_film_thickness=0.3).advance(100.0)
    assert res.status is IntegrationStatus.TOUCHDOWN and res.status == "touchdown" and res.ok
    assert [str(s) for s in IntegrationStatus] == ["done", "touchdown", "failed", "max_steps"]


def test_stepper_state_round_trips_and_is_a_copy(small_visco):
    m, s0 = small_visco
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4), 0.6, 1.0)
    it.advance(20.0, bearing_number=0.65, foil_damping=1.5, record_interval=0.5)
    snap = it.snapshot()
    assert isinstance(snap, StepperState)
    assert snap.tau == it.tau == 20.0 and snap.history == 2
    assert snap.bearing_number == pytest.approx(0.65) and snap.foil_damping == pytest.approx(1.5)
    assert snap.step == it.step_size and snap.previous_step > 0 and snap.previous_step2 > 0
    assert snap.last_record_tau == 20.0
    assert snap.statistics == it.statistics and snap.statistics.steps > 0
    # the dict form (plain JSON values) packs and unpacks every field
    d = json.loads(json.dumps(it.snapshot().as_dict()))
    assert d["bearing_number"] == snap.bearing_number and d["foil_damping"] == snap.foil_damping
    back = StepperState.from_dict(d)
    for name in StepperState.__dataclass_fields__:
        a, b = getattr(snap, name), getattr(back, name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, name
    # copies, not views: advancing changes neither the snapshot nor the dict
    s_before = snap.s.copy()
    tail = it.advance(30.0, record_interval=0.5)
    assert np.array_equal(snap.s, s_before) and np.array_equal(d["s"], s_before)
    it.restore(snap)
    again = it.advance(30.0, record_interval=0.5)
    assert np.array_equal(tail.trajectory.xi, again.trajectory.xi)
    it.restore(StepperState.from_dict(d))
    assert np.array_equal(it.advance(30.0, record_interval=0.5).trajectory.xi, tail.trajectory.xi)
    with pytest.raises(ValueError, match="shape"):
        it.restore(dataclasses.replace(snap, s=snap.s[:-1]))


def test_statistics_are_named_and_summed_over_calls(small_visco):
    m, s0 = small_visco
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4), 0.6, 1.0)
    a = it.advance(10.0, record_interval=1.0)
    b = it.advance(20.0, record_interval=1.0)
    st = it.statistics
    assert isinstance(st, IntegratorStatistics)
    assert st.steps == a.steps + b.steps
    assert st.rejected_steps == a.statistics.rejected_steps + b.statistics.rejected_steps
    assert st.jacobians == a.statistics.jacobians + b.statistics.jacobians
    assert st.rhs_evaluations == a.statistics.rhs_evaluations + b.statistics.rhs_evaluations
    assert st.recorded_samples == len(a.trajectory) + len(b.trajectory) - 1  # the tau = 0 sample
    assert a.statistics + b.statistics == st and list(st.as_array())[0] == st.steps
    it.reset(s0, 0.6, 1.0)
    assert it.statistics == IntegratorStatistics()
