"""Progress for the command line: a tqdm bar on a terminal, plain lines otherwise.

In a log file (output redirected, CI) tqdm's carriage-return updates run together on one line;
:func:`bar` gives the same interface (``update``, ``set_postfix``, ``total``, ``n``, ``refresh``,
``close``) printing one line per tenth of the work (and the last), with the postfix.
:class:`PhaseLog` names each long phase of a command that has no count to show (``analyze``,
``tune`` after its optimizer, ``reproduce`` after its runs) and how long it took; on a terminal
the running phase's clock ticks.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, TextIO

__all__ = ["PhaseLog", "PlainProgress", "bar", "phase"]


class PlainProgress:
    """A progress counter writing whole lines to ``file`` (no carriage returns)."""

    def __init__(self, total: int, unit: str, desc: str, file: TextIO | None = None,
                 every: float = 0.1) -> None:
        self.total, self.unit, self.desc = total, unit, desc
        self.file = file if file is not None else sys.stderr
        self.every = every
        self.n = 0
        self.postfix: dict[str, Any] = {}
        self._shown = -1.0
        self._shown_n = 0
        self._t0 = time.perf_counter()
        self._closed = False

    def set_postfix(self, ordered_dict: dict[str, Any] | None = None, refresh: bool = True,
                    **kw: Any) -> None:
        """As tqdm's: ``ordered_dict`` and the keywords shown after the count; ``refresh``
        (tqdm's redraw) does nothing here."""
        self.postfix = {**(ordered_dict or {}), **kw}

    def refresh(self) -> None:
        pass

    def _frac(self) -> float:
        # no total: a line at each doubling (1, 2, 4, ...), not one per update
        return self.n / self.total if self.total else float(max(int(self.n), 0).bit_length())

    def update(self, k: int = 1) -> None:
        if self._closed:                     # as tqdm's: nothing after close()
            return
        self.n += k
        frac = self._frac()
        # the end once, not a line for each update past the total
        if (frac >= 1.0 and self._shown < 1.0) or frac - self._shown >= self.every - 1e-12:
            self._line()
            self._shown = frac

    def _line(self) -> None:
        extra = ", ".join(f"{k}={v}" for k, v in self.postfix.items())
        total = f"/{self.total}" if self.total else ""
        self._shown_n = self.n
        print(f"{self.desc}: {self.n}{total} {self.unit} "
              f"({time.perf_counter() - self._t0:.1f} s){'; ' + extra if extra else ''}",
              file=self.file, flush=True)

    def close(self) -> None:
        if not self._closed and self.n != self._shown_n:     # the last count, once
            self._line()
        self._closed = True


def bar(total: int, unit: str, desc: str, file: TextIO | None = None):
    """A tqdm bar when ``file`` (default stderr) is a terminal, else a :class:`PlainProgress`."""
    file = file if file is not None else sys.stderr
    if getattr(file, "isatty", lambda: False)():
        from tqdm import tqdm

        return tqdm(total=total, unit=unit, desc=desc, file=file)
    return PlainProgress(total, unit, desc, file=file)


def phase(msg: str, file: TextIO | None = None) -> None:
    """One line naming a long phase as it starts (``"  <msg> ..."``)."""
    print(f"  {msg} ...", file=file if file is not None else sys.stdout, flush=True)


class PhaseLog:
    """``say(message)`` at the start of each phase: the phase before it ends there.

    Each phase gets a line ``"  <message> ... <seconds> s"`` once it ends. On a terminal the line
    is written at once and its clock updated every ``interval`` seconds while the phase runs; in
    a log file (no carriage returns) the start is a line of its own (``"  <message> ..."``) and
    the end another (``"  <message>: <seconds> s"``). Use it as a context manager (a phase left
    by an exception ends ``(failed)``, by Ctrl-C ``(interrupted)``), or call :meth:`close` after
    the last phase.

    Parameters
    ----------
    file : file object, optional
        Where to write (default standard output).
    live : bool, optional
        Tick the clock (default: whether ``file`` is a terminal).
    interval : float
        Seconds between clock updates.
    """

    def __init__(self, file: TextIO | None = None, live: bool | None = None,
                 interval: float = 0.5) -> None:
        self.file = file if file is not None else sys.stdout
        self.live = getattr(self.file, "isatty", lambda: False)() if live is None else live
        self.interval = interval
        self.done: list[tuple[str, float]] = []        # (message, seconds) of ended phases
        self._msg: str | None = None
        self._t0 = 0.0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __call__(self, msg: str) -> None:
        self._end()
        with self._lock:
            self._msg, self._t0 = msg, time.perf_counter()
            self._write(f"  {msg} ...", newline=not self.live)
        if self.live:
            self._stop.clear()
            self._thread = threading.Thread(target=self._tick, daemon=True)
            self._thread.start()

    def _write(self, text: str, newline: bool) -> None:
        self.file.write(("\r" if self.live else "") + text + ("\n" if newline else ""))
        self.file.flush()

    def _tick(self) -> None:
        while not self._stop.wait(self.interval):
            with self._lock:
                if self._msg is not None:
                    self._write(f"  {self._msg} ... {time.perf_counter() - self._t0:.1f} s",
                                newline=False)

    def _end(self, status: str = "") -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None
        with self._lock:
            if self._msg is None:
                return
            seconds = time.perf_counter() - self._t0
            self.done.append((self._msg, seconds))
            note = f" ({status})" if status else ""
            if self.live:
                self._write(f"  {self._msg} ... {seconds:.1f} s{note}", newline=True)
            else:
                self._write(f"  {self._msg}: {seconds:.1f} s{note}", newline=True)
            self._msg = None

    def close(self) -> None:
        """End the running phase (its line gets its time)."""
        self._end()

    def __enter__(self) -> PhaseLog:
        return self

    def __exit__(self, kind: Any, *exc: Any) -> None:
        # a phase that did not end normally does not read as done
        self._end("" if kind is None else
                  "interrupted" if issubclass(kind, KeyboardInterrupt) else "failed")
