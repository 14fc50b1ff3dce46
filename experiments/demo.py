"""The main job end to end (``make demo``): the paper's bearing from parameters to whirl.

Stages (each writes into ``--out``):
1. Table 1 in nondimensional form (``params.json``).
2. Static equilibria of the rigid, elastic and viscoelastic foil at 36 000 rpm (``equilibria.json``).
3. A transient run of the viscoelastic bearing (K_W = 1, D_W = 1, Lambda = 0.6) from the slightly
   perturbed equilibrium into the self-excited whirl: ``simulate/trajectory.csv``, ``simulation.png``,
   ``summary.json`` (the same as ``gfb simulate``).
Later stages (stability map, environments, agents) are added by their modules when present.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gfb_env.cli import equilibrium_summary
from gfb_env.cli import main as gfb_main
from gfb_env.integrator import find_equilibrium
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters


def run(out: Path, duration: float) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    b = BearingParameters()
    params = {
        "time_scale_s": b.time_scale_s,
        "bearing_number_36000rpm": b.bearing_number,
        "mass_parameter": b.mass_parameter,
        "gravity_parameter": b.gravity_parameter,
        "foil_stiffness": b.foil_stiffness,
        "kappa": b.kappa,
    }
    (out / "params.json").write_text(json.dumps(params, indent=2))
    print("== Table 1, nondimensional:", json.dumps({k: round(v, 6) for k, v in params.items()}))
    eq = {}
    lam = b.bearing_number
    for structure in ("rigid", "elastic", "viscoelastic"):
        m = GFBModel(structure)
        eq[structure] = equilibrium_summary(m, find_equilibrium(m, lam), lam)
        e = eq[structure]
        print(
            f"== equilibrium {structure:>12}: eps = {e['eccentricity']:.4f} ({e['eccentricity_um']:.1f} um), "
            f"gamma = {e['attitude_angle_deg']:.1f} deg, H_min = {e['min_film_thickness']:.3f}, "
            f"force/load = {e['bearing_force'] / e['load']:.6f}"
        )
    (out / "equilibria.json").write_text(json.dumps(eq, indent=2))
    print("== transient: viscoelastic K_W=1, D_W=1, Lambda=0.6, from the perturbed equilibrium")
    code = gfb_main(
        [
            "simulate",
            "--structure",
            "viscoelastic",
            "--bearing-number",
            "0.6",
            "--foil-stiffness",
            "1",
            "--foil-damping",
            "1",
            "--duration",
            str(duration),
            "--out",
            str(out / "simulate"),
        ]
    )
    if code != 0:
        raise SystemExit(code)
    summary = json.loads((out / "simulate" / "summary.json").read_text())
    print(f"== demo done in {time.perf_counter() - t0:.1f} s; outputs in {out}")
    return summary


def cli() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="results/demo", help="output directory (default: %(default)s)")
    p.add_argument("--duration", type=float, default=2000.0, help="tau of the transient run (default: 2000)")
    a = p.parse_args()
    run(Path(a.out), a.duration)


if __name__ == "__main__":
    cli()
