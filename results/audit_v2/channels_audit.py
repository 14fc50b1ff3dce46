# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""Outside audit of the v2 contract, channels 2-5, on fresh seeds (7_000_800+): reward recompute over
long episodes with shocks and touchdowns; info values vs the FINAL hidden draws (shock schedule
included, exact and rtol 1e-9 / sign-flipped); sensor honesty (obs vs the privileged truth); the
vector env's infos; the public attributes a policy can reach through the wrappers."""

import math

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401
from gfb_env.envs.monitor_reward import recompute_rewards
from gfb_env.envs.privileged import flatten_numbers

IDS = ["gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2", "gfb_env/WhirlRecovery-v2"]


def draws(hid):
    return [(p, v) for p, v in flatten_numbers(hid) if math.isfinite(v) and not float(v).is_integer()]


def episode(env_id, seed, kind):
    env = gym.make(env_id, privileged_info=True)
    u = env.unwrapped
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    O, R, I = [obs], [], [info]
    while True:
        if kind == "hold":
            a = np.array([0.0, 0.3], np.float32)
        elif kind == "slow":
            a = np.array([0.25, 0.0], np.float32)
        else:
            a = rng.uniform(-1, 1, 2).astype(np.float32)
        obs, r, te, tr, info = env.step(a)
        O.append(obs)
        R.append(r)
        I.append(info)
        if te or tr:
            break
    hid = u.hidden_parameters()
    rr = recompute_rewards(O, I[-1], u.public_reward_config)
    return u, np.array(O), np.array(R), I, hid, float(np.max(np.abs(rr - np.array(R))))


def main():
    for env_id in IDS:
        print("==", env_id)
        res = {"xi": [], "spd": [], "dmp": [], "px": []}
        for i, kind in enumerate(["hold", "slow", "random", "hold", "slow", "random"]):
            seed = 7_000_800 + i
            u, O, R, I, hid, err = episode(env_id, seed, kind)
            nsh = len(hid["shocks"])
            peaks = [s.get("peak_g") for s in hid["shocks"]]
            hv = draws(hid)
            hits = set()
            for info in I:
                for key, val in info.items():
                    if key == "privileged":
                        continue
                    for path, v in flatten_numbers({key: val}):
                        if not math.isfinite(v) or v == 0 or float(v).is_integer():
                            continue
                        for hp, h in hv:
                            if abs(abs(v) - abs(h)) <= 1e-9 * abs(h):
                                hits.add((path, hp))
            print(
                f" seed {seed} {kind}: {len(R)} steps, end {I[-1]['termination_reason']}, shocks {nsh} "
                f"peaks {np.round(peaks, 2).tolist()}, touchdown {I[-1]['touchdown']}, recompute max|dr| {err:.1e}, "
                f"info~hidden(1e-9) {sorted(hits)}"
            )
            cn = u.nominal_bearing.clearance_m * 1e6
            for info, o in zip(I[1:], O[1:]):
                pv = info["privileged"]
                c_um = (
                    pv["hidden_parameters"]["bearing"]["clearance_um"]
                    if pv["hidden_parameters"]["bearing"]
                    else cn
                )
                res["xi"].append((o[0] - pv["xi"] * c_um / cn) * cn)  # um
                res["spd"].append(o[6] * u.speed_scale_rpm - info["speed_rpm"])
                res["dmp"].append(
                    u.damping_from_action(float(o[7]))
                    / (pv["foil_damping"] / pv["hidden_parameters"]["damping_gain"])
                    - 1
                )
                res["px"].append(info["probe_x_um"])
        xi = np.array(res["xi"])
        print(
            f" obs xi - true xi (um): sd {xi.std():.3f}, mean {xi.mean():.3f}; obs speed - info speed_rpm (rpm): max|.| "
            f"{np.max(np.abs(res['spd'])):.3g}; obs damping / true indicated - 1: max|.| {np.max(np.abs(res['dmp'])):.2e}"
        )


def vector():
    for env_id in IDS:
        venv = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point")
        obs, info = venv.reset(seed=7_000_900)
        keys0 = sorted(info)
        seen = set()
        rng = np.random.default_rng(0)
        done_any = 0
        for _ in range(120):
            obs, r, te, tr, info = venv.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
            seen |= set(info)
            if "final_info" in info:
                seen |= {"final_info." + k for k in info["final_info"]}
            done_any += int(np.any(te | tr))
        print(
            f"vector {env_id}: reset keys {keys0}\n   step keys {sorted(seen)}; steps with an end {done_any}"
        )
        venv.close()


def reachable():
    env = gym.make("gfb_env/RunUpRandomized-v2")
    env.reset(seed=7_000_950)
    for name in ("damping_gain", "bearing", "episode", "best_stable_operating_point", "hidden_parameters"):
        try:
            v = env.get_wrapper_attr(name)
            print(
                f"get_wrapper_attr({name!r}) -> {type(v).__name__}: {str(v() if callable(v) and name != 'episode' else v)[:140]}"
            )
        except Exception as exc:  # noqa: BLE001
            print(f"get_wrapper_attr({name!r}) -> {type(exc).__name__}: {exc}")
    print(
        "hidden gain",
        env.unwrapped.hidden_parameters()["damping_gain"],
        "clearance",
        env.unwrapped.hidden_parameters()["bearing"]["clearance_m"],
    )
    print("spec kwargs keys", sorted(env.spec.kwargs))


if __name__ == "__main__":
    main()
    vector()
    reachable()
