# ruff: noqa  (audit scripts: one-off measurements, not package code)
"""Does the damping indication (obs entry 7, info['damping_indicated']) tell a hidden draw?
(a) RunUpRandomized-v2: the actuator's lag runs for b.seconds(control_interval) of the DRAWN bearing,
    so the indicated D_W after a damping step tells the step's duration, i.e. the clearance.
(b) RunUp-v2: info['damping_indicated'] = (actual D_W computed with g) / g in float64: round-off pattern vs g."""

import math

import gymnasium as gym
import numpy as np

import gfb_env  # noqa: F401
from gfb_env.machine.actuator import FoilDampingActuator  # noqa: F401


def invert_dt(act, d0, cmd, d1, lo=1e-5, hi=1.0):
    st = act.start(d0, 1.0)
    f = lambda dt: math.log(act.step(st, cmd, dt).foil_damping) - math.log(d1)  # noqa: E731
    flo, fhi = f(lo), f(hi)
    if flo * fhi > 0:
        return float("nan")
    for _ in range(80):
        mid = math.sqrt(lo * hi)
        fm = f(mid)
        if fm * flo > 0:
            lo, flo = mid, fm
        else:
            hi = mid
    return math.sqrt(lo * hi)


def part_a(seeds):
    env = gym.make("gfb_env/RunUpRandomized-v2")
    u = env.unwrapped
    rows = []
    for s in seeds:
        obs0, info0 = env.reset(seed=s)
        C = u.hidden_parameters()["bearing"]["clearance_m"]
        a = np.array([0.0, 1.0], np.float32)
        obs1, *_, info1 = env.step(a)
        cmd = u.damping_from_action(1.0)
        act = u.damping_actuator
        dt_info = invert_dt(act, info0["damping_indicated"], cmd, info1["damping_indicated"])
        dt_obs = invert_dt(
            act, u.damping_from_action(float(obs0[7])), cmd, u.damping_from_action(float(obs1[7]))
        )
        dt_true = u.episode.bearing.seconds(u.control_interval)
        rows.append((math.log(C), math.log(dt_info), math.log(dt_obs), math.log(dt_true)))
    r = np.array(rows)
    nom = u.nominal_bearing.seconds(u.control_interval)
    print(
        f"(a) nominal step {nom * 1e3:.3f} ms; drawn step ms: {np.exp(r[:, 3]).min() * 1e3:.3f}-{np.exp(r[:, 3]).max() * 1e3:.3f}"
    )
    for j, name in ((1, "info damping_indicated"), (2, "obs[7] float32")):
        ok = np.isfinite(r[:, j])
        X = np.c_[np.ones(ok.sum()), r[ok, j]]
        coef, *_ = np.linalg.lstsq(X, r[ok, 0], rcond=None)
        res = r[ok, 0] - X @ coef
        print(
            f"    {name}: ln C from ln dt_hat: slope {coef[1]:.3f}, rms err {res.std():.4f} "
            f"(prior sd ln C {r[:, 0].std():.4f}), n={ok.sum()}, max|ln dt_hat-ln dt| {np.nanmax(np.abs(r[ok, j] - r[ok, 3])):.2e}"
        )


def part_b(seeds, n_steps=30, n_cand=4000):
    env = gym.make("gfb_env/RunUp-v2")
    u = env.unwrapped
    act = u.damping_actuator
    dt = u.nominal_bearing.seconds(u.control_interval)
    lo, hi = act.gain_range
    for s in seeds:
        rng = np.random.default_rng(s)
        obs, info = env.reset(seed=s)
        g = u.hidden_parameters()["damping_gain"]
        d_ind = [info["damping_indicated"]]
        acts = []
        for _ in range(n_steps):
            a = np.array([0.0, rng.uniform(-1, 1)], np.float32)
            obs, r, te, tr, info = env.step(a)
            acts.append(u.damping_from_action(float(u.episode.last_action[1])))
            d_ind.append(info["damping_indicated"])
            if te or tr:
                break
        d0_actual = u.hidden_parameters()  # noqa: F841
        cands = np.exp(rng.uniform(math.log(lo), math.log(hi), n_cand))
        cands = np.r_[g, cands]
        score = np.zeros(len(cands))
        for ci, gc in enumerate(cands):
            st = act.start(d_ind[0] * gc, gc)
            m = 0
            for k, cmd in enumerate(acts):
                st = act.step(st, cmd, dt)
                m += (st.foil_damping / gc) == d_ind[k + 1]
            score[ci] = m / len(acts)
        full = cands[score == 1.0]
        # how often does the g-free prediction (gain 1) match exactly?
        st = act.start(d_ind[0], 1.0)
        m1 = 0
        for k, cmd in enumerate(acts):
            st = act.step(st, cmd, dt)
            m1 += st.foil_damping == d_ind[k + 1]
        print(
            f"(b) seed {s}: g={g:.4f}; steps {len(acts)}; true-g replay matches {score[0]:.2f}; g=1 replay "
            f"matches {m1 / len(acts):.2f}; candidates matching all: {len(full) - 1}/{n_cand}; "
            f"mean match of candidates {score[1:].mean():.2f}; |ln g_c - ln g| of best 5 others: "
            f"{np.sort(np.abs(np.log(cands[1:][np.argsort(-score[1:])[:5]]) - math.log(g)))}"
        )


if __name__ == "__main__":
    part_a(range(7_000_100, 7_000_132))
    part_b([7_000_200, 7_000_201, 7_000_202])
