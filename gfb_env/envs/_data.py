"""Task definitions shared by the environments and the scripts that precompute their constants.

The nominal bearing of the tasks is Table 1 of the paper with a thinner bump foil,
``t_B = 60.8 um`` instead of 101.6 um, so that the Walowit-Anno stiffness is ``K_W = 0.50`` instead of
2.337.  Reason (measured, ``docs/envs.md``): at ``K_W = 2.337`` the foil damping ``D_W`` moves the
critical bearing number ``Lambda_c`` by less than 2 % over ``D_W in [0.3, 16]``, so damping would be
no control input at all; at ``K_W = 0.5`` it moves ``Lambda_c`` from 0.595 (``D_W = 0.1``) to 0.706
(``D_W ~ 2``) on the paper grid, the regime of Fig. 4 where the optimum damping matters.

Precomputed constants live in ``data/task_constants.json`` (package data, written by
``python -m gfb_experiments.env_task_constants``); :func:`load_task_constants` reads them and
:func:`nominal_task_constants` is the one lookup the environments use: a tabulated grid and bearing comes
from the table; anything else is computed once per process with a warning that names the grid, the
reason and the expected time.  A missing or corrupt data file is an error, never a silent recompute.
"""

from __future__ import annotations

import json
import math
import warnings
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

from gfb_env.params import BearingParameters

if TYPE_CHECKING:
    from gfb_env.model import Grid

__all__ = [
    "NOMINAL_BEARING",
    "DATA_DIR",
    "TASK_CONSTANTS_PATH",
    "TASK_CONSTANTS_SCRIPT",
    "TaskConstantsWarning",
    "load_task_constants",
    "nominal_task_constants",
    "randomized_task_table",
]

#: Table 1 with a 60.8 um bump foil: K_W = 0.50 (Walowit-Anno), everything else unchanged.
NOMINAL_BEARING = BearingParameters(bump_foil_thickness_m=60.8e-6)

DATA_DIR = Path(__file__).resolve().parent / "data"
TASK_CONSTANTS_PATH = DATA_DIR / "task_constants.json"
TASK_CONSTANTS_SCRIPT = "python -m gfb_experiments.env_task_constants"


class TaskConstantsWarning(UserWarning):
    """The task constants of a grid or bearing are not tabulated and are being computed (slow)."""


@lru_cache(maxsize=1)
def load_task_constants() -> dict:
    """The precomputed task constants (``data/task_constants.json``).

    Raises:
        FileNotFoundError: the file is missing (a broken install or checkout).
        ValueError: the file is not valid JSON or lacks the ``bearing`` / ``nominal`` tables.
    """
    p = TASK_CONSTANTS_PATH
    if not p.is_file():
        raise FileNotFoundError(
            f"task constants file {p} is missing (package data of gfb_env; made by `{TASK_CONSTANTS_SCRIPT}`)"
        )
    try:
        table = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(
            f"task constants file {p} is corrupt ({exc}); remake it with `{TASK_CONSTANTS_SCRIPT}`"
        ) from None
    if not isinstance(table, dict) or not isinstance(table.get("nominal"), dict) or "bearing" not in table:
        raise ValueError(
            f"task constants file {p} lacks the 'bearing'/'nominal' tables; "
            f"remake it with `{TASK_CONSTANTS_SCRIPT}`"
        )
    return table


def randomized_task_table() -> dict:
    """The RunUpRandomized lookup table of ``data/task_constants.json`` (ValueError if absent)."""
    table = load_task_constants().get("randomized")
    if not isinstance(table, dict):
        raise ValueError(
            f"task constants file {TASK_CONSTANTS_PATH} has no 'randomized' table; "
            f"remake it with `{TASK_CONSTANTS_SCRIPT}`"
        )
    return table


def _unknowns(grid: str) -> int:
    """Gap unknowns of an ``n_phi x n_z`` grid (the cost driver of the computation)."""
    n_phi, n_z = (int(x) for x in grid.split("x"))
    return (n_phi - 1) * (n_z - 2)


def _expected_seconds(grid: str, nominal: dict) -> float:
    """Rough time of :func:`~gfb_env.analysis.task_constants.task_constants` on ``grid``: the measured
    time of the nearest tabulated grid, scaled by (unknowns ratio)^2.5 (31x7 -> 79x7: 10x for 2.6x)."""
    timed = [(g, e["seconds"]) for g, e in nominal.items() if isinstance(e, dict) and "seconds" in e]
    if not timed:
        return math.nan
    n = _unknowns(grid)
    g0, s0 = min(timed, key=lambda gs: abs(math.log(_unknowns(gs[0]) / n)))
    return float(s0) * (n / _unknowns(g0)) ** 2.5


def nominal_task_constants(grid: Grid | str, bearing: BearingParameters) -> dict:
    """Stability constants of the tasks' nominal bearing on ``grid`` (a :class:`~gfb_env.model.Grid`):
    ``lambda_best`` (max over D_W of the critical bearing number Lambda_c), ``d_opt``, ``lambda_c_dmin``,
    the curve ``Lambda_c(D_W)`` and the whirl start state.

    Tabulated grid and bearing: the entry of ``data/task_constants.json``.  Otherwise (another grid or
    bearing) computed here once per process, with a :class:`TaskConstantsWarning` naming the grid, the
    reason and the expected time (constructor only, never inside ``reset()``).  A missing or corrupt
    data file raises (see :func:`load_task_constants`).
    """
    table = load_task_constants()
    g = str(grid)
    entry = table["nominal"].get(g)
    if entry is not None and table["bearing"] == bearing.as_dict():
        return entry
    key = (g, tuple(sorted(bearing.as_dict().items())))
    if key not in _COMPUTED:
        if entry is None:
            reason = f"grid {g} is not tabulated (tabulated: {', '.join(sorted(table['nominal']))})"
        else:
            reason = f"the bearing differs from the tabulated nominal bearing {table['bearing']}"
        eta = _expected_seconds(g, table["nominal"])
        warnings.warn(
            f"task constants on grid {g}: {reason}; computing them now, once per process "
            f"(expected ~{eta:.0f} s; tabulate with `{TASK_CONSTANTS_SCRIPT} --grids {g}`)",
            TaskConstantsWarning,
            stacklevel=2,
        )
        from gfb_env.analysis.task_constants import task_constants  # heavy: only when computing
        from gfb_env.model import GFBModel, Grid, Structure

        model = GFBModel(Structure.VISCOELASTIC, Grid.parse(g), bearing=bearing)
        _COMPUTED[key] = task_constants(model)
    return _COMPUTED[key]


_COMPUTED: dict = {}
