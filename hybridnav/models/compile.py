"""Compiling the models' CasADi functions: CasADi's generated C built with the system C compiler
(once per machine, in :func:`hybridnav.native.cache_dir`) and a silent fallback to CasADi's
virtual machine, a process-wide cache of compiled functions, and NumPy-bound buffers.

Set the environment variable ``HYBRIDNAV_JIT=0`` to disable JIT compilation altogether.
"""

from __future__ import annotations

import logging
import os
import shutil
import threading
from collections import OrderedDict
from typing import Any

import casadi as cs
import numpy as np

log = logging.getLogger(__name__)

__all__ = ["jit_allowed", "jit_available"]

# --------------------------------------------------------------------------------------------
# Compilation: JIT with a silent fallback, and a process-wide cache of compiled functions.
# --------------------------------------------------------------------------------------------

_jit_state: dict[str, Any] = {}
_cache_lock = threading.Lock()
_FUNCTIONS: OrderedDict[tuple, cs.Function] = OrderedDict()
_FUNCTION_CACHE_SIZE = 128


def _jit_function(name: str, fn: cs.Function) -> cs.Function:
    """``fn`` compiled to machine code and loaded back (``casadi.external``).

    CasADi's code generator writes the C source; :func:`hybridnav.native.build_path` compiles it
    once per machine into the cache folder, named by the hash of the source (and compiler and
    flags), so every later process — tuning and ``compare`` workers, the next ``hybridnav run``
    — loads the library in milliseconds instead of running the compiler again (0.2-0.3 s per
    function).
    """
    from hybridnav import native

    compiler = os.environ.get("CC", "gcc")
    if shutil.which(compiler) is None:
        raise RuntimeError(f"C compiler {compiler!r} not found")
    gen = cs.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
    gen.add(fn)
    path = native.build_path(f"casadi-{name}", _vm_min_max(gen.dump()))
    if path is None:
        raise RuntimeError("compiling the generated code failed")
    return cs.external(fn.name(), str(path))


#: C99's fmin/fmax (glibc's) and the virtual machine's differ at equal arguments of opposite
#: signs of zero (fmin(0, -0) is -0 compiled, 0 in the virtual machine): the generated helpers
#: are replaced by the virtual machine's rule (the first argument when they compare equal, the
#: other one where one is NaN)
_MIN_MAX = {"  return fmin(x, y);\n": "  return y != y ? x : x != x ? y : y < x ? y : x;\n",
            "  return fmax(x, y);\n": "  return y != y ? x : x != x ? y : x < y ? y : x;\n"}


def _vm_min_max(code: str) -> str:
    for c99, vm in _MIN_MAX.items():
        code = code.replace(c99, vm)
    return code


def jit_allowed() -> bool:
    """Whether compiling is allowed at all (``HYBRIDNAV_JIT=0`` disables it)."""
    return os.environ.get("HYBRIDNAV_JIT", "1").strip().lower() not in ("0", "false", "no", "off")


def jit_available() -> bool:
    """Whether CasADi can JIT-compile here (tried once per process, on a tiny function).

    Set the environment variable ``HYBRIDNAV_JIT=0`` to disable JIT compilation altogether.
    """
    if not jit_allowed():
        return False
    if "ok" not in _jit_state:
        try:
            z = cs.SX.sym("z")
            f = _jit_function("hybridnav_jit_probe", cs.Function("probe", [z], [2 * z]))
            _jit_state["ok"] = float(f(1.5)) == 3.0
        except Exception as exc:  # no compiler, no headers, sandboxed temp dir, ...
            log.info("CasADi JIT unavailable, using the virtual machine: %s", exc)
            _jit_state["ok"] = False
    return _jit_state["ok"]


def _compile(key: tuple, build, jit: bool) -> cs.Function:
    """Return the cached function for ``key``, building (and JIT-compiling) it on first use."""
    full_key = key + (jit,)
    with _cache_lock:
        fn = _FUNCTIONS.get(full_key)
        if fn is not None:
            _FUNCTIONS.move_to_end(full_key)
            return fn
    fn = build()
    if jit and jit_available():
        try:
            fn = _jit_function(fn.name(), fn)
        except Exception as exc:
            log.info("JIT compilation of %s failed, using the virtual machine: %s", fn.name(), exc)
    with _cache_lock:
        _FUNCTIONS[full_key] = fn
        while len(_FUNCTIONS) > _FUNCTION_CACHE_SIZE:
            _FUNCTIONS.popitem(last=False)
    return fn


class _Buffered:
    """A compiled function bound to NumPy input/output arrays through ``Function.buffer()``.

    One instance per (function, thread): CasADi buffers hold work memory and are not re-entrant.
    """

    def __init__(self, fn: cs.Function, in_shapes, out_shapes):
        self.fn = fn
        self.ins = [np.zeros(s) for s in in_shapes]
        self.outs = [np.zeros(s) for s in out_shapes]
        self._buf, self._trigger = fn.buffer()
        for i, a in enumerate(self.ins):
            self._buf.set_arg(i, memoryview(a))
        for i, a in enumerate(self.outs):
            self._buf.set_res(i, memoryview(a))

    def __call__(self) -> None:
        self._trigger()


# --------------------------------------------------------------------------------------------
# Evaluating a function at many states: the analysis tools' samples.
# --------------------------------------------------------------------------------------------

#: functions with more instructions than this stay in the virtual machine (gcc's time on a large
#: generated file outweighs what a few batches gain)
ROWS_JIT_MAX_INSTRUCTIONS = 20_000
#: batches smaller than this stay in the virtual machine (nothing to gain from compiling)
ROWS_JIT_MIN_ROWS = 5_000
_ROWS: OrderedDict[str, cs.Function] = OrderedDict()


def _rows_function(fn: cs.Function) -> cs.Function:
    """``fn`` compiled (once per machine; once per process per function, kept by its serialized
    form), or ``fn`` itself where it is too large to compile or compiling is off or fails. The
    generated C performs the virtual machine's operations in its order (built without
    floating-point contraction): the same values bit for bit (the tests compare them)."""
    if not jit_available():
        return fn
    try:
        if fn.n_instructions() > ROWS_JIT_MAX_INSTRUCTIONS:
            return fn
        key = fn.serialize()
    except RuntimeError:            # a Callback or an external library: nothing to compile
        return fn
    with _cache_lock:
        found = _ROWS.get(key)
        if found is not None:
            _ROWS.move_to_end(key)
            return found
    try:
        found = _jit_function(f"rows_{fn.name()}", fn)
    except Exception as exc:
        log.info("JIT compilation of %s failed, using the virtual machine: %s", fn.name(), exc)
        found = fn
    with _cache_lock:
        _ROWS[key] = found
        while len(_ROWS) > _FUNCTION_CACHE_SIZE:
            _ROWS.popitem(last=False)
    return found


_ROW_MAPS: OrderedDict[tuple[int, int, bool], tuple[cs.Function, cs.Function]] = OrderedDict()


def _rows_map(fn: cs.Function, n: int) -> cs.Function:
    """``fn`` (compiled for large batches) mapped over ``n`` rows, its other inputs shared.

    Kept per function object and ``n`` (building a map costs about 60 us, a hundred times a
    small batch's evaluation, and a compiled function's map over 100,000 rows longer than its
    evaluation): the entry holds the function, so its ``id`` is not reused while kept."""
    key = (id(fn), n, n >= ROWS_JIT_MIN_ROWS and jit_available())
    with _cache_lock:
        found = _ROW_MAPS.get(key)
        if found is not None and found[0] is fn:
            _ROW_MAPS.move_to_end(key)
            return found[1]
    f = _dense(fn)
    f = _rows_function(f) if key[2] else f
    mapped = f.map(f"{fn.name()}_rows", "serial", n, list(range(1, fn.n_in())), [])
    with _cache_lock:
        _ROW_MAPS[key] = (fn, mapped)
        while len(_ROW_MAPS) > _FUNCTION_CACHE_SIZE:
            _ROW_MAPS.popitem(last=False)
    return mapped


def _dense(fn: cs.Function) -> cs.Function:
    """``fn`` with dense inputs and outputs (the buffers hold every entry, CasADi's read and
    write the nonzeros only): structural zeros read as 0 as ``np.asarray`` of the virtual
    machine's result gives them; entries of an input outside its sparsity are dropped as a call
    does."""
    if all(fn.sparsity_in(i).is_dense() for i in range(fn.n_in())) and \
            all(fn.sparsity_out(i).is_dense() for i in range(fn.n_out())):
        return fn
    sym = cs.SX.sym if fn.is_a("SXFunction") else cs.MX.sym
    ins = [sym(fn.name_in(i), fn.size1_in(i), fn.size2_in(i)) for i in range(fn.n_in())]
    outs = fn.call(ins)
    return cs.Function(fn.name(), ins, [cs.densify(o) for o in outs])


def evaluate_rows(fn: cs.Function, X: np.ndarray, *shared: Any) -> list[np.ndarray]:
    """``fn`` at every row of ``X`` ``(N, nx)`` (its first input), the other inputs ``shared``
    by every row: one ``(N, numel)`` array per output (a matrix output's entries in CasADi's
    column-major order, structural zeros as 0).

    Large batches run the compiled function (:func:`_rows_function`), and every batch writes into
    NumPy arrays through ``Function.buffer()`` instead of converting CasADi matrices (whose
    conversion to NumPy goes through a Python list of floats). The values are those of calling
    ``fn.map(N)`` in the virtual machine."""
    X = np.ascontiguousarray(X, dtype=float)
    nx = fn.numel_in(0)
    if X.ndim != 2 or X.shape[1] != nx:
        raise ValueError(f"evaluate_rows: {fn.name()}: expected states of shape (N, {nx}), got "
                         f"{X.shape}")
    if len(shared) != fn.n_in() - 1:
        raise ValueError(f"evaluate_rows: {fn.name()}: expected {fn.n_in() - 1} shared inputs, "
                         f"got {len(shared)}")
    ins = [X]
    for i, s in enumerate(shared, 1):
        a = np.ascontiguousarray(np.asarray(s, dtype=float).reshape(-1, order="F"))
        if a.size != fn.numel_in(i):
            raise ValueError(f"evaluate_rows: {fn.name()}: input {fn.name_in(i)}: expected "
                             f"{fn.numel_in(i)} values, got {a.size}")
        ins.append(a)
    n = X.shape[0]
    if n == 0:
        return [np.empty((0, fn.numel_out(i))) for i in range(fn.n_out())]
    fm = _rows_map(fn, n)                 # (dense inputs and outputs: :func:`_dense`)
    outs = [np.empty((n, fn.numel_out(i))) for i in range(fn.n_out())]
    buf, trigger = fm.buffer()
    for i, a in enumerate(ins):
        buf.set_arg(i, memoryview(a))
    for i, a in enumerate(outs):
        buf.set_res(i, memoryview(a))
    trigger()
    return outs
