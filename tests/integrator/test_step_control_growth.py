"""The opt-in step limit at a settled operating point (issue 20 item 1, ``WhirlGrowthControl``).

On the 21x5 viscoelastic model with K_W = 1 (Lambda_c = 0.598 at D_W = 1, d sigma / d Lambda = 0.221):
at Lambda = 0.5 the least damped mode decays (the option must take far fewer steps), at Lambda = 0.62 it
grows at ~0.005 per tau (the option must grow it as the tight reference does, where a plain max_step = 30
does not)."""

import dataclasses

import numpy as np
import pytest

from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import IntegratorOptions, TrapezoidalIntegrator
from gfb_env.integrator.options import BENCHMARK_INTEGRATOR_OPTIONS, WhirlGrowthControl
from gfb_env.model import GFBModel

CALL = 60.0  # tau per call, the envs' control interval


@pytest.fixture(scope="module")
def model():
    return GFBModel("viscoelastic", grid="21x5", foil_stiffness=1.0)


def _perturbed(m, lam):
    s0 = find_equilibrium(m, lam)
    s = s0.copy()
    s[m.layout.rotor_offset + 2] += 1e-3  # a kick of the rotor velocity
    return s0, s


def _hold(m, s, lam, n_calls, **options):
    """Calls of CALL tau at a held Lambda: (steps per call, rotor deviation from s0 at each call end)."""
    it = TrapezoidalIntegrator(m, s, lam, 1.0, **options)
    steps, ends = [], []
    for k in range(n_calls):
        res = it.advance((k + 1) * CALL)
        steps.append(res.statistics.steps)
        ends.append(it.state[m.layout.rotor_offset : m.layout.rotor_offset + 2])
    return np.array(steps), np.array(ends), it


# ---------------------------------------------------------------------------------------------
def test_option_validation_names_the_field():
    with pytest.raises(ValueError, match="whirl_growth_control.decay_rate"):
        IntegratorOptions(whirl_growth_control={"decay_rate": -1.0})
    with pytest.raises(ValueError, match="whirl_growth_control.settled_max_step"):
        IntegratorOptions(whirl_growth_control={"settled_max_step": float("nan")})
    with pytest.raises(ValueError, match="whirl_growth_control has unknown key"):
        IntegratorOptions(whirl_growth_control={"max_step": 5.0})
    with pytest.raises(ValueError, match="settled_max_step must be >= max_step"):
        IntegratorOptions(max_step=4.0, whirl_growth_control={"settled_max_step": 3.0})
    with pytest.raises(ValueError, match="whirl_growth_control must be"):
        IntegratorOptions(whirl_growth_control=3.0)
    with pytest.raises(ValueError, match="integrator_options: whirl_growth_control.min_window"):
        IntegratorOptions.from_mapping({"whirl_growth_control": {"min_window": 0}})
    o = IntegratorOptions.from_mapping(BENCHMARK_INTEGRATOR_OPTIONS)
    assert o.whirl_growth_control == WhirlGrowthControl()
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.whirl_growth_control.decay_rate = 1.0


def test_off_by_default_and_the_machinery_leaves_the_loop_alone(model):
    """Default: no window, today's steps.  With settled_max_step == max_step the settled calls pass the
    same loop options, so the run is bitwise the default one (the option only ever changes max_step)."""
    assert IntegratorOptions().whirl_growth_control is None
    _, s = _perturbed(model, 0.5)
    st_d, end_d, it_d = _hold(model, s, 0.5, 8)
    assert it_d.snapshot().growth_window == ()
    st_o, end_o, it_o = _hold(model, s, 0.5, 8, whirl_growth_control={"settled_max_step": 2.0})
    assert it_o.snapshot().growth_window[-1]  # it did settle
    np.testing.assert_array_equal(st_o, st_d)
    assert np.array_equal(it_o.state, it_d.state)


def test_near_equilibrium_far_fewer_steps_and_same_state(model):
    s0, s = _perturbed(model, 0.5)
    st_d, end_d, _ = _hold(model, s, 0.5, 12)
    st_o, end_o, it = _hold(model, s, 0.5, 12, **BENCHMARK_INTEGRATOR_OPTIONS)
    assert st_d[-6:].sum() >= 6 * 25  # pinned by max_step = 2
    assert st_o[-6:].sum() <= st_d[-6:].sum() / 4  # settled: the cap is lifted (measured 12 vs 180)
    assert np.abs(end_o - end_d).max() < 1e-4  # 1/60 of the probes' noise (0.006 C)
    # snapshot / restore carries the window: the continuation is the original one, bit for bit
    snap = it.snapshot()
    a = it.advance(13 * CALL)
    it.restore(snap)
    b = it.advance(13 * CALL)
    assert a.statistics == b.statistics and np.array_equal(a.trajectory.xi, b.trajectory.xi)


def test_a_growing_whirl_grows_as_in_the_tight_reference(model):
    """Lambda = 0.62 > Lambda_c: the kick's fast modes ring down, the Hopf mode grows.  The rotor's
    deviation after 20 calls (1200 tau) matches rtol = atol = 1e-5 within 5 %; a plain max_step = 30
    freezes the growth (the trapezoidal rule's growth rate sigma / (1 + (h omega)^2 / 4)) and fails."""
    lam, n = 0.62, 20
    s0, s = _perturbed(model, lam)
    r0 = model.layout.rotor_offset

    def amplitude(ends):
        return np.abs(ends[-3:] - s0[r0 : r0 + 2]).max()

    _, ref, _ = _hold(model, s, lam, n, rtol=1e-5, atol=1e-5)
    _, opt, _ = _hold(model, s, lam, n, **BENCHMARK_INTEGRATOR_OPTIONS)
    _, raised, _ = _hold(model, s, lam, n, max_step=30.0)
    a_ref, a_opt, a_raised = amplitude(ref), amplitude(opt), amplitude(raised)
    assert a_ref > 3 * amplitude(ref[:3])  # it does grow
    assert abs(a_opt / a_ref - 1) < 0.05
    assert abs(a_raised / a_ref - 1) > 0.05  # the test can fail: raising the cap alone does


def test_the_env_option_settles_alike_in_the_single_and_the_native_vector_env():
    """gym.make(..., integrator_options=BENCHMARK_INTEGRATOR_OPTIONS) on an unforced (balanced) RunUp-v2
    held at its start: the vector env's batch call and the single env give the same observations bit
    for bit, and both settle (30 integrator steps per control step with the defaults)."""
    import gymnasium as gym

    import gfb_env.envs  # noqa: F401  (registers the ids)

    kw = {"integrator_options": BENCHMARK_INTEGRATOR_OPTIONS, "rotor_balance": {"grade_range_mm_s": [0, 0]}}
    vec = gym.make_vec("gfb_env/RunUp-v2", num_envs=2, **kw)
    singles = [gym.make("gfb_env/RunUp-v2", **kw) for _ in range(2)]
    obs_v, _ = vec.reset(seed=[5, 6])
    for e, s in zip(singles, (5, 6), strict=True):
        e.reset(seed=s)
    hold = np.zeros((2, 2), dtype=np.float32)  # speed held, D_W command 1 (the action's log-scale centre)
    for _ in range(25):
        obs_v, *_ = vec.step(hold)
        for i, e in enumerate(singles):
            assert np.array_equal(obs_v[i], e.step(hold[i])[0])
    for e in singles:
        integ = e.unwrapped._integ  # noqa: SLF001 - the plant's work counter
        assert integ.statistics.steps < 25 * 20  # 30 per control step without the option
    vec.close()
