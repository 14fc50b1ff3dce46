"""Paper Fig. 5: run-up and coast-down, Lambda 0.5 -> 0.833 -> 0.5 linearly over tau = 50 000 each way.

Rigid vs viscoelastic foil (Table-1 K_W = 2.337).  The foil damping of the viscoelastic run is the
optimum ``D_W*(K_W)`` (maximum ``Lambda_c``) read from the committed stability map
(:func:`gfb_env.analysis.optimal_foil_damping`; 4.0 if the map is missing): the paper does not state its
``D_W`` for Fig. 5, and the optimum is the case its Sect. 3.2 recommends.  Envelopes (min/max over
windows of 100 tau) of xi, eta and the midplane pressure P(phi=0, Z=0).  Time scale: tau = 50 000 is
50 000 T = 7.95 s with T = 1.59e-4 s (the paper's "50 s" does not follow from its own T).

    python -m gfb_experiments.fig5_runup [--quick] [--out results/fig5_runup] [--n-jobs 2] [--foil-damping D]
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from gfb_env import GFBModel, Grid, TrapezoidalIntegrator, find_equilibrium, jsonio
from gfb_env.scripting import OneLineParser, check_output_dir


def run_case(
    structure: str,
    foil_damping: float,
    grid: str,
    tau_ramp: float,
    lam_lo: float,
    lam_hi: float,
    window: float,
    chunk: float,
) -> dict:
    from tqdm import tqdm

    model = GFBModel(structure, Grid.parse(grid))
    L = model.layout
    s = find_equilibrium(model, lam_lo)
    p00 = L.pressure_index(0, model.grid.midplane_row)
    integ = TrapezoidalIntegrator(model, s, lam_lo, foil_damping, touchdown_film_thickness=1e-5)
    rows = []
    status = "done"
    t_total = 2 * tau_ramp
    bar = tqdm(total=int(t_total), desc=f"fig5 {structure}", unit="tau", leave=False)
    t0 = time.perf_counter()
    for leg, (a, b) in enumerate(((lam_lo, lam_hi), (lam_hi, lam_lo))):
        t_leg0 = integ.tau
        while integ.tau < t_leg0 + tau_ramp - 1e-9:
            t_end = min(integ.tau + chunk, t_leg0 + tau_ramp)
            lam_end = a + (b - a) * (t_end - t_leg0) / tau_ramp
            res = integ.advance(
                t_end,
                bearing_number=lam_end,
                record_interval=0.5,
                record_indices=[p00],
                raise_on_failure=False,
            )
            tr = res.trajectory
            nw = max(1, int(round((tr.tau[-1] - tr.tau[0]) / window))) if len(tr) else 0
            for idx in np.array_split(np.arange(len(tr)), nw) if nw else []:
                if len(idx) == 0:
                    continue
                rows.append(
                    {
                        "tau": float(tr.tau[idx].mean()),
                        "leg": "up" if leg == 0 else "down",
                        "bearing_number": float(tr.bearing_number[idx].mean()),
                        "xi_min": float(tr.xi[idx].min()),
                        "xi_max": float(tr.xi[idx].max()),
                        "eta_min": float(tr.eta[idx].min()),
                        "eta_max": float(tr.eta[idx].max()),
                        "p00_min": float(tr.probes[idx, 0].min()),
                        "p00_max": float(tr.probes[idx, 0].max()),
                        "min_film_thickness": float(tr.min_film_thickness[idx].min()),
                    }
                )
            bar.update(int(chunk))
            if res.status != "done":
                status = f"{res.status} at tau={res.tau:.1f} Lambda={integ.bearing_number:.4f}"
                break
        if status != "done":
            break
    bar.close()
    return {
        "structure": structure,
        "foil_damping": foil_damping,
        "rows": rows,
        "status": status,
        "wall_time_s": time.perf_counter() - t0,
    }


def _onset(rows: list[dict], leg: str, thr: float) -> float | None:
    r = [x for x in rows if x["leg"] == leg]
    amp = np.array([x["xi_max"] - x["xi_min"] for x in r])
    lam = np.array([x["bearing_number"] for x in r])
    if leg == "up":
        i = np.nonzero(amp > thr)[0]
        return float(lam[i[0]]) if len(i) else None
    i = np.nonzero(amp > thr)[0]
    return float(lam[i[-1]]) if len(i) else None


def plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(10, 10), sharex=True, constrained_layout=True)
    styles = {"viscoelastic": "-", "rigid": "-."}
    for res in results:
        r = res["rows"]
        tau = np.array([x["tau"] for x in r])
        ls = styles[res["structure"]]
        lab = res["structure"] + (
            f" (D_W={res['foil_damping']:.3g})" if res["structure"] == "viscoelastic" else ""
        )
        ax[0].plot(tau, [x["bearing_number"] for x in r], "k" + ls, label=lab)
        for k, (name, col) in enumerate(
            (("xi", "tab:red"), ("eta", "tab:blue"), ("p00", "tab:green")), start=1
        ):
            lo = [x[f"{name}_min"] for x in r]
            hi = [x[f"{name}_max"] for x in r]
            ax[k].plot(tau, lo, ls, color=col, lw=0.9)
            ax[k].plot(tau, hi, ls, color=col, lw=0.9, label=lab)
    ax[0].set_ylabel(r"$\Lambda$")
    ax[1].set_ylabel(r"$\xi$ envelope")
    ax[2].set_ylabel(r"$\eta$ envelope")
    ax[3].set_ylabel(r"$P(0,0)$ envelope")
    ax[3].axhline(1.0, color="grey", lw=0.6, ls=":")
    ax[3].set_xlabel(r"$\tau$  (50 000 $\tau$ = 7.95 s)")
    for a in ax:
        a.legend(fontsize=8, loc="upper left")
        a.grid(alpha=0.3)
    ax[0].set_title("Run-up and coast-down (solid: viscoelastic, chain-dotted: rigid)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="33x7 grid, 2 x 1500 tau (for tests)")
    ap.add_argument("--out", default=None, help="output directory (default results/fig5_runup)")
    ap.add_argument("--n-jobs", type=int, default=1, help="run the two cases in parallel (1 or 2)")
    ap.add_argument("--foil-damping", type=float, default=None, help="D_W of the viscoelastic run")
    a = ap.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    out = Path(a.out or ("results/fig5_runup_quick" if a.quick else "results/fig5_runup"))
    out.mkdir(parents=True, exist_ok=True)
    dw = a.foil_damping
    source = "--foil-damping"
    if dw is None:
        try:
            from gfb_env.analysis import optimal_foil_damping

            dw = optimal_foil_damping(GFBModel("viscoelastic").foil_stiffness)
            source = "optimum of the stability map (gfb_env/data/stability_map.csv)"
        except (FileNotFoundError, ValueError):
            dw, source = 4.0, "default 4.0 (no stability map)"
    grid, tau_ramp, window, chunk = (
        ("33x7", 1500.0, 20.0, 500.0) if a.quick else ("79x7", 50_000.0, 100.0, 2000.0)
    )
    from joblib import Parallel, delayed

    t0 = time.perf_counter()
    results = Parallel(n_jobs=a.n_jobs)(
        delayed(run_case)(st, dw, grid, tau_ramp, 0.5, 0.833, window, chunk)
        for st in ("rigid", "viscoelastic")
    )
    with (out / "envelopes.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["structure", "foil_damping", *results[0]["rows"][0].keys()])
        w.writeheader()
        for res in results:
            for r in res["rows"]:
                w.writerow({"structure": res["structure"], "foil_damping": res["foil_damping"], **r})
    summary = {
        "grid": grid,
        "tau_ramp": tau_ramp,
        "foil_damping": dw,
        "foil_damping_source": source,
        "seconds_per_ramp": GFBModel("rigid").bearing.seconds(tau_ramp),
        "wall_time_s": time.perf_counter() - t0,
        "cases": {},
    }
    for res in results:
        rows = res["rows"]
        summary["cases"][res["structure"]] = {
            "status": res["status"],
            "onset_bearing_number_runup": _onset(rows, "up", 0.05),
            "collapse_bearing_number_coastdown": _onset(rows, "down", 0.05),
            "max_xi_peak_to_peak": max(x["xi_max"] - x["xi_min"] for x in rows),
            "max_eta_peak_to_peak": max(x["eta_max"] - x["eta_min"] for x in rows),
            "min_p00": min(x["p00_min"] for x in rows),
            "max_p00": max(x["p00_max"] for x in rows),
            "min_film_thickness": min(x["min_film_thickness"] for x in rows),
            "wall_time_s": res["wall_time_s"],
        }
    (out / "summary.json").write_text(jsonio.dumps(summary, indent=2))
    plot(results, out / "runup_coastdown.png")
    print(jsonio.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
