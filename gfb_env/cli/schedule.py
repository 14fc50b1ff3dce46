"""``gfb schedule``: a designed, verified run-up schedule for a bearing (issue 12, part 3).

The design is :func:`gfb_env.analysis.schedule.design_run_up_schedule`; this module checks the options
(one line and exit 2 before any work), runs it, verifies the schedule by a transient run and writes the
schedule (CSV), the map with the path (PNG) and a summary (JSON).
"""

from __future__ import annotations

import argparse
import time

from gfb_env import jsonio
from gfb_env.analysis.schedule import STABLE_WHIRL_AMPLITUDE
from gfb_env.model import Grid
from gfb_env.scripting import (
    add_bearing_option,
    add_out_option,
    add_unbalance_options,
    check_eigen_grid,
    grid_type,
    in_range,
    int_range,
    optional_output_dir,
    positive,
    unbalance_from_args,
    written_line,
)

__all__ = ["register", "cmd_schedule", "WHIRL_THRESHOLD"]

#: The verified run's stability threshold (units of C), kept under its old name.
WHIRL_THRESHOLD = STABLE_WHIRL_AMPLITUDE

_FILES = ("schedule.csv", "stability_curve.csv", "schedule.png", "summary.json")


def register(subparsers) -> None:
    """Add ``schedule`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "schedule",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="design and verify a run-up schedule (damping and speed path) for a bearing",
        description=(
            "Designs a run-up for the viscoelastic foil of the bearing: Lambda_c(D_W) on a log grid of\n"
            "dampings, the fold of cycles (lower edge of the hysteresis band) at the dampings with the\n"
            "highest Lambda_c, and the damping with the highest safe speed\n"
            "min((1 - margin) Lambda_c, Lambda_fold).  The schedule ramps at --acceleration at that\n"
            "damping to the target, or, if the target is above the safe speed, to the safe speed (the\n"
            "target is reported infeasible), then holds; a transient run verifies it.  With an\n"
            "unbalance (--unbalance, --unbalance-g-mm or --balance-grade, the grade taken at the target\n"
            "speed; default: none) the verification carries it from the start, and the last 500 tau of\n"
            "the hold are split into the 1x orbit and the non-synchronous motion (the whirl).\n\n"
            "Writes OUT/schedule.csv (time_s, speed_rpm, foil_damping), OUT/stability_curve.csv\n"
            "(foil_damping, critical_speed_rpm, fold_speed_rpm), OUT/schedule.png (the map with the path)\n"
            "and OUT/summary.json.  Exit code 0 when the verified run is stable (its non-synchronous\n"
            "motion below 0.05 C), 1 when it whirls, touches down or fails, 2 for bad options.\n\n"
            "JSON keys: structure, grid, foil_stiffness, target_speed_rpm, feasible, foil_damping,\n"
            "critical_speed_rpm, fold_speed_rpm, max_safe_speed_rpm, end_speed_rpm, start_speed_rpm,\n"
            "margin, margin_to_critical, margin_to_fold, acceleration_rpm_s, ramp_time_s, hold_time_s,\n"
            "verified_status, verified_stable, verified_max_whirl_amplitude_um,\n"
            "verified_min_film_thickness_um,\n"
            "verified_max_eccentricity_um, unbalance, unbalance_um, unbalance_g_mm, verified_1x_xi_um,\n"
            "verified_1x_eta_um, verified_max_vibration_amplitude_um, linear_1x_xi_um,\n"
            "linear_1x_eta_um, notes, files, wall_time_s.  With an unbalance the whirl amplitude is\n"
            "the non-synchronous part; the vibration amplitude includes the 1x orbit."
        ),
    )
    add_bearing_option(p)
    p.add_argument(
        "--target-rpm", type=positive("--target-rpm"), required=True, metavar="N", help="target speed (rpm)"
    )
    p.add_argument(
        "--margin",
        type=in_range("--margin", 0.0, 0.5),
        default=0.05,
        metavar="M",
        help="relative margin below the critical speed, in [0, 0.5) (default %(default)s)",
    )
    p.add_argument(
        "--acceleration",
        type=positive("--acceleration"),
        default=2500.0,
        metavar="RPM_PER_S",
        help="speed ramp in rpm/s (default %(default)s)",
    )
    p.add_argument(
        "--start-rpm",
        type=positive("--start-rpm"),
        default=None,
        metavar="N",
        help="start speed in rpm (default: half the end speed)",
    )
    p.add_argument(
        "--foil-stiffness",
        type=positive("--foil-stiffness"),
        default=None,
        metavar="K",
        help="K_W (default: Walowit-Anno of the bearing's bump foil)",
    )
    p.add_argument(
        "--damping-range",
        type=positive("--damping-range"),
        nargs=2,
        default=[0.1, 10.0],
        metavar=("DMIN", "DMAX"),
        help="range of the foil damping D_W searched (default 0.1 10)",
    )
    p.add_argument(
        "--n-dampings",
        type=int_range("--n-dampings", 3, 60),
        default=13,
        metavar="N",
        help="log-spaced dampings of the stability curve, 3..60 (default %(default)s)",
    )
    p.add_argument(
        "--fold-dampings",
        type=int_range("--fold-dampings", 0, 10),
        default=3,
        metavar="N",
        help="dampings (highest Lambda_c first) at which the fold of cycles is computed, 0..10; 0 skips "
        "the hysteresis band (default %(default)s; each takes seconds on 31x7, about a minute on 79x7)",
    )
    p.add_argument(
        "--hold",
        type=in_range("--hold", 500.0, 100_000.0),
        default=3000.0,
        metavar="TAU",
        help="hold at the end speed in tau, 500..100000 (default %(default)s); the verification's whirl "
        "amplitude is taken over its last 500 tau",
    )
    p.add_argument(
        "--grid",
        type=grid_type,
        default=Grid(31, 7),
        metavar="NPHIxNZ",
        help="finite-difference grid (default 31x7: Lambda_c within 1 %% of 79x7, docs/envs.md)",
    )
    add_unbalance_options(p)
    add_out_option(p, _FILES)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_schedule)


def cmd_schedule(args: argparse.Namespace) -> int:
    """Handler of ``gfb schedule``."""
    from gfb_env.analysis.runup import bearing_number_rate
    from gfb_env.analysis.schedule import design_run_up_schedule, verify_schedule
    from gfb_env.model import GFBModel
    from gfb_env.scripting import bearing_from_args

    out = optional_output_dir(args.out, "--out", _FILES)
    b = bearing_from_args(args)
    dmin, dmax = args.damping_range
    if not dmin < dmax:
        raise ValueError(f"--damping-range must satisfy 0 < DMIN < DMAX, got {dmin:g} {dmax:g}")
    if args.start_rpm is not None and not args.start_rpm < args.target_rpm:
        raise ValueError(f"--start-rpm must be below --target-rpm, got {args.start_rpm:g}")
    model = check_eigen_grid(
        GFBModel("viscoelastic", args.grid, bearing=b, foil_stiffness=args.foil_stiffness)
    )
    # a balance grade is the permissible unbalance at the service speed: the target
    unbalance = unbalance_from_args(args, b, args.target_rpm)
    rate = bearing_number_rate(model, args.acceleration)
    ramp_tau = (b.bearing_number_at(args.target_rpm) - b.bearing_number_at(args.start_rpm or 0.0)) / rate
    if ramp_tau > 250_000:
        raise ValueError(
            f"--acceleration {args.acceleration:g} rpm/s makes the ramp {ramp_tau:.3g} tau long, at most "
            "250000 (raise the acceleration)"
        )
    t0 = time.perf_counter()
    sch = design_run_up_schedule(
        model,
        b.bearing_number_at(args.target_rpm),
        margin=args.margin,
        rate=rate,
        start_bearing_number=None if args.start_rpm is None else b.bearing_number_at(args.start_rpm),
        damping_range=(dmin, dmax),
        n_dampings=args.n_dampings,
        fold_dampings=args.fold_dampings,
        hold_tau=args.hold,
    )
    ver = verify_schedule(sch, unbalance=unbalance)
    lin = None
    if unbalance is not None:  # the linear 1x orbit at the end speed, beside the measured one
        from gfb_env.analysis.response import unbalance_response

        lin = unbalance_response(model, sch.end_bearing_number, unbalance, sch.foil_damping, stability=False)

    rpm = sch.speed_rpm
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        sch.write_path_csv(out / "schedule.csv")
        sch.write_stability_curve_csv(out / "stability_curve.csv")
        sch.plot(out / "schedule.png")
    um = b.clearance_m * 1e6
    lam_end = sch.end_bearing_number
    verified_stable = ver.stable
    d = {
        "structure": "viscoelastic",
        "grid": str(model.grid),
        "foil_stiffness": float(model.foil_stiffness),
        "target_speed_rpm": args.target_rpm,
        "feasible": bool(sch.feasible),
        "foil_damping": sch.foil_damping,
        "critical_speed_rpm": rpm(sch.critical_bearing_number),
        "fold_speed_rpm": rpm(sch.fold_bearing_number),
        "max_safe_speed_rpm": rpm(sch.safe_bearing_number),
        "end_speed_rpm": rpm(lam_end),
        "start_speed_rpm": rpm(sch.start_bearing_number),
        "margin": sch.margin,
        "margin_to_critical": sch.margin_to_critical,
        "margin_to_fold": sch.margin_to_fold,
        "acceleration_rpm_s": args.acceleration,
        "ramp_time_s": b.seconds(sch.ramp_tau),
        "hold_time_s": b.seconds(sch.hold_tau),
        "verified_status": ver.status,
        "verified_stable": verified_stable,
        "verified_max_whirl_amplitude_um": ver.max_whirl_amplitude * um,
        "verified_min_film_thickness_um": ver.min_film_thickness * um,
        "verified_max_eccentricity_um": ver.max_eccentricity * um,
        "unbalance": ver.unbalance,
        "unbalance_um": 0.0 if unbalance is None else unbalance.eccentricity_um(b),
        "unbalance_g_mm": 0.0 if unbalance is None else unbalance.mass_radius_g_mm(b, args.rotor_mass_kg),
        "verified_1x_xi_um": ver.synchronous_xi * um,
        "verified_1x_eta_um": ver.synchronous_eta * um,
        "verified_max_vibration_amplitude_um": ver.max_vibration_amplitude * um,
        "linear_1x_xi_um": 0.0 if lin is None else lin.xi_amplitude * um,
        "linear_1x_eta_um": 0.0 if lin is None else lin.eta_amplitude * um,
        "notes": list(sch.notes),
        "files": {} if out is None else {k: str(out / k) for k in _FILES},
        "wall_time_s": time.perf_counter() - t0,
    }
    if out is not None:
        (out / "summary.json").write_text(jsonio.dumps(d, indent=2))
    if args.json:
        print(jsonio.dumps(d))
    else:
        verdict = "feasible" if sch.feasible else "INFEASIBLE"
        print(f"target {args.target_rpm:.0f} rpm: {verdict}; D_W = {sch.foil_damping:.3g}")
        print(
            f"  critical {d['critical_speed_rpm']:.0f} rpm, fold "
            f"{'-' if d['fold_speed_rpm'] is None else round(d['fold_speed_rpm'])} rpm, "
            f"max safe {d['max_safe_speed_rpm']:.0f} rpm; schedule ends at {d['end_speed_rpm']:.0f} rpm"
        )
        print(
            f"  verified: {'stable' if verified_stable else 'NOT STABLE'} ({ver.status}), whirl "
            f"{d['verified_max_whirl_amplitude_um']:.3g} um, "
            f"min film {d['verified_min_film_thickness_um']:.2f} um"
        )
        if unbalance is not None:
            print(
                f"  unbalance U = {ver.unbalance:.4g} ({d['unbalance_um']:.3g} um): the whirl above is the "
                f"non-synchronous part; 1x orbit x {d['verified_1x_xi_um']:.3g} um, y "
                f"{d['verified_1x_eta_um']:.3g} um (linear: {d['linear_1x_xi_um']:.3g}, "
                f"{d['linear_1x_eta_um']:.3g} um), total {d['verified_max_vibration_amplitude_um']:.3g} um"
            )
        for n in sch.notes:
            print(f"  note: {n}")
        print("  " + written_line(out and f"{out}/", d["wall_time_s"]))
    return 0 if verified_stable else 1
