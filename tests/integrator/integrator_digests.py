"""Integrator and v1 env results pinned two ways: golden values everywhere, exact digests per CPU.

Each case runs the integrator (or the v1 envs) and returns a :class:`CaseResult`:

- ``digests``: everything it produced (final state, trajectory, statistics, extremes, events, every
  info entry) as one SHA-256 digest per item, of the float64 bytes.  They prove that a refactoring
  keeps every result bit for bit, but only on the CPU and numba/LLVM/numpy versions that recorded them
  (another CPU gives other last bits): ``data/integrator_digests.json`` (beside this file) holds one
  digest set per platform.
- ``golden``: a few numbers per item (the final state, samples of the trajectory, the extremes, the
  step counts, observations and rewards at a few steps) in ``data/integrator_golden.json``, each with
  a tolerance that holds across CPUs.  The tolerance is measured when the values are written: the
  last-bit differences of another CPU are modelled by relative perturbations of every start state
  (:data:`PERTURBATIONS`), and each item may deviate :data:`TOLERANCE_FACTOR` times as much as they
  moved it (at least a floor; the golden file keeps the measured deviation beside the tolerance).

``test_integrator_digests.py`` (beside this file) checks both in the default suite (exact digests
where this platform recorded a set, the golden values everywhere).  Commands, from ``tests/integrator``::

    python integrator_digests.py write  data [--digests-only]               # golden values, digests
    python integrator_digests.py check  data/integrator_digests.json [--envs]
    python integrator_digests.py check  /work/baseline/integrator.json      # one platform's flat file

``check`` takes a digest file of either shape (one platform's flat ``{case: {item: digest}}``, or the
per-platform list of ``data``, of which it uses this platform's set); ``--envs``: the env case only,
else the integrator cases.  Write the golden values from the code before a refactoring (they are its
reference); ``write data --digests-only`` adds (or replaces) this platform's digests and leaves the
golden values (do it with code that passes the golden test).
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gfb_env.equilibrium import find_equilibrium
from gfb_env.integrator import TrapezoidalIntegrator
from gfb_env.model import GFBModel
from gfb_env.provenance import platform_fingerprint

DATA = Path(__file__).parent / "data"
DIGESTS_FILE = "integrator_digests.json"
GOLDEN_FILE = "integrator_golden.json"
#: entries of one float item kept as golden values (evenly spaced over the flattened item, ends included)
GOLDEN_SAMPLES = 12


def digest(x) -> str:
    """SHA-256 of the float64 (or int64) bytes of ``x``; text for anything that is not numeric."""
    if isinstance(x, str) or x is None:
        payload = repr(x).encode()
    else:
        a = np.asarray(x)
        a = np.ascontiguousarray(a, dtype=np.int64 if a.dtype.kind in "iub" else np.float64)
        payload = repr(a.shape).encode() + a.tobytes()
    return hashlib.sha256(payload).hexdigest()[:16]


@dataclass
class CaseResult:
    """What one case produced: items to digest (bit for bit) and golden items (within a tolerance).

    Golden items: a float array (its size exact, up to :data:`GOLDEN_SAMPLES` entries compared within
    the case's relative tolerance, relative to the item's largest magnitude), ``counts`` (int lists,
    compared within the case's count band: a last-bit change may accept or reject a step more), or
    ``exact`` (text, None or flags: compared exactly).
    """

    digests: dict[str, str] = field(default_factory=dict)
    floats: dict[str, np.ndarray] = field(default_factory=dict)
    counts: dict[str, list[int]] = field(default_factory=dict)
    exact: dict[str, Any] = field(default_factory=dict)

    def __ior__(self, other: CaseResult) -> CaseResult:
        for name in ("digests", "floats", "counts", "exact"):
            getattr(self, name).update(getattr(other, name))
        return self


def _counts(res) -> list[int]:
    st = res.statistics
    return [
        st.steps,
        st.rejected_steps,
        st.newton_failures,
        st.jacobians,
        st.factorizations,
        st.rhs_evaluations,
    ]


def _result_items(prefix: str, it: TrapezoidalIntegrator, res) -> CaseResult:
    tr = res.trajectory
    extremes = [res.min_film_thickness, *res.xi_range, *res.eta_range, res.max_eccentricity]
    td = res.touchdown
    touchdown = None if td is None else [td.tau, td.xi, td.eta, td.min_film_thickness]
    out = CaseResult()
    out.digests = {
        f"{prefix}.state": digest(it.state),
        f"{prefix}.tau": digest(res.tau),
        f"{prefix}.step_size": digest(it.step_size),
        f"{prefix}.status": digest(str(res.status)),
        f"{prefix}.counts": digest(_counts(res)),
        f"{prefix}.extremes": digest(extremes),
        f"{prefix}.touchdown": digest(touchdown),
        f"{prefix}.message": digest(res.message),
    }
    for name in ("tau", "xi", "eta", "xi_dot", "eta_dot", "min_film_thickness", "probes"):
        out.digests[f"{prefix}.trajectory.{name}"] = digest(getattr(tr, name))
    out.digests[f"{prefix}.trajectory.schedule"] = digest([tr.bearing_number, tr.foil_damping])
    out.floats = {
        f"{prefix}.state": it.state,
        f"{prefix}.tau": np.array([res.tau]),
        f"{prefix}.extremes": np.array(extremes),
        f"{prefix}.trajectory.tau": tr.tau,
        f"{prefix}.trajectory.xi": tr.xi,
        f"{prefix}.trajectory.eta": tr.eta,
        f"{prefix}.trajectory.min_film_thickness": tr.min_film_thickness,
        f"{prefix}.trajectory.probes": tr.probes,
    }
    if touchdown is not None:
        out.floats[f"{prefix}.touchdown"] = np.array(touchdown)
    out.counts = {f"{prefix}.counts": _counts(res)}
    out.exact = {f"{prefix}.status": str(res.status), f"{prefix}.touchdown": td is not None}
    return out


def _small(structure: str = "viscoelastic", grid: str = "21x5"):
    m = GFBModel(structure, grid=grid, foil_stiffness=1.0)
    return m, find_equilibrium(m, 0.6)


def case_benchmark() -> CaseResult:
    """The case of ``python -m gfb_experiments.bench_integrator`` (79x7 viscoelastic, tau 0..3000)."""
    from gfb_experiments.convergence_study import benchmark_case

    m, s0 = benchmark_case()
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    return _result_items("benchmark", it, it.advance(3000.0, record_interval=0.05))


def case_ramps() -> CaseResult:
    """Ramps in Lambda and D_W over consecutive calls, with pressure probes recorded."""
    m, s0 = _small()
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4, 0.0, 0.05), 0.6, 1.0)
    probes = m.layout.midplane_probe_indices(3)
    out = CaseResult()
    for k, (t, lam, dw) in enumerate(((40.0, 0.75, 2.0), (41.3, None, None), (90.0, 0.5, 0.7))):
        res = it.advance(t, bearing_number=lam, foil_damping=dw, record_interval=0.25, record_indices=probes)
        out |= _result_items(f"ramps{k}", it, res)
    return out


def case_elastic() -> CaseResult:
    """The elastic foil (dense off-diagonal blocks) with a Lambda ramp."""
    m, s0 = _small("elastic")
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.2, 0.5, 0.05, 0.0), 0.6)
    return _result_items("elastic", it, it.advance(50.0, bearing_number=0.8, record_interval=0.5))


def case_touchdown() -> CaseResult:
    m = GFBModel("rigid", grid="21x5")
    s0 = m.layout.with_rotor(find_equilibrium(m, 0.6), 0.0, 0.6, 0.0, 0.4)  # thrown downwards
    it = TrapezoidalIntegrator(m, s0, 0.6, touchdown_film_thickness=0.3)
    return _result_items("touchdown", it, it.advance(100.0, record_interval=0.1))


def case_failures() -> CaseResult:
    """Step size below min_step, and max_steps reached."""
    m, s0 = _small()
    s0 = m.layout.with_rotor(s0, 0.3, 0.4, 0.2, 0.0)
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0, rtol=1e-14, atol=1e-14, min_step=1e-2)
    out = _result_items("failed", it, it.advance(10.0, raise_on_failure=False, record_interval=0.1))
    it = TrapezoidalIntegrator(m, s0, 0.6, 1.0)
    out |= _result_items("max_steps", it, it.advance(10.0, max_steps=25, raise_on_failure=False))
    return out


def case_snapshot() -> CaseResult:
    """A snapshot in the middle of a run, restored after more steps: the continuation is the same."""
    m, s0 = _small()
    it = TrapezoidalIntegrator(m, m.layout.with_rotor(s0, 0.3, 0.4), 0.6, 1.0)
    it.advance(30.0, bearing_number=0.65)
    snap = it.snapshot()
    out = _result_items("snap_a", it, it.advance(60.0, bearing_number=0.7, record_interval=0.5))
    it.advance(90.0)
    it.restore(snap)
    out |= _result_items("snap_b", it, it.advance(60.0, bearing_number=0.7, record_interval=0.5))
    return out


def _info_digest(info: dict) -> list:
    """The info dict as sorted (key, value) text: every key and value, bit for bit (repr of floats)."""
    return sorted((k, repr(v)) for k, v in info.items())


#: the steps (0: the reset) whose observations are golden values of the v1 env case
ENV_GOLDEN_STEPS = (0, 10, 20, 30, 40)


def case_envs_v1() -> CaseResult:
    """40 random actions (seed 3) in each v1 task, single env and native vector env (3 envs, autoreset):
    observations, rewards, flags and every info entry (golden: observations at a few steps, every
    reward, the flags and the integrator steps).  The v1 ids are retired (issue 19): their envs are built
    for the record by ``make_retired`` / ``make_retired_vec``, the very envs ``gymnasium.make`` gave."""
    from gfb_env.envs.retired import RETIRED_V1_IDS, make_retired, make_retired_vec

    out = CaseResult()
    for env_id in RETIRED_V1_IDS:
        env = make_retired(env_id)
        obs, info = env.reset(seed=3)
        env.action_space.seed(3)
        rows, flags, infos = [obs], [], [_info_digest(info)]
        step_obs, rewards, steps = [obs], [], []
        for _ in range(40):
            obs, rew, term, trunc, info = env.step(env.action_space.sample())
            rows.append(np.append(obs, rew))
            flags.append([term, trunc])
            infos.append(_info_digest(info))
            step_obs.append(obs)
            rewards.append(rew)
            steps.append(info["integrator_steps"])
            if term or trunc:
                obs, info = env.reset()
                rows.append(obs)
                infos.append(_info_digest(info))
        out.digests[f"{env_id}.observations"] = digest(np.concatenate(rows))
        out.digests[f"{env_id}.flags"] = digest(flags)
        out.digests[f"{env_id}.info"] = digest(repr(infos))
        for k in ENV_GOLDEN_STEPS:
            out.floats[f"{env_id}.observation.{k}"] = np.asarray(step_obs[k], dtype=float)
        out.floats[f"{env_id}.rewards"] = np.asarray(rewards, dtype=float)
        out.exact[f"{env_id}.flags"] = [[bool(a), bool(b)] for a, b in flags]
        out.counts[f"{env_id}.integrator_steps"] = [int(v) for v in steps]
        env.close()
        venv = make_retired_vec(env_id, num_envs=3)
        obs, info = venv.reset(seed=5)
        venv.action_space.seed(5)
        rows, infos = [obs.ravel()], [repr(sorted((k, repr(v)) for k, v in info.items()))]
        step_obs, rewards, flags = [obs], [], []
        for _ in range(25):
            obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
            rows.append(np.concatenate([obs.ravel(), rew, term, trunc]))
            infos.append(repr(sorted((k, repr(v)) for k, v in info.items())))
            step_obs.append(obs)
            rewards.append(rew)
            flags.append([[bool(a), bool(b)] for a, b in zip(term, trunc, strict=True)])
        out.digests[f"{env_id}.vector.observations"] = digest(np.concatenate(rows))
        out.digests[f"{env_id}.vector.info"] = digest(repr(infos))
        for k in (0, 12, 25):
            out.floats[f"{env_id}.vector.observation.{k}"] = np.asarray(step_obs[k], dtype=float)
        out.floats[f"{env_id}.vector.rewards"] = np.asarray(rewards, dtype=float)
        out.exact[f"{env_id}.vector.flags"] = flags
        venv.close()
    return out


INTEGRATOR_CASES: dict[str, Callable[[], CaseResult]] = {
    "benchmark": case_benchmark,
    "ramps": case_ramps,
    "elastic": case_elastic,
    "touchdown": case_touchdown,
    "failures": case_failures,
    "snapshot": case_snapshot,
}
ENV_CASES: dict[str, Callable[[], CaseResult]] = {"envs_v1": case_envs_v1}
CASES = INTEGRATOR_CASES | ENV_CASES

#: Golden tolerances are measured per item when the golden values are written
#: (:func:`golden_with_tolerances`): another CPU changes the last bits of every operation, modelled by a
#: relative perturbation ``delta`` of every start state (:func:`_perturbed_starts`).  A short run moves
#: in proportion to delta (< 1e-8 of its scale at 1e-11).  Where a whirl grows from an unstable
#: equilibrium (the 3000-tau benchmark, the env cases' whirls) the growth amplifies any last bit until
#: an accept/reject decision of the step-size controller flips, and from then on the run differs at the
#: level of the error tolerance (3e-4): the deviations saturate (the same at 1e-15 as at 1e-11), the
#: whirl's phase after 3000 tau moves by ~10 % of its amplitude while its extremes move by 1e-5.  So
#: each float item may deviate TOLERANCE_FACTOR times the largest deviation seen (at least a floor:
#: float32 observations round); an item that moved by more than MAX_GOLDEN_TOLERANCE / TOLERANCE_FACTOR
#: is not pinned (the golden file says so, with its deviation; its digest still pins it per platform).
#: A count (steps, rejections, ...) may move by COUNT_FACTOR times its largest deviation, at least
#: COUNT_FLOOR (one decision more or less changes several counts).
PERTURBATIONS = (1e-15, 1e-13, 1e-11)
TOLERANCE_FACTOR = 10.0
MAX_GOLDEN_TOLERANCE = 0.05
FLOAT64_FLOOR = 1e-9
FLOAT32_FLOOR = 1e-6
COUNT_FACTOR = 3.0
COUNT_FLOOR = 2

PLATFORM_KEY = "_platform"


def compute(cases: dict[str, Callable[[], CaseResult]]) -> dict[str, CaseResult]:
    return {name: f() for name, f in cases.items()}


# ------------------------------------------------------------------------------------------------
# golden values
def _sample_index(size: int) -> list[int]:
    if size <= GOLDEN_SAMPLES:
        return list(range(size))
    return sorted({int(round(v)) for v in np.linspace(0, size - 1, GOLDEN_SAMPLES)})


def _scale(a: np.ndarray) -> float:
    """The largest finite magnitude of an item (its deviations are measured against it)."""
    fin = a[np.isfinite(a)]
    return float(np.max(np.abs(fin))) if fin.size else 0.0


def _deviation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| relative to a's scale (inf where the sizes or the non-finite entries differ)."""
    a, b = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    if a.shape != b.shape:
        return math.inf
    fin = np.isfinite(a)
    if not np.array_equal(a[~fin], b[~fin], equal_nan=True) or not np.all(np.isfinite(b[fin])):
        return math.inf
    if not fin.any():
        return 0.0
    return float(np.max(np.abs(a[fin] - b[fin]))) / max(_scale(a), 1e-300)


def _count_deviation(a: list[int], b: list[int]) -> int:
    return max((abs(x - y) for x, y in zip(a, b, strict=True)), default=0) if len(a) == len(b) else 10**9


def golden_of(result: CaseResult) -> dict[str, dict]:
    """The JSON form of a case's golden items, without tolerances (see :func:`golden_with_tolerances`)."""
    out: dict[str, dict] = {}
    for k, v in result.floats.items():
        flat = np.asarray(v).ravel()
        idx = _sample_index(flat.size)
        values = [float(flat[i]) if np.isfinite(flat[i]) else repr(float(flat[i])) for i in idx]
        out[k] = {"size": flat.size, "index": idx, "values": values, "scale": _scale(flat.astype(float))}
        out[k]["float32"] = np.asarray(v).dtype == np.float32
    for k, v in result.counts.items():
        out[k] = {"counts": list(v)}
    for k, v in result.exact.items():
        out[k] = {"exact": v}
    return out


def golden_with_tolerances(ref: CaseResult, perturbed: list[CaseResult]) -> dict[str, dict]:
    """:func:`golden_of` ``ref`` with each item's tolerance from its deviations in the ``perturbed``
    runs (see :data:`PERTURBATIONS`); an exact item that changed there is refused (it cannot be golden)."""
    out = golden_of(ref)
    for k, g in out.items():
        if "exact" in g:
            changed = [p for p in perturbed if p.exact[k] != ref.exact[k]]
            if changed:
                raise RuntimeError(f"{k} changes under perturbed starts: it cannot be an exact golden item")
        elif "counts" in g:
            devs = [
                max((abs(x - p.counts[k][i]) for p in perturbed), default=0)
                for i, x in enumerate(g["counts"])
            ]
            g["band"] = [max(COUNT_FLOOR, int(math.ceil(COUNT_FACTOR * d))) for d in devs]
        else:
            dev = max((_deviation(ref.floats[k], p.floats[k]) for p in perturbed), default=0.0)
            if not math.isfinite(dev):
                raise RuntimeError(f"{k} changes its size or non-finite entries under perturbed starts")
            floor = FLOAT32_FLOOR if g["float32"] else FLOAT64_FLOOR
            g["measured_deviation"] = dev
            rel = float(f"{max(floor, TOLERANCE_FACTOR * dev):.2g}")
            if rel > MAX_GOLDEN_TOLERANCE:
                out[k] = {"unpinned": f"deviates by {dev:.3g} of its scale under perturbed starts"}
            else:
                g["rel"] = rel
    return out


def golden_differences(result: CaseResult, want: dict[str, dict]) -> list[str]:
    """One line per golden item of ``want`` that ``result`` misses or does not match within its tolerance."""
    bad = []
    got = golden_of(result)
    for k in sorted(want.keys() | got.keys()):
        w, g = want.get(k), got.get(k)
        if w is None or g is None:
            bad.append(f"{k}: {'not recorded' if w is None else 'missing'}")
        elif "unpinned" in w:
            continue
        elif "exact" in w:
            if g.get("exact") != w["exact"]:
                bad.append(f"{k}: {g.get('exact')!r} != {w['exact']!r}")
        elif "counts" in w:
            gc, wc = g.get("counts", []), w["counts"]
            if len(gc) != len(wc) or any(abs(a - b) > d for a, b, d in zip(gc, wc, w["band"], strict=True)):
                bad.append(f"{k}: counts {gc} not within {w['band']} of {wc}")
        elif g.get("size") != w["size"]:
            bad.append(f"{k}: size {g.get('size')} != {w['size']}")
        else:
            x = np.asarray(result.floats[k], dtype=float).ravel()[w["index"]]
            y = np.array([float(v) for v in w["values"]])
            limit = w["rel"] * max(w["scale"], 1e-300)
            fin = np.isfinite(y)
            dev = np.zeros_like(y)
            dev[fin] = np.abs(x[fin] - y[fin])
            ok = np.array_equal(x[~fin], y[~fin], equal_nan=True) and bool(np.all(dev <= limit))
            if not ok:  # (a NaN deviation fails the <= as well)
                i = int(np.argmax(np.where(dev <= limit, -1.0, np.inf)))
                bad.append(
                    f"{k}[{w['index'][i]}]: {x[i]!r} != {y[i]!r} (deviation {abs(x[i] - y[i]):.3g} > "
                    f"{limit:.3g} = {w['rel']:g} x scale {w['scale']:.3g})"
                )
    return bad


# ------------------------------------------------------------------------------------------------
# exact digests
def platform_digests(records: list[dict], here: dict[str, str] | None = None) -> dict[str, dict] | None:
    """The digest set recorded on this platform (``None``: none was)."""
    here = platform_fingerprint() if here is None else here
    for r in records:
        if r[PLATFORM_KEY] == here:
            return r["cases"]
    return None


def digest_differences(got: dict[str, CaseResult], want: dict[str, dict[str, str]]) -> list[tuple[str, str]]:
    flat = {(c, k): v for c, d in want.items() for k, v in d.items()}
    flat_got = {(c, k): v for c, r in got.items() for k, v in r.digests.items()}
    return sorted(k for k in flat.keys() | flat_got.keys() if flat.get(k) != flat_got.get(k))


# ------------------------------------------------------------------------------------------------
def _perturbed_starts(delta: float):
    """A context in which every :meth:`TrapezoidalIntegrator.reset` (the constructor's too) starts from
    ``s (1 + delta w)`` with a fixed pattern ``w`` in [-1, 1]: a model of another CPU's last bits."""
    import contextlib

    @contextlib.contextmanager
    def ctx():
        original = TrapezoidalIntegrator.reset

        def reset(self, state, *args, **kwargs):
            s = np.asarray(state, dtype=float)
            w = np.sin(np.arange(s.size) * 0.7 + 1.0).reshape(s.shape)
            return original(self, s * (1.0 + delta * w), *args, **kwargs)

        TrapezoidalIntegrator.reset = reset
        try:
            yield
        finally:
            TrapezoidalIntegrator.reset = original

    return ctx()


def perturbed(cases: dict[str, Callable[[], CaseResult]]) -> list[dict[str, CaseResult]]:
    """The cases run once per :data:`PERTURBATIONS` size."""
    runs = []
    for delta in PERTURBATIONS:
        with _perturbed_starts(delta):
            runs.append(compute(cases))
    return runs


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("write", "check"):
        print(__doc__)
        return 2
    path = Path(argv[1])
    if argv[0] == "write":
        got = compute(CASES)
        path.mkdir(parents=True, exist_ok=True)
        if "--digests-only" not in argv:
            runs = perturbed(CASES)
            golden = {c: golden_with_tolerances(r, [p[c] for p in runs]) for c, r in got.items()}
            (path / GOLDEN_FILE).write_text(json.dumps(golden, indent=1, sort_keys=True) + "\n")
            print(f"wrote the golden values of {len(golden)} cases to {path / GOLDEN_FILE}")
        here = platform_fingerprint()
        dfile = path / DIGESTS_FILE
        records = json.loads(dfile.read_text()) if dfile.exists() else []
        records = [r for r in records if r[PLATFORM_KEY] != here]
        records.append({PLATFORM_KEY: here, "cases": {c: r.digests for c, r in got.items()}})
        dfile.write_text(json.dumps(records, indent=1, sort_keys=True) + "\n")
        print(f"wrote {sum(len(r.digests) for r in got.values())} digests for {here['cpu']} to {dfile}")
        return 0
    envs = "--envs" in argv
    got = compute(ENV_CASES if envs else INTEGRATOR_CASES)
    want = json.loads(path.read_text())
    if isinstance(want, list):
        want = platform_digests(want)
        if want is None:
            print(f"{path} has no digests for this platform ({platform_fingerprint()})")
            return 1
    else:
        want.pop(PLATFORM_KEY, None)
    want = {c: d for c, d in want.items() if c in got}
    bad = digest_differences(got, want)
    n = sum(len(d) for d in want.values())
    print(f"{n} digests checked, {len(bad)} differ" + "".join(f"\n  {c}: {k}" for c, k in bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
