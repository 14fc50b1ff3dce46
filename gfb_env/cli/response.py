"""``gfb response``: the unbalance response (Bode plot and orbit axes) from the linearised model.

Every option is checked before any work: a bad value is one line and exit code 2 (``ValueError`` from
the handler, turned into exit 2 by :func:`gfb_env.cli.main`).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gfb_env import jsonio
from gfb_env.analysis.response import ResponseCurve
from gfb_env.scripting import (
    add_model_options,
    add_out_option,
    add_speed_range_options,
    add_unbalance_options,
    bearing_range_from_args,
    check_eigen_grid,
    int_range,
    model_from_args,
    optional_output_dir,
    positive,
    unbalance_from_args,
    written_line,
)

__all__ = ["register", "cmd_response"]

_FILES = ("response.csv", "response.png", "summary.json")
#: Default speed range in Lambda (Table 1: 6 000 - 60 000 rpm).
_LAMBDA_RANGE = (0.1, 1.0)
_COLUMNS = ResponseCurve.COLUMNS


def cmd_response(args: argparse.Namespace) -> int:
    """Handler of ``gfb response``."""
    from gfb_env.analysis.response import response_curve, transient_synchronous_orbit, unbalance_response

    out = optional_output_dir(args.out, "--out", _FILES)
    model = check_eigen_grid(model_from_args(args))
    b = model.bearing
    lo, hi = bearing_range_from_args(args, b, _LAMBDA_RANGE)
    point = None
    if args.bearing_number is not None:
        point = float(args.bearing_number)
    elif args.speed_rpm is not None:
        point = b.bearing_number_at(args.speed_rpm)
    # the balance grade is specified at the maximum service speed: the point, else the top of the range
    grade_lam = point if point is not None else hi
    unbalance = unbalance_from_args(args, b, b.speed_rpm_at(grade_lam))
    if unbalance.magnitude == 0.0:
        raise ValueError("--unbalance must be positive for a response")
    t0 = time.perf_counter()
    # the requested point first: an unstable one refuses --verify before the curve is computed
    at = None if point is None else unbalance_response(model, point, unbalance, args.foil_damping)
    if args.verify and at is not None and not at.stable:
        raise ValueError(
            f"--verify: the equilibrium at Lambda={at.bearing_number:.4g} is unstable (max Re(lambda) = "
            f"{at.growth_rate:.3g}); the transient has no synchronous steady orbit there"
        )
    lams = np.linspace(lo, hi, args.n_speeds)
    curve = response_curve(model, lams, unbalance, args.foil_damping)
    if at is None:
        at = curve.peak
    verify = None
    if args.verify:
        if not at.stable:
            raise ValueError(
                f"--verify: the equilibrium at Lambda={at.bearing_number:.4g} is unstable (max Re(lambda) = "
                f"{at.growth_rate:.3g}); the transient has no synchronous steady orbit there"
            )
        orb = transient_synchronous_orbit(model, at.bearing_number, unbalance, args.foil_damping)
        verify = orb.compare(at)
    wall = time.perf_counter() - t0
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        curve.write_csv(out / "response.csv")
        curve.plot(at, out / "response.png")
    d = {
        "structure": model.structure.value,
        "grid": str(model.grid),
        "foil_stiffness": model.foil_stiffness,
        "foil_damping": args.foil_damping,
        "unbalance": unbalance.magnitude,
        "unbalance_g_mm": unbalance.mass_radius_g_mm(b, args.rotor_mass_kg),
        "unbalance_eccentricity_um": unbalance.eccentricity_um(b),
        "bearing_number": at.bearing_number,
        "speed_rpm": b.speed_rpm_at(at.bearing_number),
        "at_peak": point is None,
        "xi_amplitude": at.xi_amplitude,
        "eta_amplitude": at.eta_amplitude,
        "xi_phase_deg": at.xi_phase_deg,
        "eta_phase_deg": at.eta_phase_deg,
        "semi_major": at.semi_major,
        "semi_minor": at.semi_minor,
        "forward": at.forward,
        "stable": at.stable,
        "xi_amplitude_um": b.micrometres(at.xi_amplitude),
        "eta_amplitude_um": b.micrometres(at.eta_amplitude),
        "semi_major_um": b.micrometres(at.semi_major),
        "semi_minor_um": b.micrometres(at.semi_minor),
        "bearing_number_range": [lo, hi],
        "speed_rpm_range": [b.speed_rpm_at(lo), b.speed_rpm_at(hi)],
        "n_speeds": len(curve),
        "first_unstable_bearing_number": curve.first_unstable_bearing_number,
        "verify": verify,
        "files": {} if out is None else {k: str(out / k) for k in _FILES},
        "wall_time_s": wall,
    }
    if out is not None:
        (out / "summary.json").write_text(jsonio.dumps(d, indent=2))
    if args.json:
        print(jsonio.dumps(d))
    else:
        where = "peak of the stable range" if point is None else "requested speed"
        print(
            f"unbalance U = {unbalance.magnitude:.4g} ({d['unbalance_g_mm']:.4g} g mm); at Lambda = "
            f"{at.bearing_number:.4g} ({d['speed_rpm']:.0f} rpm, {where}):"
        )
        print(
            f"  xi {at.xi_amplitude:.4g} C ({d['xi_amplitude_um']:.3g} um), eta {at.eta_amplitude:.4g} C "
            f"({d['eta_amplitude_um']:.3g} um), orbit {at.semi_major:.4g} x {at.semi_minor:.4g} C, "
            f"{'forward' if at.forward else 'backward'}{'' if at.stable else ' (UNSTABLE equilibrium)'}"
        )
        if verify:
            print(
                f"  transient check: xi error {verify['xi_relative_error']:.2%}, eta error "
                f"{verify['eta_relative_error']:.2%}"
            )
        print("  " + written_line(out and ", ".join(d["files"].values()), wall))
    return 0


def register(subparsers) -> None:
    """Add ``response`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "response",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="unbalance response (Bode plot, orbit axes) from the linearised model: CSV + PNG + JSON",
        description=(
            "Linear unbalance response: at each speed the static equilibrium is solved and\n"
            "(i Lambda I - J) z = b is solved for the synchronous orbit, b the unbalance forcing\n"
            "U Lambda^2 (sin theta, cos theta) in the rotor acceleration rows (gfb_env.analysis.response).\n"
            "Valid below the critical speed (flagged unstable above it).  Amplitudes are zero-to-peak\n"
            "in units of C (and um); phases are the lag behind the unbalance force in the same direction.\n\n"
            "Writes OUT/response.csv (one row per speed: " + ", ".join(_COLUMNS) + "),\n"
            "OUT/response.png (amplitude and phase of xi and eta vs rpm, orbit semi-axes) and\n"
            "OUT/summary.json.  The scalar keys are at --speed-rpm / --bearing-number when given, else at\n"
            "the largest stable orbit of the range (at_peak true).\n\n"
            "JSON keys: structure, grid, foil_stiffness, foil_damping, unbalance, unbalance_g_mm,\n"
            "unbalance_eccentricity_um, bearing_number, speed_rpm, at_peak, xi_amplitude, eta_amplitude,\n"
            "xi_phase_deg, eta_phase_deg, semi_major, semi_minor, forward, stable, xi_amplitude_um,\n"
            "eta_amplitude_um, semi_major_um, semi_minor_um, bearing_number_range, speed_rpm_range,\n"
            "n_speeds, first_unstable_bearing_number, verify (with --verify: the transient's xi_amplitude,\n"
            "eta_amplitude, xi_relative_error, eta_relative_error, residual_rms; else null), files,\n"
            "wall_time_s."
        ),
    )
    add_model_options(p)
    add_unbalance_options(p, required=True)
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--bearing-number", type=positive("--bearing-number"), metavar="LAMBDA", help="evaluation speed"
    )
    g.add_argument("--speed-rpm", type=positive("--speed-rpm"), metavar="N", help="evaluation speed in rpm")
    add_speed_range_options(
        p, "Lambda 0.1 to 1.0 of the bearing; Table 1: 6 005 - 60 050 rpm", "the same in Lambda"
    )
    p.add_argument(
        "--n-speeds",
        type=int_range("--n-speeds", 2, 1000),
        default=46,
        metavar="N",
        help="number of equally spaced speeds, 2..1000 (default 46; ~0.1 s each on 79x7)",
    )
    p.add_argument(
        "--verify",
        action="store_true",
        help="also run the transient at the evaluation speed (from the equilibrium, unbalance on at tau = 0, "
        "settled for 10 decay times) and report its synchronous orbit's error against the linear one",
    )
    add_out_option(p, _FILES)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_response)
