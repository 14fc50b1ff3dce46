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
    add_model_options,
    add_speed_options,
    bearing_number_from_args,
    model_from_args,
    positive,
)
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters

__all__ = ["main", "build_parser"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit code 2
        self.exit(2, f"{self.prog}: error: {message}\n")


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
    b = BearingParameters()
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


def cmd_simulate(args: argparse.Namespace) -> int:
    from gfb_env._plotting import plot_simulation  # matplotlib only when needed

    model = model_from_args(args)
    lam = bearing_number_from_args(args, model.bearing)
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ValueError(f"--duration must be positive, got {args.duration}")
    layout = model.layout
    if args.start == "centre":
        s0 = layout.centred_state()
    else:
        s0 = find_equilibrium(model, lam)
        s0 = layout.with_rotor(s0, *(layout.rotor(s0)[:2] + np.array(args.perturbation)), 0.0, 0.0)
    probe = np.array([layout.pressure_index(0, model.grid.midplane_row)])
    integ = TrapezoidalIntegrator(model, s0, lam, args.foil_damping, touchdown_film_thickness=args.touchdown)
    dt_rec = args.record_interval
    t0 = time.perf_counter()
    res = integ.advance(args.duration, record_interval=dt_rec, record_indices=probe, raise_on_failure=False)
    wall = time.perf_counter() - t0
    tr = res.trajectory
    out_dir = Path(args.out)
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
        help="nondimensional parameters of Table 1",
        description="Print the nondimensional groups of the paper's Table 1 bearing: time "
        "scale T, bearing number Lambda, M, G, K_W (Walowit-Anno), kappa = R/L.",
    )
    p.add_argument(
        "--speed-rpm",
        type=positive("--speed-rpm"),
        default=None,
        metavar="N",
        help="rotor speed for the bearing number (default: 36 000 rpm of Table 1)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=cmd_params)

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
        "write trajectory.csv, simulation.png (orbit and time series) and summary.json.",
    )
    add_model_options(p)
    add_speed_options(p)
    p.add_argument(
        "--duration",
        type=positive("--duration"),
        required=True,
        metavar="TAU",
        help="simulated nondimensional time (tau = t / T, T = 1.59e-4 s for Table 1)",
    )
    p.add_argument(
        "--start",
        choices=["centre", "equilibrium"],
        default="equilibrium",
        help="initial state: the centred journal at ambient pressure, or the static "
        "equilibrium displaced by --perturbation. Default: %(default)s",
    )
    p.add_argument(
        "--perturbation",
        type=float,
        nargs=2,
        default=[0.01, 0.0],
        metavar=("DXI", "DETA"),
        help="displacement of the journal from equilibrium (units of C). Default: 0.01 0",
    )
    p.add_argument(
        "--record-interval",
        type=positive("--record-interval"),
        default=0.25,
        metavar="DTAU",
        help="sampling interval of the output (tau). Default: %(default)s",
    )
    p.add_argument(
        "--touchdown",
        type=float,
        default=0.01,
        metavar="HMIN",
        help="min film thickness that counts as touchdown (units of C). Default: %(default)s",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_simulate)

    try:
        from gfb_env.cli_analysis import add_analysis_commands
    except ImportError:  # analysis layer not installed
        pass
    else:
        add_analysis_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError as exc:
        print(f"gfb {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # the solver reports, never a traceback for a user error
        if type(exc).__name__ in ("EquilibriumError", "IntegrationError"):
            print(f"gfb {args.command}: error: {exc}", file=sys.stderr)
            return 1
        raise


if __name__ == "__main__":
    raise SystemExit(main())
