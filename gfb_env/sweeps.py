"""Resumable parameter sweeps with joblib, locally or on a Dask cluster.

:func:`run_sweep` maps a picklable function over a list of parameter points (dicts of JSON scalars)
with :class:`joblib.Parallel`.  With ``scheduler`` (a Dask scheduler address such as
``tcp://10.0.0.5:8786``, or a :class:`dask.distributed.Client` / ``LocalCluster``) the very same call
runs on the cluster through joblib's ``"dask"`` backend (``joblib.parallel_backend("dask")``, which
submits the tasks to the client that is current).

Every finished point is appended at once (one JSON object per line, flushed) to the ``checkpoint`` file
(JSONL); a sweep restarted with the same checkpoint skips the points already there, so an interrupted
sweep resumes.  A point whose function raises is recorded with an ``"error"`` field instead of results
(and is not retried unless ``retry_errors``), so one bad point never loses the sweep.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import traceback
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

__all__ = ["point_key", "load_checkpoint", "run_sweep"]


def point_key(point: dict) -> str:
    """Canonical key of a parameter point (sorted JSON; floats rounded to 12 significant digits)."""

    def norm(v):
        if isinstance(v, float):
            return float(f"{v:.12g}")
        return v

    return json.dumps({k: norm(v) for k, v in sorted(point.items())}, sort_keys=True)


def _jsonable(v: Any) -> Any:
    try:
        import numpy as np

        if isinstance(v, np.generic):
            v = v.item()
        elif isinstance(v, np.ndarray):
            v = v.tolist()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


def load_checkpoint(path: str | os.PathLike) -> list[dict]:
    """Records of a JSONL checkpoint (a truncated last line from an interrupted write is ignored)."""
    p = Path(path)
    if not p.exists():
        return []
    out = []
    with p.open() as fh:
        for line in fh:
            line = line.strip()
            if not line:
                continue
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return out


def _call(func: Callable[..., dict], point: dict) -> dict:
    try:
        res = func(**point)
        if not isinstance(res, dict):
            raise TypeError(f"sweep function must return a dict, got {type(res).__name__}")
        return {"point": point, "result": _jsonable(res), "error": None}
    except Exception as exc:  # noqa: BLE001 - recorded, the sweep goes on
        msg = f"{type(exc).__name__}: {exc}"
        return {"point": point, "result": None, "error": msg, "traceback": traceback.format_exc(limit=3)}


@contextlib.contextmanager
def _backend(scheduler: Any):
    if scheduler is None:
        yield None
        return
    from dask.distributed import Client
    from joblib import parallel_backend

    own = False
    if isinstance(scheduler, str):
        client = Client(scheduler)
        own = True
    elif isinstance(scheduler, Client):
        client = scheduler
    else:  # a cluster object (e.g. LocalCluster)
        client = Client(scheduler)
        own = True
    try:
        with client.as_current(), parallel_backend("dask"):
            yield client
    finally:
        if own:
            client.close()


def run_sweep(
    func: Callable[..., dict],
    points: Iterable[dict],
    checkpoint: str | os.PathLike | None = None,
    n_jobs: int = 1,
    scheduler: Any = None,
    progress: bool = True,
    desc: str = "sweep",
    retry_errors: bool = False,
) -> list[dict]:
    """Evaluate ``func(**point)`` for every point, in parallel, resuming from ``checkpoint``.

    Args:
        func: a picklable (module-level) function returning a dict of JSON-able results.
        points: parameter points, each a dict of keyword arguments.
        checkpoint: JSONL file; finished points are appended as they complete and skipped on restart.
        n_jobs: joblib workers on this machine (ignored by the Dask backend, which uses the cluster).
        scheduler: None (local joblib/loky), a Dask scheduler address, a ``Client`` or a cluster.
        progress: show a tqdm progress bar.
        desc: progress-bar label.
        retry_errors: re-run points recorded with an error.

    Returns:
        One record per point, in the order of ``points``:
        ``{"point": ..., "result": dict | None, "error": str | None}``.
    """
    from joblib import Parallel, delayed
    from tqdm import tqdm

    pts = [dict(p) for p in points]
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0:
        raise ValueError(f"n_jobs must be a non-zero integer, got {n_jobs!r}")
    done: dict[str, dict] = {}
    if checkpoint is not None:
        for rec in load_checkpoint(checkpoint):
            if "point" in rec and (rec.get("error") is None or not retry_errors):
                done[point_key(rec["point"])] = rec
        Path(checkpoint).parent.mkdir(parents=True, exist_ok=True)
    todo = []
    seen = set()
    for p in pts:
        k = point_key(p)
        if k not in done and k not in seen:
            todo.append(p)
            seen.add(k)
    if checkpoint is not None and Path(checkpoint).exists() and Path(checkpoint).stat().st_size:
        with open(checkpoint, "rb+") as raw:  # terminate a line truncated by an interruption
            raw.seek(-1, os.SEEK_END)
            if raw.read(1) != b"\n":
                raw.write(b"\n")
    fh = open(checkpoint, "a") if checkpoint is not None else None  # noqa: SIM115
    try:
        bar = tqdm(total=len(todo), desc=desc, disable=not progress or not todo)
        if todo:
            with _backend(scheduler):
                kw = {"n_jobs": n_jobs} if scheduler is None else {}
                par = Parallel(return_as="generator_unordered", **kw)
                for rec in par(delayed(_call)(func, p) for p in todo):
                    done[point_key(rec["point"])] = rec
                    if fh is not None:
                        fh.write(json.dumps(rec) + "\n")
                        fh.flush()
                    bar.update(1)
        bar.close()
    finally:
        if fh is not None:
            fh.close()
    return [done[point_key(p)] for p in pts]


#: seconds to wait for a Dask scheduler's TCP port before refusing it (Dask's own client waits 30 s)
SCHEDULER_CONNECT_TIMEOUT_S = 5.0


def check_scheduler(address: str, timeout: float = SCHEDULER_CONNECT_TIMEOUT_S) -> None:
    """ValueError (one line) unless something accepts a TCP connection at the Dask scheduler
    ``address`` (``tcp://host:port``, ``tls://host:port`` or ``host:port``) within ``timeout`` s.

    Dask's client would retry for 30 s (``distributed.comm.timeouts.connect``) and then raise with a
    traceback; other schemes (``inproc://``, ``ucx://``, ``ws://``) are left to Dask."""
    import socket
    from urllib.parse import urlsplit

    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme not in ("tcp", "tls"):
        return
    try:
        u = urlsplit("//" + rest)
        host, port = u.hostname, u.port
    except ValueError as exc:
        raise ValueError(f"--scheduler {address!r}: {exc}") from None
    if not host or port is None:
        raise ValueError(f"--scheduler {address!r}: expected tcp://host:port")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        why = exc.strerror or str(exc) or type(exc).__name__
        raise ValueError(
            f"--scheduler {address}: no Dask scheduler answers there within {timeout:g} s ({why})"
        ) from None
