"""The retired task ids (issue 18): ``gfb_env/RunUp-v0``, ``gfb_env/RunUpRandomized-v0`` and
``gfb_env/WhirlRecovery-v0`` stay registered only to refuse, with one error that says why and which id to
use (``gymnasium.make`` and ``gymnasium.make_vec``, every vectorization mode).

Why: the v0 plant is exactly identifiable from its first observation (the nominal or drawn bearing, ideal
sensors, no hidden damping effectiveness: inverting one snapshot with the simulator gives the optimum
before the first action), so v0 measured identification, not control skill.  ``CHANGELOG.md`` has the
history; git keeps the code (the last commit with v0 is the parent of the one that added this module).
"""

from __future__ import annotations

from typing import Any, NoReturn

from gymnasium import error

__all__ = ["RetiredTaskError", "RETIRED_IDS", "RetiredEntryPoint"]

#: retired id -> the id to use instead
RETIRED_IDS: dict[str, str] = {
    "gfb_env/RunUp-v0": "gfb_env/RunUp-v1",
    "gfb_env/RunUpRandomized-v0": "gfb_env/RunUpRandomized-v1",
    "gfb_env/WhirlRecovery-v0": "gfb_env/WhirlRecovery-v1",
}


class RetiredTaskError(error.Error, ValueError):
    """A retired task id was made (a :class:`gymnasium.error.Error`, and a ``ValueError`` like every
    refused argument of the envs: catch either)."""


class RetiredEntryPoint:
    """The entry point (and vector entry point) of a retired id: raises :class:`RetiredTaskError`."""

    def __init__(self, env_id: str) -> None:
        if env_id not in RETIRED_IDS:
            raise ValueError(f"env_id: not a retired id: {env_id!r} (retired: {', '.join(RETIRED_IDS)})")
        self.env_id = env_id

    def __call__(self, *args: Any, **kwargs: Any) -> NoReturn:
        new = RETIRED_IDS[self.env_id]
        raise RetiredTaskError(
            f"{self.env_id} is retired (issue 18): its plant is exactly identifiable from the first "
            f"observation, so it measures identification, not control skill (CHANGELOG.md). "
            f"Use {new}: the same task on the instrumented machine with a hidden damping effectiveness "
            "and a commanded speed (docs/envs.md)."
        )

    def __repr__(self) -> str:
        return f"RetiredEntryPoint({self.env_id!r})"
