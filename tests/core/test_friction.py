"""The frictional foil (issue 22): K_W in parallel with a Jenkins element (K_T in series with a
regularised Coulomb slider), its Jacobian, its hysteresis loop and its exact limits."""

import json
import math

import numpy as np
import pytest
from conftest import assert_refused_at_once, random_admissible_state
from scipy.integrate import solve_ivp
from test_model import fd_jacobian

from gfb_env import _kernels as K
from gfb_env.analysis.stability import critical_bearing_number, jacobian_eigenvalues
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel, Structure

KW, KT = 1.0, 0.5


def frictional(mu: float, grid: str = "21x5", eta: float | None = None, kt: float = KT) -> GFBModel:
    return GFBModel(
        "frictional",
        grid=grid,
        foil_stiffness=KW,
        stick_stiffness=kt,
        friction_coefficient=mu,
        slip_viscosity=eta,
    )


def _state_in(m: GFBModel, regime: str, rng) -> np.ndarray:
    """A random admissible state whose sliders all stick or all slip, none within 1e-3 of the limit."""
    L = m.layout
    for _ in range(200):
        s = random_admissible_state(m, rng)
        F, Fc = np.abs(m.friction_force(s)), m.friction_limit(s)
        ok = F < Fc - 1e-3 if regime == "stick" else F > Fc + 1e-3
        if ok.all():
            return s
        # move the sliders into the wanted regime: S = Q - F/K_T
        Q = m.foil_deflection(s)
        target = (
            0.3 * Fc * rng.uniform(-1, 1, Fc.size)
            if regime == "stick"
            else Fc + 0.05 + 0.05 * rng.random(Fc.size)
        )
        if regime == "slip":
            target *= rng.choice([-1.0, 1.0], Fc.size)
        # F = K_T (Q - S) with Q = (K_T S - (Pbar - 1)) / (K_W + K_T): F = K_T K_W / (K_W+K_T) (Qe - S),
        # Qe = -(Pbar - 1) / K_W; so S = Qe - F (K_W + K_T) / (K_T K_W)
        kw, kt = m.foil_stiffness, m.stick_stiffness
        Qe = Q * (kw + kt) / kw - kt * L.foil_state(s) / kw
        s[L.foil_slice] = Qe - target * (kw + kt) / (kt * kw)
        F, Fc = np.abs(m.friction_force(s)), m.friction_limit(s)
        ok = F < Fc - 1e-3 if regime == "stick" else F > Fc + 1e-3
        if ok.all() and m.min_film_thickness(s) > 0.05:
            return s
    raise AssertionError("no state found")


@pytest.mark.parametrize("regime,mu", [("stick", 2.0), ("slip", 0.05), ("slip", 0.0)])
@pytest.mark.parametrize("grid", ["13x5", "21x7"])
def test_analytic_jacobian_matches_finite_differences_in_stick_and_slip(regime, mu, grid, rng):
    m = frictional(mu, grid, eta=1e-2)
    for _ in range(2):
        s = _state_in(m, regime, rng)
        assert m.stuck(s).all() if regime == "stick" else not m.stuck(s).any()
        lam = 0.3 + rng.random()
        J = m.jacobian(s, lam).toarray()
        Jfd = fd_jacobian(m, s, lam, 1.0)
        scale = np.abs(Jfd).max()
        assert np.abs(J - Jfd).max() < 1e-7 * scale
        assert np.all((np.abs(Jfd) > 1e-6 * scale) <= (J != 0))
        slider_rows = J[m.layout.foil_slice]
        assert (
            (not slider_rows.any())
            if regime == "stick"
            else np.all(np.abs(slider_rows[:, m.layout.foil_slice].diagonal()) > 0)
        )


def loop_energy(q_hat: float, fc: float, kt: float, eta: float, n_cycles: int = 3) -> float:
    """Energy dissipated in the last of ``n_cycles`` of an imposed ``Q = q_hat sin(tau)`` (normal load
    and so F_c held fixed), the slider ODE integrated with the model's own law: ``oint F dQ``."""

    def rate(t, y):
        return [K.coulomb_slider_rate(kt * (q_hat * math.sin(t) - y[0]), fc, eta)]

    T = 2 * math.pi
    t = np.linspace((n_cycles - 1) * T, n_cycles * T, 40001)
    sol = solve_ivp(
        rate, (0.0, n_cycles * T), [0.0], method="Radau", t_eval=t, rtol=1e-10, atol=1e-12, max_step=1e-3
    )
    assert sol.success
    F = kt * (q_hat * np.sin(t) - sol.y[0])
    dQ = q_hat * np.cos(t)
    return float(np.trapezoid(F * dQ, t))


@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning")  # scipy Radau on a stuck slider
@pytest.mark.parametrize("q_hat", [0.5, 1.0, 3.0])
def test_quasi_static_loop_dissipates_the_jenkins_loop_area(q_hat):
    fc, kt, eta = 0.2, 1.0, 1e-4
    exact = 4 * fc * (q_hat - fc / kt)
    w = loop_energy(q_hat, fc, kt, eta)
    assert abs(w - exact) < 0.01 * exact, (w, exact)


def test_sticking_loop_dissipates_nothing():
    fc, kt = 0.2, 1.0
    w = loop_energy(0.9 * fc / kt, fc, kt, 1e-4)  # |F| <= 0.9 F_c: the slider never moves
    assert abs(w) < 1e-9


def test_exact_limits_equilibrium_eigenvalues_and_critical_bearing_number():
    """mu_C -> infinity (stuck from S = 0) is the elastic foil with K_W + K_T; mu_C = 0 is the elastic foil
    with K_W (to O(eta): the free slider is a Maxwell element of relaxation time eta (K_W+K_T)/(K_W K_T))."""
    for mu, k_el, eta in ((1e6, KW + KT, None), (0.0, KW, 1e-7)):
        mf, me = frictional(mu, eta=eta), GFBModel("elastic", grid="21x5", foil_stiffness=k_el)
        sf, se = find_equilibrium(mf, 0.6), find_equilibrium(me, 0.6)
        L = mf.layout
        np.testing.assert_allclose(sf[L.pressure_slice], se[: L.n_pressure], atol=1e-9)
        np.testing.assert_allclose(L.rotor(sf), se[-4:], atol=1e-9)
        np.testing.assert_allclose(mf.foil_deflection(sf), me.foil_deflection(se), atol=1e-9)
        assert np.abs(mf.rhs(sf, 0.6)).max() < 1e-8
        if mu > 1:
            assert mf.stuck(sf).all() and not L.foil_state(sf).any()  # stuck where it started
        else:
            np.testing.assert_allclose(
                mf.friction_force(sf), 0.0, atol=1e-9
            )  # the free slider carries nothing
        ef, ee = jacobian_eigenvalues(mf, sf, 0.6), jacobian_eigenvalues(me, se, 0.6)
        np.testing.assert_allclose(ef[:10], ee[:10], atol=1e-6)
        cf, ce = critical_bearing_number(mf), critical_bearing_number(me)
        assert abs(cf.critical_bearing_number - ce.critical_bearing_number) < 1e-4
        assert abs(cf.whirl_frequency_ratio - ce.whirl_frequency_ratio) < 1e-4


def test_finite_friction_equilibrium_is_the_quasi_static_slider_limit():
    """Below mu_C = K_T / (K_W + K_T) a slider loaded proportionally from S = 0 slips to its limit
    |F| = F_c; above it sticks; either way the equilibrium is at rest and inside the friction limit."""
    for mu, stuck in ((0.1, False), (1.0, True)):
        m = frictional(mu)
        s = find_equilibrium(m, 0.6)
        assert np.abs(m.rhs(s, 0.6)).max() < 1e-8
        F, Fc = np.abs(m.friction_force(s)), m.friction_limit(s)
        assert np.all(F <= Fc * (1 + 1e-9) + 1e-12)
        if stuck:
            assert m.stuck(s).all() and not m.layout.foil_state(s).any()
        else:  # most columns are loaded monotonically by the load continuation and end at the limit
            assert np.isclose(F, Fc, rtol=1e-8, atol=1e-12).sum() >= 0.7 * F.size


def test_transient_keeps_stuck_sliders_put_and_slips_the_others():
    m = frictional(1.0)
    s0 = find_equilibrium(m, 0.6)
    L = m.layout
    # a small rotor kick: every slider keeps |F| well below F_c and must not move at all
    it = TrapezoidalIntegrator(m, L.with_rotor(s0, 0.0, L.rotor(s0)[1], 0.002, 0.0), 0.6)
    foil = np.arange(L.n_pressure, L.rotor_offset)
    res = it.advance(20.0, record_interval=0.5, record_indices=foil)
    assert res.status == "done" and res.trajectory.probes.shape[0] == 41
    assert np.abs(res.trajectory.xi).max() > 1e-4  # the rotor did move
    s1 = it.state
    assert m.stuck(s1).all()
    np.testing.assert_array_equal(res.trajectory.probes, np.broadcast_to(L.foil_state(s0), (41, foil.size)))
    np.testing.assert_array_equal(L.foil_state(s1), L.foil_state(s0))
    # low friction from the unloaded state: the sliders slip as the rotor falls, and end within the limit
    m2 = frictional(0.05)
    it2 = TrapezoidalIntegrator(m2, L.centred_state(), 0.6)
    assert it2.advance(30.0).status == "done"
    s2 = it2.state
    assert np.all(np.isfinite(s2)) and np.abs(L.foil_state(s2)).max() > 1e-3
    F, Fc = np.abs(m2.friction_force(s2)), m2.friction_limit(s2)
    assert np.all(F <= Fc + m2.slip_viscosity * np.abs(m2.rhs(s2, 0.6)[L.foil_slice]) + 1e-9)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"structure": "elastic", "stick_stiffness": 1.0}, "stick_stiffness"),
        ({"structure": "viscoelastic", "friction_coefficient": 0.1}, "friction_coefficient"),
        ({"structure": "rigid", "slip_viscosity": 1e-3}, "slip_viscosity"),
        ({"structure": "frictional", "stick_stiffness": -1.0}, "stick_stiffness"),
        ({"structure": "frictional", "stick_stiffness": float("nan")}, "stick_stiffness"),
        ({"structure": "frictional", "friction_coefficient": -0.1}, "friction_coefficient"),
        ({"structure": "frictional", "friction_coefficient": float("inf")}, "friction_coefficient"),
        ({"structure": "frictional", "slip_viscosity": 0.0}, "slip_viscosity"),
    ],
)
def test_invalid_frictional_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        GFBModel(grid="13x5", **kwargs)


def test_frictional_defaults_and_layout():
    m = GFBModel("frictional", grid="13x5", foil_stiffness=0.8)
    assert m.structure is Structure.FRICTIONAL and m.stick_stiffness == 0.8
    assert m.friction_coefficient == 0.1 and m.slip_viscosity == 1e-3
    assert m.layout.n_foil == 12 and m.layout.block_size == m.grid.n_rows + 1
    assert not m.sparse_offdiagonal_blocks


# ---------------------------------------------------------------------------------------------- CLI
def _critical_json(argv: list[str], capsys) -> dict:
    from gfb_env.cli import main

    assert main(["critical", "--grid", "21x5", "--json", *argv]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(
    "friction,elastic",
    [
        (["--friction-coefficient", "1e6"], "1.5"),  # stuck from the unloaded state: K_W + K_T
        (["--friction-coefficient", "0", "--slip-viscosity", "1e-7"], "1.0"),  # free slider: K_W
    ],
)
def test_cli_critical_exact_limits(friction, elastic, capsys):
    f = _critical_json(
        ["--structure", "frictional", "--foil-stiffness", "1.0", "--stick-stiffness", "0.5", *friction],
        capsys,
    )
    e = _critical_json(["--structure", "elastic", "--foil-stiffness", elastic], capsys)
    assert f["structure"] == "frictional" and f["stick_stiffness"] == 0.5
    assert abs(f["critical_bearing_number"] - e["critical_bearing_number"]) < 1e-4
    assert abs(f["whirl_frequency_ratio"] - e["whirl_frequency_ratio"]) < 1e-4


def test_cli_equilibrium_reports_the_friction_parameters(capsys):
    from gfb_env.cli import main

    argv = ["equilibrium", "--structure", "frictional", "--friction-coefficient", "0.2", "--grid", "21x5"]
    assert main([*argv, "--bearing-number", "0.6", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["friction_coefficient"] == 0.2 and d["bearing_force"] == pytest.approx(d["load"], rel=1e-9)


_SPEED = {
    "critical": [],
    "simulate": ["--bearing-number", "0.6", "--duration", "5"],
    "equilibrium": ["--bearing-number", "0.6"],
    "hysteresis": [],
    "runup": ["--bearing-range", "0.55", "0.6"],
}
_BAD = [
    (["--structure", "frictional", "--stick-stiffness", "-1"], "--stick-stiffness", "positive"),
    (["--structure", "frictional", "--stick-stiffness", "nan"], "--stick-stiffness", "positive"),
    (["--structure", "frictional", "--friction-coefficient", "-0.1"], "--friction-coefficient", ">= 0"),
    (["--structure", "frictional", "--friction-coefficient", "nan"], "--friction-coefficient", "finite"),
    (["--structure", "frictional", "--slip-viscosity", "0"], "--slip-viscosity", "positive"),
    (["--structure", "elastic", "--stick-stiffness", "1"], "--stick-stiffness", "frictional only"),
    (
        ["--structure", "viscoelastic", "--friction-coefficient", "0.1"],
        "--friction-coefficient",
        "frictional only",
    ),
    (["--friction-coefficient", "0.1"], "--friction-coefficient", "frictional only"),  # default: viscoelastic
]


@pytest.mark.parametrize("cmd", sorted(_SPEED))
@pytest.mark.parametrize("argv,option,fragment", _BAD)
def test_cli_refuses_bad_friction_options(cmd, argv, option, fragment, tmp_path, capsys):
    from gfb_env.cli import main

    out = tmp_path / "out"
    extra = ["--out", str(out)] if cmd in ("simulate", "runup") else []
    assert_refused_at_once(
        main, [cmd, *argv, "--grid", "21x5", *_SPEED[cmd], *extra], option, fragment, capsys, out
    )


def test_cli_hysteresis_stuck_limit_is_the_elastic_foil_and_reports_the_friction(capsys):
    """mu_C = 1e6 (stuck from the unloaded state): the elastic K_W + K_T = 1.5 foil's Hopf point and
    contact bearing number (0.565238 and 0.446175 on 21x5, as `gfb hysteresis --structure elastic`)."""
    from gfb_env.cli import main

    argv = ["hysteresis", "--structure", "frictional", "--foil-stiffness", "1", "--stick-stiffness", "0.5"]
    assert main([*argv, "--friction-coefficient", "1e6", "--grid", "21x5", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["critical_bearing_number"] == pytest.approx(0.565238, abs=1e-5)
    assert d["contact_bearing_number"] == pytest.approx(0.446175, abs=1e-5)
    assert d["friction_coefficient"] == 1e6 and d["stick_stiffness"] == 0.5
    assert d["sliders_on_limit"] == "stick"


def test_cli_runup_takes_the_frictional_foil(tmp_path, capsys):
    from gfb_env.cli import main

    argv = ["runup", "--structure", "frictional", "--friction-coefficient", "0.1", "--grid", "21x5"]
    out = tmp_path / "r"
    assert main([*argv, "--bearing-range", "0.5", "0.52", "--out", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["structure"] == "frictional" and d["status"] == "done"
    assert (out / "summary.json").exists()


def test_finite_friction_critical_bearing_number_converges_in_eta_and_transients_agree():
    """mu_C = 0.3 (sliders partly at their limit, linearised on the slip branch): Lambda_c converges as the
    slip viscosity vanishes, lies between the free (K_W) and the stuck (K_W + K_T) foil, and a small
    rotor perturbation decays 0.01 below it and grows 0.01 above it."""
    scan = {"history": "scan", "sliders_on_limit": "slip"}  # the default scan's history, slip branch
    lc = {
        eta: critical_bearing_number(frictional(0.3, eta=eta), **scan).critical_bearing_number
        for eta in (1e-3, 1e-5)
    }
    assert abs(lc[1e-3] - lc[1e-5]) < 1e-4
    stuck_lc = critical_bearing_number(
        GFBModel("elastic", grid="21x5", foil_stiffness=KW + KT)
    ).critical_bearing_number
    free_lc = critical_bearing_number(
        GFBModel("elastic", grid="21x5", foil_stiffness=KW)
    ).critical_bearing_number
    assert stuck_lc < lc[1e-3] < free_lc
    m = frictional(0.3)
    L = m.layout
    for lam, grows in ((lc[1e-3] - 0.01, False), (lc[1e-3] + 0.01, True)):
        s = find_equilibrium(m, lam)
        it = TrapezoidalIntegrator(m, L.with_rotor(s, *(L.rotor(s)[:2] + [1e-3, 0.0])), lam)
        x = it.advance(600.0, record_interval=1.0).trajectory.xi - L.rotor(s)[0]
        ratio = np.abs(x[-100:]).max() / np.abs(x[50:150]).max()
        assert (ratio > 2.0) if grows else (ratio < 0.9), ratio


# ------------------------------------------------------------------------- bearing-file inputs
def test_bearing_file_friction_table_is_nondimensionalised_and_leaves_the_bearing_alone(tmp_path):
    from gfb_env.params import BearingParameters, FrictionParameters, read_bearing_file, shipped_bearing_path

    b0 = BearingParameters()
    # the shipped frictional Table 1: the same bearing (as_dict, the envs' task-constants key, unchanged)
    b, fr = read_bearing_file(shipped_bearing_path("table1_frictional"))
    assert (
        b == b0
        and b.as_dict() == b0.as_dict()
        and BearingParameters.from_toml(shipped_bearing_path("table1_frictional")) == b0
    )
    assert fr == FrictionParameters(friction_coefficient=0.1, stick_stiffness_n_m3=4.735e9)
    assert read_bearing_file(shipped_bearing_path("table1"))[1] is None
    # K_T = k_T C / p0, the scaling of K_W = k_W C / p0
    m = GFBModel("frictional", grid="13x5", bearing=b, friction=fr)
    k_w_area = b.foil_stiffness * b.ambient_pressure_pa / b.clearance_m
    assert m.stick_stiffness == pytest.approx(4.735e9 * b.clearance_m / b.ambient_pressure_pa, rel=1e-15)
    assert m.stick_stiffness == pytest.approx(m.foil_stiffness * 4.735e9 / k_w_area, rel=1e-12)
    assert m.friction_coefficient == 0.1
    # a ratio is relative to the model's K_W (here an override); explicit arguments override the file
    p = tmp_path / "b.toml"
    p.write_text("clearance_m = 40e-6\n[friction]\nfriction_coefficient = 0.2\nstick_stiffness_ratio = 0.5\n")
    b2, fr2 = read_bearing_file(p)
    assert b2 == b0.replace(clearance_m=40e-6)
    m2 = GFBModel("frictional", grid="13x5", bearing=b2, foil_stiffness=3.0, friction=fr2)
    assert m2.stick_stiffness == 1.5 and m2.friction_coefficient == 0.2
    m3 = GFBModel(
        "frictional", grid="13x5", bearing=b2, friction=fr2, stick_stiffness=0.7, friction_coefficient=0.0
    )
    assert m3.stick_stiffness == 0.7 and m3.friction_coefficient == 0.0
    # neither stiffness given: the model's default K_T = K_W
    m4 = GFBModel("frictional", grid="13x5", friction=FrictionParameters(0.3))
    assert m4.stick_stiffness == m4.foil_stiffness and m4.friction_coefficient == 0.3
    with pytest.raises(ValueError, match="friction is a parameter of the frictional foil"):
        GFBModel("elastic", grid="13x5", friction=fr)


@pytest.mark.parametrize(
    "table,match",
    [
        ("friction_coefficient = -0.1", r"friction\.friction_coefficient must be >= 0"),
        ("friction_coefficient = nan", r"friction\.friction_coefficient must be finite"),
        ("friction_coefficient = 'high'", r"friction\.friction_coefficient must be a number"),
        ("friction_coefficient = true", r"friction\.friction_coefficient must be a number"),
        ("stick_stiffness_n_m3 = 0", r"friction\.stick_stiffness_n_m3 must be positive"),
        ("stick_stiffness_ratio = -1", r"friction\.stick_stiffness_ratio must be positive"),
        ("stick_stiffness_ratio = inf", r"friction\.stick_stiffness_ratio must be finite"),
        ("stick_stiffness_n_m3 = 1e9\nstick_stiffness_ratio = 1", "at most one"),
        ("friction_coeficient = 0.1", r"unknown key friction\.friction_coeficient \(did you mean"),
        ("[friction.deeper]\nx = 1", r"unknown key friction\.deeper"),
    ],
)
def test_bad_friction_table_is_refused_naming_the_field(table, match, tmp_path):
    from gfb_env.params import BearingParameters, read_bearing_file

    p = tmp_path / "bad.toml"
    p.write_text(f"[friction]\n{table}\n")
    for read in (read_bearing_file, BearingParameters.from_toml):
        with pytest.raises(ValueError, match=match) as e:
            read(p)
        assert str(p) in str(e.value) and "\n" not in str(e.value)


def test_cli_takes_the_bearing_files_friction_and_refuses_a_bad_one(tmp_path, capsys):
    from gfb_env.cli import main

    argv = ["equilibrium", "--structure", "frictional", "--grid", "13x5", "--bearing-number", "0.6", "--json"]
    p = tmp_path / "f.toml"
    p.write_text("[friction]\nfriction_coefficient = 0.25\nstick_stiffness_ratio = 2\n")
    assert main([*argv, "--bearing", str(p)]) == 0
    d = json.loads(capsys.readouterr().out)
    m = GFBModel("frictional", grid="13x5")
    assert d["friction_coefficient"] == 0.25 and d["stick_stiffness"] == pytest.approx(2 * m.foil_stiffness)
    assert main([*argv, "--bearing", str(p), "--friction-coefficient", "0.05"]) == 0  # the option wins
    assert json.loads(capsys.readouterr().out)["friction_coefficient"] == 0.05
    assert main([*argv, "--bearing", "table1_frictional"]) == 0  # the shipped one, by name
    d = json.loads(capsys.readouterr().out)
    assert d["friction_coefficient"] == 0.1 and d["stick_stiffness"] == pytest.approx(m.foil_stiffness, 1e-3)
    # another structure ignores the table (the file describes the hardware)
    assert main(["equilibrium", "--grid", "13x5", "--bearing-number", "0.6", "--bearing", str(p)]) == 0
    capsys.readouterr()
    # gfb bearing reports the table (and nothing new for a file without one)
    assert main(["bearing", "--bearing", str(p), "--json"]) == 0
    fr = json.loads(capsys.readouterr().out)["friction"]
    assert fr["friction_coefficient"] == 0.25 and fr["stick_stiffness"] == pytest.approx(2 * m.foil_stiffness)
    assert main(["bearing", "--bearing", "table1", "--json"]) == 0
    assert "friction" not in json.loads(capsys.readouterr().out)
    p.write_text("[friction]\nstick_stiffness_ratio = 0\n")
    out = tmp_path / "out"
    assert_refused_at_once(
        main, [*argv, "--bearing", str(p)], "--bearing", "friction.stick_stiffness_ratio", capsys, out
    )
