"""The superposed synchronous response (``synchronous_response="superposed"``, issue 20 item 2)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs import V2_ENV_IDS
from gfb_env.envs.config import EnvConfig
from gfb_env.envs.synchronous_plant import SuperposedResponse
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.synchronous import SynchronousSolver, synchronous_forcing


@pytest.fixture(scope="module")
def model():
    env = gym.make("gfb_env/RunUp-v2").unwrapped
    env.reset(seed=0)
    return env.model


def _fit_1x(tau: np.ndarray, theta: np.ndarray, x: np.ndarray) -> complex:
    A = np.column_stack([np.ones_like(tau), tau - tau.mean(), np.cos(theta), np.sin(theta)])
    c = np.linalg.lstsq(A, x, rcond=None)[0]
    return complex(c[2], -c[3])


@pytest.mark.parametrize("lam", [0.40, 0.55])
def test_analytic_1x_equals_the_steady_1x_of_a_long_stepped_run(model, lam):
    """A forced run from the equilibrium at the tight reference settles on the analytic X: amplitude
    within 0.2 % and phase within 0.2 deg (the trapezoidal rule's warping at 128 steps per revolution is
    ~0.06 %), for the largest drawn unbalance, with its phase."""
    dw, ub = 1.0, Unbalance(0.02, 1.3)
    s0 = find_equilibrium(model, lam)
    solver = SynchronousSolver(model)
    solver.start_mode(s0, lam, dw)
    x = solver.update(s0, lam, dw, synchronous_forcing(model, ub, lam))
    it = TrapezoidalIntegrator(
        model, s0, lam, dw, unbalance=ub, rtol=1e-5, atol=1e-5, steps_per_revolution=128
    )
    tr = it.advance(450.0, record_interval=0.5).trajectory
    keep = tr.tau >= 300.0
    theta = lam * tr.tau[keep]
    L = model.layout
    for z, xa in ((_fit_1x(tr.tau[keep], theta, tr.xi[keep]), x[L.xi_index]),
                  (_fit_1x(tr.tau[keep], theta, tr.eta[keep]), x[L.eta_index])):  # fmt: skip
        assert abs(abs(z) / abs(xa) - 1) < 2e-3
        assert abs(np.degrees(np.angle(z / xa))) < 0.2
    assert solver.mode.real < 0  # below Lambda_c: the tracked least damped mode decays


def test_tracked_mode_is_the_rightmost_eigenvalue(model):
    from gfb_env.analysis.stability import jacobian_eigenvalues

    lam = 0.6
    s0 = find_equilibrium(model, lam)
    solver = SynchronousSolver(model)
    mode = solver.start_mode(s0, lam, 1.0)
    ev = jacobian_eigenvalues(model, s0, lam, 1.0)[0]
    assert abs(mode.real - ev.real) < 1e-8 and abs(abs(mode.imag) - abs(ev.imag)) < 1e-8


def _held_env(mode: str, steps: int):
    env = gym.make("gfb_env/RunUp-v2", synchronous_response=mode, privileged_info=True)
    obs, _ = env.reset(seed=0)
    out = [obs]
    for _ in range(steps):
        out.append(env.step(np.zeros(2))[0])
    return env, np.array(out)


def test_superposed_plant_steps_unforced_and_agrees_with_the_stepped_one():
    ref, obs_ref = _held_env("stepped", 6)
    sup, obs_sup = _held_env("superposed", 6)
    s = sup.unwrapped._sync
    assert s is not None and s.superposed_steps >= 3  # the switch-on transient stepped, then superposed
    assert sup.unwrapped._integ.unbalance is None  # the integrator is unforced while superposed
    assert sup.unwrapped.episode.integrator_steps < 0.6 * ref.unwrapped.episode.integrator_steps
    # the same random draws, the same signal: the rotor entries within a third of the 0.3 um probe
    # noise (0.006 C_nom), the 1x amplitude entries likewise
    names = ref.unwrapped.observation_layout.names
    for name in ("xi", "eta", "x_1x_pp", "y_1x_pp", "x_direct_pp", "y_direct_pp"):
        i = names.index(name)
        assert np.abs(obs_sup[:, i] - obs_ref[:, i]).max() < 0.002, name
    assert sup.unwrapped.hidden_parameters()["unbalance"] == ref.unwrapped.hidden_parameters()["unbalance"]


def test_a_switch_keeps_the_true_state_and_the_signal_continuous():
    env, _ = _held_env("superposed", 4)
    u = env.unwrapped
    s = u._sync
    assert s.superposed
    before = u._plant_state()
    tau, theta = u._integ.tau, u._integ.rotation_angle
    s._switch(u._integ, to_superposed=False)  # what before_step does when validity is lost
    assert not s.superposed and u._integ.unbalance is s.unbalance
    np.testing.assert_allclose(u._plant_state(), before, rtol=0, atol=1e-14)
    assert u._integ.tau == tau and u._integ.rotation_angle == theta
    # the stepped continuation starts where the superposed record ended (no jump at the boundary)
    last = u.episode.orbit[0][-1]
    u._sync.deviation = 1.0  # keep it stepped for the next step
    env.step(np.zeros(2))
    assert not s.superposed
    first = u.episode.orbit[0][0]
    assert abs(first - last) < 0.01  # one sample interval (0.5 tau) of a 0.02 C orbit at Lambda 0.45
    # and back: subtracting the 1x gives the unforced state again
    before = u._plant_state()
    s._switch(u._integ, to_superposed=True)
    np.testing.assert_allclose(u._plant_state(), before, rtol=0, atol=1e-14)
    assert u._integ.unbalance is None


def test_validity_falls_back_to_stepping_in_the_whirl():
    env = gym.make("gfb_env/WhirlRecovery-v2", synchronous_response="superposed")
    env.reset(seed=0)
    u = env.unwrapped
    s = u._sync
    assert isinstance(s, SuperposedResponse)
    assert not s.superposed and u._integ.unbalance is s.unbalance  # the forcing is stepped
    env.step(np.zeros(2))
    assert not s.superposed and s.stepped_steps == 1
    assert s.deviation > 0.01  # the developed whirl, seen in the stepped motion less the 1x


def test_snapshot_continues_bit_for_bit_with_the_option_on():
    env, _ = _held_env("superposed", 3)
    u = env.unwrapped
    snap = u.get_state()
    a = [env.step(np.array([0.5, 0.0]))[0] for _ in range(2)]
    u.set_state(snap)
    b = [env.step(np.array([0.5, 0.0]))[0] for _ in range(2)]
    np.testing.assert_array_equal(np.array(a), np.array(b))


def test_native_vector_env_equals_single_envs_with_the_option_on():
    n, steps = 2, 5
    vec = gym.make_vec("gfb_env/RunUp-v2", num_envs=n, synchronous_response="superposed")
    ov, _ = vec.reset(seed=11)
    singles = [gym.make("gfb_env/RunUp-v2", synchronous_response="superposed") for _ in range(n)]
    os_ = [e.reset(seed=11 + i)[0] for i, e in enumerate(singles)]
    np.testing.assert_array_equal(ov, np.array(os_))
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1, 1, size=(n, 2))
        ov, rv, *_ = vec.step(a)
        outs = [e.step(a[i]) for i, e in enumerate(singles)]
        np.testing.assert_array_equal(ov, np.array([o[0] for o in outs]))
        np.testing.assert_array_equal(rv, np.array([o[1] for o in outs]))
    assert sum(e._sync.superposed_steps for e in vec.envs) >= 2  # the superposed plant was exercised
    vec.close()


@pytest.mark.parametrize("bad", ["analytic", "", 1, None])
def test_bad_option_value_is_refused_naming_it(bad):
    with pytest.raises(ValueError, match="synchronous_response"):
        gym.make("gfb_env/RunUp-v2", synchronous_response=bad)
    with pytest.raises(ValueError, match="synchronous_response"):
        EnvConfig(synchronous_response=bad)


def test_default_is_stepped_the_v2_ids_superpose_and_a_balanced_rotor_has_nothing_to_superpose():
    assert EnvConfig().synchronous_response == "stepped"  # the config's default: the plain plant
    for env_id in V2_ENV_IDS:  # the v2 ids register the fast plant (issue 20)
        assert gym.make(env_id).unwrapped.config.synchronous_response == "superposed"
    env = gym.make("gfb_env/RunUp-v2", synchronous_response="stepped")
    env.reset(seed=0)
    assert env.unwrapped._sync is None and env.unwrapped._integ.unbalance is not None
    bal = gym.make(
        "gfb_env/RunUp-v2", synchronous_response="superposed", rotor_balance={"grade_range_mm_s": (0, 0)}
    )
    bal.reset(seed=0)
    assert bal.unwrapped._sync is None
