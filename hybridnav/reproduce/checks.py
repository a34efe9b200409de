"""Checks of what a reproduction is asked for and of stored text shown in README."""

from __future__ import annotations

import math
import numbers
import re
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.params import short_repr

__all__ = ["check_count", "check_shown"]

def check_count(option: str, value: Any, lo: int, hi: int | None = None) -> int:
    """``value`` as an integer in ``[lo, hi]`` (a bool, NaN, inf or text is refused)."""
    ok = (isinstance(value, numbers.Real) and not isinstance(value, bool)
          and math.isfinite(value) and int(value) == value
          and lo <= value and (hi is None or value <= hi))
    if not ok:
        want = "a positive integer" if (lo, hi) == (1, None) else f"an integer in [{lo}, {hi}]"
        raise HybridnavError(f"reproduce: {option}: expected {want}, got {value!r}")
    return int(value)


def check_shown(path: Path, meta: dict) -> None:
    """The free-form keys of a stored run's settings that README shows (``workers``: a count or
    ``dask ADDRESS``; ``load``: the load averages): one line of plain text each."""
    for key in ("workers", "load"):
        if key not in meta:
            continue
        v = meta[key]
        ok = (isinstance(v, int) and not isinstance(v, bool) and v >= 1) or (
            isinstance(v, str) and re.fullmatch(r"[^|<>`\n\r]{0,200}", v) is not None)
        if not ok:
            raise HybridnavError(f"{path}: {key}: expected a worker count or one line of plain "
                                 f"text, got {short_repr(v)}")
