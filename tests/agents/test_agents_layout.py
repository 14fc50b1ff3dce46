"""The agents package by role (issue 18): one policy interface, the ladder the only factory, every committed
policy found, MarginSearchAgent's memory a dataclass and its modes an enum dispatched one method each."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import shutil

import numpy as np
import pytest

import gfb_agents
import gfb_env.envs  # noqa: F401  (registers the ids)
from gfb_agents import ladder
from gfb_agents.policy import Policy, PrivilegedPolicy
from gfb_agents.rules.margin_search import MarginSearchAgent, MarginSearchMemory, Mode
from gfb_agents.rules.operating_point import OperatingPointConfig
from gfb_agents.rules.recovery import RecoveryAgent, RecoveryMemory
from gfb_env.envs import make_env


def _modules():
    """Every module of gfb_agents (imported)."""
    out = [gfb_agents]
    for info in pkgutil.walk_packages(gfb_agents.__path__, "gfb_agents."):
        out.append(importlib.import_module(info.name))
    return out


@pytest.mark.parametrize("task", ["gfb_env/RunUp-v2", "gfb_env/RunUp-v1"])  # current; retired (record)
def test_every_ladder_agent_is_a_policy_with_the_one_reset_signature(task):
    env = make_env(task, max_episode_steps=3)
    obs, _ = env.reset(seed=0)
    for name, entry in ladder.registered().items():
        if entry.kind == "learned" or task not in entry.tasks:
            continue
        pol = ladder.build(name, env)
        assert isinstance(pol, Policy) and pol.name == name
        assert isinstance(pol, PrivilegedPolicy) == (entry.kind == "oracle"), name
        pol.reset()
        if isinstance(pol, PrivilegedPolicy):
            pol.observe_reset_info(env.reset(seed=0)[1])
        a, state = pol.predict(obs, episode_start=True)
        assert a.shape == (2,) and np.all(np.abs(a) <= 1) and state is None, name
    # one reset signature in the whole package: reset(self), nothing else
    for mod in _modules():
        for _, cls in inspect.getmembers(mod, inspect.isclass):
            if issubclass(cls, Policy) and cls.__module__.startswith("gfb_agents"):
                assert list(inspect.signature(cls.reset).parameters) == ["self"], cls
    with pytest.raises(TypeError):  # the interface is abstract: predict must be defined
        Policy()


def test_the_ladder_is_the_only_factory_of_agents():
    # no other module defines a public make_* function (the SB3 vector-env helper builds envs, not agents)
    factories = {
        f"{mod.__name__}.{n}"
        for mod in _modules()
        if mod.__name__ != "gfb_agents.ladder"
        for n, f in inspect.getmembers(mod, inspect.isfunction)
        if n.startswith("make_") and f.__module__ == mod.__name__
    }
    assert factories == {"gfb_agents.learned.train.make_vec_env_for"}
    with pytest.raises(LookupError, match="no agent 'bogus' in the ladder; known: .*margin_search"):
        ladder.build("bogus", make_env("gfb_env/RunUp-v2"))


def test_load_learned_policies_finds_single_and_multi_seed_folders(tmp_path):
    from gfb_agents import POLICIES_DIR
    from gfb_agents.learned.evaluate import load_learned_policies

    src = POLICIES_DIR / "RunUp-v1_sac" / "seed0"
    for dest in ("multi/seed0", "multi/seed1", "single"):
        shutil.copytree(src, tmp_path / dest)
    (tmp_path / "notes").mkdir()  # a folder without a model is no policy
    pols = load_learned_policies(tmp_path)
    assert [p.name for p in pols] == ["multi/seed0", "multi/seed1", "single"]
    assert all(p.env_id == "gfb_env/RunUp-v1" for p in pols)
    # the ladder reads the same folders as one learned agent per folder, one run per seed
    got = {e.name: e.runs for e in ladder.learned_entries(tmp_path)}
    assert got == {"multi": 2, "single": 1}


def test_margin_search_memory_is_typed_and_its_modes_dispatch_one_method_each(monkeypatch):
    env = make_env("gfb_env/RunUp-v1")
    pol = MarginSearchAgent(env.unwrapped)
    m = pol._new_memory()
    assert dataclasses.is_dataclass(m) and isinstance(m, MarginSearchMemory)
    assert m.mode is Mode.INIT  # the nominal task: nothing to identify
    assert all(f.type != "dict" for f in dataclasses.fields(m))
    assert set(pol.MODE_HANDLERS) == set(Mode) - {Mode.DIP}
    assert set(RecoveryAgent.MODE_HANDLERS) == set(Mode)
    assert isinstance(
        RecoveryAgent(make_env("gfb_env/WhirlRecovery-v1").unwrapped)._new_memory(), RecoveryMemory
    )
    # each mode calls its own handler, and only it
    for mode, handler in pol.MODE_HANDLERS.items():
        calls = []
        for other in pol.MODE_HANDLERS.values():
            monkeypatch.setattr(
                pol, other, lambda obs, rpm, mem, _n=other, _c=calls: _c.append(_n) or [0.0, 0.0]
            )
        m.mode = mode
        assert pol._dispatch(np.zeros(3), 30000.0, m) == [0.0, 0.0]
        assert calls == [handler], mode
    m.mode = Mode.DIP  # RecoveryAgent's mode: margin_search has no handler for it
    with pytest.raises(KeyError):
        pol._dispatch(np.zeros(3), 30000.0, m)
    env.close()


@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"damping_range": (0.0, 1.0)}, "damping_range"),
        ({"damping_range": (2.0, 1.0)}, "damping_range"),
        ({"damping_range": (0.1, 1.0), "rel_sd": 0.0}, "rel_sd"),
        ({"damping_range": (0.1, 1.0), "n_lambda": 0}, "n_lambda"),
        ({"damping_range": (0.1, 1.0), "fail_cost": float("nan")}, "fail_cost"),
    ],
)
def test_operating_point_config_refuses_bad_fields_by_name(kwargs, field):
    with pytest.raises(ValueError, match=field):
        OperatingPointConfig(**kwargs)


def test_committed_policies_carry_no_optimiser_state():
    """Issue 21: the committed policies stay small: no model.zip holds an optimiser's moments (what
    export_policy strips), and no folder holds a checkpoint or a replay buffer."""
    from gfb_agents.learned.evaluate import POLICIES_DIR
    from gfb_agents.learned.export_policy import has_optimizer_state

    zips = sorted(POLICIES_DIR.rglob("model.zip"))
    assert zips, POLICIES_DIR
    assert [z for z in zips if has_optimizer_state(z)] == []
    allowed = {"model.zip", "actor.pt", "vecnormalize.pkl", "policy.json", "README.md", "learning_curve.png"}
    assert sorted({p.name for p in POLICIES_DIR.rglob("*") if p.is_file()} - allowed) == []
