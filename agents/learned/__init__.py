"""Learned agents: SB3 training (:mod:`~gfb_agents.learned.train`; its command line is
``python -m gfb_experiments.train``), the learned policy and the evaluation of any policy
(:mod:`~gfb_agents.learned.evaluate`), the export of a trained run into the committed policies
(:mod:`~gfb_agents.learned.export_policy`; ``python -m gfb_experiments.export_policy``) and the SB3
adapter of the native vector env (:mod:`~gfb_agents.learned.vec_env`); the slew limit of the damping command
(:mod:`~gfb_agents.learned.slew`, ``--damping-slew``)."""
