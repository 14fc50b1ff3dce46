"""BearingParameters.time_scale_s is computed once per bearing (the envs read it ~20 times per control
step): the cached value is the formula's, a replaced bearing gets its own, equality ignores the cache."""

from __future__ import annotations

import copy
import dataclasses
import pickle

from gfb_env.params import BearingParameters


def _formula(b: BearingParameters) -> float:
    return 6.0 * b.viscosity_pa_s / b.ambient_pressure_pa * (b.radius_m / b.clearance_m) ** 2


def test_time_scale_cached_and_fresh_for_a_replaced_bearing() -> None:
    b = BearingParameters()
    t = b.time_scale_s
    assert t == _formula(b) and b.time_scale_s is t  # the same object: computed once
    drawn = dataclasses.replace(b, clearance_m=40e-6)
    assert drawn.time_scale_s == _formula(drawn) and drawn.time_scale_s != t
    assert dataclasses.replace(b) == b and hash(dataclasses.replace(b)) == hash(b)
    for other in (copy.deepcopy(b), pickle.loads(pickle.dumps(b))):
        assert other == b and other.time_scale_s == t
    assert b.seconds(2.0) == 2.0 * t and b.speed_rpm_at(b.bearing_number_at(30_000.0)) == 30_000.0
