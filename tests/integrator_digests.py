"""SHA-256 digests of integrator results, to prove that a refactoring keeps every trajectory bit for bit.

Each case runs the integrator (or an env) and reduces everything it produced (final state, trajectory,
statistics, extremes, events) to one digest per item.  ``tests/test_integrator_digests.py`` compares the
integrator cases with ``tests/data/integrator_digests.json``; the env cases are for a manual before/after
check (the envs are being rewritten, so their numbers are not pinned in the default suite)::

    python tests/integrator_digests.py write  tests/data/integrator_digests.json        # integrator cases
    python tests/integrator_digests.py write  /tmp/envs.json --envs                     # env cases only
    python tests/integrator_digests.py check  tests/data/integrator_digests.json [--envs]

The digests are of float64 bytes: they hold on one machine and numba/LLVM version (a different CPU or
compiler may change the last bits; regenerate them then, after checking that nothing else changed).
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.provenance import platform_fingerprint


def digest(x) -> str:
    """SHA-256 of the float64 (or int64) bytes of ``x``; text for anything that is not numeric."""
    if isinstance(x, str) or x is None:
        payload = repr(x).encode()
    else:
        a = np.asarray(x)
        a = np.ascontiguousarray(a, dtype=np.int64 if a.dtype.kind in "iub" else np.float64)
        payload = repr(a.shape).encode() + a.tobytes()
    return hashlib.sha256(payload).hexdigest()[:16]


def _result_items(prefix: str, it: TrapezoidalIntegrator, res) -> dict[str, str]:
    tr = res.trajectory
    out = {
        f"{prefix}.state": digest(it.state),
        f"{prefix}.tau": digest(res.tau),
        f"{prefix}.step_size": digest(it.step_size),
        f"{prefix}.status": digest(str(res.status)),
        f"{prefix}.counts": digest(
            [res.steps, res.rejected_steps, res.newton_failures, res.jacobians, res.factorizations]
            + [res.rhs_evaluations]
        ),
        f"{prefix}.extremes": digest(
            [res.min_film_thickness, *res.xi_range, *res.eta_range, res.max_eccentricity]
        ),
        f"{prefix}.touchdown": digest(
            None
            if res.touchdown is None
            else [res.touchdown.tau, res.touchdown.xi, res.touchdown.eta, res.touchdown.min_film_thickness]
        ),
        f"{prefix}.message": digest(res.message),
    }
    for name in ("tau", "xi", "eta", "xi_dot", "eta_dot", "min_film_thickness", "probes"):
        out[f"{prefix}.trajectory.{name}"] = digest(getattr(tr, name))
    out[f"{prefix}.trajectory.schedule"] = digest([tr.bearing_number, tr.foil_damping])
    return out


def _small(structure: str = "viscoelastic", grid: str = "21x5"):
    m = GFBModel(structure, grid=grid, foil_stiffness=1.0)
    return m, find_equilibrium(m, 0.6)


def case_benchmark() -> dict[str, str]:
    """The case of ``python -m gfb_experiments.bench_integrator`` (79x7 viscoelastic, tau 0..3000)."""
    from gfb_experiments.convergence_study import benchmark_case

    m, s0 = benchmark_case()
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    return _result_items("benchmark", it, it.advance(3000.0, record_interval=0.05))


def case_ramps() -> dict[str, str]:
    """Ramps in Lambda and D_W over consecutive calls, with pressure probes recorded."""
    m, s0 = _small()
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4, 0.0, 0.05), 0.6, 1.0)
    probes = m.layout.midplane_probe_indices(3)
    out = {}
    for k, (t, lam, dw) in enumerate(((40.0, 0.75, 2.0), (41.3, None, None), (90.0, 0.5, 0.7))):
        res = it.advance(t, bearing_number=lam, foil_damping=dw, record_interval=0.25, record_indices=probes)
        out |= _result_items(f"ramps{k}", it, res)
    return out


def case_elastic() -> dict[str, str]:
    """The elastic foil (dense off-diagonal blocks) with a Lambda ramp."""
    m, s0 = _small("elastic")
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.2, 0.5, 0.05, 0.0), 0.6)
    return _result_items("elastic", it, it.advance(50.0, bearing_number=0.8, record_interval=0.5))


def case_touchdown() -> dict[str, str]:
    m = GFBModel("rigid", grid="21x5")
    s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.0, 0.6, 0.0, 0.4)  # thrown downwards
    it = TrapezoidalIntegrator(m, s0, 0.6, touchdown_film_thickness=0.3)
    return _result_items("touchdown", it, it.advance(100.0, record_interval=0.1))


def case_failures() -> dict[str, str]:
    """Step size below min_step, and max_steps reached."""
    m, s0 = _small()
    s0 = m.layout.with_rotor(s0, 0.3, 0.4, 0.2, 0.0)
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0, rtol=1e-14, atol=1e-14, min_step=1e-2)
    out = _result_items("failed", it, it.advance(10.0, raise_on_failure=False, record_interval=0.1))
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    out |= _result_items("max_steps", it, it.advance(10.0, max_steps=25, raise_on_failure=False))
    return out


def case_snapshot() -> dict[str, str]:
    """get_state / set_state in the middle of a run: the continuation is the same."""
    m, s0 = _small()
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4), 0.6, 1.0)
    it.advance(30.0, bearing_number=0.65)
    snap = it.get_state()
    out = _result_items("snap_a", it, it.advance(60.0, bearing_number=0.7, record_interval=0.5))
    it.advance(90.0)
    it.set_state(snap)
    out |= _result_items("snap_b", it, it.advance(60.0, bearing_number=0.7, record_interval=0.5))
    return out


def case_envs() -> dict[str, str]:
    """30 random actions (seed 0) in each v0 task (retired ids: kept only for the record)."""
    import gymnasium as gym

    import gfb_env  # noqa: F401  (registers the tasks)

    out = {}
    for env_id in ("gfb_env/RunUp-v0", "gfb_env/RunUpRandomized-v0", "gfb_env/WhirlRecovery-v0"):
        env = gym.make(env_id)
        obs, _ = env.reset(seed=0)
        env.action_space.seed(0)
        rows, flags, steps = [obs], [], []
        for _ in range(30):
            obs, rew, term, trunc, info = env.step(env.action_space.sample())
            rows.append(np.append(obs, rew))
            flags.append([term, trunc])
            steps.append(info["integrator_steps"])
            if term or trunc:
                obs, _ = env.reset()
                rows.append(obs)
        out[f"{env_id}.observations"] = digest(np.concatenate(rows))
        out[f"{env_id}.flags"] = digest(flags)
        out[f"{env_id}.integrator_steps"] = digest(steps)
        env.close()
    return out


def _info_digest(info: dict) -> list:
    """The info dict as sorted (key, value) text: every key and value, bit for bit (repr of floats)."""
    return sorted((k, repr(v)) for k, v in info.items())


def case_envs_v1() -> dict[str, str]:
    """40 random actions (seed 3) in each v1 task, single env and native vector env (3 envs, autoreset):
    observations, rewards, flags and every info entry."""
    import gymnasium as gym

    import gfb_env  # noqa: F401  (registers the tasks)

    out = {}
    for env_id in ("gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"):
        env = gym.make(env_id)
        obs, info = env.reset(seed=3)
        env.action_space.seed(3)
        rows, flags, infos = [obs], [], [_info_digest(info)]
        for _ in range(40):
            obs, rew, term, trunc, info = env.step(env.action_space.sample())
            rows.append(np.append(obs, rew))
            flags.append([term, trunc])
            infos.append(_info_digest(info))
            if term or trunc:
                obs, info = env.reset()
                rows.append(obs)
                infos.append(_info_digest(info))
        out[f"{env_id}.observations"] = digest(np.concatenate(rows))
        out[f"{env_id}.flags"] = digest(flags)
        out[f"{env_id}.info"] = digest(repr(infos))
        env.close()
        venv = gym.make_vec(env_id, num_envs=3)
        obs, info = venv.reset(seed=5)
        venv.action_space.seed(5)
        rows, infos = [obs.ravel()], [repr(sorted((k, repr(v)) for k, v in info.items()))]
        for _ in range(25):
            obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
            rows.append(np.concatenate([obs.ravel(), rew, term, trunc]))
            infos.append(repr(sorted((k, repr(v)) for k, v in info.items())))
        out[f"{env_id}.vector.observations"] = digest(np.concatenate(rows))
        out[f"{env_id}.vector.info"] = digest(repr(infos))
        venv.close()
    return out


INTEGRATOR_CASES: dict[str, Callable[[], dict[str, str]]] = {
    "benchmark": case_benchmark,
    "ramps": case_ramps,
    "elastic": case_elastic,
    "touchdown": case_touchdown,
    "failures": case_failures,
    "snapshot": case_snapshot,
}


PLATFORM_KEY = "_platform"


def compute(envs: bool = False) -> dict[str, dict[str, str]]:
    """``{case: {item: digest}}`` for the integrator cases, or for the env cases."""
    cases = {"envs_v1": case_envs_v1} if envs else INTEGRATOR_CASES
    return {name: f() for name, f in cases.items()}


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("write", "check"):
        print(__doc__)
        return 2
    path = Path(argv[1])
    got = compute(envs="--envs" in argv)
    if argv[0] == "write":
        path.parent.mkdir(parents=True, exist_ok=True)
        got[PLATFORM_KEY] = platform_fingerprint()
        path.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
        print(f"wrote {sum(map(len, got.values()))} digests to {path}")
        return 0
    want = json.loads(path.read_text())
    want.pop(PLATFORM_KEY, None)
    flat = {(c, k): v for c, d in want.items() for k, v in d.items()}
    flat_got = {(c, k): v for c, d in got.items() for k, v in d.items()}
    bad = sorted(k for k in flat.keys() | flat_got.keys() if flat.get(k) != flat_got.get(k))
    print(f"{len(flat)} digests checked, {len(bad)} differ" + "".join(f"\n  {c}: {k}" for c, k in bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
