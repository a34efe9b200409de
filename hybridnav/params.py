"""Declaring and checking settings: one :class:`Param` type and one message style for all.

Models, planners, optimizers, job files and generated-world tables declare their settings with
:class:`Param` (default, doc, type, bounds that may be open or closed, choices) or check a value
against the same kind of constraint with :func:`check_value`, :func:`check_int` or
:func:`check_real`. Every message has the form::

    <where><key>: expected <what>, got <value>

where ``where`` names the file or the owner (``"job.toml: "``, ``"planner apf: "``,
``"model unicycle: "``, empty for a Python keyword argument) and ``key`` the dotted key
(``"ga.population"``, ``"robots[0].params.L"``), and ``what`` is said the same way everywhere:
``a positive number``, ``a non-negative number``, ``a number in (0, 1]``, ``an integer >= 1``,
``an integer in [2, 1000]``, ``one of sbx, blend``, ``true or false``; a value of the wrong
type gets the bare type (``a number``, ``an integer``, ``a string``), ``nan`` and ``inf`` where
they are not allowed ``a finite number``.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError

__all__ = ["DEFAULT_DPI", "FIGURE_FORMATS", "FPS_RANGE", "MAX_DPI", "MAX_FPS", "MIN_DPI",
           "MIN_FPS", "Param", "check_dpi", "check_figure_format", "check_fps", "check_int",
           "check_range", "check_real", "check_seed", "check_value", "describe_params",
           "short_repr"]

#: the figure formats the commands write (``--format``; PNG for screens and reports, PDF and SVG
#: for papers); :mod:`hybridnav.plotting.output` writes them
FIGURE_FORMATS = ("png", "pdf", "svg")
#: the resolution of raster figures unless chosen (``--dpi``; PDF and SVG are vector, dpi only
#: sizes their embedded images)
DEFAULT_DPI = 120
#: the largest resolution accepted: a page-wide figure at 1200 dpi is already ~10^8 pixels
MAX_DPI = 1200
#: the smallest resolution accepted: below about 6 dpi FreeType cannot size the figures' text
#: (FreeType: "invalid ppem value")
MIN_DPI = 10
#: the frame rates of an animation (``--fps``): at most 100, at least 0.01 (a frame shown for
#: 100 s; a GIF keeps a frame's duration as a 16-bit count of centiseconds, at most 655.35 s, so
#: Pillow cannot write a rate below about 0.0016)
MIN_FPS = 0.01
MAX_FPS = 100.0
#: what :func:`check_fps` accepts, as its message and the command line's help say it
FPS_RANGE = f"a number of frames per second in [{MIN_FPS:g}, {MAX_FPS:g}]"

_KIND_WORDS = {str: "a string", list: "a list", dict: "a table", tuple: "a sequence"}


@dataclass(frozen=True)
class Param:
    """A declared setting: default, one-line doc, type, bounds or choices.

    Parameters
    ----------
    default : any
        The value used when none is given; its type is the setting's type unless ``kind`` says
        otherwise (an ``int`` default makes an integer setting, a ``float`` one a real).
    doc : str
        What the setting does, one line (listed by ``hybridnav planners`` and ``models``).
    lo, hi : float, optional
        Bounds of a number; closed unless ``lo_open`` / ``hi_open``.
    lo_open, hi_open : bool
        Make the corresponding bound strict (``lo=0, lo_open=True``: a positive number).
    choices : tuple, optional
        The allowed values.
    kind : type, optional
        The setting's type (default: the type of ``default``, ``float`` for any real and ``int``
        for any integer); give it when that is not it (e.g. ``float`` with ``default=None``).
    allow_inf : bool
        A real setting that may be ``inf`` (e.g. "no limit").
    pattern : str, optional
        A text setting's regular expression (the whole value must match).
    expected : str, optional
        What a valid value is, in words, for the messages (default: from the other fields).
    """

    default: Any
    doc: str = ""
    _: KW_ONLY                                  # the rest by keyword only
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple | None = None
    kind: type | None = None
    allow_inf: bool = False
    pattern: str | None = None
    expected: str | None = None

    def __post_init__(self) -> None:
        if self.kind is None:                 # the type of the default
            d = self.default
            kind = (bool if isinstance(d, bool) else int if isinstance(d, numbers.Integral)
                    else float if isinstance(d, numbers.Real) else type(d))
            object.__setattr__(self, "kind", kind)

    @property
    def numeric(self) -> bool:
        """Whether the setting is an integer or real number."""
        return self.kind in (int, float)

    def describe(self) -> str:
        """What a valid value is, in the words every message uses."""
        kind = self.kind
        if self.expected is not None:
            return self.expected
        if self.choices is not None:
            return "one of " + ", ".join(map(str, self.choices))
        if kind is bool:
            return "true or false"
        if kind is int:
            lo = None if self.lo is None or not math.isfinite(self.lo) else \
                math.floor(self.lo) + 1 if self.lo_open else math.ceil(self.lo)
            hi = None if self.hi is None or not math.isfinite(self.hi) else \
                math.ceil(self.hi) - 1 if self.hi_open else math.floor(self.hi)
            if lo is not None and hi is not None:
                return f"an integer in [{lo}, {hi}]"
            if lo is not None:
                return f"an integer >= {lo}"
            if hi is not None:
                return f"an integer <= {hi}"
            return "an integer"
        if kind is float:
            if self.hi is None and self.lo == 0:
                return "a positive number" if self.lo_open else "a non-negative number"
            if self.lo is None and self.hi is None:
                return "a number" if self.allow_inf else "a finite number"
            left = ("[" if self.allow_inf else "(") if self.lo is None else \
                "(" if self.lo_open else "["
            right = ("]" if self.allow_inf else ")") if self.hi is None else \
                ")" if self.hi_open else "]"
            lo = "-inf" if self.lo is None else _num(self.lo)
            hi = "inf" if self.hi is None else _num(self.hi)
            return f"a number in {left}{lo}, {hi}{right}"
        return _KIND_WORDS.get(kind, kind.__name__)

    def check(self, key: str, value: Any, where: str = "", *, parse: bool = False) -> Any:
        """Validate ``value`` and return it converted (``int`` to ``float`` for a real setting,
        an integral ``float`` to ``int`` for an integer one).

        Parameters
        ----------
        key : str
            The key the message names.
        value : any
        where : str
            Message prefix naming the file or owner, e.g. ``"job.toml: "``.
        parse : bool
            Accept strings for numbers and flags and parse them (values from ``--set``).

        Raises
        ------
        HybridnavError
            ``"<where><key>: expected <what>, got <value>"``.
        """
        kind = self.kind
        given = value

        def fail(what: str | None = None) -> HybridnavError:
            return HybridnavError(f"{where}{key}: expected {what or self.describe()}, "
                                  f"got {short_repr(given)}")

        if parse and isinstance(value, str) and kind is not str:
            value = given = self._parse(value, fail)
        if kind is bool:
            if isinstance(value, np.bool_):
                value = bool(value)
            if not isinstance(value, bool):
                raise fail("true or false")
        elif kind is int:
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or (
                    not isinstance(value, numbers.Integral)
                    and not (math.isfinite(value) and float(value) == int(value))):
                raise fail("an integer")
            value = int(value)
        elif kind is float:
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise fail("a number")
            try:
                value = float(value)
            except OverflowError:                 # an int beyond the largest float
                raise fail("a finite number") from None
            if math.isnan(value) or (math.isinf(value) and not self.allow_inf):
                raise fail("a number" if self.allow_inf else "a finite number")
        elif kind is not object and not isinstance(value, kind):
            raise fail()
        if (kind in (int, float) and not self._in_bounds(value)) or (
                self.choices is not None and value not in self.choices) or (
                self.pattern is not None and not re.fullmatch(self.pattern, str(value))):
            raise fail()
        return value

    def _in_bounds(self, v: float) -> bool:
        if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
            return False
        return not (self.hi is not None and (v > self.hi or (self.hi_open and v == self.hi)))

    def _parse(self, text: str, fail) -> Any:
        s = text.strip()
        kind = self.kind
        if kind is bool:
            low = s.lower()
            if low in ("true", "yes", "1", "on"):
                return True
            if low in ("false", "no", "0", "off"):
                return False
            raise fail("true or false")
        if kind is float:
            try:
                return float(s)
            except ValueError:
                raise fail("a number") from None
        if kind is int:
            try:
                return int(s)
            except ValueError:
                pass
            try:                               # "1e3", "3.0": the integer they write
                x = float(s)
            except ValueError:
                raise fail("an integer") from None
            if not (math.isfinite(x) and x == int(x)):
                raise fail("an integer")
            return int(x)
        return text


def _num(x: float) -> str:
    """A bound as short as ``:g`` writes it, unless that changes its value."""
    text = f"{x:g}"
    return text if float(text) == x else repr(float(x))


def short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)``, cut to about ``limit`` characters (a 400-digit number in a message helps
    no one).

    Parameters
    ----------
    value : any
    limit : int
        Longest text returned whole.
    """
    try:
        text = repr(value)
    except ValueError:                        # an int beyond Python's 4300-digit str limit
        return f"an integer of about {value.bit_length() * 0.30103:.0f} digits"
    if len(text) <= limit:
        return text
    return f"{text[:limit // 2]}...{text[-10:]} ({len(text)} characters)"


def check_value(where: str, key: str, value: Any, kind: type, lo: float | None = None,
                hi: float | None = None, choices: tuple | None = None, *,
                lo_open: bool = False, hi_open: bool = False) -> Any:
    """Validate one setting against an undeclared constraint (see :meth:`Param.check`).

    Parameters
    ----------
    where : str
        Message prefix naming the file, e.g. ``"job.toml: "`` (may be empty).
    key : str
        The dotted key the message names.
    value : any
    kind : type
        ``bool``, ``int``, ``float``, ``str``, ``list``, ``dict``, ...
    lo, hi : float, optional
        Bounds of a number (closed unless ``lo_open`` / ``hi_open``).
    choices : tuple, optional
        The allowed values.
    lo_open, hi_open : bool
        Make the bound strict.
    """
    return Param(None, kind=kind, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open,
                 choices=choices).check(key, value, where)


def check_int(name: str, value: Any, minimum: int = 1) -> int:
    """``value`` as an ``int`` >= ``minimum``, or a :class:`HybridnavError` naming ``name``.

    Parameters
    ----------
    name : str
        The key the message names.
    value : any
    minimum : int
        The smallest allowed value.
    """
    return Param(0, lo=minimum).check(name, value)


def check_seed(value: Any, key: str = "seed", *, optional: bool = True) -> int | None:
    """A seed as NumPy's ``SeedSequence`` takes it: an integer in ``[0, 2**128)`` (or None when
    ``optional``); anything else is a :class:`HybridnavError` naming ``key``.

    Parameters
    ----------
    value : any
    key : str
        The key the message names (``"seed"``, ``"--seed"``).
    optional : bool
        Whether None (fresh entropy) is allowed.
    """
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
            or not 0 <= int(value) < 2**128:
        raise HybridnavError(f"{key}: expected a non-negative integer below 2**128"
                             f"{' or None' if optional else ''}, got {short_repr(value)}")
    return int(value)


def check_real(name: str, value: Any, lo: float | None = None, hi: float | None = None, *,
               lo_open: bool = False, hi_open: bool = False, allow_inf: bool = False) -> float:
    """``value`` as a finite ``float`` in the given interval, or a :class:`HybridnavError`.

    Parameters
    ----------
    name : str
        The key the message names.
    value : any
    lo, hi : float, optional
        Bounds (closed unless ``lo_open`` / ``hi_open``).
    lo_open, hi_open : bool
        Make the bound strict.
    allow_inf : bool
        Accept ``inf`` (and ``-inf``) within the bounds.
    """
    return Param(0.0, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open,
                 allow_inf=allow_inf).check(name, value)


def check_range(where: str, key: str, value: Any, kind: type = float, lo: float | None = None,
                hi: float | None = None) -> tuple[Any, Any]:
    """A ``[low, high]`` pair with ``low <= high``, both within ``[lo, hi]``; a single number
    ``v`` means ``[v, v]``.

    Parameters
    ----------
    where : str
        Message prefix naming the file.
    key : str
    value : number or [low, high]
    kind : type
        ``int`` or ``float``.
    lo, hi : float, optional
        Bounds of both ends (closed).
    """
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


def describe_params(params: Mapping[str, Param], indent: str = "  ") -> list[str]:
    """One line per setting: ``key = default    doc (what a valid value is)``, for listings.

    Parameters
    ----------
    params : dict of str to Param
    indent : str
        Prefix of every line.
    """
    lines = []
    for key, p in params.items():
        default = f"{p.default:g}" if isinstance(p.default, float) else repr(p.default)
        lines.append(f"{indent}{key} = {default}    {p.doc} ({p.describe()})".rstrip())
    return lines


def check_figure_format(fmt: Any, name: str = "format") -> str:
    """``fmt`` as one of :data:`FIGURE_FORMATS` (lower case; a leading dot is allowed), else a
    HybridnavError ``<name>: expected one of png, pdf, svg, got ...``.

    Parameters
    ----------
    fmt : str
    name : str
        The option or parameter the value came from (``"--format"``, ``"fmt"``).
    """
    text = fmt.lower().lstrip(".") if isinstance(fmt, str) else None
    if text not in FIGURE_FORMATS:
        raise HybridnavError(f"{name}: expected one of {', '.join(FIGURE_FORMATS)}, got "
                             f"{short_repr(fmt)}")
    return text


def check_dpi(dpi: Any, name: str = "dpi") -> int:
    """``dpi`` as an integer in ``[MIN_DPI, MAX_DPI]``, else a HybridnavError
    ``<name>: expected an integer in [10, 1200] (dots per inch), got ...``.

    Parameters
    ----------
    dpi : int
    name : str
        The option or parameter the value came from (``"--dpi"``, ``"dpi"``).
    """
    if isinstance(dpi, bool) or not isinstance(dpi, numbers.Integral) \
            or not MIN_DPI <= dpi <= MAX_DPI:
        raise HybridnavError(f"{name}: expected an integer in [{MIN_DPI}, {MAX_DPI}] (dots per "
                             f"inch), got {short_repr(dpi)}")
    return int(dpi)


def check_fps(fps: Any, name: str = "fps") -> float:
    """``fps`` as a float in ``[MIN_FPS, MAX_FPS]``, else a HybridnavError
    ``<name>: expected a number of frames per second in [0.01, 100], got ...``.

    Parameters
    ----------
    fps : float
    name : str
        The option or parameter the value came from (``"--fps"``, ``"fps"``).
    """
    if isinstance(fps, bool) or not isinstance(fps, numbers.Real) \
            or not MIN_FPS <= fps <= MAX_FPS:       # NaN compares false; no float() of 10**400
        raise HybridnavError(f"{name}: expected {FPS_RANGE}, got {short_repr(fps)}")
    return float(fps)
