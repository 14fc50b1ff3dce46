"""Analysis subcommands of the ``gfb`` CLI: ``critical``, ``hysteresis``, ``map``.

:func:`gfb_env.cli.build_parser` calls :func:`register` on its subparsers object; each
subcommand sets ``func=handler`` where ``handler(args) -> int`` returns the exit code.  Invalid input
raises :class:`ValueError` with a one-line message (``main`` turns it into an error and exit code 2).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from gfb_env import jsonio
from gfb_env.params import BearingParameters
from gfb_env.scripting import (
    add_bearing_option,
    add_model_options,
    add_out_option,
    check_eigen_grid,
    float_list,
    friction_parameters,
    grid_type,
    int_range,
    model_from_args,
    optional_output_dir,
    positive,
)

__all__ = ["register", "cmd_critical", "cmd_hysteresis", "cmd_map"]

_FMT = argparse.RawDescriptionHelpFormatter
#: Largest ``--n-steps``: the shooting sweep keeps the Jacobian and its factors per step in block form
#: (0.18 MB a step on 79x7, 1.3 MB on 157x13), so 2000 steps hold 0.4 GB / 2.6 GB.
MAX_SHOOTING_STEPS = 2000


def _add_common(p: argparse.ArgumentParser) -> None:
    add_model_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _check_scan(args: argparse.Namespace) -> None:
    """``--bearing-range`` and ``--scan-step``, checked with the option names before any work."""
    from gfb_env.analysis.stability import MAX_SCAN_POINTS

    lo, hi = args.bearing_range
    if not 0 < lo < hi:
        raise ValueError(f"--bearing-range must satisfy 0 < MIN < MAX, got {lo:g} {hi:g}")
    n_scan = (hi - lo) / args.scan_step + 1
    if n_scan > MAX_SCAN_POINTS:
        raise ValueError(
            f"--scan-step {args.scan_step:g} gives {n_scan:.3g} scan points over --bearing-range "
            f"{lo:g} {hi:g}, at most {MAX_SCAN_POINTS} "
            f"(--scan-step >= {(hi - lo) / (MAX_SCAN_POINTS - 1):.3g})"
        )


def _analysis_model(args: argparse.Namespace):
    """The model, refused (exit 2) before any work when the dense eigen-analysis would be too large."""
    _check_scan(args)
    return check_eigen_grid(model_from_args(args))


def _critical(args, model):
    from gfb_env.analysis.stability import StabilityAnalysisError, critical_bearing_number

    lo, hi = args.bearing_range
    try:
        return critical_bearing_number(model, args.foil_damping, (lo, hi), args.scan_step)
    except StabilityAnalysisError as exc:
        raise ValueError(str(exc)) from None


def _frictional_definition(args: argparse.Namespace) -> dict[str, str]:
    """What the frictional foil's Lambda_c refers to (:func:`critical_bearing_number`'s defaults)."""
    from gfb_env.analysis.stability import SPINUP_STEP

    return {
        "equilibrium_history": (
            f"quasi-static spin-up from Lambda={args.bearing_range[0]:g} in steps of {SPINUP_STEP:g}"
        ),
        "sliders_on_limit": "stick",
    }


def cmd_critical(args: argparse.Namespace) -> int:
    """Handler of ``gfb critical``."""
    model = _analysis_model(args)
    t0 = time.perf_counter()
    cp = _critical(args, model)
    d = cp.as_dict()
    d["wall_time_s"] = time.perf_counter() - t0
    friction = friction_parameters(model)
    d.update(friction)
    if friction:
        d.update(_frictional_definition(args))
    if args.json:
        print(jsonio.dumps(d))
    else:
        print(f"{cp.structure} foil, K_W={cp.foil_stiffness:.4g}, D_W={cp.foil_damping:.4g}, grid {cp.grid}")
        if friction:
            print("  " + ", ".join(f"{k}={v:.4g}" for k, v in friction.items()))
            print(f"  equilibria: {d['equilibrium_history']}; sliders on their limit held")
        print(f"  critical bearing number  Lambda_c = {cp.critical_bearing_number:.5f}")
        print(f"  critical speed                   = {cp.critical_speed_rpm:.0f} rpm")
        print(f"  whirl frequency ratio Im/Lambda  = {cp.whirl_frequency_ratio:.4f}")
        print(f"  eccentricity at onset            = {cp.eccentricity_at_onset:.4f}")
        print(f"  crossing speed dRe/dLambda       = {cp.crossing_speed:.4f}")
        print(f"  ({cp.evaluations} eigenvalue solves, {d['wall_time_s']:.2f} s)")
    return 0


def cmd_hysteresis(args: argparse.Namespace) -> int:
    """Handler of ``gfb hysteresis``."""
    from gfb_env.analysis.periodic import ShootingError, coast_down_fold, fold_bearing_number

    model = _analysis_model(args)
    t0 = time.perf_counter()
    cp = _critical(args, model)
    d = cp.as_dict()
    friction = friction_parameters(model)
    d.update(friction)
    if friction:
        d.update(_frictional_definition(args))
    try:
        fr = fold_bearing_number(
            model,
            args.foil_damping,
            critical=cp.critical_bearing_number,
            n_steps=args.n_steps,
            progress=not args.json,
        )
    except ShootingError as exc:  # a computation failure, not bad input: exit 1 (2 is for bad input)
        print(f"gfb hysteresis: error: no limit cycle could be computed: {exc}", file=sys.stderr)
        return 1
    d.update(
        {
            "fold_bearing_number": fr.fold_bearing_number,
            "fold_speed_rpm": (
                model.bearing.speed_rpm_at(fr.fold_bearing_number)
                if fr.fold_bearing_number is not None
                else None
            ),
            "limit_cycle_amplitude_at_critical": fr.amplitude_at_critical,
            "limit_cycle_max_eccentricity_at_critical": fr.max_eccentricity_at_critical,
            "whirl_period_at_critical": fr.period_at_critical,
            "subcritical": fr.subcritical,
            "contact_bearing_number": fr.contact_bearing_number,
            "band_lower_bearing_number": fr.band_lower_bearing_number,
            "continuation_message": fr.message,
        }
    )
    if args.coast_down:
        try:
            cd = coast_down_fold(
                model, args.foil_damping, cp.critical_bearing_number + 0.01, progress=not args.json
            )
            d["coast_down_fold_bearing_number"] = cd.fold_bearing_number
        except ShootingError as exc:
            d["coast_down_fold_bearing_number"] = None
            d["coast_down_message"] = str(exc)
    d["wall_time_s"] = time.perf_counter() - t0
    if args.json:
        print(jsonio.dumps(d))
    else:
        lf = d["fold_bearing_number"]
        print(f"{cp.structure} foil, K_W={cp.foil_stiffness:.4g}, D_W={cp.foil_damping:.4g}, grid {cp.grid}")
        if friction:
            print("  " + ", ".join(f"{k}={v:.4g}" for k, v in friction.items()))
            print(f"  equilibria: {d['equilibrium_history']}; sliders on their limit held")
        print(
            f"  Hopf point       Lambda_c    = {cp.critical_bearing_number:.5f} "
            f"({cp.critical_speed_rpm:.0f} rpm)"
        )
        print(
            "  fold of cycles   Lambda_fold = "
            + ("not found" if lf is None else f"{lf:.5f} ({d['fold_speed_rpm']:.0f} rpm)")
        )
        if lf is not None or fr.contact_bearing_number is not None:
            lo = fr.band_lower_bearing_number
            kind = "subcritical: bistable band" if lo < cp.critical_bearing_number else "no hysteresis"
            print(f"  {kind} [{lo:.4f}, {cp.critical_bearing_number:.4f}]")
        print(
            f"  limit cycle at Lambda_c: amplitude {fr.amplitude_at_critical:.4f}, "
            f"max eps {fr.max_eccentricity_at_critical:.4f}, period {fr.period_at_critical:.3f}"
        )
        if "coast_down_fold_bearing_number" in d:
            print(f"  coast-down estimate of Lambda_fold = {d['coast_down_fold_bearing_number']}")
        print(f"  continuation: {fr.message}")
        print(f"  ({d['wall_time_s']:.1f} s)")
    return 0


#: At most this many Lambda_c searches in one ``gfb map`` (K x D viscoelastic + K elastic + 1 rigid):
#: ~5 s each on 79x7, so 1000 is ~1.4 h on one core; larger sweeps belong in a script or on a cluster.
MAX_MAP_SOLVES = 1000
_MAP_FILES = ("sweep.jsonl", "stability_map.csv", "optimum_damping.csv", "stability_map.png")


def cmd_map(args: argparse.Namespace) -> int:
    """Handler of ``gfb map``."""
    from gfb_env.analysis.maps import compute_stability_map, write_stability_map
    from gfb_env.model import GFBModel

    out = optional_output_dir(args.out, "--out", _MAP_FILES)
    kws = float_list(args.foil_stiffness, "--foil-stiffness")
    dws = float_list(args.foil_damping, "--foil-damping")
    n_solves = len(kws) * len(dws) + len(kws) + 1
    if n_solves > MAX_MAP_SOLVES:
        raise ValueError(
            f"--foil-stiffness x --foil-damping asks for {n_solves} Lambda_c searches, at most "
            f"{MAX_MAP_SOLVES} (each takes ~5 s on 79x7)"
        )
    cpus = os.cpu_count() or 1
    if args.scheduler is None and not (args.n_jobs == -1 or 1 <= args.n_jobs <= cpus):
        raise ValueError(
            f"--n-jobs must be -1 or lie in [1, {cpus}] (this machine's cores), got {args.n_jobs}"
        )
    # the largest model of the map (viscoelastic) must fit the dense eigen-analysis
    check_eigen_grid(GFBModel("viscoelastic", args.grid, bearing=args.bearing))
    t0 = time.perf_counter()
    smap = compute_stability_map(
        kws,
        dws,
        grid=str(args.grid),
        n_jobs=args.n_jobs,
        scheduler=args.scheduler,
        checkpoint=None if out is None else out / "sweep.jsonl",
        progress=not args.json,
        bearing=None if args.bearing == BearingParameters() else args.bearing,
    )
    paths = {} if out is None else write_stability_map(smap, out)
    d = {
        "out": None if out is None else str(out),
        "files": {k: str(v) for k, v in paths.items()},
        "rigid_critical_bearing_number": smap.rigid,
        "foil_stiffness": kws,
        "elastic_critical_bearing_number": [None if not np.isfinite(x) else float(x) for x in smap.elastic],
        "optimum_foil_damping": [None if not np.isfinite(x) else float(x) for x in smap.optimum_damping],
        "max_critical_bearing_number": [
            None if not np.isfinite(x) else float(x) for x in smap.optimum_critical
        ],
        "wall_time_s": time.perf_counter() - t0,
    }
    if args.json:
        print(jsonio.dumps(d))
    else:
        print(f"rigid Lambda_c = {smap.rigid:.5f}")
        for k, e, dopt, lmax in zip(kws, smap.elastic, smap.optimum_damping, smap.optimum_critical):
            print(
                f"K_W={k:8.4g}: elastic Lambda_c={e:.5f}  "
                f"viscoelastic max Lambda_c={lmax:.5f} at D_W*={dopt:.4g}"
            )
        print(
            "wrote " + ", ".join(str(p) for p in paths.values()) if paths else "no files written (--out DIR)",
            file=sys.stdout,
        )
    return 0


def register(subparsers) -> None:
    """Add ``critical``, ``hysteresis`` and ``map`` to an :mod:`argparse` subparsers object."""
    p = subparsers.add_parser(
        "critical",
        formatter_class=_FMT,
        help="critical bearing number Lambda_c (onset of whirl) from the eigenvalues",
        description=(
            "Critical bearing number Lambda_c: the equilibrium is solved along Lambda (warm-started\n"
            "Newton), the eigenvalues of the analytic Jacobian are computed, and the first crossing of\n"
            "max Re(lambda) = 0 above a stable equilibrium is bracketed by a scan and refined by Brent's\n"
            "method to 1e-5 (paper Sect. 3.2, Fig. 4).\n"
            "--structure frictional: the equilibria of a quasi-static spin-up from the range's lower end\n"
            "(steps of 0.002, each from the previous one), sliders on their Coulomb limit held in the\n"
            "linearisation (the small-perturbation limit; docs/analysis.md, Dry friction); JSON adds\n"
            "stick_stiffness, friction_coefficient, slip_viscosity, equilibrium_history,\n"
            "sliders_on_limit.\n\n"
            "JSON keys: critical_bearing_number, critical_speed_rpm, whirl_frequency_ratio\n"
            "(Im(lambda)/Lambda_c), eccentricity_at_onset, whirl_frequency, crossing_speed\n"
            "(dRe(lambda)/dLambda), structure, foil_stiffness, foil_damping, grid, evaluations,\n"
            "wall_time_s.\n"
            "Exit code 2 with a message when no stable equilibrium exists in the range, or when it is\n"
            "stable up to the end of the range."
        ),
    )
    _add_common(p)
    _add_range(p)
    p.set_defaults(func=cmd_critical)

    p = subparsers.add_parser(
        "hysteresis",
        formatter_class=_FMT,
        help="Lambda_c and the fold of cycles Lambda_fold (hysteresis band) by shooting",
        description=(
            "Hysteresis band of the subcritical Hopf bifurcation: Lambda_c from the eigenvalues, then\n"
            "the small cycles born at the Hopf point (from its critical eigenvector) are converged by\n"
            "shooting (Newton on the initial state, the period and Lambda, fixed-step trapezoidal map\n"
            "with exact variational equations) and continued by pseudo-arclength round the fold of\n"
            "cycles Lambda_fold and back up to Lambda_c on the stable whirl.  For Lambda_fold < Lambda <\n"
            "Lambda_c both the equilibrium and the whirl are stable.  Takes ~10 s on 31x7, about a\n"
            "minute on the paper grid.  Exit 1 (one line) when no cycle can be computed.\n\n"
            "JSON adds to the `critical` keys: fold_bearing_number, fold_speed_rpm,\n"
            "limit_cycle_amplitude_at_critical (half peak-to-peak xi),\n"
            "limit_cycle_max_eccentricity_at_critical,\n"
            "whirl_period_at_critical, subcritical, contact_bearing_number (no fold: where the unstable\n"
            "cycles reach contact), band_lower_bearing_number (the band's lower edge),\n"
            "continuation_message and, with --coast-down, coast_down_fold_bearing_number."
        ),
    )
    _add_common(p)
    _add_range(p)
    p.add_argument(
        "--n-steps",
        type=int_range("--n-steps", 20, MAX_SHOOTING_STEPS),
        default=300,
        help=f"trapezoidal steps per period of the shooting map, 20..{MAX_SHOOTING_STEPS} (default 300)",
    )
    p.add_argument(
        "--coast-down",
        action="store_true",
        help="also estimate Lambda_fold by a brute-force coast-down (lower Lambda in steps of "
        "0.005 from the developed whirl until it collapses)",
    )
    p.set_defaults(func=cmd_hysteresis)

    p = subparsers.add_parser(
        "map",
        formatter_class=_FMT,
        help="stability map Lambda_c(K_W, D_W) (paper Fig. 4): CSV + PNG",
        description=(
            "Stability map (paper Fig. 4): Lambda_c of the viscoelastic foil over the grid of\n"
            "--foil-stiffness x --foil-damping values, the elastic curve over K_W and the rigid value.\n"
            "Runs as a resumable joblib sweep (checkpoint OUT/sweep.jsonl), optionally on a Dask cluster.\n"
            "Writes OUT/stability_map.csv, OUT/optimum_damping.csv and OUT/stability_map.png."
        ),
    )
    p.add_argument(
        "--foil-stiffness",
        default="0.1,0.3,1,2.337,10",
        metavar="K1,K2,...",
        help="comma-separated K_W values (default 0.1,0.3,1,2.337,10)",
    )
    p.add_argument(
        "--foil-damping",
        default="0.3,1,3,10,30",
        metavar="D1,D2,...",
        help="comma-separated D_W values (default 0.3,1,3,10,30)",
    )
    p.add_argument(
        "--grid", type=grid_type, default="79x7", help="finite-difference grid N_phi x N_Z (default 79x7)"
    )
    add_out_option(p, _MAP_FILES)
    p.add_argument(
        "--n-jobs",
        type=int,
        default=1,
        help="parallel joblib workers (default 1; -1: all cores; at most the number of cores)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="Dask scheduler address, e.g. tcp://host:8786: run the sweep on that cluster",
    )
    add_bearing_option(p)
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=cmd_map)


def _add_range(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--bearing-range",
        type=positive("--bearing-range"),
        nargs=2,
        default=(0.1, 3.0),
        metavar=("MIN", "MAX"),
        help="range of Lambda scanned for the stability change (default 0.1 3.0)",
    )
    p.add_argument(
        "--scan-step",
        type=positive("--scan-step"),
        default=0.05,
        help="coarse scan step in Lambda before Brent's refinement (default 0.05)",
    )
