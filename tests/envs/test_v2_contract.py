"""The v2 ids (issue 19 s.1, 2, 4): the information contract (no ground truth in info), the vibration
monitor's observation, the reward recomputed from the observations, the costs from the measurements,
the certificate that forgives a shock's ring-down, and the v1 entries unchanged."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import record_short_episode, same_value

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.envs import (
    _V1_SPECS,
    ENV_IDS,
    FAST_PLANT_V2,
    PLAIN_PLANT,
    RETIRED_V1_IDS,
    V2_ENV_IDS,
    make_retired,
)
from gfb_env.envs.certify import StabilityCertificate
from gfb_env.envs.certify_v2 import AfterShockCertificate
from gfb_env.envs.contract import InfoClass, classify, hidden_value_matches, unclassified_keys
from gfb_env.envs.interface_v2 import MONITOR_ENTRIES, SAMPLES_PER_STEP, MonitorInterface
from gfb_env.envs.monitor_reward import recompute_rewards
from gfb_env.equilibrium import find_equilibrium
from gfb_env.machine import ShockEvent

SHORT = {"episode_steps": 12}
RU2, RUR2, WR2 = V2_ENV_IDS
VERDICT_KEYS = {"certified", "is_success", "termination_reason"}


def _episode(env_id: str, seed: int, policy=None, **kw):
    return record_short_episode(env_id, seed, policy, **kw)


@pytest.fixture(scope="module")
def episodes():
    return {env_id: _episode(env_id, 5) for env_id in V2_ENV_IDS}


def test_the_v2_ids_are_registered_with_the_v1_tasks():
    assert ENV_IDS == V2_ENV_IDS  # the current tasks
    for v1, v2 in zip(RETIRED_V1_IDS, V2_ENV_IDS, strict=True):
        s1, s2 = make_retired(v1).spec, gym.spec(v2)
        assert v1 in _V1_SPECS
        assert v2 == v1.replace("-v1", "-v2") and s1.entry_point == s2.entry_point
        assert s1.max_episode_steps == s2.max_episode_steps
        assert s1.vector_entry_point == s2.vector_entry_point
        # v1's task and machine; v2 adds its interface and the fast plant (issue 20)
        assert {
            k: v for k, v in s2.kwargs.items() if k != "interface" and k not in FAST_PLANT_V2
        } == s1.kwargs
        assert {k: s2.kwargs[k] for k in FAST_PLANT_V2} == FAST_PLANT_V2
        assert "interface" not in s1.kwargs and make_retired(v1).unwrapped.interface is None


@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_every_info_key_is_sensor_public_or_final_verdict(env_id, episodes):
    infos, hidden = episodes[env_id][:2]
    assert infos[-1]["termination_reason"] in ("success", "horizon", "touchdown", "solver_failure")
    for k, (info, hp) in enumerate(zip(infos, hidden, strict=True)):
        assert unclassified_keys(env_id, info) == []
        classes = {key: classify(env_id, key) for key in info}
        assert InfoClass.GROUND_TRUTH not in classes.values()
        verdict = {key for key, c in classes.items() if c is InfoClass.VERDICT}
        assert verdict == (VERDICT_KEYS if k == len(infos) - 1 else set()), k
        assert hidden_value_matches(info, hp) == {}  # no info value equals a hidden draw
    # the v1 leaks are gone
    seen = set().union(*infos)
    assert not seen & {"damping_gain", "foil_damping", "xi_um", "whirl_amplitude", "shocks", "time_s"}
    assert not seen & {"integrator_steps", "clearance_um", "bearing_number", "min_film_thickness"}


@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_the_observation_is_v1s_then_the_monitor_then_the_task_entries(env_id, episodes):
    v1 = make_retired(env_id.replace("-v2", "-v1")).unwrapped.observation_layout
    v2 = gym.make(env_id).unwrapped.observation_layout
    assert v2.names[:16] == v1.names[:16]
    assert v2.names[16:28] == MONITOR_ENTRIES and v2.names[28:] == v1.names[16:]
    assert v2.names[-2:] == ("speed_command", "time_left")
    obs = episodes[env_id][2]
    assert np.all(obs[0][16:28] == 0)  # no record at reset: every monitor entry 0, valid 0
    if env_id == RUR2:  # the drawn bearing's extras sit between the monitor and the command
        names = gym.make(env_id, observe_parameters=True).unwrapped.observation_layout.names
        assert names[16:28] == MONITOR_ENTRIES and len(names) == 33 and names[-2:] == v2.names[-2:]


@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_v1s_entries_are_v1s_values(env_id):
    """The same seed and actions on v1 and v2: v2 draws the samples' noise once as v1 does, so every
    v1 entry (and the command and time entries) is v1's value bit for bit; rules written for v1 read
    v2 unchanged."""
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1, 1, (6, 2)).astype(np.float32)
    out = {}
    for v, make in (("-v1", make_retired), ("-v2", gym.make)):
        # on a drawn bearing v2's step is fixed in seconds (test_v2_control_clock.py): compare on v1's clock
        kw = {"interface": MonitorInterface(control_clock="plant")} if (v, env_id) == ("-v2", RUR2) else {}
        if v == "-v2":
            kw.update(PLAIN_PLANT)  # v1's plant (the v2 ids' fast plant changes the last bits)
        env = make(env_id.replace("-v2", v), **kw)
        o, _ = env.reset(seed=4)
        obs = [o] + [env.step(a)[0] for a in actions]
        out[v] = np.array(obs)
    a, b = out["-v1"], out["-v2"]
    assert np.array_equal(a[:, :16], b[:, :16]) and np.array_equal(a[:, 16:], b[:, 28:])


@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_the_monitor_entries_come_from_the_probe_samples(env_id):
    env = gym.make(env_id, raw_probe_samples=True)
    u = env.unwrapped
    _, info = env.reset(seed=1)
    assert np.all(np.isnan(info["probe_samples"]["x_um"]))  # no record at reset
    for _ in range(3):
        obs, _, _, _, info = env.step(u.scripted_action())
    s = info["probe_samples"]
    assert all(len(v) == SAMPLES_PER_STEP and np.all(np.isfinite(v)) for v in s.values())
    c_nom_um = u.nominal_bearing.clearance_m * 1e6
    lay = u.observation_layout
    m = info["monitor"]
    assert m["x_direct_um_pp"] == np.ptp(s["x_um"]) and m["y_direct_um_pp"] == np.ptp(s["y_um"])
    assert obs[lay.index("x_direct_pp")] == np.float32(np.ptp(s["x_um"]) / c_nom_um)
    assert np.all(np.diff(s["time_s"]) > 0) and np.all(np.diff(s["keyphasor_angle_rad"]) > 0)
    if m["valid"]:
        assert obs[lay.index("monitor_valid")] == 1
        lag = math.radians(m["x_synchronous_phase_lag_deg"])
        assert obs[lay.index("x_1x_cos")] == np.float32(math.cos(lag))
    # the same readings as the info's last sample (interpolated at the step's end: ulps off where the
    # record grid is not binary-exact, a drawn bearing's 60 T_nom / T tau per step)
    assert s["x_um"][-1] == pytest.approx(info["probe_x_um"], rel=0, abs=1e-9)
    assert s["y_um"][-1] == pytest.approx(info["probe_y_um"], rel=0, abs=1e-9)
    # off by default
    env2 = gym.make(env_id)
    env2.reset(seed=1)
    assert "probe_samples" not in env2.step(env2.unwrapped.scripted_action())[-1]


def test_raw_probe_samples_needs_v2_and_a_bool():
    with pytest.raises(ValueError, match="raw_probe_samples"):
        make_retired(RETIRED_V1_IDS[0], raw_probe_samples=True)
    with pytest.raises(ValueError, match="raw_probe_samples"):
        gym.make(RU2, raw_probe_samples=1)


@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_privileged_info_adds_the_truth_and_changes_nothing_else(env_id, episodes):
    off_infos, off_hidden, off_obs, off_rewards = episodes[env_id]
    on_infos, _, on_obs, on_rewards = _episode(env_id, 5, privileged_info=True)
    assert on_rewards == off_rewards
    assert all(np.array_equal(a, b) for a, b in zip(on_obs, off_obs, strict=True))
    for on, off, hp in zip(on_infos, off_infos, off_hidden, strict=True):
        priv = on.pop("privileged")
        assert on.keys() == off.keys() and all(same_value(on[k], off[k]) for k in off)
        assert priv["hidden_parameters"] == hp
        assert {"whirl_amplitude", "min_film_thickness", "certified", "true_reward_terms"} <= set(priv)
    final = on_infos[-1]
    assert final["certified"] == priv["certified"]


# ---- reward and costs ------------------------------------------------------------------------
def _touchdown_policy(u):
    """Full speed with the least damping: whirls into a touchdown on WhirlRecovery."""
    return np.array([1.0, -1.0], dtype=np.float32)


@pytest.mark.parametrize(
    "env_id, policy",
    [(RU2, None), (RUR2, None), (WR2, None), (WR2, _touchdown_policy)],
    ids=["RunUp", "RunUpRandomized", "WhirlRecovery", "WhirlRecovery-touchdown"],
)
def test_the_reward_recomputes_bit_for_bit_from_the_observations(env_id, policy, episodes):
    infos, _, obs, rewards = episodes[env_id] if policy is None else _episode(env_id, 0, policy)
    u = gym.make(env_id, **SHORT).unwrapped
    got = recompute_rewards(np.array(obs), infos[-1], u.public_reward_config)
    assert got.tolist() == rewards  # exact
    for info, r in zip(infos[1:], rewards, strict=True):
        terms = [info[f"reward_{k}"] for k in ("speed", "whirl", "certified_speed", "on_target", "touchdown")]
        assert float(sum(terms)) == r
    if policy is not None:
        assert infos[-1]["termination_reason"] == "touchdown" and infos[-1]["touchdown"]
        assert infos[-1]["reward_touchdown"] == -100.0 and infos[-1]["cost_touchdown"] == 1.0
    # the verdict matters: without it the terminal terms are gone
    assert recompute_rewards(np.array(obs), None, u.public_reward_config)[-1] != rewards[-1] or (
        not infos[-1]["certified"] and infos[-1]["termination_reason"] == "horizon"
    )


def test_the_reward_recomputes_on_the_native_vector_env():
    envs = gym.make_vec(RU2, num_envs=2, vectorization_mode="vector_entry_point", **SHORT)
    config = envs.envs[0].public_reward_config
    obs, _ = envs.reset(seed=8)
    history, rewards = [[o] for o in obs], [[], []]
    finals: list = [None, None]
    rng = np.random.default_rng(0)
    for _ in range(12):
        obs, r, term, trunc, info = envs.step(rng.uniform(-0.3, 1, (2, 2)).astype(np.float32))
        for i in range(2):
            history[i].append(obs[i])
            rewards[i].append(float(r[i]))
            if term[i]:
                finals[i] = {k: info[k][i] for k in VERDICT_KEYS}
    assert all(f is not None for f in finals)
    for i in range(2):
        assert recompute_rewards(np.array(history[i]), finals[i], config).tolist() == rewards[i]
    envs.close()


def test_the_alarm_costs_a_developed_whirl_and_the_constraint_is_v1s():
    infos = _episode(WR2, 2)[0]
    assert infos[1]["monitor_alarm"] and infos[1]["cost_alarm"] == 1.0 and infos[1]["cost"] == 1.0
    assert infos[1]["monitor"]["x_direct_um_pp"] > 15.0 or infos[1]["monitor"]["y_direct_um_pp"] > 15.0
    assert infos[-1]["episode_cost"] == sum(i["cost"] for i in infos[1:])
    cfg = gym.make(WR2).unwrapped.public_reward_config
    assert cfg.costs.alarm_direct_pp == 0.30 and cfg.costs.episode_cost_limit == 15.0
    assert gym.make(RU2).unwrapped.public_reward_config.costs.episode_cost_limit == 5.0
    calm = _episode(RU2, 2)[0]
    assert all(i["cost"] == 0.0 for i in calm)


def test_the_reward_reads_the_measurement_not_the_truth():
    """The whirl term is -0.5 A_meas of the monitor (sqrt 2 x the larger band rms), not the true A."""
    infos = _episode(WR2, 3, privileged_info=True)[0]
    i = infos[2]
    a_meas = math.sqrt(2) * max(
        i["monitor"]["x_subsynchronous_um_rms"], i["monitor"]["y_subsynchronous_um_rms"]
    )
    assert i["monitor"]["valid"]
    assert abs(-0.5 * a_meas / 50.0 - i["reward_whirl"]) < 1e-6  # float32 observation
    assert i["reward_whirl"] != i["privileged"]["true_reward_terms"]["whirl"]


# ---- the certificate -------------------------------------------------------------------------
STEP_S, STEP_TAU, T_END = 0.01, 60.0, 1.1  # the window: 10 steps of 0.01 s ending at 1.1 s
SHOCK = ShockEvent(time_s=1.0 + 3.2 * STEP_S, peak_g=6.0, duration_ms=5.0, direction_deg=0.0)  # step 3


@pytest.fixture(scope="module")
def stable_point():
    env = gym.make(RU2)
    env.reset(seed=0)
    model = env.unwrapped.episode.model
    lam, dw = 0.62, 2.24  # well below Lambda_c(2.24) = 0.70: linearly stable
    s = find_equilibrium(model, lam)
    g = StabilityCertificate(0.05, 10).judge([0.0] * 10, model, lam, dw, s).growth_rate
    assert g < 0
    return model, lam, dw, s, g


def _v2(window, shocks, point, lam=None):
    model, lam0, dw, s, _ = point
    lam = lam0 if lam is None else lam
    s = s if lam == lam0 else find_equilibrium(model, lam)
    return AfterShockCertificate(0.05, 10).judge(window, shocks, T_END, STEP_S, STEP_TAU, model, lam, dw, s)


def _ring_down(g: float) -> list[float]:
    """Calm, a shock in step 3, then the free decay at the plant's rate from step 4 (its pulse has ended)."""
    return [0.01, 0.01, 0.01, 0.30, *(0.2 * math.exp(g * STEP_TAU * k) for k in range(6))]


def test_a_shock_in_the_window_at_a_stable_point_fails_v1_and_passes_v2(stable_point):
    model, lam, dw, s, g = stable_point
    ring_down = _ring_down(g)
    v1 = StabilityCertificate(0.05, 10).judge(ring_down, model, lam, dw, s)
    assert (v1.certified, v1.reason) == (False, "whirl_in_window")
    assert (
        _v2(ring_down, (SHOCK,), stable_point).certified,
        _v2(ring_down, (SHOCK,), stable_point).reason,
    ) == (
        True,
        "stable",
    )
    # without the shock v2 is v1
    assert _v2(ring_down, (), stable_point).reason == "whirl_in_window"
    # a whirl before the shock is not forgiven
    assert _v2([0.01, 0.08, *ring_down[2:]], (SHOCK,), stable_point).reason == "whirl_in_window"
    # a shock long before the window is not in it
    old = ShockEvent(time_s=0.5, peak_g=6.0, duration_ms=5.0, direction_deg=0.0)
    assert not _v2(ring_down, (old,), stable_point).certified
    # a shock in the last step: nothing to compare, the plant's stability decides
    late = ShockEvent(time_s=T_END - 0.3 * STEP_S, peak_g=6.0, duration_ms=5.0, direction_deg=0.0)
    assert _v2([0.01] * 9 + [0.3], (late,), stable_point).certified


def test_a_growing_or_steady_whirl_after_a_shock_fails_both(stable_point):
    model, lam, dw, s, _ = stable_point
    growing = [0.01, 0.01, 0.01, 0.30, 0.10, 0.11, 0.12, 0.13, 0.14, 0.15]
    assert not StabilityCertificate(0.05, 10).judge(growing, model, lam, dw, s).certified
    assert _v2(growing, (SHOCK,), stable_point).reason == "whirl_growing_after_shock"
    # kicked onto a whirl cycle beside the stable equilibrium (a hysteresis band): not growing, not
    # decaying as the plant's slowest mode does
    steady = [0.01, 0.01, 0.01, 0.30, 0.30, 0.29, 0.31, 0.30, 0.30, 0.30]
    assert not StabilityCertificate(0.05, 10).judge(steady, model, lam, dw, s).certified
    assert _v2(steady, (SHOCK,), stable_point).reason == "whirl_not_decaying_after_shock"


def test_a_ring_down_on_an_unstable_plant_fails_v2(stable_point):
    _, _, _, _, g = stable_point
    # 0.74 lies above lambda_best: no damping makes it stable
    v2 = _v2(_ring_down(g), (SHOCK,), stable_point, lam=0.74)
    assert (v2.certified, v2.reason) == (False, "unstable_equilibrium")


# ---- determinism, snapshots, random actions ----------------------------------------------------
@pytest.mark.parametrize("env_id", V2_ENV_IDS)
def test_same_seed_same_episode_and_snapshots_restore_exactly(env_id):
    kw = {"shock_arrivals": {"rate_per_s": 20.0, "peak_g_range": (1.0, 5.0)}, "raw_probe_samples": True}
    rng = np.random.default_rng(5)
    # slowing down near the nominal optimum damping: no episode ends (WhirlRecovery starts whirling)
    actions = np.c_[rng.uniform(-1, 0, 5), rng.uniform(0.2, 0.5, 5)].astype(np.float32)

    def run(env, acts):
        out = []
        for act in acts:
            out.append(env.step(act))
            if out[-1][2]:
                break
        return out

    a, b = gym.make(env_id, **kw), gym.make(env_id, **kw)
    a.reset(seed=9)
    b.reset(seed=9)
    ra, rb = run(a, actions[:2]), run(b, actions[:2])
    u = a.unwrapped
    snap = u.get_state()
    first = run(a, actions[:3])
    a.reset(seed=1)
    a.step(actions[0])
    u.set_state(snap)
    second = run(a, actions[:3])
    assert len(first) == 3  # the snapshot is taken in a running episode
    for x, y in [*zip(ra, rb, strict=True), *zip(first, second, strict=True)]:
        assert np.array_equal(x[0], y[0]) and x[1:4] == y[1:4]
        assert x[4].keys() == y[4].keys() and all(same_value(x[4][k], y[4][k]) for k in x[4])


def test_v2_info_speed_and_damping_are_the_observations_float32_values():
    """Outside audit (2026-12-02): ``damping_indicated`` computed as D_actual / g in float64 carried the
    rounding of the hidden gain (a replay of the public actuator matched every step for the true g only),
    and the float64 speed the drawn clearance's. v2's info reports both as the observation carries them."""
    env = gym.make("gfb_env/RunUp-v2")
    u = env.unwrapped
    obs, info = env.reset(seed=7_000_321)
    differs = 0
    for k in range(8):
        obs, _, _, _, info = env.step(np.array([0.0, (-1.0) ** k * 0.37], dtype=np.float32))
        lay = u.observation_layout
        assert info["damping_indicated"] == u.actions.damping_from_action(float(obs[lay.damping]))
        assert info["speed_rpm"] == float(obs[lay.speed]) * u.speed_scale_rpm
        # the plant's float64 quotient is not what info reports (it would fail with the old code)
        differs += info["damping_indicated"] != u._integ.foil_damping / u._ep.actuator.gain  # noqa: SLF001
    assert differs > 0
    env.close()
