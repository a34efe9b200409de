"""Large batches of a compiled model kernel split over threads (:func:`run`).

Each robot is integrated alone, so a batch's results do not depend on how it is split: every
thread takes contiguous ranges of robots (whole blocks of the kernel's lanes).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hybridnav.models.kernel import Kernel

log = logging.getLogger(__name__)

__all__ = ["THREADS_ENV", "THREAD_MIN_NS", "run", "threads"]

#: ``HYBRIDNAV_THREADS``: threads one large batch runs on. Default: the CPUs this process may
#: use, but 1 in a worker process of a pool (the tuner's, ``compare``'s, Dask's), whose siblings
#: already keep the CPUs busy
THREADS_ENV = "HYBRIDNAV_THREADS"
#: work a thread gets at least, in ns (estimated from :attr:`Kernel.cost_ns`): ~50 us to hand it
#: over and join it
THREAD_MIN_NS = 5e6
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


def run(k: Kernel, X: np.ndarray, T: np.ndarray, out: np.ndarray, steps: int, rs: int, ks: int,
        offset: int = 0, nthreads: int | None = None) -> None:
    """:meth:`Kernel.run`, split over threads for large batches (``nthreads``, default
    :func:`threads`; a thread gets at least :data:`THREAD_MIN_NS` of estimated work): each
    thread takes a contiguous range of robots (whole blocks of lanes), so the results are the
    same whatever the number of threads."""
    n = len(X)
    most = int(n * steps * k.cost_ns // THREAD_MIN_NS)
    if most < 2 or nthreads == 1:
        k.run(X, T, out, steps, rs, ks, offset)
        return
    parts = min(threads() if nthreads is None else max(1, nthreads), most, -(-n // k.lanes))
    if parts <= 1:
        k.run(X, T, out, steps, rs, ks, offset)
        return
    per = -(-n // (parts * k.lanes)) * k.lanes
    bounds = [(lo, min(n, lo + per)) for lo in range(0, n, per)]
    pool = _pool(len(bounds) - 1)
    futures = [pool.submit(k.run, X[lo:hi], T[lo:hi], out, steps, rs, ks, offset + lo * rs)
               for lo, hi in bounds[1:]]
    lo, hi = bounds[0]
    try:
        k.run(X[lo:hi], T[lo:hi], out, steps, rs, ks, offset)
    finally:
        for f in futures:
            f.result()
