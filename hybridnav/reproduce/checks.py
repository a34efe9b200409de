"""Checks of what a reproduction is asked for and of stored text shown in README."""

from __future__ import annotations

import math
import numbers
import re
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.params import short_repr

__all__ = ["check_count", "check_shown", "read_stored_csv", "read_stored_json"]

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


def read_stored_json(path: Path, expected: str) -> dict:
    """A stored run's JSON settings file as a dict; a file that is not one is a named error
    (``expected``: what it should be, for the message)."""
    import json

    from hybridnav.fileio import read_text_file

    try:
        meta = json.loads(read_text_file(path, path.name))
    except (ValueError, RecursionError) as exc:
        if isinstance(exc, HybridnavError):
            raise
        raise HybridnavError(f"{path}: expected {expected} ({short_repr(str(exc), 200)})"
                             ) from None
    if not isinstance(meta, dict):
        raise HybridnavError(f"{path}: expected a JSON object, got {type(meta).__name__}")
    return meta


def read_stored_csv(path: Path, what: str, expected: str, text_cells: bool = False):
    """A stored run's CSV table; a file that is not one is a named error (``what``: the file's
    role for the reader, ``expected``: what it should be, for the message; ``text_cells``: every
    cell as text, an empty one as ``""``)."""
    import io

    import pandas as pd

    from hybridnav.fileio import read_text_file

    text = read_text_file(path, what)
    try:
        return (pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False) if text_cells
                else pd.read_csv(io.StringIO(text)))
    except (ValueError, pd.errors.ParserError) as exc:     # EmptyDataError is a ValueError
        raise HybridnavError(f"{path}: expected {expected} (a CSV table): "
                             f"{short_repr(str(exc), 200)}") from None
