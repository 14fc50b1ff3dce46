"""The information contract (issue 19 s.1) of the retired v1 ids, as a record (built by ``make_retired``): the
privileged channel (``hidden_parameters()``, ``privileged_info``) and the classification of every v1 info key
(:mod:`gfb_env.envs.contract`): what leaked.  The v2 ids' contract: tests/envs/test_v2_contract.py."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from conftest import record_short_episode

from gfb_env.envs import ENV_IDS, RETIRED_V1_IDS, make_retired
from gfb_env.envs.contract import (
    INFO_CONTRACT,
    InfoClass,
    classify,
    hidden_value_matches,
    leaked_ground_truth,
    unclassified_keys,
)

#: short whole episodes (the horizon and its certificate reached; hold_steps 10 <= 12)
SHORT = {"episode_steps": 12}
RU, RUR, WR = "gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"


def _episode(env_id: str, seed: int, policy=None, **kw):
    return record_short_episode(env_id, seed, policy, **kw)


@pytest.fixture(scope="module")
def episodes():
    return {env_id: _episode(env_id, 5) for env_id in RETIRED_V1_IDS}


def test_every_registered_id_has_a_contract():
    # the current ids, and the retired v1 ids for the record (v2: tests/envs/test_v2_contract.py)
    assert set(INFO_CONTRACT) == set(RETIRED_V1_IDS) | set(ENV_IDS)
    with pytest.raises(ValueError, match="env_id"):
        classify("gfb_env/Nope-v9", "step")


@pytest.mark.parametrize("env_id", RETIRED_V1_IDS)
def test_every_info_key_is_classified_at_reset_and_over_a_whole_episode(env_id, episodes):
    infos = episodes[env_id][0]
    assert infos[-1]["termination_reason"] is not None  # the whole episode (horizon or earlier end)
    for info in infos:
        assert unclassified_keys(env_id, info) == []
    # and every classified key occurs (the contract lists no key the task lacks)
    seen = set().union(*infos) | {"privileged"}
    assert set(INFO_CONTRACT[env_id]) == seen


def test_a_new_key_fails_until_classified():
    assert unclassified_keys(RU, {"step": 0, "new_key": 1.0}) == ["new_key"]
    with pytest.raises(KeyError):
        classify(RU, "new_key")


def test_the_v1_ids_leak_ground_truth():
    """The v1 info hands out g, the drawn bearing and the true state (the audit of issue 19)."""
    for env_id in RETIRED_V1_IDS:
        leaks = set(leaked_ground_truth(env_id))
        assert {"damping_gain", "foil_damping", "xi_um", "whirl_amplitude", "reward_whirl"} <= leaks
        assert "probe_x_um" not in leaks and "speed_rpm" not in leaks
    assert {"clearance_um", "stiffness_factor", "load_n", "bearing_number", "time_s"} <= set(
        leaked_ground_truth(RUR)
    )
    assert classify(RU, "bearing_number") is InfoClass.SENSOR  # the nominal bearing: the speed, scaled


@pytest.mark.parametrize("env_id", RETIRED_V1_IDS)
def test_no_sensor_or_public_value_equals_a_hidden_parameter(env_id, episodes):
    """Exact float equality of every SENSOR/PUBLIC info value against every hidden draw: none on v1
    (so the classification is consistent); the GROUND_TRUTH keys that do equal one are the leaks."""
    infos, hidden = episodes[env_id][:2]
    leaking: set[str] = set()
    for info, hp in zip(infos, hidden, strict=True):
        matches = hidden_value_matches(info, hp)
        bad = [k for k in matches if classify(env_id, k) in (InfoClass.SENSOR, InfoClass.PUBLIC)]
        assert bad == [], {k: matches[k] for k in bad}
        leaking |= set(matches)
    expected = {"damping_gain", "unbalance_um", "balance_grade_mm_s"}
    if env_id == RUR:
        expected |= {"clearance_um", "stiffness_factor", "load_n", "foil_stiffness"}
    assert expected <= leaking
    assert leaking <= set(leaked_ground_truth(env_id))


@pytest.mark.parametrize("env_id", RETIRED_V1_IDS)
def test_hidden_parameters_hold_a_value_per_hidden_draw(env_id, episodes):
    infos, hidden = episodes[env_id][:2]
    hp = hidden[0]
    assert json.loads(json.dumps(hp)) == hp  # JSON-serialisable as is
    info = infos[0]
    assert hp["damping_gain"] == info["damping_gain"] and 0.3 < hp["damping_gain"] < 3.2
    u = hp["unbalance"]
    assert u["balance_grade_mm_s"] == info["balance_grade_mm_s"] and u["magnitude_um"] == info["unbalance_um"]
    assert 0 <= u["phase_rad"] < 2 * np.pi and u["magnitude_c"] > 0
    s = hp["sensors"]
    assert len(s["probe_bias_um"]) == 2 and len(s["tap_bias_kpa"]) == 8
    for k in ("probe_noise_um", "probe_position_error_um", "probe_velocity_error_um_per_s", "tap_error_kpa"):
        assert s[k] is not None and all(np.isfinite(s[k])), k
    assert s["observation_noise"] is None  # observation_noise = 0 on v1
    assert hidden[1]["sensors"]["probe_noise_um"] != s["probe_noise_um"]  # the last observation's
    if env_id == RUR:
        b = hp["bearing"]
        assert b["clearance_um"] == info["clearance_um"] and b["stiffness_factor"] == info["stiffness_factor"]
        assert b["load_n"] == info["load_n"] and b["foil_stiffness"] == info["foil_stiffness"]
        assert b["clearance_m"] * 1e6 == b["clearance_um"]
    else:
        assert hp["bearing"] is None
    if env_id == WR:
        assert set(hp["task"]) == {"start_phase_tau"} and 0 <= hp["task"]["start_phase_tau"] < 26
    else:
        assert set(hp["task"]) == {"start_velocity_c_per_t", "start_velocity_angle_rad"}
        assert 0 <= hp["task"]["start_velocity_c_per_t"] <= 1e-3


def test_hidden_parameters_same_seed_same_dict_other_seed_other():
    """On the current (v2) ids: the privileged channel is the task's, not the interface's."""

    def first(env_id, seed):
        env = gym.make(env_id)
        env.reset(seed=seed)
        return env.unwrapped.hidden_parameters()

    for env_id in ENV_IDS:
        a, b, c = first(env_id, 11), first(env_id, 11), first(env_id, 12)
        assert a == b
        assert a["damping_gain"] != c["damping_gain"] and a["unbalance"] != c["unbalance"]
        assert a["sensors"]["probe_bias_um"] != c["sensors"]["probe_bias_um"] and a["task"] != c["task"]
    assert first(ENV_IDS[1], 11)["bearing"] != first(ENV_IDS[1], 12)["bearing"]


def test_the_shock_schedule_holds_every_shock_drawn_so_far():
    """A high shock rate: each step's shocks (info["shocks"], info["shock_peak_g"]) end the schedule,
    which only grows; a snapshot restores it."""
    env = make_retired(RU, shock_arrivals={"rate_per_s": 300.0, "peak_g_range": (0.5, 1.0)})
    u = env.unwrapped
    env.reset(seed=3)
    assert u.hidden_parameters()["shocks"] == []
    n = 0
    for k in range(4):
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
        shocks = u.hidden_parameters()["shocks"]
        assert len(shocks) == n + info["shocks"]
        if info["shocks"]:
            assert max(e["peak_g"] for e in shocks[n:]) == info["shock_peak_g"]
        assert all(shocks[i]["time_s"] <= shocks[i + 1]["time_s"] for i in range(len(shocks) - 1))
        n = len(shocks)
        if k == 1:
            snap, at_snap = u.get_state(), u.hidden_parameters()
    assert n > 2
    u.set_state(snap)
    assert u.hidden_parameters() == at_snap


@pytest.mark.parametrize("bad", [1, 0, "yes", None, 1.0])
def test_privileged_info_must_be_a_bool(bad):
    with pytest.raises(ValueError, match="privileged_info"):
        gym.make(ENV_IDS[0], privileged_info=bad)


@pytest.mark.parametrize("env_id", RETIRED_V1_IDS)
def test_privileged_info_adds_the_true_quantities_and_changes_nothing_else(env_id, episodes):
    off_infos, off_hidden, off_obs, off_rewards = episodes[env_id]
    on_infos, _, on_obs, on_rewards = _episode(env_id, 5, privileged_info=True)
    assert on_rewards == off_rewards and all(
        np.array_equal(a, b) for a, b in zip(on_obs, off_obs, strict=True)
    )
    assert all("privileged" not in i for i in off_infos)
    for on, off, hp in zip(on_infos, off_infos, off_hidden, strict=True):
        priv = on["privileged"]
        rest = {k: v for k, v in on.items() if k != "privileged"}
        assert list(rest) == list(off)
        for k, v in off.items():
            assert np.array_equal(np.asarray(rest[k], dtype=object), np.asarray(v, dtype=object)), k
        assert priv["hidden_parameters"] == hp
        # the v1 info's own ground truth, under the same names
        for k in ("xi_um", "eta_um", "xi_dot_m_s", "eccentricity", "whirl_amplitude", "min_film_thickness"):
            assert priv[k] == off[k], k
        assert priv["foil_damping"] == off["foil_damping"] and priv["bearing_number"] == off["bearing_number"]
        assert priv["bearing_force_n"] == off["bearing_force_n"]
        assert classify(env_id, "privileged") is InfoClass.PRIVILEGED


def test_privileged_info_in_the_native_vector_env():
    venv = gym.make_vec(ENV_IDS[0], num_envs=2, privileged_info=True, **SHORT)
    _, infos = venv.reset(seed=7)
    gains = infos["privileged"]["hidden_parameters"]["damping_gain"]
    assert [float(g) for g in gains] == [e.hidden_parameters()["damping_gain"] for e in venv.unwrapped.envs]
    _, _, _, _, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
    amps = infos["privileged"]["whirl_amplitude"]
    assert [float(x) for x in amps] == [
        e.privileged_quantities()["whirl_amplitude"] for e in venv.unwrapped.envs
    ]
    venv.close()


def test_an_ideal_machine_has_no_sensor_or_unbalance_draws_and_the_legacy_noise_is_recorded():
    from gfb_env.envs import RunUpEnv

    env = RunUpEnv(episode_steps=12)
    env.reset(seed=2)
    hp = env.hidden_parameters()
    assert hp["damping_gain"] == 1.0 and hp["unbalance"] is None and hp["bearing"] is None
    s = hp["sensors"]
    assert s["probe_bias_um"] == [0.0, 0.0] and s["tap_bias_kpa"] == [0.0] * 8
    assert s["probe_noise_um"] is None and s["tap_error_kpa"] is None and s["observation_noise"] is None
    noisy = RunUpEnv(episode_steps=12, observation_noise=0.01)
    obs, _ = noisy.reset(seed=2)
    clean, _ = env.reset(seed=2)
    drawn = noisy.hidden_parameters()["sensors"]["observation_noise"]
    measured = noisy.observation_layout.measured_indices
    assert len(drawn) == len(measured)
    # the envelope entries (4, 5) start at 0 and are clipped at 0: compare the others
    keep = [i for i, m in enumerate(measured) if m not in (4, 5)]
    assert np.allclose((obs[measured] - clean[measured])[keep], np.asarray(drawn)[keep], atol=1e-6)
