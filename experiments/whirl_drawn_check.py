"""Can a machine with a drawn bearing whirl steadily where WhirlRecovery starts?  The measurement before a
WhirlRecovery task on a drawn bearing is built (issue 19 s.3; docs/task_redesign.md, "WhirlRecovery on a
drawn bearing").

    python -m gfb_experiments.whirl_drawn_check [--seeds 40] [--factor 1.03] [--gain G] [--steps 30]
        [--out FILE.json]

For each DEV seed: the bearing RunUpRandomized-v2 draws (C, f_K, F_L; its model and its table's
lambda_best and d_opt), the damping gain g (``--gain``, or log-uniform in WhirlRecovery-v2's [0.6, 1.8]
from the seed), the speed ``--factor`` x lambda_best of the drawn plant and the actual damping g d_opt.
The plant starts from WhirlRecovery-v2's stored whirl state (the nominal plant's cycle, in units of C) and
is held there for ``--steps`` control steps of 60 tau: does it touch down (the step), and how large is the
orbit (half the larger of the xi and eta ranges of the step, units of C) after 10 steps and at the end.
DEV seeds only: nothing here is a benchmark number.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from gfb_env.scripting import OneLineParser, check_output_dir

__all__ = ["hold_whirl", "main"]

GAIN_RANGE = (0.6, 1.8)  # WhirlRecovery-v2's prior of g


def hold_whirl(seed: int, factor: float, gain: float | None, steps: int, rr=None, wr=None) -> dict:
    """One drawn plant held in the whirl (module docstring); ``rr``, ``wr``: the unwrapped
    RunUpRandomized-v2 and WhirlRecovery-v2 envs to reuse."""
    from gfb_env.envs import make_env

    rr = rr or make_env("gfb_env/RunUpRandomized-v2").unwrapped
    wr = wr or make_env("gfb_env/WhirlRecovery-v2").unwrapped
    rr.reset(seed=seed)
    t, model, b = rr.episode.task, rr.episode.model, rr.episode.bearing
    best = rr.table(t.clearance_m, t.stiffness_factor, t.load_n)
    if gain is None:
        gain = math.exp(np.random.default_rng(seed).uniform(*np.log(GAIN_RANGE)))
    lam_w = factor * best["lambda_best"]
    integ = rr.new_integrator(model, wr._whirl_state.copy(), lam_w, gain * best["d_opt"])  # noqa: SLF001
    amps, touchdown = [], None
    t0 = time.perf_counter()
    for k in range(steps):
        res = integ.advance(integ.tau + 60.0, raise_on_failure=False)
        if res.touchdown or not math.isfinite(res.max_eccentricity):
            touchdown = k + 1
            break
        amps.append(0.5 * max(res.xi_range[1] - res.xi_range[0], res.eta_range[1] - res.eta_range[0]))
    return {
        "seed": seed,
        "clearance_um": round(t.clearance_m * 1e6, 2),
        "stiffness_factor": round(t.stiffness_factor, 4),
        "load_n": round(t.load_n, 2),
        "gain": round(gain, 4),
        "speed_rpm": round(b.speed_rpm_at(lam_w), 0),
        "best_speed_rpm": round(b.speed_rpm_at(best["lambda_best"]), 0),
        "foil_damping": round(gain * best["d_opt"], 4),
        "touchdown_step": touchdown,
        "orbit_after_10": round(amps[9], 4) if len(amps) >= 10 else None,
        "orbit_last": round(amps[-1], 4) if amps else None,
        "wall_s": round(time.perf_counter() - t0, 3),
    }


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(
        prog="python -m gfb_experiments.whirl_drawn_check", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--seeds", type=int, default=40, help="DEV seeds 0..N-1 (default 40)")
    ap.add_argument("--factor", type=float, default=1.03, help="speed / lambda_best of the drawn plant")
    ap.add_argument("--gain", type=float, default=None, help="g for every seed (default: drawn per seed)")
    ap.add_argument("--steps", type=int, default=30, help="control steps held (default 30)")
    ap.add_argument("--out", default=None, help="JSON file to write")
    a = ap.parse_args(argv)
    if a.seeds < 1 or a.steps < 10:
        ap.error(f"--seeds must be >= 1 and --steps >= 10, got {a.seeds}, {a.steps}")
    if not (math.isfinite(a.factor) and a.factor > 0):
        ap.error(f"--factor must be a positive number, got {a.factor}")
    if a.gain is not None and not (math.isfinite(a.gain) and a.gain > 0):
        ap.error(f"--gain must be a positive number, got {a.gain}")
    if a.out is not None:
        try:
            check_output_dir(str(Path(a.out).parent), "--out")
        except ValueError as exc:
            ap.error(str(exc))
    from gfb_env.envs import make_env

    rr, wr = make_env("gfb_env/RunUpRandomized-v2").unwrapped, make_env("gfb_env/WhirlRecovery-v2").unwrapped
    rows = [hold_whirl(s, a.factor, a.gain, a.steps, rr, wr) for s in range(a.seeds)]
    steady = [r["orbit_last"] for r in rows if r["touchdown_step"] is None]
    summary = {
        "factor": a.factor,
        "gain": a.gain if a.gain is not None else f"log-uniform {GAIN_RANGE}",
        "seeds": a.seeds,
        "steps": a.steps,
        "touchdowns": sum(r["touchdown_step"] is not None for r in rows),
        "touchdown_steps": sorted(r["touchdown_step"] for r in rows if r["touchdown_step"] is not None),
        "steady_orbit_range": [min(steady), max(steady)] if steady else [],
        "best_speed_rpm_range": [
            min(r["best_speed_rpm"] for r in rows),
            max(r["best_speed_rpm"] for r in rows),
        ],
    }
    print(json.dumps(summary))
    if a.out is not None:
        with open(a.out, "w") as fh:
            json.dump(
                {
                    "command": "python -m gfb_experiments.whirl_drawn_check "
                    + " ".join(sys.argv[1:] if argv is None else argv),
                    "summary": summary,
                    "rows": rows,
                },
                fh,
                indent=1,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
