"""The integrator package's shape (issue 18, sec. 3-4): every setting lives once (IntegratorOptions, the
step-size controller included), one snapshot type, the statistics on the result, and one owner of the
compiled call's argument packing (a batch row unpacks to exactly the groups a single call passes)."""

import dataclasses
import json

import numpy as np
import pytest
from numba import njit

from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.integrator import (
    IntegratorOptions,
    IntegratorStatistics,
    StepperState,
    StepSizeController,
    TrapezoidalIntegrator,
)
from gfb_env.integrator.arguments import CALL_DTYPE, LoopOptions, call_row, unpack_row
from gfb_env.model import GFBModel


@pytest.fixture(scope="module")
def small():
    m = GFBModel("viscoelastic", grid="21x5", foil_stiffness=1.0)
    s0 = find_equilibrium(m, 0.6)
    return m, m.layout.with_rotor(s0, 0.3, 0.4)


def test_every_setting_lives_once_in_the_options(small):
    m, s = small
    it = TrapezoidalIntegrator(m, s, 0.6, 1.0, rtol=1e-5, touchdown_film_thickness=0.02)
    assert it.options == IntegratorOptions(rtol=1e-5, touchdown_film_thickness=0.02)
    for f in dataclasses.fields(IntegratorOptions):  # no mirrored copies beside the options
        assert not hasattr(it, f.name), f.name
    base = IntegratorOptions(atol=1e-5, max_step=1.0)
    it = TrapezoidalIntegrator(m, s, 0.6, options=base, rtol=1e-6)
    assert it.options == dataclasses.replace(base, rtol=1e-6) and base.rtol == IntegratorOptions.rtol
    with pytest.raises(TypeError, match="rtl"):
        TrapezoidalIntegrator(m, s, 0.6, rtl=1e-3)
    with pytest.raises(ValueError, match="rtol"):
        TrapezoidalIntegrator(m, s, 0.6, rtol=-1.0)
    with pytest.raises(ValueError, match="touchdown_film_thickness"):
        TrapezoidalIntegrator(m, s, 0.6, touchdown_film_thickness=1.5)
    with pytest.raises(ValueError, match="steps_per_revolution"):
        IntegratorOptions(steps_per_revolution=0.5)
    with pytest.raises(ValueError, match="options must be an IntegratorOptions"):
        TrapezoidalIntegrator(m, s, 0.6, options={"rtol": 1e-3})


def test_the_step_size_controller_is_a_validated_part_of_the_options(small):
    m, s = small
    c = IntegratorOptions().controller
    assert c == StepSizeController()
    assert (c.safety, c.reject_safety, c.min_factor, c.max_factor) == (0.8, 0.9, 0.2, 2.0)
    assert (c.error_exponent, c.newton_failure_factor) == (-1.0 / 3.0, 0.25)
    assert IntegratorOptions(controller={"safety": 0.7}).controller.safety == 0.7
    assert IntegratorOptions.from_mapping({"controller": {"max_factor": 3.0}}).controller.max_factor == 3.0
    with pytest.raises(ValueError, match=r"controller\.safety"):
        StepSizeController(safety=1.5)
    with pytest.raises(ValueError, match=r"controller\.max_factor"):
        IntegratorOptions(controller={"max_factor": 0.5})
    with pytest.raises(ValueError, match="unknown key"):
        IntegratorOptions(controller={"safty": 0.7})
    # the compiled loop reads the controller from the options: the defaults given explicitly are the
    # default run bit for bit, another growth limit is another step sequence
    ref = TrapezoidalIntegrator(m, s, 0.6).advance(40.0, record_interval=0.5)
    same = TrapezoidalIntegrator(m, s, 0.6, controller=StepSizeController()).advance(
        40.0, record_interval=0.5
    )
    slow = TrapezoidalIntegrator(m, s, 0.6, controller={"max_factor": 1.2}).advance(40.0, record_interval=0.5)
    assert np.array_equal(ref.trajectory.xi, same.trajectory.xi) and ref.statistics == same.statistics
    assert slow.steps > ref.steps


def test_a_batch_row_unpacks_to_the_groups_of_the_single_call(small):
    m, s = small
    it = TrapezoidalIntegrator(m, s, 0.6, 1.0, unbalance=Unbalance(0.01, 0.3), max_newton_iterations=5)
    it.add_shock(HalfSineShock(start_tau=2.0, duration_tau=0.5, peak_acceleration=0.1))
    c = it.prepare(7.5, 0.65, 1.2, 0.5, None, 1234)
    assert c.forcing is not None and c.options.max_steps == 1234 and c.options.max_newton_iterations == 5
    calls = np.zeros(1, CALL_DTYPE)
    calls[0] = call_row(
        c.st.clock, c.schedule, c.options, c.recording, (c.first, c.rec_buf.shape[0]), c.forcing
    )

    @njit
    def unpack(calls):
        return unpack_row(calls[0])

    clock, schedule, opt, rec_t, rows = unpack(calls)
    assert clock == c.st.clock and schedule == c.schedule
    assert isinstance(opt, LoopOptions) and opt == c.options
    assert rec_t == (c.recording.interval, c.recording.first_tau) and rows == (c.first, c.rec_buf.shape[0])
    row = calls[0]
    assert (bool(row["forced"]), int(row["n_shocks"])) == (True, 1)
    assert (row["unbalance"], row["forcing_angle"], row["forcing_max_step"]) == (
        c.forcing.unbalance, c.forcing.angle, c.forcing.max_step
    )  # fmt: skip


def test_one_snapshot_type_with_a_json_form(small):
    m, s = small
    it = TrapezoidalIntegrator(m, s, 0.6, 1.0, unbalance=Unbalance(0.01, 0.3))
    it.add_shock(HalfSineShock(start_tau=12.0, duration_tau=0.5, peak_acceleration=0.1))
    it.advance(10.0, bearing_number=0.62, record_interval=0.5)
    for gone in ("get_state", "set_state", "stats"):
        assert not hasattr(it, gone), gone
    text = json.dumps(it.snapshot().as_dict())
    tail = it.advance(20.0, record_interval=0.5)
    end = it.state
    it.restore(StepperState.from_dict(json.loads(text)))
    again = it.advance(20.0, record_interval=0.5)
    assert np.array_equal(tail.trajectory.xi, again.trajectory.xi) and np.array_equal(it.state, end)
    assert tail.statistics == again.statistics and isinstance(tail.statistics, IntegratorStatistics)
    assert tail.steps == tail.statistics.steps > 0
