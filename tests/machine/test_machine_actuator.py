"""The foil-damping actuator: exact lag and rate limit over a held command, the gain, the ideal one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gfb_env.machine import FoilDampingActuator

LN10 = math.log(10.0)


def test_ideal_actuator_passes_the_command_exactly():
    act = FoilDampingActuator.ideal()
    assert act.is_ideal and not FoilDampingActuator().is_ideal
    st = act.start(3.7)
    for d in np.geomspace(0.1, 10.0, 37):
        st = act.step(st, float(d), 9.5e-3)
        assert st.foil_damping == d and st.indicated_damping == d  # bit for bit


def test_lag_step_response_is_the_analytic_exponential():
    act = FoilDampingActuator(time_constant_ms=10.0, rate_limit_decades_per_s=math.inf)
    d0, dc = 0.2, 5.0
    for dt in (1e-3, 9.5e-3, 30e-3):
        got = act.step(act.start(d0), dc, dt).foil_damping
        want = math.exp(math.log(dc) + (math.log(d0) - math.log(dc)) * math.exp(-dt / 10e-3))
        assert got == pytest.approx(want, rel=1e-13)
    # the state carries the lag exactly across steps (a semigroup): 3 x 3 ms == 9 ms
    st = act.start(d0)
    for _ in range(3):
        st = act.step(st, dc, 3e-3)
    assert st.foil_damping == pytest.approx(act.step(act.start(d0), dc, 9e-3).foil_damping, rel=1e-13)
    # and never overshoots, going down as well
    assert 0.2 < act.step(act.start(5.0), 0.2, 9.5e-3).foil_damping < 5.0


def test_rate_limit_alone_moves_log_damping_at_the_rate():
    act = FoilDampingActuator(time_constant_ms=0.0, rate_limit_decades_per_s=20.0)
    # 50 ms at 20 decades/s: one decade, 0.1 -> 1
    assert act.step(act.start(0.1), 10.0, 50e-3).foil_damping == pytest.approx(1.0, rel=1e-12)
    assert act.step(act.start(10.0), 0.1, 25e-3).foil_damping == pytest.approx(10**0.5, rel=1e-12)
    # 200 ms is more than the 100 ms the two decades need: exactly the target
    assert act.step(act.start(0.1), 10.0, 0.2).foil_damping == 10.0


@pytest.mark.parametrize(
    "d0, dc, dt", [(0.1, 10.0, 0.05), (10.0, 0.1, 0.02), (1.0, 1.3, 0.01), (0.1, 10.0, 0.2)]
)
def test_lag_with_rate_limit_matches_the_ode(d0, dc, dt):
    ta, r = 10e-3, 20.0 * LN10
    act = FoilDampingActuator(time_constant_ms=10.0, rate_limit_decades_per_s=20.0)

    def rhs(t, x):
        return [float(np.clip((math.log(dc) - x[0]) / ta, -r, r))]

    sol = solve_ivp(rhs, (0.0, dt), [math.log(d0)], rtol=1e-11, atol=1e-12, max_step=dt / 2000)
    assert math.log(act.step(act.start(d0), dc, dt).foil_damping) == pytest.approx(sol.y[0, -1], abs=1e-7)


def test_rate_limit_bounds_the_slope_over_substeps():
    act = FoilDampingActuator(time_constant_ms=10.0, rate_limit_decades_per_s=20.0)
    st, h = act.start(0.1), 1e-4
    logs = [math.log10(st.foil_damping)]
    for _ in range(1500):
        st = act.step(st, 10.0, h)
        logs.append(math.log10(st.foil_damping))
    rate = np.diff(logs) / h
    assert rate.max() == pytest.approx(20.0, rel=1e-9)  # the limit is reached (far from the target)
    assert rate.max() <= 20.0 * (1 + 1e-9)
    # the ramp ends 0.2 decade (r T_a) short of the target after (2 - 0.2) / 20 = 90 ms; then the lag
    assert logs[-1] == pytest.approx(1.0 - 0.2 * math.exp(-(0.15 - 0.09) / 10e-3), abs=1e-9)


def test_gain_scales_the_actual_damping_and_stays_hidden_in_the_indicated_one():
    act = FoilDampingActuator(time_constant_ms=10.0, rate_limit_decades_per_s=20.0)
    st = act.start(2.0, gain=1.6)
    for _ in range(100):  # 1 s: settled
        st = act.step(st, 1.0, 10e-3)
    assert st.foil_damping == pytest.approx(1.6, rel=1e-12)
    assert st.indicated_damping == pytest.approx(1.0, rel=1e-12)


def test_gain_draws_are_log_uniform_and_absent_without_a_range():
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert FoilDampingActuator(gain=1.3).draw_gain(rng) == 1.3
    assert rng.bit_generator.state == state  # no random number consumed
    act = FoilDampingActuator(gain_range=(0.5, 2.0))
    g = np.array([act.draw_gain(rng) for _ in range(20_000)])
    assert g.min() >= 0.5 and g.max() <= 2.0
    assert np.log(g).mean() == pytest.approx(0.0, abs=0.01)  # centre of [ln 0.5, ln 2]
    assert np.log(g).std() == pytest.approx(math.log(4.0) / math.sqrt(12.0), rel=0.02)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"time_constant_ms": -1.0}, "time_constant_ms"),
        ({"time_constant_ms": math.inf}, "time_constant_ms"),
        ({"rate_limit_decades_per_s": 0.0}, "rate_limit_decades_per_s"),
        ({"gain": 0.0}, "gain"),
        ({"gain_range": (2.0, 1.0)}, "gain_range"),
        ({"gain_range": (0.0, 1.0)}, "gain_range"),
    ],
)
def test_actuator_refuses_bad_values_by_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FoilDampingActuator(**kwargs)
