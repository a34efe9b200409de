"""Software in the loop: the exported C evaluator, compiled and called from Python.

:class:`CompiledFIS` compiles a C export (the ``.c`` file and its ``.h`` beside it, as ``hybridnav
export --format c`` writes them) with a small driver into a program that runs in a child process
(:mod:`~hybridnav.fuzzy.export.sandbox`: time and resource limits, never in this process), and
offers the ``evaluate(**inputs)`` and ``input_names`` the EFFC planner calls. So ``hybridnav run
SCENARIO --planner effc --fis build/effc.c`` drives the closed loop with the deployment artifact
itself, and :func:`hybridnav.fuzzy.export.closedloop.verify` compares that run with the Python
evaluator's, trajectory and ``w`` signal, sample by sample.

Only unmodified exports are compiled unless ``trust=True``: the source ends with the system it
was generated from (:func:`~hybridnav.fuzzy.export.c.embedded_system`), and both files must be
exactly what :func:`~hybridnav.fuzzy.export.c.to_c` writes for it (a checksum would not do: anyone
can recompute one for a file they changed; this generated text computes only the fuzzy system).
Trusted C still compiles and runs only in child processes with limits, and may include only
headers named relative to it or to the system's include folders.
"""

from __future__ import annotations

import os
import re
import shutil
import stat
import struct
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.fileio import MAX_FILE_BYTES, decode_text
from hybridnav.fuzzy.export.c import embedded_system, to_c
from hybridnav.fuzzy.export.sandbox import (
    CALL_TIMEOUT,
    COMPILE_TIMEOUT,
    Child,
    check_includes,
    compile_program,
)
from hybridnav.fuzzy.system import FuzzySystem

__all__ = ["CompiledFIS", "TRUST_HINT"]

#: What a refusal tells the user to do about C that is not an unmodified export.
TRUST_HINT = ("pass --trust (hybridnav verify) to compile and run other C: it then runs with "
              "your rights, in a child process with time and resource limits")
#: Rows of inputs per exchange with the child (each exchange has its own time limit).
_CHUNK = 4096
_HELLO = b"hnS1"
_DRIVER = r"""/* hybridnav software-in-the-loop driver: batches of inputs in, outputs out, on the two
 * file descriptors given as its last arguments (what the C prints goes to /dev/null) */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
typedef @real hn_real;
hn_real @p_evaluate(const hn_real *in);
int main(int argc, char **argv)
{
    static const unsigned char hello[4] = {'h', 'n', 'S', '1'};
    double *x = (double *)malloc(sizeof(double) * @chunk * @k);
    double *y = (double *)malloc(sizeof(double) * @chunk);
    hn_real in[@k];
    unsigned int n, i, j;
    FILE *req, *rep;
    if (argc < 3 || x == NULL || y == NULL) return 3;
    req = fdopen(atoi(argv[argc - 2]), "rb");
    rep = fdopen(atoi(argv[argc - 1]), "wb");
    if (req == NULL || rep == NULL) return 3;
    if (fwrite(hello, 1, 4, rep) != 4 || fflush(rep) != 0) return 4;
    while (fread(&n, sizeof n, 1, req) == 1) {
        if (n > @chunk || fread(x, sizeof(double) * @k, n, req) != n) return 5;
        for (i = 0; i < n; ++i) {
            for (j = 0; j < @k; ++j) in[j] = (hn_real)x[(size_t)i * @k + j];
            y[i] = (double)@p_evaluate(in);
        }
        if (fwrite(y, sizeof(double), n, rep) != n || fflush(rep) != 0) return 6;
    }
    return 0;
}
"""


def _read_c(path: Path, what: str) -> str:
    """The text of a regular file (a pipe or device is refused before it is read: it could
    block, or never end)."""
    if not os.path.lexists(path):
        raise HybridnavError(f"{path}: no such file (expected a C export: {path.stem}.c and "
                             f"{path.stem}.h, as hybridnav export --format c writes)")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise HybridnavError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise HybridnavError(f"{path}: expected the {what} as a regular file, got a folder, "
                                 "pipe or device")
        data = fh.read(MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        raise HybridnavError(f"{path}: {what} larger than {MAX_FILE_BYTES // 2**20} MiB; "
                             "expected a C export")
    return decode_text(data, str(path), what).replace("\r\n", "\n")


def _first_difference(text: str, want: str) -> int:
    """1-based number of the first line where ``text`` and ``want`` differ, or 0."""
    a, b = text.split("\n"), want.split("\n")
    for k, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return k + 1
    return 0 if len(a) == len(b) else min(len(a), len(b)) + 1


def _check_export(src: Path, header: Path, source: str, head: str, real: str) -> FuzzySystem:
    """The system ``src`` was exported from, if ``src`` and ``header`` are exactly what
    :func:`to_c` writes for it with their base name and real type; else a refusal."""
    try:
        system = embedded_system(source, str(src))
    except HybridnavError as exc:
        raise HybridnavError(f"{exc}; {TRUST_HINT}") from None
    if system is None:
        raise HybridnavError(f"{src}: expected a C file exported by hybridnav (it ends with the "
                             "system it was generated from, and is what hybridnav writes for "
                             f"it), got a file without that system; {TRUST_HINT}")
    # each table entry takes at least 8 characters ("A_K(0.0)"): a file too short for the
    # tables of its system is not its export (and is not worth the work of generating them)
    entries = sum(v.points * (1 + 2 * len(v.terms)) for v in system.inputs) + \
        system.output.points * (1 + 2 * len({r.then for r in system.rules}))
    if 8 * entries > len(source):
        raise HybridnavError(f"{src}: expected the file hybridnav exports for the system "
                             f"embedded in {src.name}, got one too short for its tables; "
                             f"{TRUST_HINT}")
    try:
        code = to_c(system, src.stem, real=real)
    except HybridnavError:
        raise HybridnavError(f"{src}: expected a C file exported by hybridnav, got one whose "
                             f"name or embedded system hybridnav does not export; {TRUST_HINT}"
                             ) from None
    for path, text, want in ((src, source, code.source), (header, head, code.header)):
        line = _first_difference(text, want)
        if line:
            raise HybridnavError(
                f"{path}: expected the file hybridnav exports for the system embedded in "
                f"{src.name}, unmodified, got one that differs from it at line {line}; export "
                f"it again (hybridnav export SYSTEM --format c) or {TRUST_HINT}")
    return system


class CompiledFIS:
    """An exported C fuzzy system, compiled and called from Python in a sandboxed child process.

    Parameters
    ----------
    source : str or path-like
        The ``.c`` file written by the C export; the header with the same stem must be beside it.
    trust : bool
        Compile C that is not an unmodified hybridnav export (see the module's description);
        it still runs only in the child process.
    timeout : float
        Seconds one call of :meth:`evaluate` may take per 4096 samples (and the program's
        start); the child is then killed.
    compile_timeout : float
        Seconds the compiler may take.

    Attributes
    ----------
    system : FuzzySystem or None
        The system the file was exported from (None for trusted C).

    Raises
    ------
    HybridnavError
        No such file, a file that is not a hybridnav C export (or not an unmodified one, unless
        ``trust``), an ``#include`` of an absolute path, ``..`` or macro, no C compiler (``CC``
        or ``gcc``/``cc`` on ``PATH``), a compilation error (its location and kind), or a
        program that does not start within ``timeout``.
    """

    def __init__(self, source: str | os.PathLike[str], *, trust: bool = False,
                 timeout: float = CALL_TIMEOUT, compile_timeout: float = COMPILE_TIMEOUT) -> None:
        src = Path(source)
        if not 0 < timeout <= 86400 or not 0 < compile_timeout <= 86400:
            raise HybridnavError(f"{src}: timeout: expected a number of seconds in (0, 86400], "
                                 f"got {timeout if not 0 < timeout <= 86400 else compile_timeout!r}")
        header = src.with_suffix(".h")
        code = _read_c(src, "C source")
        text = _read_c(header, "C header")
        m = re.search(r"^(\w+)_real (\w+)_evaluate\(", text, re.M)
        if m is None or m.group(1) != m.group(2):
            raise HybridnavError(f"{header}: not a hybridnav C export (no <prefix>_evaluate)")
        p = m.group(1)
        P = p.upper()
        ins = sorted((int(k), name.lower()) for name, k in
                     re.findall(rf"^#define {P}_IN_(\w+) (\d{{1,6}})\b", text, re.M))
        n = re.search(rf"^#define {P}_N_INPUTS (\d{{1,6}})\b", text, re.M)
        real = re.search(rf"^#define {P}_REAL (double|float)$", text, re.M)
        if n is None or real is None or not ins or [k for k, _ in ins] != list(
                range(int(n.group(1)))):
            raise HybridnavError(f"{header}: not a hybridnav C export (inputs not declared)")
        self.name = p
        self.input_names = tuple(name for _, name in ins)
        self.source = str(src)
        self.system = None if trust else _check_export(src, header, code, text, real.group(1))
        check_includes(code, str(src))
        check_includes(text, str(header))
        k = len(self.input_names)
        driver = (_DRIVER.replace("@real", real.group(1)).replace("@p", p)
                  .replace("@chunk", str(_CHUNK)).replace("@k", str(k)))
        c, h = f"c/{src.stem}.c", f"c/{src.stem}.h"
        exe = compile_program({c: code, h: text, "hybridnav_sil_driver.c": driver}, str(src),
                              shown={c: str(src), h: str(header),
                                     "hybridnav_sil_driver.c": "the hybridnav SIL driver"},
                              timeout=compile_timeout)
        try:        # once it greets, it runs: its folder can go (POSIX)
            self._child = Child([str(exe)], str(src), timeout=timeout, cwd=exe.parent)
            hello = self._child.exchange(b"", len(_HELLO), "the compiled program's start")
        finally:
            shutil.rmtree(exe.parent, ignore_errors=True)
        if hello != _HELLO:
            self._child.close()
            raise HybridnavError(f"{src}: the compiled program wrote something else than the "
                                 "driver's greeting at its start (does the C write to its "
                                 "descriptors?)")

    def __repr__(self) -> str:
        return f"CompiledFIS({self.source!r}, inputs={self.input_names})"

    def __enter__(self) -> CompiledFIS:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """End the child process (also done when the object is collected)."""
        self._child.close()

    def evaluate(self, **inputs: ArrayLike) -> NDArray[np.float64] | np.float64:
        """Crisp outputs for crisp inputs (broadcast together), computed by the C code in the
        child process: 4096 samples per exchange, each exchange within the time limit.

        Parameters
        ----------
        **inputs : array_like
            One value or array per input name (:attr:`input_names`).

        Returns
        -------
        ndarray or numpy.float64
            The outputs, in the broadcast shape (a scalar for scalar inputs).

        Raises
        ------
        TypeError
            Inputs other than :attr:`input_names`.
        HybridnavError
            The C did not return within the time limit, or its process died (the message names
            the signal); every later call raises the same.
        """
        if set(inputs) != set(self.input_names):
            raise TypeError(f"evaluate() of C system {self.name!r} takes the inputs "
                            f"{', '.join(self.input_names)}; got {', '.join(sorted(inputs))}")
        arrays = [np.asarray(inputs[k], dtype=np.float64) for k in self.input_names]
        shape = arrays[0].shape
        if any(a.shape != shape for a in arrays):
            arrays = np.broadcast_arrays(*arrays)
            shape = arrays[0].shape
        n = arrays[0].size
        X = np.empty((n, len(arrays)))          # one row of inputs per sample, as C reads them
        for j, a in enumerate(arrays):
            X[:, j] = a.ravel()
        out = np.empty(n)
        for s in range(0, n, _CHUNK):
            rows = X[s:s + _CHUNK]
            reply = self._child.exchange(struct.pack("=I", len(rows)) + rows.tobytes(),
                                         8 * len(rows), "evaluate")
            out[s:s + len(rows)] = np.frombuffer(reply, dtype=np.float64)
        return out.reshape(shape) if shape else np.float64(out[0])
