"""The JSON, FLL and .fis importers on damaged and hostile text: they return a system or raise
HybridnavError naming the file and the line (FLL, .fis) or key (JSON) -- never another exception,
never a hang. Mutations of valid exports: truncation, random characters, swapped / deleted /
duplicated lines and tokens, numbers replaced by huge, tiny, NaN, infinite or negative values;
plus arbitrary text and bytes."""

from __future__ import annotations

import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export import ZOO, ZOO_FLAT

from hybridnav import HybridnavError, fuzzy
from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.export import (
    export,
    load_any,
    read_fis,
    read_fll,
    read_json,
    read_text,
)

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
                 "2", "-7", "0.5", "1e18", "99999999999999999999999", "0x10", "1_0", "", "--1",
                 "1e-300", "[", "'", "(", ")", "#", "%", ":", ",", "=", "is", "not", "and"]
_NUM = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


@st.composite
def mutated(draw, fmt: str | list[str]) -> str:
    """A valid text of ``fmt`` (a key of SOURCES, or a list of texts) damaged 1-4 times."""
    text = draw(st.sampled_from(SOURCES[fmt] if isinstance(fmt, str) else fmt))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["truncate", "insert", "replace_number", "swap_tokens",
                                     "swap_lines", "delete_line", "duplicate_line", "replace_char"]))
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
        rest = msg[len(source) + 2:]
        if fmt == "json":  # "line L column C: ...", "<key path>: ...", or a whole-document problem
            assert ": " in rest or rest.startswith(("expected", "duplicate key", "JSON")), msg
        else:  # "line N: ..." or a whole-file problem naming what is missing
            assert re.match(r"line \d+: ", rest) or re.search(
                r"expected|missing|no '|no \[|section", rest), msg
        return
    assert isinstance(fs, FuzzySystem)
    # whatever was accepted evaluates
    fs.evaluate(**{n: 0.0 for n in fs.input_names})


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_the_sources_are_valid(fmt):
    for text in SOURCES[fmt]:
        assert isinstance(read_text(text, fmt), FuzzySystem)


@settings(deadline=None, max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), fmt=st.sampled_from(["json", "fll", "fis"]))
def test_mutated_files(data, fmt):
    check(fmt, data.draw(mutated(fmt)))


@settings(deadline=None, max_examples=150)
@given(text=st.text(max_size=300), fmt=st.sampled_from(["json", "fll", "fis"]))
def test_arbitrary_text(text, fmt):
    check(fmt, text)


@settings(deadline=None, max_examples=100)
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
    ("2 1, 1 (1.0) : 1", "2.2 1, 1 (1.0) : 1", r"line 4\d: rule: input code 2.2 has a hedge"),
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
