"""Software in the loop: the exported C evaluator, compiled and called from Python.

:class:`CompiledFIS` compiles a C export (the ``.c`` file and its ``.h`` beside it, as ``hybridnav
export --format c`` writes them) into a shared library with the system C compiler, loads it with
:mod:`ctypes` (no new dependency) and offers the ``evaluate(**inputs)`` and ``input_names`` the
EFFC planner calls. So ``hybridnav run SCENARIO --planner effc --fis build/effc.c`` drives the
closed loop with the deployment artifact itself, and :func:`hybridnav.analysis.sil.verify`
compares that run with the Python evaluator's, trajectory and ``w`` signal, sample by sample.
"""

from __future__ import annotations

import ctypes
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError

__all__ = ["CompiledFIS"]


class CompiledFIS:
    """An exported C fuzzy system, compiled into a shared library and callable from Python.

    Parameters
    ----------
    source : str or path-like
        The ``.c`` file written by the C export; the header with the same stem must be beside it.

    Raises
    ------
    HybridnavError
        No such file, a file that is not a hybridnav C export, no C compiler (``CC`` or
        ``gcc``/``cc`` on ``PATH``), or a compilation error (the compiler's message).
    """

    def __init__(self, source: str | os.PathLike[str]) -> None:
        src = Path(source)
        header = src.with_suffix(".h")
        for f in (src, header):
            if not f.is_file():
                raise HybridnavError(f"{f}: no such file (expected a C export: {src.stem}.c and "
                                     f"{src.stem}.h, as hybridnav export --format c writes)")
        text = header.read_text(encoding="utf-8", errors="replace")
        m = re.search(r"^(\w+)_real (\w+)_evaluate\(", text, re.M)
        if m is None or m.group(1) != m.group(2):
            raise HybridnavError(f"{header}: not a hybridnav C export (no <prefix>_evaluate)")
        p = m.group(1)
        P = p.upper()
        ins = sorted((int(k), name.lower()) for name, k in
                     re.findall(rf"^#define {P}_IN_(\w+) (\d+)", text, re.M))
        n = re.search(rf"^#define {P}_N_INPUTS (\d+)", text, re.M)
        real = re.search(rf"^#define {P}_REAL (\w+)", text, re.M)
        if n is None or real is None or [k for k, _ in ins] != list(range(int(n.group(1)))):
            raise HybridnavError(f"{header}: not a hybridnav C export (inputs not declared)")
        self.name = p
        self.input_names = tuple(name for _, name in ins)
        self.source = str(src)
        self._real = ctypes.c_float if real.group(1) == "float" else ctypes.c_double
        self._lib = _build(src)
        fn = getattr(self._lib, f"{p}_evaluate")
        fn.restype = self._real
        fn.argtypes = [ctypes.POINTER(self._real)]
        self._fn = fn

    def __repr__(self) -> str:
        return f"CompiledFIS({self.source!r}, inputs={self.input_names})"

    def evaluate(self, **inputs: ArrayLike) -> NDArray[np.float64] | np.float64:
        """Crisp outputs for crisp inputs, one C call per sample (inputs broadcast together)."""
        if set(inputs) != set(self.input_names):
            raise TypeError(f"evaluate() of C system {self.name!r} takes the inputs "
                            f"{', '.join(self.input_names)}; got {', '.join(sorted(inputs))}")
        arrays = np.broadcast_arrays(*(np.asarray(inputs[k], dtype=float)
                                       for k in self.input_names))
        shape = arrays[0].shape
        X = np.stack([a.ravel() for a in arrays], axis=1)
        buf = (self._real * len(self.input_names))()
        out = np.empty(len(X))
        for i, row in enumerate(X):
            buf[:] = row.tolist()
            out[i] = self._fn(buf)
        return out.reshape(shape) if shape else np.float64(out[0])


def _build(src: Path) -> ctypes.CDLL:
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if cc is None or shutil.which(cc) is None:
        raise HybridnavError(f"{src}: no C compiler to build it with (set CC, or install gcc)")
    folder = tempfile.mkdtemp(prefix="hybridnav-sil-")
    try:
        lib = Path(folder) / f"lib{src.stem}.so"
        res = subprocess.run([cc, "-std=c99", "-O2", "-shared", "-fPIC", "-o", str(lib), str(src)],
                             capture_output=True, text=True, check=False, timeout=300)
        if res.returncode != 0:
            raise HybridnavError(f"{src}: does not compile: {res.stderr.strip()[:2000]}")
        return ctypes.CDLL(str(lib))           # stays mapped after its file is removed (POSIX)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
