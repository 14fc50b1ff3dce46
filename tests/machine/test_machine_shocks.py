"""Random base-shock arrivals: Poisson counts, stated distributions, determinism, the record's fields."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gfb_env.machine import ShockArrivals, ShockEvent


def test_event_record_carries_the_forcing_arguments():
    # HalfSineShock.from_physical(bearing, start_s, peak_g, duration_ms, direction_deg)
    names = [f.name for f in dataclasses.fields(ShockEvent)]
    assert names == ["time_s", "peak_g", "duration_ms", "direction_deg"]


def test_poisson_counts_over_control_steps():
    gen = ShockArrivals(rate_per_s=3.0)
    rng = np.random.default_rng(0)
    dt = 9.54e-3
    counts = np.array([len(gen.draw(rng, k * dt, (k + 1) * dt)) for k in range(100_000)])
    # mean = variance = rate * dt for a Poisson count (0.0286); 100 000 steps: rel. error ~0.6 %
    assert counts.mean() == pytest.approx(3.0 * dt, rel=0.04)
    assert counts.var() == pytest.approx(3.0 * dt, rel=0.05)
    # over the whole 954 s: 3 per second
    assert counts.sum() / (100_000 * dt) == pytest.approx(3.0, rel=0.04)


def test_event_distributions():
    gen = ShockArrivals(rate_per_s=50.0, peak_g_range=(2.0, 20.0), duration_ms_range=(5.0, 15.0))
    rng = np.random.default_rng(1)
    ev = gen.draw(rng, 10.0, 210.0)  # ~10 000 events
    t = np.array([e.time_s for e in ev])
    assert np.all(np.diff(t) >= 0) and t.min() >= 10.0 and t.max() < 210.0
    gaps = np.diff(t)  # exponential inter-arrival times: mean = std = 1 / rate
    assert gaps.mean() == pytest.approx(1 / 50.0, rel=0.04)
    assert gaps.std() == pytest.approx(1 / 50.0, rel=0.05)
    lp = np.log([e.peak_g for e in ev])
    assert lp.min() >= math.log(2.0) and lp.max() <= math.log(20.0)
    assert lp.mean() == pytest.approx(0.5 * math.log(40.0), abs=0.02)  # log-uniform
    assert lp.std() == pytest.approx(math.log(10.0) / math.sqrt(12.0), rel=0.03)
    d = np.array([e.duration_ms for e in ev])
    assert d.min() >= 5.0 and d.max() <= 15.0 and d.mean() == pytest.approx(10.0, abs=0.1)
    a = np.array([e.direction_deg for e in ev])
    assert a.min() >= 0.0 and a.max() < 360.0 and a.mean() == pytest.approx(180.0, abs=4.0)


def test_draws_only_from_the_generator_and_none_without_a_rate():
    gen = ShockArrivals(rate_per_s=5.0)
    a = gen.draw(np.random.default_rng(4), 0.0, 2.0)
    b = gen.draw(np.random.default_rng(4), 0.0, 2.0)
    assert a == b and len(a) > 0
    rng = np.random.default_rng(4)
    state = rng.bit_generator.state
    assert ShockArrivals.none().draw(rng, 0.0, 100.0) == []
    assert gen.draw(rng, 1.0, 1.0) == []
    assert rng.bit_generator.state == state


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"rate_per_s": -1.0}, "rate_per_s"),
        ({"peak_g_range": (0.0, 5.0)}, "peak_g_range"),
        ({"duration_ms_range": (10.0, 5.0)}, "duration_ms_range"),
        ({"direction_deg_range": (0.0, math.inf)}, "direction_deg_range"),
    ],
)
def test_shock_arrivals_refuse_bad_values_by_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ShockArrivals(**kwargs)
    with pytest.raises(ValueError, match="end_s"):
        ShockArrivals().draw(np.random.default_rng(0), 2.0, 1.0)
