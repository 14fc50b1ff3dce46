"""Helpers for command-line scripts built on the simulator: the ``gfb`` command uses them, and so do the
experiments, the training and the benchmark scripts.  Public: a script of yours may use them too.

- :class:`OneLineParser`: argparse with one-line usage errors and exit code 2.
- argument checks, each naming its option: :func:`positive`, :func:`non_negative`, :func:`finite`,
  :func:`in_range`, :func:`int_range`, :func:`float_list` (comma lists, empty items refused),
  :func:`grid_type` (``NPHIxNZ``), :func:`bearing_file` (a bearing file or the name of a shipped one,
  :func:`load_bearing`);
- output folders checked before any work: :func:`check_output_dir`; JSON out: :func:`write_json`;
- option groups of the ``gfb`` subcommands and their readers: :func:`add_model_options`,
  :func:`model_from_args`, :func:`add_speed_options`, :func:`bearing_number_from_args`,
  :func:`add_unbalance_options`, :func:`unbalance_from_args`, :func:`add_speed_range_options`,
  :func:`bearing_range_from_args`, :func:`add_start_options`, :func:`check_perturbation`,
  :func:`check_eigen_grid`; the transient limits :data:`MAX_DURATION` and :data:`MAX_SAMPLES`.

The convention every helper follows: bad input raises :class:`ValueError` (or argparse's
``ArgumentTypeError``) with one line naming the option, before any computation; a script turns it
into exit code 2.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from gfb_env import jsonio
from gfb_env.model import GFBModel, Grid, Structure
from gfb_env.params import (
    BearingParameters,
    FrictionParameters,
    read_bearing_file,
    shipped_bearing_names,
    shipped_bearing_path,
)

__all__ = [
    "written_line",
    "MAX_DURATION",
    "MAX_SAMPLES",
    "add_bearing_option",
    "add_model_options",
    "add_out_option",
    "add_speed_options",
    "add_speed_range_options",
    "add_start_options",
    "add_unbalance_options",
    "bearing_file",
    "bearing_from_args",
    "bearing_number_from_args",
    "bearing_range_from_args",
    "check_eigen_grid",
    "check_output_dir",
    "check_perturbation",
    "finite",
    "float_list",
    "friction_parameters",
    "grid_type",
    "in_range",
    "int_range",
    "non_negative",
    "load_bearing",
    "load_bearing_file",
    "model_from_args",
    "OneLineParser",
    "optional_output_dir",
    "positive",
    "print_table",
    "unbalance_from_args",
    "write_json",
]


class OneLineParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose usage errors are one line (``prog: error: ...``) and
    exit code 2, without the usage block (``--help`` still prints it)."""

    def error(self, message: str) -> None:
        self.exit(2, f"{self.prog}: error: {message}\n")


def positive(name: str):
    """argparse type: a finite positive float, with an error naming the option."""

    def conv(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise argparse.ArgumentTypeError(f"{name} must be finite and positive, got {text!r}")
        return v

    return conv


def non_negative(name: str):
    """argparse type: a finite float >= 0, with an error naming the option."""

    def conv(text: str) -> float:
        v = finite(name)(text)
        if v < 0:
            raise argparse.ArgumentTypeError(f"{name} must be >= 0, got {text!r}")
        return v

    return conv


def finite(name: str):
    """argparse type: a finite float (no nan/inf), with an error naming the option."""

    def conv(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return v

    return conv


def in_range(name: str, lo: float, hi: float):
    """argparse type: a float in ``[lo, hi)``, with an error naming the option and the range."""

    def conv(text: str) -> float:
        v = finite(name)(text)
        if not lo <= v < hi:
            raise argparse.ArgumentTypeError(f"{name} must lie in [{lo:g}, {hi:g}), got {text!r}")
        return v

    return conv


def int_range(name: str, lo: int, hi: int):
    """argparse type: an integer in ``[lo, hi]``, with an error naming the option and the range."""

    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{name} must lie in [{lo}, {hi}], got {text!r}")
        return v

    return conv


def grid_type(text: str) -> Grid:
    """argparse type of ``--grid``: :meth:`Grid.parse`, including its size limit (before any work)."""
    try:
        return Grid.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def float_list(text: str, name: str, *, positive: bool = True, max_items: int | None = None) -> list[float]:
    """The numbers of a comma- (or space-) separated list ``text`` of option ``name``: finite (and
    positive unless ``positive=False``), at least one, at most ``max_items``; an empty item
    (``1,,2``, a trailing comma) is refused.

    Raises:
        ValueError: one line naming ``name``.
    """
    items = [x.strip() for x in str(text).split(",")]
    words = [w for item in items for w in item.split()]
    if not words:
        raise ValueError(f"{name} must list at least one number, got {text!r}")
    if any(not item for item in items):
        raise ValueError(f"{name} has an empty item (two commas or a trailing comma), got {text!r}")
    try:
        vals = [float(w) for w in words]
    except ValueError:
        raise ValueError(f"{name} must be a comma-separated list of numbers, got {text!r}") from None
    kind = "positive numbers" if positive else "finite numbers"
    if any(not math.isfinite(v) or (positive and not v > 0) for v in vals):
        raise ValueError(f"{name} must be a list of {kind}, got {text!r}")
    if max_items is not None and len(vals) > max_items:
        raise ValueError(f"{name} must list at most {max_items} numbers, got {len(vals)}")
    return vals


def load_bearing_file(text: str | os.PathLike) -> tuple[BearingParameters, FrictionParameters | None]:
    """The bearing of a TOML file path, or of the NAME of a bearing shipped with the package
    (:func:`gfb_env.params.shipped_bearing_names`) when no file of that name exists, and the file's
    optional ``[friction]`` table (:func:`gfb_env.params.read_bearing_file`; None without one).

    Raises:
        ValueError: one line naming the file (or the unknown name and the shipped ones).
    """
    text = os.fspath(text)
    path = Path(text).expanduser()
    if not os.path.lexists(path) and os.sep not in text and "/" not in text:
        stem = text[: -len(".toml")] if text.endswith(".toml") else text
        if stem in shipped_bearing_names():
            return read_bearing_file(shipped_bearing_path(stem))
        raise ValueError(
            f"{text}: no such file, nor the name of a shipped bearing ({', '.join(shipped_bearing_names())})"
        )
    return read_bearing_file(path)


def load_bearing(text: str | os.PathLike) -> BearingParameters:
    """The bearing of :func:`load_bearing_file` (a TOML file path or the name of a shipped bearing:
    ``table1``, ``small_turbocompressor``, ...), read by :meth:`BearingParameters.from_toml`'s reader
    (size and type checked before reading).

    Raises:
        ValueError: one line naming the file (or the unknown name and the shipped ones).
    """
    return load_bearing_file(text)[0]


def bearing_file(text: str) -> tuple[BearingParameters, FrictionParameters | None]:
    """argparse type of ``--bearing``: :func:`load_bearing_file` (a file or a shipped name, read and
    validated while the arguments are parsed, so a bad file is one line and exit 2 before any work)."""
    try:
        return load_bearing_file(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _BearingAction(argparse.Action):
    """Stores ``--bearing``'s bearing as ``args.bearing`` and its ``[friction]`` table (or None) as
    ``args.bearing_friction``, read by :func:`model_from_args` for ``--structure frictional``."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        bearing, friction = values
        setattr(namespace, self.dest, bearing)
        namespace.bearing_friction = friction


def add_bearing_option(p: argparse.ArgumentParser) -> None:
    """``--bearing FILE|NAME``: the dimensional bearing (default: the paper's Table 1), and its
    optional ``[friction]`` table (``args.bearing_friction``)."""
    p.add_argument(
        "--bearing",
        type=bearing_file,
        action=_BearingAction,
        default=BearingParameters(),
        metavar="FILE|NAME",
        help="bearing file (TOML, top-level keys = BearingParameters field names in SI units, missing "
        "keys take Table 1; an optional [friction] table: friction_coefficient, stick_stiffness_n_m3 or "
        "stick_stiffness_ratio, for --structure frictional) or the name of a bearing shipped with the "
        f"package: {', '.join(shipped_bearing_names())} (gfb_env/data/bearings/). Default: the paper's "
        "Table 1",
    )
    p.set_defaults(bearing_friction=None)


def check_output_dir(text: str, option: str = "--out", files: Iterable[str] = ()) -> Path:
    """The output folder ``text`` of ``option``, checked before any computation: it must be an
    existing folder or creatable (its first existing ancestor a folder), writable, and none of
    ``files`` inside it may be a folder or read-only.  Leaves nothing behind: writability is probed by
    creating and removing a temporary folder in the folder (or its first existing ancestor), because
    permission bits do not tell (root may "write" in ``/proc``; a read-only mount; ACLs).

    Raises:
        ValueError: one line naming ``option`` and the reason.
    """
    if not str(text).strip():
        raise ValueError(f"{option} must name a folder, got {text!r}")
    out = Path(text).expanduser()
    if out.exists():
        if not out.is_dir():
            raise ValueError(f"{option} {text}: exists and is not a folder")
        base = out
    else:
        base = out.absolute().parent
        while not base.exists() and base != base.parent:
            base = base.parent
        if not base.is_dir():
            raise ValueError(f"{option} {text}: cannot create the folder, {base} is a file")
    # os.access also reports a read-only file system (EROFS); for root it allows what root may do
    if not os.access(base, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {text}: no permission to write in {base}")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".gfb-probe-", dir=base))
    except OSError as exc:
        raise ValueError(f"{option} {text}: cannot write in {base} ({exc.strerror})") from None
    for name in files:
        f = out / name
        if f.is_dir() or (f.exists() and not os.access(f, os.W_OK)):
            raise ValueError(f"{option} {text}: cannot write {f}")
    return out


def optional_output_dir(text: str | None, option: str = "--out", files: Iterable[str] = ()) -> Path | None:
    """:func:`check_output_dir` of an optional ``--out``: None when no folder was given (the command
    then writes no files; its summary goes to stdout)."""
    return None if text is None else check_output_dir(text, option, files)


def print_table(rows: dict) -> None:
    """Print ``rows`` as an aligned two-column table (floats with 6 significant digits)."""
    width = max(len(k) for k in rows)
    for k, v in rows.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        elif isinstance(v, list):
            v = ", ".join(f"{x:.6g}" if isinstance(x, float) else str(x) for x in v)
        print(f"{k:<{width}}  {v}")


def add_out_option(p: argparse.ArgumentParser, files: Iterable[str] = ()) -> None:
    """``--out DIR``, optional: the folder of the command's ``files`` (checked before any work by
    :func:`optional_output_dir`); without it the command writes no files and prints its summary."""
    listed = f" ({', '.join(files)})" if files else ""
    p.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help=f"output folder for the files{listed}, created if needed and checked before any work. "
        "Default: write no files, print the summary only (--json: as one JSON object)",
    )


def write_json(path: str | os.PathLike, obj: Any, indent: int | None = 2) -> Path:
    """Write ``obj`` as JSON (:func:`gfb_env.jsonio.dumps`: NaN and inf as null, numpy scalars as
    numbers) to ``path``; returns the path."""
    path = Path(path)
    path.write_text(jsonio.dumps(obj, indent=indent))
    return path


def add_model_options(p: argparse.ArgumentParser, damping: bool = True) -> None:
    """Options shared by every command that builds a model (``--bearing`` included)."""
    add_bearing_option(p)
    p.add_argument(
        "--structure",
        choices=[s.value for s in Structure],
        default="viscoelastic",
        help="foil model: rigid (Q = 0), elastic (K_W Q = -(Pbar - 1), Eq. 6-8), viscoelastic "
        "(D_W Q' + K_W Q = -(Pbar - 1), Eq. 9-10) or frictional (K_W in parallel with a stick stiffness "
        "K_T and a Coulomb slider, --stick-stiffness, --friction-coefficient). Default: %(default)s",
    )
    p.add_argument(
        "--foil-stiffness",
        type=positive("--foil-stiffness"),
        default=None,
        metavar="K",
        help="nondimensional foil stiffness K_W (default: the Walowit-Anno value of the bearing's bump "
        "foil geometry; Table 1: 2.337)",
    )
    p.add_argument(
        "--stick-stiffness",
        type=positive("--stick-stiffness"),
        default=None,
        metavar="KT",
        help="frictional foil only: nondimensional stick stiffness K_T of the Jenkins element "
        "(default: equal to K_W)",
    )
    p.add_argument(
        "--friction-coefficient",
        type=non_negative("--friction-coefficient"),
        default=None,
        metavar="MU",
        help="frictional foil only: Coulomb coefficient mu_C, F_c = mu_C |Pbar - 1| (default 0.1; "
        "identified bump-foil values are about 0.05-0.2)",
    )
    p.add_argument(
        "--slip-viscosity",
        type=positive("--slip-viscosity"),
        default=None,
        metavar="ETA",
        help="frictional foil only: regularisation eta of the slider law, eta S' = sign(F) max(|F| - F_c, 0) "
        "(default 1e-3)",
    )
    if damping:
        p.add_argument(
            "--foil-damping",
            type=positive("--foil-damping"),
            default=1.0,
            metavar="D",
            help="nondimensional foil damping D_W (viscoelastic only). Default: %(default)s",
        )
    p.add_argument(
        "--grid",
        type=grid_type,
        default=Grid(),
        metavar="NPHIxNZ",
        help="finite-difference grid N_phi x N_Z as counted in the paper (N_phi includes the periodic "
        "duplicate, N_Z the ambient edges; N_Z odd). Default: 79x7",
    )


def add_speed_options(p: argparse.ArgumentParser, required: bool = True) -> None:
    g = p.add_mutually_exclusive_group(required=required)
    g.add_argument(
        "--bearing-number",
        type=positive("--bearing-number"),
        metavar="LAMBDA",
        help="bearing number Lambda = 6 mu0 omega0 / p0 (R/C)^2 (0.5995 is 36 000 rpm)",
    )
    g.add_argument("--speed-rpm", type=positive("--speed-rpm"), metavar="N", help="rotor speed in rpm")


#: The frictional foil's options of :func:`add_model_options` and the GFBModel arguments they set.
FRICTION_OPTIONS = {
    "--stick-stiffness": "stick_stiffness",
    "--friction-coefficient": "friction_coefficient",
    "--slip-viscosity": "slip_viscosity",
}


def model_from_args(args: argparse.Namespace) -> GFBModel:
    """The model of :func:`add_model_options`; the frictional options are refused (``ValueError`` naming
    the option) with any other ``--structure``.  ``--structure frictional`` takes the bearing file's
    ``[friction]`` table (``--stick-stiffness`` and ``--friction-coefficient`` override it); the other
    structures ignore that table (it describes the hardware, the structure is the model's choice)."""
    friction = {name: getattr(args, name, None) for name in FRICTION_OPTIONS.values()}
    if args.structure != Structure.FRICTIONAL:
        for option, name in FRICTION_OPTIONS.items():
            if friction[name] is not None:
                raise ValueError(
                    f"{option} is an option of --structure frictional only, not {args.structure}"
                )
        friction = {}
    elif getattr(args, "bearing_friction", None) is not None:
        friction["friction"] = args.bearing_friction
    return GFBModel(
        args.structure,
        grid=args.grid,
        bearing=bearing_from_args(args),
        foil_stiffness=args.foil_stiffness,
        **friction,
    )


def friction_parameters(model: GFBModel) -> dict[str, float]:
    """The frictional foil's parameters by name (empty for the other structures), for the reports."""
    if model.structure is not Structure.FRICTIONAL:
        return {}
    return {
        "stick_stiffness": model.stick_stiffness,
        "friction_coefficient": model.friction_coefficient,
        "slip_viscosity": model.slip_viscosity,
    }


def bearing_from_args(args: argparse.Namespace) -> BearingParameters:
    """The ``--bearing`` of the command (Table 1 when the command has no such option)."""
    b = getattr(args, "bearing", None)
    return b if b is not None else BearingParameters()


def bearing_number_from_args(args: argparse.Namespace, bearing: BearingParameters) -> float:
    if getattr(args, "bearing_number", None) is not None:
        return float(args.bearing_number)
    return bearing.bearing_number_at(float(args.speed_rpm))


# ------------------------------------------------------------------------------------------------
# unbalance (issue 10): one of --unbalance / --unbalance-g-mm / --balance-grade
def add_unbalance_options(p: argparse.ArgumentParser, required: bool = False) -> None:
    """The rotor's unbalance, nondimensional or physical (see :mod:`gfb_env.forcing`)."""
    g = p.add_mutually_exclusive_group(required=required)
    g.add_argument(
        "--unbalance",
        type=in_range("--unbalance", 0.0, 1.0),
        default=None,
        metavar="U",
        help="unbalance U = m_u e / (m C): the rotor's centre-of-mass eccentricity in units of the "
        "clearance, in [0, 1)",
    )
    g.add_argument(
        "--unbalance-g-mm",
        type=positive("--unbalance-g-mm"),
        default=None,
        metavar="UE",
        help="the rotor's static unbalance m_u e in g mm, shared equally by the two bearings "
        "(U = m_u e / (m C), m the rotor mass, --rotor-mass-kg)",
    )
    g.add_argument(
        "--balance-grade",
        type=positive("--balance-grade"),
        default=None,
        metavar="G",
        help="ISO 1940-1 / 21940-11 balance grade in mm/s (e.g. 2.5 for G 2.5): e_per = G / omega at the "
        "run speed (response over a range: its top speed), U = e_per / C",
    )
    p.add_argument(
        "--rotor-mass-kg",
        type=positive("--rotor-mass-kg"),
        default=None,
        metavar="KG",
        help="rotor mass for --unbalance-g-mm (default: twice the bearing's rotor_mass_per_bearing_kg)",
    )
    p.add_argument(
        "--unbalance-phase-deg",
        type=finite("--unbalance-phase-deg"),
        default=0.0,
        metavar="DEG",
        help="angle of the heavy spot at tau = 0, from the downward vertical in the sense of rotation. "
        "Default: 0",
    )


def unbalance_from_args(args: argparse.Namespace, bearing: BearingParameters, speed_rpm: float):
    """The :class:`~gfb_env.forcing.Unbalance` of the options (None when none was given); the balance
    grade is taken at ``speed_rpm``."""
    from gfb_env.forcing import Unbalance

    phase = math.radians(args.unbalance_phase_deg)
    if args.unbalance is not None:
        u, option = Unbalance(args.unbalance, phase), "--unbalance"
    elif args.unbalance_g_mm is not None:
        u = Unbalance.from_mass_radius(bearing, args.unbalance_g_mm, args.rotor_mass_kg, phase)
        option = "--unbalance-g-mm"
    elif args.balance_grade is not None:
        u = Unbalance.from_iso1940(bearing, args.balance_grade, speed_rpm, args.rotor_mass_kg, phase)
        option = f"--balance-grade (at {speed_rpm:.0f} rpm)"
    else:
        return None
    if not u.magnitude < 1.0:
        raise ValueError(
            f"{option}: the unbalance is {u.magnitude:.3g} clearances (centre-of-mass eccentricity "
            f"{u.eccentricity_um(bearing):.3g} um >= C): it must be below 1"
        )
    return u


def check_eigen_grid(model: GFBModel) -> GFBModel:
    """``model``, refused (``ValueError`` naming ``--grid``, exit 2) before any work when the dense
    eigen-analysis of its state would be too large (:func:`gfb_env.analysis.stability.check_eigen_size`)."""
    from gfb_env.analysis.stability import check_eigen_size

    try:
        check_eigen_size(model)
    except ValueError as exc:
        raise ValueError(f"--grid: {exc}") from None
    return model


def add_speed_range_options(
    p: argparse.ArgumentParser, default_text: str, lambda_help: str | None = None
) -> None:
    """``--speed-range MIN MAX`` (rpm) or ``--bearing-range MIN MAX`` (Lambda), mutually exclusive;
    read back by :func:`bearing_range_from_args`."""
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--speed-range",
        type=positive("--speed-range"),
        nargs=2,
        metavar=("MIN", "MAX"),
        help=f"speed range in rpm (default: {default_text})",
    )
    g.add_argument(
        "--bearing-range",
        type=positive("--bearing-range"),
        nargs=2,
        metavar=("MIN", "MAX"),
        help=lambda_help or "the same range as bearing numbers Lambda",
    )


def bearing_range_from_args(
    args: argparse.Namespace, bearing: BearingParameters, default_lambda: tuple[float, float]
) -> tuple[float, float]:
    """``(Lambda_min, Lambda_max)`` from ``--speed-range`` (rpm) or ``--bearing-range``, checked
    (``ValueError`` naming the option); ``default_lambda`` when neither is given."""
    if getattr(args, "speed_range", None) is not None:
        lo, hi = args.speed_range
        if not lo < hi:
            raise ValueError(f"--speed-range must satisfy 0 < MIN < MAX, got {lo:g} {hi:g}")
        return bearing.bearing_number_at(lo), bearing.bearing_number_at(hi)
    if getattr(args, "bearing_range", None) is not None:
        lo, hi = args.bearing_range
        if not lo < hi:
            raise ValueError(f"--bearing-range must satisfy 0 < MIN < MAX, got {lo:g} {hi:g}")
        return lo, hi
    return default_lambda


def add_start_options(p: argparse.ArgumentParser) -> None:
    """``--perturbation DXI DETA`` (the start's displacement from the equilibrium, units of C) and
    ``--touchdown HMIN`` (the film thickness that stops a run), shared by the transient commands; the
    start film is checked against the threshold before any work (:func:`check_perturbation`)."""
    p.add_argument(
        "--perturbation",
        type=finite("--perturbation"),
        nargs=2,
        default=[0.01, 0.0],
        metavar=("DXI", "DETA"),
        help="displacement of the journal from the equilibrium (units of C), the seed of the whirl; the "
        "start film must stay thicker than --touchdown everywhere. Default: 0.01 0",
    )
    p.add_argument(
        "--touchdown",
        type=in_range("--touchdown", 0.0, 1.0),
        default=0.01,
        metavar="HMIN",
        help="min film thickness (units of C) that stops the run as a touchdown, in [0, 1). "
        "Default: %(default)s",
    )


#: A developed whirl takes about 40 accepted steps per unit tau (measured: 73 449 steps for tau = 2000
#: at Lambda = 1.5 on 79x7), and the integrator stops at ``max_steps`` = 10 000 000 steps; so a
#: transient run (``gfb simulate --duration``, ``gfb runup``) is limited to 10e6 / 40 = 250 000 (40 s of
#: rotor time; ~5 min of wall time at 28 us/step on 79x7, longer on finer grids).
MAX_DURATION = 250_000.0
#: At most this many output samples (``--duration / --record-interval``): the record buffer and the
#: CSV (~90 bytes a row) stay below ~100 MB.
MAX_SAMPLES = 1_000_000


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


def written_line(written: str | None, wall_s: float | None = None) -> str:
    """The commands' last line: ``wrote <written>`` or, for a run without ``--out``, ``no files written
    (--out DIR)``; with ``wall_s``, `` (<wall_s> s)`` after it."""
    line = f"wrote {written}" if written else "no files written (--out DIR)"
    return line if wall_s is None else f"{line} ({wall_s:.1f} s)"
