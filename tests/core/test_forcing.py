"""Unbalance and base shocks (issue 10, sect. 1-2 and 4): conversions, the derived forcing terms, the
integrator's exact rotation angle, snapshots, shock step landing, and the linear response against the
transient."""

import math

import numpy as np
import pytest

from gfb_env.analysis.response import (
    response_curve,
    synchronous_components,
    transient_synchronous_orbit,
    unbalance_response,
)
from gfb_env.analysis.spectrum import amplitude_spectrum
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import (
    STANDARD_GRAVITY_M_S2,
    HalfSineShock,
    Unbalance,
    half_sine_acceleration,
    shock_acceleration,
    unbalance_acceleration,
)
from gfb_env.integrator import StepperState, TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters

B = BearingParameters()


# ------------------------------------------------------------------------------------------------
# physical units
def test_mass_radius_conversion_both_ways():
    # U = m_u e / (m C): 10 g mm on the 0.37 kg rotor with C = 50 um
    u = Unbalance.from_mass_radius(B, 10.0)
    assert u.magnitude == pytest.approx(10e-6 / (0.37 * 50e-6), rel=1e-12)
    assert u.mass_radius_g_mm(B) == pytest.approx(10.0, rel=1e-12)
    u2 = Unbalance.from_mass_radius(B, 10.0, rotor_mass_kg=1.0)
    assert u2.magnitude == pytest.approx(10e-6 / (1.0 * 50e-6), rel=1e-12)
    assert u2.mass_radius_g_mm(B, rotor_mass_kg=1.0) == pytest.approx(10.0, rel=1e-12)


def test_iso1940_grade_both_ways():
    # G 2.5 at 36 000 rpm: e_per = 2.5 mm/s / 3769.9 rad/s = 0.663 um = 0.01326 C
    u = Unbalance.from_iso1940(B, 2.5, 36_000.0)
    assert u.magnitude == pytest.approx(2.5e-3 / (36_000 * 2 * math.pi / 60) / 50e-6, rel=1e-12)
    assert u.eccentricity_um(B) == pytest.approx(0.6631, abs=1e-4)
    assert u.iso1940_grade_mm_s(B, 36_000.0) == pytest.approx(2.5, rel=1e-12)
    # the same unbalance in g mm: U_per = m e_per
    assert u.mass_radius_g_mm(B) == pytest.approx(0.37 * 0.6631e-3 * 1e3, rel=1e-3)


def test_shock_from_physical_both_ways():
    q = HalfSineShock.from_physical(B, start_s=0.01, peak_g=5.0, duration_ms=2.0, direction_deg=90.0)
    T = B.time_scale_s
    assert q.start_tau == pytest.approx(0.01 / T)
    assert q.duration_tau == pytest.approx(2e-3 / T)
    assert q.peak_acceleration == pytest.approx(5 * STANDARD_GRAVITY_M_S2 * T * T / 50e-6)
    assert q.peak_g(B) == pytest.approx(5.0)
    assert q.duration_ms(B) == pytest.approx(2.0)
    assert q.direction_rad == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: Unbalance(-1.0), "magnitude"),
        (lambda: Unbalance(float("nan")), "magnitude"),
        (lambda: Unbalance(0.1, float("inf")), "phase_rad"),
        (lambda: Unbalance.from_mass_radius(B, -1.0), "mass_radius_g_mm"),
        (lambda: Unbalance.from_mass_radius(B, 1.0, rotor_mass_kg=0.0), "rotor_mass_kg"),
        (lambda: Unbalance.from_iso1940(B, 0.0, 1000.0), "grade_mm_s"),
        (lambda: Unbalance.from_iso1940(B, 2.5, -1.0), "speed_rpm"),
        (lambda: HalfSineShock(0.0, 0.0, 1.0), "duration_tau"),
        (lambda: HalfSineShock(0.0, 1.0, -1.0), "peak_acceleration"),
        (lambda: HalfSineShock(float("nan"), 1.0, 1.0), "start_tau"),
        (lambda: HalfSineShock.from_physical(B, 0.0, 1.0, -2.0), "duration_ms"),
    ],
)
def test_bad_values_are_refused_by_name(make, field):
    with pytest.raises(ValueError, match=field):
        make()


# ------------------------------------------------------------------------------------------------
# the forcing terms
def test_unbalance_term_is_minus_the_acceleration_of_the_mass_offset():
    """The derivation: the journal gains -U d^2/dtau^2 (sin theta, cos theta); checked by a central
    difference of theta(tau) = a + b tau + c tau^2 / 2 (theta' = b + c tau, theta'' = c)."""
    U, a, b, c = 0.3, 0.7, 0.6, 0.05
    h = 1e-4
    for tau in (0.0, 1.3, 7.9):

        def offset(t):
            th = a + b * t + 0.5 * c * t * t
            return U * np.array([math.sin(th), math.cos(th)])

        want = -(offset(tau + h) - 2 * offset(tau) + offset(tau - h)) / h**2
        th = a + b * tau + 0.5 * c * tau * tau
        got = np.array(unbalance_acceleration(U, th, b + c * tau, c))
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)
    # constant speed: the centrifugal force points from the journal centre to the heavy spot
    ax, ay = unbalance_acceleration(0.1, 0.4, 0.5, 0.0)
    assert (ax, ay) == pytest.approx((0.1 * 0.25 * math.sin(0.4), 0.1 * 0.25 * math.cos(0.4)))


def test_shock_term_is_minus_the_base_acceleration():
    q = HalfSineShock(10.0, 2.0, 3.0, direction_rad=math.pi / 2)  # base accelerated toward +xi
    rows = np.array([q.as_row()])
    assert shock_acceleration(9.99, rows) == (0.0, 0.0)
    assert shock_acceleration(12.01, rows) == (0.0, 0.0)
    ax, ay = shock_acceleration(11.0, rows)
    assert ax == pytest.approx(-3.0)
    assert ay == pytest.approx(0.0, abs=1e-12)
    assert half_sine_acceleration(10.5, 10.0, 2.0, 3.0) == pytest.approx(3.0 * math.sin(math.pi / 4))
    # linear in the forcing: two equal shocks give twice the term
    two = np.array([q.as_row(), q.as_row()])
    assert shock_acceleration(10.7, two)[0] == pytest.approx(2 * shock_acceleration(10.7, rows)[0])


# ------------------------------------------------------------------------------------------------
# the integrator
@pytest.fixture(scope="module")
def rigid():
    m = GFBModel("rigid", grid="31x7")
    return m, find_equilibrium(m, 0.3)


def _forced_rhs(model, s, lam, unbalance, theta, theta_ddot=0.0):
    k = model.rhs(s, lam)
    a = unbalance_acceleration(unbalance.magnitude, theta + unbalance.phase_rad, lam, theta_ddot)
    k[model.layout.xi_dot_index] += a[0]
    k[model.layout.eta_dot_index] += a[1]
    return k


def test_rotation_angle_is_carried_exactly_over_ramps(rigid):
    m, s0 = rigid
    it = TrapezoidalIntegrator(m, s0, 0.3, unbalance=Unbalance(1e-3), rotation_angle=0.2)
    theta = 0.2
    lam = 0.3
    for tau_end, lam_end in ((5.0, 0.3), (12.0, 0.35), (20.0, 0.32)):
        dtau = tau_end - it.tau
        theta += dtau * 0.5 * (lam + lam_end)
        lam = lam_end
        it.advance(tau_end, bearing_number=lam_end)
        assert it.rotation_angle == pytest.approx(math.fmod(theta, 2 * math.pi), abs=1e-12)
    # the stored k at the end is k(s) plus the forcing at theta (theta'' of the last ramp)
    rate = (0.32 - 0.35) / 8.0
    np.testing.assert_allclose(
        it.snapshot().f, _forced_rhs(m, it.state, it.bearing_number, it.unbalance, it.rotation_angle, rate),
        rtol=1e-12, atol=1e-12,
    )  # fmt: skip


def test_jacobian_against_finite_differences_with_the_forcing_on(rigid):
    m, s0 = rigid
    it = TrapezoidalIntegrator(m, s0, 0.3, unbalance=Unbalance(0.05, 0.3))
    it.advance(7.3)
    s, lam, theta = it.state, it.bearing_number, it.rotation_angle
    J = m.jacobian(s, lam).toarray()
    k0 = _forced_rhs(m, s, lam, it.unbalance, theta)
    assert np.abs(k0 - m.rhs(s, lam)).max() > 1e-3  # the forcing is on
    h = 1e-7
    Jfd = np.empty_like(J)
    for j in range(len(s)):
        e = np.zeros(len(s))
        e[j] = h
        Jfd[:, j] = (
            _forced_rhs(m, s + e, lam, it.unbalance, theta) - _forced_rhs(m, s - e, lam, it.unbalance, theta)
        ) / (2 * h)
    assert np.abs(J - Jfd).max() <= 1e-5 * max(1.0, np.abs(J).max())


def test_forced_runs_are_deterministic_and_snapshots_bit_for_bit(rigid):
    m, s0 = rigid

    def run():
        it = TrapezoidalIntegrator(m, s0, 0.3, unbalance=Unbalance(0.02, 1.0))
        it.add_shock(HalfSineShock(30.0, 0.5, 0.05, 0.3))
        it.advance(20.0, bearing_number=0.32)
        return it

    a, b = run(), run()
    snap = a.snapshot().as_dict()
    assert snap["rotation_angle"] == b.rotation_angle and len(snap["shocks"]) == 1
    ra = a.advance(60.0, record_interval=0.5)
    rb = b.advance(60.0, record_interval=0.5)
    assert np.array_equal(ra.trajectory.xi, rb.trajectory.xi)
    assert a.shocks == ()  # over
    a.restore(StepperState.from_dict(snap))
    assert a.shocks and a.rotation_angle == snap["rotation_angle"]
    rc = a.advance(60.0, record_interval=0.5)
    assert np.array_equal(rc.trajectory.xi, ra.trajectory.xi)
    assert np.array_equal(a.state, b.state) and a.rotation_angle == b.rotation_angle
    # an old dict without the forcing fields restores as unforced
    old = {
        k: v
        for k, v in snap.items()
        if k not in ("rotation_angle", "rotation_acceleration", "unbalance", "shocks")
    }
    st = StepperState.from_dict(old)
    assert st.unbalance is None and st.shocks == () and st.rotation_angle == 0.0


def test_zero_unbalance_is_bit_for_bit_the_unforced_run(rigid):
    m, s0 = rigid
    s = m.layout.with_rotor(s0, *(m.layout.rotor(s0)[:2] + [0.01, 0.0]))
    r0 = TrapezoidalIntegrator(m, s, 0.3).advance(40.0, record_interval=0.5)
    it = TrapezoidalIntegrator(m, s, 0.3, unbalance=Unbalance(0.0))
    assert it.unbalance is None
    r1 = it.advance(40.0, record_interval=0.5)
    assert np.array_equal(r0.trajectory.xi, r1.trajectory.xi)
    # switched on and off again: k is the unforced one, bit for bit
    it2 = TrapezoidalIntegrator(m, s, 0.3)
    it2.set_unbalance(Unbalance(0.1))
    it2.set_unbalance(None)
    assert np.array_equal(it2.snapshot().f, m.rhs(s, 0.3))


def test_set_unbalance_switches_the_forcing_on(rigid):
    m, s0 = rigid
    it = TrapezoidalIntegrator(m, s0, 0.3, rotation_angle=1.1)
    it.set_unbalance(Unbalance(0.05))
    np.testing.assert_allclose(it.snapshot().f, _forced_rhs(m, s0, 0.3, Unbalance(0.05), 1.1), atol=1e-14)
    r = it.advance(20.0)
    assert r.xi_range[1] - r.xi_range[0] > 1e-3  # it moves the rotor
    with pytest.raises(ValueError, match="unbalance"):
        it.set_unbalance(0.05)


def test_a_short_shock_changes_the_velocity_by_its_integral_and_steps_land_on_it(rigid):
    m, s0 = rigid
    L = m.layout
    # a 0.005-tau pulse inside what would be one ~1-tau step near the equilibrium (short against the
    # squeeze-film damping: a 0.05-tau pulse already loses 1.3 % of its velocity change to it)
    q = HalfSineShock(
        start_tau=10.03, duration_tau=0.005, peak_acceleration=4.0, direction_rad=math.radians(30)
    )
    it = TrapezoidalIntegrator(m, s0, 0.3)
    it.advance(9.0)
    n_before = it.statistics.steps
    it.add_shock(q)
    it.advance(q.start_tau)
    v0 = it.state[[L.xi_dot_index, L.eta_dot_index]]
    steps_to_start = it.statistics.steps
    it.advance(q.end_tau)
    v1 = it.state[[L.xi_dot_index, L.eta_dot_index]]
    assert it.statistics.steps - steps_to_start >= 32  # capped at duration / 32 inside the pulse
    dv = -q.velocity_change * np.array([math.sin(q.direction_rad), math.cos(q.direction_rad)])
    np.testing.assert_allclose(v1 - v0, dv, rtol=0.01, atol=1e-3 * q.velocity_change)
    # the same pulse inside one long advance call: the steps still see it
    it2 = TrapezoidalIntegrator(m, s0, 0.3)
    it2.advance(9.0)
    it2.add_shock(q)
    r = it2.advance(10.3, record_interval=0.01)
    k = np.argmin(np.abs(r.trajectory.tau - q.end_tau))
    np.testing.assert_allclose(r.trajectory.xi_dot[k], v1[0], rtol=1e-3)
    assert it2.statistics.steps - n_before >= 32 and it2.shocks == ()
    with pytest.raises(ValueError, match="before the current time"):
        it2.add_shock(HalfSineShock(1.0, 1.0, 1.0))


# ------------------------------------------------------------------------------------------------
# the linear response against the transient (issue 10 validation)
@pytest.mark.parametrize(
    "structure, foil_stiffness, lam",
    [("rigid", None, 0.25), ("rigid", None, 0.4), ("viscoelastic", None, 0.25), ("viscoelastic", 1.0, 0.45)],
)
def test_small_unbalance_orbit_equals_the_linear_response(structure, foil_stiffness, lam):
    m = GFBModel(structure, grid="31x7", foil_stiffness=foil_stiffness)
    U = 1e-3
    lin = unbalance_response(m, lam, U)
    assert lin.stable
    orb = transient_synchronous_orbit(m, lam, U)
    for got, want in ((orb.xi, lin.xi), (orb.eta, lin.eta)):
        assert abs(got - want) <= 0.02 * abs(want)
    assert orb.residual_rms < 0.02 * lin.semi_major  # nothing but the 1x line is left
    # amplitude linear in U, in the transient too
    orb2 = transient_synchronous_orbit(m, lam, 2 * U)
    assert abs(orb2.eta - 2 * orb.eta) <= 0.01 * abs(2 * orb.eta)


def test_response_orbit_axes_and_low_speed_phase():
    m = GFBModel("rigid", grid="31x7")
    curve = response_curve(m, [0.05, 0.3], 0.01)
    for r in curve:
        assert r.semi_major >= r.semi_minor >= 0
        assert r.semi_major == pytest.approx(max(np.hypot(*_ellipse(r)).max(), 0), rel=1e-3)
    # stiffness-controlled at low speed: the rotor moves with the unbalance force, in the sense of
    # rotation (forward)
    low = curve[0]
    assert abs(low.eta_phase_deg) < 30 and low.forward
    # linear in U and independent of the phase (z is relative to the heavy spot)
    r2 = unbalance_response(m, 0.3, Unbalance(0.02, 1.0))
    assert r2.xi == pytest.approx(2 * curve[1].xi, rel=1e-9)


def _ellipse(r):
    th = np.linspace(0, 2 * np.pi, 2001)
    return (np.real(r.xi * np.exp(1j * th)), np.real(r.eta * np.exp(1j * th)))


def test_synchronous_fit_recovers_a_known_orbit():
    tau = np.linspace(0, 100, 801)
    th = 0.4 * tau + 0.3
    z = 0.002 - 0.001j
    xi = 0.1 + np.real(z * np.exp(1j * th))
    o = synchronous_components(tau, th, xi, xi)
    assert o.xi == pytest.approx(z, abs=1e-12) and o.mean_xi == pytest.approx(0.1)


def _line(spec, lam, lo, hi):
    k = (spec.omega / lam > lo) & (spec.omega / lam < hi)
    j = np.argmax(spec.amplitude[k])
    return spec.omega[k][j] / lam, spec.amplitude[k][j]


def test_fft_shows_the_1x_line_below_lambda_c():
    m = GFBModel("rigid", grid="31x7")
    lam, U = 0.4, 0.01
    s0 = find_equilibrium(m, lam)
    period = 2 * math.pi / lam
    # 64 revolutions, 16 samples each: the analysed second half holds whole periods (no scalloping)
    r = TrapezoidalIntegrator(m, s0, lam, unbalance=Unbalance(U)).advance(
        64 * period, record_interval=period / 16
    )
    spec = amplitude_spectrum(r.trajectory.eta, period / 16, fraction=0.5)
    ratio, amp = _line(spec, lam, 0.05, 3.0)  # the strongest line at all
    assert ratio == pytest.approx(1.0, abs=1e-9)
    assert amp == pytest.approx(unbalance_response(m, lam, U, stability=False).eta_amplitude, rel=0.02)


def test_fft_of_a_whirl_with_unbalance_shows_1x_and_the_whirl_line():
    # K_W = 1, D_W = 1 on the paper grid above Lambda_c = 0.587: the large whirl near 0.44 Lambda
    m = GFBModel("viscoelastic", grid="79x7", foil_stiffness=1.0)
    lam = 0.6
    s0 = find_equilibrium(m, lam)
    s0 = m.layout.with_rotor(s0, *(m.layout.rotor(s0)[:2] + [0.02, 0.0]))
    spectra = {}
    for U in (0.0, 0.01):
        r = TrapezoidalIntegrator(m, s0, lam, unbalance=Unbalance(U)).advance(2000.0, record_interval=0.5)
        assert r.ok and r.touchdown is None
        spectra[U] = amplitude_spectrum(r.trajectory.xi, 0.5, fraction=0.5)
    ratio_w, amp_w = _line(spectra[0.01], lam, 0.3, 0.6)
    assert 0.38 < ratio_w < 0.5 and amp_w > 0.3  # the whirl
    ratio_1, amp_1 = _line(spectra[0.01], lam, 0.97, 1.03)
    _, amp_1_free = _line(spectra[0.0], lam, 0.97, 1.03)
    assert abs(ratio_1 - 1.0) < 0.011  # within a bin
    assert amp_1 > 5 * amp_1_free and amp_1 > 0.003
