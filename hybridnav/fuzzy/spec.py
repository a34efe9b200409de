"""The ``hybridnav-fis/1`` data model: plain frozen dataclasses and a validating reader.

Every validation error is a :class:`hybridnav.HybridnavError` whose message is
``"<file>: <key path>: <what was expected>"`` (the file part only when there is one), e.g.
``sys.json: inputs[0].terms[1].params: expected 2 numbers for zmf, got 3``. Long values are cut
(:func:`hybridnav.params.short_repr`). What the evaluators can represent is checked here for
every reader: numbers (:func:`finite_number`, :func:`decode_json`'s :class:`HugeInteger` for
integers past Python's digit limit) and ranges (:func:`range_problem`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError, where
from hybridnav.fuzzy.mf import MF_PARAMS, check_params
from hybridnav.params import short_repr

__all__ = [
    "FORMAT", "Term", "Variable", "OutputVariable", "TermRef", "And", "Or", "Not", "Antecedent",
    "Rule", "antecedent_sentence", "parse_system", "antecedent_to_json", "range_problem",
    "finite_number", "decode_json", "HugeInteger", "MAX_MOMENT", "names_text",
]

#: The format string this module reads and writes.
FORMAT = "hybridnav-fis/1"
#: Most universe samples a variable may have (a file from elsewhere cannot exhaust memory).
MAX_POINTS = 1_000_000

DEFUZZ_METHODS = ("centroid",)
#: Largest ``max(|lo|, |hi|) * (hi - lo)`` of an output range. The centroid sums moments
#: ``x * area``: the plain-universe integral is at most this (the aggregated output is at most 1),
#: the max-min identity adds at most 15 such sums, every crossing term at most one more per output
#: term; 2**1000 leaves a factor 2**23 before a double overflows.
MAX_MOMENT = 2.0 ** 1000
_EPS = 2.0 ** -52            # numpy's finfo(float).eps, the floor of the centroid's divisor
_NORMAL = 2.0 ** -1022       # the smallest normal double


@dataclass(frozen=True)
class Term:
    """A linguistic term: a name and a membership function with scikit-fuzzy's parameters."""

    name: str
    mf: str
    params: tuple[float, ...]


@dataclass(frozen=True)
class Variable:
    """An input variable: ``points`` evenly spaced universe samples over ``range``, and terms."""

    name: str
    range: tuple[float, float]
    points: int
    terms: tuple[Term, ...]

    def term_names(self) -> tuple[str, ...]:
        """Names of the terms, in file order."""
        return tuple(t.name for t in self.terms)


@dataclass(frozen=True)
class OutputVariable(Variable):
    """The output variable: a :class:`Variable` plus the defuzzifier and the no-rule-fired value."""

    defuzz: str = "centroid"
    default: float = 0.0


@dataclass(frozen=True)
class TermRef:
    """Antecedent leaf ``[input, term]``: the membership of ``input`` in ``term``."""

    input: str
    term: str


@dataclass(frozen=True)
class And:
    """Antecedent ``{"and": [...]}``: minimum of the items."""

    items: tuple[Antecedent, ...]


@dataclass(frozen=True)
class Or:
    """Antecedent ``{"or": [...]}``: maximum of the items."""

    items: tuple[Antecedent, ...]


@dataclass(frozen=True)
class Not:
    """Antecedent ``{"not": x}``: ``1 - x``."""

    item: Antecedent


Antecedent = TermRef | And | Or | Not


@dataclass(frozen=True)
class Rule:
    """``if`` antecedent ``then`` output term, with a weight scaling the firing strength."""

    antecedent: Antecedent
    then: str
    weight: float = 1.0
    description: str | None = None

    def sentence(self, output: str) -> str:
        """The rule as people write it: ``IF alpha IS low AND dtheta IS high THEN w IS low``
        (``WITH weight`` when it is not 1); ``output`` is the output variable's name."""
        text = f"IF {antecedent_sentence(self.antecedent)} THEN {output} IS {self.then}"
        return text if self.weight == 1.0 else f"{text} WITH {self.weight:g}"


def antecedent_sentence(a: Antecedent, top: bool = True) -> str:
    """``alpha IS low AND (dtheta IS NOT high OR ...)``: keywords in capitals, a negated term
    as ``IS NOT``, other negations as ``NOT (...)``, inner and/or lists in parentheses."""
    if isinstance(a, TermRef):
        return f"{a.input} IS {a.term}"
    if isinstance(a, Not):
        if isinstance(a.item, TermRef):
            return f"{a.item.input} IS NOT {a.item.term}"
        return f"NOT ({antecedent_sentence(a.item, True)})"
    op = " AND " if isinstance(a, And) else " OR "
    body = op.join(antecedent_sentence(x, False) for x in a.items)
    return body if top or len(a.items) == 1 else f"({body})"


# --------------------------------------------------------------------------------------- numbers

class HugeInteger:
    """A JSON integer with more digits than Python converts (its 4300-digit limit), as
    :func:`decode_json` returns it: the validators report it with its key instead of the parser
    failing on the whole document. It is no number and no string (every check refuses it);
    ``str()`` describes it: ``an integer of 5000 digits``.

    Parameters
    ----------
    digits : int
        How many digits the literal has.
    """

    __slots__ = ("digits",)

    def __init__(self, digits: int) -> None:
        self.digits = digits

    def __str__(self) -> str:
        return f"an integer of {self.digits} digits"

    __repr__ = __str__


def _parse_int(text: str) -> int | HugeInteger:
    try:
        return int(text)
    except ValueError:                  # beyond sys.get_int_max_str_digits()
        return HugeInteger(len(text.lstrip("-")))


def decode_json(text: str, where: str | None = None,
                object_pairs_hook: Callable[[list[tuple[str, Any]]], Any] | None = None) -> Any:
    """``json.loads`` for files from elsewhere: every failure a :class:`HybridnavError`.

    Parameters
    ----------
    text : str
    where : str, optional
        Message prefix naming the origin (``"sys.json"``, ``"x.fis: line 5: hybridnav
        metadata"``).
    object_pairs_hook : callable, optional
        As for ``json.loads`` (e.g. to refuse duplicate keys).

    Returns
    -------
    any
        The decoded value. An integer literal with more digits than Python converts comes back
        as a :class:`HugeInteger` (a string saying so), for the validator to refuse with its key.

    Raises
    ------
    HybridnavError
        Invalid JSON (with line and column) or nesting too deep for the parser.
    """
    prefix = f"{where}: " if where else ""
    try:
        return json.loads(text, object_pairs_hook=object_pairs_hook, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise HybridnavError(f"{prefix}line {exc.lineno} column {exc.colno}: invalid JSON "
                             f"({exc.msg})") from None
    except RecursionError:
        raise HybridnavError(f"{prefix}JSON nested too deeply") from None


def finite_number(value: Any) -> float | None:
    """``value`` as a finite ``float`` if it is a finite real number, else None.

    Booleans and non-numbers give None, and so do NaN, infinities and integers beyond the
    largest double (``math.isfinite`` of such an integer raises ``OverflowError``).

    Parameters
    ----------
    value : any

    Returns
    -------
    float or None
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        v = float(value)
    except OverflowError:
        return None
    return v if math.isfinite(v) else None


def range_problem(lo: float, hi: float, points: int, *, output: bool = False) -> str | None:
    """What keeps ``points`` universe samples over ``[lo, hi]`` from being evaluated, or None.

    The one check of a variable's range, for every reader (JSON, FLL, .fis) and for systems
    built in Python. The universe is ``np.linspace(lo, hi, points)`` (``step = (hi - lo) /
    (points - 1)``, sample ``k`` is ``lo + k * step`` rounded, the last is ``hi``), and the
    evaluators need:

    - finite ``lo < hi`` whose width ``hi - lo`` is a finite double (else the step is ``inf``
      and the samples NaN), and samples computed without overflow;
    - samples that increase strictly, at least ``2**-1022`` (the smallest normal double) apart:
      where the step is below the spacing of doubles near ``lo`` and ``hi``, rounding makes
      neighbours equal (``[1, nextafter(1, 2)]`` with 101 points has two distinct samples) and
      the interpolation slopes (membership change / sample gap, up to ``1 / gap``) infinite.
      This is checked on the samples themselves, so it is exact;
    - for the output, a centroid that stays finite: ``max(|lo|, |hi|) * (hi - lo) <=``
      :data:`MAX_MOMENT` (``[-1e308, 1]`` makes the moment integral overflow: NaN, -inf); and a
      width of at least ``eps`` = 2.2e-16: scikit-fuzzy divides the moment by ``max(area, eps)``,
      the area is at most the width, so a narrower output range could never give its centroid.

    Parameters
    ----------
    lo, hi : float
        The range.
    points : int
        Universe samples (>= 2).
    output : bool
        Check it as the output's range (the centroid conditions).

    Returns
    -------
    str or None
        ``"expected ..., got [lo, hi]"``, or None when the range can be evaluated.
    """
    got = f"got [{lo!r}, {hi!r}]"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f"expected a range of finite numbers, {got}"
    if not lo < hi:
        return f"expected a range [lo, hi] with lo < hi, {got}"
    width = hi - lo
    if not math.isfinite(width):
        return f"expected a range whose width hi - lo is finite in double, {got}"
    if output and not max(abs(lo), abs(hi)) * width <= MAX_MOMENT:
        return ("expected an output range with max(|lo|, |hi|) * (hi - lo) <= 2**1000 (the "
                f"centroid's moment integral must stay finite), {got}")
    if output and width < _EPS:
        return (f"expected an output range at least {_EPS!r} wide (the centroid divides by "
                f"max(area, eps) and the area is at most the width), {got}")
    try:
        with np.errstate(over="raise", invalid="raise", divide="ignore", under="ignore"):
            xs = np.linspace(lo, hi, points)
    except FloatingPointError:      # k * step past the largest double (k = points - 1)
        return (f"expected a range whose universe samples lo + k (hi - lo) / {points - 1} are "
                f"finite doubles, {got}")
    gaps = np.diff(xs)
    if not gaps.min() >= _NORMAL:
        return (f"expected a range wide enough for {points} distinct universe samples at least "
                f"2**-1022 apart (steps (hi - lo) / {points - 1} that rounding near lo and hi "
                f"keeps apart), {got}")
    return None


def names_text(names: Sequence[str], limit: int = 160) -> str:
    """``a, b, c`` for a message, cut to about ``limit`` characters (a file may define
    thousands of terms, or very long names).

    Parameters
    ----------
    names : sequence of str
    limit : int
        Longest text returned whole.

    Returns
    -------
    str
    """
    text = ", ".join(names)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(names)} names)"


def _key(k: str) -> str:
    """A key from a file as a key path component, cut when it is long."""
    return k if len(k) <= 60 else short_repr(k, 60)


# --------------------------------------------------------------------------------------- reading

class _Reader:
    """Validation helpers that know the source file for error messages."""

    def __init__(self, source: str | None) -> None:
        self.source = source

    def fail(self, key: str, msg: str) -> HybridnavError:
        if len(key) > 200:                   # antecedents nested hundreds deep
            key = f"{key[:80]}...{key[-100:]}"
        prefix = where(self.source, key) if key else (self.source or "")
        return HybridnavError(f"{prefix}: {msg}" if prefix else msg)

    def mapping(self, value: Any, key: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(key, f"expected an object, got {_typename(value)}")
        for k in value:
            if not isinstance(k, str):
                raise self.fail(key, f"expected string keys, got {short_repr(k)}")
        return value

    def keys(self, value: Mapping[str, Any], key: str, required: Sequence[str],
             optional: Sequence[str] = ()) -> None:
        for k in required:
            if k not in value:
                raise self.fail(_join(key, k), "missing required key")
        allowed = set(required) | set(optional)
        for k in value:
            if k not in allowed:
                raise self.fail(_join(key, _key(k)), f"unknown key (allowed here: "
                                f"{', '.join(sorted(allowed))})")

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"expected a string, got {_typename(value)}")
        if not value.strip():
            raise self.fail(key, "expected a non-empty string")
        return value

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, HugeInteger):
            raise self.fail(key, f"expected a finite number, got {value}")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {_typename(value)}")
        v = finite_number(value)
        if v is None:
            raise self.fail(key, f"expected a finite number, got {short_repr(value)}")
        return v

    def integer(self, value: Any, key: str, lo: int, hi: int) -> int:
        what = f"expected an integer from {lo} to {hi}"
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"{what}, got {_typename(value)}")
        if not lo <= value <= hi:
            raise self.fail(key, f"{what}, got {short_repr(value)}")
        return int(value)

    def array(self, value: Any, key: str) -> Sequence[Any]:
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
            raise self.fail(key, f"expected an array, got {_typename(value)}")
        return value


def _join(key: str, k: str) -> str:
    return f"{key}.{k}" if key else k


def _typename(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, HugeInteger):
        return str(value)
    if isinstance(value, str):
        return f"string {short_repr(value)}"
    if isinstance(value, (int, float)):
        return f"number {short_repr(value)}"
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, Sequence):
        return "an array"
    return type(value).__name__


def _read_terms(r: _Reader, value: Any, key: str) -> tuple[Term, ...]:
    items = r.array(value, key)
    if len(items) == 0:
        raise r.fail(key, "expected at least one term")
    terms: list[Term] = []
    seen: set[str] = set()
    for j, item in enumerate(items):
        k = f"{key}[{j}]"
        d = r.mapping(item, k)
        r.keys(d, k, ("name", "mf", "params"))
        name = r.string(d["name"], f"{k}.name")
        if name in seen:
            raise r.fail(f"{k}.name", f"duplicate term name {short_repr(name)}")
        seen.add(name)
        mf = r.string(d["mf"], f"{k}.mf")
        if mf not in MF_PARAMS:
            raise r.fail(f"{k}.mf", f"unknown membership function {short_repr(mf)} (expected "
                         f"one of {', '.join(MF_PARAMS)})")
        praw = r.array(d["params"], f"{k}.params")
        want = MF_PARAMS[mf]
        if len(praw) != len(want):
            raise r.fail(f"{k}.params", f"expected {len(want)} numbers for {mf}, got "
                         f"{len(praw)} ({mf} takes {', '.join(want)})")
        params = tuple(r.number(v, f"{k}.params[{i}]") for i, v in enumerate(praw))
        problem = check_params(mf, params)
        if problem:
            raise r.fail(f"{k}.params", problem)
        terms.append(Term(name, mf, params))
    return tuple(terms)


def _read_variable_fields(r: _Reader, d: Mapping[str, Any], key: str) -> dict[str, Any]:
    name = r.string(d["name"], f"{key}.name")
    rng = r.array(d["range"], f"{key}.range")
    if len(rng) != 2:
        raise r.fail(f"{key}.range", f"expected 2 numbers [lo, hi], got {len(rng)}")
    lo = r.number(rng[0], f"{key}.range[0]")
    hi = r.number(rng[1], f"{key}.range[1]")
    points = r.integer(d["points"], f"{key}.points", 2, MAX_POINTS)
    problem = range_problem(lo, hi, points, output=key == "output")
    if problem:
        raise r.fail(f"{key}.range", problem)
    terms = _read_terms(r, d["terms"], f"{key}.terms")
    if points * len(terms) > MAX_SAMPLES:
        raise r.fail(f"{key}.points", f"expected points x terms of at most {MAX_SAMPLES} (the "
                                      f"sampled memberships' memory), got {points} x "
                                      f"{len(terms)}")
    return {"name": name, "range": (lo, hi), "points": points, "terms": terms}


#: Largest ``points x terms`` of one variable: its sampled memberships (80 MB of float64)
MAX_SAMPLES = 10_000_000


def _read_antecedent(r: _Reader, value: Any, key: str, inputs: Mapping[str, Variable]) -> Antecedent:
    if isinstance(value, Mapping):
        d = r.mapping(value, key)
        if len(d) != 1 or next(iter(d)) not in ("and", "or", "not"):
            raise r.fail(key, "expected [input, term] or an object with exactly one key "
                         f"'and', 'or' or 'not', got keys {short_repr(sorted(d))}")
        op = next(iter(d))
        k = f"{key}.{op}"
        if op == "not":
            return Not(_read_antecedent(r, d[op], k, inputs))
        items = r.array(d[op], k)
        if len(items) == 0:
            raise r.fail(k, "expected a non-empty array of antecedents")
        parsed = tuple(_read_antecedent(r, it, f"{k}[{i}]", inputs) for i, it in enumerate(items))
        return And(parsed) if op == "and" else Or(parsed)
    if isinstance(value, Sequence) and not isinstance(value, (str, bytes)):
        if len(value) != 2 or not all(isinstance(v, str) for v in value):
            raise r.fail(key, "expected [input, term] (two strings), or an object "
                         "{\"and\": [...]}, {\"or\": [...]} or {\"not\": ...}")
        inp, term = value
        if inp not in inputs:
            raise r.fail(key, f"no input named {short_repr(inp)} (inputs: {names_text(inputs)})")
        if term not in inputs[inp].term_names():
            raise r.fail(key, f"input {short_repr(inp)} has no term {short_repr(term)} "
                         f"(terms: {names_text(inputs[inp].term_names())})")
        return TermRef(inp, term)
    raise r.fail(key, f"expected [input, term] or an object with 'and', 'or' or 'not', "
                 f"got {_typename(value)}")


def parse_system(d: Any, source: str | None = None) -> dict[str, Any]:
    """Validate a ``hybridnav-fis/1`` document and return its parts.

    Parameters
    ----------
    d : mapping
        The decoded JSON document.
    source : str, optional
        File name for error messages.

    Returns
    -------
    dict
        Keys ``name``, ``description``, ``inputs`` (tuple of :class:`Variable`), ``output``
        (:class:`OutputVariable`) and ``rules`` (tuple of :class:`Rule`).

    Raises
    ------
    HybridnavError
        On anything that is not a valid ``hybridnav-fis/1`` system.
    """
    r = _Reader(source)
    doc = r.mapping(d, "")
    if "format" not in doc:
        raise r.fail("format", f"missing required key (expected \"{FORMAT}\")")
    fmt = doc["format"]
    if fmt != FORMAT:
        if isinstance(fmt, str) and fmt.startswith("hybridnav-fis/"):
            raise r.fail("format", f"unsupported format version {short_repr(fmt)}: this "
                         f"hybridnav reads \"{FORMAT}\" (a newer hybridnav may read it)")
        raise r.fail("format", f"expected \"{FORMAT}\", got {_typename(fmt)}")
    r.keys(doc, "", ("format", "name", "inputs", "output", "rules"), ("description",))
    name = r.string(doc["name"], "name")
    description = None
    if "description" in doc:
        if not isinstance(doc["description"], str):
            raise r.fail("description", f"expected a string, got {_typename(doc['description'])}")
        description = doc["description"]

    raw_inputs = r.array(doc["inputs"], "inputs")
    if len(raw_inputs) == 0:
        raise r.fail("inputs", "expected at least one input")
    inputs: dict[str, Variable] = {}
    for i, item in enumerate(raw_inputs):
        k = f"inputs[{i}]"
        dd = r.mapping(item, k)
        r.keys(dd, k, ("name", "range", "points", "terms"))
        var = Variable(**_read_variable_fields(r, dd, k))
        if var.name in inputs:
            raise r.fail(f"{k}.name", f"duplicate input name {short_repr(var.name)}")
        inputs[var.name] = var

    k = "output"
    dd = r.mapping(doc["output"], k)
    r.keys(dd, k, ("name", "range", "points", "terms", "defuzz", "default"))
    fields = _read_variable_fields(r, dd, k)
    if fields["name"] in inputs:
        raise r.fail(f"{k}.name", f"output name {short_repr(fields['name'])} is also an input "
                     "name")
    defuzz = r.string(dd["defuzz"], f"{k}.defuzz")
    if defuzz not in DEFUZZ_METHODS:
        raise r.fail(f"{k}.defuzz", f"unknown defuzzification {short_repr(defuzz)} (expected "
                     f"one of {', '.join(DEFUZZ_METHODS)})")
    default = r.number(dd["default"], f"{k}.default")
    lo, hi = fields["range"]
    if not lo <= default <= hi:
        raise r.fail(f"{k}.default", f"expected a value inside the output range [{lo!r}, {hi!r}], "
                     f"got {default!r}")
    output = OutputVariable(**fields, defuzz=defuzz, default=default)

    raw_rules = r.array(doc["rules"], "rules")
    if len(raw_rules) == 0:
        raise r.fail("rules", "expected at least one rule")
    rules: list[Rule] = []
    for i, item in enumerate(raw_rules):
        k = f"rules[{i}]"
        dd = r.mapping(item, k)
        r.keys(dd, k, ("if", "then"), ("weight", "description"))
        ante = _read_antecedent(r, dd["if"], f"{k}.if", inputs)
        then = r.string(dd["then"], f"{k}.then")
        if then not in output.term_names():
            raise r.fail(f"{k}.then", f"output {short_repr(output.name)} has no term "
                         f"{short_repr(then)} (terms: {names_text(output.term_names())})")
        weight = 1.0
        if "weight" in dd:
            weight = r.number(dd["weight"], f"{k}.weight")
            if not 0.0 <= weight <= 1.0:
                raise r.fail(f"{k}.weight", f"expected a number in [0, 1], got {weight!r}")
        desc = None
        if "description" in dd:
            if not isinstance(dd["description"], str):
                raise r.fail(f"{k}.description",
                             f"expected a string, got {_typename(dd['description'])}")
            desc = dd["description"]
        rules.append(Rule(ante, then, weight, desc))

    return {"name": name, "description": description, "inputs": tuple(inputs.values()),
            "output": output, "rules": tuple(rules)}


# --------------------------------------------------------------------------------------- writing

def antecedent_to_json(a: Antecedent) -> Any:
    """The JSON form of an antecedent (``[input, term]`` or a one-key object)."""
    if isinstance(a, TermRef):
        return [a.input, a.term]
    if isinstance(a, And):
        return {"and": [antecedent_to_json(x) for x in a.items]}
    if isinstance(a, Or):
        return {"or": [antecedent_to_json(x) for x in a.items]}
    if isinstance(a, Not):
        return {"not": antecedent_to_json(a.item)}
    raise TypeError(f"not an antecedent: {a!r}")


def variable_to_json(v: Variable) -> dict[str, Any]:
    """The JSON form of an input or output variable."""
    d: dict[str, Any] = {
        "name": v.name, "range": [v.range[0], v.range[1]], "points": v.points,
        "terms": [{"name": t.name, "mf": t.mf, "params": list(t.params)} for t in v.terms],
    }
    if isinstance(v, OutputVariable):
        d["defuzz"] = v.defuzz
        d["default"] = v.default
    return d
