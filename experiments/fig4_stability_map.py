"""Paper Fig. 4: critical bearing number over foil stiffness K_W and damping D_W.

Viscoelastic foil on a log-spaced K_W x D_W grid, the elastic curve over K_W and the rigid value, each
``Lambda_c`` from the eigenvalues of the analytic Jacobian (:func:`gfb_env.analysis.critical_bearing_number`),
swept in parallel and resumably by :func:`gfb_env.sweeps.run_sweep`.

    python -m gfb_experiments.fig4_stability_map [--quick] [--out results/fig4_stability_map] [--n-jobs 2]
                                             [--scheduler tcp://host:8786]

Writes ``stability_map.csv`` (one row per configuration), ``optimum_damping.csv``, ``summary.json``,
``stability_map.png`` and the sweep checkpoint ``sweep.jsonl`` (delete it to recompute).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from gfb_env import jsonio
from gfb_env.analysis.maps import compute_stability_map, write_stability_map
from gfb_env.scripting import OneLineParser, check_output_dir


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 x 2 map on a 33x7 grid (for tests)")
    ap.add_argument("--out", default=None, help="output directory (default results/fig4_stability_map)")
    ap.add_argument("--n-jobs", type=int, default=1, help="parallel workers (default 1)")
    ap.add_argument(
        "--scheduler", default=None, help="Dask scheduler address (runs the sweep on the cluster)"
    )
    ap.add_argument("--n-stiffness", type=int, default=8, help="K_W points in [0.1, 10] (full mode)")
    ap.add_argument("--n-damping", type=int, default=10, help="D_W points in [0.1, 100] (full mode)")
    a = ap.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    out = Path(a.out or ("results/fig4_stability_map_quick" if a.quick else "results/fig4_stability_map"))
    if a.quick:
        kws, dws, grid = np.array([0.5, 2.0]), np.array([1.0, 4.0]), "33x7"
    else:
        kws, dws, grid = np.logspace(-1, 1, a.n_stiffness), np.logspace(-1, 2, a.n_damping), "79x7"
    t0 = time.perf_counter()
    smap = compute_stability_map(
        kws,
        dws,
        grid=grid,
        n_jobs=a.n_jobs,
        scheduler=a.scheduler,
        checkpoint=out / "sweep.jsonl",
        scan_step=0.05,
    )
    wall = time.perf_counter() - t0
    paths = write_stability_map(smap, out)
    summary = {
        "grid": grid,
        "n_stiffness": len(kws),
        "n_damping": len(dws),
        "wall_time_s": wall,
        "n_jobs": a.n_jobs,
        "rigid_critical_bearing_number": smap.rigid,
        "foil_stiffness": kws.tolist(),
        "elastic_critical_bearing_number": [None if not np.isfinite(x) else x for x in smap.elastic],
        "optimum_foil_damping": [None if not np.isfinite(x) else x for x in smap.optimum_damping],
        "max_critical_bearing_number": [None if not np.isfinite(x) else x for x in smap.optimum_critical],
        "status_counts": {},
    }
    for r in smap.records:
        s = r["result"]["status"] if r["result"] else "error"
        summary["status_counts"][s] = summary["status_counts"].get(s, 0) + 1
    old = out / "summary.json"
    if old.exists() and wall < 10.0:  # everything came from the checkpoint: keep the measured time
        prev = json.loads(old.read_text())
        summary["wall_time_s"] = prev.get("wall_time_s", wall)
        summary["n_jobs"] = prev.get("n_jobs", a.n_jobs)
    old.write_text(jsonio.dumps(summary, indent=2))
    print(jsonio.dumps({k: summary[k] for k in ("grid", "wall_time_s", "rigid_critical_bearing_number")}))
    print("wrote", *[str(p) for p in paths.values()])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
