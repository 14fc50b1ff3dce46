"""The benchmark's ladder of agents: naive, rules, oracle, learned -- one registry, one owner.

Every agent of the benchmark is an :class:`AgentEntry`: a name, a kind (``naive`` | ``rule`` |
``oracle`` | ``learned``), the task ids it applies to and a factory.  The benchmark
(``python -m gfb_experiments.benchmark_agents``) runs, for each task, *every* entry that applies to it on
the same seeds, and normalises each episode's return with the same seed's naive and oracle returns
(``gfb_experiments.benchmark_stats.normalized_scores``): 0 = naive, 1 = oracle.  So every task needs
exactly one ``naive`` and one ``oracle`` entry.

Registering an agent (the interface for the v1 oracle, the rules and the learned agents)::

    from gfb_agents.ladder import AgentEntry, register, V1_TASKS
    # make_oracle(env) -> Policy; supersede=True takes the tasks from the built-in oracle_v1
    register(AgentEntry("my_oracle", "oracle", V1_TASKS, make_oracle), supersede=True)
    register(AgentEntry("identify_shock", "rule", ("gfb_env/RunUpRandomized-v1",), make_rule))
    register_learned("runs/RunUpRandomized-v1_sac", name="sac")   # a gfb_agents.train output (seed*/)

A factory is called as ``factory(env)`` with a fresh env of the task (``gymnasium.make(task,
**env_kwargs)``, not yet reset) -- the very env the agent's episodes are then played on, so an oracle may
keep it and read the episode's hidden parameters through the env's public accessors -- and returns a
:class:`~gfb_agents.scripted.Policy`; a naive agent or a rule must read only the observation and the
env's documented configuration.  The evaluation calls ``policy.reset()`` before each ``env.reset`` and,
where the policy has one, ``policy.observe_reset_info(info)`` after it (oracles only).  Factories and
entries must be picklable (module-level functions or ``functools.partial`` of them): the evaluation
sweep builds the agents in its worker processes.

A learned entry has one run per independent training seed (``run_paths``); the benchmark plays every run
on the same test seeds and the statistics stratify by run.

The built-in ladder (:func:`default_ladder`): on every task the naive ramp (:class:`NaiveRampAgent`), the
v1 rules of :mod:`gfb_agents.rules_v1` on the tasks each was written for,
:class:`~gfb_agents.oracle.CommandedOracle` (``oracle_v1``) as the oracle, and the committed learned
policies of their task.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gfb_agents.nominal_map import NominalMap
from gfb_agents.scripted import ControlSpec, Policy, ScriptedPolicy

__all__ = [
    "KINDS",
    "AgentEntry",
    "NaiveRampAgent",
    "register",
    "set_tasks",
    "unregister",
    "registered",
    "scoped",
    "register_learned",
    "learned_entries",
    "ladder_for",
    "naive_for",
    "oracle_for",
    "default_ladder",
    "LADDER",
    "V1_TASKS",
    "NAIVE_DAMPING",
    "NAIVE_MARGIN",
]

KINDS = ("naive", "rule", "oracle", "learned")
#: name of the v1 observation entry of the commanded speed (``gfb_env.envs.units.SPEED_COMMAND``)
SPEED_COMMAND = "speed_command"

try:  # the task list has one owner (the retired v0 ids are no task of the ladder)
    from gfb_env.envs import ENV_IDS

    V1_TASKS: tuple[str, ...] = tuple(t for t in ENV_IDS if t.endswith("-v1"))
except ImportError:  # pragma: no cover - gfb_env is a dependency
    V1_TASKS = ()


@dataclass(frozen=True)
class AgentEntry:
    """One rung of the ladder.

    Attributes:
        name: unique name (the table's ``agent`` column).
        kind: ``"naive"``, ``"rule"``, ``"oracle"`` or ``"learned"``.
        tasks: the task ids it applies to.
        factory: ``factory(env) -> Policy`` (None for a learned entry, which loads ``run_paths``).
        run_paths: learned entries only: one trained model per independent training seed (a directory
            :class:`~gfb_agents.evaluate.LearnedPolicy` reads: its ``best/`` model, selected on the
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


class NaiveRampAgent(ScriptedPolicy):
    """``naive``: the paper's constant-damping ramp (0 of the normalised scale).

    Commands ``D_W = damping`` (1, the paper's Fig. 5 value) throughout and ramps at the motor limit
    toward ``min(commanded speed, (1 - margin) Lambda_c(D_W) of the nominal bearing)``, then holds.  The
    commanded speed is read from the observation where the task publishes one
    (``env.observation_layout.has("speed_command")``: ``speed_command_rpm(obs)``, the v1 tasks), else the
    task's documented
    nominal target (``ControlSpec.target_rpm``).  It reads nothing else: no whirl feedback, no
    identification -- what a user who knows only the paper's map of the nominal bearing would do.
    """

    def __init__(
        self,
        spec: ControlSpec,
        nmap: NominalMap,
        damping: float = 1.0,
        margin: float = 0.05,
        name: str = "naive",
    ):
        super().__init__(name, spec)
        if not 0 <= margin < 0.5:
            raise ValueError(f"margin must lie in [0, 0.5), got {margin!r}")
        self.damping = float(damping)
        self.cap_rpm = float(nmap.rpm((1.0 - margin) * nmap.critical_at(self.damping)))
        # the command is an observation entry of the v1 tasks only (ObservationLayout.has / the decoder)
        lay = spec.observations
        has = getattr(lay, "has", None)
        self._command = lay.speed_command_rpm if has is not None and has(SPEED_COMMAND) else None

    def setpoint_rpm(self, obs: np.ndarray) -> float:
        cmd = float(self._command(obs)) if self._command is not None else self.spec.target_rpm
        return min(cmd, self.cap_rpm) if math.isfinite(cmd) else self.cap_rpm

    def _act(self, obs, rpm, m):
        return [self.track(m, rpm, self.setpoint_rpm(obs)), self.spec.damping_action(self.damping)]


#: the naive agent's damping and margin below Lambda_c(D_W) of the nominal bearing (issue 11)
NAIVE_DAMPING = 1.0
NAIVE_MARGIN = 0.05


def make_naive(env) -> NaiveRampAgent:
    """The naive ramp for ``env`` (:class:`NaiveRampAgent` with D_W = 1 and a 5 % margin)."""
    nmap = NominalMap.from_env(env)
    return NaiveRampAgent(ControlSpec.from_env(env, nmap), nmap, NAIVE_DAMPING, NAIVE_MARGIN)


def make_v1_rule(name: str, env) -> Policy:
    """The v1 rule ``name`` of :func:`gfb_agents.rules_v1.make_rule`."""
    from gfb_agents.rules_v1 import make_rule

    return make_rule(name, env)


def make_commanded_oracle(env) -> Policy:
    """The v1 tasks' oracle (:class:`gfb_agents.oracle.CommandedOracle`)."""
    from gfb_agents.oracle import CommandedOracle

    return CommandedOracle(env)


#: the registry: name -> entry (use :func:`register`; :func:`default_ladder` fills it on first use)
LADDER: dict[str, AgentEntry] = {}
_DEFAULTS_LOADED = False

_RU1, _RUR1, _WR1 = "gfb_env/RunUp-v1", "gfb_env/RunUpRandomized-v1", "gfb_env/WhirlRecovery-v1"
#: the v1 rules (``docs/agents.md``) and the tasks each was written for
_V1_RULES = (
    ("map_informed_v1", (_RU1, _RUR1, _WR1), "nominal map with g = 1: d_opt, hold at 0.95 Lambda_c"),
    ("identify_map_v1", (_RUR1,), "fit the drawn bearing, its table's d_opt and 0.95 lambda_best, g = 1"),
    (
        "margin_search",
        (_RU1, _RUR1),
        "identify, estimate g (unbalance probe, shock decays), best expected hold",
    ),
    ("recovery", (_WR1,), "decelerate out of the whirl, estimate g, return below the estimated boundary"),
)


def register(entry: AgentEntry, replace: bool = False, supersede: bool = False) -> AgentEntry:
    """Add ``entry`` to the ladder (ValueError if the name is taken, unless ``replace``).

    ``supersede=True`` (for a naive or oracle entry): every other entry of the same kind gives up
    ``entry.tasks`` (and is removed if no task is left), so each task keeps exactly one naive and one
    oracle -- e.g. an oracle registered for RunUp-v1 takes that task from the built-in ``oracle_v1``,
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
    ``set_tasks("margin_search", ["gfb_env/RunUp-v1"])`` keeps a rule off the other tasks)."""
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
        AgentEntry("naive", "naive", V1_TASKS, make_naive, description="D_W = 1, motor limit, hold"),
    ]
    # the v1 rules (gfb_agents.rules_v1): each on the tasks it was written for
    for name, tasks, desc in _V1_RULES:
        out.append(AgentEntry(name, "rule", tasks, functools.partial(make_v1_rule, name), description=desc))
    out.append(
        AgentEntry(
            "oracle_v1",
            "oracle",
            V1_TASKS,
            make_commanded_oracle,
            description="knows g, the bearing and the exact lambda_best: D_opt/g, 1 % below min(cmd, best)",
        )
    )
    try:
        from gfb_agents.learned.evaluate import POLICIES_DIR

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
    training seed (``seed*/`` subfolders, as ``gfb_agents.train --seeds`` writes them)."""
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
