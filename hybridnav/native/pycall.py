"""Calling a shipped kernel's functions from Python without ctypes' per-call cost.

A call through :mod:`ctypes` costs 5-30 us (an ``ndarray.ctypes`` object per array, a
conversion per argument): more than a small batch's work in the sweep's box kernels.
:func:`functions` builds the same C source, once per machine, as a CPython extension with one
generated entry point, ``call(index, *args)``, that converts each argument as the function's
ctypes signature says (``c_int64``: an integer, ``c_double``: a float, ``c_void_p``: an object
with the buffer protocol, e.g. an ndarray or a ctypes structure, passed as the address of its
first byte) and calls the function (returning nothing or an ``c_int64``) -- the same compiled
function, so the same results. Where ``Python.h`` is missing
or the extension cannot be built it binds the functions through :func:`hybridnav.native.kernel`
instead (the same calls, the arrays' ``ctypes.data``); ``None`` where neither is available.
"""

from __future__ import annotations

import ctypes
import importlib.machinery
import importlib.util
import logging
import os
import sysconfig
import threading
from collections.abc import Callable
from ctypes import c_double, c_int64, c_void_p
from typing import Any

import numpy as np

from hybridnav import native

log = logging.getLogger(__name__)

__all__ = ["functions", "load_extension"]

_CONVERT = {c_int64: "I", c_double: "D", c_void_p: "P"}
_MODULES: dict[str, Any] = {}
_LOCK = threading.Lock()


def load_extension(path, module: str):
    """The CPython extension ``module`` in the file ``path`` (loaded once per process), or
    ``None`` where it cannot be loaded."""
    with _LOCK:
        mod = _MODULES.get(str(path))
        if mod is None:
            try:
                loader = importlib.machinery.ExtensionFileLoader(module, str(path))
                spec = importlib.util.spec_from_file_location(module, str(path), loader=loader)
                mod = importlib.util.module_from_spec(spec)
                loader.exec_module(mod)
            except (ImportError, OSError) as exc:
                log.info("cannot load %s: %s", path, exc)
                return None
            _MODULES[str(path)] = mod
        return mod


def extension_file(name: str, code: str, options: tuple[str, ...] = ()):
    """``code`` built as a CPython extension (``-DHN_PYTHON``, Python's headers): its path, or
    ``None`` (no ``Python.h``, kernels switched off, a failed build)."""
    include = sysconfig.get_paths().get("include")
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    if not include or not suffix or not os.path.isfile(os.path.join(include, "Python.h")):
        return None
    return native.build_file(name, code, (f"-I{include}", "-DHN_PYTHON", *options), suffix)


def _wrapper(module: str, signatures: dict[str, tuple[list, Any]]) -> str | None:
    """The C of the entry point ``call(index, *args)`` for the functions in ``signatures``
    (in their order), or ``None`` where one takes an argument it cannot convert."""
    cases = []
    for k, (symbol, (argtypes, restype)) in enumerate(signatures.items()):
        kinds = [_CONVERT.get(t) for t in argtypes]
        if None in kinds or restype not in (None, c_int64):
            return None
        conv = "".join(f"  if (hn_arg_{c}(a[{i + 1}], &v[{i}], &b[{i}])) goto done;\n"
                       for i, c in enumerate(kinds))
        args = ", ".join(f"v[{i}].{c.lower()}" for i, c in enumerate(kinds))
        call = (f"{symbol}({args});\n  ret = Py_None;\n  Py_INCREF(ret);" if restype is None
                else f"ret = PyLong_FromLongLong({symbol}({args}));")
        cases.append(f"  case {k}:\n  if (na != {len(kinds) + 1}) goto arity;\n{conv}"
                     f"  {call}\n  goto done;\n")
    n_max = max((len(a) for a, _ in signatures.values()), default=0) + 1
    return _PY.format(N=n_max, CASES="".join(cases), MODULE=module)


_PY = r"""
#ifdef HN_PYTHON
#define PY_SSIZE_T_CLEAN
#include <Python.h>
typedef union {{ long long i; double d; void *p; }} hn_value;
static int hn_arg_I(PyObject *o, hn_value *v, Py_buffer *b)
{{
  (void)b;
  v->i = PyLong_AsLongLong(o);
  return v->i == -1 && PyErr_Occurred();
}}
static int hn_arg_D(PyObject *o, hn_value *v, Py_buffer *b)
{{
  (void)b;
  v->d = PyFloat_AsDouble(o);
  return v->d == -1.0 && PyErr_Occurred();
}}
static int hn_arg_P(PyObject *o, hn_value *v, Py_buffer *b)
{{
  if (PyObject_GetBuffer(o, b, PyBUF_STRIDES) < 0)
    return 1;
  v->p = b->buf;
  return 0;
}}
static PyObject *hn_py_call(PyObject *self, PyObject *const *a, Py_ssize_t na)
{{
  hn_value v[{N}];
  Py_buffer b[{N}];
  PyObject *ret = NULL;
  (void)self;
  for (int i = 0; i < {N}; i++)
    b[i].obj = NULL;
  if (na < 1) goto arity;
  long long which = PyLong_AsLongLong(a[0]);
  if (which == -1 && PyErr_Occurred()) goto done;
  switch (which) {{
{CASES}  default:
    PyErr_SetString(PyExc_ValueError, "call(): no such function");
    goto done;
  }}
arity:
  PyErr_SetString(PyExc_TypeError, "call(): wrong number of arguments");
done:
  for (int i = 0; i < {N}; i++)
    if (b[i].obj != NULL) PyBuffer_Release(&b[i]);
  return ret;
}}
static PyMethodDef hn_methods[] = {{
  {{"call", (PyCFunction)(void (*)(void))hn_py_call, METH_FASTCALL, "call(index, *args)"}},
  {{NULL, NULL, 0, NULL}}
}};
static struct PyModuleDef hn_module = {{PyModuleDef_HEAD_INIT, .m_name = "{MODULE}",
                                        .m_size = -1, .m_methods = hn_methods}};
PyMODINIT_FUNC PyInit_{MODULE}(void) {{ return PyModule_Create(&hn_module); }}
#endif
"""


def _from_extension(name: str, signatures) -> dict[str, Callable] | None:
    module = f"_hn_{name}"
    wrapper = _wrapper(module, signatures)
    if wrapper is None:
        return None
    path = extension_file(f"{name}-py", native.source(f"{name}.c") + wrapper)
    mod = None if path is None else load_extension(path, module)
    if mod is None:
        return None
    call = mod.call
    return {symbol: (lambda *args, _k=k: call(_k, *args)) for k, symbol in enumerate(signatures)}


def _from_ctypes(name: str, signatures) -> dict[str, Callable] | None:
    lib = native.kernel(name, signatures)
    if lib is None:
        return None

    def bind(fn: ctypes._CFuncPtr) -> Callable:
        def call(*args):
            return fn(*(a.ctypes.data if isinstance(a, np.ndarray) else ctypes.addressof(a)
                        if isinstance(a, ctypes.Structure) else a for a in args))
        return call

    return {symbol: bind(getattr(lib, symbol)) for symbol in signatures}


def functions(name: str, signatures: dict[str, tuple[list, Any]]) -> dict[str, Callable] | None:
    """The functions of the shipped C source ``<name>.c``, by symbol, each called with its
    arguments as integers, floats and arrays (``c_void_p``: an ndarray, its first element's
    address): through the generated CPython extension, else :mod:`ctypes`; ``None`` where kernels
    are switched off or neither can be built. Built and loaded once per process (kept with
    :func:`hybridnav.native.kernel`'s libraries)."""
    if not native.enabled():
        return None
    key = f"{name}:functions"
    found = native._KERNELS.get(key, False)
    if found is False:
        found = _from_extension(name, signatures)
        if found is None:
            found = _from_ctypes(name, signatures)
        native._KERNELS[key] = found
    return found
