"""Worker processes of the native vector env (``GFBVectorEnv(..., num_processes=P)``, issue 20 item 3).

The env step's Python (judge, sensors, monitor, observation, info) holds the interpreter's lock, so the
threads of one process cannot run it on two cores at once: the compiled plant is parallel, the rest of
the step is not (measured: one process with 2 threads 1.0x of one thread on RunUp-v2, two independent
processes 1.99x).  So the vector env splits its envs into ``P`` contiguous shards: shard 0 in the
calling process, each other shard in a worker process of its own that holds its envs (plain task envs
built from the same class and keyword arguments) and steps them with the same protocol
(:func:`step_envs`: each env's :meth:`~gfb_env.envs.base.GFBEnv.plan_step`, the plant of all in one
compiled call, each :meth:`~gfb_env.envs.base.GFBEnv.finish_step`).  The vector env sends a shard its
actions, steps its own shard, then collects: the shards run at the same time.  An env's results depend
only on its own state and generator, so they are bit for bit those of one process (tested).

The calling process sees a worker's envs through :class:`RemoteEnv` proxies: reading an attribute
returns a copy (pickled), calling a method runs it in the worker and returns a copy of its result,
setting an attribute sets it there.  A worker is a fresh interpreter (``python -c``, not a fork: numba's
thread pools are not safe to fork; not ``multiprocessing``'s spawn either, which re-runs the caller's
``__main__`` and so needs its ``if __name__ == "__main__"`` guard) that imports the same package (the
caller's ``sys.path`` first on its ``PYTHONPATH``) and talks to the vector env over a socket pair; it ends
when the vector env is closed or its process exits.  The env class must be importable by name (a class
defined in ``__main__`` is not).
"""

from __future__ import annotations

import os
import pickle
import socket
import subprocess
import sys
import traceback
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from gfb_env.envs.base import GFBEnv, PlantResult
from gfb_env.integrator import BatchAdvance

__all__ = ["RemoteEnv", "Shard", "step_envs"]

#: the message tags of the protocol (calling process -> worker)
_STEP, _GETATTR, _CALL, _SETATTR, _CLOSE = "step", "getattr", "call", "setattr", "close"
#: a worker's answer that an attribute is a method (the proxy then calls it there)
_CALLABLE = "<callable>"


def step_envs(
    envs: list[GFBEnv], rows: list[list[float]], batch: BatchAdvance
) -> list[tuple[np.ndarray, float, bool, dict]]:
    """One control step of ``envs`` with their actions ``rows`` (two floats each): each env's
    :meth:`~gfb_env.envs.base.GFBEnv.plan_step`, the plant of every prepared plan in one compiled
    ``batch`` call, each env's :meth:`~gfb_env.envs.base.GFBEnv.finish_step` as soon as its plant is
    done (in no fixed order with 2+ threads: an env's finish uses its own state and generator only,
    while the others are still integrating).  Returns (observation, reward, terminated, info) per env,
    in the order of ``envs``."""
    plans = [env.plan_step(row) for env, row in zip(envs, rows, strict=True)]
    out: list[Any] = [None] * len(plans)

    def finish(p: int, result: PlantResult) -> None:
        obs, reward, terminated, _, info = envs[p].finish_step(plans[p], result)
        out[p] = (obs, reward, terminated, info)

    ready = [p for p, plan in enumerate(plans) if plan.call is not None]
    for p, plan in enumerate(plans):
        if plan.call is None:  # its preparation failed: the failure is its result
            finish(p, plan.failure)
    batch.run_prepared_each(
        [plans[p].integrator for p in ready],
        [plans[p].call for p in ready],
        lambda k, result: finish(ready[k], result),
    )
    return out


def _worker_main(fd: int) -> None:
    """A worker process's entry (``python -c``): its end of the socket pair is ``fd``."""
    conn = Connection(fd)
    try:
        _serve(conn, *conn.recv())
    except EOFError:  # the calling process is gone
        pass


def _serve(conn: Connection, env_class: type[GFBEnv], count: int, render_mode: str | None, kwargs: dict):
    """The worker's loop: build ``count`` envs, then answer the calling process until it says close."""
    try:
        envs = [env_class(render_mode=render_mode, **kwargs) for _ in range(count)]
        batch = BatchAdvance(1)
        conn.send(("ok", None))
    except BaseException as e:  # noqa: BLE001 - handed to the calling process, which raises it
        conn.send(("error", _portable(e)))
        return
    while True:
        try:
            msg = conn.recv()
        except EOFError:  # the calling process is gone
            break
        tag = msg[0]
        try:
            if tag == _STEP:
                _, rows, local = msg
                answer = step_envs([envs[i] for i in local], rows, batch)
            elif tag == _GETATTR:
                value = getattr(envs[msg[1]], msg[2])
                answer = _CALLABLE if callable(value) else value
            elif tag == _CALL:
                _, i, name, args, kw = msg
                answer = getattr(envs[i], name)(*args, **kw)
            elif tag == _SETATTR:
                setattr(envs[msg[1]], msg[2], msg[3])
                answer = None
            elif tag == _CLOSE:
                for env in envs:
                    env.close()
                batch.close()
                conn.send(("ok", None))
                break
            else:
                raise RuntimeError(f"unknown message {tag!r}")
            conn.send(("ok", answer))
        except BaseException as e:  # noqa: BLE001 - handed to the calling process, which raises it
            conn.send(("error", _portable(e)))
    conn.close()


def _portable(e: BaseException) -> BaseException:
    """``e`` if it pickles (the calling process raises the same type), else a RuntimeError with its
    text and traceback."""
    try:
        pickle.loads(pickle.dumps(e))
        return e
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(e).__name__}: {e}\n{traceback.format_exc()}")


class Shard:
    """A worker process holding ``count`` envs of ``env_class`` (the module docstring)."""

    def __init__(self, env_class: type[GFBEnv], count: int, render_mode: str | None, kwargs: dict):
        mine, theirs = socket.socketpair()
        # the caller's import path first, so that the worker imports the same package (and env class)
        path = [os.getcwd() if p == "" else p for p in sys.path if isinstance(p, str)]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([*path, os.environ.get("PYTHONPATH", "")]))
        code = "import sys; from gfb_env.envs.shards import _worker_main; _worker_main(int(sys.argv[1]))"
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", code, str(theirs.fileno())], pass_fds=(theirs.fileno(),), env=env
            )
        finally:
            theirs.close()
        self._conn = Connection(mine.detach())
        self._pending = False
        try:
            self._conn.send((env_class, count, render_mode, kwargs))
            self._receive()  # the envs are built (or their error is raised here)
        except BaseException:
            self._kill()
            raise

    def _receive(self) -> Any:
        try:
            tag, value = self._conn.recv()
        except EOFError:
            raise RuntimeError(
                f"the vector env's worker process {self.process.pid} ended (exit code {self.process.poll()})"
            ) from None
        if tag == "error":
            raise value
        return value

    def request(self, *msg: Any) -> Any:
        """Send ``msg`` and wait for the answer (raises the worker's exception)."""
        if self._pending:
            raise RuntimeError("a step of this shard is still running: collect it first")
        self._conn.send(msg)
        return self._receive()

    def start_step(self, rows: list[list[float]], local: list[int]) -> None:
        """Send a step of the envs ``local`` (indices in the shard); :meth:`collect_step` waits."""
        self._conn.send((_STEP, rows, local))
        self._pending = True

    def collect_step(self) -> list[tuple[np.ndarray, float, bool, dict]]:
        self._pending = False
        return self._receive()

    def close(self) -> None:
        """End the worker (its envs closed), or kill it if it does not answer."""
        if self._conn.closed:
            return
        if self.process.poll() is None:
            try:
                if self._pending:
                    self.collect_step()
                self.request(_CLOSE)
            except Exception:  # noqa: BLE001 - closing: a worker that failed is killed below
                pass
        self._kill()

    def _kill(self) -> None:
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._conn.close()


class RemoteEnv:
    """The calling process's view of env ``index`` of a :class:`Shard`: attributes are read (a copy),
    set and called in the worker."""

    def __init__(self, shard: Shard, index: int, env_class: type[GFBEnv]):
        object.__setattr__(self, "_shard", shard)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_env_class", env_class)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        value = self._shard.request(_GETATTR, self._index, name)
        if isinstance(value, str) and value == _CALLABLE:
            shard, index = self._shard, self._index

            def method(*args: Any, **kwargs: Any) -> Any:
                return shard.request(_CALL, index, name, args, kwargs)

            method.__name__ = name
            return method
        return value

    def __setattr__(self, name: str, value: Any) -> None:
        self._shard.request(_SETATTR, self._index, name, value)

    def __repr__(self) -> str:
        return f"<RemoteEnv {self._env_class.__name__} #{self._index} in process {self._shard.process.pid}>"
