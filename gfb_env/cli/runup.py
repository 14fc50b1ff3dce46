"""``gfb runup``: a transient run-up (and coast-down) at a given acceleration: waterfall, orbits, envelopes.

It works on any bearing file (``--bearing``) and writes physical units by default (rpm, Hz, um),
nondimensional ones with ``--nondimensional``.  Every option is checked before any work: a bad value
is one line and exit code 2 (``ValueError`` from a handler, turned into exit 2 by :func:`gfb_env.cli.main`).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

from gfb_env import jsonio
from gfb_env.scripting import (
    add_model_options,
    add_out_option,
    add_speed_range_options,
    add_start_options,
    add_unbalance_options,
    bearing_range_from_args,
    check_eigen_grid,
    float_list,
    model_from_args,
    optional_output_dir,
    positive,
    unbalance_from_args,
    written_line,
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
        orbit = float_list(args.orbit_rpm, "--orbit-rpm", max_items=12)
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
    from gfb_env.analysis.runup import analyse_run_up, run_up
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
    if res.status != "done" and tr.tau[-1] - tr.tau[0] < args.window:
        # nothing to analyse: without this, the waterfall's "shorter than one window" reads as a bad
        # --window (exit 2) when the bearing whirled from the first speed (e.g. the small turbocompressor
        # at the default range, far above its onset)
        print(
            f"gfb runup: error: {res.message or res.status} at {b.speed_rpm_at(tr.bearing_number[-1]):.0f} "
            f"rpm, before one waterfall window "
            f"({args.window:g} tau): start below the onset (--speed-range; `gfb critical` gives it)",
            file=sys.stderr,
        )
        return 1
    ru = analyse_run_up(res, b, args.window, lam_c)
    title = (
        f"{model.structure.value} foil, K_W={model.foil_stiffness:.3g}, D_W={args.foil_damping:.3g}, "
        f"{args.acceleration:g} rpm/s"
    )
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        ru.write_trajectory_csv(out / "trajectory.csv")
        ru.write_envelope_csv(out / "envelope.csv")
        ru.plot_waterfall(out / "waterfall.png", args.nondimensional, title)
        ru.plot_orbits(c["orbit_rpm"], out / "orbits.png", args.nondimensional, title)
        ru.plot_envelope(out / "envelope.png", args.nondimensional, title)
    ub = c["unbalance"]
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
        **ru.summary(),
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
        crit, onset, collapse = (
            d["critical_speed_rpm"],
            d["whirl_onset_speed_rpm"],
            d["whirl_collapse_speed_rpm"],
        )
        print(f"  linear critical speed: {crit and round(crit)} rpm")
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
        print("  " + written_line(out and f"{out}/", d["wall_time_s"]))
    return 0 if ru.ok else 1


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
