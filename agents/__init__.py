"""Agents for the gfb_env tasks: scripted baselines (:mod:`gfb_agents.scripted`), SB3 training
(:mod:`gfb_agents.train`), evaluation of scripted and learned policies alike (:mod:`gfb_agents.evaluate`).

See ``docs/agents.md``."""
