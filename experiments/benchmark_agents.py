"""Agent benchmark: the whole ladder (naive, rules, oracle, learned) of every task on the same seeds.

    python -m gfb_experiments.benchmark_agents [--split test] [--episodes 200] [--tasks ID,ID]
        [--agents NAME,NAME] [--out results] [--n-jobs N | --scheduler ADDRESS] [--chunk 10]
        [--policies DIR | --no-learned] [--learned DIR ...] [--env-kwargs JSON] [--reps N] [--merge]
        [--quick] [--normalise consistent|mean|iqm]

Method (``docs/agents.md``, "The benchmark's method"):

* Seeds come from :mod:`gfb_agents.seeds`: ``--split test`` (default; the first ``--episodes`` seeds of
  the test range, for the final table only), ``validation`` (model selection, rule tuning) or
  ``legacy_v0`` (seeds 10000..10049, the v0 table of 2026-11: ``--split legacy_v0 --episodes 50
  --tasks <v0 ids>`` replays it).
* The tasks (``--tasks``): the current (v2) ids by default; the retired v1 ids are accepted only to
  reproduce the v1 record (``results/benchmark_v1``), on envs built by ``gfb_env.envs.retired.make_retired``
  (their info and reward leak the hidden plant: not a benchmark).
* The agents come from the ladder (:mod:`gfb_agents.ladder`): every entry that applies to a task plays the
  same seeds; a learned entry plays them once per training seed.  The naive, ``hold`` and oracle entries
  of a task always run (they define the normalised score, :mod:`gfb_experiments.benchmark_stats`: the zero
  is the better of naive and hold, per aggregate).  A task with no learned policy (a new task id before
  its training) is played without learned agents; the run and the table's notes say so.
* The sweep runs (task, agent, run, chunk of ``--chunk`` seeds) jobs with joblib (``--n-jobs``) or on a
  Dask cluster (``--scheduler tcp://host:8786``: the workers need this package and the learned models at
  the same paths).  Each finished chunk is stored at once as a small JSON file under
  ``<out>/benchmark_cache/<split>/``; a rerun skips the chunks whose key (task, agent, kind, run, seeds,
  env kwargs, the learned model's bytes) matches, so an interrupted sweep resumes.  After changing an
  agent's or the env's code, delete the cache folder (or pass ``--fresh``).

Writes ``<out>/benchmark_agents.csv`` (one row per (task, agent); columns :data:`COLUMNS`),
``benchmark_agents.json`` (the rows, the normalisation per task, every episode's return and normalised
score, the seeds and the command), ``benchmark_agents.md`` (the Markdown table),
``benchmark_agents_profile_<Task>.png`` (rliable performance profile per task) and
``benchmark_agents_paths.png`` (each agent's first episode in the (Lambda, D_W) plane over the hysteresis
band of the task's nominal plant; the paths also in ``benchmark_agents_paths.json``). Where a task's run has
its oracle and at least one rule, ``benchmark_headroom.csv`` (``benchmark_headroom_<split>.csv`` for a split
other than test; columns :data:`HEADROOM_COLUMNS` then :data:`HEADROOM_EXTRA_COLUMNS`): the oracle's
headroom over the best rule (highest normalised IQM on these seeds: :func:`best_rule`) with paired bootstrap
95 % CIs over the evaluation seeds (:func:`headroom_of`).  ``--normalise consistent`` (default) scales the
IQM columns by the zero reference's and the oracle's IQMs and the mean columns by their means (so each
aggregate puts the reference at exactly 0 and the oracle at exactly 1); ``mean`` / ``iqm`` scale both by
one statistic (the v1 table used ``mean``).  ``--merge`` keeps the rows of other
(task, agent) pairs of an existing table. Learned policies that are expected but missing (no folder, or none
in it) end the run at once with exit code 2; ``--no-learned`` runs without them. So do, with one line before
any episode, an unknown task or agent (or one that plays none of the ``--tasks``), an empty ``--tasks`` /
``--agents``, ``--env-kwargs`` for an unknown task or that its task refuses, an ``--out`` that cannot be
written and a ``--scheduler`` that does not answer.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import os
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from gfb_agents import ladder as ladder_mod
from gfb_agents.ladder import AgentEntry, ladder_for, learned_entries, naive_for, oracle_for
from gfb_agents.learned.evaluate import POLICIES_DIR, EpisodeResult, run_episode, summarise
from gfb_agents.nominal_map import NominalMap
from gfb_agents.seeds import MIN_TEST_EPISODES, SPLITS, split_seeds
from gfb_env import jsonio
from gfb_env.envs import ENV_IDS, RETIRED_V1_IDS, make_env
from gfb_env.scripting import OneLineParser, check_output_dir
from gfb_env.sweeps import check_scheduler
from gfb_experiments.benchmark_stats import (
    DEFAULT_REPS,
    NORMALISATIONS,
    interval_estimates,
    normalized_scores,
    paired_headroom,
    performance_profile_png,
    reference_plan,
    rescale_estimates,
)

TASKS = ENV_IDS  # the task list has one owner (the default run: the current, v2 ids)
#: every task the benchmark can play (``--tasks``): the current (v2) ids, and the retired v1 ids to reproduce
#: the record (``results/benchmark_v1``; built by ``gfb_env.envs.retired.make_retired``: not a benchmark)
KNOWN_TASKS = (*ENV_IDS, *RETIRED_V1_IDS)
COLUMNS = [
    "task",
    "agent",
    "kind",
    "split",
    "reference",
    "reference_mean",
    "episodes",
    "training_seeds",
    "success_rate",
    "mean_return",
    "return_ci95",
    "return_ci_low",
    "return_ci_high",
    "normalized_score",
    "normalized_mean_ci_low",
    "normalized_mean_ci_high",
    "normalized_iqm",
    "normalized_ci_low",
    "normalized_ci_high",
    "touchdowns",
    "mean_cost",
    "mean_damping_change",
    "time_to_target_s",
    "final_speed_rpm",
    "final_stable_rate",
    "max_whirl_amplitude",
    "mean_steps",
    "oracle_lost_seeds",
    "wall_s",
]
_INT_COLUMNS = ("episodes", "training_seeds", "touchdowns", "oracle_lost_seeds")
_STR_COLUMNS = ("task", "agent", "kind", "split", "reference", "reference_mean")
#: the ladder's "hold the start speed" entry: with the naive ramp, a candidate for the zero of every task
HOLD = "hold"
CACHE_DIR = "benchmark_cache"
#: columns of ``benchmark_headroom.csv`` (the oracle's headroom over the best rule, paired CIs)
HEADROOM_COLUMNS = [
    "task",
    "best_rule",
    "test_seeds",
    "headroom_iqm",
    "headroom_ci_low",
    "headroom_ci_high",
    "headroom_mean",
    "headroom_mean_ci_low",
    "headroom_mean_ci_high",
]
#: columns after :data:`HEADROOM_COLUMNS`: the seeds' split, the zero references, the claim
HEADROOM_EXTRA_COLUMNS = ["split", "reference", "reference_mean", "established"]
#: the headroom a claim needs at the lower bound of its paired 95 % CI (issue 19)
HEADROOM_CLAIM = 0.2


def hold_for(task: str) -> AgentEntry | None:
    """The ladder's ``hold`` entry where it plays ``task`` (None otherwise): always run, a zero candidate."""
    return next((e for e in ladder_for(task) if e.name == HOLD), None)


# ------------------------------------------------------------------------------------------- jobs
@dataclasses.dataclass(frozen=True, eq=False)  # hashed by identity (env_kwargs is a dict)
class Chunk:
    """One job of the sweep: ``entry``'s run ``run`` on ``seeds`` of ``task``."""

    task: str
    entry: AgentEntry
    run: int
    seeds: tuple[int, ...]
    split: str
    env_kwargs: dict
    record_seed: int | None

    def key(self) -> dict:
        """What the cached result depends on (a file with another key is recomputed)."""
        return {
            "task": self.task,
            "agent": self.entry.name,
            "kind": self.entry.kind,
            "run": self.run,
            "split": self.split,
            "seeds": list(self.seeds),
            "env_kwargs": self.env_kwargs,
            "record_seed": self.record_seed,
            "model_sha256": _model_digest(self.entry, self.run),
            "code_sha256": code_digest(),
        }

    def path(self, out: Path) -> Path:
        slug = self.task.replace("/", "_")
        return out / CACHE_DIR / self.split / slug / self.entry.name / f"run{self.run}_{self.seeds[0]}.json"


def code_digest() -> str:
    """sha256 of the source files of ``gfb_env`` and ``gfb_agents`` (names and bytes): a cached chunk
    played by other code (another plant, clock, rule) is played again, not reused.  (A plain function
    with its own memo, not ``functools.cache``: run as ``__main__`` the chunks' functions are pickled by
    value for the worker processes, and a cache wrapper is not.)"""
    import gfb_agents
    import gfb_env

    memo = code_digest.__dict__
    if "value" not in memo:
        h = hashlib.sha256()
        for pkg in (gfb_env, gfb_agents):
            root = Path(pkg.__file__).resolve().parent
            for f in sorted(root.rglob("*.py")):
                h.update(str(f.relative_to(root)).encode())
                h.update(f.read_bytes())
        memo["value"] = h.hexdigest()
    return memo["value"]


def _model_digest(entry: AgentEntry, run: int) -> str | None:
    """sha256 of a learned run's model and normalisation files (None for other kinds)."""
    if entry.kind != "learned":
        return None
    d = Path(entry.run_paths[run])
    base = d / "best" if any((d / "best" / m).exists() for m in ("model.zip", "actor.pt")) else d
    h = hashlib.sha256()
    for name in ("model.zip", "actor.pt", "vecnormalize.pkl"):  # actor.pt: a deployed actor alone
        p = base / name
        if p.exists():
            h.update(p.read_bytes())
    return h.hexdigest()


def play_chunk(chunk: Chunk) -> dict:
    """Play one chunk (in a worker): a fresh env of the task, the agent built against it, the seeds in
    order.  Returns ``{"key", "episodes": [EpisodeResult as dict], "wall_s"}``."""
    import gfb_env.envs  # noqa: F401  (registers the ids in a fresh worker)

    t0 = time.perf_counter()
    # the judge (run_episode) reads a v2 id's true quantities from its privileged channel itself
    env = make_env(chunk.task, **chunk.env_kwargs)
    try:
        pol = chunk.entry.build(env, chunk.run)
        eps = [
            dataclasses.asdict(run_episode(env, pol, int(s), record_path=s == chunk.record_seed))
            for s in chunk.seeds
        ]
    finally:
        env.close()
    return {"key": chunk.key(), "episodes": eps, "wall_s": time.perf_counter() - t0}


def _episode_from_dict(d: dict) -> EpisodeResult:
    fields = {f.name for f in dataclasses.fields(EpisodeResult)}
    kw = {k: (math.nan if v is None and k not in ("termination_reason",) else v) for k, v in d.items()}
    return EpisodeResult(**{k: v for k, v in kw.items() if k in fields})


def _load_cached(chunk: Chunk, out: Path) -> dict | None:
    p = chunk.path(out)
    if not p.exists():
        return None
    try:
        rec = json.loads(p.read_text())
    except (json.JSONDecodeError, OSError):
        return None  # a torn write from an interruption: recompute
    if rec.get("key") != json.loads(jsonio.dumps(chunk.key())):
        return None
    return rec


def _store(chunk: Chunk, out: Path, rec: dict) -> None:
    p = chunk.path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".tmp")
    tmp.write_text(jsonio.dumps(rec))
    os.replace(tmp, p)  # atomic: a killed run leaves a complete file or none


def plan(
    tasks: list[str],
    split: str,
    episodes: int,
    chunk_size: int,
    agent_filter: set[str] | None = None,
    env_kwargs: dict[str, dict] | None = None,
) -> list[Chunk]:
    """The chunks of a benchmark run (naive, hold and oracle of each task always included: they define
    the normalisation)."""
    env_kwargs = env_kwargs or {}
    seeds = split_seeds(split, episodes)
    out = []
    for task in tasks:
        for e in ladder_for(task):
            always = e.kind in ("naive", "oracle") or e.name == HOLD
            if agent_filter and e.name not in agent_filter and not always:
                continue
            for r in range(e.runs):
                for i in range(0, len(seeds), chunk_size):
                    out.append(
                        Chunk(
                            task,
                            e,
                            r,
                            tuple(seeds[i : i + chunk_size]),
                            split,
                            dict(env_kwargs.get(task, {})),
                            seeds[0] if r == 0 else None,
                        )
                    )
    return out


def run_chunks(
    chunks: list[Chunk],
    out: Path,
    n_jobs: int = 1,
    scheduler: str | None = None,
    fresh: bool = False,
    progress: bool = True,
) -> dict[Chunk, dict]:
    """Results of every chunk: from the cache where the key matches (unless ``fresh``), else played
    with joblib / Dask and stored at once."""
    from joblib import Parallel, delayed
    from tqdm import tqdm

    from gfb_env.sweeps import _backend

    done: dict[Chunk, dict] = {}
    todo = []
    for c in chunks:
        rec = None if fresh else _load_cached(c, out)
        if rec is None:
            todo.append(c)
        else:
            done[c] = rec
    print(
        f"benchmark: {len(chunks)} chunks ({len(done)} cached in {out / CACHE_DIR}, {len(todo)} to play)",
        file=sys.stderr,
    )
    if todo:
        bar = tqdm(total=len(todo), desc="benchmark chunks", unit="chunk", disable=not progress)
        with _backend(scheduler):
            kw = {"n_jobs": n_jobs} if scheduler is None else {}
            par = Parallel(return_as="generator_unordered", **kw)
            by_key = {json.dumps(jsonio.to_jsonable(c.key()), sort_keys=True): c for c in todo}
            for rec in par(delayed(play_chunk)(c) for c in todo):
                c = by_key[json.dumps(jsonio.to_jsonable(rec["key"]), sort_keys=True)]
                rec = json.loads(jsonio.dumps(rec))
                _store(c, out, rec)
                done[c] = rec
                rets = [e["episode_return"] for e in rec["episodes"]]
                bar.set_postfix_str(f"{c.task.split('/')[-1]} {c.entry.name} run{c.run}: {np.mean(rets):.1f}")
                bar.update(1)
        bar.close()
    return done


# ---------------------------------------------------------------------------------------- reduce
def best_rule(rows: list[dict], task: str, agents: dict) -> dict | None:
    """The row of ``task``'s best rule: the highest normalised IQM among its rules with per-episode scores
    in ``agents``, on the table's own (test) seeds (the JSON keeps no validation scores).  Choosing on the
    seeds the headroom is then measured on favours the rule that was lucky on them, so the headroom is
    biased DOWN: conservative for a claim that headroom exists.  None where the task has no such rule."""
    rules = [
        r
        for r in rows
        if r["task"] == task
        and r["kind"] == "rule"
        and r["agent"] in agents
        and math.isfinite(r["normalized_iqm"])
    ]
    return max(rules, key=lambda r: r["normalized_iqm"]) if rules else None


def _set_headroom(task: str, info: dict, rows: list[dict], reps: int) -> None:
    """``info["headroom"]``: the oracle's over the best rule of ``task`` (:func:`best_rule`),
    :func:`headroom_of` their per-seed scores in ``info["agents"]``; removed where the task has no oracle
    or no rule with scores."""
    agents = info.get("agents", {})
    info.pop("headroom", None)
    best = best_rule(rows, task, agents)
    if info.get("oracle") in agents and best is not None:
        info["headroom"] = headroom_of(info, best, reps)


def paired_difference(agents: dict, first: str, second: str, reps: int) -> dict:
    """:func:`benchmark_stats.paired_headroom` of agent ``first`` over ``second`` from a task's per-agent
    scores ``agents``: the IQM columns' scale (``normalized``) and, where both have it, the mean columns'
    (``normalized_mean``; a table older than issue 19's consistent normalisation had one scale)."""
    a, b = agents[first], agents[second]
    am, bm = a.get("normalized_mean"), b.get("normalized_mean")
    if am is None or bm is None:
        am = bm = None
    return paired_headroom(a["normalized"], b["normalized"], reps=reps, oracle_mean=am, rule_mean=bm)


def headroom_of(info: dict, best: dict, reps: int) -> dict:
    """The paired headroom of a task's oracle over the rule of row ``best``, from the task's JSON entry
    ``info`` (its per-agent scores): the IQM difference on the IQM columns' scale (``normalized``), the mean
    difference on the mean columns' (``normalized_mean``; a table older than issue 19's consistent
    normalisation had one scale), both on the same resampled seeds (:func:`benchmark_stats.paired_headroom`).
    With the best rule, the split, the task's zero references and ``established`` (:func:`established`)."""
    h = paired_difference(info["agents"], info["oracle"], best["agent"], reps)
    return {
        "best_rule": best["agent"],
        "split": best["split"],
        "reference": info.get("reference"),
        "reference_mean": info.get("reference_mean"),
        **h,
        "established": established(h),
    }


def established(h: dict) -> bool:
    """A headroom claim (issue 19): both paired CIs' lower bounds (IQM and mean) at least
    :data:`HEADROOM_CLAIM`."""
    return bool(h["iqm_low"] >= HEADROOM_CLAIM and h["mean_low"] >= HEADROOM_CLAIM)


def merge_tasks(old: dict, new: dict, rows: list[dict], reps: int) -> dict:
    """The per-task entries of a ``--merge`` run: a task only in one table keeps its entry; a task in
    both keeps every agent's per-episode scores of the old table that the new run did not re-play (the
    new run's normalisation references, and its re-played agents, replace the old), and its headroom is
    recomputed from the merged agents and ``rows``."""
    out = {**old, **new}
    for task in old.keys() & new.keys():
        merged = {**old[task], **new[task]}
        merged["agents"] = {**old[task].get("agents", {}), **new[task].get("agents", {})}
        if not merged.get("no_headroom"):
            _set_headroom(task, merged, rows, reps)
        out[task] = merged
    return out


def reduce_results(
    chunks: list[Chunk], results: dict[Chunk, dict], reps: int = DEFAULT_REPS, normalise: str = "consistent"
) -> tuple[list[dict], dict, dict]:
    """``(rows, per_task, paths)``: one row per (task, agent); per task the normalisation info, every
    episode's returns and scores and, where the task has its oracle and a rule, the oracle's headroom over
    the best rule (``"headroom"``: :func:`benchmark_stats.paired_headroom`); the recorded first-episode
    paths.  ``normalise`` (:data:`benchmark_stats.NORMALISATIONS`): ``"consistent"`` (each aggregate by
    its own statistic), ``"mean"`` or ``"iqm"``; the zero per aggregate is the better of the naive and
    ``hold`` by that statistic (:func:`benchmark_stats.reference_plan`)."""
    groups: dict[tuple[str, str], list[Chunk]] = {}
    for c in chunks:
        groups.setdefault((c.task, c.entry.name), []).append(c)
    # episodes per (task, agent, run), in seed order
    eps: dict[tuple[str, str], list[list[EpisodeResult]]] = {}
    walls: dict[tuple[str, str], float] = {}
    for k, cs in groups.items():
        runs: dict[int, list[EpisodeResult]] = {}
        for c in sorted(cs, key=lambda c: (c.run, c.seeds[0])):
            runs.setdefault(c.run, []).extend(_episode_from_dict(d) for d in results[c]["episodes"])
            walls[k] = walls.get(k, 0.0) + float(results[c]["wall_s"])
        eps[k] = [runs[r] for r in sorted(runs)]
    rows, per_task, paths = [], {}, {}
    for task in dict.fromkeys(c.task for c in chunks):
        nv, oc = naive_for(task), oracle_for(task)
        refs = {e.name: eps[(task, e.name)] for e in (nv, hold_for(task)) if e and (task, e.name) in eps}
        ref_o = eps.get((task, oc.name)) if oc else None
        info: dict = {"naive": nv.name if nv else None, "oracle": oc.name if oc else None}
        seeds, scales = None, {}
        if nv and nv.name in refs and ref_o:
            ro = np.array([e.episode_return for e in ref_o[0]])
            cand = {k: np.array([e.episode_return for e in v[0]]) for k, v in refs.items()}
            plan_ = reference_plan(cand, normalise)
            for agg, p in plan_.items():
                _, ninfo = normalized_scores(ro, cand[p["reference"]], ro, reference=p["statistic"])
                scales[agg] = {**p, **ninfo}
            info.update(
                {
                    "normalise": normalise,
                    "reference": plan_["iqm"]["reference"],  # the zero of the IQM columns
                    "reference_mean": plan_["mean"]["reference"],  # the zero of the mean columns
                    "reference_candidates": list(cand),
                    "scales": scales,
                    "no_headroom": any(v["no_headroom"] for v in scales.values()),
                    "oracle_lost_seeds": scales["iqm"]["oracle_lost_seeds"],
                }
            )
            seeds = [e.seed for e in refs[nv.name][0]]
        else:
            info.update({"no_headroom": True, "reason": "naive or oracle missing"})
        agents_out = {}
        for (t, name), runs in eps.items():
            if t != task:
                continue
            entry = next(c.entry for c in groups[(t, name)])
            flat = [e for r in runs for e in r]
            ret = np.array([[e.episode_return for e in r] for r in runs])
            rstat = interval_estimates(ret, reps=reps)
            if scales:
                if any([e.seed for e in r] != seeds for r in runs):
                    raise ValueError(f"{task} {name}: its seeds differ from the naive agent's")
                sc = {}
                for agg, sp in scales.items():
                    score, sinfo = normalized_scores(
                        ret, cand[sp["reference"]], ro, reference=sp["statistic"]
                    )
                    est = rescale_estimates(rstat, sinfo["reference_zero"], sinfo["reference_gap"])
                    if sinfo["no_headroom"]:
                        est = dict.fromkeys(est, math.nan)
                    sc[agg] = (score, est)
                lost = scales["iqm"]["oracle_lost_seeds"]
            else:
                nan = np.full(ret.shape, math.nan)
                sc = {agg: (nan, dict.fromkeys(rstat, math.nan)) for agg in ("iqm", "mean")}
                lost = 0
            (s_iqm, e_iqm), (s_mean, e_mean) = sc["iqm"], sc["mean"]
            summ = summarise(flat)
            row = {
                "task": task,
                "agent": name,
                "kind": entry.kind,
                "split": next(iter(groups[(t, name)])).split,
                "reference": info.get("reference") or "",
                "reference_mean": info.get("reference_mean") or "",
                "episodes": ret.shape[1],
                "training_seeds": entry.runs if entry.kind == "learned" else 0,
                "success_rate": summ["success_rate"],
                "mean_return": float(ret.mean()),
                "return_ci95": 0.5 * (rstat["mean_high"] - rstat["mean_low"]),
                "return_ci_low": rstat["mean_low"],
                "return_ci_high": rstat["mean_high"],
                "normalized_score": e_mean["mean"],
                "normalized_mean_ci_low": e_mean["mean_low"],
                "normalized_mean_ci_high": e_mean["mean_high"],
                "normalized_iqm": e_iqm["iqm"],
                "normalized_ci_low": e_iqm["iqm_low"],
                "normalized_ci_high": e_iqm["iqm_high"],
                "touchdowns": summ["touchdowns"],
                "mean_cost": summ["mean_cost"],
                "mean_damping_change": summ["mean_damping_change"],
                "time_to_target_s": summ["time_to_target_s"],
                "final_speed_rpm": summ["final_speed_rpm"],
                "final_stable_rate": summ["final_stable_rate"],
                "max_whirl_amplitude": summ["max_whirl_amplitude"],
                "mean_steps": summ["mean_steps"],
                "oracle_lost_seeds": lost,
                "wall_s": round(walls[(t, name)], 1),
            }
            rows.append(row)
            agents_out[name] = {
                "training": _training_records(entry),
                "kind": entry.kind,
                "seeds": [e.seed for e in runs[0]],
                "returns": ret.tolist(),
                "normalized": s_iqm.tolist(),  # on the IQM columns' scale (the IQM headroom's)
                "normalized_mean": s_mean.tolist(),  # on the mean columns' scale
                "normalized_mean_ci": [e_mean["mean_low"], e_mean["mean_high"]],
            }
            first = runs[0][0]
            if first.path_bearing_number:
                paths[(task, name)] = {
                    "lam": [float(x) for x in first.path_bearing_number],
                    "dw": [float(x) for x in first.path_damping],
                    "success": bool(first.success),
                    "reason": first.termination_reason,
                }
        info["agents"] = agents_out
        if not info.get("no_headroom"):
            _set_headroom(task, info, rows, reps)
        per_task[task] = info
    order = {k: i for i, k in enumerate(ladder_mod.KINDS)}
    rows.sort(key=lambda r: (list(per_task).index(r["task"]), order[r["kind"]], r["agent"]))
    return rows, per_task, paths


def _training_records(entry: AgentEntry) -> list[dict]:
    """Per training seed of a learned entry: steps, wall time, throughput and the best validation, from
    its ``run.json`` / ``policy.json`` (empty for the other kinds)."""
    out = []
    for p in entry.run_paths if entry.kind == "learned" else ():
        meta = {}
        for f in ("run.json", "policy.json"):
            if (Path(p) / f).exists():
                meta = json.loads((Path(p) / f).read_text())
                break
        keep = ("seed", "timesteps", "wall_time_s", "env_steps_per_s", "best_validation", "algo", "command")
        out.append({"path": str(p), **{k: meta.get(k) for k in keep}})
    return out


# ---------------------------------------------------------------------------------------- output
def _read_previous(out: Path) -> tuple[list[dict], dict]:
    """Rows and paths of an earlier run in ``out`` (for ``--merge``)."""
    rows, paths = [], {}
    p = out / "benchmark_agents.csv"
    if p.exists():
        for r in csv.DictReader(p.open()):
            row: dict = {}
            for k in COLUMNS:
                v = r.get(k, "")
                if k in _STR_COLUMNS:
                    row[k] = v
                elif k in _INT_COLUMNS:
                    row[k] = int(float(v)) if v not in ("", None) else 0
                else:
                    row[k] = math.nan if v in ("", None) else float(v)
            rows.append(row)
    pj = out / "benchmark_agents_paths.json"
    if pj.exists():
        for key, v in json.loads(pj.read_text()).items():
            task, agent = key.split("|", 1)
            paths[(task, agent)] = v
    return rows, paths


def _fmt(v, digits: int = 2) -> str:
    if isinstance(v, float):
        if not math.isfinite(v):
            return "-"
        return f"{v:.{digits}f}"
    return str(v)


def write_csv(rows: list[dict], path: Path) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(
                {
                    k: ("" if isinstance(r.get(k), float) and not math.isfinite(r[k]) else r.get(k))
                    for k in COLUMNS
                }
            )


def _scale_text(per_task: dict) -> str:
    """How the table's normalised columns are scaled (its header line)."""
    modes = {info.get("normalise", "mean") for info in per_task.values() if "scales" in info} or {"mean"}
    if modes == {"consistent"}:
        return (
            "IQM columns normalised by the zero reference's and the oracle's IQMs of returns, mean columns "
            "by their means (each aggregate by its own statistic: the reference's normalised IQM and mean "
            "are exactly 0, the oracle's exactly 1)"
        )
    if len(modes) == 1:
        (m,) = modes
        return f"every normalised column by the zero reference's and the oracle's {m.upper()}s of returns"
    return f"mixed normalisations ({', '.join(sorted(modes))}: a merged table)"


def markdown_table(rows: list[dict], per_task: dict | None = None, notes: list[str] | tuple = ()) -> str:
    """The benchmark as Markdown: one table, grouped by task, ladder order (the best normalised IQM of a
    non-oracle agent per task in bold); then per task its zero reference, best rule, best learned agent
    and the oracle's paired headroom over the best rule (``per_task[task]["headroom"]``, the numbers of
    ``benchmark_headroom.csv``), with a claim only where both CIs' lower bounds reach 0.2; ``notes``
    (e.g. the tasks whose learned agents were skipped) last."""
    per_task = per_task or {}
    splits = sorted({r["split"] for r in rows})
    lines = [
        f"Benchmark on the {', '.join(splits)} seeds (`gfb_agents.seeds`); "
        "`python -m gfb_experiments.benchmark_agents`. Normalised score per episode on the task's scale: "
        "0 = the zero reference (per task the better of the naive ramp `naive` and `hold` the start speed, "
        "by the aggregate being normalised; column `reference` of the CSV), 1 = the oracle; "
        f"{_scale_text(per_task)}. IQM and mean with 95 % stratified-bootstrap CIs (rliable's method).",
        "",
        "| task | agent | kind | split | seeds x episodes | success | return (mean [95% CI]) | "
        "normalised IQM [95% CI] | normalised mean [95% CI] | touchdowns | mean cost | mean abs dD cmd |",
        "|" + "---|" * 12,
    ]
    for task in dict.fromkeys(r["task"] for r in rows):
        sub = [r for r in rows if r["task"] == task]
        cand = [
            r["normalized_iqm"] for r in sub if r["kind"] != "oracle" and math.isfinite(r["normalized_iqm"])
        ]
        best = max(cand) if cand else math.nan
        for r in sub:
            lo, hi = _fmt(r["normalized_ci_low"]), _fmt(r["normalized_ci_high"])
            iqm = f"{_fmt(r['normalized_iqm'])} [{lo}, {hi}]"
            if r["kind"] != "oracle" and r["normalized_iqm"] == best:
                iqm = f"**{iqm}**"
            mlo, mhi = r.get("normalized_mean_ci_low", math.nan), r.get("normalized_mean_ci_high", math.nan)
            mean = f"{_fmt(r['normalized_score'])} [{_fmt(mlo)}, {_fmt(mhi)}]"
            runs = max(1, int(r["training_seeds"]))
            lines.append(
                f"| {task.split('/')[-1]} | {r['agent']} | {r['kind']} | {r['split']} | {runs} x "
                f"{r['episodes']} | {r['success_rate']:.0%} | {_fmt(r['mean_return'], 1)} "
                f"[{_fmt(r['return_ci_low'], 1)}, {_fmt(r['return_ci_high'], 1)}] | {iqm} | {mean} | "
                f"{r['touchdowns']}/{runs * r['episodes']} | {_fmt(r['mean_cost'])} | "
                f"{_fmt(r['mean_damping_change'], 3)} |"
            )
    lines += [
        "",
        "Per task: the zero reference (IQM columns; mean columns), the best rule (highest normalised IQM on "
        "these seeds: choosing on the seeds the headroom is measured on biases the headroom down, "
        "conservative for a claim), the best learned agent, and the oracle's headroom over the best rule "
        "(IQM(oracle) - IQM(rule) on the IQM scale, mean(oracle) - mean(rule) on the mean scale) with paired "
        "bootstrap 95 % CIs over the seeds (both agents' aggregates recomputed on the same resampled seeds; "
        "`benchmark_headroom.csv`). A headroom of at least 0.2 is claimed only where both CIs' lower bounds "
        "are >= 0.2; otherwise it is not established.",
        "",
        "| task | split | zero reference | best rule | best learned | headroom IQM [95% CI] | "
        "headroom mean [95% CI] | headroom >= 0.2 |",
        "|" + "---|" * 8,
    ]
    for task in dict.fromkeys(r["task"] for r in rows):
        sub = [r for r in rows if r["task"] == task]
        info = per_task.get(task, {})

        def best(kind: str, sub=sub) -> dict | None:
            c = [r for r in sub if r["kind"] == kind and math.isfinite(r["normalized_iqm"])]
            return max(c, key=lambda r: r["normalized_iqm"]) if c else None

        def cell(r: dict | None) -> str:
            if r is None:
                return "-"
            lo, hi = _fmt(r["normalized_ci_low"]), _fmt(r["normalized_ci_high"])
            return f"{r['agent']} {_fmt(r['normalized_iqm'])} [{lo}, {hi}]"

        ref = info.get("reference") or "-"
        ref_m = info.get("reference_mean") or "-"
        h = info.get("headroom")
        bl = best("learned")
        learned = cell(bl) if bl is not None else "- (none)"
        if h:
            br = next((r for r in sub if r["agent"] == h["best_rule"]), None)
            h_iqm = f"{_fmt(h['iqm'])} [{_fmt(h['iqm_low'])}, {_fmt(h['iqm_high'])}]"
            h_mean = f"{_fmt(h['mean'])} [{_fmt(h['mean_low'])}, {_fmt(h['mean_high'])}]"
            claim = "established" if established(h) else "not established"
        else:
            br, h_iqm, h_mean, claim = best("rule"), "-", "-", "not established (no oracle or rule)"
        split = sub[0]["split"]
        lines.append(
            f"| {task.split('/')[-1]} | {split} | {ref}; {ref_m} | {cell(br)} | {learned} | {h_iqm} | "
            f"{h_mean} | {claim} |"
        )
    lines += [
        "",
        "Columns: split = the seeds' split (`test` for the table); seeds x episodes = independent training "
        "seeds (1 for naive, rules, oracle) x episodes; success = share of episodes ending in `success`; "
        "normalised IQM = interquartile mean of the per-episode scores, CI over episodes stratified by "
        "training seed (seeds resampled too where there are several); touchdowns include solver failures; "
        "mean cost = mean over episodes of the summed `info['cost']` (- where the task has none); mean abs "
        "dD cmd = mean per step of the change of the commanded damping on the action scale (log D_W, 2 = "
        "whole range).",
    ]
    if notes:
        lines += ["", *[f"Note: {n}" for n in notes]]
    return "\n".join(lines) + "\n"


def nominal_band_lower(env, path: str | Path | None = None):
    """``D_W -> `` lower edge of the nominal bearing's hysteresis band (the fold of cycles, or where the
    unstable cycles reach contact, or ``Lambda_c`` where there is no band), from the map of the tasks'
    nominal bearing (``gfb_env/data/hysteresis_map_tasks.csv``, made by ``python -m
    gfb_experiments.hysteresis_map --tasks``) interpolated in log D_W; None when that map is not of
    the env's grid and foil stiffness (within 5 %).  For the figure only: the agents do not read it."""
    from gfb_env.analysis.maps import HYSTERESIS_MAP_TASKS_CSV, MAPS_DATA_DIR, load_hysteresis_map

    u = getattr(env, "unwrapped", env)
    hm = load_hysteresis_map(path if path is not None else MAPS_DATA_DIR / HYSTERESIS_MAP_TASKS_CSV)
    kw = float(u.constants.get("foil_stiffness", 0.0) or u.nominal_bearing.foil_stiffness)
    sel = (np.abs(np.log(hm.foil_stiffness / kw)) < 0.05) & (hm.grid == str(u.grid))
    if hm.band_lower_bearing_number is None or not np.isfinite(hm.band_lower_bearing_number[sel]).any():
        return None
    return lambda d: hm.band_lower(kw, d)


@dataclasses.dataclass(frozen=True)
class PlantBand:
    """What the paths figure draws behind a task's agents: the task's nominal plant's map (its
    ``Lambda_c(D_W)``) and the lower edge of its hysteresis band (``band_lower``: ``D_W -> Lambda`` of the
    fold of cycles or where the unstable cycles reach contact; None where no map of the task's grid and
    bearing is stored: then the nominal map's own fold, if any, is drawn), and a word on its source."""

    nmap: NominalMap
    band_lower: Callable[[float], float] | None
    source: str


def plant_band(env) -> PlantBand:
    """The :class:`PlantBand` of ``env``'s task: the stored map of the tasks' hysteresis band
    (:func:`nominal_band_lower`) where it is of the env's grid and foil stiffness, else the nominal map's
    fold."""
    nmap = NominalMap.from_env(env)
    band = nominal_band_lower(env)
    u = getattr(env, "unwrapped", env)
    src = (
        f"stored map of the nominal bearing on grid {u.grid}"
        if band is not None
        else f"no stored map of grid {u.grid} and this foil: nominal map's fold only"
    )
    return PlantBand(nmap, band, src)


def plot_paths(
    paths: dict,
    nmap: NominalMap | dict[str, PlantBand],
    path: Path,
    tasks: list[str],
    band_lower=None,
) -> None:
    """First-episode path of every agent in the (Lambda, D_W) plane over the hysteresis band of each
    task's nominal plant: stable (equilibrium only) below the band, bistable inside it (between the fold
    of limit cycles -- or where the unstable cycles reach contact -- and the Hopf ``Lambda_c``: a large
    disturbance ends in whirl or touchdown), whirl only above ``Lambda_c``.

    ``nmap``: per task its :class:`PlantBand` (:func:`plant_band`), or one :class:`NominalMap` for every
    task with ``band_lower`` (``D_W ->`` lower edge of the band, :func:`nominal_band_lower`; without it
    the band is drawn from the nominal map's fold where that is known)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if isinstance(nmap, dict):
        bands = nmap
        missing = [t for t in tasks if t not in bands]
        if missing:
            raise ValueError(f"plot_paths: no plant band for {', '.join(missing)}")
    else:
        bands = {t: PlantBand(nmap, band_lower, "") for t in tasks}
    n = len(tasks)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 6.4), squeeze=False)
    names = sorted({a for (_, a) in paths})
    colors = {a: plt.cm.tab10(i % 10) for i, a in enumerate(names)}
    styles = {a: ("-", "--", ":", "-.")[i % 4] for i, a in enumerate(names)}
    for ax, task in zip(axes[0], tasks, strict=False):
        pb = bands[task]
        m = pb.nmap
        d = np.geomspace(m.damping.min(), m.damping.max(), 200)
        lc = np.array([m.critical_at(x) for x in d])
        lf = np.array([m.fold_at(x) for x in d])
        if pb.band_lower is not None:
            # the band map's Lambda_c (eigenvalues, same grid) and the task constants' agree to ~1e-3
            lf = np.minimum([pb.band_lower(x) for x in d], lc)
        lams = [x for (t, _), r in paths.items() if t == task for x in r["lam"]]
        x0 = min([0.40, *lams]) - 0.01
        x1 = max([0.80, *lams]) + 0.01
        ax.fill_betweenx(
            d, x0, np.where(np.isfinite(lf), lf, lc), color="#cfe8cf", label="stable (equilibrium only)"
        )
        if np.isfinite(lf).any():
            ax.fill_betweenx(
                d,
                np.where(np.isfinite(lf), lf, lc),
                lc,
                color="#ffe9a8",
                label="hysteresis band (fold .. $\\Lambda_c$: a large disturbance -> whirl or touchdown)",
            )
        ax.fill_betweenx(d, lc, x1, color="#f6c6c6", label="whirl only (above $\\Lambda_c$)")
        ax.plot(lc, d, "k-", lw=1)
        if np.isfinite(lf).any():
            ax.plot(lf, d, "k--", lw=1)
        for (t, a), r in paths.items():
            if t != task or not r["lam"]:
                continue
            lam, dw = np.asarray(r["lam"]), np.asarray(r["dw"])
            ax.plot(
                lam,
                dw,
                styles[a],
                color=colors[a],
                lw=1.3,
                alpha=0.9,
                label=f"{a} ({r['reason'] or 'time'})",
            )
            ax.plot(lam[0], dw[0], "o", color=colors[a], ms=3)
            ax.plot(lam[-1], dw[-1], "s" if r["success"] else "x", color=colors[a], ms=5)
        ax.set_yscale("log")
        ax.set_xlim(x0, x1)
        ax.set_ylim(d.min(), d.max())
        ax.set_xlabel(r"bearing number $\Lambda$")
        ax.set_ylabel(r"foil damping $D_W$")
        title = task.split("/")[-1]
        if "Randomized" in task:
            title += " (drawn bearing's $\\Lambda$; band of the nominal bearing)"
        if not np.isfinite(lf).any():
            title += "\n(fold of cycles not mapped for this foil: hysteresis band not drawn)"
        elif pb.source:
            title += f"\n({pb.source})"
        ax.set_title(title, fontsize=8)
        # below the axes: inside, it hid the band's lower part (the region the figure is about)
        ax.legend(fontsize=5.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
    import textwrap

    caption = (
        "Agent paths (first benchmark episode; o start, s success, x other end) over each task's nominal "
        "plant: its hysteresis band, the fold of limit cycles over the damping range on the task's grid "
        "(gfb_env/data/hysteresis_map_tasks.csv: the nominal bearing; RunUpRandomized draws bearings, its "
        "band is the nominal bearing's)"
    )
    lines = textwrap.wrap(caption, width=int(70 * n))
    fig.suptitle("\n".join(lines), fontsize=8.5)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.025 * len(lines)))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def profile_name(task: str) -> str:
    return f"benchmark_agents_profile_{task.split('/')[-1]}.png"


def headroom_csv_name(split: str) -> str:
    """``benchmark_headroom.csv`` for the test split, ``benchmark_headroom_<split>.csv`` for another
    (a validation run's headroom is never mistaken for the table's)."""
    return "benchmark_headroom.csv" if split == "test" else f"benchmark_headroom_{split}.csv"


def write_headroom_csv(per_task: dict, path: Path) -> bool:
    """One row per task with a ``"headroom"`` entry (columns :data:`HEADROOM_COLUMNS`); False (and no
    file) if no task has one."""
    hs = [(t, info["headroom"]) for t, info in per_task.items() if info.get("headroom")]
    if not hs:
        return False
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(HEADROOM_COLUMNS + HEADROOM_EXTRA_COLUMNS)
        for t, h in hs:
            w.writerow(
                [t, h["best_rule"], h["seeds"]]
                + [repr(float(h[k])) for k in ("iqm", "iqm_low", "iqm_high", "mean", "mean_low", "mean_high")]
                + [h.get("split", ""), h.get("reference") or "", h.get("reference_mean") or ""]
                + [str(established(h))]
            )
    return True


def write_outputs(
    out: Path, rows: list[dict], per_task: dict, paths: dict, meta: dict, env_kwargs: dict[str, dict]
) -> None:
    """CSV, JSON, Markdown, the headroom CSV (where a task has oracle and rule), one performance profile
    per task, the paths figure."""
    write_csv(rows, out / "benchmark_agents.csv")
    write_headroom_csv(per_task, out / headroom_csv_name(meta["split"]))
    (out / "benchmark_agents.md").write_text(markdown_table(rows, per_task, meta.get("notes", ())))
    (out / "benchmark_agents_paths.json").write_text(
        jsonio.dumps({f"{t}|{n}": v for (t, n), v in paths.items()})
    )
    for task, info in per_task.items():
        sd = {a: np.asarray(v["normalized"], dtype=np.float64) for a, v in info.get("agents", {}).items()}
        performance_profile_png(
            sd, out / profile_name(task), title=f"{task.split('/')[-1]} ({meta['split']} seeds)"
        )
    tasks = list(dict.fromkeys(r["task"] for r in rows))
    bands = {}
    for t in tasks:  # each task's own plant (grid, bearing): v2 ids may differ from v1's
        env = make_env(t, **env_kwargs.get(t, {}))
        try:
            bands[t] = plant_band(env)
        finally:
            env.close()
    plot_paths(paths, bands, out / "benchmark_agents_paths.png", tasks)
    jsonio.write_json(out / "benchmark_agents.json", {**meta, "rows": rows, "tasks": per_task})


# ------------------------------------------------------------------------------------------- CLI
def learned_notes(tasks: list[str], no_learned: bool = False) -> list[str]:
    """The table's notes on learned agents: the tasks that have none on the ladder (a new task id before
    any policy of it is trained and committed) are played without them, which the table says rather than
    fail or leave silently out."""
    if no_learned:
        return ["run with --no-learned: no learned agent on any task"]
    bare = [t for t in tasks if not any(e.kind == "learned" for e in ladder_for(t))]
    if not bare:
        return []
    names = ", ".join(t.split("/")[-1] for t in bare)
    which = "it" if len(bare) == 1 else "them"
    return [f"no learned policy is committed for {names}: learned agents skipped on {which}"]


def _names(ap, option: str, text: str) -> list[str]:
    """The comma-separated names of ``option``; an empty list or an empty name is a usage error (an
    empty ``--agents`` / ``--tasks`` used to mean "all")."""
    names = [x.strip() for x in text.split(",")]
    if not any(names):
        ap.error(f"{option} names nothing (got {text!r}); leave it out for all")
    if not all(names):
        ap.error(f"{option} has an empty name in {text!r}")
    return list(dict.fromkeys(names))


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m gfb_experiments.benchmark_agents", description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="test", choices=sorted(SPLITS), help="seed split (gfb_agents.seeds)")
    ap.add_argument(
        "--episodes", type=int, default=MIN_TEST_EPISODES, help="seeded episodes per (task, agent, run)"
    )
    ap.add_argument("--quick", action="store_true", help="two episodes per pair, one per chunk (for tests)")
    ap.add_argument("--tasks", default=None, help=f"comma-separated env ids (default: {','.join(TASKS)})")
    ap.add_argument(
        "--agents",
        default=None,
        help="comma-separated agent names (default: all; naive and oracle always run)",
    )
    ap.add_argument("--out", default="results", help="output directory (the chunk cache goes under it)")
    ap.add_argument(
        "--policies",
        default=None,
        help="directory of learned policies (default: the committed ones, shipped as gfb_agents/policies)",
    )
    ap.add_argument(
        "--learned",
        action="append",
        default=[],
        help="a gfb_agents.learned.train output folder (seed*/ runs) to register as a learned agent "
        "(repeatable)",
    )
    ap.add_argument(
        "--no-learned",
        action="store_true",
        help="run without the committed learned policies (without it, missing ones are an error)",
    )
    ap.add_argument("--n-jobs", type=int, default=1, help="parallel chunks on this machine (-1: all cores)")
    ap.add_argument(
        "--scheduler", default=None, help="Dask scheduler address: run the chunks on that cluster"
    )
    ap.add_argument("--chunk", type=int, default=10, help="seeds per cached job (>= 1)")
    ap.add_argument("--reps", type=int, default=DEFAULT_REPS, help="bootstrap replications (>= 100)")
    ap.add_argument(
        "--normalise",
        default="consistent",
        choices=NORMALISATIONS,
        help="scale of the normalised columns: consistent (default: IQM columns by the zero reference's and "
        "the oracle's IQMs, mean columns by their means), or both by means / by IQMs",
    )
    ap.add_argument("--fresh", action="store_true", help="ignore the chunk cache (replay every chunk)")
    ap.add_argument(
        "--env-kwargs",
        default=None,
        help='JSON {task id: {gymnasium.make kwargs}}, e.g. {"gfb_env/RunUp-v2": {}}',
    )
    ap.add_argument(
        "--merge",
        action="store_true",
        help="keep the rows of other (task, agent) pairs of the existing table in --out",
    )
    a = ap.parse_args(argv)
    env_kwargs: dict[str, dict] = {}
    if a.env_kwargs:
        try:
            env_kwargs = json.loads(a.env_kwargs)
        except json.JSONDecodeError as exc:
            ap.error(f"--env-kwargs is not valid JSON: {exc}")
        if not isinstance(env_kwargs, dict) or not all(isinstance(v, dict) for v in env_kwargs.values()):
            ap.error("--env-kwargs must be a JSON object mapping task ids to objects")
    episodes = 2 if a.quick else a.episodes
    chunk = 1 if a.quick else a.chunk
    if episodes < 1:
        ap.error(f"--episodes must be >= 1, got {a.episodes}")
    if episodes > len(SPLITS[a.split]):
        ap.error(f"--episodes {episodes}: the {a.split} split has only {len(SPLITS[a.split])} seeds")
    if chunk < 1:
        ap.error(f"--chunk must be >= 1, got {a.chunk}")
    if a.reps < 100:
        ap.error(f"--reps must be >= 100, got {a.reps}")
    cpus = os.cpu_count() or 1
    if a.scheduler is None and not (a.n_jobs == -1 or 1 <= a.n_jobs <= cpus):
        ap.error(f"--n-jobs must be -1 or lie in [1, {cpus}] (this machine's cores), got {a.n_jobs}")
    try:  # before any episode: an unwritable --out fails now, not after the benchmark
        check_output_dir(a.out, "--out")
    except ValueError as exc:
        ap.error(str(exc))
    tasks = _names(ap, "--tasks", a.tasks) if a.tasks is not None else list(TASKS)
    for t in tasks:
        if t not in KNOWN_TASKS:  # a registered id that is not a task (CartPole-v1) has no ladder
            ap.error(f"--tasks: unknown task {t!r}; known: {', '.join(KNOWN_TASKS)}")
    for t, kw in env_kwargs.items():
        # a known task outside --tasks is allowed (one JSON for several runs, --merge); a typo is not
        if t not in KNOWN_TASKS:
            ap.error(f"--env-kwargs: unknown task {t!r}; known: {', '.join(KNOWN_TASKS)}")
        try:  # the env each chunk builds: bad keywords fail now, not in the first worker
            make_env(t, **kw).close()
        except (TypeError, ValueError) as exc:
            ap.error(f"--env-kwargs of {t}: {' '.join(str(exc).split())}")
    if a.no_learned and a.policies:
        ap.error("--no-learned and --policies exclude each other")
    if a.scheduler is not None:
        try:
            check_scheduler(a.scheduler)
        except ValueError as exc:
            ap.error(str(exc))
    with ladder_mod.scoped():
        return _run(ap, a, tasks, episodes, chunk, env_kwargs, argv)


def _run(ap, a, tasks, episodes, chunk, env_kwargs, argv) -> int:
    # the learned agents: the committed ones (or --policies), plus --learned training outputs
    for e in ladder_mod.registered().values():
        if e.kind == "learned":
            ladder_mod.unregister(e.name)
    if not a.no_learned:
        # before any episode: a benchmark that silently lacks its learned agents is wrong, not partial
        root = Path(a.policies) if a.policies else POLICIES_DIR
        try:
            found = learned_entries(root)
        except (FileNotFoundError, ValueError) as exc:
            print(f"{ap.prog}: error: {exc}; pass --no-learned to run without them", file=sys.stderr)
            return 2
        if not found:
            print(
                f"{ap.prog}: error: no learned policy (<name>/model.zip) in {root}; "
                "pass --no-learned to run without them",
                file=sys.stderr,
            )
            return 2
        for e in found:
            ladder_mod.register(e, replace=True)
    for d in a.learned:
        taken = ladder_mod.registered().get(Path(d).name)
        if taken is not None:  # registering it would silently replace that agent in the table
            what = "a committed learned policy" if taken.kind == "learned" else f"the {taken.kind} agent"
            ap.error(
                f"--learned {d}: its name {taken.name!r} is already {what}, which it would replace; "
                "train into (or rename to) a folder of another name"
            )
        try:
            ladder_mod.register_learned(d)
        except (FileNotFoundError, ValueError) as exc:
            ap.error(f"--learned {d}: {exc}")
    agents = None
    if a.agents is not None:
        agents = set(_names(ap, "--agents", a.agents))
        known = sorted({e.name for t in tasks for e in ladder_for(t)})
        unknown = sorted(agents - set(ladder_mod.registered()))
        if unknown:
            ap.error(
                f"--agents: unknown agent {', '.join(map(repr, unknown))}; "
                f"agents of the tasks: {', '.join(known)}"
            )
        idle = sorted(agents - set(known))
        if idle:
            ap.error(
                f"--agents: {', '.join(map(repr, idle))} plays none of the tasks {', '.join(tasks)}; "
                f"their agents: {', '.join(known)}"
            )
    out = Path(a.out)
    t0 = time.perf_counter()
    chunks = plan(tasks, a.split, episodes, chunk, agents, env_kwargs)
    notes = learned_notes(tasks, a.no_learned)
    for n in notes:
        print(f"note: {n}", file=sys.stderr)
    for t in tasks:
        if naive_for(t) is None or oracle_for(t) is None:
            print(
                f"warning: {t} has no naive or no oracle agent: its normalised scores are NaN",
                file=sys.stderr,
            )
    if a.split == "test" and episodes < MIN_TEST_EPISODES:
        print(
            f"note: {episodes} test episodes per (task, agent) is below the table's {MIN_TEST_EPISODES}",
            file=sys.stderr,
        )
    results = run_chunks(chunks, out, a.n_jobs, a.scheduler, fresh=a.fresh)
    rows, per_task, paths = reduce_results(chunks, results, reps=a.reps, normalise=a.normalise)
    if a.merge:
        old_rows, old_paths = _read_previous(out)
        new = {(r["task"], r["agent"]) for r in rows}
        rows = [r for r in old_rows if (r["task"], r["agent"]) not in new] + rows
        paths = {**{k: v for k, v in old_paths.items() if k not in new}, **paths}
        if any(int(r["episodes"]) != episodes or r["split"] != a.split for r in rows):
            print("warning: merged rows have different episode counts or splits", file=sys.stderr)
        order = {t: i for i, t in enumerate(KNOWN_TASKS)}
        kinds = {k: i for i, k in enumerate(ladder_mod.KINDS)}
        rows.sort(key=lambda r: (order.get(r["task"], 99), kinds.get(r["kind"], 9), r["agent"]))
        if (out / "benchmark_agents.json").exists():
            old_meta = json.loads((out / "benchmark_agents.json").read_text())
            if old_meta.get("normalise", "mean") != a.normalise:  # older tables have no key: means
                print("warning: merged rows were normalised by another reference", file=sys.stderr)
            per_task = merge_tasks(old_meta.get("tasks", {}), per_task, rows, a.reps)
    seeds = split_seeds(a.split, episodes)
    meta = {
        "split": a.split,
        "episodes": episodes,
        "seeds": [seeds[0], seeds[-1]],
        "tasks": list(dict.fromkeys(r["task"] for r in rows)),
        "env_kwargs": env_kwargs,
        "bootstrap_reps": a.reps,
        "normalise": a.normalise,
        "notes": notes,
        "command": "python -m gfb_experiments.benchmark_agents "
        + " ".join(shlex.quote(x) for x in (argv if argv is not None else sys.argv[1:])),
        "wall_time_s_last_run": round(time.perf_counter() - t0, 1),
    }
    write_outputs(out, rows, per_task, paths, meta, env_kwargs)
    print((out / "benchmark_agents.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
