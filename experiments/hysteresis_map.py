"""Hysteresis map: Lambda_c (Hopf) and Lambda_fold (fold of cycles) against D_W for K_W = 1 and Table-1 K_W.

For each (K_W, D_W): ``Lambda_c`` from the eigenvalues, then the whirl at ``Lambda_c + 0.01`` is shot
and continued down round the fold of cycles (:func:`gfb_env.analysis.fold_bearing_number`).  Regions:
below ``Lambda_fold`` only the equilibrium is stable, between the two both (bistable: a disturbance can
start a whirl that survives), above ``Lambda_c`` only the whirl.  A few points also get the brute-force
coast-down estimate as a cross-check.  The environments read ``hysteresis_map.csv`` through
:func:`gfb_env.analysis.load_hysteresis_map`.

    python -m gfb_experiments.hysteresis_map [--quick | --tasks] [--out results/hysteresis_map] [--n-jobs 2]
                                         [--scheduler ADDRESS]

``--tasks``: the environments' nominal bearing instead (K_W = 0.5007, t_B = 60.8 um) on their default
31x7 grid, written to ``results/hysteresis_map_tasks``: where the bistable band of the RL tasks lies.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from gfb_env import BearingParameters, jsonio
from gfb_env.analysis import compute_hysteresis_map, write_hysteresis_map
from gfb_env.scripting import OneLineParser, check_output_dir


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="K_W=1, D_W=4 on a 33x7 grid (tests)")
    ap.add_argument(
        "--tasks",
        action="store_true",
        help="the environments' nominal bearing (K_W=0.5007) on their 31x7 grid, D_W 0.1..10 "
        "(shipped as gfb_env/data/hysteresis_map_tasks.csv for the benchmark's path figure)",
    )
    ap.add_argument("--out", default=None, help="output directory (default results/hysteresis_map)")
    ap.add_argument("--n-jobs", type=int, default=1, help="parallel workers")
    ap.add_argument("--scheduler", default=None, help="Dask scheduler address")
    ap.add_argument("--n-steps", type=int, default=300, help="trapezoidal steps per period in the shooting")
    a = ap.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    if a.quick and a.tasks:
        ap.error("--quick and --tasks exclude each other")
    default_out = "results/hysteresis_map" + ("_quick" if a.quick else "_tasks" if a.tasks else "")
    out = Path(a.out or default_out)
    kw_table = round(BearingParameters().foil_stiffness, 4)
    if a.quick:
        kws, dws, grid, n_steps, cd = [1.0], [4.0], "33x7", 120, set()
    elif a.tasks:
        from gfb_env.envs import DEFAULT_GRID, NOMINAL_BEARING

        kw_env = round(NOMINAL_BEARING.foil_stiffness, 4)
        # the tasks' damping range, ~1.5x apart: the band's width changes fast near the optimum damping
        dws = [0.1, 0.15, 0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 10.0]
        kws, grid, n_steps = [kw_env], DEFAULT_GRID, a.n_steps
        cd = {(kw_env, 2.0)}
    else:
        kws, dws, grid, n_steps = [1.0, kw_table], [0.5, 1.0, 2.0, 4.0, 8.0, 16.0], "79x7", a.n_steps
        cd = {(1.0, 1.0), (1.0, 4.0), (kw_table, 1.0)}
    t0 = time.perf_counter()
    rows = compute_hysteresis_map(
        kws,
        dws,
        grid=grid,
        n_steps=n_steps,
        coast_down_points=cd,
        n_jobs=a.n_jobs,
        scheduler=a.scheduler,
        checkpoint=out / "sweep.jsonl",
    )
    p = write_hysteresis_map(rows, out)
    _plot(rows, kws, out / "hysteresis_map.png")
    summary = {
        "grid": grid,
        "n_steps": n_steps,
        "wall_time_s": time.perf_counter() - t0,
        "points": [
            {
                k: r.get(k)
                for k in (
                    "foil_stiffness",
                    "foil_damping",
                    "critical_bearing_number",
                    "fold_bearing_number",
                    "coast_down_fold_bearing_number",
                    "limit_cycle_amplitude_at_critical",
                    "contact_bearing_number",
                    "band_lower_bearing_number",
                    "fold_message",
                )
            }
            for r in rows
        ],
    }
    (out / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    print("wrote", p)
    return 0


def _plot(rows: list[dict], kws: list[float], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, len(kws), figsize=(6 * len(kws), 4.5), squeeze=False, constrained_layout=True)
    for ax, kw in zip(axs[0], kws):
        r = sorted([x for x in rows if x["foil_stiffness"] == kw], key=lambda x: x["foil_damping"])
        d = np.array([x["foil_damping"] for x in r])

        def col(name, r=r):
            return np.array([x.get(name) if x.get(name) is not None else math.nan for x in r], dtype=float)

        lc, lf = col("critical_bearing_number"), col("fold_bearing_number")
        cd = col("coast_down_fold_bearing_number")
        # the band's lower edge: the fold, or where the unstable cycles reach contact, or Lambda_c
        band = col("band_lower_bearing_number")
        contact = col("contact_bearing_number")
        known = np.isfinite(lf) | np.isfinite(band)
        lf_fill = np.where(np.isfinite(band), band, np.where(np.isfinite(lf), lf, lc))
        top = np.nanmax(lc) * 1.15 if np.isfinite(lc).any() else 1.0
        bot = np.nanmin(lf_fill) * 0.9 if np.isfinite(lc).any() else 0.3
        ax.fill_between(d, bot, lf_fill, color="tab:green", alpha=0.25, label="stable equilibrium only")
        ax.fill_between(
            d,
            lf_fill,
            lc,
            color="tab:orange",
            alpha=0.35,
            label="bistable (a large disturbance: whirl, or touchdown)",
        )
        if np.isfinite(contact).any():
            ax.plot(d, contact, "v", color="tab:brown", ms=6, label="unstable cycles reach contact (no fold)")
        ax.fill_between(d, lc, top, color="tab:red", alpha=0.2, label="whirl only")
        if not known.all():
            # no fold from shooting there (the whirl touches down, or the shooting failed): below
            # Lambda_c the equilibrium is stable, but whether a whirl coexists is not known
            for x in d[~known]:
                ax.axvline(x, color="0.4", ls=":", lw=1)
            ax.plot(d[~known], lc[~known], "o", mfc="white", mec="k", ms=7, label="no fold found here")
        ax.plot(d, lc, "k-o", ms=4, label=r"$\Lambda_c$ (Hopf)")
        ax.plot(d, lf, "b-s", ms=4, label=r"$\Lambda_{fold}$ (shooting)")
        if np.isfinite(cd).any():
            ax.plot(d, cd, "mx", ms=8, mew=2, label=r"$\Lambda_{fold}$ (coast-down)")
        ax.set_xscale("log")
        ax.set_xticks(d)
        ax.set_xticklabels([f"{x:g}" for x in d])
        ax.minorticks_off()
        ax.set_ylim(bot, top)
        ax.set_xlabel(r"foil damping $D_W$")
        ax.set_ylabel(r"bearing number $\Lambda$")
        ax.set_title(f"viscoelastic foil, $K_W$ = {kw:g}")
        ax.legend(fontsize=7, loc="upper left", framealpha=0.9)
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
