"""Checking user-given settings: one checker for numbers, flags, choices and ranges.

Every message has the form ``"<where><key>: expected ..., got ..."`` so that it names the file
(``where`` is e.g. ``"job.toml: "``) and the dotted key.
"""

from __future__ import annotations

import math
from typing import Any

from hybridnav.errors import HybridnavError

__all__ = ["check_value", "check_range"]


def check_value(where: str, key: str, value: Any, kind: type, lo: float | None = None,
                hi: float | None = None, choices: tuple | None = None) -> Any:
    """Validate one setting and return it converted (an int where a float is expected).

    Parameters
    ----------
    where : str
        Message prefix naming the file, e.g. ``"job.toml: "`` (may be empty).
    key : str
        Dotted key, e.g. ``"ga.population"``.
    value : any
    kind : type
        ``bool``, ``int``, ``float``, ``str``, ``list`` or ``dict``.
    lo, hi : float, optional
        Inclusive bounds for numbers.
    choices : tuple, optional
        The allowed values.

    Raises
    ------
    HybridnavError
        Naming ``where``, ``key`` and what was expected.
    """
    def fail(msg: str) -> HybridnavError:
        return HybridnavError(f"{where}{key}: {msg}")

    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind in (int, float):
        ok = isinstance(value, kind) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise fail(f"expected {kind.__name__}, got {value!r}")
    if kind is float and not math.isfinite(value):
        raise fail(f"expected a finite number, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise fail(f"expected a value in [{lo}, {hi if hi is not None else 'inf'}], got "
                   f"{value!r}")
    if choices is not None and value not in choices:
        raise fail(f"expected one of {', '.join(map(str, choices))}, got {value!r}")
    return value


def check_range(where: str, key: str, value: Any, kind: type = float, lo: float | None = None,
                hi: float | None = None) -> tuple[Any, Any]:
    """A ``[low, high]`` pair with ``low <= high``, both within ``[lo, hi]``; a single number
    ``v`` means ``[v, v]``."""
    if not isinstance(value, (list, tuple)):
        value = [value, value]
    if len(value) != 2:
        raise HybridnavError(f"{where}{key}: expected [low, high], got {value!r}")
    a = check_value(where, f"{key}[0]", value[0], kind, lo, hi)
    b = check_value(where, f"{key}[1]", value[1], kind, lo, hi)
    if a > b:
        raise HybridnavError(f"{where}{key}: expected [low, high] with low <= high, got "
                             f"{list(value)!r}")
    return a, b
