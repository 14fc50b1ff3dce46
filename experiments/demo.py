"""The main job end to end (``make demo``): the paper's bearing from parameters to whirl.

Stages (each writes into ``--out``):
1. Table 1 in nondimensional form (``params.json``).
2. Static equilibria of the rigid, elastic and viscoelastic foil at 36 000 rpm (``equilibria.json``).
3. A transient run of the viscoelastic bearing (K_W = 1, D_W = 1, Lambda = 0.6) from the slightly
   perturbed equilibrium into the self-excited whirl: ``simulate/trajectory.csv``, ``simulation.png``,
   ``summary.json`` (the same as ``gfb simulate``).
4. Linear stability: the critical bearing number Lambda_c of the rigid foil and of the viscoelastic
   foil (K_W = 1) at two dampings (``critical.json``), as ``gfb critical`` computes it.
5. The control task: one seeded ``gfb_env/RunUp-v2`` episode (the instrumented machine: actuator lag,
   noisy probes, shocks, unbalance, a hidden damping gain, a speed command) flown by the ``margin_search``
   rule, with its path and a rendered frame (``runup_episode.json``, ``runup_frame.png``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gfb_env import jsonio
from gfb_env.cli import main as gfb_main
from gfb_env.equilibrium import equilibrium_summary, find_equilibrium
from gfb_env.model import GFBModel
from gfb_env.params import BearingParameters
from gfb_env.scripting import OneLineParser, check_output_dir


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
    (out / "params.json").write_text(jsonio.dumps(params, indent=2))
    print("== Table 1, nondimensional:", jsonio.dumps({k: round(v, 6) for k, v in params.items()}))
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
    (out / "equilibria.json").write_text(jsonio.dumps(eq, indent=2))
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
    summary["critical"] = critical_stage(out)
    summary["runup_episode"] = runup_stage(out)
    print(f"== demo done in {time.perf_counter() - t0:.1f} s; outputs in {out}")
    return summary


def critical_stage(out: Path) -> list[dict]:
    from gfb_env.analysis import critical_bearing_number

    rows = []
    for structure, kw, dw in (("rigid", None, 1.0), ("viscoelastic", 1.0, 1.0), ("viscoelastic", 1.0, 4.0)):
        cp = critical_bearing_number(GFBModel(structure, foil_stiffness=kw), foil_damping=dw)
        rows.append(cp.as_dict())
        print(
            f"== Lambda_c {structure:>12} K_W={cp.foil_stiffness:.3g} D_W={dw:g}: "
            f"{cp.critical_bearing_number:.4f} ({cp.critical_speed_rpm:.0f} rpm), "
            f"whirl ratio {cp.whirl_frequency_ratio:.3f}"
        )
    (out / "critical.json").write_text(jsonio.dumps(rows, indent=2))
    return rows


def runup_stage(out: Path, seed: int = 0) -> dict:
    import gymnasium as gym

    from gfb_agents.ladder import build
    from gfb_agents.learned.evaluate import run_episode

    env = gym.make("gfb_env/RunUp-v2", render_mode="rgb_array")
    # the benchmark's best rule on this task (README): it estimates the hidden damping gain on the way
    agent = build("margin_search", env)
    res = run_episode(env, agent, seed=seed, record_path=True)
    frame = env.render()
    env.close()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.imsave(out / "runup_frame.png", frame)
    d = {
        "agent": agent.name,
        "seed": seed,
        "return": res.episode_return,
        "steps": res.steps,
        "termination_reason": res.termination_reason,
        "time_to_target_s": res.time_to_target_s,
        "final_speed_rpm": res.final_speed_rpm,
        "max_whirl_amplitude": res.max_whirl_amplitude,
        "path_bearing_number": res.path_bearing_number,
        "path_foil_damping": res.path_damping,
    }
    (out / "runup_episode.json").write_text(jsonio.dumps(d, indent=2))
    print(
        f"== RunUp-v2 with {agent.name}: {res.termination_reason} after {res.steps} steps, return "
        f"{res.episode_return:.1f}, final speed {res.final_speed_rpm:.0f} rpm"
    )
    return {k: v for k, v in d.items() if not k.startswith("path")}


def cli() -> None:
    p = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="results/demo", help="output directory (default: %(default)s)")
    p.add_argument("--duration", type=float, default=2000.0, help="tau of the transient run (default: 2000)")
    a = p.parse_args()
    if a.out is not None:  # before any work: an unwritable --out fails now
        try:
            check_output_dir(str(a.out), "--out")
        except ValueError as exc:
            p.error(str(exc))
    run(Path(a.out), a.duration)


if __name__ == "__main__":
    cli()
