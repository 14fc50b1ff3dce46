"""The superposed synchronous response (``synchronous_response="superposed"``, issue 20 item 2): where it
is valid, what it costs, how accurate it is.

Three parts (``--part``):

``linearity``
    The nominal RunUp plant (31x7, viscoelastic foil) held at ``D_W = 1`` at speeds toward ``Lambda_c``
    (0.659), the largest drawn unbalance (G 6.3 at 60 000 rpm, U = 0.020) and the smallest (G 1, U =
    0.0032): a long stepped forced run at the tight reference (rtol = atol = 1e-5, 128 steps per
    revolution), started on the analytic orbit, its 1x vector of the last 300 tau (least squares on cos /
    sin theta) against the analytic ``X``.  The growth rate of the least damped mode says where
    superposing stops being linear (the threshold ``MIN_DECAY_RATE`` of
    :mod:`gfb_env.envs.synchronous_plant`); a run thrown onto the whirl is reported as such.
``cost``
    Integrator steps and CPU us (``time.process_time``, min of ``--repeats``) per control step, default vs
    superposed, RunUp-v2 from its start, the speed held at several fractions of ``Lambda_c``, D_W = 1.
``episodes``
    Whole episodes of RunUp-v2 and RunUpRandomized-v2 (seeds ``--seeds``, a hold and a naive-ramp policy):
    superposed (default tolerances) and stepped default against the tight stepped reference, with the same
    random draws; per observation entry max |difference| / that entry's sensor noise, the 1x amplitude
    error in %, whether the verdicts (``is_success``, ``termination_reason``, ``certified``) agree, how many
    control steps were superposed / stepped and how many switches.

Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.synchronous_response_check --part linearity
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.equilibrium import find_equilibrium
from gfb_env.forcing import Unbalance
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.synchronous import SynchronousSolver, synchronous_forcing

TIGHT = {"rtol": 1e-5, "atol": 1e-5, "steps_per_revolution": 128}
TASKS = ("gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2")


def fit_1x(tau: np.ndarray, theta: np.ndarray, x: np.ndarray) -> complex:
    """Z with ``x ~ mean + trend + Re(Z e^{i theta})`` by least squares."""
    A = np.column_stack([np.ones_like(tau), tau - tau.mean(), np.cos(theta), np.sin(theta)])
    c = np.linalg.lstsq(A, x, rcond=None)[0]
    return complex(c[2], -c[3])


def stepped_steady_1x(
    model, lam: float, dw: float, magnitude: float, tau_run: float, start_on_orbit: bool = True, **options
) -> dict:
    """The 1x response of a stepped forced run held at ``lam`` (module docstring), and the analytic one."""
    s0 = find_equilibrium(model, lam)
    solver = SynchronousSolver(model)
    solver.start_mode(s0, lam, dw)
    ub = Unbalance(magnitude, 0.0)
    x = solver.update(s0, lam, dw, synchronous_forcing(model, ub, lam))
    L = model.layout
    start = s0 + x.real if start_on_orbit else s0
    integ = TrapezoidalIntegrator(model, start, lam, dw, unbalance=ub, **(TIGHT | options))
    res = integ.advance(tau_run, record_interval=0.25, raise_on_failure=False)
    tr = res.trajectory
    keep = tr.tau >= tr.tau[-1] - 300.0
    theta = lam * tr.tau[keep]  # theta' = Lambda, theta(0) = 0
    zx = fit_1x(tr.tau[keep], theta, tr.xi[keep])
    ze = fit_1x(tr.tau[keep], theta, tr.eta[keep])
    # what is left besides the 1x: the whirl, if the rotor was thrown onto it
    resid = tr.xi[keep] - (zx * np.exp(1j * theta)).real
    resid -= resid.mean()
    ax, ae = x[L.xi_index], x[L.eta_index]
    return {
        "bearing_number": lam,
        "unbalance": magnitude,
        "growth_rate": solver.mode.real,
        "status": str(res.status),
        "analytic_xi_amp": abs(ax),
        "amp_err_xi_pct": 100 * (abs(zx) / abs(ax) - 1),
        "amp_err_eta_pct": 100 * (abs(ze) / abs(ae) - 1),
        "phase_err_xi_deg": math.degrees(np.angle(zx / ax)),
        "phase_err_eta_deg": math.degrees(np.angle(ze / ae)),
        "residual_rms_over_1x": float(np.sqrt(np.mean(resid**2)) / abs(ax)),
        "integrator_steps": int(res.statistics.steps),
    }


def part_linearity(lams: Sequence[float], tau_run: float) -> list[dict]:
    env = gym.make("gfb_env/RunUp-v2").unwrapped
    env.reset(seed=0)
    model = env.model
    rows = []
    for lam in lams:
        for u in (0.020, 0.0032):
            r = stepped_steady_1x(model, lam, 1.0, u, tau_run)
            rows.append(r)
            print(
                f"Lambda {lam:.4f} U {u:.4f} growth {r['growth_rate']:+.4f}  1x amp err xi "
                f"{r['amp_err_xi_pct']:+.2f} % eta {r['amp_err_eta_pct']:+.2f} %  phase "
                f"{r['phase_err_xi_deg']:+.2f} / {r['phase_err_eta_deg']:+.2f} deg  "
                f"residual/1x {r['residual_rms_over_1x']:.3f}  {r['status']}",
                flush=True,
            )
    return rows


# ------------------------------------------------------------------------------------------------
def part_cost(fractions: Sequence[float], steps: int, repeats: int, warmup: int = 25) -> list[dict]:
    """Speed held at ``fraction * Lambda_c(D_W=1)`` (the env's speed set at reset through the plant)."""
    rows = []
    for frac in fractions:
        row = {"lambda_fraction": frac}
        for mode in ("stepped", "superposed"):
            best, counts = math.inf, None
            for _ in range(repeats):
                env = gym.make("gfb_env/RunUp-v2", synchronous_response=mode).unwrapped
                env.reset(seed=0)
                integ = env._integ
                lam = frac * 0.659
                s0 = find_equilibrium(env.model, lam)
                # the plant at the held speed and D_W = 1 (the actuator's state too), then a fresh start
                integ.reset(s0, lam, 1.0)
                env._ep.actuator = env.damping_actuator.start(1.0, env._ep.actuator.gain)
                env._start_synchronous_response(env._sync.unbalance if env._sync else integ.unbalance)
                a = np.array([0.0, env.action_from_damping(1.0 / env._ep.actuator.gain)])
                # past the switch-on transient (stepped until the free motion is below 0.0005 C), then time
                for _k in range(warmup):
                    env.step(a)
                n0 = env.episode.integrator_steps
                sup0 = env._sync.superposed_steps if env._sync is not None else 0
                t0 = time.process_time()
                for _k in range(steps):
                    env.step(a)
                dt = time.process_time() - t0
                best = min(best, dt / steps * 1e6)
                counts = (env.episode.integrator_steps - n0) / steps
                sync = env._sync
            row[mode] = {
                "us_per_step": best,
                "integrator_steps": counts,
                "superposed_steps": None if sync is None else sync.superposed_steps,
                "timed_steps_superposed": None if sync is None else sync.superposed_steps - sup0,
                "growth_rate": None if sync is None else sync.growth_rate,
            }
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


# ------------------------------------------------------------------------------------------------
def entry_noise(env) -> np.ndarray:
    """The sensor noise (one standard deviation) of each observation entry of a v2 env, in observation
    units, from the public probe and tap models (docs/machine.md); the monitor's entries from its
    reading's own ``*_std`` (NaN where the entry carries no noise: speed, damping, command, time)."""
    u = env.unwrapped
    names = u.observation_layout.names
    nb = u.nominal_bearing
    cnom = nb.clearance_m * 1e6
    sig = u.proximity_probes.noise_um
    dt = nb.seconds(u.record_interval)
    w = u.proximity_probes.velocity_window
    tt = np.arange(w) * dt
    vel = sig / math.sqrt(float(((tt - tt.mean()) ** 2).sum())) * nb.time_scale_s / cnom
    tap = u.pressure_taps.noise_kpa * 1e3 / nb.ambient_pressure_pa
    r = u.episode.interface.reading
    out = np.full(len(names), np.nan)
    for i, n in enumerate(names):
        if n in ("xi", "eta"):
            out[i] = sig / cnom
        elif n in ("xi_dot", "eta_dot"):
            out[i] = vel
        elif n in ("xi_extent", "eta_extent", "x_direct_pp", "y_direct_pp"):
            out[i] = 0.6 * sig / cnom  # the pk-pk of pure noise scatters 0.6 sigma (docs/machine.md)
        elif n.startswith("pressure_"):
            out[i] = tap
        elif r is not None and r.valid:
            p = r.x if n.startswith("x_") else r.y
            if n.endswith("1x_pp"):
                out[i] = p.synchronous_um_pp_std / cnom
            elif n.endswith(("1x_cos", "1x_sin")):
                out[i] = math.radians(p.synchronous_phase_lag_deg_std)
            elif n.endswith("subsync_rms"):
                out[i] = p.subsynchronous_um_rms_std / cnom
    return out


def _policy(name: str, env) -> np.ndarray:
    u = env.unwrapped
    if name == "hold":
        return np.array([0.0, 0.0])
    # naive ramp: full acceleration toward the command, the nominal optimum damping
    return u.scripted_action(1.0)


def run_episode(task: str, seed: int, policy: str, mode: str, options: dict | None) -> dict:
    env = gym.make(task, synchronous_response=mode, privileged_info=True, integrator_options=options)
    obs, info = env.reset(seed=seed)
    u = env.unwrapped
    O, N, A1, F = [obs], [entry_noise(env)], [], [False]
    cpu = 0.0
    term = trunc = False
    while not (term or trunc):
        a = _policy(policy, env)
        t0 = time.process_time()
        obs, _r, term, trunc, info = env.step(a)
        cpu += time.process_time() - t0
        O.append(obs)
        N.append(entry_noise(env))
        F.append(u._sync is not None and u._sync.superposed)  # the mode of the step just made
        r = u.episode.interface.reading
        A1.append(
            (r.x.synchronous_um_pp, r.y.synchronous_um_pp) if r is not None and r.valid else (np.nan, np.nan)
        )
    s = u._sync
    return {
        "obs": np.array(O),
        "superposed": np.array(F),
        "noise": np.array(N),
        "one_x": np.array(A1),
        "verdict": (info.get("is_success"), str(info.get("termination_reason")), info.get("certified")),
        "steps": len(O) - 1,
        "integrator_steps": u.episode.integrator_steps,
        "cpu_us_per_step": cpu / max(len(O) - 1, 1) * 1e6,
        "sync": None if s is None else (s.superposed_steps, s.stepped_steps, s.switches),
        "names": u.observation_layout.names,
    }


def compare(ref: dict, other: dict, only_superposed: bool = False) -> dict:
    """Per entry max |other - ref| / noise (over every step, or the steps ``other`` superposed)."""
    n = min(len(ref["obs"]), len(other["obs"]), len(other["superposed"]))
    rows = other["superposed"][:n] if only_superposed else np.ones(n, bool)
    if not rows.any():
        return {"steps": 0}
    d = np.abs(other["obs"][:n] - ref["obs"][:n])[rows]
    noise = ref["noise"][:n][rows]
    ratio = np.where(np.isfinite(noise) & (noise > 0), d / np.where(noise > 0, noise, 1.0), np.nan)
    worst = {}
    for i, name in enumerate(ref["names"]):
        col = ratio[:, i]
        worst[name] = float(np.nanmax(col)) if np.isfinite(col).any() else float(d[:, i].max())
    a_ref, a_oth = ref["one_x"][: n - 1][rows[1:]], other["one_x"][: n - 1][rows[1:]]
    big = a_ref > 0.5  # um pp: where the 1x stands out of the noise (0.077 um pp)
    err = np.abs(a_oth[big] / a_ref[big] - 1) * 100 if big.any() else np.array([math.nan])
    return {
        "steps": int(rows.sum()),
        "max_over_noise": worst,
        "one_x_amp_err_pct_max": float(np.max(err)),
        "one_x_amp_err_pct_median": float(np.median(err)),
        "verdicts_equal": ref["verdict"] == other["verdict"],
        "same_length": len(ref["obs"]) == len(other["obs"]),
    }


def part_episodes(seeds: Sequence[int], policies: Sequence[str], tasks: Sequence[str] = TASKS) -> list[dict]:
    rows = []
    for task in tasks:
        for policy in policies:
            for seed in seeds:
                ref = run_episode(task, seed, policy, "stepped", TIGHT)
                dflt = run_episode(task, seed, policy, "stepped", None)
                sup = run_episode(task, seed, policy, "superposed", None)
                row = {
                    "task": task,
                    "policy": policy,
                    "seed": seed,
                    "steps": ref["steps"],
                    "verdict_ref": ref["verdict"],
                    "integrator_steps_per_step": {
                        "reference": ref["integrator_steps"] / ref["steps"],
                        "stepped": dflt["integrator_steps"] / dflt["steps"],
                        "superposed": sup["integrator_steps"] / sup["steps"],
                    },
                    "cpu_us_per_step": {
                        "stepped": dflt["cpu_us_per_step"],
                        "superposed": sup["cpu_us_per_step"],
                    },
                    "superposed_stepped_switches": sup["sync"],
                    "stepped_vs_ref": compare(ref, dflt),
                    "superposed_vs_ref": compare(ref, sup),
                    "superposed_steps_vs_ref": compare(ref, sup, only_superposed=True),
                    "stepped_on_those_steps_vs_ref": compare(
                        ref, dflt | {"superposed": sup["superposed"]}, True
                    ),
                }
                rows.append(row)
                w_sup = max(row["superposed_vs_ref"]["max_over_noise"].items(), key=lambda kv: kv[1])
                w_stp = max(row["stepped_vs_ref"]["max_over_noise"].items(), key=lambda kv: kv[1])
                print(
                    f"{task} {policy} seed {seed}: {ref['steps']} steps, ref verdict {ref['verdict']}; "
                    "integrator "
                    f"steps/step ref {row['integrator_steps_per_step']['reference']:.1f} stepped "
                    f"{row['integrator_steps_per_step']['stepped']:.1f} superposed "
                    f"{row['integrator_steps_per_step']['superposed']:.1f}; cpu us stepped "
                    f"{dflt['cpu_us_per_step']:.0f} superposed {sup['cpu_us_per_step']:.0f}; sup/stp/switch "
                    f"{sup['sync']}; worst |d|/noise superposed {w_sup[0]} {w_sup[1]:.3f}, stepped "
                    f"{w_stp[0]} {w_stp[1]:.3f}; 1x err % superposed max "
                    f"{row['superposed_vs_ref']['one_x_amp_err_pct_max']:.2f} median "
                    f"{row['superposed_vs_ref']['one_x_amp_err_pct_median']:.2f}, stepped max "
                    f"{row['stepped_vs_ref']['one_x_amp_err_pct_max']:.2f}; verdicts equal superposed "
                    f"{row['superposed_vs_ref']['verdicts_equal']} stepped "
                    f"{row['stepped_vs_ref']['verdicts_equal']}",
                    flush=True,
                )
                ss, st = row["superposed_steps_vs_ref"], row["stepped_on_those_steps_vs_ref"]
                if ss["steps"]:
                    w1 = max(ss["max_over_noise"].items(), key=lambda kv: kv[1])
                    w2 = max(st["max_over_noise"].items(), key=lambda kv: kv[1])
                    print(
                        f"   on the {ss['steps']} superposed steps: worst |d|/noise superposed "
                        f"{w1[0]} {w1[1]:.3f}, stepped {w2[0]} {w2[1]:.3f}; 1x err % superposed max "
                        f"{ss['one_x_amp_err_pct_max']:.2f} median {ss['one_x_amp_err_pct_median']:.2f}, "
                        f"stepped max {st['one_x_amp_err_pct_max']:.2f}",
                        flush=True,
                    )
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m gfb_experiments.synchronous_response_check", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--part", choices=("linearity", "cost", "episodes"), required=True)
    ap.add_argument("--lambdas", type=float, nargs="+", default=[0.45, 0.55, 0.60, 0.62, 0.64, 0.65, 0.655])
    ap.add_argument("--tau", type=float, default=1500.0, help="linearity: length of each held run (tau)")
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.7, 0.85, 0.93, 0.97])
    ap.add_argument("--steps", type=int, default=20, help="cost: timed control steps")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--policies", nargs="+", default=["hold", "ramp"], choices=("hold", "ramp"))
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    ap.add_argument("--out", default=None, help="write the rows as JSON here")
    a = ap.parse_args(argv)
    if a.tau <= 300 or a.steps < 1 or a.repeats < 1:
        ap.error("--tau must exceed 300, --steps and --repeats must be >= 1")
    if a.part == "linearity":
        rows = part_linearity(a.lambdas, a.tau)
    elif a.part == "cost":
        rows = part_cost(a.fractions, a.steps, a.repeats)
    else:
        rows = part_episodes(a.seeds, a.policies, a.tasks)
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
