"""Precompute the constants of the Gymnasium tasks (``gfb_env/envs/data/task_constants.json``).

For each grid in ``--grids`` (nominal bearing of :mod:`gfb_env.envs._data`, K_W = 0.50):

* ``lambda_c(D_W)`` on a log grid of the damping range, the optimum damping ``d_opt`` and the best
  stable bearing number ``lambda_best = max_D lambda_c(D)`` (golden-section refinement in log D);
* a point on the developed whirl limit cycle at ``Lambda_w = 1.07 lambda_best``, ``D_W = d_opt``
  (the start of WhirlRecovery), with its period and extremes.

For the default grid only, the RunUpRandomized lookup table of ``lambda_best`` (and ``d_opt``,
``lambda_c`` at the damping bounds) over clearance C, stiffness factor f_K (K_W = f_K K_W,WA(C)) and
external load F_L.

Stability uses :mod:`gfb_env.analysis.task_constants`.  Run::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python -m gfb_experiments.env_task_constants

(one BLAS thread: the dense eigenvalue solves oversubscribe a shared machine otherwise; ~3 min on
2 shared cores: 31x7 20 s, 79x7 50 s, the randomized table 105 s).  `tests/analysis/test_task_constants.py`
recomputes its cheap parts and compares.
"""

from __future__ import annotations

import itertools
import json
import time

import numpy as np

from gfb_env import jsonio
from gfb_env.analysis.maps import optimum_from_curve
from gfb_env.analysis.task_constants import (
    WHIRL_FACTOR,
    critical_bearing_numbers_on_grid,
    developed_whirl_state,
    task_constants,
)
from gfb_env.envs._data import NOMINAL_BEARING, TASK_CONSTANTS_PATH
from gfb_env.model import GFBModel, Grid
from gfb_env.provenance import platform_fingerprint
from gfb_env.scripting import OneLineParser

D_MIN, D_MAX = 0.1, 10.0
DAMPINGS = np.geomspace(D_MIN, D_MAX, 13)


def main() -> None:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grids", default="31x7,79x7")
    ap.add_argument("--default-grid", default="31x7")
    ap.add_argument("--no-table", action="store_true")
    ap.add_argument("--whirl-only", action="store_true", help="recompute only the whirl start of --grids")
    args = ap.parse_args()
    out = {
        "made_on": platform_fingerprint(),  # the whirl state's last digits depend on the machine
        "bearing": NOMINAL_BEARING.as_dict(),
        "foil_stiffness": NOMINAL_BEARING.foil_stiffness,
        "damping_range": [D_MIN, D_MAX],
        "command": "python -m gfb_experiments.env_task_constants "
        + " ".join(f"--grids {args.grids} --default-grid {args.default_grid}".split()),
        "nominal": {},
    }
    if TASK_CONSTANTS_PATH.exists():
        old = json.loads(TASK_CONSTANTS_PATH.read_text())
        out["nominal"].update(old.get("nominal", {}))
        if args.no_table and "randomized" in old:
            out["randomized"] = old["randomized"]
    for g in filter(None, args.grids.split(",")):
        t0 = time.perf_counter()
        model = GFBModel("viscoelastic", Grid.parse(g), bearing=NOMINAL_BEARING)
        if args.whirl_only:
            entry = dict(out["nominal"][g])
            lam_w = round(WHIRL_FACTOR * entry["lambda_best"], 4)
            entry["whirl"] = developed_whirl_state(model, lam_w, entry["d_opt"])
        else:
            entry = task_constants(model, D_MIN, D_MAX)
        if not args.whirl_only:
            entry["seconds"] = time.perf_counter() - t0
        out["nominal"][g] = entry
        print(
            g,
            {k: v for k, v in entry.items() if k not in ("whirl", "curve_d", "curve_lambda_c")},
            "whirl:",
            {k: v for k, v in entry["whirl"].items() if k != "state"},
            flush=True,
        )
        _write(out)
    if not args.no_table:
        t0 = time.perf_counter()
        clearance = [40e-6, 45e-6, 50e-6, 55e-6, 60e-6]
        stiff = [0.7, 1.0, 1.4]
        load = [15.0, 20.25, 25.0]
        rows = []
        for c, fk, fl in itertools.product(clearance, stiff, load):
            bp = NOMINAL_BEARING.replace(clearance_m=c, external_load_per_bearing_n=fl)
            model = GFBModel(
                "viscoelastic",
                Grid.parse(args.default_grid),
                bearing=bp,
                foil_stiffness=fk * bp.foil_stiffness,
            )
            lc = critical_bearing_numbers_on_grid(model, DAMPINGS, lam_min=0.2)
            d_opt, best = optimum_from_curve(DAMPINGS, lc)
            rows.append(
                [c, fk, fl, best, d_opt, lc[0], lc[-1], bp.speed_rpm_at(best), bp.speed_rpm_at(lc[0])]
            )
            print("table", rows[-1], flush=True)
        out["randomized"] = {
            "grid": args.default_grid,
            "axes": {
                "clearance_m": clearance,
                "stiffness_factor": stiff,
                "external_load_per_bearing_n": load,
            },
            "columns": [
                "clearance_m",
                "stiffness_factor",
                "external_load_per_bearing_n",
                "lambda_best",
                "d_opt",
                "lambda_c_dmin",
                "lambda_c_dmax",
                "rpm_best",
                "rpm_c_dmin",
            ],
            "rows": rows,
            "seconds": time.perf_counter() - t0,
        }
    _write(out)
    print(jsonio.dumps({"written": str(TASK_CONSTANTS_PATH)}))


def _write(out: dict) -> None:
    """Merge into the file as it is now (another run may have added grids meanwhile)."""
    TASK_CONSTANTS_PATH.parent.mkdir(parents=True, exist_ok=True)
    merged = json.loads(TASK_CONSTANTS_PATH.read_text()) if TASK_CONSTANTS_PATH.exists() else {}
    nominal = {**merged.get("nominal", {}), **out["nominal"]}
    merged.update(out)
    merged["nominal"] = nominal
    TASK_CONSTANTS_PATH.write_text(jsonio.dumps(merged, indent=1))


if __name__ == "__main__":
    main()
