"""Paper Fig. 7: FFT of an under-, a critically and an over-damped whirl (K_W = 1, Lambda = 0.6).

The viscoelastic foil with D_W = 1 (under-damped), 4 (near the optimum, "critical") and 16 (over-damped);
each run starts from the previous settled whirl (D_W ascending), integrates until the orbit settles and
then records ``tail`` tau more at dtau = 0.25; the Hann-windowed amplitude spectrum of xi
(:func:`gfb_env.analysis.amplitude_spectrum`) is plotted against omega / Lambda.

    python -m gfb_experiments.fig7_fft [--quick] [--out results/fig7_fft]
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from gfb_env import GFBModel, Grid, TrapezoidalIntegrator, jsonio
from gfb_env.analysis import amplitude_spectrum, dominant_frequency, settle_whirl
from gfb_env.scripting import OneLineParser, check_output_dir

LAMBDA = 0.6
K_W = 1.0
DT = 0.25


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="33x7 grid, D_W = 4, 16, short (tests)")
    ap.add_argument("--out", default=None, help="output directory (default results/fig7_fft)")
    a = ap.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    out = Path(a.out or ("results/fig7_fft_quick" if a.quick else "results/fig7_fft"))
    out.mkdir(parents=True, exist_ok=True)
    grid = Grid.parse("33x7" if a.quick else "79x7")
    tail = 400.0 if a.quick else 1600.0
    labels = {1.0: "under-damped", 4.0: "critically damped", 16.0: "over-damped"}
    if a.quick:  # the coarse grid closes the film of the weakly damped whirl
        labels = {4.0: "critically damped", 16.0: "over-damped"}
    model = GFBModel("viscoelastic", grid, foil_stiffness=K_W)
    t0 = time.perf_counter()
    state = None
    rows, spectra = [], []
    for dw, label in tqdm(labels.items(), desc="fig7"):
        sw = settle_whirl(
            model,
            LAMBDA,
            dw,
            state=state,
            kick=0.3,
            tau_max=1500 if a.quick else 8000,
            window=100.0,
            integrator_options={"touchdown_film_thickness": 1e-4},
        )
        integ = TrapezoidalIntegrator(model, sw.state, LAMBDA, dw, touchdown_film_thickness=1e-4)
        res = integ.advance(tail, record_interval=DT, raise_on_failure=False)
        xi = res.trajectory.xi
        row = {
            "foil_damping": dw,
            "label": label,
            "status": sw.status,
            "max_eccentricity": math.nan,
            "omega": math.nan,
            "ratio": math.nan,
            "amplitude": math.nan,
        }
        if len(xi) > 16 and np.ptp(xi) > 1e-3:
            df = dominant_frequency(xi, DT, fraction=1.0, bearing_number=LAMBDA)
            sp = amplitude_spectrum(xi, DT, fraction=1.0)
            spectra.append((dw, label, sp))
            row.update(
                {
                    "max_eccentricity": float(res.trajectory.eccentricity.max()),
                    "omega": df.omega,
                    "ratio": df.ratio,
                    "amplitude": df.amplitude,
                }
            )
            state = integ.state
        rows.append(row)
    with (out / "fft_peaks.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with (out / "spectra.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["foil_damping", "omega_over_lambda", "amplitude"])
        for dw, _, sp in spectra:
            keep = sp.omega / LAMBDA <= 3.0
            for om, am in zip(sp.omega[keep], sp.amplitude[keep]):
                w.writerow([dw, f"{om / LAMBDA:.5f}", f"{am:.6g}"])
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    for dw, label, sp in spectra:
        ax.plot(sp.omega / LAMBDA, sp.amplitude, label=f"{label}, $D_W$={dw:g}")
    ax.axvline(0.5, color="grey", ls=":", lw=1, label=r"$\omega=\Lambda/2$")
    ax.set_xlim(0, 2.0)
    ax.set_xlabel(r"$\omega / \Lambda$")
    ax.set_ylabel(r"amplitude of $\xi$")
    ax.set_title(rf"Fig. 7: FFT of $\xi$, $K_W$={K_W:g}, $\Lambda$={LAMBDA}, grid {grid}")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.savefig(out / "fft.png", dpi=110)
    plt.close(fig)
    (out / "summary.json").write_text(
        jsonio.dumps({"grid": str(grid), "peaks": rows, "wall_time_s": time.perf_counter() - t0}, indent=2)
    )
    for r in rows:
        print(r)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
