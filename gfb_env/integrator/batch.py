"""Many :class:`~gfb_env.integrator.TrapezoidalIntegrator` calls in one compiled call:
:class:`BatchAdvance`, its stacked workspace and the batch kernels (a parallel ``prange`` over worker
slots that claim envs from an atomic work index, a serial ``range``: numba's parallel launch costs
~50 us per call, so one thread or one env takes the serial one; and a GIL-free claiming kernel that
Python threads call at once, for :meth:`BatchAdvance.run_prepared_each`).  They take the argument
groups of :mod:`gfb_env.integrator.arguments`."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import wait as futures_wait
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import njit, prange, types
from numba.extending import intrinsic

from gfb_env import _kernels as K
from gfb_env.integrator.arguments import (
    CALL_DTYPE,
    CLOCK_FIELDS,
    BatchArrays,
    Factorization,
    Forcing,
    Jacobian,
    Recording,
    call_row,
    store_clock,
    unpack_row,
)
from gfb_env.integrator.results import _EXTREMES_START, AdvanceResult, IntegrationError, IntegrationStatus
from gfb_env.integrator.stages import _advance
from gfb_env.integrator.stepper import (
    DEFAULT_MAX_STEPS,
    PreparedCall,
    TrapezoidalIntegrator,
    _call_compiled,
    _shape_key,
)
from gfb_env.model import GFBModel

__all__ = ["BatchAdvance"]


# ------------------------------------------------------------------------------------------------
@njit(cache=True)
def _advance_env(i, b, n_rows, sparse, size_tag):
    """:func:`~gfb_env.integrator.stages._advance` of env i of a batch: it gets exactly the argument
    groups (types included) that :meth:`TrapezoidalIntegrator.advance` passes, built from row i of the
    stacked arrays ``b`` (:class:`~gfb_env.integrator.arguments.BatchArrays`, its scalars by name from
    ``b.calls[i]``: :func:`~gfb_env.integrator.arguments.unpack_row`), so it runs the same compiled
    loop and its result is bit for bit the single call's.  The clock at the end and the status code go
    back into ``b.calls[i]``.  Each env's Jacobian and factorisation workspace carries nothing from
    call to call (every call evaluates J first).  A failure is a status of its env only."""
    c = b.calls[i]
    clock, schedule, opt, rec_t, rows = unpack_row(c)
    Y = b.y
    y = (Y[i, 0], Y[i, 1], Y[i, 2], Y[i, 3], Y[i, 4])
    kargs = (b.ip[i], b.fp[i], b.sn[i], b.cs[i])
    jac = Jacobian(b.Ad[i], b.Ap[i], b.Am[i], b.Er[i], b.Rr[i], b.Srr[i])
    lu = Factorization(b.Dlu[i], b.Dpiv[i], b.Uhat[i], b.Yw[i], b.Slu[i], b.Spiv[i], n_rows, sparse, size_tag)
    rec = Recording(b.record_indices, rec_t[0], rec_t[1], b.record_buffers[i, rows[0] : rows[1]])
    if c.forced:
        forcing = Forcing(c.unbalance, c.forcing_angle, b.shocks[i, : c.n_shocks], c.forcing_max_step)
        code, clock = _advance(y, clock, schedule, kargs, jac, lu, opt, rec, b.stats[i], b.ext[i], forcing)
    else:
        code, clock = _advance(y, clock, schedule, kargs, jac, lu, opt, rec, b.stats[i], b.ext[i], None)
    c.status = code
    store_clock(c, clock)


@intrinsic
def _claim(typingctx, counter):
    """``counter[0]`` before adding 1 to it, atomically (LLVM's ``atomicrmw add``, sequentially
    consistent): the work index the threads of :func:`_advance_batch` take their envs from."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0]).data
        return builder.atomic_rmw("add", data, ir.Constant(ir.IntType(64), 1), "seq_cst")

    return types.int64(counter), codegen


@njit(parallel=True, cache=True)
def _advance_batch(b, lu_static, order, counter, n_workers):
    """:func:`_advance_env` of envs ``order[0], order[1], ...`` claimed one at a time by ``n_workers``
    workers (a ``prange`` over the workers; each takes the next env of the shared work index
    ``counter[0]`` (0 on entry) when it is done with its last one).  Why not a ``prange`` over the envs:
    numba's ``workqueue`` layer hands each thread a fixed, contiguous share of the iterations whatever
    the chunk size, so the call waits for the thread whose envs cost most or that the OS preempted (on
    a shared machine the second thread got 0.57 of a core); with the claim the envs flow to whichever
    thread runs.  Each env is still one :func:`_advance_env` of its own rows, so the results do not
    depend on the order, the worker or the thread count.  A parallel loop takes arrays, not tuples:
    ``b`` is unpacked by name before it and repacked by keyword inside (numba refuses a name that
    BatchArrays lacks or misses), ``lu_static`` likewise."""
    n_rows, sparse, size_tag = lu_static
    calls, y, ip, fp, sn, cs = b.calls, b.y, b.ip, b.fp, b.sn, b.cs
    Ad, Ap, Am, Er, Rr, Srr = b.Ad, b.Ap, b.Am, b.Er, b.Rr, b.Srr
    Dlu, Dpiv, Uhat, Yw, Slu, Spiv = b.Dlu, b.Dpiv, b.Uhat, b.Yw, b.Slu, b.Spiv
    record_indices, record_buffers, stats, ext, shocks = (
        b.record_indices,
        b.record_buffers,
        b.stats,
        b.ext,
        b.shocks,
    )
    n = order.shape[0]
    for _w in prange(n_workers):
        env = BatchArrays(
            calls=calls, y=y, ip=ip, fp=fp, sn=sn, cs=cs, Ad=Ad, Ap=Ap, Am=Am, Er=Er, Rr=Rr, Srr=Srr,
            Dlu=Dlu, Dpiv=Dpiv, Uhat=Uhat, Yw=Yw, Slu=Slu, Spiv=Spiv, record_indices=record_indices,
            record_buffers=record_buffers, stats=stats, ext=ext, shocks=shocks,
        )  # fmt: skip
        j = _claim(counter)
        while j < n:
            _advance_env(order[j], env, n_rows, sparse, size_tag)
            j = _claim(counter)


@njit(nogil=True, cache=True)
def _advance_claimed(b, lu_static, order, counter, done, limit):
    """:func:`_advance_env` of the envs ``order[j]`` this thread claims from the shared work index
    ``counter[0]``, at most ``limit`` of them, without the GIL (the threads of
    :meth:`BatchAdvance.run_prepared_each` call it at once); after each env ``done[env]`` becomes 1
    (an atomic add, after the env's rows are written: the caller may then read them)."""
    n_rows, sparse, size_tag = lu_static
    n = order.shape[0]
    for _ in range(limit):
        j = _claim(counter)
        if j >= n:
            return
        k = order[j]
        _advance_env(k, b, n_rows, sparse, size_tag)
        _claim(done[k : k + 1])


@njit(cache=True)
def _advance_batch_serial(b, lu_static):
    """:func:`_advance_env` of env i = 0..N-1 one after the other, in the calling thread: for one
    thread or one env (numba's parallel launch costs ~50 us of CPU per call even then, measured)."""
    n_rows, sparse, size_tag = lu_static
    for i in range(b.calls.shape[0]):
        _advance_env(i, b, n_rows, sparse, size_tag)


#: an env's cost in a call from its counts (``stats``: steps, rejections, Jacobians, factorisations,
#: rhs calls, ...): the kernels' CPU us on the 31x7 grid (Jacobian 7.8, factorisation 15, rhs 0.88
#: plus a block solve 2.35 per Newton iteration); only the order of the parallel call's claims uses it
_COST_OF_COUNT = np.array([0.0, 0.0, 0.0, 7.8, 15.0, 3.2, 0.0, 0.0, 0.0])


def _choose_threading_layer() -> None:
    """numba's ``workqueue`` threading layer for the batch unless the user chose one
    (``NUMBA_THREADING_LAYER``) or numba already started one.  Measured on the shared 2-core machine
    (load ~4): with 2 threads GNU OpenMP's ``omp`` layer made a batch call 5x slower than 1 thread
    (its workers spin while the cores are busy), ``workqueue`` was as fast as 1 thread; ``workqueue``
    is also fork-safe (GNU OpenMP is not: a forked worker that launched threads would hang).  It is
    not thread-safe: do not step two batches from two Python threads at once."""
    if os.environ.get("NUMBA_THREADING_LAYER") is None and numba.config.THREADING_LAYER == "default":
        from numba.np.ufunc import parallel

        if not getattr(parallel, "_is_initialized", True):  # (numba internals: when unknown, leave it)
            numba.config.THREADING_LAYER = "workqueue"


class _BatchWorkspace:
    """The stacked arrays of :func:`_advance_batch` for up to ``capacity`` envs of one model shape
    (:class:`~gfb_env.integrator.arguments.BatchArrays`, sliced to the batch by :meth:`arrays`)."""

    def __init__(self, capacity: int, model: GFBModel, n_recorded: int):
        N, n = capacity, model.layout.size
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        z = np.zeros
        self.shape_key = _shape_key(model)
        self.capacity, self.n_recorded = capacity, n_recorded
        self.kargs_of_slot: list[tuple | None] = [None] * N  # whose kernel args each row holds
        self.cost = np.zeros(N)  # each row's cost in its last call (:data:`_COST_OF_COUNT`)
        self.lu_static = (model.grid.n_rows, model.sparse_offdiagonal_blocks, K.size_tag(m))
        self.stacked = BatchArrays(
            calls=z(N, CALL_DTYPE),
            y=z((N, 5, n)),
            ip=z((N, 3), np.int64), fp=z((N, K.N_FLOAT_PARAMETERS)), sn=z((N, nc)), cs=z((N, nc)),
            Ad=z((N, nc, m, m)), Ap=z((N, nc, m, m)), Am=z((N, nc, m, m)), Er=z((N, nc, m, 4)),
            Rr=z((N, nc, 4, m)), Srr=z((N, 4, 4)),
            Dlu=z((N, nc, m, m)), Dpiv=z((N, nc, m), np.int64), Uhat=z((N, nc, m, m)),
            Yw=z((N, nc, m, nb)), Slu=z((N, nb, nb)), Spiv=z((N, nb), np.int64),
            record_indices=np.zeros(0, np.int64),
            record_buffers=np.empty((N, 0, n_recorded + 2)),
            stats=z((N, 9), np.int64), ext=z((N, 9)),
            shocks=z((N, 0, 4)),
        )  # fmt: skip

    def fits(self, n_envs: int, model: GFBModel, n_recorded: int) -> bool:
        return (
            n_envs <= self.capacity and _shape_key(model) == self.shape_key and n_recorded == self.n_recorded
        )

    def reserve(self, rows: int, shocks: int) -> None:
        """At least ``rows`` sample rows and ``shocks`` shock rows per env."""
        N, b = self.capacity, self.stacked
        if b.record_buffers.shape[1] < rows:
            self.stacked = b = b._replace(record_buffers=np.empty((N, rows, b.record_buffers.shape[2])))
        if b.shocks.shape[1] < shocks:
            self.stacked = b._replace(shocks=np.zeros((N, shocks, 4)))

    def arrays(self, n: int, record_indices: np.ndarray) -> BatchArrays:
        """The first ``n`` envs' rows of every stacked array, and the batch's recorded entries."""
        return BatchArrays(*(a[:n] for a in self.stacked))._replace(record_indices=record_indices)


class BatchAdvance:
    """Advance many :class:`TrapezoidalIntegrator` objects with one compiled, parallel call.

    :meth:`advance` runs, for each integrator, exactly what its :meth:`TrapezoidalIntegrator.advance`
    runs: the same Python preparation and finish, and the same compiled loop (:func:`_advance`, called
    by :func:`_advance_batch` in a numba ``prange`` over the integrators), so every result and state is
    bit for bit the one-by-one result, for any thread count.  Integrators may have different models of
    one grid (e.g. randomised bearings), be forced (unbalance, shocks) or not; a failure (status
    ``"failed"``/``"max_steps"``) is that integrator's only.  Integrators of different grids, or calls
    with different recorded entries, are advanced one after the other (same results).

    Args:
        num_threads: numba threads of the call (``numba.set_num_threads``; at most
            ``numba.config.NUMBA_NUM_THREADS``, the cores numba sees, which is the default).  The
            environment variable ``NUMBA_NUM_THREADS`` caps it for the process.
    """

    def __init__(self, num_threads: int | None = None):
        self.num_threads = num_threads
        self._ws: _BatchWorkspace | None = None
        self._workers: tuple[int, int, ThreadPoolExecutor] | None = None  # (pid, workers, pool)

    @property
    def num_threads(self) -> int:
        return self._num_threads

    @num_threads.setter
    def num_threads(self, value: int | None) -> None:
        limit = numba.config.NUMBA_NUM_THREADS
        if value is None:
            value = limit
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= limit:
            raise ValueError(
                f"num_threads must be an integer in [1, {limit}] (NUMBA_NUM_THREADS), got {value!r}"
            )
        self._num_threads = int(value)

    def advance(
        self,
        integrators: list[TrapezoidalIntegrator],
        tau_end: list[float],
        bearing_number: list[float | None],
        foil_damping: list[float | None],
        record_interval: float | None = None,
        record_indices: np.ndarray | None = None,
        max_steps: int = DEFAULT_MAX_STEPS,
        raise_on_failure: bool = True,
    ) -> list[AdvanceResult]:
        """:meth:`TrapezoidalIntegrator.advance` of every integrator (``tau_end``, ``bearing_number``,
        ``foil_damping``: one per integrator; the recording and ``max_steps`` are shared).  Bad
        arguments raise as one call after the other would (the integrators before the bad one are
        advanced).  With ``raise_on_failure`` an :class:`IntegrationError` is raised after all are
        advanced, for the first one that failed."""
        integs = list(integrators)
        n = len(integs)
        if len({id(x) for x in integs}) != n:
            raise ValueError("integrators: each integrator may appear only once")
        for name, v in (
            ("tau_end", tau_end),
            ("bearing_number", bearing_number),
            ("foil_damping", foil_damping),
        ):
            if len(v) != n:
                raise ValueError(f"{name}: {len(v)} values for {n} integrators")
        calls: list[PreparedCall] = []
        try:
            for k, integ in enumerate(integs):
                calls.append(
                    integ.prepare(
                        tau_end[k],
                        bearing_number[k],
                        foil_damping[k],
                        record_interval,
                        record_indices,
                        max_steps,
                    )
                )
        except Exception:
            self.run_prepared(integs[: len(calls)], calls)  # those before the bad one, as one by one
            raise
        results = self.run_prepared(integs, calls)
        if raise_on_failure:
            for r in results:
                if r.status in (IntegrationStatus.FAILED, IntegrationStatus.MAX_STEPS):
                    raise IntegrationError(r.message)
        return results

    def run_prepared(
        self, integs: list[TrapezoidalIntegrator], calls: list[PreparedCall]
    ) -> list[AdvanceResult]:
        """The compiled part and the finish of calls prepared by ``integs[k].prepare(...)`` (each
        integrator once; used by the vector env, which prepares each env's call itself)."""
        n = len(calls)
        _choose_threading_layer()
        if n == 0:
            return []
        staged = self._stage(integs, calls)
        if staged is None:
            return [self._one(it, c) for it, c in zip(integs, calls, strict=True)]
        b, ws, key = staged
        threads = min(self._num_threads, n)
        if threads == 1:
            self._launch(_advance_batch_serial, key, b, ws.lu_static)
        else:
            # the costliest envs of the last call first (longest processing time first: the last
            # env claimed is then a cheap one, so the threads end together)
            order = np.argsort(-ws.cost[:n], kind="stable")
            counter = np.zeros(1, np.int64)
            old_threads = numba.get_num_threads()
            numba.set_num_threads(threads)
            try:
                self._launch(_advance_batch, key, b, ws.lu_static, order, counter, threads)
            finally:
                numba.set_num_threads(old_threads)
        ws.cost[:n] = b.stats @ _COST_OF_COUNT
        return [self._result(b, k, it, c) for k, (it, c) in enumerate(zip(integs, calls, strict=True))]

    def run_prepared_each(
        self,
        integs: list[TrapezoidalIntegrator],
        calls: list[PreparedCall],
        each: Callable[[int, AdvanceResult], None],
    ) -> None:
        """:meth:`run_prepared`, handing each result to ``each(k, result)`` in the calling thread as
        soon as call ``k`` is integrated, while the other calls still are: the caller's Python work
        on a finished env (the vector env's judge, sensors and observation) overlaps the compiled
        work on the others, so both cores work through the whole step, not only its compiled part.
        The compiled part runs in ``num_threads - 1`` worker threads (a pool kept by this object)
        and in the calling thread whenever it has no result to hand on; each thread claims the next
        env (costliest of the last call first) from an atomic work index.  With one thread or one
        call the results come in order after :meth:`run_prepared`; otherwise in the order they are
        done, each still bit for bit the one-by-one result (the calls are independent).  If
        ``each`` raises, the workers' calls are waited for, then it propagates."""
        n = len(calls)
        threads = min(self._num_threads, n)
        staged = self._stage(integs, calls) if threads > 1 else None
        if staged is None:
            for k, r in enumerate(self.run_prepared(integs, calls)):
                each(k, r)
            return
        b, ws, key = staged
        order = np.argsort(-ws.cost[:n], kind="stable")
        counter = np.zeros(1, np.int64)
        done = np.zeros(n, np.int64)
        lu_static = ws.lu_static

        def claim(limit: int) -> None:
            self._launch(_advance_claimed, key, b, lu_static, order, counter, done, limit)

        workers = [self._pool(threads - 1).submit(claim, n) for _ in range(threads - 1)]
        pending = list(range(n))
        try:
            while pending:
                ready = [k for k in pending if done[k]]
                if ready:
                    for k in ready:
                        pending.remove(k)
                        each(k, self._result(b, k, integs[k], calls[k]))
                elif counter[0] < n:
                    claim(1)  # nothing to hand on: integrate one env here
                else:  # the workers hold the last envs
                    futures_wait(workers, timeout=2e-4)
                    for w in workers:
                        if w.done() and w.exception() is not None:
                            raise w.exception()
        finally:
            futures_wait(workers)
        ws.cost[:n] = b.stats @ _COST_OF_COUNT

    def close(self) -> None:
        """Stop the worker threads (a later :meth:`run_prepared_each` starts new ones)."""
        pool, self._workers = self._workers, None
        if pool is not None and pool[0] == os.getpid():
            pool[2].shutdown(wait=False)

    def __getstate__(self) -> dict:
        # a copy or a pickle holds no threads (a thread pool can be neither): it starts its own
        return {**self.__dict__, "_workers": None}

    def _pool(self, workers: int) -> ThreadPoolExecutor:
        """The worker threads of :meth:`run_prepared_each` (a new pool after a fork or a change of
        the thread count: a forked child has no threads)."""
        pool = self._workers
        if pool is None or pool[0] != os.getpid() or pool[1] != workers:
            if pool is not None and pool[0] == os.getpid():
                pool[2].shutdown(wait=False)
            pool = self._workers = (os.getpid(), workers, ThreadPoolExecutor(workers, "gfb-batch"))
        return pool[2]

    def _stage(
        self, integs: list[TrapezoidalIntegrator], calls: list[PreparedCall]
    ) -> tuple[BatchArrays, _BatchWorkspace, tuple] | None:
        """Every call's scalars and state into the stacked workspace (the batch arrays, the
        workspace and the compiled entry's key), or None when the integrators' grids or recorded
        entries differ (then they are advanced one by one)."""
        n = len(calls)
        model0 = integs[0].model
        key = integs[0]._shape_key
        rec_key = integs[0]._record_key
        rec_idx = calls[0].recording.indices
        if any(it._shape_key != key or it._record_key != rec_key for it in integs):
            return None
        ws = self._ws
        if ws is None or not ws.fits(n, model0, len(rec_idx)):
            ws = self._ws = _BatchWorkspace(
                max(n, ws.capacity if ws is not None else 0), model0, len(rec_idx)
            )
        ws.reserve(max(c.rec_buf.shape[0] for c in calls), max(len(c.st.shocks) for c in calls))
        b = ws.arrays(n, rec_idx)
        Y = b.y
        # every scalar of every call into its row of b.calls (the one packer: arguments.call_row)
        b.calls[:] = [
            call_row(c.st.clock, c.schedule, c.options, c.recording, (c.first, c.rec_buf.shape[0]), c.forcing)
            for c in calls
        ]
        b.stats[:] = 0
        b.ext[:] = _EXTREMES_START
        for k, (it, c) in enumerate(zip(integs, calls, strict=True)):
            st, Yk = c.st, Y[k]
            Yk[0], Yk[1], Yk[2], Yk[3], Yk[4] = st.s, st.f, st.fprev, st.sprev, st.sprev2
            if ws.kargs_of_slot[k] is not it._kernel_args:
                b.ip[k], b.fp[k], b.sn[k], b.cs[k] = it._kernel_args
                ws.kargs_of_slot[k] = it._kernel_args
            if c.first:
                b.record_buffers[k, 0] = c.rec_buf[0]
            if c.forcing is not None:
                b.shocks[k, : len(c.forcing.shocks)] = c.forcing.shocks
        return b, ws, (ws.lu_static, len(rec_idx))

    @staticmethod
    def _result(b: BatchArrays, k: int, it: TrapezoidalIntegrator, c: PreparedCall) -> AdvanceResult:
        """Row ``k``'s state back into its call's arrays, and its integrator's finish."""
        st = c.st
        st.s[:], st.f[:], st.fprev[:], st.sprev[:], st.sprev2[:] = b.y[k]
        clock = b.calls[list(CLOCK_FIELDS)][k : k + 1].tolist()[0]
        code = b.calls["status"][k : k + 1].tolist()[0]
        rec_buf = b.record_buffers[k, : c.rec_buf.shape[0]]
        return it._finish(c, code, clock, b.stats[k].tolist(), b.ext[k].tolist(), rec_buf, False)

    @staticmethod
    def _launch(kernel: Any, key: tuple, *args: Any) -> None:
        """The compiled batch call (a method: ``bench_env`` times it)."""
        _call_compiled(kernel, key, *args)

    @staticmethod
    def _one(it: TrapezoidalIntegrator, c: PreparedCall) -> AdvanceResult:
        code, clock = it._run(c)
        return it._finish(c, code, clock, c.stats.tolist(), c.ext.tolist(), c.rec_buf, False)
