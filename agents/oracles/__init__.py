"""The oracles: policies that know the hidden parameters (1 on the benchmark's normalised scale).
:class:`~gfb_agents.oracles.commanded.CommandedOracle` (``oracle_v1``) is the oracle of every v1 task."""
