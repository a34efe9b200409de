"""Compile C and run it in a child process with limits: never in the hybridnav process.

What :class:`~hybridnav.fuzzy.export.sil.CompiledFIS` uses to build and call a C export (and
any C it is told to trust). :func:`check_includes` refuses ``#include`` of absolute paths, of
``..`` and of macro-computed names before anything is compiled. :func:`compile_program` writes
the checked text into a fresh folder and compiles it there with a time limit, no standard input,
resource limits and its own process group (killed whole on a timeout); a failure is reported as
the location and kind of the first error, never as the compiler's full text (which can quote
other files: a hostile file makes the compiler print lines of whatever it names). A
:class:`Child` runs the program in its own session with CPU, memory and file-size limits and
exchanges bytes with it over pipes, each exchange under a time limit after which its process
group is killed; a child that dies is reported with its signal or status.
"""

from __future__ import annotations

import math
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path, PurePosixPath

from hybridnav.errors import HybridnavError

__all__ = ["COMPILE_TIMEOUT", "CALL_TIMEOUT", "CHILD_CPU_SECONDS", "check_includes",
           "compile_program", "Child"]

#: Seconds a compilation may take (wall clock; the compiler's processes are killed after it).
COMPILE_TIMEOUT = 60.0
#: Seconds a child may take to answer one exchange (default of :class:`Child`).
CALL_TIMEOUT = 10.0
#: CPU seconds a child may use in all: the limit that ends a child stuck in a loop whose parent
#: died before it could kill it.
CHILD_CPU_SECONDS = 600
_CHILD_MEMORY = 2**30                  # address space of a child (RLIMIT_AS)
_COMPILE_MEMORY = 4 * 2**30            # ... of each compiler process
_FILE_SIZE = 2**28                     # largest file either may write (RLIMIT_FSIZE)

_TRIGRAPHS = {"=": "#", "/": "\\", "'": "^", "(": "[", ")": "]", "!": "|", "<": "{", ">": "}",
              "-": "~"}
_DIRECTIVE = re.compile(r"^[ \t\f\v]*#[ \t\f\v]*(include_next|include|import|embed)\b(.*)$",
                        re.M)
_HEADER_NAME = re.compile(r'[ \t\f\v]*(?:"([^"]*)"|<([^>]*)>)[ \t\f\v]*\Z')


def _logical_text(text: str) -> str:
    """``text`` as the preprocessor reads directives: trigraphs and ``%:`` replaced, line
    splices joined and comments made a space; the newlines a splice or comment removed are
    added after its logical line, so line numbers stay those of the file."""
    text = re.sub(r"\?\?([=/'()!<>-])", lambda m: _TRIGRAPHS[m.group(1)], text)
    text = text.replace("%:", "#")
    lines: list[str] = []
    pending = ""
    joined = 0
    for line in text.split("\n"):
        stripped = line.rstrip(" \t\r")
        if stripped.endswith("\\"):          # gcc also splices a backslash before spaces
            pending += stripped[:-1]
            joined += 1
            continue
        lines.append(pending + line + "\n" * joined)
        pending, joined = "", 0
    if pending:
        lines.append(pending + "\n" * joined)
    text = "\n".join(lines)
    out: list[str] = []
    newlines = 0
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            end = n if end < 0 else end + 2
            newlines += text.count("\n", i, end)
            out.append(" ")
            i = end
        elif text.startswith("//", i):
            end = text.find("\n", i)
            i = n if end < 0 else end
        elif c in "\"'":                     # a literal ends at its quote or at the line's end
            j = i + 1
            while j < n and text[j] not in (c, "\n"):
                j += 2 if text[j] == "\\" else 1
            j = min(j, n)
            out.append(text[i:j + 1] if j < n and text[j] == c else text[i:j])
            i = j + 1 if j < n and text[j] == c else j
        elif c == "\n":
            out.append("\n" * (1 + newlines))
            newlines = 0
            i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def check_includes(text: str, where: str) -> None:
    """Refuse C whose preprocessor would read a file named by an absolute path, through
    ``..``, or by a macro (a name that cannot be checked before compiling).

    Parameters
    ----------
    text : str
        C source or header text.
    where : str
        The file, for the message.

    Raises
    ------
    HybridnavError
        Naming the line and the kind of name (the name itself is not quoted). ``#include``,
        ``#include_next``, ``#import`` and ``#embed`` are checked as the preprocessor reads them:
        through comments, line splices, trigraphs and digraphs.
    """
    logical = _logical_text(text)
    for m in _DIRECTIVE.finditer(logical):
        line = logical.count("\n", 0, m.start()) + 1
        name = _HEADER_NAME.match(m.group(2))
        if name is None:
            problem = "a computed (macro) or malformed name"
        else:
            path = PurePosixPath(name.group(1) if name.group(1) is not None else name.group(2))
            problem = ("an empty name" if not str(path) or str(path) == "." else
                       "an absolute path" if path.is_absolute() or str(path).startswith("~")
                       else "a '..' component" if ".." in path.parts else "")
        if problem:
            raise HybridnavError(
                f"{where}: line {line}: #{m.group(1)}: expected a header named relative to the "
                f"file or the system's include folders (\"name.h\" or <name.h>), got {problem}; "
                "nothing was compiled")


#: Sets the limits given in argv[1], then executes argv[2:]: a fresh, isolated interpreter
#: (``-I -S``) between fork and the program, where ``preexec_fn`` would run Python code in a
#: forked copy of a process that may have threads (unsafe: it can deadlock).
_LAUNCHER = ("import os, resource, sys\n"
             "v = [int(x) for x in sys.argv[1].split(',')]\n"
             "for k in range(0, len(v), 3):\n"
             "    try:\n"
             "        resource.setrlimit(v[k], (v[k + 1], v[k + 2]))\n"
             "    except (ValueError, OSError):\n"     # a limit this system does not take
             "        pass\n"
             "os.execvp(sys.argv[2], sys.argv[2:])\n")


def _limited(argv: Sequence[str], cpu: int, memory: int, fsize: int) -> list[str]:
    """``argv`` run with CPU, address-space and file-size limits and no core files (each at
    most the current hard limit)."""
    import resource

    plan = []
    for res, value in ((resource.RLIMIT_CPU, cpu), (resource.RLIMIT_AS, memory),
                       (resource.RLIMIT_FSIZE, fsize), (resource.RLIMIT_CORE, 0)):
        hard = resource.getrlimit(res)[1]
        # CPU: the soft limit sends SIGXCPU (named in messages), the hard one a second later SIGKILL
        top = value + 1 if res == resource.RLIMIT_CPU else value
        if hard != resource.RLIM_INFINITY:
            value, top = min(value, hard), min(top, hard)
        plan += [res, value, top]
    if not sys.executable:
        raise HybridnavError("cannot start a child process with limits: no Python interpreter "
                             "path (sys.executable) to start it with")
    return [sys.executable, "-I", "-S", "-c", _LAUNCHER, ",".join(map(str, plan)), *argv]


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the process group of ``proc`` (its own session: it and what it started), then
    reap it. Only while ``proc`` is not reaped: until then no other group can have its id."""
    if proc.returncode is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:  # pragma: no cover - a SIGKILLed process exits
        pass


def _exit_status(proc: subprocess.Popen, wait: float) -> int | None:
    """``proc``'s exit status (``-signal`` if killed) once it has exited, within ``wait``
    seconds, without reaping it (so that its group can still be killed); None if it runs on."""
    if not hasattr(os, "waitid"):           # (macOS) reaped: its group is then left alone
        try:
            return proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            return None
    deadline = time.monotonic() + wait
    while True:
        info = os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT | os.WNOHANG)
        if info is not None:
            return info.si_status if info.si_code == os.CLD_EXITED else -info.si_status
        if time.monotonic() > deadline:
            return None
        time.sleep(0.005)


def _quoted_cut(text: str) -> str:
    """A compiler message with whatever it quotes replaced (quoted text is file content)."""
    text = re.sub(r"[`'\"\u2018\u201c][^`'\"\u2019\u201d]*[`'\"\u2019\u201d]", "'...'", text)
    return text if len(text) <= 160 else text[:157] + "..."


def _first_error(stderr: str, names: Mapping[str, str]) -> str:
    """Location and kind of the compiler's first error: the message only where it is in one of
    ``names`` (folder path -> the name to show), quoted parts removed; elsewhere the file and
    line alone."""
    for raw in stderr.splitlines():
        m = re.match(r"(.+?):(\d+):(?:(\d+):)? *(?:fatal )?error: *(.*)", raw)
        if m:
            file, line, col, msg = m.groups()
            loc = f"{line}:{col}" if col else line
            if file in names:
                return f"{names[file]}:{loc}: {_quoted_cut(msg)}"
            return f"an error at line {line} of {file} (a file it includes or names)"
    for raw in stderr.splitlines():
        if any(w in raw for w in ("undefined reference", "multiple definition", "error")):
            for path, shown in names.items():
                raw = raw.replace(path, shown)
            return f"link error: {_quoted_cut(raw)}"
    return "no error message"


def compile_program(files: Mapping[str, str], where: str, *,
                    shown: Mapping[str, str] | None = None,
                    timeout: float = COMPILE_TIMEOUT) -> Path:
    """Compile and link ``files`` into an executable, in a fresh folder, in limited child
    processes.

    Parameters
    ----------
    files : mapping of str to str
        Relative file name (``"c/effc.c"``) to text; the ``.c`` files are compiled (C99, ``-O2``)
        and linked with ``-lm``. The text is written as given: what was checked is compiled.
    where : str
        Named in error messages.
    shown : mapping of str to str, optional
        Relative file name to the name an error message shows (default: the name itself).
    timeout : float
        Seconds the compiler may take.

    Returns
    -------
    pathlib.Path
        The executable; the caller removes its folder (``path.parent``) when done.

    Raises
    ------
    HybridnavError
        No C compiler (``CC``, or ``gcc``/``cc`` on ``PATH``), the time limit passed, or a
        compilation error (its location and kind: see the module's description).
    """
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if cc is None or shutil.which(cc) is None:
        raise HybridnavError(f"{where}: no C compiler to build it with (set CC, or install gcc)")
    folder = Path(tempfile.mkdtemp(prefix="hybridnav-sil-"))
    names = {}
    try:
        for name, text in files.items():
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            names[str(path)] = (shown or {}).get(name, name)
        exe = folder / "program"
        cmd = [cc, "-std=c99", "-O2", "-o", str(exe),
               *(str(folder / n) for n in files if n.endswith(".c")), "-lm"]
        env = {**os.environ, "LC_ALL": "C", "LANG": "C"}
        proc = subprocess.Popen(_limited(cmd, math.ceil(timeout), _COMPILE_MEMORY, _FILE_SIZE),
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, cwd=folder, env=env,
                                start_new_session=True)
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            try:
                proc.communicate(timeout=5)
            except subprocess.TimeoutExpired:  # pragma: no cover - a process left the group
                pass
            raise HybridnavError(f"{where}: expected to compile within {timeout:g} s, took "
                                 "longer (the compiler was stopped)") from None
        if proc.returncode != 0:
            text = err.decode("utf-8", errors="replace")
            raise HybridnavError(f"{where}: does not compile: {_first_error(text, names)}")
        return exe
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


def _end(proc: subprocess.Popen, fds: tuple[int, int], owner: int) -> None:
    if os.getpid() != owner:     # a forked copy of the parent: the child is not its to end
        return
    _kill_group(proc)
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass


class Child:
    """A program running in a child process of its own session, with limits, spoken to over
    pipes: :meth:`exchange` writes bytes and reads a reply of a known size, within a time limit.

    Parameters
    ----------
    argv : sequence of str
        The program and its arguments. Two more arguments follow them: the numbers of the file
        descriptors it reads requests from and writes replies to (not its standard input and
        output: what the C prints does not get into the replies).
    where : str
        Named in error messages (the C file).
    timeout : float
        Seconds each exchange may take.
    cwd : path-like, optional
        Its working folder.

    Notes
    -----
    The child's standard input, output and error are ``/dev/null``; its limits are
    :data:`CHILD_CPU_SECONDS` of CPU, 1 GiB of address space, 256 MiB files, no core file. It
    is killed (with everything it started) on a timeout, by :meth:`close`, and when the object
    is collected or the interpreter exits.
    """

    def __init__(self, argv: Sequence[str], where: str, *, timeout: float = CALL_TIMEOUT,
                 cwd: str | os.PathLike[str] | None = None) -> None:
        if not timeout > 0:
            raise HybridnavError(f"{where}: timeout: expected a positive number of seconds, got "
                                 f"{timeout!r}")
        self.where = where
        self.timeout = float(timeout)
        requests, self._w = os.pipe()
        self._r, replies = os.pipe()
        try:
            self._proc = subprocess.Popen(
                _limited([*argv, str(requests), str(replies)], CHILD_CPU_SECONDS, _CHILD_MEMORY,
                         _FILE_SIZE),
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                pass_fds=(requests, replies), cwd=cwd, start_new_session=True)
        except BaseException:
            for fd in (self._w, self._r):
                os.close(fd)
            raise
        finally:                # the child's ends: its EOF and ours come when it holds the last
            os.close(requests)
            os.close(replies)
        os.set_blocking(self._w, False)
        self._poll = select.poll()
        self._failed: str | None = None
        self._finalizer = weakref.finalize(self, _end, self._proc, (self._w, self._r),
                                           os.getpid())
        self._lock = threading.Lock()

    def exchange(self, data: bytes, size: int, what: str) -> bytes:
        """Write ``data`` to the child and read ``size`` bytes of reply.

        Parameters
        ----------
        data : bytes
        size : int
            Bytes of the reply.
        what : str
            What the exchange does, for messages (``"evaluate"``).

        Returns
        -------
        bytes

        Raises
        ------
        HybridnavError
            No reply within the time limit (the child is killed), or the child died (its signal
            or exit status); every later exchange raises the same.
        """
        with self._lock:
            if self._failed is not None:
                raise HybridnavError(self._failed)
            try:
                return self._exchange(data, size, what)
            except HybridnavError:
                raise
            except BaseException:   # interrupted mid-exchange: the protocol is out of step
                self._failed = f"{self.where}: {what} was interrupted: its child process was ended"
                self._finalizer()
                raise

    def _exchange(self, data: bytes, size: int, what: str) -> bytes:
        deadline = time.monotonic() + self.timeout
        view = memoryview(data)
        out = bytearray()
        poll = self._poll
        try:
            if view:
                view = view[self._write(view):]
                if view:
                    poll.register(self._w, select.POLLOUT)
            if size:
                poll.register(self._r, select.POLLIN)
            while view or len(out) < size:
                left = deadline - time.monotonic()
                if left <= 0:
                    self._fail(f"{what} did not return within {self.timeout:g} s (the time "
                               "limit): its child process was killed")
                for fd, _ in poll.poll(math.ceil(left * 1000)):
                    if fd == self._w:
                        view = view[self._write(view):]
                        if not view:
                            poll.unregister(self._w)
                    else:
                        chunk = os.read(self._r, size - len(out))
                        if not chunk:
                            self._died(what)
                        out += chunk
                        if len(out) == size:
                            poll.unregister(self._r)
        except BrokenPipeError:
            self._died(what)
        finally:
            for fd in (self._w, self._r):
                try:
                    poll.unregister(fd)
                except KeyError:
                    pass
        return bytes(out)

    def _write(self, view: memoryview) -> int:
        try:
            return os.write(self._w, view)
        except BlockingIOError:
            return 0

    def _died(self, what: str) -> None:
        rc = _exit_status(self._proc, 1.0)
        if rc is None:                           # closed its output but lives on
            self._fail(f"{what} closed its output without an answer: its child process was "
                       "killed")
        assert rc is not None
        if rc < 0:
            try:
                name = signal.Signals(-rc).name
            except ValueError:
                name = str(-rc)
            limit = f" (its CPU limit is {CHILD_CPU_SECONDS} s)" if name in ("SIGXCPU",) else ""
            self._fail(f"{what} crashed with signal {name}{limit} in its child process")
        self._fail(f"{what}: its child process exited with status {rc} instead of answering")

    def _fail(self, message: str) -> None:
        """End the child (its whole group) and raise ``message``, now and on every later call."""
        self._failed = f"{self.where}: {message}"
        self._finalizer()
        raise HybridnavError(self._failed)

    def close(self) -> None:
        """End the child (and whatever it started); later exchanges raise."""
        if self._failed is None:
            self._failed = f"{self.where}: the child process was closed"
        self._finalizer()
