"""Helpers shared by the exporters and importers: names, numbers, rule normal forms, building.

Nothing here is public API; :mod:`hybridnav.fuzzy.export` re-exports what users need.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.mf import MF_PARAMS, check_params, sample
from hybridnav.fuzzy.spec import (
    MAX_POINTS,
    And,
    Antecedent,
    Not,
    Or,
    Rule,
    Term,
    TermRef,
    Variable,
    decode_json,
    finite_number,
    range_problem,
)
from hybridnav.fuzzy.system import FuzzySystem
from hybridnav.params import short_repr

__all__ = [
    "DEFAULT_POINTS", "MAX_POINTS", "IDENT", "fnum", "name_problem", "check_names",
    "comment_text", "normalize_antecedent",
    "flatten_antecedent", "normalize", "LineError", "build_system", "metadata_json",
    "parse_metadata", "version", "sampled_polyline",
]

#: Universe samples per variable when an imported file does not say (FLL, MATLAB .fis).
DEFAULT_POINTS = 101
#: Names the text formats can carry unchanged: C-like identifiers.
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

# words fuzzylite's rule parser reads as keywords or hedges (case-sensitive), and FCL keywords
# (IEC 61131 keywords are case-insensitive)
_FUZZYLITE_WORDS = frozenset({"if", "is", "then", "and", "or", "with", "not", "any", "very",
                              "somewhat", "extremely", "seldom"})
_FCL_WORDS = frozenset(w.lower() for w in (
    "IF", "IS", "THEN", "AND", "OR", "NOT", "WITH", "TERM", "RANGE", "METHOD", "ACCU", "ACT",
    "DEFAULT", "RULE", "RULEBLOCK", "END_RULEBLOCK", "FUZZIFY", "END_FUZZIFY", "DEFUZZIFY",
    "END_DEFUZZIFY", "VAR_INPUT", "VAR_OUTPUT", "END_VAR", "FUNCTION_BLOCK",
    "END_FUNCTION_BLOCK", "REAL", "NC", "COG", "MIN", "MAX", "LOCK", "ENABLED", "TRUE", "FALSE",
    "OPTION", "END_OPTION", "COA", "COGS", "LM", "RM", "PROD", "ASUM", "BSUM", "BDIF"))


def version() -> str:
    """The installed hybridnav version (for file headers)."""
    from hybridnav import __version__

    return __version__


def fnum(x: float) -> str:
    """Shortest text that reads back as exactly ``x`` (Python's ``repr`` of the float)."""
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"not a finite number: {v!r}")
    return repr(v)


# ---------------------------------------------------------------------------------------- names

_LABEL = {"fll": "FLL", "fis": ".fis", "fcl": "FCL", "c": "C"}


def name_problem(name: str, fmt: str) -> str | None:
    """What keeps a variable or term name from being written to ``fmt`` and read back, or None.

    The one rule for names, used by the exporters (:func:`check_names`) and by the FLL and .fis
    importers, so that whatever they read can be written again. Names must be identifiers
    (``[A-Za-z_][A-Za-z0-9_]*``: fuzzylite keeps only letters, digits, ``_`` and ``.`` of a name,
    IEC 61131 identifiers are letters, digits and ``_``, C needs identifiers) that fuzzylite's
    rule parser does not read as a keyword or hedge (``if is then and or with not any very
    somewhat extremely seldom``, case-sensitive; fuzzylite also builds rules from a .fis file's
    names); for ``fcl`` also not an FCL keyword (any case); for ``c`` identifiers of any spelling.

    Parameters
    ----------
    name : str
    fmt : {"fll", "fis", "fcl", "c"}

    Returns
    -------
    str or None
        ``"expected ..."`` (without the name), or None when the name can be carried.
    """
    if not IDENT.match(name):
        return "expected an identifier (letters, digits, '_', not starting with a digit)"
    if fmt == "c":                   # names reach only C comments and macros
        return None
    if fmt == "fcl":
        if name.lower() in _FUZZYLITE_WORDS | _FCL_WORDS:
            return ("expected a name that is not a keyword in FCL rules (FCL keywords in any "
                    "case, fuzzylite's rule words; fuzzylite would misread the rules)")
    elif name in _FUZZYLITE_WORDS:
        return (f"expected a name that is not a keyword in {_LABEL.get(fmt, fmt)} rules "
                f"({' '.join(sorted(_FUZZYLITE_WORDS))}; fuzzylite would misread the rules)")
    return None


def check_names(system: FuzzySystem, fmt: str) -> None:
    """Raise :class:`HybridnavError` unless every name can be written to ``fmt`` unchanged
    (:func:`name_problem`)."""
    src = f"{system.source}: " if system.source else ""

    def check(name: str, key: str) -> None:
        problem = name_problem(name, fmt)
        if problem:
            raise HybridnavError(f"{src}{key}: name {short_repr(name)} cannot be written to "
                                 f"{_LABEL.get(fmt, fmt)}: {problem}")

    for i, v in enumerate(system.inputs):
        check(v.name, f"inputs[{i}].name")
        for j, t in enumerate(v.terms):
            check(t.name, f"inputs[{i}].terms[{j}].name")
    check(system.output.name, "output.name")
    for j, t in enumerate(system.output.terms):
        check(t.name, f"output.terms[{j}].name")


def one_line(text: str) -> str:
    """``text`` on one line without ``#`` (safe after an FLL ``description:`` key)."""
    return " ".join(text.replace("#", " ").split())


_COMMENT_SAFE = re.compile(r"[^A-Za-z0-9 _.,:;+=()\[\]{}<>!@$&|~^-]")


def comment_text(text: str) -> str:
    """Free text (a system's name) made safe inside any format's comment or quoted name: one
    line of printable ASCII without the characters that open or close a comment or a string in
    C, FCL, FLL or .fis (``/ * ? \\ # % ' "``, which also rules out C trigraphs and line
    splices); each other character becomes ``_``. The exact text travels in the metadata."""
    return _COMMENT_SAFE.sub("_", " ".join(text.split()))


def description_lines(text: str | None, width: int = 92) -> list[str]:
    """A system's description as comment lines safe in every format (:func:`comment_text`),
    wrapped, prefixed ``Description:`` (none for an empty description): what the system is and
    how it was tuned — e.g. the safety filter it must be deployed with — travels with it."""
    import textwrap

    text = comment_text(text or "")
    return textwrap.wrap(f"Description: {text}", width) if text.strip() else []


# ------------------------------------------------------------------------------ rule normal forms

def normalize_antecedent(a: Antecedent) -> Antecedent:
    """Negation normal form, with one-item ``and``/``or`` lists replaced by their item.

    ``not`` is pushed to the leaves by De Morgan's laws: ``not (x and y)`` becomes
    ``(not x) or (not y)``. This is exact in floating point, not only in exact arithmetic:
    ``1 - v`` rounds monotonically, so ``1 - min(a, b) == max(1 - a, 1 - b)`` bit for bit (and
    the same for an even number of negations with min/max unchanged). Double negations of a
    leaf are kept (``x is not not t``), since ``1 - (1 - v)`` may differ from ``v`` by rounding.
    """
    def push(x: Antecedent, k: int) -> Antecedent:
        if isinstance(x, TermRef):
            out: Antecedent = x
            for _ in range(k):
                out = Not(out)
            return out
        if isinstance(x, Not):
            return push(x.item, k + 1)
        items = tuple(push(i, k) for i in x.items)
        if len(items) == 1:
            return items[0]
        is_and = isinstance(x, And) != (k % 2 == 1)
        return And(items) if is_and else Or(items)

    return push(a, 0)


def flatten_antecedent(a: Antecedent) -> Antecedent:
    """:func:`normalize_antecedent`, then nested ``and`` in ``and`` (``or`` in ``or``) merged.

    Exact as well: min and max are associative in floating point.
    """
    a = normalize_antecedent(a)

    def flat(x: Antecedent) -> Antecedent:
        if isinstance(x, (TermRef, Not)):
            return x
        cls = type(x)
        items: list[Antecedent] = []
        for i in x.items:
            f = flat(i)
            if isinstance(f, cls):
                items.extend(f.items)
            else:
                items.append(f)
        return cls(tuple(items))

    return flat(a)


def normalize(system: FuzzySystem, *, flat: bool = False) -> FuzzySystem:
    """The system with every rule antecedent in the normal form the text formats write.

    Parameters
    ----------
    system : FuzzySystem
    flat : bool
        The MATLAB .fis form: also merge nested ``and``/``or`` of the same kind, and list the
        conditions of a rule's top-level ``and``/``or`` in input order (leaves first by input
        position; compound items keep their place after them).

    Returns
    -------
    FuzzySystem
        Evaluates bit for bit like ``system`` (every step is exact in floating point).
        FLL and FCL export write ``normalize(system)``; the .fis export writes
        ``normalize(system, flat=True)``. Importing an exported FLL or .fis file gives this system
        back (``==``).
    """
    order = {v.name: i for i, v in enumerate(system.inputs)}

    def leaf_input(x: Antecedent) -> str | None:
        while isinstance(x, Not):
            x = x.item
        return x.input if isinstance(x, TermRef) else None

    def fix(a: Antecedent) -> Antecedent:
        if not flat:
            return normalize_antecedent(a)
        a = flatten_antecedent(a)
        if isinstance(a, (And, Or)):
            def rank(x: Antecedent) -> int:
                name = leaf_input(x)
                return order[name] if name is not None else len(order)
            a = type(a)(tuple(sorted(a.items, key=rank)))
        return a

    rules = [Rule(fix(r.antecedent), r.then, r.weight, r.description) for r in system.rules]
    return FuzzySystem(system.name, system.inputs, system.output, rules, system.description,
                       system.source)


# ------------------------------------------------------------------------------------- metadata

def sampled_polyline(v: Variable, t: Term) -> list[tuple[float, float]]:
    """The term sampled on the variable's universe, as hybridnav interpolates it.

    Interior points of flat runs (equal neighbours) are dropped: linear interpolation of the
    rest gives exactly the same values.
    """
    xs = np.linspace(v.range[0], v.range[1], v.points)
    ys = sample(t.mf, t.params, xs)
    keep = np.ones(len(xs), dtype=bool)
    keep[1:-1] = ~((ys[1:-1] == ys[:-2]) & (ys[1:-1] == ys[2:]))
    return list(zip(xs[keep].tolist(), ys[keep].tolist()))


def metadata_json(system: FuzzySystem, *, default: bool = False, name: bool = False,
                  mfs: bool = False) -> str:
    """One-line JSON with what a text format has no place for (points, descriptions, and with
    ``mfs`` the membership functions of terms written as sampled polylines)."""
    meta: dict[str, Any] = {"format": "hybridnav-fis/1"}
    if name:
        meta["name"] = system.name
    meta["points"] = {v.name: v.points for v in (*system.inputs, system.output)}
    if mfs:
        meta["mfs"] = {v.name: {t.name: [t.mf, list(t.params)] for t in v.terms}
                       for v in (*system.inputs, system.output)}
    if default:
        meta["default"] = system.output.default
    if system.description is not None:
        meta["description"] = system.description
    if any(r.description is not None for r in system.rules):
        meta["rule_descriptions"] = [r.description for r in system.rules]
    return json.dumps(meta, ensure_ascii=True, allow_nan=False, separators=(", ", ": "))


def parse_metadata(text: str, where: str) -> dict[str, Any]:
    """Validate a metadata JSON object written by :func:`metadata_json`.

    Returns a dict with the optional keys ``name`` (str), ``mfs`` (variable -> term ->
    ``[mf, params]``), ``points`` (name -> int), ``default`` (float),
    ``description`` (str) and ``rule_descriptions`` (list of str or None).
    """
    raw = decode_json(text, f"{where}: hybridnav metadata")
    if not isinstance(raw, dict):
        raise HybridnavError(f"{where}: hybridnav metadata: expected a JSON object")
    out: dict[str, Any] = {}
    for k, v in raw.items():
        if k == "format":
            if v != "hybridnav-fis/1":
                raise HybridnavError(f"{where}: hybridnav metadata: unsupported format "
                                     f"{short_repr(v)}")
        elif k == "points":
            if not isinstance(v, dict):
                raise HybridnavError(f"{where}: hybridnav metadata: 'points' must map names to "
                                     "integers")
            for name, n in v.items():
                if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= MAX_POINTS:
                    raise HybridnavError(f"{where}: hybridnav metadata: points of "
                                         f"{short_repr(name)}: expected an integer in [2, "
                                         f"{MAX_POINTS}], got {short_repr(n)}")
            out["points"] = dict(v)
        elif k == "name":
            if not isinstance(v, str) or not v.strip():
                raise HybridnavError(f"{where}: hybridnav metadata: 'name' must be a non-empty "
                                     "string")
            out["name"] = v
        elif k == "mfs":
            ok = isinstance(v, dict) and all(
                isinstance(terms, dict) and all(
                    isinstance(d, list) and len(d) == 2 and d[0] in MF_PARAMS
                    and isinstance(d[1], list) and len(d[1]) == len(MF_PARAMS[d[0]])
                    and all(finite_number(p) is not None for p in d[1])
                    for d in terms.values())
                for terms in v.values())
            if not ok:
                raise HybridnavError(f"{where}: hybridnav metadata: 'mfs' must map variable -> "
                                     "term -> [mf, [parameters]]")
            out["mfs"] = v
        elif k == "default":
            if finite_number(v) is None:
                raise HybridnavError(f"{where}: hybridnav metadata: default: expected a finite "
                                     f"number, got {short_repr(v)}")
            out["default"] = finite_number(v)
        elif k == "description":
            if not isinstance(v, str):
                raise HybridnavError(f"{where}: hybridnav metadata: 'description' must be a "
                                     "string")
            out["description"] = v
        elif k == "rule_descriptions":
            if not isinstance(v, list) or not all(d is None or isinstance(d, str) for d in v):
                raise HybridnavError(f"{where}: hybridnav metadata: 'rule_descriptions' must be "
                                     "a list of strings or nulls")
            out["rule_descriptions"] = list(v)
        else:
            raise HybridnavError(f"{where}: hybridnav metadata: unknown key {short_repr(k)}")
    return out


# ------------------------------------------------------------------------------------- building

class LineError:
    """Makes :class:`HybridnavError` messages ``"<file>: line N: <what>"``."""

    def __init__(self, source: str | None) -> None:
        self.source = source

    def where(self, line: int | None) -> str:
        """``"<file>: line N"`` (either part left out when unknown)."""
        return ": ".join(p for p in (self.source, f"line {line}" if line else None) if p)

    def __call__(self, line: int | None, msg: str) -> HybridnavError:
        w = self.where(line)
        return HybridnavError(f"{w}: {msg}" if w else msg)


def check_term(err: LineError, line: int, name: str, mf: str, params: Sequence[float],
               lo: float, hi: float, points: int) -> tuple[float, ...]:
    """Validate one term's parameters (finite, valid for ``mf``, finite samples)."""
    p = tuple(float(v) for v in params)
    if len(p) != len(MF_PARAMS[mf]):
        raise err(line, f"term '{name}': {mf} takes {len(MF_PARAMS[mf])} parameters "
                  f"({', '.join(MF_PARAMS[mf])}), got {len(p)}")
    if not all(math.isfinite(v) for v in p):
        raise err(line, f"term {short_repr(name)}: expected finite parameters, got {list(p)}")
    problem = check_params(mf, p)
    if problem:
        raise err(line, f"term {short_repr(name)}: {problem}")
    try:
        sample(mf, p, np.linspace(lo, hi, points))
    except FloatingPointError:
        raise err(line, f"term {short_repr(name)}: {mf}{list(p)} has no finite membership "
                  f"values on [{lo!r}, {hi!r}] (parameters too extreme)") from None
    return p


def check_range(err: LineError, line: int, lo: float, hi: float, points: int, what: str, *,
                output: bool = False) -> None:
    """The shared range check (:func:`hybridnav.fuzzy.spec.range_problem`) as a line error."""
    problem = range_problem(lo, hi, points, output=output)
    if problem:
        raise err(line, f"{what}: {problem}")


def check_name(err: LineError, line: int, name: str, fmt: str, what: str) -> str:
    """``name`` if :func:`name_problem` has nothing against it, else a line error."""
    problem = name_problem(name, fmt)
    if problem:
        raise err(line, f"{what}: {problem}, got {short_repr(name)}")
    return name


def check_points(err: LineError, line: int | None, n: int, name: str) -> int:
    """Universe samples within [2, MAX_POINTS]."""
    if not 2 <= n <= MAX_POINTS:
        raise err(line, f"variable {short_repr(name)}: expected between 2 and {MAX_POINTS} "
                  f"universe points, got {short_repr(n)}")
    return n


def build_system(doc: Mapping[str, Any], source: str | None) -> FuzzySystem:
    """``FuzzySystem.from_dict`` for an importer whose checks already named the lines.

    Anything the importer did not catch is reported with the JSON key path (``from_dict``'s
    messages), prefixed by the file name.
    """
    try:
        return FuzzySystem.from_dict(doc, source)
    except FloatingPointError as exc:  # pragma: no cover - importers sample terms beforehand
        raise HybridnavError(f"{source + ': ' if source else ''}{exc}") from None


def terms_json(terms: Iterable[tuple[str, str, Sequence[float]]]) -> list[dict[str, Any]]:
    """``[{"name", "mf", "params"}]`` from ``(name, mf, params)`` triples."""
    return [{"name": n, "mf": mf, "params": list(p)} for n, mf, p in terms]


def parse_number(err: LineError, line: int, text: str, what: str) -> float:
    """A finite float from a text file (``nan``/``inf`` are rejected), or a line error."""
    try:
        v = float(text)
    except ValueError:
        raise err(line, f"{what}: expected a number, got {short_repr(text)}") from None
    if not math.isfinite(v):
        raise err(line, f"{what}: expected a finite number, got {short_repr(text)}")
    return v
