"""``gfb runup``: a transient run-up (and coast-down) at a given acceleration: waterfall, orbits, envelopes.

It works on any bearing file (``--bearing``) and writes physical units by default (rpm, Hz, um),
nondimensional ones with ``--nondimensional``.  Every option is checked before any work: a bad value
is one line and exit code 2 (``ValueError`` from a handler, turned into exit 2 by :func:`gfb_env.cli.main`).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from gfb_env import jsonio
from gfb_env.scripting import (
    add_model_options,
    add_out_option,
    add_speed_range_options,
    add_start_options,
    add_unbalance_options,
    bearing_range_from_args,
    check_eigen_grid,
    model_from_args,
    optional_output_dir,
    positive,
    unbalance_from_args,
)

__all__ = ["check_runup_args", "cmd_runup", "register"]

_FMT = argparse.RawDescriptionHelpFormatter


def _eigen_model(args: argparse.Namespace):
    return check_eigen_grid(model_from_args(args))


# --------------------------------------------------------------------------------------- runup
#: Default speed range of ``runup`` in Lambda: the paper's Fig. 5 (Table 1: 30 000 - 50 000 rpm).
_RUNUP_LAMBDA = (0.5, 0.833)
_RUNUP_FILES = (
    "trajectory.csv",
    "envelope.csv",
    "waterfall.png",
    "orbits.png",
    "envelope.png",
    "summary.json",
)
#: Half peak-to-peak of xi (units of C) over a window above which the journal counts as whirling.
WHIRL_THRESHOLD = 0.02


def _speed_list(text: str, option: str) -> list[float]:
    try:
        vals = [float(x) for x in str(text).replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{option} must be a comma-separated list of speeds in rpm, got {text!r}") from None
    if not vals or len(vals) > 12 or any(not (math.isfinite(v) and v > 0) for v in vals):
        raise ValueError(f"{option} must list 1 to 12 positive speeds in rpm, got {text!r}")
    return vals


def check_runup_args(args: argparse.Namespace, model) -> dict:
    """Every check of ``runup`` that needs no integration; returns the derived numbers."""
    from gfb_env.analysis.runup import bearing_number_rate
    from gfb_env.scripting import MAX_DURATION, MAX_SAMPLES

    b = model.bearing
    lo, hi = bearing_range_from_args(args, b, _RUNUP_LAMBDA)
    rate = bearing_number_rate(model, args.acceleration)
    legs = 2 if args.coast_down else 1
    duration = legs * (hi - lo) / rate
    if duration > MAX_DURATION:
        need = args.acceleration * duration / MAX_DURATION
        raise ValueError(
            f"--acceleration {args.acceleration:g} rpm/s over {b.speed_rpm_at(lo):.0f}-"
            f"{b.speed_rpm_at(hi):.0f} rpm takes tau = {duration:.4g}, at most {MAX_DURATION:g} "
            f"(--acceleration >= {need:.4g})"
        )
    if duration / args.record_interval > MAX_SAMPLES:
        raise ValueError(
            f"--record-interval {args.record_interval:g} gives "
            f"{duration / args.record_interval:.3g} samples, at most {MAX_SAMPLES}"
        )
    # the 1x line at the top speed (omega = Lambda per unit tau) must lie below the Nyquist frequency
    nyquist_dt = math.pi / (1.25 * hi)
    if args.record_interval > nyquist_dt:
        raise ValueError(
            f"--record-interval {args.record_interval:g} cannot resolve the 1x line at Lambda={hi:.4g}: "
            f"at most {nyquist_dt:.3g}"
        )
    if args.window < 16 * args.record_interval or args.window > duration / legs:
        raise ValueError(
            f"--window {args.window:g} must lie in [16 x --record-interval, one leg = "
            f"{duration / legs:.4g}] tau"
        )
    lo_rpm, hi_rpm = b.speed_rpm_at(lo), b.speed_rpm_at(hi)
    if args.orbit_rpm is None:
        orbit = [lo_rpm + f * (hi_rpm - lo_rpm) for f in (0.25, 0.5, 0.75, 0.98)]
    else:
        orbit = _speed_list(args.orbit_rpm, "--orbit-rpm")
        bad = [v for v in orbit if not lo_rpm <= v <= hi_rpm]
        if bad:
            raise ValueError(
                f"--orbit-rpm {bad[0]:g} lies outside the speed range {lo_rpm:.0f}-{hi_rpm:.0f} rpm"
            )
    # a balance grade is the rotor's permissible unbalance at its top (service) speed
    unbalance = unbalance_from_args(args, b, b.speed_rpm_at(hi))
    return {
        "lo": lo,
        "hi": hi,
        "rate": rate,
        "duration": duration,
        "orbit_rpm": orbit,
        "unbalance": unbalance,
    }


def cmd_runup(args: argparse.Namespace) -> int:
    """Handler of ``gfb runup``."""
    from gfb_env.analysis.runup import envelopes, run_up, waterfall
    from gfb_env.analysis.stability import StabilityAnalysisError, critical_bearing_number
    from gfb_env.equilibrium import find_equilibrium
    from gfb_env.scripting import check_perturbation

    out = optional_output_dir(args.out, "--out", _RUNUP_FILES)
    model = _eigen_model(args)
    b = model.bearing
    c = check_runup_args(args, model)
    lo, hi = c["lo"], c["hi"]
    check_perturbation(model, find_equilibrium(model, lo), args.perturbation, args.touchdown)
    t0 = time.perf_counter()
    try:  # the linear onset, for the pictures (the run itself does not need it)
        cp = critical_bearing_number(model, args.foil_damping, (0.05, max(3.0, 2 * hi)), 0.05)
        lam_c = cp.critical_bearing_number
    except StabilityAnalysisError:
        lam_c = None
    res = run_up(
        model,
        args.foil_damping,
        (lo, hi),
        c["rate"],
        coast_down=args.coast_down,
        perturbation=tuple(args.perturbation),
        record_interval=args.record_interval,
        touchdown=args.touchdown,
        progress=not args.json,
        unbalance=c["unbalance"],
    )
    tr = res.trajectory
    env = envelopes(res, args.window)
    wf = waterfall(res, args.window)
    um = b.clearance_m * 1e6
    rpm = np.array([b.speed_rpm_at(x) for x in tr.bearing_number])
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        np.savetxt(
            out / "trajectory.csv",
            np.column_stack(
                [
                    tr.tau,
                    tr.tau * b.time_scale_s,
                    rpm,
                    tr.bearing_number,
                    res.leg,
                    tr.xi * um,
                    tr.eta * um,
                    tr.min_film_thickness * um,
                ]
            ),  # fmt: skip
            delimiter=",",
            header="tau,time_s,speed_rpm,bearing_number,leg,xi_um,eta_um,min_film_thickness_um",
            comments="",
            fmt="%.8g",
        )
    env_rpm = np.array([b.speed_rpm_at(x) for x in env["bearing_number"]])
    amp = env["whirl"]  # with an unbalance: the non-synchronous part (see gfb_env.analysis.runup)
    if out is not None:
        np.savetxt(
            out / "envelope.csv",
            np.column_stack(
                [
                    env["tau"] * b.time_scale_s,
                    env_rpm,
                    env["bearing_number"],
                    env["leg"],
                    env["xi_min"] * um,
                    env["xi_max"] * um,
                    env["eta_min"] * um,
                    env["eta_max"] * um,
                    env["eps_max"] * um,
                    env["hmin"] * um,
                    env["sync_xi"] * um,
                    env["sync_eta"] * um,
                    amp * um,
                ]
            ),  # fmt: skip
            delimiter=",",
            header="time_s,speed_rpm,bearing_number,leg,xi_min_um,xi_max_um,eta_min_um,eta_max_um,"
            "max_eccentricity_um,min_film_thickness_um,sync_xi_um,sync_eta_um,whirl_amplitude_um",
            comments="",
            fmt="%.8g",
        )
    whirl = amp > WHIRL_THRESHOLD
    up, down = whirl & (env["leg"] == 0), whirl & (env["leg"] == 1)
    onset = float(env_rpm[np.argmax(up)]) if up.any() else None
    collapse = float(env_rpm[np.nonzero(down)[0][-1]]) if down.any() else None
    # dominant line of the last run-up window, as a multiple of the rotor speed
    j_top = int(np.nonzero(wf.leg == 0)[0][-1])
    k = 1 + int(np.argmax(wf.amplitude[j_top, 1:]))
    ratio = float(wf.omega[k] / wf.bearing_number[j_top])
    # the 1x (order-tracked) response: at the top speed of the run-up and its largest value
    ub = c["unbalance"]
    i_up = np.nonzero(env["leg"] == 0)[0]
    i_top = int(i_up[-1])
    sync = np.maximum(env["sync_xi"], env["sync_eta"])
    i_max = int(np.argmax(sync))
    title = (
        f"{model.structure.value} foil, K_W={model.foil_stiffness:.3g}, D_W={args.foil_damping:.3g}, "
        f"{args.acceleration:g} rpm/s"
    )
    crit_rpm = None if lam_c is None else b.speed_rpm_at(lam_c)
    if out is not None:
        _plot_waterfall(wf, b, out / "waterfall.png", args.nondimensional, title, ratio)
        _plot_orbits(res, b, c["orbit_rpm"], args.window, out / "orbits.png", args.nondimensional, title)
        _plot_envelope(
            env, b, out / "envelope.png", args.nondimensional, title, lam_c, c["unbalance"] is not None
        )
    d = {
        "structure": model.structure.value,
        "grid": str(model.grid),
        "foil_stiffness": float(model.foil_stiffness),
        "foil_damping": args.foil_damping,
        "speed_rpm_range": [b.speed_rpm_at(lo), b.speed_rpm_at(hi)],
        "bearing_number_range": [lo, hi],
        "acceleration_rpm_s": args.acceleration,
        "bearing_number_rate": c["rate"],
        "coast_down": bool(args.coast_down),
        "unbalance": 0.0 if ub is None else ub.magnitude,
        "unbalance_um": 0.0 if ub is None else ub.eccentricity_um(b),
        "unbalance_g_mm": 0.0 if ub is None else ub.mass_radius_g_mm(b, args.rotor_mass_kg),
        "duration_tau": float(tr.tau[-1]),
        "duration_s": float(tr.tau[-1]) * b.time_scale_s,
        "status": res.status,
        "message": res.message,
        "touchdown_speed_rpm": (
            None if res.touchdown_tau is None else float(np.interp(res.touchdown_tau, tr.tau, rpm))
        ),
        "critical_speed_rpm": crit_rpm,
        "whirl_onset_speed_rpm": onset,
        "whirl_collapse_speed_rpm": collapse,
        "max_whirl_amplitude_um": float(amp.max()) * um,
        "max_eccentricity_um": float(tr.eccentricity.max()) * um,
        "min_film_thickness_um": float(tr.min_film_thickness.min()) * um,
        "top_speed_dominant_order": ratio,
        "top_speed_1x_speed_rpm": float(env_rpm[i_top]),
        "top_speed_1x_xi_um": float(env["sync_xi"][i_top]) * um,
        "top_speed_1x_eta_um": float(env["sync_eta"][i_top]) * um,
        "max_1x_amplitude_um": float(sync[i_max]) * um,
        "max_1x_speed_rpm": float(env_rpm[i_max]),
        "steps": res.steps,
        "files": {} if out is None else {k: str(out / k) for k in _RUNUP_FILES},
        "wall_time_s": time.perf_counter() - t0,
    }
    if out is not None:
        (out / "summary.json").write_text(jsonio.dumps(d, indent=2))
    if args.json:
        print(jsonio.dumps(d))
    else:
        print(title + f", grid {model.grid}")
        print(f"  status: {res.status} {res.message}".rstrip())
        print(f"  linear critical speed: {crit_rpm and round(crit_rpm)} rpm")
        print(f"  whirl onset on the run-up: {onset and round(onset)} rpm; collapse on coast-down: "
              f"{collapse and round(collapse)} rpm")  # fmt: skip
        print(
            f"  max whirl amplitude {d['max_whirl_amplitude_um']:.1f} um, "
            f"min film {d['min_film_thickness_um']:.1f} um"
        )
        if ub is not None:
            print(
                f"  unbalance U = {ub.magnitude:.4g} ({d['unbalance_um']:.3g} um): 1x at "
                f"{d['top_speed_1x_speed_rpm']:.0f} rpm x {d['top_speed_1x_xi_um']:.3g} um, y "
                f"{d['top_speed_1x_eta_um']:.3g} um; largest 1x {d['max_1x_amplitude_um']:.3g} um at "
                f"{d['max_1x_speed_rpm']:.0f} rpm"
            )
        print(
            f"  wrote {out}/ ({d['wall_time_s']:.1f} s)"
            if out
            else f"  no files written: --out DIR ({d['wall_time_s']:.1f} s)"
        )
    return 0 if res.status in ("done", "touchdown") else 1


def _plot_waterfall(wf, b, path: Path, nondim: bool, title: str, ratio: float) -> None:
    from gfb_env.plotting import plt

    legs = [leg for leg in (0, 1) if (wf.leg == leg).any()]
    fig, axes = plt.subplots(
        1, len(legs), figsize=(6 * len(legs), 6.5), squeeze=False, constrained_layout=True
    )
    hz = 1.0 / (2 * math.pi * b.time_scale_s)
    x = wf.omega if nondim else wf.omega * hz
    speeds = wf.bearing_number if nondim else np.array([b.speed_rpm_at(v) for v in wf.bearing_number])
    amp = wf.amplitude * (1.0 if nondim else b.clearance_m * 1e6)
    # at most 40 spectra a leg, the tallest peak 4 line spacings high
    n_lines = min(40, max(int(np.sum(wf.leg == leg)) for leg in legs))
    step = (speeds.max() - speeds.min()) / max(n_lines - 1, 1) if len(speeds) > 1 else 1.0
    scale = 4 * step / max(float(amp[:, 1:].max()), 1e-12)
    fmax = 1.6 * (speeds.max() if nondim else speeds.max() / 60.0)
    for ax, leg in zip(axes[0], legs):
        idx = np.nonzero(wf.leg == leg)[0]
        idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(len(idx), 40)).astype(int))]
        for j in idx[::-1] if leg == 0 else idx:
            ax.fill_between(x, speeds[j], speeds[j] + scale * amp[j], color="white", zorder=j)
            ax.plot(x, speeds[j] + scale * amp[j], color="k", lw=0.6, zorder=j)
        sp = np.array([speeds.min(), speeds.max()])
        f1 = sp if nondim else sp / 60.0
        ax.plot(f1, sp, "r--", lw=1, label="1x", zorder=10_000)
        ax.plot(0.43 * f1, sp, "b--", lw=1, label="0.43x", zorder=10_000)
        ax.set_xlim(0, fmax)
        ax.set_xlabel(r"angular frequency $\omega$ (rad per unit $\tau$)" if nondim else "frequency (Hz)")
        ax.set_ylabel(r"$\Lambda$" if nondim else "rotor speed (rpm)")
        ax.set_title(
            ("run-up" if leg == 0 else "coast-down") + f" (dominant at top: {ratio:.2f}x)", fontsize=9
        )
        ax.legend(loc="lower right", fontsize=8)
    unit = "C" if nondim else "um"
    fig.suptitle(f"Waterfall of xi ({unit}, Hann windows): {title}", fontsize=10)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _plot_orbits(res, b, orbit_rpm, window, path: Path, nondim: bool, title: str) -> None:
    from gfb_env.plotting import plt

    tr = res.trajectory
    rpm = np.array([b.speed_rpm_at(v) for v in tr.bearing_number])
    up = res.leg == 0
    c = 1.0 if nondim else b.clearance_m * 1e6
    n = len(orbit_rpm)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.6), squeeze=False, constrained_layout=True)
    th = np.linspace(0, 2 * np.pi, 200)
    dt = float(tr.tau[1] - tr.tau[0])
    half = max(2, int(window / dt / 2))
    for ax, v in zip(axes[0], orbit_rpm):
        j = int(np.argmin(np.where(up, np.abs(rpm - v), np.inf)))
        i = slice(max(0, j - half), j + half)
        ax.plot(c * np.sin(th), c * np.cos(th), "k--", lw=0.7)
        ax.plot(c * tr.xi[i], c * tr.eta[i], lw=0.7, color="tab:red")
        ax.set_aspect("equal")
        ax.invert_yaxis()
        ax.set_title(f"Lambda={tr.bearing_number[j]:.3f}" if nondim else f"{rpm[j]:.0f} rpm", fontsize=9)
        ax.set_xlabel(r"$\xi$ (C)" if nondim else "x (um)")
    axes[0][0].set_ylabel(r"$\eta$ (C, down)" if nondim else "y (um, down)")
    fig.suptitle(f"Orbits on the run-up ({window:g} tau each): {title}", fontsize=9)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _plot_envelope(
    env, b, path: Path, nondim: bool, title: str, lam_c: float | None, sync: bool = False
) -> None:
    from gfb_env.plotting import plt

    c = 1.0 if nondim else b.clearance_m * 1e6
    t = env["tau"] if nondim else env["tau"] * b.time_scale_s
    sp = env["bearing_number"] if nondim else np.array([b.speed_rpm_at(v) for v in env["bearing_number"]])
    fig, ax = plt.subplots(4, 1, figsize=(8, 9), constrained_layout=True)
    ax[0].plot(t, sp, "k-")
    ax[0].set_ylabel(r"$\Lambda$" if nondim else "speed (rpm)")
    for a, name, col in ((ax[1], "xi", "tab:red"), (ax[2], "eta", "tab:blue")):
        a.plot(t, c * env[f"{name}_min"], color=col, lw=0.9)
        a.plot(t, c * env[f"{name}_max"], color=col, lw=0.9)
        a.set_ylabel(
            (f"$\\{name}$ envelope (C)") if nondim else f"{'x' if name == 'xi' else 'y'} envelope (um)"
        )
    for a in ax[:3]:
        a.sharex(ax[0])
        a.grid(alpha=0.3)
    ax[2].set_xlabel(r"$\tau$" if nondim else "time (s)")
    amp = env["whirl"] * c
    for leg, style, lab in ((0, "-", "run-up"), (1, "--", "coast-down")):
        m = env["leg"] == leg
        if m.any():
            ax[3].plot(sp[m], amp[m], "k" + style, lw=1.2, label=lab + (" (non-synchronous)" if sync else ""))
            if sync:  # the order-tracked 1x response beside the whirl
                ax[3].plot(sp[m], c * env["sync_xi"][m], "tab:red", ls=style, lw=1, label=f"1x x, {lab}")
                ax[3].plot(sp[m], c * env["sync_eta"][m], "tab:blue", ls=style, lw=1, label=f"1x y, {lab}")
    if lam_c is not None:
        xc = lam_c if nondim else b.speed_rpm_at(lam_c)
        lab = f"linear onset Lambda_c = {xc:.4f}" if nondim else f"linear critical speed {xc:.0f} rpm"
        ax[3].axvline(xc, color="tab:red", ls="-.", lw=1, label=lab)
    ax[3].set_xlabel(r"$\Lambda$" if nondim else "speed (rpm)")
    ax[3].set_ylabel("amplitude (C)" if nondim else "amplitude (um)")
    if sync:
        ax[3].set_yscale("log")  # the 1x orbit (~um) beside a whirl (~C)
    ax[3].legend(fontsize=8)
    ax[3].grid(alpha=0.3)
    fig.suptitle(f"Run-up envelopes (paper Fig. 5): {title}", fontsize=10)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def register(subparsers) -> None:
    """Add ``runup`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "runup",
        formatter_class=_FMT,
        help="transient run-up (and coast-down) at a given acceleration: waterfall, orbits, envelopes",
        description=(
            "Transient run-up at --acceleration rpm/s from the perturbed static equilibrium at the first\n"
            "speed (optionally back down with --coast-down), integrated with the adaptive trapezoidal\n"
            "rule (Lambda ramps linearly within each step).  With an unbalance (--unbalance,\n"
            "--unbalance-g-mm or --balance-grade, the grade taken at the top speed) the rotor carries it\n"
            "from the start: the waterfall shows the 1x line, envelope.csv its order-tracked amplitude,\n"
            "and the whirl amplitude is then the non-synchronous part (xi minus its 1x fit).\n"
            "Writes OUT/trajectory.csv (tau, time_s, speed_rpm,\n"
            "bearing_number, leg, xi_um, eta_um, min_film_thickness_um), OUT/envelope.csv (per window,\n"
            "with sync_xi_um, sync_eta_um, whirl_amplitude_um),\n"
            "OUT/waterfall.png (spectra of x vs speed with the 1x and 0.43x lines), OUT/orbits.png\n"
            "(at --orbit-rpm), OUT/envelope.png (the paper's Fig. 5 in s, rpm and um, and the whirl\n"
            "amplitude vs speed with the linear critical speed) and OUT/summary.json.\n\n"
            "JSON keys: structure, grid, foil_stiffness, foil_damping, speed_rpm_range,\n"
            "bearing_number_range, acceleration_rpm_s, bearing_number_rate, coast_down, unbalance,\n"
            "unbalance_um, unbalance_g_mm, duration_tau,\n"
            "duration_s, status, message, touchdown_speed_rpm, critical_speed_rpm,\n"
            "whirl_onset_speed_rpm, whirl_collapse_speed_rpm (half peak-to-peak x above 0.02 C),\n"
            "max_whirl_amplitude_um, max_eccentricity_um, min_film_thickness_um,\n"
            "top_speed_dominant_order, top_speed_1x_speed_rpm, top_speed_1x_xi_um,\n"
            "top_speed_1x_eta_um, max_1x_amplitude_um, max_1x_speed_rpm (order-tracked zero-to-peak\n"
            "1x amplitudes per window), steps, files, wall_time_s."
        ),
    )
    add_model_options(p)
    add_speed_range_options(
        p, "Lambda 0.5 to 0.833 of the bearing, the paper's Fig. 5; Table 1: 30 025 - 50 025 rpm"
    )
    p.add_argument(
        "--acceleration",
        type=positive("--acceleration"),
        default=2500.0,
        metavar="RPM_PER_S",
        help="speed ramp in rpm/s (default 2500, about the paper's Fig. 5); the run may last at most "
        "tau = 250 000",
    )
    p.add_argument("--coast-down", action="store_true", help="ramp back down to the first speed")
    add_unbalance_options(p)
    p.add_argument(
        "--orbit-rpm",
        default=None,
        metavar="N1,N2,...",
        help="speeds (rpm) of the orbit plots on the run-up, 1..12 in the range (default: 4 spread over it)",
    )
    p.add_argument(
        "--window",
        type=positive("--window"),
        default=256.0,
        metavar="TAU",
        help="window of the waterfall spectra and envelopes in tau (default 256; Table 1: 0.041 s)",
    )
    p.add_argument(
        "--record-interval",
        type=positive("--record-interval"),
        default=0.5,
        metavar="DTAU",
        help="sampling interval in tau (default 0.5); must resolve the 1x line at the top speed",
    )
    add_start_options(p)
    p.add_argument(
        "--nondimensional",
        action="store_true",
        help="plot in Lambda, tau and units of C (default: rpm, s, um)",
    )
    add_out_option(p, _RUNUP_FILES)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_runup)
