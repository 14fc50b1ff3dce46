"""``gfb campbell``: the Campbell diagram and log decrement of the rotor whirl modes over speed.

Works on any bearing file (``--bearing``) and writes physical units by default (rpm, Hz, um),
nondimensional ones with ``--nondimensional``.  Every option is checked before any work: a bad value
is one line and exit code 2.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gfb_env import jsonio
from gfb_env.scripting import (
    add_model_options,
    add_out_option,
    add_speed_range_options,
    bearing_range_from_args,
    check_eigen_grid,
    int_range,
    model_from_args,
    optional_output_dir,
    written_line,
)

__all__ = ["cmd_campbell", "register"]

_FMT = argparse.RawDescriptionHelpFormatter
#: Default speed range of ``campbell`` in Lambda (Table 1: 6 000 - 72 000 rpm).
_CAMPBELL_LAMBDA = (0.1, 1.2)
_CAMPBELL_FILES = ("campbell.csv", "campbell.png", "summary.json")


def _eigen_model(args: argparse.Namespace):
    return check_eigen_grid(model_from_args(args))


def cmd_campbell(args: argparse.Namespace) -> int:
    """Handler of ``gfb campbell``."""
    from gfb_env.analysis.campbell import campbell_diagram

    out = optional_output_dir(args.out, "--out", _CAMPBELL_FILES)
    model = _eigen_model(args)
    b = model.bearing
    lo, hi = bearing_range_from_args(args, b, _CAMPBELL_LAMBDA)
    t0 = time.perf_counter()
    cd = campbell_diagram(model, np.linspace(lo, hi, args.n_speeds), args.foil_damping, args.modes)
    wall = time.perf_counter() - t0
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        cd.write_csv(out / "campbell.csv")
        cd.plot(out / "campbell.png", args.nondimensional)
    d = cd.summary()
    d["bearing_number_range"] = [lo, hi]
    d["speed_rpm_range"] = [b.speed_rpm_at(lo), b.speed_rpm_at(hi)]
    d["files"] = {} if out is None else {k: str(out / k) for k in _CAMPBELL_FILES}
    d["wall_time_s"] = wall
    if out is not None:
        (out / "summary.json").write_text(jsonio.dumps(d, indent=2))
    if args.json:
        print(jsonio.dumps(d))
    else:
        print(f"{cd.structure} foil, K_W={cd.foil_stiffness:.4g}, D_W={cd.foil_damping:.4g}, grid {cd.grid}")
        if cd.onset_bearing_number is None:
            print("  no zero crossing of the log decrement in the range")
        else:
            print(
                f"  onset (log decrement = 0): Lambda = {cd.onset_bearing_number:.5f}, "
                f"{cd.onset_speed_rpm:.0f} rpm, whirl {d['onset_frequency_hz']:.1f} Hz "
                f"({d['onset_whirl_frequency_ratio']:.3f} x)"
            )
        print("  " + written_line(out and ", ".join(d["files"].values()), wall))
    return 0


def register(subparsers) -> None:
    """Add ``campbell`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "campbell",
        formatter_class=_FMT,
        help="Campbell diagram and log decrement of the rotor whirl modes vs speed: CSV + PNG + JSON",
        description=(
            "Campbell diagram: at each speed the static equilibrium is solved and the eigenvalues and\n"
            "eigenvectors of the Jacobian are computed; the rotor-dominated modes are those with the\n"
            "largest share of the eigenvector in the rotor states (xi, eta, xi', eta') (see\n"
            "gfb_env.analysis.campbell).  Frequency f = Im(lambda)/(2 pi T) Hz, damping ratio\n"
            "zeta = -Re(lambda)/|lambda|, log decrement delta = -2 pi Re(lambda)/Im(lambda) (ROSS\n"
            "conventions).  The onset (delta = 0) is refined by Brent's method: it equals the critical\n"
            "speed of `gfb critical`.\n\n"
            "Writes OUT/campbell.csv (speed_rpm, bearing_number, mode, frequency_hz, angular_frequency,\n"
            "whirl_frequency_ratio, growth_rate, damping_ratio, log_decrement, rotor_participation,\n"
            "eccentricity), OUT/campbell.png (Campbell diagram with the 1x and 0.5x lines; log\n"
            "decrement with the critical speed) and OUT/summary.json.\n\n"
            "JSON keys: structure, grid, foil_stiffness, foil_damping, modes, n_speeds,\n"
            "bearing_number_range, speed_rpm_range, onset_bearing_number, onset_speed_rpm,\n"
            "onset_frequency_hz, onset_whirl_frequency_ratio, min_log_decrement,\n"
            "min_log_decrement_speed_rpm, equilibria_failed, files, wall_time_s."
        ),
    )
    add_model_options(p)
    add_speed_range_options(p, "Lambda 0.1 to 1.2 of the bearing; Table 1: 6 005 - 72 060 rpm")
    p.add_argument(
        "--n-speeds",
        type=int_range("--n-speeds", 3, 1000),
        default=45,
        metavar="N",
        help="number of equally spaced speeds, 3..1000 (default 45; ~0.1 s each on 79x7)",
    )
    p.add_argument(
        "--modes",
        type=int_range("--modes", 1, 6),
        default=2,
        metavar="K",
        help="rotor modes kept, 1..6 (default 2: the whirl mode and the second rotor mode)",
    )
    p.add_argument(
        "--nondimensional",
        action="store_true",
        help="plot over Lambda with angular frequencies per unit tau (default: rpm and Hz)",
    )
    add_out_option(p, _CAMPBELL_FILES)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_campbell)
