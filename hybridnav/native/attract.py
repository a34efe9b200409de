"""The firefly attraction loop (``attract.c``) bound to NumPy: the loop over the brighter
fireflies of :func:`hybridnav.planners.swarm.firefly._attraction_moves` in C, one call per
attraction, with the exponential left to NumPy (``np.exp``, so the attractiveness is the NumPy
path's to the bit: NumPy's exp can differ from the C library's by an ulp).

:func:`moves` returns ``False`` where it does not apply (no compiler, kernels switched off, more
than 2 dimensions, where NumPy's ``einsum`` of a row with itself is a sum in another order), and
the caller runs its NumPy loop.
"""

from __future__ import annotations

from collections.abc import Callable
from ctypes import Structure, c_double, c_int64, c_void_p

import numpy as np

from hybridnav.native import pycall

__all__ = ["moves"]


class _Attract(Structure):
    _fields_ = [("n", c_int64), ("d", c_int64), ("m", c_int64), ("Xs", c_void_p),
                ("Ys", c_void_p), ("E", c_void_p), ("order", c_void_p), ("first", c_void_p),
                ("diff", c_void_p), ("arg", c_void_p), ("ex", c_void_p), ("row", c_void_p),
                ("rank", c_void_p), ("off", c_int64), ("inv_diag2", c_double),
                ("neg_gamma", c_double), ("scale", c_double), ("beta_min", c_double)]


#: the kernel's function (the structure passed by its address)
_SIGNATURES = {"hn_attract_step": ([c_void_p, c_int64, c_int64], c_int64)}


def _library() -> dict[str, Callable] | None:
    """The kernel's function by symbol, built and loaded once per process (``None``:
    unavailable or switched off; :func:`hybridnav.native.pycall.functions`)."""
    return pycall.functions("attract", _SIGNATURES)


def moves(Xs: np.ndarray, Ys: np.ndarray, E: np.ndarray, order: np.ndarray, first: np.ndarray,
          m: int, inv_diag2: float, gamma: float, beta0: float, beta_min: float) -> bool:
    """Move ``Ys`` (sorted by brightness, C-contiguous float64, in place) towards each of the
    ``J = len(first)`` brightest in turn, as the NumPy loop of ``_attraction_moves`` does, the
    random steps ``E`` rows in the order they were drawn (``order``: the index of the firefly
    at each sorted position); False (``Ys`` untouched) where the kernel does not apply."""
    n, d = Xs.shape
    if d > 2 or d < 1:
        return False
    lib = _library()
    if lib is None:
        return False
    Xs = np.ascontiguousarray(Xs, dtype=np.float64)
    E = np.ascontiguousarray(E, dtype=np.float64)
    order = np.ascontiguousarray(order, dtype=np.int64)
    first = np.ascontiguousarray(first, dtype=np.int64)
    if not (Ys.flags.c_contiguous and Ys.dtype == np.float64):
        raise ValueError("Ys must be C-contiguous float64")
    diff = np.empty((n, d))
    arg, ex = np.empty(n), np.empty(n)
    row, rank = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    a = _Attract(n, d, int(m), Xs.ctypes.data, Ys.ctypes.data, E.ctypes.data, order.ctypes.data,
                 first.ctypes.data, diff.ctypes.data, arg.ctypes.data, ex.ctypes.data,
                 row.ctypes.data, rank.ctypes.data, 0, float(inv_diag2), -gamma,
                 beta0 - beta_min, float(beta_min))
    ref = a
    step, exp = lib["hn_attract_step"], np.exp
    J = len(first)
    k = step(ref, 0, J)
    for p in range(1, J + 1):
        exp(arg[:k], out=ex[:k])
        k = step(ref, p, J)
    return True
