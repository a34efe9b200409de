"""Where independent tasks run: this process, local processes, or Dask — the one parallel-execution
mechanism, used by the tuner (chunks of a generation) and by ``compare`` (runs).

Every backend returns the results in submission order, so callers see the same numbers whatever
runs them; ``on_done(i)`` (optional) is called as task ``i`` finishes, in completion order, for
progress bars. A lost worker does not lose the work: its tasks run again (the process pool is
rebuilt and the unfinished tasks resubmitted; Dask reschedules a dead worker's tasks by itself).
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from hybridnav.errors import HybridnavError

log = logging.getLogger(__name__)

__all__ = ["Backend", "DaskBackend", "ProcessBackend", "SerialBackend", "make_backend"]


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
    """A local process pool; chunks of a dead worker run again on a fresh pool."""

    name = "processes"

    def __init__(self, workers: int, retries: int = 3) -> None:
        self.workers = workers
        self.retries = retries
        self._pool = ProcessPoolExecutor(max_workers=workers)

    def map(self, fn, args, on_done=None):
        results: list[Any] = [None] * len(args)
        todo = list(range(len(args)))
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
            self._pool = ProcessPoolExecutor(max_workers=self.workers)
            todo = lost
        raise HybridnavError(f"backend: worker processes kept dying; {len(todo)} chunk(s) could "
                             "not be evaluated")

    def close(self):
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskBackend(Backend):
    """A Dask cluster: an existing scheduler (``address``), a client, or a new LocalCluster."""

    name = "dask"

    def __init__(self, address: str | Any = "", workers: int = 2) -> None:
        from distributed import Client, LocalCluster

        self._own: list[Any] = []
        if isinstance(address, Client):
            self.client = address
        elif address:
            try:
                self.client = Client(address, timeout=30)
            except OSError as exc:
                raise HybridnavError(f"--dask {address}: cannot reach the scheduler ({exc})") \
                    from None
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
        futures = [self.client.submit(fn, *a, pure=False, retries=3) for a in args]
        if on_done is not None:
            from distributed import as_completed as dask_completed

            index = {f.key: i for i, f in enumerate(futures)}
            for fut in dask_completed(futures):
                on_done(index[fut.key])
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
        return DaskBackend("" if dask == "local" else dask, workers=max(workers, 1))
    if workers > 1:
        return ProcessBackend(workers)
    return SerialBackend()
