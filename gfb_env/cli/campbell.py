"""``gfb campbell``: the Campbell diagram and log decrement of the rotor whirl modes over speed.

Works on any bearing file (``--bearing``) and writes physical units by default (rpm, Hz, um),
nondimensional ones with ``--nondimensional``.  Every option is checked before any work: a bad value
is one line and exit code 2.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

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
    delta = cd.log_decrement
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        _write_csv(cd, out / "campbell.csv", args.modes)
        _plot_campbell(cd, out / "campbell.png", args.nondimensional)
    ok = np.isfinite(delta)
    jmin = np.unravel_index(np.nanargmin(np.where(ok, delta, np.inf)), delta.shape) if ok.any() else None
    on = cd.onset_eigenvalue
    d = {
        "structure": cd.structure,
        "grid": cd.grid,
        "foil_stiffness": cd.foil_stiffness,
        "foil_damping": cd.foil_damping,
        "modes": args.modes,
        "n_speeds": len(cd.bearing_number),
        "bearing_number_range": [lo, hi],
        "speed_rpm_range": [b.speed_rpm_at(lo), b.speed_rpm_at(hi)],
        "onset_bearing_number": cd.onset_bearing_number,
        "onset_speed_rpm": cd.onset_speed_rpm,
        "onset_frequency_hz": None if on is None else b.frequency_hz(on.imag),
        "onset_whirl_frequency_ratio": None if on is None else on.imag / cd.onset_bearing_number,
        "min_log_decrement": None if jmin is None else float(delta[jmin]),
        "min_log_decrement_speed_rpm": None if jmin is None else float(cd.speed_rpm[jmin[0]]),
        "equilibria_failed": int(np.sum(~np.isfinite(cd.eccentricity))),
        "files": {} if out is None else {k: str(out / k) for k in _CAMPBELL_FILES},
        "wall_time_s": wall,
    }
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
        print(f"  wrote {', '.join(d['files'].values()) or 'no files (--out DIR)'} ({wall:.1f} s)")
    return 0


def _write_csv(cd, path: Path, modes: int) -> None:
    f_hz, zeta, delta, ratio = cd.frequency_hz, cd.damping_ratio, cd.log_decrement, cd.whirl_frequency_ratio
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "speed_rpm",
                "bearing_number",
                "mode",
                "frequency_hz",
                "angular_frequency",
                "whirl_frequency_ratio",
                "growth_rate",
                "damping_ratio",
                "log_decrement",
                "rotor_participation",
                "eccentricity",
            ]
        )
        for j in range(len(cd.bearing_number)):
            for k in range(modes):
                ev = cd.eigenvalues[j, k]
                w.writerow(
                    [f"{x:.8g}" if isinstance(x, float) else x for x in (
                        float(cd.speed_rpm[j]), float(cd.bearing_number[j]), k + 1, float(f_hz[j, k]),
                        float(ev.imag), float(ratio[j, k]), float(ev.real), float(zeta[j, k]),
                        float(delta[j, k]), float(cd.participation[j, k]), float(cd.eccentricity[j]),
                    )]
                )  # fmt: skip


def _plot_campbell(cd, path: Path, nondimensional: bool) -> None:
    from gfb_env.plotting import plt

    if nondimensional:
        x, xl = cd.bearing_number, r"bearing number $\Lambda$"
        y, yl = cd.eigenvalues.imag, r"whirl frequency $\mathrm{Im}\,\lambda$ (rad per unit $\tau$)"
        one_x = cd.bearing_number
        x_on = cd.onset_bearing_number
    else:
        x, xl = cd.speed_rpm, "rotor speed (rpm)"
        y, yl = cd.frequency_hz, "damped natural frequency (Hz)"
        one_x = cd.speed_rpm / 60.0
        x_on = cd.onset_speed_rpm
    delta = cd.log_decrement
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True, constrained_layout=True)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink"]
    for k in range(y.shape[1]):
        a1.plot(x, y[:, k], "-", color=colours[k], lw=1.5, label=f"rotor mode {k + 1}")
        bad = delta[:, k] < 0
        a1.plot(x[bad], y[bad, k], "o", ms=4, color="tab:red", label="unstable" if k == 0 else None)
        a2.plot(x, delta[:, k], "-", color=colours[k], lw=1.5, label=f"rotor mode {k + 1}")
    a1.plot(x, one_x, "k--", lw=1, label="1x (synchronous)")
    a1.plot(x, 0.5 * one_x, "k:", lw=1, label="0.5x")
    top = np.nanmax(y[:, 0]) if np.isfinite(y[:, 0]).any() else 1.0
    a1.set_ylim(0, 2.2 * top)
    a1.set_ylabel(yl)
    a1.legend(fontsize=8, loc="upper left")
    a1.grid(alpha=0.3)
    a1.set_title(
        f"Campbell diagram: {cd.structure} foil, K_W={cd.foil_stiffness:.3g}, D_W={cd.foil_damping:.3g}, "
        f"grid {cd.grid}",
        fontsize=10,
    )
    a2.axhline(0, color="k", lw=0.8)
    fin = delta[np.isfinite(delta)]
    if fin.size:
        a2.set_ylim(max(fin.min(), -3) - 0.3, min(fin.max(), 8) + 0.3)
    if x_on is not None:
        lab = f"onset {x_on:.4f}" if nondimensional else f"critical speed {x_on:.0f} rpm"
        for a in (a1, a2):
            a.axvline(x_on, color="tab:red", lw=1, ls="-.")
        a2.plot([x_on], [0], "o", color="tab:red", label=lab)
    a2.set_ylabel(r"logarithmic decrement $\delta = -2\pi\,\mathrm{Re}\lambda/\mathrm{Im}\lambda$")
    a2.set_xlabel(xl)
    a2.legend(fontsize=8, loc="upper right")
    a2.grid(alpha=0.3)
    fig.savefig(path, dpi=90)
    plt.close(fig)


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
