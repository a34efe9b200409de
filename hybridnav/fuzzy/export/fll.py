"""fuzzylite's FLL (fuzzylite language): export, and import of the subset hybridnav can represent.

Export writes a Mamdani engine that fuzzylite 6 evaluates like :meth:`FuzzySystem.evaluate` up to
the difference between sampled and analytic membership functions (fuzzylite evaluates the
formulas, hybridnav interpolates ``points`` samples) and fuzzylite's midpoint-rule centroid
(``Centroid 1000``):

- terms: ``zmf`` -> ``ZShape``, ``smf`` -> ``SShape``, ``trimf`` -> ``Triangle``, ``trapmf`` ->
  ``Trapezoid``, ``gaussmf`` -> ``Gaussian mean sd``, ``gbellmf a b c`` -> ``Bell c a b``
  (center width slope), ``sigmf b c`` -> ``Sigmoid b c`` (inflection slope);
- inputs ``lock-range: true`` (clipped to the range, as hybridnav does), output ``default:`` the
  system's default, ``aggregation: Maximum``, ``defuzzifier: Centroid 1000``;
- rule block ``conjunction: Minimum``, ``disjunction: Maximum``, ``implication: Minimum``,
  ``activation: General``; rules ``if x is a and (y is b or z is not c) then w is d with 0.5``:
  negation only on a leaf (the ``not`` hedge), so rules are written in negation normal form (see
  :func:`hybridnav.fuzzy.export.normalize`: exact, De Morgan); nested groups are parenthesized
  (fuzzylite binds ``and`` tighter than ``or`` and honours parentheses);
- numbers with Python's shortest exact representation (fuzzylite's own exporter writes 3 decimals);
- what FLL has no key for (universe points, a multi-line description, rule descriptions) goes in a
  ``# hybridnav: {...}`` comment line, which fuzzylite ignores and :func:`read_fll` reads back.

Where a variable's ``points`` do not resolve its terms (e.g. a Z curve spanning a few samples),
the interpolated membership hybridnav evaluates differs visibly from the formula fuzzylite
evaluates; ``to_fll(system, sampled=True)`` then writes every term as a ``Discrete`` polyline of
its samples, which fuzzylite evaluates exactly as hybridnav does.

Import reads that subset: ``Engine`` (``description``), one ``OutputVariable``, any number of
``InputVariable`` s, one ``RuleBlock``; ``enabled: true`` only; ``lock-range`` either way
(hybridnav always clips inputs); the seven term classes above with height 1; ``Maximum``
aggregation, ``Centroid`` (any resolution), ``Minimum`` (or ``none``) conjunction, ``Maximum`` (or
``none``) disjunction, ``Minimum`` implication, ``General`` activation, ``lock-previous: false``;
rules with ``and``, ``or``, parentheses, the ``not`` hedge and ``with``. Universe points come
from the metadata comment, else ``points`` (default :data:`DEFAULT_POINTS` = 101). A ``default``
of ``nan`` (fuzzylite's own default) becomes the middle of the output range, with a warning.
Variable and term names must pass the exporter's rule
(:func:`~hybridnav.fuzzy.export._common.name_problem`: identifiers, no fuzzylite rule words), so
whatever is read can be written again; ranges pass :func:`hybridnav.fuzzy.spec.range_problem`
with the variable's points. Every error is a :class:`HybridnavError` naming the file and line.
"""

from __future__ import annotations

import logging
import math
import re
from typing import Any

from hybridnav.fuzzy.export._common import (
    DEFAULT_POINTS,
    LineError,
    build_system,
    check_name,
    check_names,
    comment_text,
    check_points,
    check_range,
    check_term,
    fnum,
    metadata_json,
    normalize,
    one_line,
    parse_metadata,
    parse_number,
    sampled_polyline,
    version,
)
from hybridnav.fuzzy.spec import (
    And,
    Antecedent,
    Not,
    Or,
    Term,
    TermRef,
    Variable,
    antecedent_to_json,
    names_text,
)
from hybridnav.fuzzy.system import FuzzySystem
from hybridnav.params import short_repr

__all__ = ["to_fll", "read_fll"]

log = logging.getLogger(__name__)

#: hybridnav mf -> (fuzzylite class, order of our parameters in fuzzylite's)
_TO_FL: dict[str, tuple[str, tuple[int, ...]]] = {
    "zmf": ("ZShape", (0, 1)),
    "smf": ("SShape", (0, 1)),
    "trimf": ("Triangle", (0, 1, 2)),
    "trapmf": ("Trapezoid", (0, 1, 2, 3)),
    "gaussmf": ("Gaussian", (0, 1)),
    "gbellmf": ("Bell", (2, 0, 1)),
    "sigmf": ("Sigmoid", (0, 1)),
}
_FROM_FL = {cls: (mf, order) for mf, (cls, order) in _TO_FL.items()}

_META = "# hybridnav:"


# ------------------------------------------------------------------------------------------ export

def fl_term(mf: str, params: tuple[float, ...]) -> str:
    """``Class p1 p2 ...`` for a term (fuzzylite's class and parameter order)."""
    cls, order = _TO_FL[mf]
    return " ".join([cls, *(fnum(params[i]) for i in order)])


def rule_text(a: Antecedent) -> str:
    """An antecedent in fuzzylite syntax; ``a`` must be in negation normal form."""
    def leaf(x: Antecedent) -> str | None:
        k = 0
        while isinstance(x, Not):
            x, k = x.item, k + 1
        if isinstance(x, TermRef):
            return " ".join([x.input, "is", *(["not"] * k), x.term])
        if k:  # pragma: no cover - normal form has negation on leaves only
            raise ValueError("negation of a compound antecedent: normalize first")
        return None

    def text(x: Antecedent, top: bool) -> str:
        s = leaf(x)
        if s is not None:
            return s
        assert isinstance(x, (And, Or))
        op = " and " if isinstance(x, And) else " or "
        body = op.join(text(i, False) for i in x.items)
        return body if top else f"({body})"

    return text(a, True)


def to_fll(system: FuzzySystem, *, sampled: bool = False) -> str:
    """The system as fuzzylite FLL text.

    Parameters
    ----------
    system : FuzzySystem
    sampled : bool
        Write every term as a fuzzylite ``Discrete`` term: the polyline of its universe samples,
        which is exactly the membership hybridnav evaluates, instead of the analytic
        ``ZShape``/``Gaussian``/... (whose values between samples differ from the interpolated
        ones). fuzzylite then differs from :meth:`FuzzySystem.evaluate` only by its centroid
        quadrature. The metadata line keeps the original terms, so :func:`read_fll` still
        returns the system.

    Returns
    -------
    str
        FLL text ending with a newline (see the module docstring for the mapping).

    Raises
    ------
    HybridnavError
        A variable or term name that is not an identifier or is a fuzzylite keyword.
    """
    check_names(system, "fll")
    system = normalize(system)

    def term(v: Variable, t: Term) -> str:
        if not sampled:
            return fl_term(t.mf, t.params)
        return "Discrete " + " ".join(f"{fnum(x)} {fnum(y)}" for x, y in sampled_polyline(v, t))

    lines = [
        f"# hybridnav-fis/1 system exported by hybridnav {version()} as fuzzylite FLL (fuzzylite 6).",
        "# Inputs are clipped to their range (lock-range); 'default' is the output when no rule "
        "fires.",
        "# The next line is hybridnav metadata (universe points, descriptions); fuzzylite ignores "
        "it.",
        f"{_META} {metadata_json(system, name=comment_text(system.name) != system.name, mfs=sampled)}",
        f"Engine: {comment_text(system.name) or 'unnamed'}",
    ]
    if system.description is not None and one_line(system.description):
        lines.append(f"  description: {one_line(system.description)}")
    for v in system.inputs:
        lines += [f"InputVariable: {v.name}", "  enabled: true",
                  f"  range: {fnum(v.range[0])} {fnum(v.range[1])}", "  lock-range: true"]
        lines += [f"  term: {t.name} {term(v, t)}" for t in v.terms]
    o = system.output
    lines += [f"OutputVariable: {o.name}", "  enabled: true",
              f"  range: {fnum(o.range[0])} {fnum(o.range[1])}", "  lock-range: false",
              "  aggregation: Maximum", "  defuzzifier: Centroid 1000",
              f"  default: {fnum(o.default)}", "  lock-previous: false"]
    lines += [f"  term: {t.name} {term(o, t)}" for t in o.terms]
    lines += ["RuleBlock: rules", "  enabled: true", "  conjunction: Minimum",
              "  disjunction: Maximum", "  implication: Minimum", "  activation: General"]
    for r in system.rules:
        w = "" if r.weight == 1.0 else f" with {fnum(r.weight)}"
        lines.append(f"  rule: if {rule_text(r.antecedent)} then {o.name} is {r.then}{w}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ import

_TOKEN = re.compile(r"\(|\)|[^\s()]+")
_MAX_DEPTH = 100


def parse_rule(err: LineError, line: int, text: str, inputs: dict[str, list[str]],
               output: str, out_terms: list[str]) -> tuple[Antecedent, str, float]:
    """Parse ``if <antecedent> then <output> is <term> [with <weight>]``.

    Grammar (fuzzylite's precedence): ``or`` of ``and`` s of items, an item being a parenthesized
    antecedent or ``<input> is [not ...] <term>``. A chain ``a and b and c`` is one ``and`` with
    three items; a parenthesized group is its own node.
    """
    toks = _TOKEN.findall(text)
    pos = 0

    def peek() -> str | None:
        return toks[pos] if pos < len(toks) else None

    def take(what: str) -> str:
        nonlocal pos
        if pos >= len(toks):
            raise err(line, f"rule: expected {what}, got the end of the rule")
        pos += 1
        return toks[pos - 1]

    def expect(word: str) -> None:
        got = take(f"'{word}'")
        if got != word:
            raise err(line, f"rule: expected '{word}', got {short_repr(got)}")

    def item(depth: int) -> Antecedent:
        if depth > _MAX_DEPTH:
            raise err(line, f"rule: parentheses nested deeper than {_MAX_DEPTH}")
        if peek() == "(":
            take("'('")
            a = disjunction(depth + 1)
            expect(")")
            return a
        name = take("an input variable")
        if name not in inputs:
            raise err(line, f"rule: expected an input variable ({names_text(inputs)}), "
                      f"got {short_repr(name)}")
        expect("is")
        k = 0
        while peek() == "not":
            take("'not'")
            k += 1
        term = take(f"a term of {short_repr(name)}")
        if term not in inputs[name]:
            if term in ("any", "very", "somewhat", "extremely", "seldom"):
                raise err(line, f"rule: hedge {short_repr(term)} is not supported (only 'not')")
            raise err(line, f"rule: input {short_repr(name)} has no term {short_repr(term)} "
                      f"(terms: {names_text(inputs[name])})")
        a: Antecedent = TermRef(name, term)
        for _ in range(k):
            a = Not(a)
        return a

    def conjunction(depth: int) -> Antecedent:
        items = [item(depth)]
        while peek() == "and":
            take("'and'")
            items.append(item(depth))
        return items[0] if len(items) == 1 else And(tuple(items))

    def disjunction(depth: int) -> Antecedent:
        items = [conjunction(depth)]
        while peek() == "or":
            take("'or'")
            items.append(conjunction(depth))
        return items[0] if len(items) == 1 else Or(tuple(items))

    expect("if")
    ante = disjunction(0)
    expect("then")
    name = take("the output variable")
    if name != output:
        raise err(line, f"rule: expected the output variable {short_repr(output)} after 'then', "
                  f"got {short_repr(name)}")
    expect("is")
    term = take(f"a term of {short_repr(output)}")
    if term not in out_terms:
        if term in ("not", "any", "very", "somewhat", "extremely", "seldom"):
            raise err(line, "rule: hedges in the consequent are not supported "
                      f"({short_repr(term)})")
        raise err(line, f"rule: output {short_repr(output)} has no term {short_repr(term)} "
                  f"(terms: {names_text(out_terms)})")
    weight = 1.0
    if peek() == "with":
        take("'with'")
        weight = parse_number(err, line, take("a weight"), "rule weight")
        if not 0.0 <= weight <= 1.0:
            raise err(line, f"rule weight: expected a number in [0, 1], got {weight!r}")
    if peek() is not None:
        nxt = peek()
        if nxt == "and":
            raise err(line, "rule: only one consequent is supported")
        raise err(line, f"rule: unexpected {short_repr(nxt)} after the consequent")
    return ante, term, weight


class _Var:
    """A variable being read."""

    def __init__(self, name: str, line: int, output: bool) -> None:
        self.name = name
        self.line = line
        self.output = output
        self.range: tuple[float, float] | None = None
        self.range_line = line
        self.terms: list[tuple[str, str, tuple[float, ...], int]] = []
        self.default: float | None = None
        self.default_line = line


def read_fll(text: str, source: str | None = None, *, points: int = DEFAULT_POINTS) -> FuzzySystem:
    """Read a fuzzy system from fuzzylite FLL text.

    Parameters
    ----------
    text : str
        FLL text (the subset described in the module docstring).
    source : str, optional
        File name for error messages.
    points : int
        Universe samples per variable when the file has no hybridnav metadata line.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        Anything outside the supported subset or invalid; the message names the file and line.
    """
    err = LineError(source)
    check_points(err, None, points, "(points argument)")
    meta: dict[str, Any] = {}
    meta_line = 0
    name: str | None = None
    description: str | None = None
    variables: list[_Var] = []
    section: str | None = None
    block_seen = False
    conj = disj = None
    rules_raw: list[tuple[int, str]] = []
    cur: _Var | None = None

    for n, raw in enumerate(text.splitlines(), start=1):
        stripped = raw.strip()
        if stripped.startswith(_META):
            if meta:
                raise err(n, "a second hybridnav metadata line")
            meta = parse_metadata(stripped[len(_META):], err.where(n))
            meta_line = n
            continue
        line = stripped.split("#", 1)[0].strip()
        if not line:
            continue
        key, sep, value = line.partition(":")
        key, value = key.strip(), value.strip()
        if not sep:
            # before the Engine line the file may be anything: its text is not shown
            raise err(n, f"expected 'key: value', got {line[:60]!r}" if section is not None
                      else "expected 'key: value' (an FLL file starts with 'Engine: NAME'), got "
                           f"a line of {len(line)} characters without ':'")
        if key == "Engine":
            if section is not None:
                raise err(n, "'Engine:' must come first, once")
            section, name = "engine", value
            continue
        if key in ("InputVariable", "OutputVariable"):
            if block_seen:
                raise err(n, f"'{key}:' after the RuleBlock is not supported")
            if not value:
                raise err(n, f"{key}: expected a name")
            check_name(err, n, value, "fll", f"{key} name")
            if any(v.name == value for v in variables):
                raise err(n, f"duplicate variable name {short_repr(value)}")
            out = key == "OutputVariable"
            if out and any(v.output for v in variables):
                raise err(n, "only one OutputVariable is supported")
            cur = _Var(value, n, out)
            variables.append(cur)
            section = "variable"
            continue
        if key == "RuleBlock":
            if block_seen:
                raise err(n, "only one RuleBlock is supported")
            block_seen, section, cur = True, "rules", None
            continue
        if section is None:
            raise err(n, f"expected 'Engine:' before {short_repr(key)}")
        if key == "description":
            if section == "engine":
                description = value
            continue
        if key == "enabled":
            if value != "true":
                raise err(n, f"enabled: only 'true' is supported, got {short_repr(value)}")
            continue
        if section == "engine":
            raise err(n, f"unexpected key {short_repr(key)} in the Engine section")
        if section == "variable":
            assert cur is not None
            _variable_key(err, n, cur, key, value)
            continue
        # rule block
        if key == "conjunction":
            if value not in ("Minimum", "none", ""):
                raise err(n, f"conjunction: only Minimum is supported, got {short_repr(value)}")
            conj = value
        elif key == "disjunction":
            if value not in ("Maximum", "none", ""):
                raise err(n, f"disjunction: only Maximum is supported, got {short_repr(value)}")
            disj = value
        elif key == "implication":
            if value != "Minimum":
                raise err(n, f"implication: only Minimum is supported, got {short_repr(value)}")
        elif key == "activation":
            if value not in ("General", "none", ""):
                raise err(n, f"activation: only General is supported, got {short_repr(value)}")
        elif key == "rule":
            rules_raw.append((n, value))
        else:
            raise err(n, f"unexpected key {short_repr(key)} in the RuleBlock section")

    if section is None:
        raise err(None, "no 'Engine:' section (not an FLL file?)")
    inputs = [v for v in variables if not v.output]
    outputs = [v for v in variables if v.output]
    if not inputs:
        raise err(None, "expected at least one InputVariable")
    if not outputs:
        raise err(None, "expected an OutputVariable")
    o = outputs[0]
    if not block_seen or not rules_raw:
        raise err(None, "expected a RuleBlock with at least one rule")
    pts: dict[str, int] = meta.get("points", {})
    docs: list[dict[str, Any]] = []
    for v in variables:
        if v.range is None:
            raise err(v.line, f"variable {short_repr(v.name)}: missing 'range:'")
        if not v.terms:
            raise err(v.line, f"variable {short_repr(v.name)}: expected at least one term")
        m = pts.get(v.name, points)
        check_range(err, v.range_line, v.range[0], v.range[1], m, "range", output=v.output)
        mfs = meta.get("mfs", {}).get(v.name, {})
        for k, (tname, mf, p, tl) in enumerate(v.terms):
            if not mf:
                if tname not in mfs:
                    raise err(tl, f"term {short_repr(tname)}: Discrete terms are read only from "
                              "files hybridnav wrote with sampled=True (the metadata line names "
                              "the membership function)")
                mf, p = mfs[tname][0], tuple(float(q) for q in mfs[tname][1])
            v.terms[k] = (tname, mf, check_term(err, tl, tname, mf, p, v.range[0], v.range[1],
                                                m), tl)
        d: dict[str, Any] = {"name": v.name, "range": list(v.range), "points": m,
                             "terms": [{"name": t, "mf": mf, "params": list(p)}
                                       for t, mf, p, _ in v.terms]}
        docs.append(d)
    lo, hi = o.range  # type: ignore[misc]
    if o.default is None or math.isnan(o.default):
        default = 0.5 * (lo + hi)
        if "default" not in meta:
            log.warning("%s: output '%s' has no numeric default (fuzzylite returns NaN when no "
                        "rule fires); using the middle of the range, %r",
                        source or "FLL", o.name, default)
    else:
        default = o.default
    default = meta.get("default", default)
    if not lo <= default <= hi:
        raise err(meta_line if "default" in meta else o.default_line,
                  f"default: expected a value inside the output range [{lo!r}, {hi!r}], got "
                  f"{default!r}")
    out_doc = docs[variables.index(o)]
    out_doc.update({"defuzz": "centroid", "default": default})

    in_terms = {v.name: [t[0] for t in v.terms] for v in inputs}
    out_terms = [t[0] for t in o.terms]
    rules: list[dict[str, Any]] = []
    descs = meta.get("rule_descriptions")
    if descs is not None and len(descs) != len(rules_raw):
        log.warning("%s: hybridnav metadata lists %d rule descriptions for %d rules; ignoring "
                    "them", source or "FLL", len(descs), len(rules_raw))
        descs = None
    for k, (n, value) in enumerate(rules_raw):
        ante, then, weight = parse_rule(err, n, value, in_terms, o.name, out_terms)
        if conj in (None, "none", "") and _uses(ante, And):
            raise err(n, "rule uses 'and' but the RuleBlock has no conjunction")
        if disj in (None, "none", "") and _uses(ante, Or):
            raise err(n, "rule uses 'or' but the RuleBlock has no disjunction")
        rd: dict[str, Any] = {"if": antecedent_to_json(ante), "then": then, "weight": weight}
        if descs is not None and descs[k] is not None:
            rd["description"] = descs[k]
        rules.append(rd)

    doc: dict[str, Any] = {"format": "hybridnav-fis/1",
                           "name": meta.get("name") or name or "unnamed"}
    desc = meta.get("description", description)
    if desc is not None:
        doc["description"] = desc
    doc.update({"inputs": [docs[variables.index(v)] for v in inputs], "output": out_doc,
                "rules": rules})
    return build_system(doc, source)


def _uses(a: Antecedent, cls: type) -> bool:
    if isinstance(a, TermRef):
        return False
    if isinstance(a, Not):
        return _uses(a.item, cls)
    return isinstance(a, cls) or any(_uses(i, cls) for i in a.items)


def _bool(err: LineError, n: int, key: str, value: str) -> bool:
    if value not in ("true", "false"):
        raise err(n, f"{key}: expected true or false, got {short_repr(value)}")
    return value == "true"


def _variable_key(err: LineError, n: int, v: _Var, key: str, value: str) -> None:
    """One ``key: value`` line of an InputVariable / OutputVariable section."""
    if key == "range":
        parts = value.split()
        if len(parts) != 2:
            raise err(n, f"range: expected two numbers 'lo hi', got {short_repr(value)}")
        lo = parse_number(err, n, parts[0], "range")
        hi = parse_number(err, n, parts[1], "range")
        v.range, v.range_line = (lo, hi), n   # checked with the points, once they are known
    elif key == "lock-range":
        _bool(err, n, key, value)  # inputs are always clipped by hybridnav
    elif key == "term":
        parts = value.split()
        if len(parts) < 2:
            raise err(n, f"term: expected 'name Class parameters...', got {short_repr(value)}")
        tname, cls, args = parts[0], parts[1], parts[2:]
        check_name(err, n, tname, "fll", "term name")
        if any(t[0] == tname for t in v.terms):
            raise err(n, f"variable {short_repr(v.name)}: duplicate term name {short_repr(tname)}")
        if v.range is None:
            raise err(n, f"term {short_repr(tname)}: 'range:' must come before the terms")
        if cls == "Discrete":  # written by to_fll(sampled=True): the metadata has the mf
            v.terms.append((tname, "", (), n))
            return
        if cls not in _FROM_FL:
            raise err(n, f"term {short_repr(tname)}: class {short_repr(cls)} is not supported "
                      f"(supported: {', '.join(_FROM_FL)})")
        mf, order = _FROM_FL[cls]
        if len(args) not in (len(order), len(order) + 1):
            raise err(n, f"term {short_repr(tname)}: {cls} takes {len(order)} parameters (and an "
                      f"optional height), got {len(args)}")
        nums = [parse_number(err, n, a, f"term {short_repr(tname)}") for a in args]
        if len(nums) > len(order) and nums[-1] != 1.0:
            raise err(n, f"term {short_repr(tname)}: only height 1 is supported, got {nums[-1]!r}")
        params = [0.0] * len(order)
        for k, i in enumerate(order):  # fuzzylite's k-th parameter is our i-th
            params[i] = nums[k]
        v.terms.append((tname, mf, tuple(params), n))
    elif not v.output:
        raise err(n, f"unexpected key {short_repr(key)} in an InputVariable section")
    elif key == "aggregation":
        if value != "Maximum":
            raise err(n, f"aggregation: only Maximum is supported, got {short_repr(value)}")
    elif key == "defuzzifier":
        parts = value.split()
        if not parts or parts[0] != "Centroid" or len(parts) > 2:
            raise err(n, f"defuzzifier: only Centroid is supported, got {short_repr(value)}")
        if len(parts) == 2:
            parse_number(err, n, parts[1], "Centroid resolution")
    elif key == "default":
        if value.lower() == "nan":
            v.default = math.nan
        else:
            v.default = parse_number(err, n, value, "default")
        v.default_line = n
    elif key == "lock-previous":
        if _bool(err, n, key, value):
            raise err(n, "lock-previous: true is not supported (hybridnav systems have no state)")
    elif key == "lock-valid":  # fuzzylite 5's name for lock-previous
        if _bool(err, n, key, value):
            raise err(n, "lock-valid: true is not supported (hybridnav systems have no state)")
    else:
        raise err(n, f"unexpected key {short_repr(key)} in an OutputVariable section")
