"""The monitor's cheaper bookkeeping (issue 20) gives np.unwrap's bits and cached constants that no
caller can change."""

from __future__ import annotations

import dataclasses

import numpy as np

from gfb_env.machine import VibrationMonitor
from gfb_env.machine.monitor import _unwrap


def test_unwrap_is_numpys_bit_for_bit():
    rng = np.random.default_rng(0)
    turning = np.cumsum(rng.uniform(0.0, 1.5, 200)) - 3.0  # a monitor's angles: < pi per sample
    wrapped = np.mod(turning, 2 * np.pi)  # reduced: steps of ~-2 pi
    with_zero = np.array([-0.0, -0.0, 0.5, 1.0])  # the -0.0 that p[1:] + 0.0 turns into 0.0
    for p in (turning, wrapped, with_zero, rng.normal(0.0, 4.0, 50)):
        assert _unwrap(p).tobytes() == np.unwrap(p).tobytes()


def test_band_ratios_are_cached_but_not_shared():
    m = VibrationMonitor()
    r = m.band_ratios
    r[:] = 0.0  # the caller's copy only
    assert np.array_equal(m.band_ratios, np.linspace(0.30, 0.55, 4))
    other = dataclasses.replace(m, subsynchronous_band_ratio=(0.2, 0.5), subsynchronous_frequencies=3)
    assert np.array_equal(other.band_ratios, np.linspace(0.2, 0.5, 3))
    assert m == VibrationMonitor()  # no hidden state in equality


def test_the_probes_inverse_geometry_is_cached_read_only():
    from gfb_env.machine import ProximityProbes

    p = ProximityProbes()
    inv = p._inverse_directions
    assert inv is p._inverse_directions and not inv.flags.writeable
    assert inv.tobytes() == np.linalg.inv(p.directions).tobytes()
