"""The JSON, FLL and .fis importers on damaged and hostile text: they return a system or raise
HybridnavError naming the file and the line (FLL, .fis) or key (JSON) -- never another exception,
never a hang, never a message over 600 characters. Mutations of valid exports: truncation, random
characters, swapped / deleted / duplicated lines and tokens, numbers replaced by huge (400 to
5000 digits, past Python's 4300-digit limit), tiny, NaN, infinite or negative values, ranges
replaced by ones a float step wide, far from zero or as wide as doubles go; plus arbitrary text.

What a reader accepts must be what the evaluators can represent: on a grid of inputs ``evaluate``
(batch and single samples) gives finite outputs inside the output range -- except where
scikit-fuzzy's centroid divides by ``eps`` instead of an aggregated area below it (tiny
activations), which pulls the output towards 0 (the area is computed here independently of the
engine) -- and an accepted FLL or .fis system can be exported to its format again (readers and
exporters share one rule for names).

``HYBRIDNAV_FUZZ_EXAMPLES=N`` runs every fuzz test here with N examples (a long run; the default
counts keep the suite fast).
"""

from __future__ import annotations

import math
import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export import ZOO, ZOO_FLAT, rule_strengths

from hybridnav import HybridnavError, fuzzy
from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.engine import universe
from hybridnav.fuzzy.export import (
    export,
    load_any,
    normalize,
    read_fis,
    read_fll,
    read_json,
    read_text,
)
from hybridnav.fuzzy.mf import sample

#: examples of the long fuzz run (``HYBRIDNAV_FUZZ_EXAMPLES``), else each test's own count
_LONG = os.environ.get("HYBRIDNAV_FUZZ_EXAMPLES", "").strip()


def examples(default: int) -> int:
    """``default``, or the count ``HYBRIDNAV_FUZZ_EXAMPLES`` asks for."""
    return int(_LONG) if _LONG else default


SOURCES = {
    "json": [export(fuzzy.builtin("effc-5rule"), "json"),
             export(FuzzySystem.from_dict(ZOO), "json")],
    "fll": [export(fuzzy.builtin("effc-5rule"), "fll"),
            export(FuzzySystem.from_dict(ZOO), "fll"),
            export(fuzzy.builtin("effc-2rule"), "fll", sampled=True)],
    "fis": [export(fuzzy.builtin("effc-5rule"), "fis"),
            export(FuzzySystem.from_dict(ZOO_FLAT), "fis")],
}
WEIRD_NUMBERS = ["1e308", "-1e308", "1e999", "nan", "NaN", "inf", "-inf", "1e-320", "0", "-0.0",
                 "2", "3", "-7", "0.5", "1e18", "99999999999999999999999", "1000000", "0x10",
                 "1_0", "", "--1", "1e-300", "[", "'", "(", ")", "#", "%", ":", ",", "=", "is",
                 "not", "and"]
#: numbers past what doubles and Python's int() take, and the non-finite spellings of each format
HOSTILE_NUMBERS = ["9" * 400, "-" + "9" * 400, "1" + "0" * 4300, "9" * 5000, "-" + "8" * 5000,
                   "1." + "3" * 5000, "1e308", "-1e308", "1.7976931348623157e308", "5e-324",
                   "-1e-310", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "-Infinity", "Inf",
                   "1e400"]
_NUM = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
# a range in the three formats: JSON "range": [lo, hi], FLL range: lo hi, .fis Range=[lo hi]
_RANGE = re.compile(r'(?P<pre>"range": \[|range: |Range=\[)(?P<lo>[^\s,\]]+)(?P<sep>,? )'
                    r'(?P<hi>[^\s,\]]+)')


def _hostile_range(draw) -> tuple[float, float]:
    """A range the evaluators cannot use, or can only just: a float step wide at some
    magnitude, a number of steps around what 101 or 1001 distinct samples need, as wide as
    doubles go (or the centroid's moments allow), far from zero, next to zero."""
    x = draw(st.sampled_from([1.0, -1.0, 0.5, 3.0, 1e6, -1e6, 1e15, 1e-300, 0.0, 1e300, -7.5]))
    kind = draw(st.sampled_from(["step", "steps", "huge", "far", "tiny", "eps"]))
    if kind == "step":
        return x, math.nextafter(x, math.inf)
    if kind == "steps":
        m = draw(st.sampled_from([2, 3, 50, 99, 100, 101, 150, 999, 1000, 1001, 5000, 10**5]))
        return x, x + m * math.ulp(x)
    if kind == "huge":
        return draw(st.sampled_from([(-1e308, 1.0), (-1.7e308, 1.7e308), (0.0, 1e308),
                                     (-1e200, 1e200), (1e150, 1e151), (-1e154, 1e154),
                                     (-1e150, 1e150), (0.0, 2.0 ** 500), (-2.0 ** 499, 2.0 ** 499),
                                     (0.0, 1.7976931348623157e308)]))
    if kind == "far":
        return x, x + draw(st.sampled_from([1e-12, 1e-9, 1.0, 1e-16 * max(abs(x), 1.0)]))
    if kind == "tiny":
        return draw(st.sampled_from([(0.0, 1e-300), (1e-300, 2e-300), (0.0, 5e-324),
                                     (-1e-310, 1e-310), (0.0, 1e-307)]))
    return x, x + draw(st.sampled_from([2.220446049250313e-16, 1.1e-16, 4.5e-16]))


KINDS = ("truncate", "insert", "replace_number", "swap_tokens", "swap_lines", "delete_line",
         "duplicate_line", "replace_char", "hostile_number", "hostile_range")
#: the mutations of numbers only (most such files still parse: the numeric checks get the work)
NUMBER_KINDS = ("replace_number", "hostile_number", "hostile_range")


@st.composite
def mutated(draw, fmt: str | list[str], kinds: tuple[str, ...] = KINDS) -> str:
    """A valid text of ``fmt`` (a key of SOURCES, or a list of texts) damaged 1-4 times by
    mutations of ``kinds``."""
    text = draw(st.sampled_from(SOURCES[fmt] if isinstance(fmt, str) else fmt))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(kinds))
        lines = text.split("\n")
        if kind == "truncate":
            text = text[:draw(st.integers(0, len(text)))]
        elif kind == "insert":
            pos = draw(st.integers(0, len(text)))
            text = text[:pos] + draw(st.text(min_size=1, max_size=8)) + text[pos:]
        elif kind == "replace_char":
            pos = draw(st.integers(0, max(len(text) - 1, 0)))
            text = text[:pos] + draw(st.characters()) + text[pos + 1:]
        elif kind == "replace_number":
            nums = list(_NUM.finditer(text))
            if nums:
                m = nums[draw(st.integers(0, len(nums) - 1))]
                text = text[:m.start()] + draw(st.sampled_from(WEIRD_NUMBERS)) + text[m.end():]
        elif kind == "hostile_number":
            nums = list(_NUM.finditer(text))
            if nums:
                m = nums[draw(st.integers(0, len(nums) - 1))]
                text = text[:m.start()] + draw(st.sampled_from(HOSTILE_NUMBERS)) + text[m.end():]
        elif kind == "hostile_range":
            ranges = list(_RANGE.finditer(text))
            if ranges:
                m = ranges[draw(st.integers(0, len(ranges) - 1))]
                lo, hi = _hostile_range(draw)
                text = (text[:m.start()] + m["pre"] + repr(lo) + m["sep"] + repr(hi)
                        + text[m.end():])
        elif kind == "swap_tokens":
            toks = re.split(r"(\s+)", text)
            if len(toks) > 2:
                i, j = draw(st.integers(0, len(toks) - 1)), draw(st.integers(0, len(toks) - 1))
                toks[i], toks[j] = toks[j], toks[i]
                text = "".join(toks)
        elif kind == "swap_lines" and len(lines) > 1:
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
        elif kind == "delete_line" and lines:
            del lines[draw(st.integers(0, len(lines) - 1))]
            text = "\n".join(lines)
        elif kind == "duplicate_line" and lines:
            i = draw(st.integers(0, len(lines) - 1))
            lines.insert(i, lines[i])
            text = "\n".join(lines)
    return text


def check(fmt: str, text: str) -> None:
    source = f"sys.{fmt}"
    try:
        fs = read_text(text, fmt, source)
    except HybridnavError as exc:
        msg = str(exc)
        assert msg.startswith(f"{source}: "), msg
        assert len(msg) < 600, msg[:2000]                  # long values are cut
        rest = msg[len(source) + 2:]
        if fmt == "json":  # "line L column C: ...", "<key path>: ...", or a whole-document problem
            assert ": " in rest or rest.startswith(("expected", "duplicate key", "JSON")), msg
        else:  # "line N: ..." or a whole-file problem naming what is missing
            assert re.match(r"line \d+: ", rest) or re.search(
                r"expected|missing|no '|no \[|section", rest), msg
        return
    assert isinstance(fs, FuzzySystem)
    check_evaluates_inside_its_range(fs)
    if fmt != "json":                  # JSON carries any name; FLL and .fis what they can write
        assert read_text(export(fs, fmt), fmt) == normalize(fs, flat=fmt == "fis")


def grid(fs: FuzzySystem, n: int = 7) -> dict[str, np.ndarray]:
    """``n`` points per input over its range (between universe samples too), all combinations."""
    with np.errstate(over="ignore"):         # k * step near the largest double: hi replaces it
        axes = [np.linspace(v.range[0], v.range[1], n) for v in fs.inputs]
    mesh = np.meshgrid(*axes, indexing="ij")
    return {name: m.ravel() for name, m in zip(fs.input_names, mesh)}


def aggregated_area(fs: FuzzySystem, X: dict[str, np.ndarray]) -> np.ndarray:
    """scikit-fuzzy's aggregated output area per sample, computed without the engine: rule
    strengths from np.interp of the sampled input terms (min / max / 1 - x, times the weight),
    each output term cut at its largest strength, the universe upsampled at every cut's
    crossings (``_interp_universe_fast``), the clipped terms' maximum integrated as a polyline."""
    n = len(next(iter(X.values())))
    cuts = {t.name: np.zeros(n) for t in fs.output.terms}
    for r, strength in zip(fs.rules, rule_strengths(fs, X)):
        cuts[r.then] = np.maximum(cuts[r.then], strength)
    xs = universe(fs.output)
    F = {t.name: sample(t.mf, t.params, xs) for t in fs.output.terms}
    area = np.empty(n)
    for b in range(n):
        live = [(F[name], c[b]) for name, c in cuts.items() if c[b] > 0.0]
        new = [xs]
        for f, c in live:
            above = f >= c
            i = np.flatnonzero(above[:-1] != above[1:])
            new.append(xs[i] + (c - f[i]) * (xs[i + 1] - xs[i]) / (f[i + 1] - f[i]))
        u = np.union1d(xs, np.concatenate(new))
        agg = np.zeros(len(u))
        for f, c in live:
            np.maximum(agg, np.minimum(c, np.interp(u, xs, f)), out=agg)
        area[b] = np.trapezoid(agg, u)
    return area


def check_evaluates_inside_its_range(fs: FuzzySystem) -> None:
    """Finite outputs on a grid, inside the output range (to rounding); where the aggregated
    area is below eps scikit-fuzzy's centroid is moment / eps, between 0 and the centroid."""
    X = grid(fs)
    y = fs.evaluate(**X)
    k = np.linspace(0, len(y) - 1, 5).astype(int)          # the single-sample path agrees
    one = np.array([fs.evaluate(**{n: float(c[i]) for n, c in X.items()}) for i in k])
    np.testing.assert_allclose(one, y[k], rtol=1e-9, atol=1e-12 * np.abs(fs.output.range).max())
    assert np.all(np.isfinite(y)), (fs.output.range, y[~np.isfinite(y)][:5])
    lo, hi = fs.output.range
    tol = 1e-9 * (hi - lo) + 1e-12 * max(abs(lo), abs(hi))
    inside = (y >= lo - tol) & (y <= hi + tol)
    if not inside.all():
        floor = aggregated_area(fs, {n: c[~inside] for n, c in X.items()}) < 1.000001 * EPS
        yo = y[~inside]
        assert floor.all(), (fs.output.range, yo[~floor][:5])
        assert np.all((yo >= min(lo, 0.0) - tol) & (yo <= max(hi, 0.0) + tol)), (lo, hi, yo)


EPS = float(np.finfo(float).eps)


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_the_sources_are_valid(fmt):
    for text in SOURCES[fmt]:
        assert isinstance(read_text(text, fmt), FuzzySystem)


@settings(deadline=None, max_examples=examples(300), suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), fmt=st.sampled_from(["json", "fll", "fis"]))
def test_mutated_files(data, fmt):
    check(fmt, data.draw(mutated(fmt)))


@settings(deadline=None, max_examples=examples(300),
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), fmt=st.sampled_from(["json", "fll", "fis"]))
def test_number_mutations(data, fmt):
    check(fmt, data.draw(mutated(fmt, NUMBER_KINDS)))


@settings(deadline=None, max_examples=examples(150))
@given(text=st.text(max_size=300), fmt=st.sampled_from(["json", "fll", "fis"]))
def test_arbitrary_text(text, fmt):
    check(fmt, text)


@settings(deadline=None, max_examples=examples(100))
@given(prefix=st.sampled_from(["Engine: x\nInputVariable: a\n", "[System]\n", '{"format": "h']),
       body=st.text(alphabet=st.sampled_from(list("()[]{}'\":=,# \n%-.0123456789eEanotisf")),
                    max_size=200))
def test_near_miss_text(prefix, body):
    fmt = "fll" if prefix.startswith("Engine") else "fis" if prefix.startswith("[") else "json"
    check(fmt, prefix + body)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_hostile_inputs_are_user_errors(tmp_path):
    deep = "(" * 5000 + "a is t" + ")" * 5000
    fll = SOURCES["fll"][0].replace("rule: if alpha is low then w is low",
                                    f"rule: if {deep} then w is low")
    with pytest.raises(HybridnavError, match=r"^x\.fll: line \d+: rule: parentheses nested "):
        read_fll(fll, "x.fll")
    with pytest.raises(HybridnavError, match=r"^x\.json: JSON nested too deeply"):
        read_json('{"a": ' * 100000 + "1" + "}" * 100000, "x.json")
    d = fuzzy.builtin("effc-2rule").to_dict()
    d["output"]["points"] = 10**12
    import json

    with pytest.raises(HybridnavError, match=r"^x\.json: output\.points: expected an integer from 2 to 1000000"):
        read_json(json.dumps(d), "x.json")
    d = fuzzy.builtin("effc-2rule").to_dict()
    d["inputs"][0]["terms"][0] = {"name": "low", "mf": "gaussmf", "params": [0.0, 1e-170]}
    with pytest.raises(HybridnavError, match=r"^x\.json: inputs\[0\]\.terms\[0\]\.params: "
                       r"expected parameters whose membership values are finite"):
        read_json(json.dumps(d), "x.json")
    fis = SOURCES["fis"][0].replace("MF1='low':'zmf',[0.2 1.2]", "MF1='low':'gaussmf',[1e-170 0]")
    with pytest.raises(HybridnavError, match=r"^x\.fis: line \d+: term 'low': gaussmf"):
        read_fis(fis, "x.fis")
    meta = SOURCES["fis"][0].replace('"dtheta": 101', '"dtheta": 1000000000')
    with pytest.raises(HybridnavError, match=r"^x\.fis: line 5: hybridnav metadata: points of "):
        read_fis(meta, "x.fis")
    (tmp_path / "bin.fis").write_bytes(b"\xff\xfe[System]\n")
    with pytest.raises(HybridnavError, match=r"bin\.fis: not UTF-8 text"):
        load_any(tmp_path / "bin.fis")
    with pytest.raises(HybridnavError, match=r"nope\.fll: cannot read"):
        load_any(tmp_path / "nope.fll")
    with pytest.raises(HybridnavError, match=r"unknown fuzzy system file type '\.txt'"):
        load_any(tmp_path / "x.txt")


@pytest.mark.parametrize("old,new,msg", [
    ("DefuzzMethod='centroid'", "DefuzzMethod='mom'",
     r"line 17: DefuzzMethod: only 'centroid' is supported"),
    ("AndMethod='min'", "AndMethod='prod'", r"line 13: AndMethod: only 'min' is supported"),
    ("AggMethod='max'", "AggMethod='sum'", r"line 16: AggMethod: only 'max' is supported"),
    ("Type='mamdani'", "Type='sugeno'", r"line 8: Type: only 'mamdani'"),
    ("NumMFs=2\nMF1='low':'zmf',[0.2 1.2]", "NumMFs=3\nMF1='low':'zmf',[0.2 1.2]",
     r"line 22: NumMFs=3 but \[Input1\] has 2 MF lines"),
    ("MF1='low':'zmf',[0.2 1.2]", "MF1='low':'pimf',[0.2 1.2 1 2]",
     r"line 23: MF1 'low': membership function 'pimf' is not supported"),
    ("MF1='low':'zmf',[0.2 1.2]", "MF1='low':'zmf',[1.2 0.2]", r"line 23: term 'low': expected a < b"),
    ("2 1, 1 (1.0) : 1", "2.2 1, 1 (1.0) : 1", r"line 4\d: rule: input code '2.2' has a hedge"),
    ("2 1, 1 (1.0) : 1", "2 1, -1 (1.0) : 1", r"line 4\d: rule: output code must be a term index"),
    ("2 1, 1 (1.0) : 1", "2 1, 1 (1.5) : 1", r"line 4\d: rule weight: expected a number in \[0, 1\]"),
    ("2 1, 1 (1.0) : 1", "2 1, 1 (1.0) : 3", r"line 4\d: rule connector: expected 1 \(AND\) or 2"),
    ("2 1, 1 (1.0) : 1", "2 1 1, 1 (1.0) : 1", r"line 4\d: rule: expected 2 input codes, got 3"),
    ("NumOutputs=1", "NumOutputs=2", r"line 11: NumOutputs=2 but the file has 1"),
    ("Range=[0.0 2.0]", "Range=[2.0 0.0]", r"line 28: \[Input2\] Range: expected a range"),
])
def test_fis_errors_name_the_line(old, new, msg):
    text = SOURCES["fis"][0]
    assert old in text
    with pytest.raises(HybridnavError, match=rf"^c\.fis: {msg}"):
        read_fis(text.replace(old, new, 1), "c.fis")


@pytest.mark.parametrize("old,new,msg", [
    ("aggregation: Maximum", "aggregation: AlgebraicSum", r"aggregation: only Maximum"),
    ("defuzzifier: Centroid 1000", "defuzzifier: Bisector 1000", r"defuzzifier: only Centroid"),
    ("implication: Minimum", "implication: AlgebraicProduct", r"implication: only Minimum"),
    ("conjunction: Minimum", "conjunction: AlgebraicProduct", r"conjunction: only Minimum"),
    ("term: low ZShape 0.2 1.2", "term: low PiShape 0.2 1.2 1 2", r"term 'low': class 'PiShape' is not"),
    ("term: low ZShape 0.2 1.2", "term: low ZShape 0.2 1.2 0.5", r"term 'low': only height 1 is supported"),
    ("term: low ZShape 0.2 1.2", "term: low ZShape 0.2 inf", r"term 'low': expected a finite number"),
    ("  enabled: true\n  range: 0.0 2.0", "  enabled: false\n  range: 0.0 2.0",
     r"enabled: only 'true' is supported"),
    ("lock-previous: false", "lock-previous: true", r"lock-previous: true is not supported"),
    ("if alpha is low then w is low", "if alpha is very low then w is low",
     r"rule: hedge 'very' is not supported"),
    ("if alpha is low then w is low", "if alpha is low then w is low and w is high",
     r"rule: only one consequent"),
    ("if alpha is low then w is low", "if alpha is low then w is low with 2",
     r"rule weight: expected a number in \[0, 1\]"),
    ("if alpha is low then w is low", "if (alpha is low then w is low", r"rule: expected '\)'"),
    ("if alpha is low then w is low", "if beta is low then w is low", r"rule: expected an input"),
    ("default: 0.5", "default: 3.0", r"default: expected a value inside the output range"),
])
def test_fll_errors_name_the_line(old, new, msg):
    text = SOURCES["fll"][0]
    assert old in text
    with pytest.raises(HybridnavError, match=rf"^c\.fll: line \d+: {msg}"):
        read_fll(text.replace(old, new, 1), "c.fll")


def test_fll_default_nan_becomes_mid_range(caplog):
    text = SOURCES["fll"][0].replace("default: 0.5", "default: nan")
    text = "\n".join(ln for ln in text.splitlines() if not ln.startswith("# hybridnav:"))
    fs = read_fll(text, "f.fll")
    assert fs.output.default == 0.5 and "no numeric default" in caplog.text
    assert {v.points for v in (*fs.inputs, fs.output)} == {101}
