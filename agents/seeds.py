"""The one owner of the benchmark's seeds: disjoint ranges for training, validation and test.

Every script that plays or trains takes its seeds from here (no literal seeds elsewhere):

========================  ======================  ============================================================
split                     seeds                   used by
========================  ======================  ============================================================
``TRAIN``                 1 000 000 - 1 999 999   the training envs of ``gfb_agents.learned.train`` (run
                                                  ``r``, env ``i``, session ``k``: :func:`train_env_seed`)
``VALIDATION``            2 000 000 - 2 999 999   model selection (the best checkpoint of a training run) and
                                                  the tuning of rules; ``--split validation`` of the benchmark
``TEST``                  3 000 000 - 3 999 999   the final table only (``--split test``, the default)
``LEGACY_V0``             10 000 - 10 049         the v0 table of 2026-11 (seen during development; kept only
                                                  to reproduce that table, never a test set)
``DEV``                   0 - 9 999               unit tests, examples, exploration, early tuning (the
                                                  v1 oracle margins and rules of issue 11 were tuned on
                                                  seeds here: disjoint from TEST all the same)
========================  ======================  ============================================================

A seed here is the argument of ``env.reset(seed=...)``.  A training env is seeded once per session and
then draws its episodes from its own random stream, so the training episodes are not the test episodes:
a test episode is a fresh ``reset(seed=s)`` with ``s`` in ``TEST``, and no training env is ever reset with
a seed of ``VALIDATION`` or ``TEST`` (:func:`train_env_seed` stays inside ``TRAIN``).

The ranges are disjoint (tested); the earlier seeds of this project (0..149 for the identification
check, 10000..10049 for the v0 table, 20000..20019 for the v0 policy selection) all lie in ``DEV`` or
``LEGACY_V0``, so the test split is fresh.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "SeedRange",
    "TRAIN",
    "VALIDATION",
    "TEST",
    "LEGACY_V0",
    "DEV",
    "SPLITS",
    "split_seeds",
    "train_env_seed",
    "BOOTSTRAP_SEED",
    "MIN_TEST_EPISODES",
    "MAX_TRAIN_RUNS",
    "MAX_TRAIN_ENVS",
    "MAX_TRAIN_SESSIONS",
]


@dataclass(frozen=True)
class SeedRange:
    """The integers ``start, start + 1, ..., stop - 1`` (``stop`` excluded), named ``name``."""

    name: str
    start: int
    stop: int

    def __post_init__(self) -> None:
        if not 0 <= self.start < self.stop:
            raise ValueError(f"seed range {self.name}: need 0 <= start < stop, got {self.start}, {self.stop}")

    def __len__(self) -> int:
        return self.stop - self.start

    def __contains__(self, seed: object) -> bool:
        return isinstance(seed, int) and self.start <= seed < self.stop

    def first(self, n: int, offset: int = 0) -> list[int]:
        """The ``n`` seeds ``start + offset, ..., start + offset + n - 1`` (ValueError if they leave the
        range)."""
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"number of seeds must be a non-negative integer, got {n!r}")
        if isinstance(offset, bool) or not isinstance(offset, int) or offset < 0:
            raise ValueError(f"seed offset must be a non-negative integer, got {offset!r}")
        if offset + n > len(self):
            raise ValueError(
                f"{n} seeds from offset {offset} leave the {self.name} range ({len(self)} seeds)"
            )
        return list(range(self.start + offset, self.start + offset + n))

    def overlaps(self, other: SeedRange) -> bool:
        return self.start < other.stop and other.start < self.stop


TRAIN = SeedRange("train", 1_000_000, 2_000_000)
VALIDATION = SeedRange("validation", 2_000_000, 3_000_000)
TEST = SeedRange("test", 3_000_000, 4_000_000)
LEGACY_V0 = SeedRange("legacy_v0", 10_000, 10_050)
DEV = SeedRange("dev", 0, 10_000)

#: the splits a benchmark run may use (``--split``)
SPLITS: dict[str, SeedRange] = {r.name: r for r in (TEST, VALIDATION, LEGACY_V0)}

#: the issue's floor for the final table: at least this many test episodes per (task, agent)
MIN_TEST_EPISODES = 200  # issue 19: >= 200 test seeds per (task, agent) where the cost allows

#: layout of :func:`train_env_seed`: run ``r`` owns ``MAX_TRAIN_SESSIONS * MAX_TRAIN_ENVS`` seeds
MAX_TRAIN_ENVS = 100
MAX_TRAIN_SESSIONS = 100
MAX_TRAIN_RUNS = len(TRAIN) // (MAX_TRAIN_ENVS * MAX_TRAIN_SESSIONS)

#: the random state of the bootstrap (rliable draws its indices from NumPy's global generator; the
#: statistics code seeds it with this and restores it afterwards)
BOOTSTRAP_SEED = 20_261_130


def split_seeds(split: str, n: int) -> list[int]:
    """The first ``n`` seeds of ``split`` (``"test"``, ``"validation"`` or ``"legacy_v0"``)."""
    if split not in SPLITS:
        raise ValueError(f"split must be one of {sorted(SPLITS)}, got {split!r}")
    return SPLITS[split].first(n)


def train_env_seed(run: int, env_index: int, session: int = 0) -> int:
    """Seed of training env ``env_index`` of independent training run ``run`` in its ``session``-th
    (re)start: every run, env and resumed session gets its own seed, all inside ``TRAIN``.

    A resumed run re-seeds its envs (a new session) so that it does not replay the first session's
    episodes."""
    for name, v, hi in (
        ("run", run, MAX_TRAIN_RUNS),
        ("env_index", env_index, MAX_TRAIN_ENVS),
        ("session", session, MAX_TRAIN_SESSIONS),
    ):
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < hi:
            raise ValueError(f"{name} must be an integer in [0, {hi}), got {v!r}")
    return TRAIN.start + (run * MAX_TRAIN_SESSIONS + session) * MAX_TRAIN_ENVS + env_index
