"""The interval evaluation of :class:`hybridnav.analysis.interval.IntervalFunction` in C
(``interval.c``) for programs of arithmetic and exact operations only: ``input``, ``output``,
``const``, ``add``, ``sub``, ``mul``, ``div``, ``inv``, ``neg``, ``twice``, ``assign``, ``sq``,
``sqrt``, ``fabs``, ``fmin``, ``fmax``, ``sign``, ``floor``, ``ceil``, the comparisons ``lt``,
``le``, ``eq``, ``ne``, ``not``, ``and``, ``or`` and ``if_else_zero`` (rational functions such as
the LbCS closed loop, polynomial candidates and their derivatives, saturated and switched
controllers).

The NumPy path evaluates one instruction over every box with about twenty array operations, which
costs 70-100 us per instruction whatever the batch (the certificate's branch and bound evaluates
batches of 1 to 4,096 boxes); the kernel runs the same IEEE operations in the same order per box,
so its enclosures and flags are the NumPy path's (the tests compare them on boxes with zeros,
subnormals, huge and infinite ends). :func:`program` returns ``None`` for a program with any other
operation (its transcendental functions are NumPy's, which can differ from the C library's by an
ulp), and :func:`evaluate` ``None`` where no kernel is available: the caller runs its NumPy path.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from ctypes import c_int64, c_void_p
from typing import Any

import numpy as np

from hybridnav.native import pycall

__all__ = ["Program", "evaluate", "program"]

#: operation codes of interval.c
CODES = {name: k for k, name in enumerate(
    ("input", "output", "const", "add", "sub", "mul", "div", "inv", "neg", "twice", "assign",
     "sq", "sqrt", "fabs", "fmin", "fmax", "sign", "floor", "ceil", "lt", "le", "eq", "ne", "not",
     "and", "or", "if_else_zero"))}
_BINARY = {"add", "sub", "mul", "div", "fmin", "fmax", "lt", "le", "eq", "ne", "and", "or",
           "if_else_zero"}

_SIGNATURES = {"hn_interval": ([c_int64] + [c_void_p] * 5 + [c_int64] * 4 + [c_void_p] * 13,
                               None)}


def _library() -> dict[str, Callable] | None:
    """The kernel's function, built and loaded once per process (``None``: unavailable or
    switched off; :func:`hybridnav.native.pycall.functions`)."""
    return pycall.functions("interval", _SIGNATURES)


class Program:
    """An :class:`~hybridnav.analysis.interval.IntervalFunction`'s instructions as the kernel's
    arrays."""

    def __init__(self, op, in0, in1, out, konst, sz_w: int, nx: int, n_out: int,
                 const_slots: frozenset[int] = frozenset()) -> None:
        self.op, self.in0, self.in1, self.out, self.konst = op, in0, in1, out, konst
        self.sz_w, self.nx, self.n_out = sz_w, nx, n_out
        #: slots written by ``const``: the NumPy path neither clamps them nor marks them > 0
        self.const_slots = const_slots


def program(instructions: Sequence[tuple], sz_w: int, nx: int, n_out: int) -> Program | None:
    """The kernel's form of ``IntervalFunction._program`` (``(name, ins, outs, const, same)``
    tuples), or ``None`` where the kernel does not apply: another operation, a work slot
    written twice (the kernel keeps one value per slot and box), or an index out of range."""
    rows = []
    written: set[int] = set()
    consts: set[int] = set()
    for name, ins, outs, const, same in instructions:
        if name not in CODES or same is not None:
            return None
        if name == "output":
            # (the kernel writes row outs[1] of its (N, n_out) arrays, unchecked: the NumPy
            # path's IndexError, not a write out of bounds, for a malformed program)
            if ins[0] not in written or outs[0] != 0 or not 0 <= outs[1] < n_out:
                return None
            rows.append((CODES[name], ins[0], -1, outs[1], 0.0))
            continue
        slot = outs[0]
        if slot in written or not 0 <= slot < sz_w:
            return None
        written.add(slot)
        if name == "input":
            if ins[0] != 0 or not 0 <= ins[1] < nx:
                return None
            rows.append((CODES[name], ins[1], -1, slot, 0.0))
        elif name == "const":
            rows.append((CODES[name], -1, -1, slot, float(const)))
            consts.add(slot)
        else:
            binary = name in _BINARY
            if ins[0] not in written or (binary and ins[1] not in written):
                return None
            rows.append((CODES[name], ins[0], ins[1] if binary else -1, slot, 0.0))
    if not rows:
        return None
    ints = np.array([r[:4] for r in rows], dtype=np.int64)
    return Program(*(np.ascontiguousarray(ints[:, j]) for j in range(4)),
                   np.array([r[4] for r in rows], dtype=np.float64), sz_w, nx, n_out,
                   frozenset(consts))


#: clamp bounds the kernel takes as the NumPy path does: real scalars (``np.float64`` and
#: ``bool`` are ``float`` and ``int``); a per-box array broadcasts there, ``np.longdouble``
#: computes in its precision, and ``None``, strings or complex numbers are errors there
_SCALARS = (int, float, np.integer, np.bool_, np.float16, np.float32)


def evaluate(prog: Program, lo: np.ndarray, hi: np.ndarray,
             clamp_slot: Mapping[int, tuple[float, float]]) -> tuple[Any, ...] | None:
    """``(out_lo, out_hi, smooth, continuous)`` of ``IntervalFunction._call`` on the boxes
    ``lo``, ``hi`` ``(N, nx)`` with the per-slot clamps ``clamp_slot``; ``None`` where no kernel
    is available, or a clamp bound is not a real scalar (:data:`_SCALARS`)."""
    if not all(isinstance(v, _SCALARS) for pair in clamp_slot.values() for v in pair):
        return None
    lib = _library()
    if lib is None:
        return None
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    hi = np.ascontiguousarray(hi, dtype=np.float64)
    n = lo.shape[0]
    sz = prog.sz_w
    has = np.zeros(sz, dtype=np.uint8)
    cl, ch = np.zeros(sz), np.zeros(sz)
    pos = np.zeros(sz, dtype=np.uint8)
    for slot, (a, b) in clamp_slot.items():
        has[slot], cl[slot], ch[slot] = 1, a, b
        # (a constant's slot is not clamped, nor an open bound: as in the NumPy path)
        pos[slot] = cl[slot] == 0 and slot not in prog.const_slots
    out_lo, out_hi = np.empty((n, prog.n_out)), np.empty((n, prog.n_out))
    smooth = np.ones((n, prog.n_out), dtype=bool)
    cont = np.ones((n, prog.n_out), dtype=bool)
    wl, wh = np.empty(sz), np.empty(sz)
    flags = np.empty(3 * sz, dtype=np.uint8)
    lib["hn_interval"](len(prog.op), prog.op, prog.in0, prog.in1, prog.out, prog.konst, sz, n,
                       prog.nx, prog.n_out, lo, hi, has, cl, ch, pos, out_lo, out_hi, smooth,
                       cont, wl, wh, flags)
    return out_lo, out_hi, smooth, cont
