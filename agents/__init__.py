"""Agents for the gfb_env tasks, by role (``docs/agents.md``):

* :mod:`gfb_agents.policy`: the one policy interface (``reset()``, ``predict(obs, state, episode_start)``);
* :mod:`gfb_agents.ladder`: the benchmark's ladder, the one factory of agents (``ladder.build(name, env)``);
* :mod:`gfb_agents.rules`: the honest rules, one module per family;
* :mod:`gfb_agents.estimation`: what the rules estimate online (identification, stability, gain, probes);
* :mod:`gfb_agents.oracles`: the oracles (they know the hidden parameters);
* :mod:`gfb_agents.learned`: SB3 training, evaluation, export, the SB3 vector-env adapter;
* :mod:`gfb_agents.seeds`: the seed splits.
"""

from pathlib import Path

#: the installed package's folder (its data: ``policies/``, ``hyperparams/``)
PACKAGE_DIR = Path(__file__).resolve().parent
#: the committed learned policies (package data), one folder per agent
POLICIES_DIR = PACKAGE_DIR / "policies"
#: the rl-zoo3-style hyperparameter files of ``gfb_agents.learned.train``
HYPERPARAMS_DIR = PACKAGE_DIR / "hyperparams"
