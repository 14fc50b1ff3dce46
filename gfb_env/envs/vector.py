"""A native Gymnasium vector environment of the GFB tasks (issue 13, first step).

``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` (or no
``vectorization_mode``: the registered ``vector_entry_point`` is then Gymnasium's default) returns a
:class:`GFBVectorEnv` of ``N`` copies of the task.  It holds ``N`` plain (unwrapped) task envs and runs
one control step as the single env's stages over the whole batch:

1. :meth:`GFBEnv.plan_step` of each env (its action checked and sanitised, its motor, actuator, kick and
   shocks, its plant's call prepared; each env's random draws stay in their own order);
2. the plant: the integrator of every stepped env over the control interval, in one compiled batch
   (:meth:`~gfb_env.integrator.BatchAdvance.run_prepared_each`; ``num_threads`` threads, default all
   cores numba sees: ``num_threads - 1`` worker threads and this one claim the envs one at a time);
3. :meth:`GFBEnv.finish_step` of each env as soon as its plant is done, in this thread while the
   workers integrate the others (judge: outcome, stability, reward and termination; emit: its
   observation and info), so the Python of the step overlaps its compiled part; then the time limit
   over the batch; Gymnasium's info arrays are built for the whole batch (one conversion per value
   type, exactly ``VectorEnv._add_info``'s arrays).  The results do not depend on the thread count
   or on the order in which the envs finish (each env's finish uses its own state and generator).

Threads share one interpreter lock, so the Python of stages 1 and 3 runs on one core whatever
``num_threads`` is: RunUp-v2 at N = 16 spends ~27 us per env step in the compiled plant and ~600 in
that Python (issue 20's profile).  ``num_processes=P`` splits the envs into ``P`` shards, the first
stepped (stages 1-3) in this process and each other one by a worker process of its own
(:mod:`gfb_env.envs.shards`), all at the same time: ``gymnasium.make_vec(id, num_envs=16,
vectorization_mode="vector_entry_point", num_processes=2)`` uses two cores for the whole step.
Results do not depend on ``P`` (tested).

:meth:`GFBEnv.step` is the same three phases for one env.

Semantics: identical, bit for bit, to ``gymnasium.vector.SyncVectorEnv`` over ``gymnasium.make(id)`` (the
task env in ``TimeLimit``) with the same seeds: observations, rewards, terminations, truncations and infos
(Gymnasium's vector info format, each key with its ``_key`` mask).  ``reset(seed=s)`` seeds env ``i``
with ``s + i`` (a list seeds each env); ``options["reset_mask"]`` resets only some envs.

Autoreset (``metadata["autoreset_mode"]``, Gymnasium 1.x, https://farama.org/Vector-Autoreset-Mode):

* ``AutoresetMode.NEXT_STEP`` (default, as ``SyncVectorEnv``): an env that terminated or was truncated
  in step ``t`` is reset (unseeded: its generator continues) by step ``t + 1``, whose action for it is
  ignored; that step returns its reset observation and info with reward 0 and neither flag set.
* ``AutoresetMode.SAME_STEP``: the env is reset in the step that ended it; the step returns the reset
  observation and info, the last ones under ``infos["final_obs"]`` and ``infos["final_info"]``.
* ``AutoresetMode.DISABLED``: no reset; stepping an ended env raises, reset it with ``reset_mask``.

:meth:`GFBVectorEnv.get_state` / :meth:`GFBVectorEnv.set_state` snapshot the whole batch (every env's
exact snapshot, the time limit counters and the autoreset flags).
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from gfb_env.envs.base import GFBEnv
from gfb_env.envs.run_up import RunUpEnv
from gfb_env.envs.run_up_randomized import RunUpRandomizedEnv
from gfb_env.envs.shards import RemoteEnv, Shard, step_envs
from gfb_env.envs.whirl_recovery import WhirlRecoveryEnv
from gfb_env.integrator import BatchAdvance

__all__ = ["GFBVectorEnv", "RunUpVectorEnv", "RunUpRandomizedVectorEnv", "WhirlRecoveryVectorEnv"]


class GFBVectorEnv(VectorEnv):
    """``num_envs`` copies of one GFB task stepped as a batch (see the module docstring).

    Args:
        num_envs: number of envs (>= 1).
        env_class: the task (a :class:`~gfb_env.envs.base.GFBEnv` subclass; the task subclasses below
            fix it).
        max_episode_steps: truncation after this many steps of an episode (Gymnasium's ``TimeLimit``;
            ``make_vec`` passes the registered value); None: no time limit.
        autoreset_mode: an :class:`~gymnasium.vector.AutoresetMode` or its value.
        render_mode: ``None`` or ``"rgb_array"`` (``render()`` returns one frame per env).
        num_threads: threads of the compiled plant stage (numba; default: every core numba sees,
            ``numba.config.NUMBA_NUM_THREADS``, itself capped by the environment variable
            ``NUMBA_NUM_THREADS``); the results do not depend on it.  See :attr:`num_threads`.  With
            worker processes each worker uses one thread, and so does this one by default.
        num_processes: 1 (default): the envs live in this process; ``P > 1``: they are split into ``P``
            contiguous shards, the first stepped here, each other one by a worker process of its own,
            all at the same time
            (:mod:`gfb_env.envs.shards`; the way to use several cores for the step's Python, which
            threads cannot: see the module docstring).  The results do not depend on it.
        **kwargs: the task's keyword arguments (:class:`~gfb_env.envs.config.EnvConfig`), the same for
            every env.
    """

    #: the task of the subclasses registered as ``vector_entry_point``
    env_class: ClassVar[type[GFBEnv] | None] = None

    def __init__(
        self,
        num_envs: int = 1,
        *,
        env_class: type[GFBEnv] | None = None,
        max_episode_steps: int | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        num_threads: int | None = None,
        num_processes: int = 1,
        **kwargs: Any,
    ) -> None:
        super().__init__()
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if (
            isinstance(num_processes, bool)
            or not isinstance(num_processes, int | np.integer)
            or not 1 <= num_processes <= num_envs
        ):
            raise ValueError(
                f"num_processes must be an integer in [1, num_envs={num_envs}], got {num_processes!r}"
            )
        #: the compiled batch integrator of this process's envs (its ``num_threads`` may be changed at any
        #: time); with worker processes one thread by default (a process per core)
        self._batch = BatchAdvance(1 if num_threads is None and num_processes > 1 else num_threads)
        if max_episode_steps is not None and (
            isinstance(max_episode_steps, bool)
            or not isinstance(max_episode_steps, int | np.integer)
            or max_episode_steps < 1
        ):
            raise ValueError(
                f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}"
            )
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            modes = [m.value for m in AutoresetMode]
            raise ValueError(f"autoreset_mode must be one of {modes}, got {autoreset_mode!r}") from None
        cls = env_class if env_class is not None else self.env_class
        if cls is None or not (isinstance(cls, type) and issubclass(cls, GFBEnv)):
            raise ValueError(f"env_class must be a GFBEnv subclass, got {cls!r}")
        self.num_envs = int(num_envs)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        #: the envs' shards: contiguous index ranges, sizes differing by at most one (the larger first);
        #: shard 0 lives in this process, each other one in a worker process of its own
        #: (:mod:`gfb_env.envs.shards`)
        p = int(num_processes)
        sizes = [self.num_envs // p + (k < self.num_envs % p) for k in range(p)]
        self._shard_ranges = [range(sum(sizes[:k]), sum(sizes[: k + 1])) for k in range(p)]
        #: the task envs, unwrapped (the time limit and the order checks are done here); a worker
        #: process's envs are :class:`~gfb_env.envs.shards.RemoteEnv` proxies
        self.envs: list[GFBEnv] = []
        self._shards: list[Shard] = []
        # shard 0 here (its envs built first: they check the arguments, in one line, before any process
        # starts), each other shard in a worker process
        self.envs = [cls(render_mode=render_mode, **deepcopy(kwargs)) for _ in self._shard_ranges[0]]
        first = self.envs[0]
        if p > 1:
            try:
                for r in self._shard_ranges[1:]:
                    shard = Shard(cls, len(r), render_mode, deepcopy(kwargs))
                    self._shards.append(shard)
                    self.envs.extend(RemoteEnv(shard, j, cls) for j in range(len(r)))
            except BaseException:
                for shard in self._shards:
                    shard.close()
                raise
        self.metadata = {**first.metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = render_mode
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        n = self.num_envs
        self._observations = np.zeros(self.observation_space.shape, dtype=self.observation_space.dtype)
        self._rewards = np.zeros(n, dtype=np.float64)
        self._terminations = np.zeros(n, dtype=np.bool_)
        self._truncations = np.zeros(n, dtype=np.bool_)
        self._autoreset_envs = np.zeros(n, dtype=np.bool_)
        self._elapsed_steps = np.zeros(n, dtype=np.int64)
        self._needs_reset = True
        #: :meth:`_batch_infos_of_kind`'s plans, by (keys, value types)
        self._info_plans: dict[tuple, tuple] = {}

    # ------------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the envs (all, or those of ``options["reset_mask"]``); env ``i`` gets ``seed + i``."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        elif isinstance(seed, list | tuple):
            seeds = list(seed)
        else:  # Gymnasium's SyncVectorEnv raises TypeError here too (without saying why)
            raise TypeError(
                f"seed must be None, an int or a list of num_envs={n} ints or None, "
                f"got {type(seed).__name__} {seed!r}"
            )
        if len(seeds) != n:
            raise ValueError(f"seed: a list of seeds must have length num_envs={n}, got {len(seeds)}")
        options = dict(options) if options is not None else None
        mask = np.ones(n, dtype=np.bool_)
        if options is not None and "reset_mask" in options:
            # the exception types of Gymnasium's SyncVectorEnv: TypeError for the type and the dtype,
            # ValueError for the shape and an all-False mask
            mask = options.pop("reset_mask")
            if not isinstance(mask, np.ndarray):
                raise TypeError(f"options['reset_mask'] must be a numpy array, got {type(mask).__name__}")
            if mask.shape != (n,):
                raise ValueError(f"options['reset_mask'] must have shape ({n},), got {mask.shape}")
            if mask.dtype != np.bool_:
                raise TypeError(f"options['reset_mask'] must have dtype bool, got {mask.dtype}")
            if not np.any(mask):
                raise ValueError("options['reset_mask'] must contain at least one True")
            if self._needs_reset and not np.all(mask):
                raise RuntimeError("reset all envs (no reset_mask) before resetting some")
        infos = self._batch_infos([(i, self._reset_env(i, seeds[i], options)) for i in np.flatnonzero(mask)])
        self._needs_reset = False
        return self._observations.copy(), infos

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        a = self.check_actions(actions)
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            to_reset = self._autoreset_envs.copy()
        else:
            if self.autoreset_mode is AutoresetMode.DISABLED and np.any(self._autoreset_envs):
                raise RuntimeError(
                    "autoreset is disabled: reset the ended envs with reset(options={'reset_mask': ...})"
                )
            to_reset = np.zeros(n, dtype=np.bool_)
        stepped = np.flatnonzero(~to_reset)
        env_infos: list[dict | None] = [None] * n
        for i, info in zip(stepped, self._step_envs(a, stepped), strict=True):
            env_infos[i] = info
        # ---- autoresets
        final: dict[int, dict] = {}
        for i in np.flatnonzero(to_reset):
            env_infos[i] = self._reset_env(i)
            self._rewards[i] = 0.0
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            for i in np.flatnonzero(self._terminations | self._truncations):
                final[i] = {"final_obs": self._observations[i].copy(), "final_info": env_infos[i]}
                ended = (self._terminations[i], self._truncations[i])
                env_infos[i] = self._reset_env(i)
                self._terminations[i], self._truncations[i] = ended  # reported for the step that ended
        entries: list[tuple[int, dict]] = []
        for i in range(n):
            if i in final:
                entries.append((i, final[i]))
            entries.append((i, env_infos[i]))
        infos = self._batch_infos(entries)
        self._autoreset_envs = self._terminations | self._truncations
        return (
            self._observations.copy(),
            self._rewards.copy(),
            self._terminations.copy(),
            self._truncations.copy(),
            infos,
        )

    def check_actions(self, actions: Any) -> np.ndarray:
        """``actions`` as float64 ``(num_envs, 2)``, with the exception types of Gymnasium's
        ``SyncVectorEnv``: a scalar (nothing to iterate over) raises ``TypeError``; a wrong shape and a
        complex or non-numeric dtype raise ``ValueError`` (as each env's ``step`` does)."""
        n = self.num_envs
        a = np.asarray(actions)
        if a.ndim == 0:
            raise TypeError(f"actions must be a batch of shape ({n}, 2), got the scalar {actions!r}")
        if a.shape != (n, 2):
            raise ValueError(f"actions must have shape ({n}, 2), got {a.shape}")
        if a.dtype.kind not in "biuf":
            raise ValueError(f"actions must be real numbers, got dtype {a.dtype}")
        return a.astype(np.float64, copy=False)

    def _batch_infos(self, entries: list[tuple[int, dict]]) -> dict[str, Any]:
        """Gymnasium's vector info of ``entries`` (env index, info), exactly what calling
        ``VectorEnv._add_info`` on each in turn gives (the same arrays, dtypes, masks and key order),
        built key by key: one array and one mask per key instead of a dict pass per env (that pass
        cost ~70 us per env and step, as much as the Python of the env's own step)."""
        n = self.num_envs
        idx = [int(i) for i, _ in entries]
        keys = tuple(entries[0][1]) if entries else ()
        if idx == list(range(n)) and all(tuple(info) == keys for _, info in entries):
            kinds = {tuple(map(type, info.values())) for _, info in entries}
            if len(kinds) == 1:  # every env's values of one type per key (the common case)
                return self._batch_infos_of_kind(entries, keys, kinds.pop())
            # every env reports the same keys in the same order, but some key's values differ in
            # type between envs: the values of all keys of one numeric type converted in one call
            # (rows of one array, each exactly the array _add_info builds), one block of masks
            columns = list(zip(*(info.values() for _, info in entries), strict=True))
            arrays: list[Any] = [None] * len(keys)
            groups: dict[type, list[int]] = {}
            for pos, (key, values) in enumerate(zip(keys, columns, strict=True)):
                types = set(map(type, values))
                t = type(values[0])
                if (
                    len(types) == 1
                    and key != "final_obs"
                    and (t in (int, float, bool) or issubclass(t, np.number))
                ):
                    groups.setdefault(t, []).append(pos)
                elif key != "final_obs" and dict in types:
                    if types != {dict}:  # a dict in some envs only: Gymnasium's own pass, env by env
                        return self._add_infos_one_by_one(entries)
                    arrays[pos] = self._batch_infos(list(zip(idx, values, strict=True)))
                else:
                    arrays[pos] = self._info_array(key, idx, list(values))
            for t, positions in groups.items():
                block = np.array([columns[p] for p in positions], dtype=t)
                for p, row in zip(positions, block, strict=True):
                    arrays[p] = row
            masks = np.ones((len(keys), n), dtype=np.bool_)
            out: dict[str, Any] = {}
            for key, array, mask in zip(keys, arrays, masks, strict=True):
                out[key] = array
                out[f"_{key}"] = mask
            return out
        by_key: dict[str, tuple[list[int], list[Any]]] = {}
        for i, info in entries:
            for key, value in info.items():
                col = by_key.setdefault(key, ([], []))
                col[0].append(int(i))
                col[1].append(value)
        out = {}
        for key, (ids, values) in by_key.items():
            if key != "final_obs" and isinstance(values[0], dict):
                if not all(isinstance(v, dict) for v in values):
                    return self._add_infos_one_by_one(entries)
                out[key] = self._batch_infos(list(zip(ids, values, strict=True)))
            else:
                out[key] = self._info_array(key, ids, values)
            mask = np.zeros(n, dtype=np.bool_)
            mask[ids] = True
            out[f"_{key}"] = mask
        return out

    def _batch_infos_of_kind(
        self, entries: list[tuple[int, dict]], keys: tuple[str, ...], kind: tuple[type, ...]
    ) -> dict[str, Any]:
        """:meth:`_batch_infos` of the envs ``0 .. n-1`` whose infos all have the keys ``keys`` and the
        value types ``kind`` (one tuple per env compared, instead of a set of types per key): the same
        arrays.  What each key becomes depends on its key and type only, so that plan is made once per
        (keys, types) and kept."""
        plans = self._info_plans
        plan = plans.get((keys, kind))
        if plan is None:
            groups: dict[type, list[int]] = {}
            nested, other = [], []
            for pos, (key, t) in enumerate(zip(keys, kind, strict=True)):
                if key != "final_obs" and (t in (int, float, bool) or issubclass(t, np.number)):
                    groups.setdefault(t, []).append(pos)
                elif key != "final_obs" and t is dict:
                    nested.append(pos)
                else:
                    other.append(pos)
            plan = (tuple(groups.items()), tuple(nested), tuple(other), tuple(f"_{k}" for k in keys))
            if len(plans) >= 64:  # (bounded: a task's infos take a handful of kinds)
                plans.clear()
            plans[(keys, kind)] = plan
        groups_of_type, nested, other, mask_keys = plan
        n = self.num_envs
        columns = list(zip(*(info.values() for _, info in entries), strict=True))
        arrays: list[Any] = [None] * len(keys)
        for t, positions in groups_of_type:
            block = np.array([columns[p] for p in positions], dtype=t)
            for p, row in zip(positions, block, strict=True):
                arrays[p] = row
        for p in nested:
            arrays[p] = self._batch_infos(list(enumerate(columns[p])))
        for p in other:
            arrays[p] = self._info_array(keys[p], list(range(n)), list(columns[p]))
        masks = np.ones((len(keys), n), dtype=np.bool_)
        out: dict[str, Any] = {}
        for key, mask_key, array, mask in zip(keys, mask_keys, arrays, masks, strict=True):
            out[key] = array
            out[mask_key] = mask
        return out

    def _add_infos_one_by_one(self, entries: list[tuple[int, dict]]) -> dict[str, Any]:
        """Gymnasium's own pass, env by env (for a key that is a dict in some envs only)."""
        out: dict[str, Any] = {}
        for i, info in entries:
            out = self._add_info(out, info, i)
        return out

    def _info_array(self, key: str, ids: list[int], values: list[Any]) -> np.ndarray:
        """The batch array of one info key, by ``_add_info``'s rules: the first value's type sets it."""
        n = self.num_envs
        first = values[0]
        t = type(first)
        if key == "final_obs":
            array = np.full(n, fill_value=None, dtype=object)
        elif t in (int, float, bool) or issubclass(t, np.number):
            if len(ids) == n and ids == list(range(n)) and all(type(v) is t for v in values):
                # one conversion of values of one type: what assigning them one by one gives
                return np.array(values, dtype=t)
            array = np.zeros(n, dtype=t)
        elif isinstance(first, np.ndarray):
            array = np.zeros((n, *first.shape), dtype=first.dtype)
        else:
            array = np.full(n, fill_value=None, dtype=object)
        for i, v in zip(ids, values, strict=True):
            array[i] = v
        return array

    def _reset_env(self, i: int, seed: int | None = None, options: dict | None = None) -> dict:
        """Reset env ``i`` (its observation into the batch, its flags and time limit cleared); its info."""
        self._observations[i], info = self.envs[i].reset(seed=seed, options=options)
        self._terminations[i] = self._truncations[i] = self._autoreset_envs[i] = False
        self._elapsed_steps[i] = 0
        return info

    def _step_envs(self, actions: np.ndarray, stepped: np.ndarray) -> list[dict]:
        """One control step of the envs ``stepped`` (indices) with their rows of ``actions`` (float64,
        ``(num_envs, 2)``): the single env's protocol over the batch (:meth:`GFBEnv.plan_step` of each,
        the plant of all in one compiled call, :func:`~gfb_env.envs.base.advance_plans`, then
        :meth:`GFBEnv.finish_step` of each); observations, rewards, terminations and time-limit
        truncations into the batch; returns their infos.  No autoreset (the callers' autoreset
        semantics differ)."""
        rows = actions.tolist()  # each env's action as two Python floats (its own check is then cheap)
        # the workers' shards are sent their actions first, then this process steps its own shard
        # while they step theirs, then their results are collected
        parts = []
        for shard, r in zip(self._shards, self._shard_ranges[1:], strict=True):
            ids = [int(i) for i in stepped if r.start <= i < r.stop]
            if ids:
                shard.start_step([rows[i] for i in ids], [i - r.start for i in ids])
                parts.append((shard, ids))
        local = [int(i) for i in stepped if i < self._shard_ranges[0].stop]
        results = step_envs([self.envs[i] for i in local], [rows[i] for i in local], self._batch)
        by_env = dict(zip(local, results, strict=True))
        for shard, ids in parts:
            by_env.update(zip(ids, shard.collect_step(), strict=True))
        if by_env:  # every env's row of each batch array written in one assignment
            ids = list(by_env)
            obs, rewards, terminated, _ = zip(*by_env.values(), strict=True)
            self._observations[ids] = obs
            self._rewards[ids] = rewards
            self._terminations[ids] = terminated
        infos = [by_env[int(i)][3] for i in stepped]
        self._elapsed_steps[stepped] += 1
        if self.max_episode_steps is not None:
            self._truncations[stepped] = self._elapsed_steps[stepped] >= self.max_episode_steps
        else:
            self._truncations[stepped] = False
        return infos

    @property
    def num_threads(self) -> int:
        """Threads of the compiled plant stage (settable; 1 to ``numba.config.NUMBA_NUM_THREADS``)."""
        return self._batch.num_threads

    @num_threads.setter
    def num_threads(self, value: int | None) -> None:
        self._batch.num_threads = value

    # ------------------------------------------------------------------------------------------
    def get_state(self) -> dict:
        """Exact snapshot of the whole batch (every env's :meth:`GFBEnv.get_state`, the time limit
        counters, the step's flags and the autoreset flags)."""
        if self._needs_reset:
            raise RuntimeError("call reset() first")
        return {
            "envs": [env.get_state() for env in self.envs],
            "elapsed_steps": self._elapsed_steps.copy(),
            "observations": self._observations.copy(),
            "rewards": self._rewards.copy(),
            "terminations": self._terminations.copy(),
            "truncations": self._truncations.copy(),
            "autoreset_envs": self._autoreset_envs.copy(),
        }

    def set_state(self, snapshot: dict) -> None:
        """Restore a :meth:`get_state` snapshot; the continuation is bit-for-bit identical."""
        if len(snapshot["envs"]) != self.num_envs:
            raise ValueError(f"snapshot has {len(snapshot['envs'])} envs, this vector env {self.num_envs}")
        for env, s in zip(self.envs, snapshot["envs"], strict=True):
            env.set_state(s)
        self._elapsed_steps = snapshot["elapsed_steps"].copy()
        self._observations = snapshot["observations"].copy()
        self._rewards = snapshot["rewards"].copy()
        self._terminations = snapshot["terminations"].copy()
        self._truncations = snapshot["truncations"].copy()
        self._autoreset_envs = snapshot["autoreset_envs"].copy()
        self._needs_reset = False

    # ------------------------------------------------------------------------------------------
    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """Each env's ``np_random_seed``."""
        return tuple(env.np_random_seed for env in self.envs)

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each env's generator."""
        return tuple(env.np_random for env in self.envs)

    def render(self) -> tuple[Any, ...]:
        return tuple(env.render() for env in self.envs)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call method ``name`` of every env (or read the attribute when not callable)."""
        out = []
        for env in self.envs:
            f = getattr(env, name)
            out.append(f(*args, **kwargs) if callable(f) else f)
        return tuple(out)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: Any) -> None:
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr: {len(values)} values for {self.num_envs} envs")
        for env, v in zip(self.envs, values, strict=True):
            setattr(env, name, v)

    @property
    def num_processes(self) -> int:
        """Processes the envs run in (this one and its workers; :mod:`gfb_env.envs.shards`)."""
        return len(self._shard_ranges)

    def close_extras(self, **kwargs: Any) -> None:
        self._batch.close()
        for env in self.envs[: len(self._shard_ranges[0])]:
            env.close()
        for shard in self._shards:
            shard.close()


class RunUpVectorEnv(GFBVectorEnv):
    """``gfb_env/RunUp-v*`` as a :class:`GFBVectorEnv`."""

    env_class = RunUpEnv


class RunUpRandomizedVectorEnv(GFBVectorEnv):
    """``gfb_env/RunUpRandomized-v*`` as a :class:`GFBVectorEnv`."""

    env_class = RunUpRandomizedEnv


class WhirlRecoveryVectorEnv(GFBVectorEnv):
    """``gfb_env/WhirlRecovery-v*`` as a :class:`GFBVectorEnv`."""

    env_class = WhirlRecoveryEnv
