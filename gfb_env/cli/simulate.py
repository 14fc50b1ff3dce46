"""``gfb simulate``: a transient run at constant speed (trajectory CSV, figure, JSON summary)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from gfb_env import jsonio
from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.scripting import (
    MAX_DURATION,
    MAX_SAMPLES,
    add_model_options,
    add_out_option,
    add_speed_options,
    add_start_options,
    add_unbalance_options,
    bearing_number_from_args,
    check_perturbation,
    model_from_args,
    optional_output_dir,
    positive,
    print_table,
    unbalance_from_args,
)

__all__ = ["check_simulate_args", "cmd_simulate", "register", "whirl_frequency_ratio"]


def whirl_frequency_ratio(signal: np.ndarray, sample_interval: float, bearing_number: float) -> float | None:
    """Dominant whirl frequency / Lambda from the FFT of the last 30 % of ``signal`` (None if flat)."""
    from gfb_env.analysis.spectrum import dominant_frequency

    try:
        return dominant_frequency(signal, sample_interval, fraction=0.3, bearing_number=bearing_number).ratio
    except ValueError:
        return None


_SIMULATE_FILES = ("trajectory.csv", "summary.json", "simulation.png")


def check_simulate_args(args: argparse.Namespace) -> Path | None:
    """The checks of ``simulate`` that need no model (run before any computation); the output folder
    (None without ``--out``)."""
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
    return optional_output_dir(args.out, "--out", _SIMULATE_FILES)


def cmd_simulate(args: argparse.Namespace) -> int:
    from gfb_env.plotting import plot_simulation  # matplotlib only when needed

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
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        header = "tau,xi,eta,bearing_number,foil_damping,min_film_thickness,pressure_phi0_z0"
        data = np.column_stack(
            [
                tr.tau,
                tr.xi,
                tr.eta,
                tr.bearing_number,
                tr.foil_damping,
                tr.min_film_thickness,
                tr.probes[:, 0],
            ]
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
    if out_dir is not None:
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
        print_table({k: v for k, v in summary.items() if v is not None and v != ""})
        if out_dir is not None:
            print("wrote " + ", ".join(str(out_dir / f) for f in _SIMULATE_FILES))
        else:
            print("no files written (--out DIR)")
    return 0 if res.ok else 1


def register(subparsers) -> None:
    """Add ``simulate`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
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
    add_out_option(p, _SIMULATE_FILES)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_simulate)
