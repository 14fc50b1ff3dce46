import math

import pytest

from gfb_env.params import BearingParameters, NondimensionalParameters


def test_table1_nondimensional_values():
    """DESIGN.md section 3: Table 1 in nondimensional form."""
    b = BearingParameters()
    assert b.time_scale_s == pytest.approx(1.590e-4, rel=1e-3)
    assert b.bearing_number_at(30_000) == pytest.approx(0.4996, abs=1e-4)
    assert b.bearing_number_at(36_000) == pytest.approx(0.5995, abs=1e-4)
    assert b.bearing_number_at(50_000) == pytest.approx(0.8326, abs=1e-4)
    assert b.mass_parameter == pytest.approx(4.974, abs=1e-3)
    assert b.gravity_parameter == pytest.approx(0.06032, abs=1e-5)
    assert b.mass_parameter * b.gravity_parameter == pytest.approx(0.3000, abs=1e-4)
    assert b.kappa == pytest.approx(0.5)
    assert b.foil_stiffness == pytest.approx(2.337, abs=1e-3)


def test_conversions_round_trip():
    b = BearingParameters()
    assert b.speed_rpm_at(b.bearing_number_at(41_234.5)) == pytest.approx(41_234.5)
    assert b.tau(b.seconds(123.0)) == pytest.approx(123.0)
    assert b.micrometres(1.0) == pytest.approx(50.0)
    assert b.newtons(1.0) == pytest.approx(101_325 * 0.01905 * 0.0381)
    # the paper's tau_max = 50 000 is 7.95 s with its own T (not the 50 s it states)
    assert b.seconds(50_000) == pytest.approx(7.95, abs=0.01)
    # whirl at Lambda/2 rad per unit tau at 36 000 rpm is 300 Hz
    assert b.frequency_hz(b.bearing_number_at(36_000) / 2) == pytest.approx(300.0, rel=1e-9)
    # a ramp of 1000 rpm/s
    rate = b.bearing_number_at(1000.0) * b.time_scale_s
    assert b.rate_rpm_per_s(rate) == pytest.approx(1000.0)


@pytest.mark.parametrize(
    "field,value",
    [
        ("length_m", 0.0),
        ("radius_m", -1.0),
        ("clearance_m", 0.0),
        ("clearance_m", 0.01),  # not << R
        ("rotor_mass_per_bearing_kg", -0.1),
        ("viscosity_pa_s", math.nan),
        ("poisson_ratio", 0.5),
        ("poisson_ratio", -1.0),
        ("bump_count", 0),
        ("bump_count", 2.5),
        ("youngs_modulus_pa", math.inf),
        ("speed_rpm", -1.0),
        ("bump_half_width_m", 1.0),
    ],
)
def test_invalid_parameters_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        BearingParameters(**{field: value})


def test_nondimensional_validation():
    with pytest.raises(ValueError, match="foil_stiffness"):
        NondimensionalParameters(4.97, 0.06, -1.0, 0.5)
    with pytest.raises(ValueError, match="speed_rpm"):
        BearingParameters().bearing_number_at(-5)
    with pytest.raises(ValueError, match="bearing_number"):
        BearingParameters().speed_rpm_at(math.nan)
