"""The benchmark's ladder of agents: naive, rules, oracle, learned -- one registry, the one factory.

Every agent of the benchmark is an :class:`AgentEntry`: a name, a kind (``naive`` | ``rule`` |
``oracle`` | ``learned``), the task ids it applies to and a factory.  The benchmark
(``python -m gfb_experiments.benchmark_agents``) runs, for each task, *every* entry that applies to it on
the same seeds, and normalises each episode's return with the same seed's naive and oracle returns
(``gfb_experiments.benchmark_stats.normalized_scores``): 0 = naive, 1 = oracle.  So every task needs
exactly one ``naive`` and one ``oracle`` entry.

Registering an agent (the interface for the oracle, the rules and the learned agents)::

    from gfb_agents.ladder import AgentEntry, register, V2_TASKS
    # make_oracle(env) -> Policy; supersede=True takes the tasks from the built-in oracle_v1
    register(AgentEntry("my_oracle", "oracle", V2_TASKS, make_oracle), supersede=True)
    register(AgentEntry("identify_shock", "rule", ("gfb_env/RunUpRandomized-v2",), make_my_rule))
    register_learned("runs/RunUpRandomized-v2_sac", name="sac")   # a gfb_agents.learned.train output
    policy = build("margin_search", gym.make("gfb_env/RunUp-v2"))  # any registered agent, for a script

The ladder also keeps the entries of the retired v1 ids (:data:`V1_TASKS`) for the record: the committed v1
policies and ``results/benchmark_v1`` replay on envs built by :func:`gfb_env.envs.retired.make_retired`
(their info and reward leak the hidden plant: not a benchmark).

A factory is called as ``factory(env)`` with a fresh env of the task (``gymnasium.make(task,
**env_kwargs)``, not yet reset) -- the very env the agent's episodes are then played on, so an oracle may
keep it and read the episode's hidden parameters through the env's public accessors -- and returns a
:class:`~gfb_agents.policy.Policy`; a naive agent or a rule must read only the observation and the
env's documented configuration.  The evaluation calls ``policy.reset()`` before each ``env.reset`` and,
for an oracle (:class:`~gfb_agents.policy.PrivilegedPolicy`), ``policy.observe_reset_info(info)`` after
it.  Factories and entries must be picklable (module-level functions or ``functools.partial`` of them):
the evaluation sweep builds the agents in its worker processes.

A learned entry has one run per independent training seed (``run_paths``); the benchmark plays every run
on the same test seeds and the statistics stratify by run.

The built-in ladder (:func:`default_ladder`): on every task the naive ramp (:class:`NaiveRampAgent`),
the ``hold`` reference (:class:`~gfb_agents.rules.naive.HoldStartAgent`: the start speed held at D_W = 1,
kind ``rule`` because the normalisation's 0 is the one naive entry; issue 19), the v1 rules of
:mod:`gfb_agents.rules` on the tasks each was written for,
:class:`~gfb_agents.oracles.commanded.CommandedOracle` (``oracle_v1``) as the oracle, and the committed
learned policies of their task (every ``gfb_agents/policies/<agent>/`` folder, one run per ``seed*/``).
The rules and the oracle are built only here (:func:`build`, or an entry's :meth:`AgentEntry.build`).
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from gfb_agents.nominal_map import NominalMap
from gfb_agents.policy import ControlSpec, Policy
from gfb_agents.rules.naive import NAIVE_DAMPING, NAIVE_MARGIN, HoldStartAgent, NaiveRampAgent

__all__ = [
    "KINDS",
    "AgentEntry",
    "NaiveRampAgent",
    "register",
    "set_tasks",
    "unregister",
    "registered",
    "build",
    "make_naive",
    "make_hold",
    "make_commanded_oracle",
    "scoped",
    "register_learned",
    "learned_entries",
    "ladder_for",
    "naive_for",
    "oracle_for",
    "default_ladder",
    "LADDER",
    "V1_TASKS",
    "V2_TASKS",
    "NAIVE_DAMPING",
    "NAIVE_MARGIN",
]

KINDS = ("naive", "rule", "oracle", "learned")

try:  # the task list has one owner (the retired v0 ids are no task of the ladder)
    from gfb_env.envs import RETIRED_V1_IDS, V2_ENV_IDS

    #: the v2 ids (issue 19), the current tasks: the same plants with the information contract and the
    #: monitor's observation
    V2_TASKS: tuple[str, ...] = tuple(V2_ENV_IDS)
    #: the retired v1 ids (issue 19: their info and reward leak the hidden plant): the ladder keeps their
    #: entries for the record (the committed v1 policies, ``results/benchmark_v1``), played on envs built by
    #: :func:`gfb_env.envs.retired.make_retired`; not a benchmark
    V1_TASKS: tuple[str, ...] = tuple(RETIRED_V1_IDS)
except ImportError:  # pragma: no cover - gfb_env is a dependency
    V1_TASKS = V2_TASKS = ()


@dataclass(frozen=True)
class AgentEntry:
    """One rung of the ladder.

    Attributes:
        name: unique name (the table's ``agent`` column).
        kind: ``"naive"``, ``"rule"``, ``"oracle"`` or ``"learned"``.
        tasks: the task ids it applies to.
        factory: ``factory(env) -> Policy`` (None for a learned entry, which loads ``run_paths``).
        run_paths: learned entries only: one trained model per independent training seed (a directory
            :class:`~gfb_agents.learned.evaluate.LearnedPolicy` reads: its ``best/`` model, selected on the
            validation seeds, where present).
        description: one line for the docs.
    """

    name: str
    kind: str
    tasks: tuple[str, ...]
    factory: Callable[..., Policy] | None = None
    run_paths: tuple[str, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or "|" in self.name or "/" in self.name:
            raise ValueError(f"agent name must be a non-empty string without '|' or '/', got {self.name!r}")
        if self.kind not in KINDS:
            raise ValueError(f"kind of {self.name!r} must be one of {KINDS}, got {self.kind!r}")
        object.__setattr__(self, "tasks", tuple(self.tasks))
        object.__setattr__(self, "run_paths", tuple(str(p) for p in self.run_paths))
        if not self.tasks:
            raise ValueError(f"agent {self.name!r} applies to no task")
        if self.kind == "learned":
            if not self.run_paths:
                raise ValueError(f"learned agent {self.name!r} needs run_paths (one per training seed)")
        elif self.factory is None or not callable(self.factory):
            raise ValueError(f"agent {self.name!r} needs a factory(env) -> Policy")

    @property
    def runs(self) -> int:
        """Independent training seeds (1 for a naive, rule or oracle agent)."""
        return len(self.run_paths) if self.kind == "learned" else 1

    def build(self, env, run: int = 0) -> Policy:
        """The policy of run ``run`` for ``env`` (a fresh env of one of :attr:`tasks`)."""
        if not 0 <= run < self.runs:
            raise ValueError(f"agent {self.name!r} has {self.runs} run(s), asked for run {run}")
        if self.kind == "learned":
            from gfb_agents.learned.evaluate import LearnedPolicy

            pol: Policy = LearnedPolicy(self.run_paths[run], name=self.name)
        else:
            pol = self.factory(env)
        pol.name = self.name
        return pol


def make_naive(env) -> NaiveRampAgent:
    """The naive ramp for ``env`` (:class:`NaiveRampAgent` with D_W = 1 and a 5 % margin)."""
    nmap = NominalMap.from_env(env)
    return NaiveRampAgent(ControlSpec.from_env(env, nmap), nmap, NAIVE_DAMPING, NAIVE_MARGIN)


def make_hold(env) -> HoldStartAgent:
    """The ``hold`` reference for ``env``: start speed held (action 0), the naive's D_W = 1."""
    return HoldStartAgent(ControlSpec.from_env(env, NominalMap.from_env(env)), NAIVE_DAMPING)


def _make_map_informed_v1(env) -> Policy:
    """``map_informed_v1``: the nominal map's schedule (g = 1) capped at the command."""
    from gfb_agents.rules.map_informed import CommandCappedAgent, MapInformedAgent

    u = getattr(env, "unwrapped", env)
    nmap = NominalMap.from_env(u)
    inner = MapInformedAgent(ControlSpec.from_env(u, nmap), nmap)
    return CommandCappedAgent(u, inner, "map_informed_v1", nmap=nmap)


def _make_identify_map_v1(env) -> Policy:
    """``identify_map_v1``: the published table at the identified bearing, capped at the command."""
    from gfb_agents.rules.identify_map import IdentifyingAgent
    from gfb_agents.rules.map_informed import CommandCappedAgent

    u = getattr(env, "unwrapped", env)
    return CommandCappedAgent(u, IdentifyingAgent(u), "identify_map_v1")


def _make_margin_search(env) -> Policy:
    from gfb_agents.rules.margin_search import MarginSearchAgent

    return MarginSearchAgent(getattr(env, "unwrapped", env))


def _make_margin_search_1x(env) -> Policy:
    from gfb_agents.rules.margin_search_1x import MarginSearch1xAgent

    return MarginSearch1xAgent(getattr(env, "unwrapped", env))


def _make_margin_aim_1x(env) -> Policy:
    from gfb_agents.rules.margin_aim_1x import MarginAim1xAgent

    return MarginAim1xAgent(getattr(env, "unwrapped", env))


def _make_margin_aim_1x_05(env) -> Policy:
    from gfb_agents.rules.margin_aim_1x import MarginAim1xAgent

    return MarginAim1xAgent(getattr(env, "unwrapped", env), margin=0.005, name="margin_aim_1x_05")


def _make_recovery(env) -> Policy:
    from gfb_agents.rules.recovery import RecoveryAgent

    return RecoveryAgent(getattr(env, "unwrapped", env))


def _make_recovery_reset(env) -> Policy:
    from gfb_agents.rules.recovery_reset import RecoveryResetAgent

    return RecoveryResetAgent(getattr(env, "unwrapped", env))


def _make_recovery_detect(env) -> Policy:
    from gfb_agents.rules.recovery_detect import RecoveryDetectAgent

    return RecoveryDetectAgent(getattr(env, "unwrapped", env))


def make_commanded_oracle(env) -> Policy:
    """The commanded-speed tasks' oracle (:class:`gfb_agents.oracles.commanded.CommandedOracle`; v2 and the
    retired v1)."""
    from gfb_agents.oracles.commanded import CommandedOracle

    return CommandedOracle(env)


#: the registry: name -> entry (use :func:`register`; :func:`default_ladder` fills it on first use)
LADDER: dict[str, AgentEntry] = {}
_DEFAULTS_LOADED = False

_RU1, _RUR1, _WR1 = "gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"
_RU2, _RUR2, _WR2 = "gfb_env/RunUp-v2", "gfb_env/RunUpRandomized-v2", "gfb_env/WhirlRecovery-v2"
#: the v1 rules (``docs/agents.md``) and the tasks each was written for
_V1_RULES = (
    (
        "map_informed_v1",
        (_RU1, _RUR1, _WR1),
        _make_map_informed_v1,
        "nominal map with g = 1: d_opt, hold at 0.95 Lambda_c",
    ),
    (
        "identify_map_v1",
        (_RUR1,),
        _make_identify_map_v1,
        "fit the drawn bearing, its table's d_opt and 0.95 lambda_best, g = 1",
    ),
    (
        "margin_search",
        (_RU1, _RUR1, _RU2, _RUR2),
        _make_margin_search,
        "identify, estimate g (unbalance probe, shock decays), best expected hold",
    ),
    (
        "margin_search_1x",
        (_RU2, _RUR2),
        _make_margin_search_1x,
        "margin_search plus g from the monitor's 1x vector ratios between probe dampings (v2)",
    ),
    (
        "margin_aim_1x",
        (_RU2, _RUR2),
        _make_margin_aim_1x,
        "margin_search_1x's estimates and damping, set-point 1 % below its posterior-mean boundary (audit)",
    ),
    (
        "margin_aim_1x_05",
        (_RU2, _RUR2),
        _make_margin_aim_1x_05,
        "margin_aim_1x with a 0.5 % margin",
    ),
    (
        "recovery",
        (_WR1, _WR2),
        _make_recovery,
        "decelerate out of the whirl, estimate g, return below the estimated boundary",
    ),
    (
        "recovery_reset",
        (_WR1, _WR2),
        _make_recovery_reset,
        "recovery, g from the reset observation and the first step's particle update; no probe if sharp",
    ),
    (
        "recovery_detect",
        (_WR2,),
        _make_recovery_detect,
        "recovery_reset plus a CUSUM on the sub-synchronous growth; re-identify g from rate and whirl ratio",
    ),
)


def register(entry: AgentEntry, replace: bool = False, supersede: bool = False) -> AgentEntry:
    """Add ``entry`` to the ladder (ValueError if the name is taken, unless ``replace``).

    ``supersede=True`` (for a naive or oracle entry): every other entry of the same kind gives up
    ``entry.tasks`` (and is removed if no task is left), so each task keeps exactly one naive and one
    oracle -- e.g. an oracle registered for RunUp-v2 takes that task from the built-in ``oracle_v1``,
    which keeps the others."""
    _ensure_defaults()
    if entry.name in LADDER and not replace:
        raise ValueError(f"agent {entry.name!r} is already registered (pass replace=True)")
    if supersede:
        for other in [e for e in LADDER.values() if e.kind == entry.kind and e.name != entry.name]:
            set_tasks(other.name, [t for t in other.tasks if t not in entry.tasks])
    LADDER[entry.name] = entry
    return entry


def set_tasks(name: str, tasks: Iterable[str]) -> None:
    """Restrict (or extend) the tasks of the registered entry ``name``; no task left removes it (e.g.
    ``set_tasks("margin_search", ["gfb_env/RunUp-v2"])`` keeps a rule off the other tasks)."""
    _ensure_defaults()
    if name not in LADDER:
        raise KeyError(f"no registered agent {name!r}")
    tasks = tuple(tasks)
    if tasks:
        LADDER[name] = dataclasses.replace(LADDER[name], tasks=tasks)
    else:
        del LADDER[name]


def unregister(name: str) -> None:
    _ensure_defaults()
    LADDER.pop(name, None)


def registered() -> dict[str, AgentEntry]:
    """The ladder now (a copy), by name."""
    _ensure_defaults()
    return dict(LADDER)


def build(name: str, env, run: int = 0) -> Policy:
    """The registered agent ``name`` built for ``env`` (a fresh env of a task, not yet reset; run
    ``run`` of a learned agent): the one factory of every agent, for the benchmark and for scripts alike.
    An entry's :attr:`AgentEntry.tasks` are the tasks the benchmark plays it on; a script may build a rule
    for another task (e.g. to compare rules across tasks).  LookupError naming the known agents if
    ``name`` is not registered."""
    _ensure_defaults()
    if name not in LADDER:
        raise LookupError(f"no agent {name!r} in the ladder; known: {', '.join(sorted(LADDER))}")
    return LADDER[name].build(env, run)


@contextlib.contextmanager
def scoped():
    """Changes to the ladder inside the ``with`` block are undone after it (a benchmark run registers
    its learned agents without leaking them into the caller's ladder)."""
    _ensure_defaults()
    saved = dict(LADDER)
    try:
        yield
    finally:
        LADDER.clear()
        LADDER.update(saved)


def default_ladder() -> dict[str, AgentEntry]:
    """The built-in entries (module docstring), by name; learned ones from the committed policies."""
    out = [
        AgentEntry(
            "naive", "naive", V1_TASKS + V2_TASKS, make_naive, description="D_W = 1, motor limit, hold"
        ),
        # a reference, kind "rule" since each task has one naive (the normalisation's 0 stays naive)
        AgentEntry(
            "hold",
            "rule",
            V1_TASKS + V2_TASKS,
            make_hold,
            description="reference (issue 19), not a controller: holds the start speed at D_W = 1",
        ),
    ]
    # the v1 rules (gfb_agents.rules): each on the tasks it was written for
    for name, tasks, factory, desc in _V1_RULES:
        out.append(AgentEntry(name, "rule", tasks, factory, description=desc))
    out.append(
        AgentEntry(
            "oracle_v1",
            "oracle",
            V1_TASKS + V2_TASKS,
            make_commanded_oracle,
            description="knows g, the bearing and the exact lambda_best: D_opt/g, 1 % below min(cmd, best)",
        )
    )
    try:
        from gfb_agents import POLICIES_DIR

        out += learned_entries(POLICIES_DIR)
    except FileNotFoundError:  # a broken install: the benchmark refuses to run without them
        pass
    return {e.name: e for e in out}


def _ensure_defaults() -> None:
    global _DEFAULTS_LOADED
    if not _DEFAULTS_LOADED:
        _DEFAULTS_LOADED = True
        for k, v in default_ladder().items():
            LADDER.setdefault(k, v)


def learned_entries(root: str | Path) -> list[AgentEntry]:
    """A learned entry per folder of ``root`` (the name is the folder's; the task from its ``run.json``
    or ``policy.json``).  A folder is one agent: either one model (``model.zip``) or one model per
    training seed (``seed*/`` subfolders, as ``gfb_agents.learned.train --seeds`` writes them)."""
    from gfb_agents.learned.evaluate import run_dirs, run_env_id

    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"no policies folder {root}")
    out = []
    for d in sorted(root.iterdir()):
        if not d.is_dir():
            continue
        runs = run_dirs(d)
        if runs:
            env_id = run_env_id(runs[0])
            if env_id is None:
                raise ValueError(f"{runs[0]} has no run.json/policy.json naming its env_id")
            out.append(AgentEntry(d.name, "learned", (env_id,), run_paths=tuple(str(r) for r in runs)))
    return out


def register_learned(path: str | Path, name: str | None = None, replace: bool = True) -> AgentEntry:
    """Register the learned agent in ``path`` (one model, or one per training seed in ``seed*/``)."""
    from gfb_agents.learned.evaluate import run_dirs, run_env_id

    p = Path(path)
    runs = run_dirs(p) if p.is_dir() else []
    if not runs:
        raise FileNotFoundError(f"no trained model (model.zip or seed*/model.zip) in {p}")
    env_id = run_env_id(runs[0])
    if env_id is None:
        raise ValueError(f"{runs[0]} has no run.json naming its env_id")
    return register(
        AgentEntry(name or p.name, "learned", (env_id,), run_paths=tuple(str(r) for r in runs)),
        replace=replace,
    )


def ladder_for(task: str, names: Iterable[str] | None = None) -> list[AgentEntry]:
    """The entries that apply to ``task`` (all, or those in ``names``), in ladder order: naive, rules,
    oracle, learned."""
    _ensure_defaults()
    want = set(names) if names is not None else None
    sel = [e for e in LADDER.values() if task in e.tasks and (want is None or e.name in want)]
    return sorted(sel, key=lambda e: KINDS.index(e.kind))


def _unique(task: str, kind: str) -> AgentEntry | None:
    sel = [e for e in ladder_for(task) if e.kind == kind]
    if len(sel) > 1:
        raise ValueError(
            f"task {task} has {len(sel)} {kind} agents ({[e.name for e in sel]}); one is allowed"
        )
    return sel[0] if sel else None


def naive_for(task: str) -> AgentEntry | None:
    """The one naive entry of ``task`` (None if none is registered)."""
    return _unique(task, "naive")


def oracle_for(task: str) -> AgentEntry | None:
    """The one oracle entry of ``task`` (None if none is registered)."""
    return _unique(task, "oracle")
