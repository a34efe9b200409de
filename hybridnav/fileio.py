"""Files: atomic writing (a temporary file in the target's folder, then ``os.replace``), JSON, and
reading user files as text and TOML with every failure a :class:`HybridnavError` naming the file."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import socket
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.params import short_repr

__all__ = ["LOCK_NAME", "MAX_FILE_BYTES", "MAX_ROBOT_NAME", "SAFE_NAME", "TEMPORARY_NAME",
           "atomic_path", "check_writable",
           "atomic_write_bytes", "atomic_write_text", "clean_temporaries", "decode_text",
           "dumps_json", "json_ready", "locked_folder", "parse_toml", "read_json", "read_text_file",
           "short_text", "show_key", "shown_path"]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path`` atomically.

    The temporary file keeps ``path``'s suffix so that writers which pick a format from the name
    (matplotlib's ``savefig``) still work. On an exception the temporary file is removed and
    ``path`` is left as it was.
    """
    path = Path(path)
    made = _missing_folders(path.parent)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                   dir=path.parent)
    except OSError as exc:
        _remove_empty(made)
        raise _cannot_write(path, exc) from None
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600 files; give the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        _remove_empty(made)            # a failed write leaves no folder it made either
        if isinstance(exc, OSError) and not isinstance(exc, HybridnavError):
            raise _cannot_write(path, exc) from None
        raise


def _missing_folders(folder: Path) -> list[Path]:
    """The folders ``folder.mkdir(parents=True)`` would make, innermost first."""
    missing = []
    while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def _remove_empty(folders: list[Path]) -> None:
    """Remove ``folders`` (innermost first) where empty: what a failed writer made."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return                     # not empty (another writer's), or gone: stop here


def check_writable(path: str | os.PathLike) -> None:
    """Raise a :class:`HybridnavError` unless a file could be written at ``path`` (its folder
    made where missing), without writing or making anything: for commands that run for a while
    before they write (``hybridnav animate``).

    Parameters
    ----------
    path : str or path-like
        The file to be written.

    Raises
    ------
    HybridnavError
        ``path`` is a folder, a part of it is a file, or its nearest existing folder cannot be
        written.
    """
    path = Path(path)
    if path.is_dir():
        raise HybridnavError(f"{shown_path(path)}: cannot write (it is a folder; expected a "
                             "file name)")
    folder = path.parent
    while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise HybridnavError(f"{shown_path(path)}: cannot write ({shown_path(folder)} is not a "
                             "folder)")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise HybridnavError(f"{shown_path(path)}: cannot write (no permission to write in "
                             f"{shown_path(folder)})")


def _cannot_write(path: Path, exc: OSError) -> HybridnavError:
    """A write failure (full disk, read-only folder, ...) named by the file hybridnav was writing,
    not by its temporary file."""
    return HybridnavError(f"{path}: cannot write ({exc.strerror or exc}); nothing was replaced")


#: The names :func:`atomic_path` gives its temporary files: a dot, the target's name,
#: ``tempfile.mkstemp``'s 8 random characters, ``.tmp`` and the target's suffix; only these are
#: temporaries.
TEMPORARY_NAME = re.compile(r"^\.(?P<name>.+)\.[a-z0-9_]{8}\.tmp(\.[A-Za-z0-9]+)?$")


def clean_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporary files a killed writer left in ``folder`` (not in its sub-folders).

    Only names :func:`atomic_path` makes (:data:`TEMPORARY_NAME`) and only regular files are
    removed; call it only while holding the folder's lock (:func:`locked_folder`), so no live
    writer owns them.

    Returns
    -------
    list of Path
        The files removed.
    """
    gone = []
    folder = Path(folder)
    if not folder.is_dir():
        return gone
    for tmp in folder.iterdir():
        if TEMPORARY_NAME.match(tmp.name) and tmp.is_file() and not tmp.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
                gone.append(tmp)
    return gone


#: The lock file a job keeps in the folder it writes (see :func:`locked_folder`).
LOCK_NAME = ".hybridnav.lock"


@contextlib.contextmanager
def locked_folder(folder: str | os.PathLike, command: str) -> Iterator[Path]:
    """Hold ``folder`` for one job: a second job writing the same folder is refused.

    The lock is an exclusive ``flock`` on the file :data:`LOCK_NAME` in ``folder`` (made when
    missing), which holds the owner's pid, host, command and start time for the other job's
    message. The kernel releases it when the owner ends, however it ends (a killed job leaves
    no lock to clean up); the file is removed when the block ends. A folder this call made is
    removed again when the job wrote nothing in it.

    Parameters
    ----------
    folder : str or path-like
    command : str
        What holds the lock, for the other job's message (e.g. ``"tune job.toml"``).

    Yields
    ------
    Path
        The folder.

    Raises
    ------
    HybridnavError
        The folder cannot be made or written (read-only, full disk), the lock file is not a
        regular file, or another job holds the lock (its pid, host, command and start time
        named).
    """
    import fcntl
    import stat

    folder = Path(folder)
    lock = folder / LOCK_NAME
    made = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HybridnavError(f"{shown_path(folder)}: cannot make the output folder "
                             f"({exc.strerror or exc})") from None
    owner = {"pid": os.getpid(), "host": socket.gethostname(), "command": command[:200],
             "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    for _ in range(20):
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NONBLOCK | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            raise HybridnavError(f"{shown_path(folder)}: cannot write in the output folder "
                                 f"({exc.strerror or exc})") from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise HybridnavError(f"{shown_path(lock)}: expected the lock file of a hybridnav "
                                     "job (a regular file); remove it")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                held = _lock_owner(fd)
                raise HybridnavError(
                    f"{shown_path(folder)}: another hybridnav job is writing this folder (pid "
                    f"{held.get('pid')} on {held.get('host')}, "
                    f"{short_text(str(held.get('command')), 200)!r}, since {held.get('started')}"
                    "); wait for it to end or choose another output folder") from None
            # the file may have been removed by its previous owner after we opened it: the
            # lock counts only on the file the path names now
            try:
                same = os.stat(lock, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, (json.dumps(owner) + "\n").encode("utf-8"))
        except BaseException:
            with contextlib.suppress(OSError):
                os.close(fd)
            raise
        break
    else:
        raise HybridnavError(f"{shown_path(lock)}: could not take the folder's lock (it keeps "
                             "being replaced)")
    try:
        yield folder
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()                        # while still holding it: see the inode check
        with contextlib.suppress(OSError):
            os.close(fd)
        if made:                                 # a job that failed before writing: no trace
            with contextlib.suppress(OSError):
                folder.rmdir()                   # only when empty


def short_text(text: str, limit: int) -> str:
    """``text`` cut to about ``limit`` characters (its start and end kept)."""
    return text if len(text) <= limit else f"{text[:limit - 30]}...{text[-20:]}"


def _lock_owner(fd: int) -> dict[str, Any]:
    """What the lock holder wrote into the lock file (placeholders when unreadable)."""
    try:
        data = json.loads(os.pread(fd, 65536, 0).decode("utf-8"))
    except (OSError, ValueError):
        data = None
    if not isinstance(data, dict):
        return {"pid": "?", "host": "?", "command": "?", "started": "?"}
    return data


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (flushed to disk before the rename)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def json_ready(obj: Any) -> Any:
    """Recursively convert NumPy scalars/arrays to Python, and non-finite floats to ``None``.

    JSON has no NaN or infinity; hybridnav writes ``null`` for them (e.g. no clearance measured).
    """
    if isinstance(obj, dict):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_ready(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


def dumps_json(obj: Any) -> str:
    """``json.dumps`` of :func:`json_ready` (indented, strict: no NaN), with a final newline."""
    return json.dumps(json_ready(obj), indent=2, allow_nan=False) + "\n"


#: A name that becomes part of a file name or a CSV header (robots' trajectory files, result
#: extras, columns): letters, digits, ``_``, ``-`` and ``.``, no path separator; test it with
#: ``SAFE_NAME.fullmatch`` (``$`` alone would let a final newline through).
SAFE_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,128}$")
#: Longest robot name: its files add prefixes (``swarm_best_``) and suffixes to it
MAX_ROBOT_NAME = 100

#: Largest input file read (scenarios, jobs, fuzzy systems, maps): 64 MiB.
MAX_FILE_BYTES = 64 * 2**20


def read_text_file(path: str | os.PathLike, what: str) -> str:
    """The UTF-8 text of a file, or a :class:`HybridnavError` naming it.

    Parameters
    ----------
    path : str or path-like
    what : str
        What the file is, for the message (e.g. ``"scenario file"``).

    Raises
    ------
    HybridnavError
        The file cannot be read, is larger than :data:`MAX_FILE_BYTES`, or is not UTF-8 text
        (binary, UTF-16, ...: the message gives the offset of the first bad byte).
    """
    import stat

    p = Path(path)
    try:
        # non-blocking: a FIFO or a device is refused instead of waiting for a writer
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)
        with open(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise HybridnavError(f"{shown_path(p)}: expected a regular {what}, got a "
                                     f"{'folder' if p.is_dir() else 'pipe, device or socket'}")
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise HybridnavError(f"{shown_path(p)}: cannot read {what} ({exc.strerror or exc})") \
            from None
    if len(data) > MAX_FILE_BYTES:
        raise HybridnavError(f"{p}: {what} larger than {MAX_FILE_BYTES // 2**20} MiB; expected a "
                             "text file")
    return decode_text(data, str(p), what)


def shown_path(path: str | os.PathLike) -> str:
    """A path as messages show it: whole up to 200 characters, else its start and end."""
    s = os.fspath(path)
    return s if len(s) <= 200 else f"{s[:120]}...{s[-60:]} ({len(s)} characters)"


def decode_text(data: bytes, source: str, what: str) -> str:
    """``data`` as UTF-8 text (an initial byte-order mark dropped), or a :class:`HybridnavError`
    naming ``source``."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        hint = " (it looks like UTF-16)" if data[:2] in (b"\xff\xfe", b"\xfe\xff") else ""
        raise HybridnavError(f"{source}: not UTF-8 text: byte {exc.start} (0x{data[exc.start]:02x}) "
                             f"of the {what} cannot be decoded{hint}") from None
    if "\0" in text:
        raise HybridnavError(f"{source}: not text: the {what} contains a NUL byte at "
                             f"character {text.index(chr(0))}")
    return text.removeprefix("\ufeff")


def parse_toml(text: str, source: str, what: str = "file") -> dict[str, Any]:
    """Parse TOML text, or raise a :class:`HybridnavError` naming ``source``: syntax errors (with
    the line), nesting too deep for the parser, integers with more digits than Python converts."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HybridnavError(f"{source}: {what} is not valid TOML: {exc}") from None
    except RecursionError:
        raise HybridnavError(f"{source}: {what} nests arrays or tables too deeply to read "
                             "(expected at most a few levels)") from None
    except ValueError as exc:             # e.g. Python's 4300-digit limit for int("...")
        raise HybridnavError(f"{source}: {what} has a number that cannot be read: "
                             f"{str(exc).split(';')[0]}") from None


def show_key(key: Any) -> str:
    """A key as messages show it: a plain name as it is, anything else quoted and cut.

    Parameters
    ----------
    key : any
    """
    return key if isinstance(key, str) and SAFE_NAME.fullmatch(key) else short_repr(key, 40)


def read_json(path: str | os.PathLike, what: str) -> Any:
    """A JSON file as hybridnav writes them (:func:`dumps_json`), read strictly: every number
    finite and readable, no key given twice, else a :class:`HybridnavError` naming the file and
    the key.

    Python's ``json`` takes ``NaN`` and ``Infinity``, turns ``1e999`` into ``inf`` and raises
    ``ValueError`` for an integer past its digit limit (``sys.get_int_max_str_digits()``); here
    each is refused at its key (``robots[0].compute_time: expected a number as hybridnav writes
    them ...``). Integers beyond the float range (``10**400``) are read as they are: the caller's
    check of the key says what it expects (:func:`hybridnav.fuzzy.spec.finite_number`).

    Parameters
    ----------
    path : str or path-like
    what : str
        What the file is, for the messages (e.g. ``"result file"``).

    Raises
    ------
    HybridnavError
        What :func:`read_text_file` raises; invalid JSON (with line and column), nesting too deep
        for the parser, a number :func:`dumps_json` never writes, a duplicate key.
    """
    path = Path(path)
    text = read_text_file(path, what)
    try:
        data = json.loads(text, parse_int=_json_int, parse_float=_json_float,
                          parse_constant=_Unreadable, object_pairs_hook=_json_object)
    except json.JSONDecodeError as exc:
        raise HybridnavError(f"{path}: not valid JSON: {exc}") from None
    except RecursionError:
        raise HybridnavError(f"{path}: not valid JSON: nested too deeply (expected a "
                             f"{what} as hybridnav writes it)") from None
    stack: list[tuple[str, Any]] = [("", data)]
    while stack:                       # iterative: as deep as the JSON parser went
        key, value = stack.pop()
        if isinstance(value, _Unreadable):
            raise HybridnavError(f"{path}: {key or '(top level)'}: expected a number as "
                                 f"hybridnav writes them (finite, at most "
                                 f"{sys.get_int_max_str_digits() or 'any number of'} digits), got "
                                 f"{value.what}")
        if isinstance(value, _Duplicates):
            raise HybridnavError(f"{path}: {key or '(top level)'}: duplicate key "
                                 f"{short_repr(value.duplicate, 40)}")
        if isinstance(value, dict):
            stack.extend((f"{key}.{show_key(k)}" if key else show_key(k), v)
                         for k, v in reversed(value.items()))
        elif isinstance(value, list):
            stack.extend((f"{key}[{i}]", v) for i, v in reversed(list(enumerate(value))))
    return data


class _Unreadable:
    """A JSON number the writer never writes (NaN, Infinity, 1e999, an integer past Python's
    digit limit), kept in place so that the message can name its key."""

    def __init__(self, what: str) -> None:
        self.what = what


class _Duplicates(dict):
    """A JSON object with a key given twice (the first of them in ``duplicate``)."""

    duplicate: str = ""


def _json_int(text: str) -> Any:
    try:
        return int(text)
    except ValueError:                 # Python's 4300-digit limit
        return _Unreadable(f"an integer of {len(text.lstrip('-'))} digits")


def _json_float(text: str) -> Any:
    value = float(text)
    return value if math.isfinite(value) else _Unreadable(f"{short_repr(text, 40)} (beyond "
                                                          "the float range)")


def _json_object(pairs: list[tuple[str, Any]]) -> dict:
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    dup = _Duplicates(out)
    seen: set[str] = set()
    for k, _ in pairs:
        if k in seen:
            dup.duplicate = k
            break
        seen.add(k)
    return dup
