"""Agents for the gfb_env tasks: scripted baselines (:mod:`agents.scripted`), SB3 training
(:mod:`agents.train`), evaluation of scripted and learned policies alike (:mod:`agents.evaluate`).

See ``docs/agents.md``."""
