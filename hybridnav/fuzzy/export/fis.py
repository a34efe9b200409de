"""MATLAB Fuzzy Logic Toolbox ``.fis`` files: export and import.

The ``.fis`` text has a ``[System]`` section (``Type='mamdani'``, ``AndMethod='min'``,
``OrMethod='max'``, ``ImpMethod='min'``, ``AggMethod='max'``, ``DefuzzMethod='centroid'``), one
``[InputN]`` section per input and one ``[Output1]`` (``Name``, ``Range=[lo hi]``, ``NumMFs``,
``MFk='name':'type',[params]``), and ``[Rules]``, one line per rule::

    2 -1, 1 (0.5) : 1

(term index per input, 1-based, ``0`` = input not used, negative = ``not``; the output term;
the weight; ``1`` = the conditions are joined by AND, ``2`` = by OR). So a .fis rule is one flat
AND or OR over distinct inputs, each condition possibly negated. Export writes
:func:`hybridnav.fuzzy.export.normalize` ``(system, flat=True)`` (exact: negations pushed to the
leaves, nested and-in-and / or-in-or merged) with each rule's conditions in input order, and
raises :class:`HybridnavError` naming the rule when that is still not flat (mixed and/or, one
input twice, a double negation).

MATLAB parameter orders: ``gaussmf [sigma c]`` (hybridnav: mean, sigma) and ``sigmf [a c]``
(slope, center; hybridnav: center, slope) are swapped; ``zmf``, ``smf``, ``trimf``, ``trapmf`` and
``gbellmf`` are the same.

What .fis has no place for:

- the universe points (MATLAB evaluates analytic membership functions), hybridnav's
  ``default`` (MATLAB returns the middle of the output range when no rule fires), descriptions.
  Export writes them on a ``% hybridnav: {...}`` comment line; MATLAB's ``readfis`` and
  fuzzylite skip lines starting with ``%``. Import reads that line when present; otherwise every
  variable gets ``points`` samples (default :data:`DEFAULT_POINTS` = 101) and the default is the
  middle of the output range (what MATLAB returns). Export logs a warning when the system's
  default is not the middle of the range (MATLAB would answer differently there).
- input clipping: hybridnav clips inputs to their range; MATLAB and fuzzylite's .fis reader do not
  (fuzzylite leaves ``lock-range`` off). Inside the ranges they agree.

Import accepts MATLAB's Mamdani files with these seven membership functions (and fuzzylite's
.fis files: ``#`` comments, ``Default=``); every other type, method, hedge code (fractional
indices) or Sugeno system is a :class:`HybridnavError` naming the file and line. Names must pass
the exporter's rule (:func:`~hybridnav.fuzzy.export._common.name_problem`: identifiers, no
fuzzylite rule words, since fuzzylite builds rules from them), ranges
:func:`hybridnav.fuzzy.spec.range_problem` with the variable's points.
"""

from __future__ import annotations

import logging
import re
from typing import Any

from hybridnav.errors import HybridnavError
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
    parse_metadata,
    parse_number,
    version,
)
from hybridnav.fuzzy.spec import And, Antecedent, Not, Or, TermRef, antecedent_to_json
from hybridnav.fuzzy.system import FuzzySystem
from hybridnav.params import short_repr

__all__ = ["to_fis", "read_fis", "fis_rule_row"]

log = logging.getLogger(__name__)

#: hybridnav mf -> order of our parameters in MATLAB's
_TO_MATLAB: dict[str, tuple[int, ...]] = {
    "zmf": (0, 1), "smf": (0, 1), "trimf": (0, 1, 2), "trapmf": (0, 1, 2, 3),
    "gaussmf": (1, 0), "gbellmf": (0, 1, 2), "sigmf": (1, 0),
}
_META = "% hybridnav:"


# ------------------------------------------------------------------------------------------ export

def fis_rule_row(a: Antecedent, input_names: list[str],
                 key: str) -> tuple[list[tuple[bool, str] | None], int]:
    """The conditions of a flat antecedent per input, and MATLAB's connector.

    Parameters
    ----------
    a : Antecedent
        Already :func:`~hybridnav.fuzzy.export.normalize` d with ``flat=True``.
    input_names : list of str
    key : str
        Rule key for error messages (``rules[3]``).

    Returns
    -------
    conditions : list
        Per input: None (not used) or ``(negated, term name)``.
    connector : int
        1 (AND) or 2 (OR).

    Raises
    ------
    HybridnavError
        The antecedent is not one flat AND/OR over distinct inputs.
    """
    if isinstance(a, (TermRef, Not)):
        items: tuple[Antecedent, ...] = (a,)
        connector = 1
    else:
        items = a.items
        connector = 1 if isinstance(a, And) else 2
    conds: list[tuple[bool, str] | None] = [None] * len(input_names)
    for it in items:
        neg = False
        if isinstance(it, Not):
            neg, it = True, it.item
        if not isinstance(it, TermRef):
            kind = "a double negation" if isinstance(it, Not) else "and/or nested in or/and"
            raise HybridnavError(f"{key}: cannot be written as a MATLAB .fis rule ({kind}; .fis "
                                 "rules are one flat AND or OR of conditions on distinct inputs, "
                                 "each possibly negated)")
        i = input_names.index(it.input)
        if conds[i] is not None:
            raise HybridnavError(f"{key}: cannot be written as a MATLAB .fis rule (input "
                                 f"'{it.input}' appears twice; .fis has one column per input)")
        conds[i] = (neg, it.term)
    return conds, connector


def to_fis(system: FuzzySystem) -> str:
    """The system as a MATLAB ``.fis`` file (Fuzzy Logic Toolbox; fuzzylite reads it too).

    Parameters
    ----------
    system : FuzzySystem

    Returns
    -------
    str
        The .fis text, ending with a newline.

    Raises
    ------
    HybridnavError
        A rule that is not one flat AND/OR over distinct inputs (the message names the rule), or
        a name that is not an identifier / is a fuzzylite keyword.
    """
    check_names(system, "fis")
    src = f"{system.source}: " if system.source else ""
    system = normalize(system, flat=True)
    names = [v.name for v in system.inputs]
    o = system.output
    mid = 0.5 * (o.range[0] + o.range[1])
    if o.default != mid:
        log.warning("%s.fis export: output default %r is not the middle of the range; MATLAB "
                    "returns %r where no rule fires (hybridnav's default is kept in a comment)",
                    system.name, o.default, mid)
    rows = []
    for k, r in enumerate(system.rules):
        conds, conn = fis_rule_row(r.antecedent, names, f"{src}rules[{k}]")
        ins = []
        for v, c in zip(system.inputs, conds):
            if c is None:
                ins.append("0")
            else:
                idx = v.term_names().index(c[1]) + 1
                ins.append(str(-idx if c[0] else idx))
        out = o.term_names().index(r.then) + 1
        rows.append(f"{' '.join(ins)}, {out} ({fnum(r.weight)}) : {conn}")

    def mf_line(j: int, t: Any) -> str:
        ps = " ".join(fnum(t.params[i]) for i in _TO_MATLAB[t.mf])
        return f"MF{j}='{t.name}':'{t.mf}',[{ps}]"

    name = comment_text(system.name)      # the exact name travels in the metadata
    lines = [
        f"% hybridnav-fis/1 system exported by hybridnav {version()} as a MATLAB .fis file.",
        f"% When no rule fires hybridnav returns the default {fnum(o.default)}; MATLAB returns the "
        f"middle of the output range ({fnum(mid)}).",
        "% hybridnav clips inputs to their ranges; MATLAB and fuzzylite do not.",
        "% The next line is hybridnav metadata (universe points, default, descriptions); "
        "readfis skips it.",
        f"{_META} {metadata_json(system, default=True, name=name != system.name)}",
        "[System]", f"Name='{name}'", "Type='mamdani'", "Version=2.0",
        f"NumInputs={len(system.inputs)}", "NumOutputs=1", f"NumRules={len(system.rules)}",
        "AndMethod='min'", "OrMethod='max'", "ImpMethod='min'", "AggMethod='max'",
        "DefuzzMethod='centroid'",
    ]
    for i, v in enumerate(system.inputs, start=1):
        lines += ["", f"[Input{i}]", f"Name='{v.name}'",
                  f"Range=[{fnum(v.range[0])} {fnum(v.range[1])}]", f"NumMFs={len(v.terms)}"]
        lines += [mf_line(j, t) for j, t in enumerate(v.terms, start=1)]
    lines += ["", "[Output1]", f"Name='{o.name}'", f"Range=[{fnum(o.range[0])} {fnum(o.range[1])}]",
              f"NumMFs={len(o.terms)}"]
    lines += [mf_line(j, t) for j, t in enumerate(o.terms, start=1)]
    lines += ["", "[Rules]", *rows]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ import

_SECTION = re.compile(r"\[(System|Input(\d+)|Output(\d+)|Rules)\]\Z")
_MF = re.compile(r"'(?P<name>[^']*)'\s*:\s*'(?P<type>[^']*)'\s*,\s*\[(?P<params>[^\]]*)\]\Z")
_RULE = re.compile(r"(?P<ins>[^,]*),(?P<outs>[^(]*)\((?P<w>[^)]*)\)\s*:\s*(?P<conn>\S+)\Z")
_SYSTEM_DEFAULTS = {"AndMethod": "min", "OrMethod": "max", "ImpMethod": "min", "AggMethod": "max",
                    "DefuzzMethod": "centroid"}


def _string(err: LineError, n: int, key: str, value: str) -> str:
    """A MATLAB quoted string ``'text'`` (unquoted text accepted as well)."""
    v = value.strip()
    if len(v) >= 2 and v[0] == "'" and v[-1] == "'":
        v = v[1:-1]
    if "'" in v:
        raise err(n, f"{key}: expected a quoted string, got {short_repr(value)}")
    return v


def _int(err: LineError, n: int, key: str, text: str) -> int:
    v = parse_number(err, n, text, key)
    if v != int(v):
        raise err(n, f"{key}: expected an integer, got {short_repr(text)}")
    if abs(v) > 1e9:
        raise err(n, f"{key}: integer too large: {short_repr(text)}")
    return int(v)


def _numbers(err: LineError, n: int, key: str, text: str) -> list[float]:
    return [parse_number(err, n, t, key) for t in text.replace(",", " ").split()]


class _Section:
    def __init__(self, kind: str, index: int, line: int) -> None:
        self.kind, self.index, self.line = kind, index, line
        self.items: list[tuple[int, str]] = []


def read_fis(text: str, source: str | None = None, *, points: int = DEFAULT_POINTS) -> FuzzySystem:
    """Read a fuzzy system from MATLAB ``.fis`` text.

    Parameters
    ----------
    text : str
        A Mamdani .fis file (see the module docstring for what is supported).
    source : str, optional
        File name for error messages.
    points : int
        Universe samples per variable when the file has no hybridnav metadata line.

    Returns
    -------
    FuzzySystem
        ``default`` is the metadata's, else the middle of the output range (MATLAB's answer when
        no rule fires).

    Raises
    ------
    HybridnavError
        Unsupported or invalid content; the message names the file and line.
    """
    err = LineError(source)
    check_points(err, None, points, "(points argument)")
    meta: dict[str, Any] = {}
    meta_line: int | None = None
    sections: list[_Section] = []
    for n, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line.startswith(_META):
            if meta:
                raise err(n, "a second hybridnav metadata line")
            meta = parse_metadata(line[len(_META):], err.where(n))
            meta_line = n
            continue
        if not line or line[0] in "%#" or line.startswith("//"):
            continue
        m = _SECTION.match(line)
        if m:
            kind = m.group(1)
            idx = int(m.group(2) or m.group(3) or 0) if len(line) < 30 else -1
            sec = _Section("Input" if m.group(2) else "Output" if m.group(3) else kind, idx, n)
            if sec.kind in ("System", "Rules") and any(s.kind == sec.kind for s in sections):
                raise err(n, f"a second [{sec.kind}] section")
            sections.append(sec)
            continue
        if line.startswith("["):
            raise err(n, f"unknown section {line[:40]!r} (expected [System], [InputN], "
                      "[Output1], [Rules])")
        if not sections:
            raise err(n, f"expected [System] first, got a line of {len(line)} characters "
                         "outside any section")  # not shown: the file may be anything
        sections[-1].items.append((n, line))

    system = [s for s in sections if s.kind == "System"]
    if not system:
        raise err(None, "no [System] section (not a .fis file?)")
    sysd: dict[str, tuple[int, str]] = {}
    for n, line in system[0].items:
        key, eq, value = line.partition("=")
        key = key.strip()
        if not eq:
            raise err(n, f"expected Key=value, got {line[:60]!r}")
        if key in sysd:
            raise err(n, f"duplicate key {key}")
        if key not in ("Name", "Type", "Version", "NumInputs", "NumOutputs", "NumRules",
                       "AndMethod", "OrMethod", "ImpMethod", "AggMethod", "DefuzzMethod"):
            raise err(n, f"unknown [System] key {short_repr(key)}")
        sysd[key] = (n, value.strip())

    def sysval(key: str) -> tuple[int, str]:
        if key in sysd:
            n, v = sysd[key]
            return n, _string(err, n, key, v)
        return system[0].line, _SYSTEM_DEFAULTS.get(key, "")

    n, typ = sysval("Type")
    if "Type" in sysd and typ != "mamdani":
        raise err(n, f"Type: only 'mamdani' systems are supported, got {short_repr(typ)}")
    for key, want in _SYSTEM_DEFAULTS.items():
        n, got = sysval(key)
        if got != want:
            raise err(n, f"{key}: only '{want}' is supported (hybridnav uses scikit-fuzzy's "
                      f"Mamdani semantics), got {short_repr(got)}")
    name = sysval("Name")[1].strip() or "unnamed"

    inputs = [s for s in sections if s.kind == "Input"]
    outputs = [s for s in sections if s.kind == "Output"]
    rules_sec = [s for s in sections if s.kind == "Rules"]
    for k, s in enumerate(inputs, start=1):
        if s.index != k:
            raise err(s.line, f"expected [Input{k}] here (inputs are numbered 1, 2, ... in order)")
    if not inputs:
        raise err(None, "expected at least one [InputN] section")
    if len(outputs) != 1 or outputs[0].index != 1:
        raise err(outputs[1].line if len(outputs) > 1 else None,
                  "expected exactly one output section, [Output1] (hybridnav systems have one "
                  "output)")
    if not rules_sec or not rules_sec[0].items:
        raise err(rules_sec[0].line if rules_sec else None,
                  "expected a [Rules] section with at least one rule")
    for key, count in (("NumInputs", len(inputs)), ("NumOutputs", 1),
                       ("NumRules", len(rules_sec[0].items))):
        if key in sysd:
            n, v = sysd[key]
            if _int(err, n, key, v) != count:
                raise err(n, f"{key}={v} but the file has {count}")

    pts: dict[str, int] = meta.get("points", {})
    var_docs = [_read_variable(err, s, pts, points) for s in (*inputs, outputs[0])]
    in_docs, out_doc = var_docs[:-1], var_docs[-1]
    names = [d["name"] for d in in_docs]
    if len(set(names)) != len(names):
        dup = next(x for x in names if names.count(x) > 1)
        raise err(inputs[names.index(dup, names.index(dup) + 1)].line,
                  f"duplicate input name {short_repr(dup)}")
    if out_doc["name"] in names:
        raise err(outputs[0].line, f"output name {short_repr(out_doc['name'])} is also an input "
                  "name")
    lo, hi = out_doc["range"]
    default = meta.get("default", 0.5 * (lo + hi))
    if not lo <= default <= hi:
        raise err(meta_line, f"hybridnav metadata: default {default!r} is outside the output range "
                  f"[{lo!r}, {hi!r}]")
    out_doc.update({"defuzz": "centroid", "default": default})

    rules = []
    rsec = rules_sec[0]
    descs = meta.get("rule_descriptions")
    if descs is not None and len(descs) != len(rsec.items):
        log.warning("%s: hybridnav metadata lists %d rule descriptions for %d rules; ignoring "
                    "them", source or ".fis", len(descs), len(rsec.items))
        descs = None
    for k, (n, line) in enumerate(rsec.items):
        rd = _read_rule(err, n, line, in_docs, out_doc)
        if descs is not None and descs[k] is not None:
            rd["description"] = descs[k]
        rules.append(rd)

    doc: dict[str, Any] = {"format": "hybridnav-fis/1", "name": meta.get("name", name)}
    if "description" in meta:
        doc["description"] = meta["description"]
    doc.update({"inputs": in_docs, "output": out_doc, "rules": rules})
    return build_system(doc, source)


def _read_variable(err: LineError, s: _Section, pts: dict[str, int],
                   points: int) -> dict[str, Any]:
    """An [InputN] / [Output1] section as a hybridnav-fis/1 variable (without defuzz/default)."""
    what = f"[{s.kind}{s.index}]"
    name: str | None = None
    rng: tuple[float, float] | None = None
    rng_line = s.line
    num_mfs: tuple[int, int] | None = None
    mfs: list[tuple[int, int, str, str, list[float]]] = []
    for n, line in s.items:
        key, eq, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not eq:
            raise err(n, f"expected Key=value, got {line[:60]!r}")
        if key == "Name":
            name = check_name(err, n, _string(err, n, key, value), "fis", "Name")
        elif key == "Range":
            if not (value.startswith("[") and value.endswith("]")):
                raise err(n, f"Range: expected [lo hi], got {short_repr(value)}")
            nums = _numbers(err, n, "Range", value[1:-1])
            if len(nums) != 2:
                raise err(n, f"Range: expected two numbers [lo hi], got {short_repr(value)}")
            rng, rng_line = (nums[0], nums[1]), n   # checked with the points below
        elif key == "NumMFs":
            num_mfs = (n, _int(err, n, key, value))
        elif key.startswith("MF") and key[2:].isdigit():
            if len(key) >= 12:                 # the key reaches messages: keep it short
                raise err(n, f"expected MF{len(mfs) + 1} here (membership functions are "
                          f"numbered 1, 2, ...), got {short_repr(key)}")
            m = _MF.match(value)
            if not m:
                raise err(n, f"{key}: expected 'name':'type',[params], got {value[:60]!r}")
            mfs.append((n, int(key[2:]), m.group("name"), m.group("type"),
                        _numbers(err, n, key, m.group("params"))))
        elif key == "Enabled" or (s.kind == "Output" and key in ("LockPrevious", "LockRange")):
            v = _int(err, n, key, value)
            if key == "Enabled" and v != 1:
                raise err(n, "Enabled: disabled variables are not supported")
            if key == "LockPrevious" and v != 0:
                raise err(n, "LockPrevious: not supported (hybridnav systems have no state)")
        elif s.kind == "Output" and key == "Default":
            continue  # fuzzylite's extension; hybridnav's default comes from metadata / mid-range
        else:
            raise err(n, f"unknown {what} key {short_repr(key)}")
    if name is None:
        raise err(s.line, f"{what}: missing Name=")
    if rng is None:
        raise err(s.line, f"{what}: missing Range=[lo hi]")
    if not mfs:
        raise err(s.line, f"{what}: expected at least one membership function MFk=...")
    if num_mfs is not None and num_mfs[1] != len(mfs):
        raise err(num_mfs[0], f"NumMFs={num_mfs[1]} but {what} has {len(mfs)} MF lines")
    m_pts = check_points(err, s.line, pts.get(name, points), name)
    check_range(err, rng_line, rng[0], rng[1], m_pts, f"{what} Range", output=s.kind == "Output")
    terms = []
    seen: set[str] = set()
    for k, (n, idx, tname, typ, params) in enumerate(mfs, start=1):
        if idx != k:
            raise err(n, f"expected MF{k} here (membership functions are numbered 1, 2, ...)")
        check_name(err, n, tname, "fis", f"MF{k} name")
        if tname in seen:
            raise err(n, f"MF{k}: duplicate term name {short_repr(tname)}")
        seen.add(tname)
        if typ not in _TO_MATLAB:
            raise err(n, f"MF{k} {short_repr(tname)}: membership function {short_repr(typ)} is "
                      f"not supported (supported: {', '.join(_TO_MATLAB)})")
        order = _TO_MATLAB[typ]
        if len(params) != len(order):
            raise err(n, f"MF{k} {short_repr(tname)}: {typ} takes {len(order)} parameters, got "
                      f"{len(params)}")
        ours = [0.0] * len(order)
        for k, i in enumerate(order):  # MATLAB's k-th parameter is our i-th
            ours[i] = params[k]
        p = check_term(err, n, tname, typ, ours, rng[0], rng[1], m_pts)
        terms.append({"name": tname, "mf": typ, "params": list(p)})
    return {"name": name, "range": list(rng), "points": m_pts, "terms": terms}


def _read_rule(err: LineError, n: int, line: str, in_docs: list[dict[str, Any]],
               out_doc: dict[str, Any]) -> dict[str, Any]:
    """One [Rules] line ``i1 i2 ..., o (w) : c`` as a hybridnav-fis/1 rule."""
    m = _RULE.match(line)
    if not m:
        raise err(n, f"expected a rule 'i1 i2 ..., o (weight) : 1|2', got {line[:60]!r}")
    ins = m.group("ins").replace(",", " ").split()
    outs = m.group("outs").split()
    if len(ins) != len(in_docs):
        raise err(n, f"rule: expected {len(in_docs)} input codes, got {len(ins)}")
    if len(outs) != 1:
        raise err(n, f"rule: expected 1 output code, got {len(outs)}")
    weight = parse_number(err, n, m.group("w").strip(), "rule weight")
    if not 0.0 <= weight <= 1.0:
        raise err(n, f"rule weight: expected a number in [0, 1], got {weight!r}")
    conn = m.group("conn")
    if conn not in ("1", "2"):
        raise err(n, f"rule connector: expected 1 (AND) or 2 (OR), got {short_repr(conn)}")
    leaves: list[Antecedent] = []
    for d, code_s in zip(in_docs, ins):
        code = parse_number(err, n, code_s, "rule input code")
        if code != int(code):
            raise err(n, f"rule: input code {short_repr(code_s)} has a hedge (fractional part); "
                      "hedges are not supported")
        c = int(code)
        if c == 0:
            continue
        if abs(c) > len(d["terms"]):
            raise err(n, f"rule: input {short_repr(d['name'])} has {len(d['terms'])} terms, got "
                      f"code {short_repr(code_s)}")
        leaf: Antecedent = TermRef(d["name"], d["terms"][abs(c) - 1]["name"])
        leaves.append(Not(leaf) if c < 0 else leaf)
    if not leaves:
        raise err(n, "rule: every input code is 0 (a rule needs at least one condition)")
    oc = parse_number(err, n, outs[0], "rule output code")
    if oc != int(oc) or not 1 <= oc <= len(out_doc["terms"]):
        raise err(n, f"rule: output code must be a term index 1..{len(out_doc['terms'])} "
                  "(negated or hedged consequents are not supported), got "
                  f"{short_repr(outs[0])}")
    ante: Antecedent = leaves[0] if len(leaves) == 1 else (
        And(tuple(leaves)) if conn == "1" else Or(tuple(leaves)))
    return {"if": antecedent_to_json(ante), "then": out_doc["terms"][int(oc) - 1]["name"],
            "weight": weight}
