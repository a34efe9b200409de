"""Where independent tasks run: this process, local processes, or Dask — the one parallel-execution
mechanism, used by the tuner (chunks of a generation) and by ``compare`` (runs).

Every backend returns the results in submission order, so callers see the same numbers whatever
runs them; ``on_done(i)`` (optional) is called as task ``i`` finishes, in completion order, for
progress bars. A lost worker does not lose the work: its tasks run again (the process pool is
rebuilt and the unfinished tasks resubmitted; Dask reschedules a dead worker's tasks by itself).
"""

from __future__ import annotations

import atexit
import logging
import os
import pickle
import threading
import time
import uuid
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.params import Param, short_repr

log = logging.getLogger(__name__)

__all__ = ["DASK_ADDRESS", "NO_WORKERS_TIMEOUT", "Backend", "DaskBackend", "ProcessBackend",
           "load_average",
           "SerialBackend", "Shipped", "close_shared", "cores", "make_backend", "shared_backend",
           "unship"]

#: What ``--dask`` / ``[backend] dask`` takes: empty (no Dask), ``local`` (a new LocalCluster on
#: this machine) or a scheduler address ``[protocol://]host:port``.
DASK_ADDRESS = Param("", "a Dask scheduler address or 'local'",
                     pattern=r"|local|((tcp|tls|ucx|ws|wss|inproc)://)?"
                             r"([A-Za-z0-9_.\-]+|\[[0-9A-Fa-f:.]+\]):[0-9]{1,5}",
                     expected="'local' or a scheduler address such as tcp://host:8786")

#: Seconds a Dask run waits with no worker connected before it fails (its checkpoint keeps the
#: finished generations; ``--resume`` continues). The environment variable
#: ``HYBRIDNAV_DASK_NO_WORKERS_TIMEOUT`` overrides it.
NO_WORKERS_TIMEOUT = 300.0


#: objects a worker process has received as :class:`Shipped`, by key (a few kept)
_ARRIVED: dict[str, Any] = {}


def _arrive(key: str, blob: bytes) -> Any:
    """The object of ``key`` in this process: unpickled from ``blob`` the first time only."""
    obj = _ARRIVED.get(key)
    if obj is None:
        if len(_ARRIVED) >= 16:
            _ARRIVED.pop(next(iter(_ARRIVED)))
        obj = _ARRIVED[key] = pickle.loads(blob)
    return obj


class Shipped:
    """An object sent with every task of a job but unpickled once per worker process.

    Pickled, it is its key and its bytes (serialized once, here); a worker that already holds
    the key gets the copy it unpickled the first time, with whatever that copy built for itself
    (a cost's packed worlds, a settings object's fuzzy family), instead of a fresh copy per
    task. The object must not change after it is wrapped. In this process (the serial backend)
    a task receives the wrapper itself: :func:`unship` gives the object in both cases.
    """

    def __init__(self, obj: Any) -> None:
        self.obj = obj
        self.key = uuid.uuid4().hex
        self._blob: bytes | None = None

    def __reduce__(self):
        if self._blob is None:
            self._blob = pickle.dumps(self.obj, protocol=pickle.HIGHEST_PROTOCOL)
        return (_arrive, (self.key, self._blob))


def unship(obj: Any) -> Any:
    """``obj``, or the object a :class:`Shipped` wraps."""
    return obj.obj if isinstance(obj, Shipped) else obj


def cores() -> int:
    """The cores this process may run on (its CPU affinity; at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


class Backend(ABC):
    """``map(fn, args_list) -> results`` in order; ``close()`` when done."""

    name = "serial"

    @abstractmethod
    def map(self, fn: Callable, args: Sequence[tuple],
            on_done: Callable[[int], None] | None = None) -> list[Any]:
        """Results of ``fn(*a)`` for every ``a`` in ``args``, in order; ``on_done(i)`` as task
        ``i`` finishes."""

    def close(self) -> None:
        """Release workers (nothing to do for the serial backend)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialBackend(Backend):
    """Everything in this process."""

    def map(self, fn, args, on_done=None):
        out = []
        for i, a in enumerate(args):
            out.append(fn(*a))
            if on_done is not None:
                on_done(i)
        return out


class ProcessBackend(Backend):
    """A local process pool; chunks of a dead worker run again on a fresh pool.

    The pool has at most ``workers`` processes, no more than the cores this process may use
    (:func:`cores`) and no more than the tasks of the largest ``map`` so far: a job of one chunk
    starts one process, whatever ``workers`` says.
    """

    name = "processes"

    def __init__(self, workers: int, retries: int = 3, full: bool = False) -> None:
        self.workers = workers
        self.retries = retries
        self.limit = min(workers, cores())
        if self.limit < workers:
            log.info("%d worker processes asked for, %d used: the cores of this machine",
                     workers, self.limit)
        self.full = full                   # always all ``limit`` processes (a shared pool)
        self.size = 0                      # processes of the current pool (made on demand)
        self._pool: ProcessPoolExecutor | None = None

    def _ensure(self, tasks: int) -> ProcessPoolExecutor:
        want = self.limit if self.full else max(1, min(self.limit, tasks))
        if self._pool is None or want > self.size:
            if self._pool is not None:
                self._pool.shutdown(wait=True)
            self._pool = ProcessPoolExecutor(max_workers=want)
            self.size = want
        return self._pool

    def map(self, fn, args, on_done=None):
        results: list[Any] = [None] * len(args)
        todo = list(range(len(args)))
        self._ensure(len(args))
        for attempt in range(self.retries + 1):
            futures = {self._pool.submit(fn, *args[i]): i for i in todo}
            lost = []
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    results[i] = fut.result()
                except BrokenProcessPool:
                    lost.append(i)
                    continue
                if on_done is not None:
                    on_done(i)
            lost.sort()
            if not lost:
                return results
            log.warning("a worker process died; re-running %d chunk(s) (attempt %d)",
                        len(lost), attempt + 1)
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = ProcessPoolExecutor(max_workers=self.size)
            todo = lost
        raise HybridnavError(f"backend: worker processes kept dying; {len(todo)} chunk(s) could "
                             "not be evaluated")

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            self.size = 0


class _Kept(Backend):
    """A view of a shared :class:`ProcessBackend` whose ``close`` keeps the pool running."""

    name = "processes"

    def __init__(self, backend: ProcessBackend) -> None:
        self.backend = backend
        self.workers, self.limit = backend.workers, backend.limit

    def map(self, fn, args, on_done=None):
        return self.backend.map(fn, args, on_done)


_SHARED: dict[int, ProcessBackend] = {}
_SHARED_LOCK = threading.Lock()


def close_shared() -> None:
    """Shut down the pools :func:`shared_backend` keeps (at exit; or to reap the workers, e.g.
    to count their CPU time)."""
    with _SHARED_LOCK:
        for backend in _SHARED.values():
            backend.close()
        _SHARED.clear()


atexit.register(close_shared)


def shared_backend(workers: int = 1, dask: str | Any = "") -> Backend:
    """:func:`make_backend`, except that local worker processes are kept for the life of this
    process and reused by every later call with the same ``workers``: a worker pays its start-up
    (imports, compiled model functions, fuzzy systems, packed worlds: everything cached per
    process) once, not once per call — ``reproduce`` calls ``compare`` once per protocol and
    layout. ``close()`` of the returned backend leaves the pool running (it is shut down when
    this process exits).

    Workers are forked when the pool is first used, so they keep that moment's working
    directory and module state; tasks must not depend on either (``compare`` ships loaded
    scenarios and absolute paths). Dask and a single worker are as :func:`make_backend` gives
    them.

    Parameters
    ----------
    workers : int
        Local worker processes (1: in this process).
    dask : str or distributed.Client
        A Dask scheduler address or client (then :func:`make_backend`'s Dask backend).

    Returns
    -------
    Backend
        A backend whose ``close()`` keeps the shared pool.
    """
    if dask or workers <= 1:
        return make_backend(workers, dask)
    with _SHARED_LOCK:
        backend = _SHARED.get(workers)
        if backend is None:
            backend = _SHARED[workers] = ProcessBackend(workers, full=True)
    return _Kept(backend)


class DaskBackend(Backend):
    """A Dask cluster: an existing scheduler (``address``), a client, or a new LocalCluster."""

    name = "dask"

    def __init__(self, address: str | Any = "", workers: int = 2,
                 no_workers_timeout: float | None = None) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise HybridnavError(
                "--dask: Dask's distributed scheduler is not installed; it is an optional extra: "
                'pip install "hybridnav[dask]"') from None

        if no_workers_timeout is None:
            env = os.environ.get("HYBRIDNAV_DASK_NO_WORKERS_TIMEOUT")
            no_workers_timeout = NO_WORKERS_TIMEOUT if env is None else Param(
                1.0, lo=0).check("HYBRIDNAV_DASK_NO_WORKERS_TIMEOUT", env, parse=True)
        self.no_workers_timeout = float(no_workers_timeout)
        self._own: list[Any] = []
        if isinstance(address, Client):
            self.client = address
        elif address:
            address = DASK_ADDRESS.check("--dask", address)
            try:
                self.client = Client(address, timeout=30)
            except (OSError, ValueError, TypeError) as exc:
                raise HybridnavError(f"--dask {short_repr(address)}: cannot reach the scheduler "
                                     f"({short_repr(str(exc), 200)})") from None
            self._own.append(self.client)
        else:
            # no dashboard, and the scheduler's HTTP endpoint on a free local port: the default
            # 8787 warns on stderr when another cluster has it
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None,
                                   scheduler_kwargs={"dashboard": False,
                                                     "dashboard_address": "127.0.0.1:0"})
            self.client = Client(cluster)
            self._own += [self.client, cluster]

    def map(self, fn, args, on_done=None):
        from distributed import wait

        futures = [self.client.submit(fn, *a, pure=False, retries=3) for a in args]
        index = {f.key: i for i, f in enumerate(futures)}
        pending = set(futures)
        alone_since = None                 # when the scheduler was last seen without workers
        while pending:
            try:
                done = wait(list(pending), timeout=1.0, return_when="FIRST_COMPLETED").done
            except TimeoutError:
                done = set()
            for fut in sorted(done, key=lambda f: index[f.key]):
                pending.discard(fut)
                if on_done is not None and fut.status == "finished":
                    on_done(index[fut.key])
            if done or not pending:
                alone_since = None
                continue
            if self.client.scheduler_info().get("workers"):
                alone_since = None
            elif alone_since is None:
                alone_since = time.monotonic()
            elif time.monotonic() - alone_since > self.no_workers_timeout:
                self.client.cancel(list(pending))
                raise HybridnavError(
                    f"backend: the Dask scheduler has had no worker for "
                    f"{self.no_workers_timeout:g} s; {len(pending)} of {len(futures)} task(s) "
                    "unfinished (the checkpoint keeps the finished generations: start workers "
                    "and --resume)")
        return self.client.gather(futures)

    def close(self):
        for obj in self._own:
            obj.close()


def make_backend(workers: int = 1, dask: str | Any = "") -> Backend:
    """``dask`` (an address, ``"local"``, or a client) wins; else processes when ``workers > 1``.

    Parameters
    ----------
    workers : int
        Local worker processes (1: this process).
    dask : str or distributed.Client
        A scheduler address, ``"local"`` (a new local cluster) or a client; empty: none.
    """
    if dask:
        if isinstance(dask, str):
            dask = DASK_ADDRESS.check("--dask", dask)
        return DaskBackend("" if dask == "local" else dask, workers=max(workers, 1))
    if workers > 1:
        return ProcessBackend(workers)
    return SerialBackend()


def load_average() -> str:
    """The 1, 5 and 15 minute load averages as text (what timings and parallel speed-ups on a
    shared machine need beside them; ``"unknown"`` where the platform has none)."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "unknown"
