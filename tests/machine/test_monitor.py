"""The vibration monitor (gfb_env.machine.monitor): exact recovery of synthetic signals, the band, the noise
predictions against Monte Carlo, the configuration's checks and the degenerate records."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_env.machine import ProximityProbes, VibrationMonitor
from gfb_env.machine.monitor import keyphasor_angles

N = 120  # samples per control step, as the envs record them
F_HZ = 700.0  # ~42 000 rpm: about the speed of the v1 tasks
REVS = 6.0  # revolutions per record (a 60-tau step)
SIGMA = 0.3  # the default probe noise, um


def record(ramp: float = 0.05, n: int = N, revs: float = REVS, angle0: float = 0.3):
    """Sample times (s) and rotation angles (rad) of a step whose speed ramps by ``ramp`` (a fraction),
    theta' = omega exactly as the integrator tracks it; and the step's mean speed (rad/s)."""
    om0 = 2 * math.pi * F_HZ
    t = np.arange(1, n + 1) * (revs / F_HZ / n)
    th = keyphasor_angles(t, 0.0, angle0, om0, t[-1], om0 * (1 + ramp))
    return t, th, (th[-1] - th[0]) / (t[-1] - t[0])


def synthetic(t, th, om, amp=1.0, lag_deg=70.0, sub=0.8, sub_ratio=0.45, mean=3.0, trend=100.0):
    """1x ``amp cos(theta - lag)`` + a sub-synchronous sinusoid at ``sub_ratio`` of the mean speed (a
    natural frequency: it does not follow the ramp) + mean + trend; and the sub part alone."""
    s = sub * np.sin(sub_ratio * om * t + 0.2)
    return amp * np.cos(th - math.radians(lag_deg)) + s + mean + trend * t, s


def rms(a):
    return float(np.sqrt(np.mean(np.square(a))))


def test_keyphasor_angles_are_the_integrators_theta():
    # theta(tau) = theta0 + Lambda0 (tau - tau0) + (Lambda1 - Lambda0) (tau - tau0)^2 / (2 span)
    th = keyphasor_angles(np.array([10.0, 40.0, 70.0]), 10.0, 1.0, 0.5, 70.0, 0.8)
    rate = 0.3 / 60
    assert th == pytest.approx([1.0, 1.0 + 15 + 0.5 * rate * 900, 1.0 + 30 + 0.5 * rate * 3600], rel=1e-14)
    with pytest.raises(ValueError, match="tau_end"):
        keyphasor_angles(np.array([0.0]), 1.0, 0.0, 0.5, 1.0, 0.5)


def test_exact_recovery_of_a_noise_free_signal_with_a_ramping_speed():
    t, th, om = record()
    x, s = synthetic(t, th, om)
    y, _ = synthetic(t, th, om, amp=0.4, lag_deg=300.0, sub=0.0, mean=-1.0, trend=0.0)
    r = VibrationMonitor().measure(t, x, y, th)
    assert r.valid and r.n_samples == N
    # the record spans N - 1 sample intervals; the speed is the key's mean over it
    assert r.revolutions == pytest.approx((th[-1] - th[0]) / (2 * math.pi), rel=1e-14)
    assert r.running_speed_rpm == pytest.approx(om * 60 / (2 * math.pi), rel=1e-14)
    assert 1.02 < r.running_speed_rpm / (F_HZ * 60) < 1.03
    # 1x under a speed ramp, mean and trend: exact up to the sub-synchronous part not in the band's
    # columns (0.45x lies between 0.383x and 0.467x); the level to its coverage (a few per cent)
    assert r.x.synchronous_um_pp == pytest.approx(2.0, rel=2e-3)
    assert r.x.synchronous_phase_lag_deg == pytest.approx(70.0, abs=0.1)
    assert r.x.subsynchronous_um_rms == pytest.approx(rms(s), rel=0.03)
    assert r.x.subsynchronous_ratio == pytest.approx(0.45, abs=2e-3)
    assert r.x.mean_um == pytest.approx(3.0 + 100.0 * 0.5 * (t[0] + t[-1]), rel=1e-3)
    assert r.x.trend_um_per_s == pytest.approx(100.0, rel=0.05)
    assert r.x.residual_um_rms < 0.01 * rms(s) and r.x.second_harmonic_um_pp < 2e-3
    # on a band column (0.3833x, 4 pairs over 0.30-0.55) the fit is exact
    x2, s2 = synthetic(t, th, om, sub_ratio=0.3 + 0.25 / 3)
    r2 = VibrationMonitor().measure(t, x2, x2, th).x
    assert r2.synchronous_um_pp == pytest.approx(2.0, rel=1e-10) and r2.residual_um_rms < 1e-10
    assert r2.synchronous_phase_lag_deg == pytest.approx(70.0, abs=1e-8)
    assert r2.trend_um_per_s == pytest.approx(100.0, rel=1e-8)
    assert r.x.direct_um_pp == pytest.approx(x.max() - x.min(), rel=1e-15)
    # exact probe: no noise, no predicted scatter
    assert r.x.synchronous_um_pp_std == 0.0 and r.x.subsynchronous_noise_floor_um_rms == 0.0
    # a pure 1x signal has no sub-synchronous level (the 1x is in the fit)
    assert r.y.synchronous_um_pp == pytest.approx(0.8, rel=1e-10)
    assert r.y.synchronous_phase_lag_deg == pytest.approx(300.0, abs=1e-8)
    assert r.y.subsynchronous_um_rms < 1e-10
    # the phasor is the response module's convention: signal = Re(Z e^{i theta})
    z = r.y.synchronous_phasor_um
    assert np.allclose(z.real * np.cos(th) - z.imag * np.sin(th), y + 1.0, atol=1e-10)


def test_a_pure_subsynchronous_signal_has_no_1x_and_its_frequency_is_found():
    t, th, om = record()
    for ratio in (0.37, 0.42, 0.49):
        _, s = synthetic(t, th, om, amp=0.0, sub=1.0, sub_ratio=ratio)
        r = VibrationMonitor().measure(t, s, s, th)
        assert r.x.synchronous_um_pp < 0.02  # 1 % of the whirl's 2 um pp (finite-record leakage)
        assert r.x.subsynchronous_ratio == pytest.approx(ratio, abs=2e-3)
    _, s = synthetic(t, th, om, amp=0.0, sub=1.0, sub_ratio=0.3 + 0.25 / 3)  # on a column: exactly none
    assert VibrationMonitor().measure(t, s, s, th).x.synchronous_um_pp < 1e-10


@pytest.mark.parametrize("revs", [4.3, 6.0, 6.7])  # 60 tau at Lambda 0.45 (RunUp-v1's start) to 0.70
def test_band_captures_every_ratio_in_it_and_never_exceeds_the_signal(revs):
    t, th, om = record(revs=revs)
    mon = VibrationMonitor()
    for ratio in np.linspace(0.30, 0.55, 26):
        for phase in (0.0, 1.0, 2.0):
            s = np.sin(ratio * om * t + phase)
            level = mon.measure(t, s, s, th).x.subsynchronous_um_rms
            assert 0.90 * rms(s) < level <= rms(s) * (1 + 1e-12), (ratio, phase)
    # far outside the band little passes (the skirts of a short record: docs/machine.md), never more
    for ratio, most in ((0.1, 0.7), (1.5, 0.5), (3.0, 0.2), (0.7, 1.0), (0.8, 1.0)):
        s = np.sin(ratio * om * t + 0.4)
        assert mon.measure(t, s, s, th).x.subsynchronous_um_rms <= most * rms(s), ratio


def test_recovery_with_noise_is_within_the_predicted_scatter():
    t, th, om = record()
    x, s = synthetic(t, th, om)
    rng = np.random.default_rng(5)
    noisy = x + SIGMA * rng.standard_normal(N)
    r = VibrationMonitor().measure(t, noisy, noisy, th, noise_um=SIGMA)
    p = r.x
    assert abs(p.synchronous_um_pp - 2.0) < 4 * p.synchronous_um_pp_std
    assert abs(p.synchronous_phase_lag_deg - 70.0) < 4 * p.synchronous_phase_lag_deg_std
    clean = VibrationMonitor().measure(t, x, x, th).x.subsynchronous_um_rms
    expected = math.hypot(clean, p.subsynchronous_noise_floor_um_rms)  # E[level^2] = true^2 + floor^2
    assert abs(p.subsynchronous_um_rms - expected) < 4 * p.subsynchronous_um_rms_std
    assert p.subsynchronous_ratio == pytest.approx(0.45, abs=0.02)
    # the formula of the docs: sigma_A ~ sigma sqrt(2 / N) zero-to-peak
    assert p.synchronous_um_pp_std == pytest.approx(2 * SIGMA * math.sqrt(2 / N), rel=0.1)
    assert math.radians(p.synchronous_phase_lag_deg_std) == pytest.approx(
        0.5 * p.synchronous_um_pp_std / 1.0, rel=0.05
    )


@pytest.mark.parametrize(("revs", "most"), [(3.7, 2.8), (4.3, 1.4), (6.0, 1.1), (8.0, 1.05)])
def test_1x_noise_approaches_the_long_record_formula(revs, most):
    # sigma_pp = 2 sigma sqrt(2 / N) for many revolutions; a short record pays for the band columns
    t, th, _ = record(revs=revs, ramp=0.0)
    for lag in range(0, 360, 15):
        x = np.cos(th - math.radians(lag))
        ratio = VibrationMonitor().measure(t, x, x, th, noise_um=SIGMA).x.synchronous_um_pp_std / (
            2 * SIGMA * math.sqrt(2 / N)
        )
        assert 0.99 < ratio < most, (revs, lag)


def test_noise_predictions_agree_with_monte_carlo():
    t, th, om = record()
    x, s = synthetic(t, th, om)
    mon = VibrationMonitor()
    rng = np.random.default_rng(11)
    draws = [
        mon.measure(t, *(x + SIGMA * rng.standard_normal((2, N))), th, noise_um=SIGMA) for _ in range(200)
    ]
    amp = np.array([d.x.synchronous_um_pp for d in draws])
    lag = np.array([d.x.synchronous_phase_lag_deg for d in draws])
    level = np.array([d.x.subsynchronous_um_rms for d in draws])
    ref = mon.measure(t, x, x, th, noise_um=SIGMA).x  # the noise-free signal's predicted scatter
    assert amp.std() == pytest.approx(ref.synchronous_um_pp_std, rel=0.2)
    assert lag.std() == pytest.approx(ref.synchronous_phase_lag_deg_std, rel=0.2)
    assert level.std() == pytest.approx(ref.subsynchronous_um_rms_std, rel=0.2)
    assert ref.subsynchronous_um_rms_std == pytest.approx(SIGMA / math.sqrt(N), rel=1e-12)
    assert np.mean(level**2) == pytest.approx(
        ref.subsynchronous_um_rms**2 + ref.subsynchronous_noise_floor_um_rms**2, rel=0.02
    )
    assert abs(amp.mean() - 2.0) < 3 * ref.synchronous_um_pp_std / math.sqrt(200)  # 1x is unbiased
    # pure noise: the level's rms is the floor; the 1x amplitude is Rayleigh-distributed
    noise = [mon.measure(t, *(SIGMA * rng.standard_normal((2, N))), th, noise_um=SIGMA) for _ in range(200)]
    floor = noise[0].x.subsynchronous_noise_floor_um_rms
    assert floor == pytest.approx(SIGMA * math.sqrt(8 / N), rel=1e-12)  # sigma sqrt(2K / N), K = 4
    assert rms([d.x.subsynchronous_um_rms for d in noise]) == pytest.approx(floor, rel=0.2)
    assert all(d.x.synchronous_phase_lag_deg_std <= math.degrees(math.pi / math.sqrt(3)) for d in noise)
    # the direct peak-to-peak is biased up by the noise (the values docs/machine.md quotes)
    pp = np.array([d.x.direct_um_pp for d in draws])
    assert 0.0 < pp.mean() - (x.max() - x.min()) < 3 * SIGMA
    pp0 = np.array([d.x.direct_um_pp for d in noise])
    assert pp0.mean() == pytest.approx(5.1 * SIGMA, rel=0.1)  # the range of 120 normal samples


def test_probes_readings_are_the_geometry_plus_bias_plus_noise():
    xi, eta = np.linspace(-5, 5, N), np.linspace(2, 3, N)
    bias = np.array([0.7, -0.4])
    ideal = ProximityProbes.ideal()
    rng = np.random.default_rng(0)
    x, y = ideal.readings_um(rng, xi, eta, bias)
    assert np.array_equal(x, ideal.read_um(xi, eta, bias)[0]) and np.array_equal(
        y, ideal.read_um(xi, eta, bias)[1]
    )
    assert rng.standard_normal() == np.random.default_rng(0).standard_normal()  # no draw when exact
    p = ProximityProbes(noise_um=0.3)
    x, y = p.readings_um(np.random.default_rng(1), np.zeros(20000), np.zeros(20000), bias)
    assert x.mean() == pytest.approx(0.7, abs=0.01) and x.std() == pytest.approx(0.3, rel=0.03)
    assert y.mean() == pytest.approx(-0.4, abs=0.01) and np.corrcoef(x, y)[0, 1] == pytest.approx(0, abs=0.03)


def test_keyphasor_angle_shifts_the_phase_lag():
    t, th, om = record()
    x, _ = synthetic(t, th, om)
    lag0 = VibrationMonitor().measure(t, x, x, th).x.synchronous_phase_lag_deg
    lag = VibrationMonitor(keyphasor_angle_deg=30.0).measure(t, x, x, th).x.synchronous_phase_lag_deg
    assert lag0 == pytest.approx(70.0, abs=0.1) and lag == pytest.approx(
        lag0 - 30.0, abs=1e-8
    )  # the key passes 30 deg later: the peak lags it 30 deg less


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("subsynchronous_band_ratio", (0.5, 0.4)),
        ("subsynchronous_band_ratio", (0.0, 0.5)),
        ("subsynchronous_band_ratio", (0.5, 0.95)),
        ("subsynchronous_band_ratio", 0.4),
        ("subsynchronous_frequencies", 0),
        ("subsynchronous_frequencies", 2.5),
        ("ratio_scan_step", 0.0),
        ("ratio_scan_step", 0.5),
        ("min_revolutions", -1.0),
        ("min_revolutions", math.nan),
        ("keyphasor_angle_deg", math.inf),
    ],
)
def test_bad_configuration_is_refused_by_name(field, value):
    with pytest.raises(ValueError, match=field):
        VibrationMonitor(**{field: value})


def test_bad_records_are_refused_by_name():
    t, th, om = record()
    x, _ = synthetic(t, th, om)
    mon = VibrationMonitor()
    assert mon.min_samples == 28  # twice the 14 columns
    with pytest.raises(ValueError, match="time_s must have at least 28"):
        mon.measure(t[:10], x[:10], x[:10], th[:10])
    with pytest.raises(ValueError, match="y_um must have as many"):
        mon.measure(t, x, x[:-1], th)
    bad = x.copy()
    bad[3] = math.nan
    with pytest.raises(ValueError, match="x_um must be finite"):
        mon.measure(t, bad, x, th)
    with pytest.raises(ValueError, match="time_s must be strictly increasing"):
        mon.measure(t[::-1], x, x, th)
    with pytest.raises(ValueError, match="quarter revolution"):
        mon.measure(t, x, x, th * 8)
    with pytest.raises(ValueError, match="noise_um"):
        mon.measure(t, x, x, th, noise_um=-0.1)


def test_degenerate_records_give_no_nan():
    t, th, om = record()
    mon = VibrationMonitor()
    x, _ = synthetic(t, th, om)
    # zero speed: the documented fallback (no filtered values), the direct ones stay
    r = mon.measure(t, x, x, np.full(N, 1.0), noise_um=SIGMA)
    assert not r.valid and r.revolutions == 0.0 and r.running_speed_rpm == 0.0
    assert r.x.synchronous_um_pp == 0.0 and r.x.subsynchronous_um_rms == 0.0
    assert r.x.direct_um_pp == pytest.approx(x.max() - x.min()) and r.x.subsynchronous_ratio == pytest.approx(
        0.425
    )
    # just below min_revolutions (3.5)
    t2, th2, _ = record(revs=3.45, ramp=0.0)
    assert not mon.measure(t2, x, x, th2).valid
    assert VibrationMonitor(min_revolutions=3.4).measure(t2, x, x, th2).valid
    # a constant signal: zeros, the phase scatter capped at a uniform phase's
    r = mon.measure(t, np.full(N, 4.0), np.zeros(N), th, noise_um=SIGMA)
    assert r.valid and r.x.mean_um == pytest.approx(4.0) and r.x.synchronous_um_pp < 1e-12
    assert r.y.synchronous_um_pp == 0.0 and r.y.synchronous_phase_lag_deg_std == pytest.approx(
        math.degrees(math.pi / math.sqrt(3))
    )
    for reading in (r, mon.measure(t, x, x, np.full(N, 1.0), noise_um=SIGMA)):
        assert all(math.isfinite(v) for v in reading.as_dict().values())
    assert len(r.as_dict()) == 2 * 13 + 3
