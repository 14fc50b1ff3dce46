"""SHA-256 digests of the v1 agents' actions and rewards, to prove that a refactoring of ``gfb_agents`` keeps
every agent's behaviour bit for bit.

Every v1 ladder agent (naive, the rules, the oracle and the first run of every committed learned policy) plays
the first ``STEPS`` control steps of two development seeds of each v1 task it applies to, through the
agents' public interface only (the ladder builds it; ``reset``, the oracle's reset info, ``predict``), as
:func:`gfb_agents.learned.evaluate.run_episode` plays it.  Each episode is reduced to digests of its
actions, its rewards and its end (terminated / truncated / reason).  A manual before/after check (like
the env cases of ``integrator_digests.py``)::

    python tests/agents/agents_digests.py write /tmp/agents_v1.json
    python tests/agents/agents_digests.py check /tmp/agents_v1.json

The digests are of float64 bytes: they hold on one machine and numba/LLVM version.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

# the digest helpers live beside the integrator's tests (tests/integrator/integrator_digests.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrator"))
from integrator_digests import PLATFORM_KEY, digest  # noqa: E402

from gfb_env.envs.retired import make_retired  # the v1 ids are retired: their envs for the record

#: control steps per episode (the whole v1 episode: every mode of margin_search and recovery is reached)
STEPS = 250
#: two development seeds (``gfb_agents.seeds.DEV``: tuning only, never the benchmark's)
SEEDS = (3, 17)
_RU1, _RUR1, _WR1 = "gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"
#: the v1 ladder by task: naive, rules, oracle, learned (the first training seed of each)
AGENTS = {
    _RU1: ("naive", "map_informed_v1", "margin_search", "oracle_v1"),
    _RUR1: ("naive", "map_informed_v1", "identify_map_v1", "margin_search", "oracle_v1"),
    _WR1: ("naive", "map_informed_v1", "recovery", "oracle_v1"),
}
LEARNED = ("sac", "ppo_fs4", "recurrentppo")


def _ladder_entry(task: str, name: str):
    from gfb_agents.ladder import ladder_for

    sel = [e for e in ladder_for(task) if e.name == name]
    if len(sel) != 1:
        raise LookupError(f"{task}: no ladder entry {name!r}")
    return sel[0]


def play(task: str, name: str, seed: int) -> dict[str, str]:
    env = make_retired(task)
    try:
        policy = _ladder_entry(task, name).build(env, 0)
        policy.reset()
        obs, info = env.reset(seed=seed)
        observe = getattr(policy, "observe_reset_info", None)
        if observe is not None:
            observe(info)
        acts, rews, ends = [], [], []
        state, start = None, True
        for _ in range(STEPS):
            a, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
            start = False
            acts.append(np.asarray(a, dtype=np.float64).reshape(-1))
            obs, r, term, trunc, info = env.step(a)
            rews.append(float(r))
            ends.append([bool(term), bool(trunc)])
            if term or trunc:
                break
        key = f"{task}|{name}|{seed}"
        return {
            f"{key}.actions": digest(np.array(acts)),
            f"{key}.rewards": digest(rews),
            f"{key}.ends": digest(ends),
            f"{key}.reason": digest(str(info.get("termination_reason"))),
            f"{key}.steps": str(len(rews)),  # plain, for the reader
        }
    finally:
        env.close()


def compute(only: str | None = None) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for task, names in AGENTS.items():
        short = task.split("/")[1]
        for name in names + tuple(f"{short}_{a}" for a in LEARNED):
            if only is not None and only not in name:
                continue
            items: dict[str, str] = {}
            for seed in SEEDS:
                items |= play(task, name, seed)
            out[f"{short}|{name}"] = items
            print(f"  {short} {name}", flush=True)
    return out


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("write", "check"):
        print(__doc__)
        return 2
    from gfb_env.provenance import platform_fingerprint

    path = Path(argv[1])
    got = compute()
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
