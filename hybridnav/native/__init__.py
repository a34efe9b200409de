"""Compiled kernels: C sources shipped with the package, built once per machine with the system C
compiler and loaded through :mod:`ctypes`.

:func:`build` compiles a source (plus generated code, e.g. a model step from CasADi's code
generator) into a shared library in the cache folder (:func:`cache_dir`) named by the hash of the source, the compiler and its flags, so
every process of a job (workers included) loads the same file and a changed source is rebuilt.
The file is written to a temporary name, synced and renamed, with its SHA-256 beside it: two
processes building at once both end up with a whole library, and a truncated or foreign file in
the cache (which would crash the process that loads it) is built again instead of loaded. Without a compiler, or with ``HYBRIDNAV_NATIVE=0``, :func:`build` returns
``None`` and callers use their NumPy path (same results to rounding, slower).
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
import threading
from importlib import resources
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

__all__ = ["ENV", "build", "build_file", "build_path", "cache_dir", "enabled", "source"]

FLAGS = ("-O3", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math")
_LOADED: dict[str, ctypes.CDLL | None] = {}
_LOCK = threading.Lock()


#: ``HYBRIDNAV_NATIVE=0`` (or ``off``, ``no``, ``false``) switches every compiled kernel off
ENV = "HYBRIDNAV_NATIVE"


def enabled() -> bool:
    """Whether compiled kernels may be used (``HYBRIDNAV_NATIVE=0`` switches them off)."""
    return os.environ.get(ENV, "1").strip().lower() not in ("0", "false", "no", "off")


def cache_dir() -> Path:
    """Where built libraries are kept (not created here): ``$HYBRIDNAV_CACHE_DIR/native``, else
    ``$XDG_CACHE_HOME/hybridnav/native``, else ``~/.cache/hybridnav/native``."""
    root = os.environ.get("HYBRIDNAV_CACHE_DIR")
    if not root:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(xdg, "hybridnav")
    return Path(root) / "native"


def source(name: str) -> str:
    """The text of a C source shipped in this package."""
    return resources.files(__name__).joinpath(name).read_text(encoding="utf-8")


def build(name: str, code: str, libs: tuple[str, ...] = ()) -> ctypes.CDLL | None:
    """The library compiled from ``code`` (loaded once per process), or ``None`` where it cannot
    be built or loaded (no compiler, a compile error — logged —, a library in ``libs`` missing or
    lacking a symbol the code uses, or kernels switched off). ``libs`` are extra options after the
    source (libraries such as ``-lmvec``, linked before ``-lm``)."""
    if not enabled():
        return None
    key = _key(name, code, libs, ".so")
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
        target = _build(key, code, libs, ".so")
        lib = None
        if target is not None:
            try:
                lib = ctypes.CDLL(str(target))
            except OSError as exc:
                log.info("cannot load %s: %s", target, exc)
        _LOADED[key] = lib
        return lib


_KERNELS: dict[str, ctypes.CDLL | None] = {}


def kernel(name: str, signatures: dict[str, tuple[list, Any]]) -> ctypes.CDLL | None:
    """The shipped C source ``<name>.c`` built and loaded once per process, its functions typed
    by ``signatures`` (symbol -> (argtypes, restype)); ``None`` where kernels are switched off or
    unavailable, or the library lacks one of the symbols."""
    if not enabled():
        return None
    if name not in _KERNELS:
        lib = build(name, source(f"{name}.c"))
        try:
            for symbol, (argtypes, restype) in signatures.items():
                if lib is not None:
                    fn = getattr(lib, symbol)
                    fn.argtypes, fn.restype = argtypes, restype
        except AttributeError:             # a library without the kernel's functions
            lib = None
        _KERNELS[name] = lib
    return _KERNELS[name]


def build_file(name: str, code: str, options: tuple[str, ...] = (),
               suffix: str = ".so") -> Path | None:
    """Compile ``code`` (unless already in the cache) into a shared object named ``suffix`` (e.g.
    a Python extension's) and return its path, without loading it; ``None`` where it cannot be
    built. ``options`` go after the source (``-I...``, ``-D...``, libraries)."""
    if not enabled():
        return None
    with _LOCK:
        return _build(_key(name, code, options, suffix), code, options, suffix)


def build_path(name: str, code: str) -> Path | None:
    """The file of the library compiled from ``code`` (built once per machine), for loaders other
    than :mod:`ctypes` (CasADi's ``external``); ``None`` where it cannot be built. Unlike
    :func:`build_file` this does not look at ``HYBRIDNAV_NATIVE``: CasADi's compiled functions
    have their own switch (``HYBRIDNAV_JIT``)."""
    # -z defs: a symbol the code uses that no library defines (CasADi's generated code calls
    # an erfinv that glibc lacks) fails the build instead of the process at the first call
    # ("symbol lookup error": the library is loaded lazily)
    options = ("-Wl,-z,defs",)
    with _LOCK:
        return _build(_key(name, code, options, ".so"), code, options)


def _key(name: str, code: str, options: tuple[str, ...], suffix: str) -> str:
    compiler = os.environ.get("CC", "gcc")
    parts = (code, compiler, *FLAGS, *options) + ((suffix,) if suffix != ".so" else ())
    return f"{name}-{hashlib.sha256(chr(0).join(parts).encode()).hexdigest()[:20]}"


def _sidecar(target: Path) -> Path:
    return target.with_name(target.name + ".sha256")


def _intact(target: Path) -> bool:
    """Whether a cached library is the file that was built (its SHA-256 recorded beside it)."""
    try:
        want = _sidecar(target).read_text(encoding="ascii").strip()
        return hashlib.sha256(target.read_bytes()).hexdigest() == want
    except OSError:
        return False


@contextlib.contextmanager
def _locked(folder: Path, key: str):
    """Hold an exclusive lock on ``key`` across processes sharing the cache (two workers that
    build or check the same library at once would otherwise see each other's half-written
    pair of files and rebuild it); without ``fcntl`` or a writable folder, no lock."""
    try:
        import fcntl

        folder.mkdir(parents=True, exist_ok=True)
        fh = open(folder / f".{key}.lock", "a+")
    except (ImportError, OSError):
        yield
        return
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        yield
    finally:
        fh.close()                                  # releases the lock


def _build(key: str, code: str, options: tuple[str, ...] = (),
           suffix: str = ".so") -> Path | None:
    folder = cache_dir()
    with _locked(folder, key):
        return _build_locked(key, code, options, suffix, folder)


def _build_locked(key: str, code: str, options: tuple[str, ...], suffix: str,
                  folder: Path) -> Path | None:
    compiler = os.environ.get("CC", "gcc")
    target = folder / f"{key}{suffix}"
    if target.exists() and not _intact(target):
        # a truncated or foreign file would crash the process inside dlopen: build it again
        log.warning("%s does not match its recorded hash: building it again", target)
        for p in (target, _sidecar(target)):
            p.unlink(missing_ok=True)
    if not target.exists():
        if shutil.which(compiler) is None:
            log.info("no C compiler (%s): compiled kernels unavailable", compiler)
            return None
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:
                src = Path(tmp) / f"{key}.c"
                src.write_text(code, encoding="utf-8")
                out = Path(tmp) / f"{key}{suffix}"
                proc = subprocess.run([compiler, *FLAGS, "-o", str(out), str(src), *options,
                                       "-lm"], capture_output=True, text=True, timeout=300)
                if proc.returncode != 0:
                    log.warning("compiling %s failed: %s", key, proc.stderr.strip()[-2000:])
                    return None
                data = out.read_bytes()
                with open(out, "rb+") as fh:             # on disk before it gets its name
                    os.fsync(fh.fileno())
                side = Path(tmp) / "hash"
                side.write_text(hashlib.sha256(data).hexdigest(), encoding="ascii")
                os.replace(out, target)
                os.replace(side, _sidecar(target))
        except (OSError, subprocess.SubprocessError) as exc:
            log.info("compiled kernel %s unavailable: %s", key, exc)
            return None
    return target
