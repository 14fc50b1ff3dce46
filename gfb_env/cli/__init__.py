"""The ``gfb`` command (also ``python -m gfb_env``): the simulator for engineers.

One module per group of subcommands, each with a ``register(subparsers)`` that adds its subcommands and
sets ``func=handler`` (``handler(args) -> int``, the exit code):

=========================  =============================================================
:mod:`gfb_env.cli.static`     ``params``, ``bearing``, ``equilibrium``
:mod:`gfb_env.cli.simulate`   ``simulate``
:mod:`gfb_env.cli.stability`  ``critical``, ``hysteresis``, ``map``
:mod:`gfb_env.cli.campbell`   ``campbell``
:mod:`gfb_env.cli.runup`      ``runup``
:mod:`gfb_env.cli.schedule`   ``schedule``
:mod:`gfb_env.cli.response`   ``response``
=========================  =============================================================

The modules import only :mod:`gfb_env.scripting` (the public helpers for scripts: option checks,
output folders, JSON) and the analysis layer, never this package's ``__init__``: no import circle.
The computations and their figures live in the analysis results (``result.plot()``), so a Python user
gets what the command writes.

Exit codes: 0 success; 2 bad input (one line ``gfb CMD: error: ...``, before any work); 1 a
computation that failed (no equilibrium, an integration or shooting failure, a whirling verification),
also one line.
"""

from __future__ import annotations

import argparse
import sys

from gfb_env._threads import set_thread_defaults
from gfb_env.scripting import OneLineParser

__all__ = ["build_parser", "main", "version"]

#: The command modules, in the order of ``gfb --help``.
COMMAND_MODULES = ("static", "simulate", "stability", "campbell", "runup", "schedule", "response")


def version() -> str:
    """The installed distribution's version (``importlib.metadata``), else ``gfb_env.__version__``
    (a source checkout that is not installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("gfb-env")
    except PackageNotFoundError:
        import gfb_env

        return gfb_env.__version__


def build_parser() -> argparse.ArgumentParser:
    """The ``gfb`` parser with every subcommand registered."""
    import importlib

    parser = OneLineParser(
        prog="gfb",
        description="Gas foil bearing rotor simulator (Leister, Baum & Seemann 2017). All quantities are "
        "nondimensional as in the paper unless the name ends in a unit (_rpm, _um, _N, _s).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    for name in COMMAND_MODULES:
        importlib.import_module(f"gfb_env.cli.{name}").register(sub)
    return parser


def _computation_errors() -> tuple[type[BaseException], ...]:
    """The failures of a computation (not of its input): exit code 1 with one line."""
    from numpy.linalg import LinAlgError

    from gfb_env.analysis.periodic import ShootingError
    from gfb_env.analysis.stability import StabilityAnalysisError
    from gfb_env.equilibrium import EquilibriumError
    from gfb_env.integrator import IntegrationError

    return (
        EquilibriumError,
        IntegrationError,
        StabilityAnalysisError,
        ShootingError,
        LinAlgError,
        ArithmeticError,
        MemoryError,
    )


def main(argv: list[str] | None = None) -> int:
    """Run ``gfb`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    set_thread_defaults()  # for the sweep workers this command may start (see gfb_env._threads)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except Exception as exc:  # one line, never a traceback for a user error or a solver failure
        failed = _computation_errors()
        # LinAlgError is a ValueError: a singular matrix is the solver's failure, not the user's
        if isinstance(exc, failed):
            code = 1
        elif isinstance(exc, ValueError):
            code = 2
        elif isinstance(exc, OSError):  # e.g. the disk filled up: the outputs were checked up front
            code = 1
        else:
            raise
        # one line even when a library's message has several
        message = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        print(f"gfb {args.command}: error: {message}", file=sys.stderr)
        return code


if __name__ == "__main__":
    raise SystemExit(main())
