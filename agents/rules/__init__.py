"""The honest rules, one module per family; each reads only the observation, the env's documented
configuration and the project's own model (never the episode or the hidden draw).

* :mod:`.naive`: the benchmark's naive ramp (``naive``);
* :mod:`.schedule`: the paper's schedule (``gfb schedule``'s run-up as an agent);
* :mod:`.map_informed`: the nominal map's schedule, capped at the command (``map_informed_v1``);
* :mod:`.identify_map`: the published table at the identified bearing (``identify_map_v1``);
* :mod:`.margin_search`: identify, estimate the damping gain online, hold at the best expected operating
  point (``margin_search``; its decision: :mod:`.operating_point`);
* :mod:`.recovery`: the WhirlRecovery rule (``recovery``; written for v1, played on v2);
* :mod:`.common`: what the commanded-speed rules share.

Build them through the ladder (:func:`gfb_agents.ladder.build`), the one factory."""
