"""What the parallel benchmarks time beside their own work: a trivially parallel CPU loop (the
speed-up two processes can get on this machine at this moment) and the load it ran under."""

from __future__ import annotations

import subprocess


def burn(n: int) -> int:
    """``n`` steps of a pure-Python CPU loop (no memory, no I/O: ideal to run in parallel)."""
    s = 0
    for i in range(n):
        s += i * i
    return s


def uptime() -> str:
    """``uptime``'s line: the load averages a timing on a shared machine needs beside it."""
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
