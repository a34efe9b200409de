"""Export tuned fuzzy systems for deployment, and import systems designed elsewhere.

>>> from hybridnav import fuzzy
>>> fis = fuzzy.builtin("effc-5rule")
>>> text = fuzzy.export(fis, "fll")                        # fuzzylite language, as text
>>> paths = fuzzy.export_to_file(fis, "c", "build/effc")   # build/effc.h and build/effc.c
>>> again = fuzzy.load_any("controller.fis")               # a MATLAB-designed system

Formats (:data:`FORMATS`):

``json``
    The ``hybridnav-fis/1`` document (:meth:`FuzzySystem.to_json`).
``fll``
    fuzzylite's language (:mod:`~hybridnav.fuzzy.export.fll`); read back by :func:`read_fll`.
``fis``
    MATLAB Fuzzy Logic Toolbox (:mod:`~hybridnav.fuzzy.export.fis`); read back by
    :func:`read_fis`. Rules must be flat AND/OR over distinct inputs.
``fcl``
    IEC 61131-7 Fuzzy Control Language with point-list terms (:mod:`~hybridnav.fuzzy.export.fcl`).
``c``
    A standalone C99 header and source evaluating exactly like :meth:`FuzzySystem.evaluate`
    (:mod:`~hybridnav.fuzzy.export.c`).

The text formats write rules in the normal form of :func:`normalize` (negations on the leaves,
exact); FLL and .fis keep universe points and descriptions in a comment line that fuzzylite and
MATLAB skip, so ``read_fll(to_fll(s)) == normalize(s)`` and
``read_fis(to_fis(s)) == normalize(s, flat=True)``. Importers raise only :class:`HybridnavError`,
naming the file and the line (FLL, .fis) or key (JSON); nothing is ever unpickled.

Importing this module does not import scikit-fuzzy.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, read_text_file
from hybridnav.fuzzy.export._common import DEFAULT_POINTS, MAX_POINTS, normalize
from hybridnav.fuzzy.export.c import CCode, c_identifier, to_c
from hybridnav.fuzzy.export.fcl import to_fcl
from hybridnav.fuzzy.export.fis import read_fis, to_fis
from hybridnav.fuzzy.export.fll import read_fll, to_fll
from hybridnav.fuzzy.system import FuzzySystem, builtin, loads

__all__ = [
    "FORMATS", "DEFAULT_POINTS", "MAX_POINTS", "CCode", "export", "export_to_file", "to_fll",
    "to_fis", "to_fcl", "to_c", "read_json", "read_fll", "read_fis", "read_text", "load_any",
    "normalize", "c_identifier",
]

log = logging.getLogger(__name__)

#: The export formats, in the order the CLI lists them.
FORMATS = ("json", "fll", "fis", "fcl", "c")
#: File suffix of each text format.
SUFFIXES = {"json": ".json", "fll": ".fll", "fis": ".fis", "fcl": ".fcl"}


def _check_format(fmt: str) -> str:
    if fmt not in FORMATS:
        raise HybridnavError(f"unknown export format {fmt!r} (expected one of "
                             f"{', '.join(FORMATS)})")
    return fmt


def export(system: FuzzySystem, format: str, path: str | os.PathLike[str] | None = None,
           **options: Any) -> str | CCode:
    """The system in another format, as text; written to ``path`` when given.

    Parameters
    ----------
    system : FuzzySystem
    format : {"json", "fll", "fis", "fcl", "c"}
    path : str or path-like, optional
        Where to write (atomically). For ``"c"`` a path prefix: ``build/effc`` (or
        ``build/effc.c`` / ``build/effc.h``) writes ``build/effc.h`` and ``build/effc.c``, and the
        C names are prefixed ``effc_``.
    **options
        ``"fll"``, ``"fcl"``: ``sampled=True`` writes every term as the polyline of its universe
        samples (fuzzylite then agrees with :meth:`FuzzySystem.evaluate` up to its centroid
        quadrature; see :func:`to_fll`). ``"c"``: ``real="double"`` or ``"float"`` (and
        ``basename`` when ``path`` is not given).

    Returns
    -------
    str or CCode
        The text; for ``"c"`` a :class:`CCode` ``(basename, header, source)``.

    Raises
    ------
    HybridnavError
        Unknown format or option, or a system the format cannot express (the message names the
        rule or key).
    """
    _check_format(format)
    if format == "c":
        unknown = set(options) - {"real", "basename"}
        if unknown:
            raise HybridnavError(f"C export: unknown option(s) {', '.join(sorted(unknown))} "
                                 "(expected real, basename)")
        if path is not None:
            prefix = _c_prefix(path)
            code = to_c(system, prefix.name, real=options.get("real", "double"))
            atomic_write_text(prefix.with_name(prefix.name + ".h"), code.header)
            atomic_write_text(prefix.with_name(prefix.name + ".c"), code.source)
            log.info("wrote %s.h and %s.c", prefix, prefix)
            return code
        return to_c(system, options.get("basename"), real=options.get("real", "double"))
    allowed = {"sampled"} if format in ("fll", "fcl") else set()
    unknown = set(options) - allowed
    if unknown:
        raise HybridnavError(f"{format} export: unknown option(s) {', '.join(sorted(unknown))}"
                             + (f" (expected {', '.join(sorted(allowed))})" if allowed else
                                " (it takes none)"))
    if format == "fll":
        text = to_fll(system, **options)
    elif format == "fcl":
        text = to_fcl(system, **options)
    elif format == "fis":
        text = to_fis(system)
    else:
        text = system.to_json()
    if path is not None:
        atomic_write_text(path, text)
        log.info("wrote %s", path)
    return text


def _c_prefix(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    if p.suffix in (".c", ".h"):
        p = p.with_suffix("")
    if not p.name or p.name in (".", ".."):
        raise HybridnavError(f"C export: expected a path prefix such as build/effc, got {str(path)!r}")
    return p


def export_to_file(system: FuzzySystem, fmt: str, out_path: str | os.PathLike[str] | None = None,
                   **options: Any) -> list[Path]:
    """Write the system in format ``fmt``; the function the ``hybridnav export`` command calls.

    Parameters
    ----------
    system : FuzzySystem
    fmt : {"json", "fll", "fis", "fcl", "c"}
    out_path : str or path-like, optional
        The file (for ``"c"`` the prefix, see :func:`export`; an existing directory gets
        ``<name>.<suffix>`` inside it). Default: ``<name>.<suffix>`` in the current directory,
        ``<name>`` being :func:`c_identifier` of the system's name.
    **options
        As for :func:`export`.

    Returns
    -------
    list of pathlib.Path
        The written files (two for ``"c"``: header, then source).

    Raises
    ------
    HybridnavError
        As :func:`export`.
    """
    _check_format(fmt)
    stem = c_identifier(system.name)
    if out_path is None:
        target = Path(stem if fmt == "c" else stem + SUFFIXES[fmt])
    else:
        target = Path(out_path)
        if target.is_dir():
            target = target / (stem if fmt == "c" else stem + SUFFIXES[fmt])
    export(system, fmt, target, **options)
    if fmt == "c":
        prefix = _c_prefix(target)
        return [prefix.with_name(prefix.name + ".h"), prefix.with_name(prefix.name + ".c")]
    return [target]


# ------------------------------------------------------------------------------------------ import

def read_json(text: str, source: str | None = None) -> FuzzySystem:
    """Read a ``hybridnav-fis/1`` JSON document, hardened for files from elsewhere.

    The same as :func:`hybridnav.fuzzy.loads`, which already turns nesting too deep for Python's
    JSON parser, more than :data:`MAX_POINTS` universe points and parameters whose membership
    values overflow into :class:`HybridnavError` s naming the key.

    Parameters
    ----------
    text : str
    source : str, optional
        File name for error messages.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
    """
    return loads(text, source)


def read_text(text: str, format: str, source: str | None = None, *,
              points: int = DEFAULT_POINTS) -> FuzzySystem:
    """Read a system from text in ``format`` (``"json"``, ``"fll"`` or ``"fis"``).

    Parameters
    ----------
    text : str
    format : {"json", "fll", "fis"}
    source : str, optional
        File name for error messages.
    points : int
        Universe points for FLL / .fis files without hybridnav metadata.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
    """
    if format == "json":
        return read_json(text, source)
    if format == "fll":
        return read_fll(text, source, points=points)
    if format == "fis":
        return read_fis(text, source, points=points)
    raise HybridnavError(f"cannot import format {format!r} (expected json, fll or fis)")


def load_any(name_or_path: str | os.PathLike[str], *, points: int = DEFAULT_POINTS) -> FuzzySystem:
    """Load a system from a ``.json``, ``.fll`` or ``.fis`` file, a built-in one by name, or a
    :class:`FuzzySystem` or scikit-fuzzy ``ControlSystem`` in Python code (``module:NAME`` or
    ``path/file.py:NAME``; :func:`hybridnav.fuzzy.from_skfuzzy`).

    Parameters
    ----------
    name_or_path : str or path-like
        A file (the suffix picks the reader), a built-in name (``effc-5rule``), or
        ``module:NAME`` / ``file.py:NAME`` naming a ``FuzzySystem`` or a ``ControlSystem`` (the
        code is run).
    points : int
        Universe points for FLL / .fis files without hybridnav metadata (default 101).

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        Unreadable file, unknown suffix or built-in name, or invalid content (file and line/key
        named).
    """
    s = os.fspath(name_or_path)
    if isinstance(name_or_path, str) and ":" in s \
            and not s.lower().endswith((".json", ".fll", ".fis")) \
            and not os.path.exists(s):
        return _from_python(s)
    suffix = Path(s).suffix.lower()
    fmt = {".json": "json", ".fll": "fll", ".fis": "fis"}.get(suffix)
    if fmt is None:
        if isinstance(name_or_path, os.PathLike) or "/" in s or os.sep in s or suffix:
            raise HybridnavError(f"{s}: unknown fuzzy system file type {suffix or '(none)'!r} "
                                 "(expected .json, .fll or .fis)")
        return builtin(s)
    text = read_text_file(s, "fuzzy system file")
    log.debug("loading fuzzy system from %s (%s)", s, fmt)
    return read_text(text, fmt, s, points=points)


def _from_python(spec: str) -> FuzzySystem:
    """The system ``module:NAME`` or ``file.py:NAME`` names: a ``FuzzySystem`` as it is, a
    scikit-fuzzy ``ControlSystem`` converted."""
    import importlib
    import importlib.util

    from hybridnav.fuzzy.system import from_skfuzzy

    where, _, attr = spec.rpartition(":")
    if not where or not attr:
        raise HybridnavError(f"{spec}: expected module:NAME or file.py:NAME")
    try:
        if where.endswith(".py"):
            if not os.path.isfile(where):
                raise HybridnavError(f"{where}: " + ("not a file" if os.path.exists(where)
                                                     else "no such file"))
            # in sys.modules while it runs, as an import is (dataclasses and pickle look the
            # module up there), under a name that shadows no other module
            name = f"_hybridnav_fis_{Path(where).stem}"
            mod_spec = importlib.util.spec_from_file_location(name, where)
            module = importlib.util.module_from_spec(mod_spec)
            sys.modules[name] = module
            try:
                mod_spec.loader.exec_module(module)
            except BaseException:
                sys.modules.pop(name, None)
                raise
        else:
            module = importlib.import_module(where)
    except HybridnavError:
        raise
    except (Exception, SystemExit) as exc:     # any error in the user's code, or its exit()
        raise HybridnavError(f"{spec}: cannot import {where!r} ({type(exc).__name__}: "
                             f"{exc})") from None
    if not hasattr(module, attr):
        raise HybridnavError(f"{spec}: {where!r} has no {attr!r}")
    obj = getattr(module, attr)
    if isinstance(obj, type):
        raise HybridnavError(f"{spec}: got the class {obj.__name__}; expected an instance (a "
                             "hybridnav FuzzySystem or a skfuzzy.control.ControlSystem)")
    if isinstance(obj, FuzzySystem):
        # a system built with hybridnav's own API, as its data: a subclass's own behaviour
        # would be neither what the exports describe nor run inside this error handling
        try:
            return loads(obj.to_json(), source=spec)
        except HybridnavError:
            raise
        except Exception as exc:             # the user's subclass failed to describe itself
            raise HybridnavError(f"{spec}: cannot read the system ({type(exc).__name__}: "
                                 f"{exc})") from None
    from skfuzzy.control import ControlSystem

    if not isinstance(obj, ControlSystem):
        raise HybridnavError(f"{spec}: expected a hybridnav FuzzySystem or a "
                             f"skfuzzy.control.ControlSystem, got {type(obj).__name__}")
    return from_skfuzzy(obj, name=attr)
