"""The C build of the single-sample evaluator: compiled once per machine, loaded on demand.

:meth:`hybridnav.fuzzy.FuzzySystem.evaluate` with one sample runs
:meth:`CompiledSystem.evaluate_scalar <hybridnav.fuzzy.engine.CompiledSystem.evaluate_scalar>`,
about 10 us in Python, most of it interpreter overhead. ``_native.c`` is the same computation in
C, operation for operation (so the results are identical, bit for bit, not merely close), as
one CPython extension module for every system: an ``Evaluator`` holds one system's tables, packed
here by :func:`_pack` from the engine's own lists. No per-system compilation: a system's
evaluator is made in about 0.1 ms from its tables.

When it is used. A system counts its single-sample evaluations on the Python path; at the
:data:`AFTER`-th it asks :func:`evaluator`. If the module is in the cache folder it is loaded
(about 1 ms, once per process); if not, a background thread starts the compiler (about 1 s of
one core, once per machine and Python) and the system keeps the Python path, asking again every
:data:`AFTER` evaluations. No evaluation ever waits for the compiler: a script doing a handful
of evaluations pays nothing (not even the load), one doing thousands switches after the first
few hundred. :meth:`FuzzySystem.use_native` switches at once (building in the foreground if
needed). Before a system switches, its C evaluator is checked against the Python path on a few
inputs (bit for bit); a mismatch (a compiler that ignores ``-ffp-contract=off``, x87 extended
precision) logs a warning and the system keeps the Python path.

Where there is no C compiler (``CC``, or ``gcc``/``cc``/``clang`` on ``PATH``), no
``Python.h``, or on Windows, or with the environment variable ``HYBRIDNAV_NATIVE=0``,
everything stays on the Python path, with the same results.

The cache folder is ``$HYBRIDNAV_CACHE_DIR`` or ``$XDG_CACHE_HOME/hybridnav`` (default
``~/.cache/hybridnav``), subfolder ``native``. The module's file name holds a hash of the C
source, the compiler command and the Python build (its extension suffix), so a changed source,
compiler or Python gets a new build and never loads a stale one. The compiler runs under ``sh``
which moves the result into place, so a build started by a process that exits meanwhile still
completes; a lock file keeps processes started together from compiling at once.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import logging
import math
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import threading
import time
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["AFTER", "available", "build", "cache_dir", "evaluator", "library_path"]

log = logging.getLogger(__name__)

#: Single-sample evaluations of one system on the Python path before it asks for the C
#: evaluator (and between two asks while the module is being built): about 2 ms of Python-path
#: work, against about 1 ms to load the module and 0.1 ms to pack a system's tables.
AFTER = 200

#: ``HYBRIDNAV_NATIVE=0`` (or ``off``, ``no``, ``false``) keeps every system on the Python path
#: (it switches every compiled kernel off)
ENV = "HYBRIDNAV_NATIVE"
_MODULE = "_hybridnav_fuzzy_native"
_LAYOUT = 1            # the packing below; _native.c checks it (HN_LAYOUT)
_HEADER = 16
# -ffp-contract=off: a * b + c stays two roundings, as in Python (no fused multiply-add); no
# -ffast-math, so -O3 only vectorizes what keeps IEEE results (the dense branch's min/max loops)
_FLAGS = ["-O3", "-fPIC", "-shared", "-ffp-contract=off", "-fno-strict-aliasing"]
_STALE_LOCK = 600.0    # seconds after which a build lock is taken to be a dead build's

_lock = threading.Lock()
_module: Any = None
_state = "idle"        # idle, building, failed (no compiler, no Python.h, failed build), off
_thread: threading.Thread | None = None
_builds = 0            # compiler runs started by this process (the tests read it)


def _reset_after_fork() -> None:
    global _lock, _state, _thread
    _lock = threading.Lock()
    if _state == "building":  # the building thread is the parent's
        _state = "idle"
    _thread = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)


def _enabled() -> bool:
    from hybridnav import native

    return native.enabled() and sys.platform != "win32"


def cache_dir() -> Path:
    """The folder of the compiled module (not created here): the compiled kernels' folder,
    :func:`hybridnav.native.cache_dir`."""
    from hybridnav import native

    return native.cache_dir()


def _source() -> str:
    return resources.files("hybridnav.fuzzy").joinpath("_native.c").read_text(encoding="utf-8")


def _compiler() -> list[str] | None:
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc") or shutil.which(
        "clang")
    if not cc:
        return None
    cmd = shlex.split(cc)
    return cmd if cmd and shutil.which(cmd[0]) else None


def _include() -> str | None:
    for key in ("include", "platinclude"):
        inc = sysconfig.get_paths().get(key)
        if inc and os.path.isfile(os.path.join(inc, "Python.h")):
            return inc
    return None


def _command(cc: list[str], include: str) -> list[str]:
    cmd = [*cc, *_FLAGS, f"-I{include}"]
    if sys.platform == "darwin":
        cmd += ["-undefined", "dynamic_lookup"]
    return cmd


def library_path() -> Path | None:
    """Where the compiled module for this source, compiler and Python is (or would be).

    Returns
    -------
    pathlib.Path or None
        None where it cannot be built here (no compiler, no ``Python.h``, Windows, disabled).
    """
    if not _enabled():
        return None
    cc, include = _compiler(), _include()
    if cc is None or include is None:
        return None
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    h = hashlib.sha256()
    for part in (_source(), "\0".join(_command(cc, include)), suffix, sys.version,
                 str(_LAYOUT)):
        h.update(part.encode("utf-8", "surrogatepass"))
        h.update(b"\0")
    return cache_dir() / f"fis-{h.hexdigest()[:20]}{suffix}"


def _load(path: Path) -> Any:
    loader = importlib.machinery.ExtensionFileLoader(_MODULE, str(path))
    spec = importlib.util.spec_from_file_location(_MODULE, str(path), loader=loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    if getattr(mod, "LAYOUT", None) != _LAYOUT:
        raise ImportError(f"{path}: layout {getattr(mod, 'LAYOUT', None)}, expected {_LAYOUT}")
    return mod


def _compile(path: Path) -> bool:
    """Run the compiler into ``path`` (under ``sh``, which moves the result into place even if
    this process exits meanwhile). False if another process holds the build lock."""
    global _builds
    cc, include = _compiler(), _include()
    if cc is None or include is None:
        raise OSError("no C compiler or no Python.h")
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = path.with_name(path.name + ".lock")
    try:
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        try:
            if time.time() - lock.stat().st_mtime < _STALE_LOCK:
                return False
            lock.unlink()
        except FileNotFoundError:
            pass
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    os.close(fd)
    src = path.with_name(path.name + ".c")
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        src.write_text(_source(), encoding="utf-8")
    except BaseException:
        lock.unlink(missing_ok=True)
        raise
    script = ('tmp=$1; final=$2; lock=$3; shift 3; "$@" -o "$tmp"; rc=$?; '
              'if [ $rc -eq 0 ]; then mv -f "$tmp" "$final" || rc=$?; fi; '
              'rm -f "$tmp" "$lock"; exit $rc')
    _builds += 1
    log.debug("compiling the fuzzy C evaluator into %s", path)
    res = subprocess.run(["sh", "-c", script, "sh", str(tmp), str(path), str(lock),
                          *_command(cc, include), str(src)],
                         capture_output=True, text=True, check=False, timeout=600)
    if res.returncode != 0:
        raise OSError(f"compiler exit {res.returncode}: {res.stderr.strip()[:2000]}")
    return True


def _get(start: bool) -> Any:
    """The loaded module; or, when it is not in the cache: start a background build (if
    ``start``) and return None."""
    global _module, _state, _thread
    if _module is not None:
        return _module
    if _state in ("failed", "off"):
        return None
    with _lock:
        if _module is not None or _state in ("failed", "off"):
            return _module
        path = library_path()
        if path is None:
            _state = "off" if not _enabled() else "failed"
            log.debug("no C build of the fuzzy evaluator here (disabled, no compiler or no "
                      "Python.h): the Python path it is")
            return None
        if path.is_file():
            try:
                _module = _load(path)
                return _module
            except (ImportError, OSError) as exc:
                # removed, so that another process builds it again; this one gives up
                log.warning("the fuzzy C evaluator %s does not load (%s): the Python path it is",
                            path, exc)
                path.unlink(missing_ok=True)
                _state = "failed"
                return None
        if start and _state == "idle":
            _state = "building"
            _thread = threading.Thread(target=_background, args=(path,),
                                       name="hybridnav-fuzzy-native", daemon=True)
            _thread.start()
    return None


def _background(path: Path) -> None:
    global _state
    try:
        _compile(path)   # False: another process is building it; the next _get finds it
        state = "idle"
    except (OSError, subprocess.SubprocessError) as exc:
        log.debug("building the fuzzy C evaluator failed: %s", exc)
        state = "failed"
    with _lock:
        _state = state


def build(wait: bool = True, timeout: float = 600.0) -> bool:
    """Load the compiled module, building it first if it is not in the cache.

    Parameters
    ----------
    wait : bool
        Wait for the build (else only start it in the background).
    timeout : float
        Seconds to wait at most (for this process's build or another's).

    Returns
    -------
    bool
        Whether the module is loaded.
    """
    deadline = time.monotonic() + timeout
    while _get(start=True) is None:
        if not wait or _state in ("failed", "off") or time.monotonic() > deadline:
            return False
        t = _thread
        if t is not None:
            t.join(max(0.0, deadline - time.monotonic()))
        if _get(start=False) is None:
            time.sleep(0.1)  # another process holds the build lock: it will be there soon
    return True


def available() -> bool | None:
    """Whether the C evaluator is loaded (True), never will be in this process (False), or may
    be later (None: not built yet, or being built).

    Returns
    -------
    bool or None
    """
    if _module is not None:
        return True
    if _state in ("failed", "off") or not _enabled():
        return False
    return None


# ----------------------------------------------------------------------------- the tables

def _pack(eng) -> tuple[bytes, bytes]:
    """The engine's scalar-path tables in the flat layout ``_native.c`` reads (``hn_parse``)."""
    ints: list[int] = []           # the data region, after the header and the records
    dbl: list[float] = [float(eng.default), float(eng._tiny_area)]

    def D(values) -> int:
        dbl.extend(float(v) for v in values)
        return len(dbl) - len(values)

    n_in = len(eng._in_py)
    T = len(eng.out_terms)
    subs = eng._subsets_py
    n_rec = 5 * n_in + 3 * len(eng._prog) + 2 + 2 * T + 5 + 6 * len(subs) + 3 * T
    base = _HEADER + n_rec

    def Iv(values) -> int:
        ints.extend(int(v) for v in values)
        return base + len(ints) - len(values)

    rec: list[int] = []
    for _lo, _hi, xs, F, S in eng._in_py:
        nt = len(F[0])
        rec += [len(xs), nt, D(xs), D([v for row in F for v in row]),
                D([v for row in S for v in row])]
    for op, kids in eng._prog:
        rec += [op, len(kids), Iv(kids)]
    rec += [Iv(eng._root_list), D(eng._weight_list)]
    for b in eng._cut_lists:
        rec += [len(b), Iv(b)]
    xs, Fo, So = eng._out_py
    M = len(xs)
    W = D(eng._W.ravel().tolist()) if not subs else -1
    rec += [Iv([1 if p else 0 for p in eng.out_positive]), D(xs),
            D([v for row in Fo for v in row]), D([v for row in So for v in row]), W]
    for sign, sub, lv, Pa, Pm, Qa, Qm in subs:
        rec += [1 if sign > 0 else -1, len(sub), Iv(sub), len(lv), D(lv), D(Pa + Pm + Qa + Qm)]
    for lv, table in zip(eng._levels_py, eng._tables_py):
        starts = [0]
        for row in table:
            starts.append(starts[-1] + len(row))
        data_at = base + len(ints) + len(starts)   # the rows follow their start offsets
        rows = Iv([data_at + s for s in starts])
        Iv([i for row in table for i in row])
        rec += [len(lv), D(lv), rows]
    assert len(rec) == n_rec
    header = [_LAYOUT, n_in, eng.n_leaves, len(eng._prog), len(eng._root_list), T, len(subs), M,
              eng.n_slots] + [0] * (_HEADER - 9)
    return (np.array(header + rec + ints, dtype=np.int64).tobytes(),
            np.array(dbl, dtype=np.float64).tobytes())


def _probe_inputs(eng) -> list[list[float]]:
    """A few inputs to check a new evaluator with: the ranges' ends, middles and inside points."""
    rng = np.random.default_rng(12345)
    cols = []
    for lo, hi, *_ in eng._in_py:
        cols.append([lo, hi, 0.5 * (lo + hi), *rng.uniform(lo, hi, 7).tolist()])
    k = len(cols[0])
    return [[c[(j + 3 * i) % k] for i, c in enumerate(cols)] for j in range(k)]


def evaluator(eng, names: tuple[str, ...], start: bool = True) -> tuple[Any, bool]:
    """The C evaluator of one compiled system, if the module is ready.

    Parameters
    ----------
    eng : CompiledSystem
    names : tuple of str
        The input names (the keywords ``Evaluator.kw`` looks up).
    start : bool
        Start a background build if the module is not in the cache.

    Returns
    -------
    evaluator, retry
        ``(Evaluator, False)``; or ``(None, True)``: not yet (ask again later); or
        ``(None, False)``: never (no compiler, disabled, too large a system, or a check against
        the Python path failed).
    """
    mod = _get(start)
    if mod is None:
        return None, available() is None
    try:
        ints, dbl = _pack(eng)
        ev = mod.Evaluator(tuple(names), np.float64, ints, dbl)
    except (ValueError, TypeError, OverflowError) as exc:
        log.debug("no C evaluator for this system: %s", exc)
        return None, False
    for x in _probe_inputs(eng):
        want, got = eng.evaluate_scalar(x), ev.scalar(x)
        if got is not None and not (got == want or (math.isnan(got) and math.isnan(want))):
            log.warning("the fuzzy C evaluator gives %r where the Python path gives %r at %r: "
                        "keeping the Python path (compiler flags not honoured?)", got, want, x)
            return None, False
    return ev, False
