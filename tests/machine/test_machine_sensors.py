"""Proximity probes and pressure taps: geometry, bias, noise statistics, no draws when ideal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_env.machine import PressureTaps, ProximityProbes

S2 = math.sqrt(0.5)


def test_probe_geometry_45_degrees_either_side_of_the_top():
    p = ProximityProbes.ideal()
    # journal 10 um toward +xi: X (upper +xi side) sees it approach, Y (upper -xi side) recede
    x, y = p.read_um(10.0, 0.0)
    assert x == pytest.approx(10 * S2, rel=1e-14) and y == pytest.approx(-10 * S2, rel=1e-14)
    # journal 10 um up (eta is positive downward, along gravity): both probes see it approach
    x, y = p.read_um(0.0, -10.0)
    assert x == pytest.approx(10 * S2, rel=1e-14) and y == pytest.approx(10 * S2, rel=1e-14)
    # down by gravity: both recede; the inverse recovers (xi, eta)
    rng = np.random.default_rng(1)
    xi, eta = rng.normal(size=50) * 20, rng.normal(size=50) * 20
    back = p.displacement_um(*p.read_um(xi, eta))
    assert np.allclose(back[0], xi, atol=1e-12) and np.allclose(back[1], eta, atol=1e-12)
    # a fixed bias adds to the readings
    assert p.read_um(0.0, 0.0, np.array([1.5, -2.0])) == (1.5, -2.0)


def test_other_probe_angles_and_parallel_probes_refused():
    p = ProximityProbes(x_angle_deg=90.0, y_angle_deg=0.0, noise_um=0.0, bias_spread_um=0.0)
    x, y = p.read_um(3.0, 4.0)  # X horizontal toward +xi, Y at the top (eta up is toward it)
    assert x == pytest.approx(3.0) and y == pytest.approx(-4.0)
    with pytest.raises(ValueError, match="parallel"):
        ProximityProbes(x_angle_deg=45.0, y_angle_deg=45.0)


def test_probe_bias_alone_is_a_constant_error_in_the_xi_eta_frame():
    p = ProximityProbes(noise_um=0.0, bias_um=(3.0, -1.0), bias_spread_um=0.0)
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    bias = p.draw_bias(rng)
    t = np.linspace(0, 60, 121)
    err = p.measurement_errors(rng, 5 * np.sin(t), 5 * np.cos(t), 1e-4, bias)
    assert rng.bit_generator.state == state  # no noise, no spread: nothing drawn
    # the bias read back through the geometry: (xi, eta) = inverse of the probe directions
    assert np.allclose(err.position_um, p.displacement_um(3.0, -1.0), atol=1e-14)
    assert np.all(err.extent_um == 0.0) and np.all(err.velocity_um_per_s == 0.0)


def test_probe_noise_statistics():
    p = ProximityProbes(noise_um=0.3, bias_um=(0.0, 0.0), bias_spread_um=0.0, velocity_window=5)
    rng = np.random.default_rng(3)
    dt = 7.95e-5  # 0.5 tau of the nominal bearing
    xi = eta = np.zeros(121)
    pos, vel, ext = [], [], []
    for _ in range(4000):
        e = p.measurement_errors(rng, xi, eta, dt, np.zeros(2))
        pos.append(e.position_um)
        vel.append(e.velocity_um_per_s)
        ext.append(e.extent_um)
    pos, vel, ext = np.array(pos), np.array(vel), np.array(ext)
    # orthogonal probes: the noise of xi and eta is that of one probe, uncorrelated, zero mean
    assert np.abs(pos.mean(axis=0)).max() < 4 * 0.3 / math.sqrt(4000)
    assert pos.std(axis=0) == pytest.approx([0.3, 0.3], rel=0.05)
    assert abs(np.corrcoef(pos.T)[0, 1]) < 0.06
    # least-squares slope over 5 samples: std = sigma / (dt sqrt(sum (k - 2)^2)) = sigma / (dt sqrt(10))
    assert vel.std(axis=0) == pytest.approx([0.3 / (dt * math.sqrt(10))] * 2, rel=0.05)
    # the extent of 121 samples of pure noise: max - min of 121 normals ~ 5.2 sigma
    assert ext.mean(axis=0) == pytest.approx([5.2 * 0.3] * 2, rel=0.05)


def test_probe_bias_spread_is_drawn_per_episode():
    p = ProximityProbes(noise_um=0.0, bias_um=(1.0, -2.0), bias_spread_um=1.5)
    rng = np.random.default_rng(5)
    b = np.array([p.draw_bias(rng) for _ in range(5000)])
    assert b.mean(axis=0) == pytest.approx([1.0, -2.0], abs=4 * 1.5 / math.sqrt(5000))
    assert b.std(axis=0) == pytest.approx([1.5, 1.5], rel=0.05)


def test_probe_noise_is_deterministic_with_the_seed():
    p = ProximityProbes()
    xi = np.linspace(0, 1, 121)
    a = p.measurement_errors(np.random.default_rng(7), xi, xi, 1e-4, np.zeros(2))
    b = p.measurement_errors(np.random.default_rng(7), xi, xi, 1e-4, np.zeros(2))
    c = p.measurement_errors(np.random.default_rng(8), xi, xi, 1e-4, np.zeros(2))
    assert np.array_equal(a.position_um, b.position_um) and np.array_equal(a.extent_um, b.extent_um)
    assert not np.array_equal(a.position_um, c.position_um)
    # a single sample (the reset) still gets a velocity noise from the padded earlier samples
    one = p.measurement_errors(np.random.default_rng(7), xi[:1], xi[:1], 1e-4, np.zeros(2))
    assert np.all(one.velocity_um_per_s != 0.0) and np.all(one.extent_um == 0.0)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"noise_um": -0.1}, "noise_um"),
        ({"bias_um": 3.0}, "bias_um"),
        ({"bias_um": (0.0, math.nan)}, "bias_um"),
        ({"bias_spread_um": math.inf}, "bias_spread_um"),
        ({"velocity_window": 1}, "velocity_window"),
        ({"velocity_window": 2.5}, "velocity_window"),
    ],
)
def test_probes_refuse_bad_values_by_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ProximityProbes(**kwargs)


def test_pressure_taps_noise_and_bias_statistics():
    taps = PressureTaps(noise_kpa=0.35, bias_kpa=0.5, bias_spread_kpa=0.9)
    rng = np.random.default_rng(11)
    biases = np.array([taps.draw_bias(rng, 8) for _ in range(2000)])
    assert biases.mean() == pytest.approx(0.5, abs=4 * 0.9 / math.sqrt(16000))
    assert biases.std() == pytest.approx(0.9, rel=0.03)
    fixed = np.linspace(-1, 1, 8)
    errs = np.array([taps.errors_kpa(rng, fixed) for _ in range(4000)])
    assert np.allclose(errs.mean(axis=0), fixed, atol=4 * 0.35 / math.sqrt(4000))
    assert errs.std(axis=0) == pytest.approx(np.full(8, 0.35), rel=0.06)
    # a reading is the true pressure in kPa plus the error
    r = taps.read_kpa(np.full(8, 101_325.0), np.random.default_rng(0), fixed)
    assert r == pytest.approx(101.325 + taps.errors_kpa(np.random.default_rng(0), fixed), rel=1e-15)


def test_ideal_pressure_taps_draw_nothing():
    taps = PressureTaps.ideal()
    assert taps.is_ideal and not PressureTaps().is_ideal
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert np.all(taps.draw_bias(rng, 8) == 0.0) and np.all(taps.errors_kpa(rng, np.zeros(8)) == 0.0)
    assert rng.bit_generator.state == state
    with pytest.raises(ValueError, match="noise_kpa"):
        PressureTaps(noise_kpa=-1.0)
