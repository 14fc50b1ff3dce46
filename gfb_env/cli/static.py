"""``gfb params``, ``gfb bearing``, ``gfb equilibrium``: the static commands (no time integration)."""

from __future__ import annotations

import argparse
import dataclasses

from gfb_env import jsonio
from gfb_env.equilibrium import equilibrium_summary, find_equilibrium
from gfb_env.scripting import (
    add_bearing_option,
    add_model_options,
    add_speed_options,
    bearing_number_from_args,
    friction_parameters,
    model_from_args,
    positive,
    print_table,
)

__all__ = ["cmd_bearing", "cmd_equilibrium", "cmd_params", "register"]


def cmd_params(args: argparse.Namespace) -> int:
    b = args.bearing
    speed = args.speed_rpm if args.speed_rpm is not None else b.speed_rpm
    out = {
        "time_scale_s": b.time_scale_s,
        "speed_rpm": speed,
        "bearing_number": b.bearing_number_at(speed),
        "mass_parameter": b.mass_parameter,
        "gravity_parameter": b.gravity_parameter,
        "load": b.mass_parameter * b.gravity_parameter,
        "foil_stiffness": b.foil_stiffness,
        "kappa": b.kappa,
        "clearance_um": b.clearance_m * 1e6,
        "force_scale_N": b.force_scale_n,
    }
    if args.json:
        print(jsonio.dumps(out))
    else:
        print_table(out)
    return 0


def cmd_bearing(args: argparse.Namespace) -> int:
    from gfb_env.bearing_report import bearing_report

    out = bearing_report(args.bearing, args.speed_rpm)
    out["parameters"] = args.bearing.as_dict()
    fr = args.bearing_friction
    if fr is not None:  # the file's [friction] table (only then: the plain bearing's output is unchanged)
        kw = args.bearing.foil_stiffness
        kt = fr.stick_stiffness(args.bearing, kw)
        out["friction"] = {**dataclasses.asdict(fr), "stick_stiffness": kw if kt is None else kt}
    if args.json:
        print(jsonio.dumps(out))
    else:
        print_table({k: v for k, v in out.items() if k not in ("warnings", "parameters", "friction")})
        for k, v in out.get("friction", {}).items():
            print(f"friction.{k}: {v}")
        for w in out["warnings"]:
            print(f"warning: {w}")
        if not out["warnings"]:
            print("no warnings (specific load, DellaCorte load capacity, C/R, surface speed)")
    return 0


def cmd_equilibrium(args: argparse.Namespace) -> int:
    model = model_from_args(args)
    lam = bearing_number_from_args(args, model.bearing)
    s = find_equilibrium(model, lam)
    out = equilibrium_summary(model, s, lam)
    out.update(friction_parameters(model))
    if args.json:
        print(jsonio.dumps(out))
    else:
        print_table(out)
    return 0


def register(subparsers) -> None:
    """Add ``params``, ``bearing`` and ``equilibrium`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "params",
        help="nondimensional parameters of the bearing (Table 1 by default)",
        description="Print the nondimensional groups of the bearing (--bearing FILE, default the "
        "paper's Table 1): time scale T, bearing number Lambda, M, G, K_W (Walowit-Anno), kappa = R/L.",
    )
    add_bearing_option(p)
    p.add_argument(
        "--speed-rpm",
        type=positive("--speed-rpm"),
        default=None,
        metavar="N",
        help="rotor speed for the bearing number (default: speed_rpm of the bearing, Table 1: 36 000)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=cmd_params)

    p = subparsers.add_parser(
        "bearing",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="design summary of a bearing file: groups, loads, sanity warnings",
        description=(
            "Read a bearing file (--bearing) and print its nondimensional groups (T, Lambda and Lambda\n"
            "per 1000 rpm, M, G, M G, K_W by Walowit-Anno, kappa = R/L), its load figures and warnings:\n"
            "  specific load   w = W/(L D), W = m g + F_L, D = 2R: warns above 34 kPa (5 psi, start-up\n"
            "                  load), 140 kPa (20 psi) and 340 kPa (50 psi) (Barber-Nichols foil-bearing\n"
            "                  application guide, barber-nichols.com);\n"
            "  load capacity   DellaCorte's rule of thumb W_max = D_c (L D)(D Omega) [lbf; in; krpm]\n"
            "                  with D_c = 0.1 lbf/(in^3 krpm) for first-generation bump foils (DellaCorte\n"
            "                  & Valco, Tribol. Trans. 43(4), 2000): warns when W > W_max;\n"
            "  clearance       C/R outside [5e-4, 5e-3] (usual for gas foil bearings);\n"
            "  surface speed   Omega R outside 30-305 m/s (Barber-Nichols guide).\n"
            "static_load_ratio = W / (p0 L D).\n\n"
            "JSON keys: speed_rpm, time_scale_s, bearing_number, bearing_number_per_1000_rpm,\n"
            "mass_parameter, gravity_parameter, load, foil_stiffness, kappa, static_load_n,\n"
            "specific_load_kpa, static_load_ratio, dellacorte_capacity_n, dellacorte_load_ratio,\n"
            "clearance_ratio, surface_speed_m_s, bump_pitch_m, warnings (list), parameters (the file's\n"
            "fields with Table-1 defaults filled in); friction (only for a file with a [friction] table:\n"
            "its keys and the nondimensional stick_stiffness K_T at the file's K_W)."
        ),
    )
    add_bearing_option(p)
    p.add_argument(
        "--speed-rpm",
        type=positive("--speed-rpm"),
        default=None,
        metavar="N",
        help="speed of the bearing number, load capacity and surface speed (default: the file's speed_rpm)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=cmd_bearing)

    p = subparsers.add_parser(
        "equilibrium",
        help="static equilibrium of the journal",
        description="Solve k(s0, Lambda) = 0 by Newton (load continuation from the centred "
        "journal) and report eccentricity, attitude angle, film and load balance.",
    )
    add_model_options(p)
    add_speed_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=cmd_equilibrium)
