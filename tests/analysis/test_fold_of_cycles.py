"""The fold of cycles (lower edge of the hysteresis band) on the environments' coarse grids (issue 18,
defect 3): the branch of cycles starts at the Hopf point, a computation failure is exit 1, and the
shooting sweep keeps its per-step factors in a few arrays (bounded memory)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gfb_env import GFBModel, Grid, TrapezoidalIntegrator
from gfb_env.analysis import critical_bearing_number, fold_bearing_number
from gfb_env.analysis.periodic import ShootingError, _OrbitSweep, hopf_cycles
from gfb_env.cli import main
from gfb_env.equilibrium import find_equilibrium

TRAINING_GRID = Grid(31, 7)  # gfb_env.envs.DEFAULT_GRID


@pytest.fixture(scope="module")
def fold_31x7():
    """K_W = 1, D_W = 1 on 31x7: the developed whirl at Lambda_c + 0.01 closes the film there (the old
    start from a settled whirl failed), but the fold exists below Lambda_c."""
    m = GFBModel("viscoelastic", TRAINING_GRID, foil_stiffness=1.0)
    lc = critical_bearing_number(m, 1.0).critical_bearing_number
    return m, lc, fold_bearing_number(m, 1.0, critical=lc, n_steps=300)


def test_fold_on_the_training_grid_lies_below_the_hopf_point(fold_31x7):
    _, lc, fr = fold_31x7
    assert fr.fold_bearing_number is not None, fr.message
    assert 0.85 * lc < fr.fold_bearing_number < lc and fr.subcritical
    assert fr.fold_bearing_number == pytest.approx(0.52819, abs=2e-4)  # measured (issue 18 report)
    lams = fr.branch.bearing_number
    j = int(np.argmin(lams))
    # from the Hopf point: small unstable cycles, Lambda falling; past the fold the whirl is stable
    assert fr.branch.orbits[0].amplitude < 0.1 and fr.branch.orbits[0].stable is False
    assert all(o.stable is False for o in fr.branch.orbits[: j - 1])
    assert any(o.stable for o in fr.branch.orbits[j + 1 :])
    # on 31x7 the stable whirl comes near contact before Lambda_c: said, not extrapolated
    assert "near contact" in fr.message and np.isnan(fr.amplitude_at_critical)


def test_transients_confirm_the_fold(fold_31x7):
    """A run started on the computed stable cycle stays on it; 0.001 above the fold the whirl persists,
    0.001 below it it collapses to the equilibrium (adaptive integrator, an independent discretisation)."""
    m, _, fr = fold_31x7
    lf = fr.fold_bearing_number
    o = max((x for x in fr.branch.orbits if x.stable), key=lambda x: x.min_film_thickness)
    integ = TrapezoidalIntegrator(m, o.state, o.bearing_number, 1.0, rtol=1e-5, atol=1e-5)
    r = integ.advance(10 * o.period, record_interval=o.period / 100)
    assert 0.5 * np.ptp(r.trajectory.xi) == pytest.approx(o.amplitude, rel=0.01)
    amps = {}
    for dl in (0.001, -0.001):
        integ = TrapezoidalIntegrator(m, o.state, o.bearing_number, 1.0, rtol=1e-5, atol=1e-5)
        integ.advance(50.0, bearing_number=lf + dl)
        r = integ.advance(integ.tau + 2500.0, record_interval=0.5)
        amps[dl] = 0.5 * float(np.ptp(r.trajectory.xi[-120:]))
    assert amps[0.001] > 0.9 * o.amplitude  # the whirl persists just above the fold
    assert amps[-0.001] < 0.01  # and dies just below it


def test_hysteresis_command_on_the_training_grid(capsys):
    argv = ["hysteresis", "--structure", "viscoelastic", "--foil-stiffness", "1", "--foil-damping", "1"]
    assert main([*argv, "--grid", "31x7", "--json"]) == 0  # was exit 2 "no limit cycle could be computed"
    d = json.loads(capsys.readouterr().out)
    assert d["subcritical"] is True
    assert d["fold_bearing_number"] < d["critical_bearing_number"]
    assert d["fold_speed_rpm"] < d["critical_speed_rpm"]


def test_a_computation_failure_is_exit_1_in_one_line(monkeypatch, capsys):
    import gfb_env.analysis.periodic as periodic

    def fail(*args, **kwargs):
        raise ShootingError("shooting Newton did not converge in 15 iterations (residual 1e-3)")

    monkeypatch.setattr(periodic, "fold_bearing_number", fail)
    argv = ["hysteresis", "--foil-stiffness", "1", "--foil-damping", "1", "--grid", "21x5", "--json"]
    assert main(argv) == 1  # exit 2 is for bad input only
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1
    assert lines[0].startswith("gfb hysteresis: error: no limit cycle could be computed: shooting Newton")


def test_hopf_cycles_are_small_cycles_on_the_subcritical_side():
    m = GFBModel("viscoelastic", Grid(21, 5), foil_stiffness=1.0)
    lc = critical_bearing_number(m, 1.0).critical_bearing_number
    o1, o2 = hopf_cycles(m, 1.0, lc, n_steps=100)
    assert o1.residual < 1e-8 and abs(o1.state[m.layout.xi_dot_index]) < 1e-8
    assert 0.04 < o1.amplitude < 0.06 and 0.09 < o2.amplitude < 0.12
    assert o2.bearing_number < o1.bearing_number < lc  # subcritical: the cycles lie below Lambda_c
    assert o1.stable is False  # the unstable cycle bounding the equilibrium's basin
    # the period of the small cycle is that of the critical eigenvalue
    ev = np.linalg.eigvals(m.jacobian(find_equilibrium(m, lc), lc, 1.0).toarray())
    omega = ev.imag[np.argmax(np.where(ev.imag > 0, ev.real, -np.inf))]
    assert o1.period == pytest.approx(2 * np.pi / omega, rel=0.02)


def test_sweep_products_equal_the_sparse_variational_recursion():
    """The block-stored factors give the monodromy product of the sparse recursion
    ``(I - h/2 J_{n+1}) X_{n+1} = (I + h/2 J_n) X_n`` (reference: the CSR Jacobian and SuperLU)."""
    m = GFBModel("viscoelastic", Grid(21, 5), foil_stiffness=1.0)
    L = m.layout
    s = find_equilibrium(m, 0.58)
    s = L.with_rotor(s, s[L.xi_index] + 0.2, s[L.eta_index])
    N, T = 40, 20.0
    sw = _OrbitSweep(m, s, T, 0.58, 1.0, N, need_dlam=True)
    h = T / N
    # reference: the same trapezoidal steps (adaptive integrator off: solve each step by Newton)
    eye = sp.identity(L.size, format="csc")
    states = [s]
    for _ in range(N):
        x, k0 = states[-1].copy(), m.rhs(states[-1], 0.58, 1.0)
        for _ in range(30):
            r = x - states[-1] - 0.5 * h * (k0 + m.rhs(x, 0.58, 1.0))
            x = x - spla.spsolve((eye - 0.5 * h * m.jacobian(x, 0.58, 1.0)).tocsc(), r)
        states.append(x)
    assert np.max(np.abs(states[-1] - sw.end)) < 1e-9
    v = np.random.default_rng(1).standard_normal(L.size)
    y = v.copy()
    for a, b in zip(states[:-1], states[1:], strict=True):
        y = spla.spsolve(
            (eye - 0.5 * h * m.jacobian(b, 0.58, 1.0)).tocsc(), y + 0.5 * h * (m.jacobian(a, 0.58, 1.0) @ y)
        )
    assert np.max(np.abs(sw.monodromy_product(v) - y)) < 1e-9 * np.max(np.abs(y))


def test_shooting_memory_stays_bounded_on_the_paper_grid():
    """Six more sweeps with Floquet multipliers on 79x7 in a fresh process: the peak resident memory
    grows by less than 100 MB over the first (one sweep's factors ~60 MB; measured 0).  Stored as 300
    SuperLU + CSR objects per sweep they took ~107 MB each and the heap kept growing (fragmentation):
    +304 MB over the same six sweeps, 2.4 GB for one ``gfb hysteresis`` run on 79x7."""
    code = textwrap.dedent(
        """
        import resource
        from gfb_env import GFBModel
        from gfb_env.analysis.periodic import _OrbitSweep, _floquet
        from gfb_env.equilibrium import find_equilibrium
        m = GFBModel("viscoelastic", "79x7", foil_stiffness=1.0)
        L = m.layout
        s = find_equilibrium(m, 0.59)
        s = L.with_rotor(s, s[L.xi_index] + 0.3, s[L.eta_index])
        sw = _OrbitSweep(m, s, 25.0, 0.59, 1.0, 300, need_dlam=True)  # compiled, one sweep held
        _floquet(sw)
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        for _ in range(6):
            sw = None
            sw = _OrbitSweep(m, s, 25.0, 0.59, 1.0, 300, need_dlam=True)
            _floquet(sw)
        print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    growth_mb = float(out.stdout.strip().splitlines()[-1])
    assert growth_mb < 100, growth_mb


def test_the_benchmark_path_figure_draws_the_tasks_hysteresis_band(tmp_path, monkeypatch):
    """The band of the tasks' nominal bearing (31x7, K_W = 0.50) comes from the shipped tasks map: the
    path figure draws it instead of saying "fold of cycles not mapped"; the agents' map is unchanged."""
    import gymnasium as gym

    import gfb_experiments.benchmark_agents as bench
    from gfb_agents.nominal_map import NominalMap

    env = gym.make("gfb_env/RunUp-v2")
    nmap = NominalMap.from_env(env)
    assert len(nmap.fold) == 0  # what the agents read: unchanged
    band = bench.nominal_band_lower(env)
    assert band is not None
    lower = np.array([band(d) for d in nmap.damping])
    crit = np.array([nmap.critical_at(d) for d in nmap.damping])
    assert np.all(lower <= crit + 2e-3) and np.any(lower < crit - 0.02)  # a band, below Lambda_c
    titles = []
    monkeypatch.setattr("matplotlib.axes.Axes.set_title", lambda ax, t, **kw: titles.append(t))
    paths = {
        ("gfb_env/RunUp-v2", "naive"): {"lam": [0.4, 0.6], "dw": [2.0, 2.0], "reason": "", "success": True}
    }
    bench.plot_paths(paths, nmap, tmp_path / "p.png", ["gfb_env/RunUp-v2"], band)
    assert (tmp_path / "p.png").exists() and not any("not mapped" in t for t in titles)
    env.close()
