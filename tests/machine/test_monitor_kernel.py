"""The vibration monitor's compiled kernel (gfb_env.machine._monitor_kernels, issue 20 s.3) against the numpy
implementation it replaced (``VibrationMonitor.measure_reference``): every field of the reading within 1e-9
relative (1e-12 absolute, in units of the signal's largest um, near zero) on seeded whirl + 1x + noise
records, zero, pure noise, pure 1x and the shortest records; a rank-deficient band falls back on numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gfb_env.machine import VibrationMonitor
from gfb_env.machine import _monitor_kernels as kernels
from gfb_env.machine.monitor import keyphasor_angles

RTOL, ATOL = 1e-9, 1e-12


def record(n: int = 120, revs: float = 6.0, ramp: float = 0.05, f_hz: float = 700.0, angle0: float = 0.3):
    om0 = 2 * math.pi * f_hz
    t = np.arange(1, n + 1) * (revs / f_hz / n)
    th = keyphasor_angles(t, 0.0, angle0, om0, t[-1], om0 * (1 + ramp))
    return t, th, (th[-1] - th[0]) / (t[-1] - t[0])


def assert_same(monitor: VibrationMonitor, args: tuple, noise_um: float, skip: tuple[str, ...] = ()) -> None:
    got = monitor.measure(*args, noise_um=noise_um).as_dict()
    want = monitor.measure_reference(*args, noise_um=noise_um).as_dict()
    assert got.keys() == want.keys()
    t, x, y = args[:3]
    # near zero the rounding is that of the signal (um, at least 1); the trend's is per second: that
    # of the mean over the record's duration
    base = ATOL * max(1.0, float(np.abs(x).max()), float(np.abs(y).max()))
    atol = {k: base / (t[-1] - t[0]) for k in ("x_trend_um_per_s", "y_trend_um_per_s")}
    bad = {
        k: (got[k], want[k])
        for k in want
        if k not in skip and not math.isclose(got[k], want[k], rel_tol=RTOL, abs_tol=atol.get(k, base))
    }
    assert not bad, bad


@pytest.mark.parametrize("seed", range(6))
def test_whirl_plus_1x_plus_noise_agrees_with_numpy(seed):
    rng = np.random.default_rng(seed)
    revs, ramp = rng.uniform(3.6, 7.0), rng.uniform(-0.1, 0.2)
    t, th, om = record(revs=revs, ramp=ramp, angle0=rng.uniform(0, 100))
    ratio, a1, aw, sigma = rng.uniform(0.3, 0.55), rng.uniform(0, 30), rng.uniform(0, 20), rng.uniform(0, 1)
    whirl = aw * np.cos(ratio * om * t + rng.uniform(0, 6))
    x = a1 * np.cos(th - 1.1) + whirl + 5 + 50 * t + sigma * rng.standard_normal(len(t))
    y = a1 * np.sin(th - 1.1) + 0.8 * whirl - 3 + sigma * rng.standard_normal(len(t))
    x += 0.3 * np.cos(2 * th)  # a 2x
    monitor = VibrationMonitor(keyphasor_angle_deg=float(rng.uniform(0, 360)))
    assert_same(monitor, (t, x, y, th), sigma)


def test_zero_signal_and_pure_noise_agree_with_numpy():
    t, th, _ = record()
    zero = np.zeros(len(t))
    # the phase of a zero vector is atan2 of signed zeros: numpy's solve gives -0.0 (180 degrees), the
    # kernel +0.0 (0); the observation gives no phase to a zero amplitude
    lags = ("x_synchronous_phase_lag_deg", "y_synchronous_phase_lag_deg")
    assert_same(VibrationMonitor(), (t, zero, zero, th), 0.3, skip=lags)
    assert_same(VibrationMonitor(), (t, zero, zero, th), 0.0, skip=lags)
    assert VibrationMonitor().measure(t, zero, zero, th).x.synchronous_um_pp == 0.0
    rng = np.random.default_rng(7)
    assert_same(VibrationMonitor(), (t, rng.standard_normal(len(t)), rng.standard_normal(len(t)), th), 1.0)


def test_pure_1x_agrees_with_numpy_except_the_ratio_of_an_empty_band():
    t, th, _ = record(revs=4.0)
    x, y = 10 * np.cos(th - 0.5), 10 * np.sin(th - 0.5)
    # the band's level is rounding (1e-15): its dominant ratio is the argmax of rounding, in either
    assert_same(
        VibrationMonitor(), (t, x, y, th), 0.2, skip=("x_subsynchronous_ratio", "y_subsynchronous_ratio")
    )


@pytest.mark.parametrize("revs", [3.5, 4.0, 6.5])
def test_the_shortest_record_agrees_with_numpy(revs):
    monitor = VibrationMonitor()
    t, th, om = record(n=monitor.min_samples, revs=revs)
    rng = np.random.default_rng(3)
    x = 4 * np.cos(th) + 2 * np.cos(0.4 * om * t) + 0.3 * rng.standard_normal(len(t))
    y = 4 * np.sin(th) + 0.3 * rng.standard_normal(len(t))
    assert_same(monitor, (t, x, y, th), 0.3)


def test_too_slow_record_is_the_same_reading():
    t, th, _ = record(revs=2.0)
    x = np.cos(th) + t
    got = VibrationMonitor().measure(t, x, -x, th, noise_um=0.3)
    assert not got.valid
    assert got == VibrationMonitor().measure_reference(t, x, -x, th, noise_um=0.3)


def test_a_band_inside_the_nuisance_span_falls_back_on_numpy():
    # 20 band pairs crowded into 0.30-0.31x: the band columns are dependent to rounding, numpy's SVD
    # drops directions; the kernel cannot prove full rank and says so
    monitor = VibrationMonitor(subsynchronous_band_ratio=(0.30, 0.31), subsynchronous_frequencies=20)
    t, th, om = record(n=200, revs=6.0)
    rng = np.random.default_rng(5)
    x, y = np.cos(0.305 * om * t) + 0.1 * rng.standard_normal(len(t)), np.cos(th)
    out, kin = np.empty((2, kernels.N_FIELDS)), np.empty(4)
    ratios, scan = monitor.band_ratios, np.arange(0.30, 0.3101, 0.005)
    dr = ratios[1] - ratios[0]
    status = kernels.measure_kernel(
        t, x, y, th, 0.1, 0.0, 3.5, ratios[0], dr, len(ratios), scan[0], 0.005, len(scan), out, kin
    )
    assert status == kernels.NEEDS_REFERENCE
    assert monitor.measure(t, x, y, th, noise_um=0.1) == monitor.measure_reference(t, x, y, th, noise_um=0.1)


def test_reduced_angles_are_unwrapped_and_bad_records_refused_as_before():
    t, th, om = record()
    x, y = 3 * np.cos(th) + np.cos(0.4 * om * t), 3 * np.sin(th)
    monitor = VibrationMonitor()
    # reduced to [0, 2 pi): the kernel sends them to numpy's checks, which unwrap them
    got = monitor.measure(t, x, y, np.mod(th, 2 * math.pi)).as_dict()
    want = monitor.measure(t, x, y, th).as_dict()
    assert all(math.isclose(got[k], want[k], rel_tol=RTOL, abs_tol=1e-10) for k in want), (got, want)
    bad_t = t.copy()
    bad_t[5] = np.nan
    with pytest.raises(ValueError, match="time_s must be finite"):
        monitor.measure(bad_t, x, y, th)
    with pytest.raises(ValueError, match="rotation_angle_rad must not decrease"):
        monitor.measure(t, x, y, th[::-1].copy())
    with pytest.raises(ValueError, match="quarter revolution"):
        monitor.measure(t, x, y, 1.6 * np.arange(len(t)))
