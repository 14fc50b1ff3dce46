"""Options and converters shared by the ``gfb`` subcommands (``cli`` and ``cli_analysis``)."""

from __future__ import annotations

import argparse
import math

from gfb_env.model import GFBModel, Grid, Structure
from gfb_env.params import BearingParameters

__all__ = [
    "add_model_options",
    "add_speed_options",
    "model_from_args",
    "bearing_number_from_args",
    "positive",
]


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


def _grid(text: str) -> Grid:
    try:
        return Grid.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_model_options(p: argparse.ArgumentParser, damping: bool = True) -> None:
    """Options shared by every command that builds a model."""
    p.add_argument(
        "--structure",
        choices=[s.value for s in Structure],
        default="viscoelastic",
        help="foil model: rigid (Q = 0), elastic (K_W Q = -(Pbar - 1), Eq. 6-8) or viscoelastic "
        "(D_W Q' + K_W Q = -(Pbar - 1), Eq. 9-10). Default: %(default)s",
    )
    p.add_argument(
        "--foil-stiffness",
        type=positive("--foil-stiffness"),
        default=None,
        metavar="K",
        help="nondimensional foil stiffness K_W (default: Walowit-Anno value of Table 1, 2.337)",
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
        type=_grid,
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


def model_from_args(args: argparse.Namespace) -> GFBModel:
    return GFBModel(args.structure, grid=args.grid, foil_stiffness=args.foil_stiffness)


def bearing_number_from_args(args: argparse.Namespace, bearing: BearingParameters) -> float:
    if getattr(args, "bearing_number", None) is not None:
        return float(args.bearing_number)
    return bearing.bearing_number_at(float(args.speed_rpm))
