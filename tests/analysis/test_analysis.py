"""Tests of gfb_env.analysis: stability, Lambda_c, shooting, Floquet, fold, FFT, maps, sweeps, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gfb_env import GFBModel, Grid, TrapezoidalIntegrator
from gfb_env.analysis import (
    NoCriticalPointError,
    NoStableEquilibriumError,
    amplitude_spectrum,
    continue_equilibria,
    continue_periodic_orbits,
    critical_bearing_number,
    dominant_frequency,
    find_periodic_orbit,
    linear_stability,
    load_hysteresis_map,
    optimal_foil_damping,
    periodic_orbit_from_simulation,
    settle_whirl,
    write_hysteresis_map,
)
from gfb_env.sweeps import load_checkpoint, run_sweep

COARSE = Grid(33, 7)


# ---------------------------------------------------------------------------------------------- stability
@pytest.fixture(scope="module")
def rigid_critical():
    return critical_bearing_number(GFBModel("rigid", Grid(79, 7)))


def test_critical_bearing_number_rigid_paper_grid(rigid_critical):
    cp = rigid_critical
    assert 0.45 < cp.critical_bearing_number < 0.6
    # the growth rate changes sign at Lambda_c (to the tolerance of brentq)
    m = GFBModel("rigid", Grid(79, 7))
    below = linear_stability(m, cp.critical_bearing_number - 0.005, guess=cp.state)
    above = linear_stability(m, cp.critical_bearing_number + 0.005, guess=cp.state)
    assert below.growth_rate < 0 < above.growth_rate
    assert abs(linear_stability(m, cp.critical_bearing_number, state=cp.state).growth_rate) < 1e-5
    # a whirl mode: sub-synchronous, below Lambda/2
    assert 0.3 < cp.whirl_frequency_ratio < 0.55
    assert cp.critical_speed_rpm == pytest.approx(m.bearing.speed_rpm_at(cp.critical_bearing_number))
    d = cp.as_dict()
    for k in (
        "critical_bearing_number",
        "critical_speed_rpm",
        "whirl_frequency_ratio",
        "eccentricity_at_onset",
    ):
        assert k in d and math.isfinite(d[k])


def test_hopf_pair_crosses_with_nonzero_speed(rigid_critical):
    assert rigid_critical.crossing_speed > 0.05
    m = GFBModel("rigid", Grid(79, 7))
    st = linear_stability(m, rigid_critical.critical_bearing_number, state=rigid_critical.state)
    # the critical eigenvalue is a complex pair, not a real eigenvalue
    assert st.whirl_frequency > 0.1
    ev = st.eigenvalues
    assert np.any(np.isclose(ev, np.conj(ev[0]), atol=1e-8))


def test_critical_bearing_number_converges_under_grid_refinement(rigid_critical):
    coarse = critical_bearing_number(GFBModel("rigid", Grid(41, 7))).critical_bearing_number
    # refining phi changes little (DESIGN.md: the Z direction dominates the error)
    assert abs(coarse - rigid_critical.critical_bearing_number) < 0.01


@pytest.mark.slow
def test_critical_bearing_number_converges_in_z():
    vals = [
        critical_bearing_number(GFBModel("rigid", Grid(79, nz))).critical_bearing_number for nz in (7, 11, 15)
    ]
    d1, d2 = abs(vals[1] - vals[0]), abs(vals[2] - vals[1])
    assert d2 < d1  # converging
    assert d2 < 0.02


def test_critical_reports_missing_stable_equilibrium_and_missing_onset():
    m = GFBModel("rigid", Grid(41, 7))
    with pytest.raises(NoStableEquilibriumError):
        critical_bearing_number(m, bearing_range=(0.6, 0.9), scan_step=0.1)
    with pytest.raises(NoCriticalPointError):
        critical_bearing_number(m, bearing_range=(0.2, 0.4), scan_step=0.1)
    with pytest.raises(ValueError, match="foil_damping"):
        critical_bearing_number(m, foil_damping=-1.0)
    with pytest.raises(ValueError, match="bearing_range"):
        critical_bearing_number(m, bearing_range=(0.5, 0.2))


def test_viscoelastic_damping_raises_critical_bearing_number():
    m = GFBModel("viscoelastic", Grid(41, 7), foil_stiffness=1.0)
    lc1 = critical_bearing_number(m, 1.0, bearing_range=(0.45, 0.8)).critical_bearing_number
    lc4 = critical_bearing_number(m, 4.0, bearing_range=(0.45, 0.8)).critical_bearing_number
    assert lc4 > lc1


def test_equilibrium_continuation_is_smooth():
    m = GFBModel("elastic", Grid(41, 7))
    lams = np.linspace(0.3, 0.9, 13)
    br = continue_equilibria(m, lams)
    assert len(br) == len(lams) and br.failed_at is None
    eps = br.eccentricity
    assert np.all(np.diff(eps) < 0)  # the journal centres as the speed rises
    # smooth: second differences much smaller than first differences
    assert np.max(np.abs(np.diff(eps, 2))) < 0.2 * np.max(np.abs(np.diff(eps)))
    assert np.all(br.min_film_thickness > 0)
    with pytest.raises(ValueError):
        continue_equilibria(m, [])


# ---------------------------------------------------------------------------------------------- FFT
def test_fft_finds_known_sinusoid():
    dt = 0.25
    t = np.arange(0, 3000, dt)
    omega = 0.2937
    x = 0.4 * np.sin(omega * t + 0.3) + 0.05 * np.sin(3.1 * omega * t) + 0.7
    df = dominant_frequency(x, dt, fraction=0.5, bearing_number=0.6)
    assert df.omega == pytest.approx(omega, rel=2e-3)
    assert df.amplitude == pytest.approx(0.4, rel=0.05)
    assert df.ratio == pytest.approx(omega / 0.6, rel=2e-3)
    sp = amplitude_spectrum(x, dt)
    assert sp.omega.shape == sp.amplitude.shape
    with pytest.raises(ValueError, match="sample_interval"):
        dominant_frequency(x, 0.0)


# ---------------------------------------------------------------------------------------------- orbits
@pytest.fixture(scope="module")
def coarse_orbit():
    """A settled, shot limit cycle on a coarse grid: viscoelastic K_W = 1, D_W = 4, above Lambda_c."""
    m = GFBModel("viscoelastic", COARSE, foil_stiffness=1.0)
    lc = critical_bearing_number(m, 4.0).critical_bearing_number
    lam = lc + 0.01
    sw = settle_whirl(
        m, lam, 4.0, kick=0.3, tau_max=6000, integrator_options={"touchdown_film_thickness": 1e-4}
    )
    assert sw.status == "whirl"
    orb = periodic_orbit_from_simulation(m, lam, 4.0, sw.state, sw.period, n_steps=100)
    return m, lc, orb


def test_shooting_orbit_returns_to_itself(coarse_orbit):
    m, lc, orb = coarse_orbit
    assert orb.residual < 1e-7
    assert abs(orb.state[m.layout.xi_dot_index]) < 1e-7  # on the phase section
    # integrated once more with the fixed-step map: returns to itself
    again = find_periodic_orbit(m, orb.bearing_number, 4.0, orb.state, orb.period, n_steps=100, floquet=False)
    assert again.newton_iterations <= 2
    assert np.max(np.abs(again.state - orb.state)) < 1e-6
    # and with the independent adaptive integrator (a different discretisation): close
    integ = TrapezoidalIntegrator(m, orb.state, orb.bearing_number, 4.0, rtol=1e-5, atol=1e-5)
    integ.advance(orb.period)
    r0, r1 = m.layout.rotor(orb.state), m.layout.rotor(integ.state)
    assert np.max(np.abs(r1[:2] - r0[:2])) < 0.05 * max(orb.amplitude, 0.1)
    # a whirl near Lambda / 2, well below the rotor speed
    assert 0.25 < orb.whirl_frequency_ratio < 0.6


def test_floquet_multiplier_one_and_stable_cycle(coarse_orbit):
    _, _, orb = coarse_orbit
    assert abs(orb.trivial_multiplier - 1.0) < 1e-3
    assert orb.stable is True
    assert np.all(np.abs(orb.nontrivial_multipliers) < 1.0)


def test_fold_of_cycles_below_critical_bearing_number(coarse_orbit):
    m, lc, orb = coarse_orbit
    br = continue_periodic_orbits(m, orb, first_step=-0.005, max_points=25)
    assert br.fold_bearing_number is not None, br.message
    assert br.fold_bearing_number < lc  # subcritical Hopf: a hysteresis band
    # past the fold, the cycle branch is unstable (a multiplier outside the unit circle)
    j = int(np.argmin(br.bearing_number))
    assert all(o.stable for o in br.orbits[: max(j - 1, 1)])
    assert br.orbits[-1].stable is False


# ---------------------------------------------------------------------------------------------- maps, sweeps
def _square(x: float, y: float = 0.0) -> dict:
    return {"value": x * x + y}


def test_sweep_resumes_from_checkpoint(tmp_path):
    ck = tmp_path / "ck.jsonl"
    pts = [{"x": float(i)} for i in range(5)]
    recs = run_sweep(_square, pts[:3], ck, n_jobs=1, progress=False)
    assert [r["result"]["value"] for r in recs] == [0.0, 1.0, 4.0]
    # simulate an interruption mid-write: a truncated last line is ignored
    with ck.open("a") as fh:
        fh.write('{"point": {"x": 9')
    calls = []

    def counting(x, y=0.0):
        calls.append(x)
        return _square(x, y)

    recs = run_sweep(counting, pts, ck, n_jobs=1, progress=False)
    assert sorted(calls) == [3.0, 4.0]  # only the unfinished points ran
    assert [r["result"]["value"] for r in recs] == [0.0, 1.0, 4.0, 9.0, 16.0]
    assert len([r for r in load_checkpoint(ck) if "point" in r]) == 5


def test_sweep_records_errors():
    def bad(x):
        raise RuntimeError("boom")

    recs = run_sweep(bad, [{"x": 1.0}], None, progress=False)
    assert recs[0]["result"] is None and "boom" in recs[0]["error"]


def test_sweep_on_dask_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cl:
        pts = [{"x": float(i), "y": 1.0} for i in range(4)]
        recs = run_sweep(_square, pts, tmp_path / "d.jsonl", scheduler=cl, progress=False)
    assert [r["result"]["value"] for r in recs] == [1.0, 2.0, 5.0, 10.0]
    assert len(load_checkpoint(tmp_path / "d.jsonl")) == 4


def test_hysteresis_map_roundtrip(tmp_path):
    rows = [
        {"foil_stiffness": 1.0, "foil_damping": d, "critical_bearing_number": lc, "fold_bearing_number": lf}
        for d, lc, lf in ((1.0, 0.58, 0.54), (4.0, 0.62, 0.60), (16.0, 0.59, math.nan))
    ]
    p = write_hysteresis_map(rows, tmp_path)
    hm = load_hysteresis_map(p)
    assert hm.critical_bearing_number.tolist() == [0.58, 0.62, 0.59]
    assert math.isnan(hm.fold_bearing_number[2])
    assert hm.region(1.0, 4.0, 0.55) == "stable"
    assert hm.region(1.0, 4.0, 0.61) == "bistable"
    assert hm.region(1.0, 4.0, 0.63) == "whirl"
    with pytest.raises(FileNotFoundError):
        load_hysteresis_map(tmp_path / "missing.csv")


def test_optimal_foil_damping_from_committed_map():
    d1 = optimal_foil_damping(1.0)  # the map is committed: a missing file is a failure, not a skip
    d_table = optimal_foil_damping(2.337)
    assert 1.0 < d1 < 10.0  # the paper: near 4 at K_W = 1
    assert d_table > d1  # the optimum grows with K_W
    with pytest.raises(ValueError, match="foil_stiffness"):
        optimal_foil_damping(-1.0)


# ---------------------------------------------------------------------------------------------- CLI
def _cli(argv):
    """The real ``gfb`` parser; handler exceptions propagate (``main`` maps ValueError to exit 2)."""
    from gfb_env.cli import build_parser

    args = build_parser().parse_args(argv)
    return args.func(args)


def test_cli_critical_json(capsys):
    assert _cli(["critical", "--structure", "rigid", "--grid", "41x7", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for k in (
        "critical_bearing_number",
        "critical_speed_rpm",
        "whirl_frequency_ratio",
        "eccentricity_at_onset",
    ):
        assert isinstance(d[k], float)
    assert 0.45 < d["critical_bearing_number"] < 0.6


def test_cli_bad_input_is_rejected(capsys):
    from gfb_env.cli import main

    for argv, fragment in (
        (["critical", "--grid", "79by7"], "grid"),
        (["critical", "--foil-damping", "-2"], "--foil-damping"),
    ):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2 and fragment in capsys.readouterr().err
    with pytest.raises(ValueError, match="foil-stiffness"):
        _cli(["map", "--foil-stiffness", "a,b", "--out", "/tmp/x"])
    with pytest.raises(ValueError):  # no stable equilibrium in the range
        _cli(["critical", "--structure", "rigid", "--grid", "41x7", "--bearing-range", "0.6", "0.9"])
    assert main(["critical", "--structure", "rigid", "--grid", "41x7", "--bearing-range", "0.6", "0.9"]) == 2


@pytest.mark.parametrize("cmd", ["critical", "hysteresis", "map"])
def test_cli_help(cmd, capsys):
    with pytest.raises(SystemExit) as e:
        _cli([cmd, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "--json" in out and "--grid" in out and "--foil-stiffness" in out


def test_cli_map_writes_files(tmp_path, capsys):
    out = tmp_path / "map"
    rc = _cli(
        [
            "map",
            "--foil-stiffness",
            "1",
            "--foil-damping",
            "1,4",
            "--grid",
            "25x5",
            "--out",
            str(out),
            "--json",
        ]
    )
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert (out / "stability_map.csv").exists() and (out / "stability_map.png").exists()
    assert d["rigid_critical_bearing_number"] > 0


def test_analysis_size_limits_refuse_before_any_solve():
    from gfb_env.analysis.stability import MAX_EIGEN_STATE_SIZE, check_eigen_size, jacobian_eigenvalues

    big = GFBModel("viscoelastic", Grid(157, 25))  # state size 3748
    assert big.layout.size > MAX_EIGEN_STATE_SIZE
    with pytest.raises(ValueError, match=r"^grid 157x25 is too large for the dense eigenvalue analysis"):
        check_eigen_size(big)
    with pytest.raises(ValueError, match="dense eigenvalue"):
        jacobian_eigenvalues(big, big.layout.centred_state(), 0.6)
    with pytest.raises(ValueError, match="dense eigenvalue"):
        critical_bearing_number(big)
    check_eigen_size(GFBModel("viscoelastic", Grid(157, 13)))  # 1876: allowed
    with pytest.raises(ValueError, match=r"^scan_step 1e-06 .* at most 1000"):
        critical_bearing_number(GFBModel("rigid", COARSE), scan_step=1e-6)
