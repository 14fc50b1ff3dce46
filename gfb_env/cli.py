"""The ``gfb`` command (also ``python -m gfb_env``): the simulator for engineers.

Subcommands: ``params`` (nondimensional groups of Table 1), ``equilibrium`` (static equilibrium),
``simulate`` (a transient run with CSV/PNG/JSON output) and, from :mod:`gfb_env.cli_analysis`,
the stability analysis commands.  Every subcommand has ``--help``.  Bad arguments give a one-line
error and exit code 2.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from gfb_env import jsonio
from gfb_env._cli_common import (
    OneLineParser,
    add_bearing_option,
    add_model_options,
    add_speed_options,
    add_start_options,
    add_unbalance_options,
    bearing_number_from_args,
    check_output_dir,
    model_from_args,
    positive,
    unbalance_from_args,
)
from gfb_env._threads import set_thread_defaults
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel

__all__ = ["main", "build_parser"]


_Parser = OneLineParser


def _print_table(rows: dict) -> None:
    width = max(len(k) for k in rows)
    for k, v in rows.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        elif isinstance(v, list):
            v = ", ".join(f"{x:.6g}" if isinstance(x, float) else str(x) for x in v)
        print(f"{k:<{width}}  {v}")


# ------------------------------------------------------------------------------------------------
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
        _print_table(out)
    return 0


def cmd_bearing(args: argparse.Namespace) -> int:
    from gfb_env.bearing_report import bearing_report

    out = bearing_report(args.bearing, args.speed_rpm)
    out["parameters"] = args.bearing.as_dict()
    if args.json:
        print(jsonio.dumps(out))
    else:
        _print_table({k: v for k, v in out.items() if k not in ("warnings", "parameters")})
        for w in out["warnings"]:
            print(f"warning: {w}")
        if not out["warnings"]:
            print("no warnings (specific load, DellaCorte load capacity, C/R, surface speed)")
    return 0


def equilibrium_summary(model: GFBModel, s: np.ndarray, bearing_number: float) -> dict:
    b = model.bearing
    force = model.bearing_force(s)
    eps = model.eccentricity(s)
    hmin = model.min_film_thickness(s)
    fmag = float(np.hypot(*force))
    return {
        "structure": model.structure.value,
        "grid": str(model.grid),
        "bearing_number": bearing_number,
        "speed_rpm": b.speed_rpm_at(bearing_number),
        "foil_stiffness": model.foil_stiffness,
        "eccentricity": eps,
        "attitude_angle_deg": math.degrees(model.attitude_angle(s)),
        "min_film_thickness": hmin,
        "max_pressure": float(model.layout.pressure(s).max()),
        "bearing_force": fmag,
        "load": model.load,
        "eccentricity_um": b.micrometres(eps),
        "min_film_thickness_um": b.micrometres(hmin),
        "bearing_force_N": b.newtons(fmag),
    }


def cmd_equilibrium(args: argparse.Namespace) -> int:
    model = model_from_args(args)
    lam = bearing_number_from_args(args, model.bearing)
    s = find_equilibrium(model, lam)
    out = equilibrium_summary(model, s, lam)
    if args.json:
        print(jsonio.dumps(out))
    else:
        _print_table(out)
    return 0


def whirl_frequency_ratio(signal: np.ndarray, sample_interval: float, bearing_number: float) -> float | None:
    """Dominant whirl frequency / Lambda from the FFT of the last 30 % of ``signal`` (None if flat)."""
    from gfb_env.analysis.spectrum import dominant_frequency

    try:
        return dominant_frequency(signal, sample_interval, fraction=0.3, bearing_number=bearing_number).ratio
    except ValueError:
        return None


#: A developed whirl takes about 40 accepted steps per unit tau (measured: 73 449 steps for tau = 2000
#: at Lambda = 1.5 on 79x7), and the integrator stops at ``max_steps`` = 10 000 000 steps; so
#: ``--duration`` is limited to 10e6 / 40 = 250 000 (40 s of rotor time; ~5 min of wall time at
#: 28 us/step on 79x7, longer on finer grids).
MAX_DURATION = 250_000.0
#: At most this many output samples (``--duration / --record-interval``): the record buffer and the
#: CSV (~90 bytes a row) stay below ~100 MB.
MAX_SAMPLES = 1_000_000
_SIMULATE_FILES = ("trajectory.csv", "summary.json", "simulation.png")


def check_simulate_args(args: argparse.Namespace) -> Path:
    """The checks of ``simulate`` that need no model (run before any computation); the output folder."""
    if args.duration > MAX_DURATION:
        raise ValueError(
            f"--duration {args.duration:g} is too long: at most {MAX_DURATION:g} (a whirl takes ~40 "
            "steps per tau and the integrator stops after 10 000 000 steps)"
        )
    n_samples = args.duration / args.record_interval
    if n_samples > MAX_SAMPLES:
        raise ValueError(
            f"--record-interval {args.record_interval:g} gives {n_samples:.3g} samples over --duration "
            f"{args.duration:g}, at most {MAX_SAMPLES} "
            f"(--record-interval >= {args.duration / MAX_SAMPLES:.3g})"
        )
    return check_output_dir(args.out, "--out", _SIMULATE_FILES)


def check_perturbation(
    model: GFBModel, s_eq: np.ndarray, perturbation: list[float], touchdown: float
) -> None:
    """Refuse (``ValueError`` naming ``--perturbation``) a displacement of the journal from the
    equilibrium ``s_eq`` after which the film is not thicker than ``touchdown`` everywhere.

    The film is linear in the displacement: ``H_i(t) = H_i - t (d_xi sin phi_i + d_eta cos phi_i)``
    for the unit direction ``d``, so the largest allowed step along ``d`` is exact."""
    p = np.asarray(perturbation, dtype=float)
    size = float(np.hypot(*p))
    if size == 0.0:
        return
    d = p / size
    H = model.film_thickness(s_eq)
    rate = d[0] * np.sin(model.grid.phi) + d[1] * np.cos(model.grid.phi)
    closing = rate > 0
    t_max = float(np.min((H[closing] - touchdown) / rate[closing])) if closing.any() else math.inf
    if size < t_max:
        return
    hmin = float(np.min(H - size * rate))
    raise ValueError(
        f"--perturbation {p[0]:g} {p[1]:g} leaves a min film thickness of {hmin:.3g} at the start; in "
        f"this direction the journal may move less than {t_max:.3g} from its equilibrium to keep the "
        f"film above --touchdown {touchdown:g}"
    )


def cmd_simulate(args: argparse.Namespace) -> int:
    from gfb_env._plotting import plot_simulation  # matplotlib only when needed

    out_dir = check_simulate_args(args)
    model = model_from_args(args)
    lam = bearing_number_from_args(args, model.bearing)
    unbalance = unbalance_from_args(args, model.bearing, model.bearing.speed_rpm_at(lam))
    layout = model.layout
    if args.start == "centre":
        s0 = layout.centred_state()
    else:
        s_eq = find_equilibrium(model, lam)
        check_perturbation(model, s_eq, args.perturbation, args.touchdown)
        s0 = layout.with_rotor(s_eq, *(layout.rotor(s_eq)[:2] + np.array(args.perturbation)), 0.0, 0.0)
    probe = np.array([layout.pressure_index(0, model.grid.midplane_row)])
    integ = TrapezoidalIntegrator(
        model, s0, lam, args.foil_damping, touchdown_film_thickness=args.touchdown, unbalance=unbalance
    )
    dt_rec = args.record_interval
    t0 = time.perf_counter()
    res = integ.advance(args.duration, record_interval=dt_rec, record_indices=probe, raise_on_failure=False)
    wall = time.perf_counter() - t0
    tr = res.trajectory
    out_dir.mkdir(parents=True, exist_ok=True)
    header = "tau,xi,eta,bearing_number,foil_damping,min_film_thickness,pressure_phi0_z0"
    data = np.column_stack(
        [tr.tau, tr.xi, tr.eta, tr.bearing_number, tr.foil_damping, tr.min_film_thickness, tr.probes[:, 0]]
    )
    np.savetxt(out_dir / "trajectory.csv", data, delimiter=",", header=header, comments="", fmt="%.8g")
    summary = {
        "structure": model.structure.value,
        "grid": str(model.grid),
        "bearing_number": lam,
        "speed_rpm": model.bearing.speed_rpm_at(lam),
        "foil_stiffness": model.foil_stiffness,
        "foil_damping": args.foil_damping,
        "unbalance": 0.0 if unbalance is None else unbalance.magnitude,
        "unbalance_g_mm": 0.0
        if unbalance is None
        else unbalance.mass_radius_g_mm(model.bearing, args.rotor_mass_kg),
        "duration": float(res.tau),
        "duration_s": model.bearing.seconds(res.tau),
        "status": res.status,
        "message": res.message,
        "max_eccentricity": float(res.max_eccentricity),
        "max_eccentricity_um": model.bearing.micrometres(res.max_eccentricity),
        "min_film_thickness": float(res.min_film_thickness),
        "min_film_thickness_um": model.bearing.micrometres(res.min_film_thickness),
        "whirl_frequency_ratio": whirl_frequency_ratio(tr.xi, dt_rec, lam),
        "touchdown": res.touchdown is not None,
        "touchdown_tau": None if res.touchdown is None else res.touchdown.tau,
        "steps": res.steps,
        "wall_time_s": wall,
    }
    (out_dir / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    plot_simulation(
        tr,
        out_dir / "simulation.png",
        title=f"{model.structure.value}, Lambda={lam:.4g}, "
        f"K_W={model.foil_stiffness:.3g}, D_W={args.foil_damping:.3g}",
    )
    if args.json:
        print(jsonio.dumps(summary))
    else:
        _print_table({k: v for k, v in summary.items() if v is not None and v != ""})
        print(f"wrote {out_dir / 'trajectory.csv'}, {out_dir / 'simulation.png'}, {out_dir / 'summary.json'}")
    return 0 if res.ok else 1


# ------------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="gfb",
        description="Gas foil bearing rotor simulator (Leister, Baum & Seemann 2017). All quantities are "
        "nondimensional as in the paper unless the name ends in a unit (_rpm, _um, _N, _s).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser(
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

    p = sub.add_parser(
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
            "fields with Table-1 defaults filled in)."
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

    p = sub.add_parser(
        "equilibrium",
        help="static equilibrium of the journal",
        description="Solve k(s0, Lambda) = 0 by Newton (load continuation from the centred "
        "journal) and report eccentricity, attitude angle, film and load balance.",
    )
    add_model_options(p)
    add_speed_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=cmd_equilibrium)

    p = sub.add_parser(
        "simulate",
        help="transient simulation at constant speed",
        description="Integrate the coupled model with the adaptive trapezoidal rule and "
        "write trajectory.csv, simulation.png (orbit and time series) and summary.json. With an unbalance "
        "(--unbalance, --unbalance-g-mm or --balance-grade) the rotor carries it from tau = 0.",
    )
    add_model_options(p)
    add_speed_options(p)
    p.add_argument(
        "--duration",
        type=positive("--duration"),
        required=True,
        metavar="TAU",
        help="simulated nondimensional time (tau = t / T, T = 1.59e-4 s for Table 1); at most 250000",
    )
    p.add_argument(
        "--start",
        choices=["centre", "equilibrium"],
        default="equilibrium",
        help="initial state: the centred journal at ambient pressure, or the static "
        "equilibrium displaced by --perturbation. Default: %(default)s",
    )
    add_start_options(p)
    p.add_argument(
        "--record-interval",
        type=positive("--record-interval"),
        default=0.25,
        metavar="DTAU",
        help="sampling interval of the output (tau). Default: %(default)s",
    )
    add_unbalance_options(p)
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_simulate)

    try:
        from gfb_env.cli_analysis import add_analysis_commands
    except ImportError:  # analysis layer not installed
        pass
    else:
        add_analysis_commands(sub)
        from gfb_env.cli_engineering import add_engineering_commands

        add_engineering_commands(sub)
        from gfb_env.cli_schedule import add_schedule_command

        add_schedule_command(sub)
        from gfb_env.cli_response import add_response_command

        add_response_command(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    set_thread_defaults()  # for the sweep workers this command may start (see gfb_env._threads)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError as exc:
        print(f"gfb {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # e.g. the disk filled up while writing: the outputs were checked up front
        print(f"gfb {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # the solver reports, never a traceback for a user error
        if type(exc).__name__ in ("EquilibriumError", "IntegrationError"):
            print(f"gfb {args.command}: error: {exc}", file=sys.stderr)
            return 1
        raise


if __name__ == "__main__":
    raise SystemExit(main())
