"""Grid convergence of the static equilibrium (the numbers of the README's "Grid convergence").

Equilibrium eccentricity at Lambda = 0.6 (Table 1; rigid and viscoelastic foil) on grids refined in phi
and in Z, and the relative difference to the finest grid.  Writes
``results/grid_convergence/grid_convergence.csv``.

    python -m gfb_experiments.grid_convergence
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from gfb_env.equilibrium import find_equilibrium
from gfb_env.model import GFBModel, Grid
from gfb_env.scripting import OneLineParser, check_output_dir

GRIDS = [(79, 7), (79, 9), (79, 13), (79, 25), (157, 7), (157, 13), (157, 25), (313, 25)]


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="results/grid_convergence")
    a = p.parse_args(argv)
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            p.error(str(exc))
    rows = []
    for structure in ("rigid", "viscoelastic"):
        eps = {}
        for g in GRIDS:
            m = GFBModel(structure, grid=Grid(*g))
            eps[g] = m.eccentricity(find_equilibrium(m, 0.6))
        ref = eps[GRIDS[-1]]
        for g in GRIDS:
            rows.append(
                {
                    "structure": structure,
                    "grid": f"{g[0]}x{g[1]}",
                    "eccentricity": eps[g],
                    "relative_difference_to_finest": (eps[g] - ref) / ref,
                }
            )
            rel = 100 * (eps[g] - ref) / ref
            print(f"{structure:>12} {g[0]:>3}x{g[1]:<3} eps = {eps[g]:.5f}  ({rel:+.2f} %)")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "grid_convergence.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
