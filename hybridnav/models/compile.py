"""Compiling the models' CasADi functions: JIT with the system C compiler and a silent fallback
to CasADi's virtual machine, a process-wide cache of compiled functions, and NumPy-bound buffers.

Set the environment variable ``HYBRIDNAV_JIT=0`` to disable JIT compilation altogether.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
import tempfile
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
    """JIT-compile ``fn`` in a private temporary folder, removed once the library is loaded.

    CasADi would otherwise write its C source into the working directory. The shared object stays
    mapped after its file is deleted (POSIX), so nothing is left behind, even at exit.
    """
    folder = tempfile.mkdtemp(prefix="hybridnav-jit-")
    try:
        compiler = os.environ.get("CC", "gcc")
        if shutil.which(compiler) is None:
            raise RuntimeError(f"C compiler {compiler!r} not found")
        opts = {
            "jit": True,
            "compiler": "shell",
            "jit_name": "hybridnav_jit",
            "jit_temp_suffix": True,
            "jit_cleanup": False,
            "jit_options": {"compiler": compiler, "flags": ["-O2"],
                            "verbose": False, "cleanup": False, "directory": folder + os.sep},
        }
        args = fn.mx_in()
        with _quiet_stderr(folder):
            return cs.Function(name, args, fn.call(args), opts)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _quiet_stderr(folder: str):
    """Send the compiler's messages (written to file descriptor 2) to the debug log instead."""
    path = os.path.join(folder, "compiler-messages.txt")
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(path, "wb") as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)
        with contextlib.suppress(OSError), open(path, "rb") as fh:
            text = fh.read().decode(errors="replace").strip()
            if text:
                log.debug("compiler output: %s", text)


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
