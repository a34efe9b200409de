"""Large batches of a compiled model kernel split over threads (:func:`run`).

Each robot is integrated alone, so a batch's results do not depend on how it is split: every
thread takes contiguous ranges of robots (whole blocks of the kernel's lanes).
"""

from __future__ import annotations

import itertools
import logging
import multiprocessing
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["PIECES", "PIECE_NS", "THREADS_ENV", "THREAD_MIN_NS", "pieces", "run", "threads"]

#: ``HYBRIDNAV_THREADS``: threads one large batch runs on. Default: the CPUs this process may
#: use, but 1 in a worker process of a pool (the tuner's, ``compare``'s, Dask's), whose siblings
#: already keep the CPUs busy
THREADS_ENV = "HYBRIDNAV_THREADS"
#: work a thread gets at least, in ns (estimated from the kernel's ``cost_ns``): handing a
#: piece to a pool thread and joining it costs ~30 us
THREAD_MIN_NS = 1e6
#: work of one range a thread claims (:func:`pieces`), in ns: small enough that a thread
#: slowed by other processes leaves the rest to the others, large enough that claiming costs
#: nothing much
PIECE_NS = 1e6
#: ranges per thread at most
PIECES = 8
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def threads() -> int:
    """Threads a large batch runs on (see :data:`THREADS_ENV`)."""
    v = os.environ.get(THREADS_ENV, "").strip()
    if v:
        try:
            return max(1, int(v))
        except ValueError:
            log.warning("%s=%r is not an integer; using 1 thread", THREADS_ENV, v)
            return 1
    if multiprocessing.parent_process() is not None:
        return 1
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _pool(workers: int) -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None or _POOL._max_workers < workers:
            if _POOL is not None:
                _POOL.shutdown(wait=False)
            _POOL = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="hybridnav-kernel")
        return _POOL


def _reset_after_fork() -> None:
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()   # the parent's threads do not exist here


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)


def pieces(n: int, steps: int, cost_ns: float, lanes: int,
           nthreads: int | None = None) -> tuple[int, list[tuple[int, int]]]:
    """How :func:`run` splits ``n`` robots: ``(threads, ranges)``. One range (and one thread)
    unless the batch's estimated work (``n * steps * cost_ns``) gives each of at least two
    threads :data:`THREAD_MIN_NS`; then contiguous ranges of whole blocks of ``lanes`` robots
    (the last one shorter), about :data:`PIECE_NS` of work each but at most :data:`PIECES` per
    thread, which the threads claim one at a time."""
    work = n * steps * cost_ns
    if work < 2 * THREAD_MIN_NS or nthreads == 1:    # small batches: no look at the CPUs
        return 1, [(0, n)]
    blocks = -(-n // lanes)
    want = threads() if nthreads is None else max(1, int(nthreads))
    workers = min(want, int(work // THREAD_MIN_NS), blocks)
    if workers <= 1:
        return 1, [(0, n)]
    count = min(blocks, workers * PIECES, max(workers, int(work // PIECE_NS)))
    per = -(-blocks // count) * lanes
    return workers, [(lo, min(n, lo + per)) for lo in range(0, n, per)]


def run(k: Any, X: np.ndarray, T: np.ndarray, out: np.ndarray, steps: int, rs: int, ks: int,
        offset: int = 0, nthreads: int | None = None) -> None:
    """``k.run`` of a :class:`hybridnav.models.kernel.Kernel`, split over threads for large
    batches (``nthreads``, default :func:`threads`; see :func:`pieces`). The calling thread and
    the pool's threads claim the ranges one at a time, so a thread that gets less of the CPUs (a
    shared machine) takes fewer of them instead of holding up the rest; every robot is
    integrated alone, so the results are the same whatever the number of threads and whoever
    runs a range."""
    if len(X) * steps * k.cost_ns < 2 * THREAD_MIN_NS:
        k.run(X, T, out, steps, rs, ks, offset)        # the common small batch, at once
        return
    workers, ranges = pieces(len(X), steps, k.cost_ns, k.lanes, nthreads)
    if workers <= 1:
        k.run(X, T, out, steps, rs, ks, offset)
        return
    claim = itertools.count()               # next() on it is atomic (it holds the GIL)

    def work() -> None:
        for i in iter(claim.__next__, None):
            if i >= len(ranges):
                return
            lo, hi = ranges[i]
            k.run(X[lo:hi], T[lo:hi], out, steps, rs, ks, offset + lo * rs)

    pool = _pool(workers - 1)
    futures = [pool.submit(work) for _ in range(workers - 1)]
    try:
        work()
    finally:
        for f in futures:               # one not started yet would find nothing left to claim
            if not f.cancel():
                f.result()
