"""The heap search of :func:`hybridnav.planners.path.gridsearch._search` in C (``gridheap.c``).

The Python loop costs ~2 us per expanded node (a ``heapq`` entry, a move-table lookup and a few
float operations per neighbour); the kernel runs the same loop -- keys ``(f // q, -g, node)`` with
Python's floor division, neighbours in the move table's order, updates on strict improvement only
-- so its path, length and ``expanded`` are the Python loop's (the tests compare them on random
grids, every heuristic and move rule). :func:`search` returns ``None`` where no kernel is
available (no compiler, ``HYBRIDNAV_NATIVE=0``, or out of memory): the caller runs its loop.
"""

from __future__ import annotations

from collections.abc import Callable
from ctypes import c_double, c_int64, c_void_p

import numpy as np

from hybridnav.native import pycall

__all__ = ["available", "search"]

_SIGNATURES = {"hn_grid_search": ([c_int64, c_int64, c_int64] + [c_void_p] * 4 + [c_double]
                                  + [c_int64, c_int64] + [c_double] * 4 + [c_void_p] * 6,
                                  c_int64)}

#: heuristics the kernel computes itself (as ``gridsearch._heuristic_table`` does with NumPy);
#: any other comes as a table
MODES = {"zero": 1, "manhattan": 2, "octile": 3}


def _library() -> dict[str, Callable] | None:
    """The kernel's function, built and loaded once per process (``None``: unavailable or
    switched off; :func:`hybridnav.native.pycall.functions`)."""
    return pycall.functions("gridheap", _SIGNATURES)


def available() -> bool:
    """Whether the kernel can be used here."""
    return _library() is not None


def search(masks: bytes, s: int, t: int, offs: np.ndarray, costs: np.ndarray, q: float,
           heuristic: tuple) -> tuple[np.ndarray | None, float, int] | None:
    """``(flat path or None, length, expanded)`` of the heap search from ``s`` to ``t`` on the
    padded grid of per-node move ``masks`` (bit ``k``: offset ``offs[k]``, cost ``costs[k]``,
    int64 and float64 arrays of 8) with key quantum ``q``; ``None`` where the kernel is
    unavailable. ``heuristic`` is ``("table", h)`` (``h``: n doubles, a buffer) or ``(name, wp,
    gx, gy, c, scale)`` for a name in :data:`MODES` (padded width, goal column and row, the
    octile factor and the scale, as ``_heuristic_table`` uses them)."""
    lib = _library()
    if lib is None:
        return None
    n = len(masks)
    if heuristic[0] == "table":
        h = np.frombuffer(heuristic[1], dtype=np.float64)
        mode, wp, gx, gy, c, scale = 0, 1, 0.0, 0.0, 0.0, 0.0
    else:
        h = _NO_TABLE
        mode, (wp, gx, gy, c, scale) = MODES[heuristic[0]], heuristic[1:]
    g = np.empty(n)
    parent = np.empty(n, dtype=np.int64)
    closed = np.empty(n, dtype=np.uint8)
    path = np.empty(n, dtype=np.int64)
    out_g = np.zeros(1)
    out = np.zeros(1, dtype=np.int64)
    k = lib["hn_grid_search"](n, s, t, np.frombuffer(masks, dtype=np.uint8), offs, costs, h, q,
                              mode, wp, gx, gy, c, scale, g, parent, closed, out_g, out, path)
    if k < 0:
        return None
    if k == 0:
        return None, np.inf, int(out[0])
    return path[:k], float(out_g[0]), int(out[0])


_NO_TABLE = np.zeros(1)
