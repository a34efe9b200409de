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
    path = native.build_path(f"casadi-{name}", gen.dump())
    if path is None:
        raise RuntimeError("compiling the generated code failed")
    return cs.external(fn.name(), str(path))


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
