"""The motor component: v0's acceleration limit, operation for operation, and its validation."""

from __future__ import annotations

import numpy as np
import pytest

from gfb_env.envs._data import NOMINAL_BEARING
from gfb_env.envs.config import EnvConfig
from gfb_env.machine import Motor


def test_motor_ramps_at_its_acceleration_limit_in_rpm_per_s():
    b, m = NOMINAL_BEARING, Motor(30_000.0)
    lam0 = b.bearing_number_at(27_000.0)
    limits = (b.bearing_number_at(12_000.0), b.bearing_number_at(60_000.0))
    for a in (1.0, 0.5, -0.25):
        lam1 = m.bearing_number_at_step_end(lam0, a, b, 60.0, limits)
        # 60 tau = 9.54 ms: the speed moves by a * 30 000 rpm/s * 9.54 ms
        assert b.speed_rpm_at(lam1) - 27_000.0 == pytest.approx(a * 30_000.0 * b.seconds(60.0), rel=1e-9)
    # the speed range clips the command
    assert m.bearing_number_at_step_end(limits[1] - 1e-6, 1.0, b, 60.0, limits) == limits[1]
    assert m.bearing_number_at_step_end(limits[0] + 1e-6, -1.0, b, 60.0, limits) == limits[0]


def test_motor_is_v0s_arithmetic_bit_for_bit():
    b, m = NOMINAL_BEARING.replace(clearance_m=43e-6), Motor(25_000.0)
    limits = (0.2, 0.9)
    rng = np.random.default_rng(0)
    for lam0, a in zip(rng.uniform(0.2, 0.9, 50), rng.uniform(-1, 1, 50), strict=True):
        v0 = float(np.clip(lam0 + a * (25_000.0 / b.rate_rpm_per_s(1.0)) * 60.0, *limits))
        assert m.bearing_number_at_step_end(lam0, a, b, 60.0, limits) == v0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "fast"])
def test_motor_refuses_bad_acceleration(bad):
    with pytest.raises(ValueError, match="max_acceleration_rpm_per_s"):
        Motor(bad)


def test_env_config_has_one_acceleration_limit():
    assert EnvConfig().motor == Motor(30_000.0) and EnvConfig().max_acceleration_rpm_per_s == 30_000.0
    cfg = EnvConfig(motor=Motor(20_000.0))
    assert cfg.max_acceleration_rpm_per_s == 20_000.0
    assert EnvConfig(max_acceleration_rpm_per_s=10_000.0).motor == Motor(10_000.0)
    assert EnvConfig(motor={"max_acceleration_rpm_per_s": 5_000.0}).max_acceleration_rpm_per_s == 5_000.0
    with pytest.raises(ValueError, match="contradicts"):
        EnvConfig(motor=Motor(20_000.0), max_acceleration_rpm_per_s=30_000.0)
    with pytest.raises(ValueError, match="motor"):
        EnvConfig(motor="strong")
