"""The vibration monitor (:mod:`gfb_env.machine.monitor`) on the real plant (issue 19 sect. 2).

1. **1x against the linear unbalance response.**  On ``gfb_env/RunUp-v2``'s machine (development seeds:
   the episode's bearing, drawn unbalance and actual damping, read from the env's internals), the journal
   starts at the equilibrium at a speed Lambda (fractions of the episode's Lambda_c), runs with the
   unbalance until the free motion has decayed (8 / |max Re lambda|, at most 4000 tau), then one 60-tau
   control step is recorded on the envs' grid (120 samples) and turned into probe readings (exact, and
   the realistic probes of ``MACHINE_V1``: 0.3 um noise and a drawn bias); the monitor's 1x phasor of
   each probe is compared with the analytic ``(i Lambda I - J) z = b`` of
   :func:`gfb_env.analysis.response.unbalance_response`, projected on the probe
   (``C (u . z) e^{i phase}``).  A step with the motor's largest speed ramp (30 000 rpm/s) is compared
   with the linear response at its mean speed.
2. **A developed whirl.**  ``gfb_env/WhirlRecovery-v2``'s start (the stored limit cycle advanced by a
   random phase, the drawn gain and unbalance): one control step at the whirl's speed and damping; the
   monitor's sub-synchronous level, its dominant ratio against the limit cycle's (2 pi / (period
   Lambda_w)), and the 1x against it.

Run::

    OMP_NUM_THREADS=1 python -m gfb_experiments.monitor_check --seeds 0,1,2 --out results/monitor_check

Writes ``summary.json`` into ``--out`` and prints the numbers.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_env.analysis.response import unbalance_response
from gfb_env.analysis.stability import critical_bearing_number, jacobian_eigenvalues
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.machine import ProximityProbes, VibrationMonitor
from gfb_env.machine.monitor import keyphasor_angles
from gfb_env.scripting import OneLineParser, check_output_dir, write_json

__all__ = ["record_step", "one_x_check", "whirl_check", "main"]

STEP_TAU = 60.0  # the envs' control interval
SAMPLES = 120  # the envs' record grid per control step


def record_step(
    integ: TrapezoidalIntegrator, bearing_number_end: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Advance ``integ`` by one control step on the envs' record grid: (tau, xi, eta, theta) of the
    samples (theta from the integrator's angle at the step's start and the Lambda ramp)."""
    tau0, th0, lam0 = integ.tau, integ.rotation_angle, integ.bearing_number
    lam1 = lam0 if bearing_number_end is None else bearing_number_end
    res = integ.advance(tau0 + STEP_TAU, lam1, record_interval=STEP_TAU / SAMPLES)
    tr = res.trajectory
    keep = tr.tau > tau0 + 1e-9  # the samples of the step, (tau0, tau0 + 60], as the envs take them
    th = keyphasor_angles(tr.tau[keep], tau0, th0, lam0, tau0 + STEP_TAU, lam1)
    # the integrator carries theta itself: the key's angle at the step's end is its angle
    gap = (th[-1] - integ.rotation_angle + math.pi) % (2 * math.pi) - math.pi
    if abs(gap) > 1e-9 or abs(tr.tau[keep][-1] - integ.tau) > 1e-9:
        raise RuntimeError(f"keyphasor angle off the integrator's by {gap:.3g} rad")
    return tr.tau[keep], tr.xi[keep], tr.eta[keep], th


def _readings(probes: ProximityProbes, rng: np.random.Generator, c_um: float, xi, eta, bias) -> tuple:
    return probes.readings_um(rng, np.asarray(xi) * c_um, np.asarray(eta) * c_um, bias)


def _probe_phasors(probes: ProximityProbes, c_um: float, z_xi: complex, z_eta: complex, phase: float):
    """The linear 1x phasors (X, Y) in um zero-to-peak, keyphasor convention (signal = Re(Z e^{i theta}))."""
    u = probes.directions
    rot = np.exp(1j * phase)
    return [c_um * rot * (u[k, 0] * z_xi + u[k, 1] * z_eta) for k in range(2)]


def one_x_check(seed: int, fractions: Sequence[float], monitor: VibrationMonitor) -> list[dict[str, Any]]:
    """Part 1 for one RunUp-v2 episode: per speed (a fraction of Lambda_c at the episode's actual damping)."""
    env = gym.make("gfb_env/RunUp-v2")
    env.reset(seed=seed)
    u = env.unwrapped
    ep, integ0 = u.episode, u._integ  # noqa: SLF001 - the check reads the plant the env runs
    model, bearing = ep.model, ep.bearing
    ub, dw = integ0.unbalance, integ0.foil_damping
    realistic = u.proximity_probes
    c_um = bearing.clearance_m * 1e6
    rng = np.random.default_rng(1000 + seed)
    bias = realistic.draw_bias(rng)
    dt_s = bearing.seconds(STEP_TAU / SAMPLES)
    lam_max_rate = u.max_rate(bearing)  # dLambda/dtau at the motor's limit
    crit = critical_bearing_number(model, dw, bearing_range=(0.3, 2.0))
    lam_c = crit.critical_bearing_number
    rows = []
    for frac in fractions:
        lam = frac * lam_c
        s0 = find_equilibrium(model, lam)
        growth = float(jacobian_eigenvalues(model, s0, lam, dw)[0].real)
        lin = unbalance_response(model, lam, ub, dw, state=s0, stability=False)
        integ = TrapezoidalIntegrator(model, s0, lam, dw, unbalance=ub, rtol=1e-7, atol=1e-9)
        # whole control steps, as in the envs (the record grid is anchored at tau = 0)
        integ.advance(STEP_TAU * math.ceil(min(8.0 / -growth, 4000.0) / STEP_TAU))
        for ramp in (False, True):
            lam_end = lam + lam_max_rate * STEP_TAU if ramp else None
            tau, xi, eta, th = record_step(integ, lam_end)
            t_s = bearing.seconds(tau)
            if ramp:  # quasi-steady: the linear response at the step's mean speed
                lin_ref = unbalance_response(
                    model, lam + 0.5 * lam_max_rate * STEP_TAU, ub, dw, stability=False
                )
            else:
                lin_ref = lin
            want = _probe_phasors(realistic, c_um, lin_ref.xi, lin_ref.eta, ub.phase_rad)
            exact = monitor.measure(t_s, *_readings(ProximityProbes.ideal(), rng, c_um, xi, eta, bias), th)
            noisy = monitor.measure(
                t_s, *_readings(realistic, rng, c_um, xi, eta, bias), th, noise_um=realistic.noise_um
            )
            for name, k in (("x", 0), ("y", 1)):
                pe, pn = getattr(exact, name), getattr(noisy, name)
                z = want[k]
                rows.append(
                    {
                        "seed": seed,
                        "bearing_number": lam,
                        "critical_bearing_number": lam_c,
                        "onset_whirl_ratio": crit.whirl_frequency_ratio,
                        "ramp": ramp,
                        "speed_rpm": exact.running_speed_rpm,
                        "foil_damping": dw,
                        "unbalance": ub.magnitude,
                        "growth_rate": growth,
                        "probe": name,
                        "linear_um_pp": 2 * abs(z),
                        "linear_phase_lag_deg": math.degrees(-np.angle(z)) % 360.0,
                        "exact_um_pp": pe.synchronous_um_pp,
                        "exact_phase_lag_deg": pe.synchronous_phase_lag_deg,
                        "exact_relative_error": abs(pe.synchronous_phasor_um - z) / abs(z),
                        "exact_subsynchronous_um_rms": pe.subsynchronous_um_rms,
                        "noisy_um_pp": pn.synchronous_um_pp,
                        "noisy_um_pp_std": pn.synchronous_um_pp_std,
                        "noisy_phase_lag_deg": pn.synchronous_phase_lag_deg,
                        "noisy_phase_lag_deg_std": pn.synchronous_phase_lag_deg_std,
                        "noisy_amplitude_z": (pn.synchronous_um_pp - 2 * abs(z)) / pn.synchronous_um_pp_std,
                        "noisy_subsynchronous_um_rms": pn.subsynchronous_um_rms,
                        "noise_floor_um_rms": pn.subsynchronous_noise_floor_um_rms,
                        "dt_s": dt_s,
                    }
                )
    env.close()
    return rows


def whirl_check(seed: int, monitor: VibrationMonitor) -> dict[str, Any]:
    """Part 2 for one WhirlRecovery-v2 start: one control step of the developed whirl."""
    env = gym.make("gfb_env/WhirlRecovery-v2")
    env.reset(seed=seed)
    u = env.unwrapped
    ep, integ = u.episode, u._integ  # noqa: SLF001
    bearing = ep.bearing
    lam_w = integ.bearing_number
    ratio = 2 * math.pi / (u.whirl_period * lam_w)
    tau, xi, eta, th = record_step(integ)
    c_um = bearing.clearance_m * 1e6
    rng = np.random.default_rng(2000 + seed)
    probes = u.proximity_probes
    r = monitor.measure(
        bearing.seconds(tau),
        *_readings(probes, rng, c_um, xi, eta, ep.probe_bias_um),
        th,
        noise_um=probes.noise_um,
    )
    exact = monitor.measure(bearing.seconds(tau), *probes.read_um(xi * c_um, eta * c_um), th)
    out = {
        "seed": seed,
        "bearing_number": lam_w,
        "speed_rpm": r.running_speed_rpm,
        "revolutions": r.revolutions,
        "limit_cycle_ratio": ratio,
        "unbalance": 0.0 if integ.unbalance is None else integ.unbalance.magnitude,
        "true_orbit_um_rms": {
            "x": float(np.std(probes.read_um(xi * c_um, eta * c_um)[0])),
            "y": float(np.std(probes.read_um(xi * c_um, eta * c_um)[1])),
        },
    }
    for name in ("x", "y"):
        p, pe = getattr(r, name), getattr(exact, name)
        out[name] = {
            "direct_um_pp": p.direct_um_pp,
            "subsynchronous_um_rms": p.subsynchronous_um_rms,
            "subsynchronous_um_rms_std": p.subsynchronous_um_rms_std,
            "noise_floor_um_rms": p.subsynchronous_noise_floor_um_rms,
            "subsynchronous_ratio": p.subsynchronous_ratio,
            "exact_subsynchronous_ratio": pe.subsynchronous_ratio,
            "synchronous_um_pp": p.synchronous_um_pp,
            "synchronous_um_pp_std": p.synchronous_um_pp_std,
            "second_harmonic_um_pp": p.second_harmonic_um_pp,
            "residual_um_rms": p.residual_um_rms,
        }
    env.close()
    return out


def main(argv: Sequence[str] | None = None) -> int:
    p = OneLineParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", default="0,1,2", help="development seeds (0-9999), comma-separated")
    p.add_argument("--fractions", default="0.64,0.75,0.86,0.93", help="speeds as fractions of Lambda_c")
    p.add_argument("--out", default="results/monitor_check")
    args = p.parse_args(argv)
    try:
        seeds = [int(v) for v in args.seeds.split(",")]
        fractions = [float(v) for v in args.fractions.split(",")]
    except ValueError:
        p.error(
            f"--seeds and --fractions must be comma-separated numbers, got {args.seeds!r}, {args.fractions!r}"
        )
    if not all(0 <= s < 10_000 for s in seeds):
        p.error(f"--seeds must be development seeds in [0, 9999], got {args.seeds!r}")
    if not all(0.3 <= f < 1.0 for f in fractions):
        p.error(f"--fractions must lie in [0.3, 1), got {args.fractions!r}")
    try:
        out = check_output_dir(args.out, files=("summary.json",))
    except ValueError as e:
        p.error(str(e))
    monitor = VibrationMonitor()
    one_x = [row for s in seeds for row in one_x_check(s, fractions, monitor)]
    whirl = [whirl_check(s, monitor) for s in seeds]
    for r in one_x:
        lin = f"linear {r['linear_um_pp']:.4f} um pp {r['linear_phase_lag_deg']:6.1f} deg"
        ex = f"exact {r['exact_um_pp']:.4f} {r['exact_phase_lag_deg']:6.1f}"
        ex += f" (|dZ|/|Z| {r['exact_relative_error']:.2e})"
        no = (
            f"noisy {r['noisy_um_pp']:.3f}+-{r['noisy_um_pp_std']:.3f} "
            f"{r['noisy_phase_lag_deg']:6.1f}+-{r['noisy_phase_lag_deg_std']:.1f}"
        )
        ramp = " ramp" if r["ramp"] else "     "
        print(f"1x seed {r['seed']} Lambda {r['bearing_number']:.3f}{ramp} {r['probe']}: {lin} | {ex} | {no}")
    for w in whirl:
        for name in ("x", "y"):
            q = w[name]
            sub = f"sub {q['subsynchronous_um_rms']:.2f}+-{q['subsynchronous_um_rms_std']:.3f} um rms"
            ref = f"orbit rms {w['true_orbit_um_rms'][name]:.2f}, floor {q['noise_floor_um_rms']:.3f}"
            rat = f"ratio {q['subsynchronous_ratio']:.4f} (limit cycle {w['limit_cycle_ratio']:.4f})"
            rest = f"1x {q['synchronous_um_pp']:.3f} um pp, direct {q['direct_um_pp']:.1f} um pp"
            print(f"whirl seed {w['seed']} {name}: {sub} ({ref}) {rat} {rest}")
    errs = [r["exact_relative_error"] for r in one_x]
    zs = [r["noisy_amplitude_z"] for r in one_x]
    summary = {
        "one_x": one_x,
        "whirl": whirl,
        "one_x_max_exact_relative_error": max(errs),
        "one_x_max_exact_relative_error_constant_speed": max(
            r["exact_relative_error"] for r in one_x if not r["ramp"]
        ),
        "one_x_noisy_amplitude_z_rms": float(np.sqrt(np.mean(np.square(zs)))),
        "whirl_max_ratio_error": max(
            abs(w[n]["subsynchronous_ratio"] - w["limit_cycle_ratio"]) for w in whirl for n in "xy"
        ),
    }
    print(
        f"1x: max |Z_monitor - Z_linear| / |Z_linear| = {summary['one_x_max_exact_relative_error']:.2e} "
        f"(constant speed {summary['one_x_max_exact_relative_error_constant_speed']:.2e}); noisy amplitude "
        f"z-score rms {summary['one_x_noisy_amplitude_z_rms']:.2f}; whirl ratio max error "
        f"{summary['whirl_max_ratio_error']:.4f}"
    )
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "summary.json", summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
