"""The three fuzzy-system readers (hybridnav-fis/1 JSON, fuzzylite FLL, MATLAB .fis) on hostile
numbers and names (issue 27): never a traceback, never a system the evaluators cannot represent.

One test per class, in every format where the class applies, each asserting the exact message
(file, key or line, what was expected, the value cut short):

- integers past Python's 4300-digit limit (``json.loads`` raised ValueError on the document);
- numbers past the largest double (a 400-digit range made ``float()`` raise OverflowError);
- ranges whose centroid overflows (``[-1e308, 1]``: NaN, -inf) or whose width does;
- ranges too narrow for their universe samples (``[1, nextafter(1, 2)]``: evaluate returned
  0.0556, outside the range) and output ranges narrower than the centroid's ``eps``;
- names the reader accepted and the exporter of the same format refused (a term ``and``).

The shared check is :func:`hybridnav.fuzzy.spec.range_problem`; the fuzz test
(``test_fuzzy_export_fuzz.py``) mutates numbers of all three formats the same ways.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export_fuzz import check_evaluates_inside_its_range, examples

from hybridnav import HybridnavError, fuzzy
from hybridnav.cli import main
from hybridnav.fuzzy.export import export, read_text
from hybridnav.fuzzy.spec import range_problem
from hybridnav.params import short_repr

BASE = fuzzy.builtin("effc-5rule")
TEXT = {fmt: export(BASE, fmt) for fmt in ("json", "fll", "fis")}
#: where each format writes the output range, and how
OUT_RANGE = {"json": ('"range": [0.0, 1.0]', '"range": [{lo}, {hi}]'),
             "fll": ("range: 0.0 1.0", "range: {lo} {hi}"),
             "fis": ("Range=[0.0 1.0]", "Range=[{lo} {hi}]")}
#: the second input's range (alpha, [0, 2])
IN_RANGE = {"json": ('"range": [0.0, 2.0]', '"range": [{lo}, {hi}]'),
            "fll": ("range: 0.0 2.0", "range: {lo} {hi}"),
            "fis": ("Range=[0.0 2.0]", "Range=[{lo} {hi}]")}
BIG = "9" * 5000            # past Python's int() limit of 4300 digits
HUGE = "9" * 400            # an integer beyond the largest double
FUZZYLITE_WORDS = "and any extremely if is not or seldom somewhat then very with"


def edit(fmt: str, old: str, new: str) -> tuple[str, int]:
    """The base text of ``fmt`` with ``old`` (once) replaced, and the line it is on."""
    text = TEXT[fmt]
    assert text.count(old) == 1, old
    return text.replace(old, new), text[:text.index(old)].count("\n") + 1


def refused(fmt: str, text: str, message: str) -> None:
    """Reading ``text`` as ``s.<fmt>`` fails with exactly ``message`` (after the file name)."""
    with pytest.raises(HybridnavError) as err:
        read_text(text, fmt, f"s.{fmt}")
    assert str(err.value) == f"s.{fmt}: {message}"
    assert len(str(err.value)) < 600


def ranged(fmt: str, where: dict, lo: float | str, hi: float | str) -> tuple[str, int]:
    old, new = where[fmt]
    return edit(fmt, old, new.format(lo=lo, hi=hi))


def at(fmt: str, line: int, key: str, fis_key: str) -> str:
    """The message prefix: the key (JSON) or the line and its key (FLL, .fis)."""
    return key if fmt == "json" else f"line {line}: {fis_key if fmt == 'fis' else 'range'}"


# ---- integers past Python's 4300-digit limit ----------------------------------------------------

@pytest.mark.parametrize("old,new,message", [
    ('"then": "high",\n      "weight": 1.0', f'"then": "high",\n      "weight": {BIG}',
     "rules[1].weight: expected a finite number, got an integer of 5000 digits"),
    ('"points": 1001', f'"points": {BIG}',
     "inputs[1].points: expected an integer from 2 to 1000000, got an integer of 5000 digits"),
    ('"params": [0.3, 0.9]', f'"params": [-{BIG}, 0.9]',
     "output.terms[1].params[0]: expected a finite number, got an integer of 5000 digits"),
    ('"default": 0.5', f'"default": {BIG}',
     "output.default: expected a finite number, got an integer of 5000 digits"),
    ('"name": "w"', f'"name": {BIG}', "output.name: expected a string, got an integer of 5000 "
                                      "digits"),
], ids=["weight", "points", "params", "default", "name"])
def test_json_integer_past_the_digit_limit_names_its_key(old, new, message):
    text, _ = edit("json", old, new)
    refused("json", text, message)


def test_fll_and_fis_integers_past_the_digit_limit_name_the_line():
    text, n = edit("fll", "term: low ZShape 0.1 0.7", f"term: low ZShape {BIG} 0.7")
    refused("fll", text, f"line {n}: term 'low': expected a finite number, got {short_repr(BIG)}")
    text, n = edit("fll", '"w": 101', f'"w": {BIG}')
    refused("fll", text, f"line {n}: hybridnav metadata: points of 'w': expected an integer in "
                         "[2, 1000000], got an integer of 5000 digits")
    text, n = edit("fis", '"default": 0.5', f'"default": {BIG}')
    refused("fis", text, f"line {n}: hybridnav metadata: default: expected a finite number, got "
                         "an integer of 5000 digits")
    text, n = edit("fis", "2 1, 1 (1.0) : 1", f"2 1, 1 ({BIG}) : 1")
    refused("fis", text, f"line {n}: rule weight: expected a finite number, got {short_repr(BIG)}")
    assert short_repr(BIG).endswith("(5002 characters)")           # the value is cut


def test_long_keys_and_listings_are_cut():
    """A 5000-digit .fis key (found by the long fuzz run), an antecedent nested 300 deep, a
    variable with 2000 terms: each message stays short."""
    key = "MF2" + "0" * 5000
    text, n = edit("fis", "MF2='high':'smf',[0.2 1.2]", f"{key}='high':'smf',[1e999 1.2]")
    refused("fis", text, f"line {n}: expected MF2 here (membership functions are numbered 1, "
                         f"2, ...), got {short_repr(key)}")
    d = BASE.to_dict()
    a = ["dtheta", "nope"]
    for _ in range(300):
        a = {"and": [a]}
    d["rules"][0]["if"] = a
    with pytest.raises(HybridnavError, match=r"^s\.json: rules\[0\]\.if\.and\[0\].*\.\.\..*"
                       r"\.and\[0\]: input 'dtheta' has no term 'nope'") as err:
        fuzzy.FuzzySystem.from_dict(d, "s.json")
    assert len(str(err.value)) < 300
    d = BASE.to_dict()
    d["inputs"][0]["terms"] = [{"name": f"t{i}", "mf": "trimf", "params": [0, 1, 2]}
                               for i in range(2000)]
    with pytest.raises(HybridnavError,
                       match=r"\(terms: t0, t1, .*\.\.\. \(2000 names\)\)$") as err:
        fuzzy.FuzzySystem.from_dict(d, "s.json")
    assert len(str(err.value)) < 300


# ---- numbers past the largest double ------------------------------------------------------------

@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_a_400_digit_range_bound_is_a_finite_number_error(fmt):
    text, n = ranged(fmt, OUT_RANGE, "0.0", HUGE)
    got = short_repr(int(HUGE) if fmt == "json" else HUGE)    # JSON reads an integer, FLL text
    key = {"json": "output.range[1]", "fll": f"line {n}: range", "fis": f"line {n}: Range"}[fmt]
    refused(fmt, text, f"{key}: expected a finite number, got {got}")


def test_fis_400_digit_metadata_default_and_other_numbers():
    """The reported .fis example: the metadata line's default (OverflowError before), and the
    same number in every other numeric field."""
    text, n = edit("fis", '"default": 0.5', f'"default": {HUGE}')
    refused("fis", text, f"line {n}: hybridnav metadata: default: expected a finite number, got "
                         f"{short_repr(int(HUGE))}")
    for old, new, message in [
            ("MF1='low':'zmf',[0.1 0.7]", f"MF1='low':'zmf',[0.1 {HUGE}]",
             f"MF1: expected a finite number, got {short_repr(HUGE)}"),
            ("NumMFs=2\nMF1='low':'zmf',[0.1", f"NumMFs={HUGE}\nMF1='low':'zmf',[0.1",
             f"NumMFs: expected a finite number, got {short_repr(HUGE)}"),
            ('"dtheta": 101', f'"dtheta": {HUGE}', "hybridnav metadata: points of 'dtheta': "
             f"expected an integer in [2, 1000000], got {short_repr(int(HUGE))}")]:
        text, n = edit("fis", old, new)
        refused("fis", text, f"line {n}: {message}")


# ---- ranges the centroid or the universe cannot handle -------------------------------------------

@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_an_output_range_whose_centroid_overflows_is_refused(fmt):
    """[-1e308, 1] evaluated to NaN or -inf (and `run --planner effc` drove out of bounds)."""
    text, n = ranged(fmt, OUT_RANGE, "-1e308", "1.0")
    refused(fmt, text, f"{at(fmt, n, 'output.range', '[Output1] Range')}: expected an output range "
                       "with max(|lo|, |hi|) * (hi - lo) <= 2**1000 (the centroid's moment "
                       "integral must stay finite), got [-1e+308, 1.0]")


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_a_range_whose_width_overflows_is_refused(fmt):
    text, n = ranged(fmt, IN_RANGE, "-1e308", "1e308")
    refused(fmt, text, f"{at(fmt, n, 'inputs[1].range', '[Input2] Range')}: expected a range "
                       "whose width hi - lo is finite in double, got [-1e+308, 1e+308]")


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
@pytest.mark.parametrize("where", ["output", "input"])
def test_a_range_one_float_step_wide_is_refused(fmt, where):
    """[1, nextafter(1, 2)] with 101 points has two distinct samples; evaluate returned 0.0556."""
    hi = math.nextafter(1.0, 2.0)
    text, n = ranged(fmt, OUT_RANGE if where == "output" else IN_RANGE, "1.0", repr(hi))
    points = 101 if where == "output" else 1001
    key = at(fmt, n, "output.range" if where == "output" else "inputs[1].range",
             "[Output1] Range" if where == "output" else "[Input2] Range")
    refused(fmt, text, f"{key}: expected a range wide enough for {points} distinct universe "
                       f"samples at least 2**-1022 apart (steps (hi - lo) / {points - 1} that "
                       f"rounding near lo and hi keeps apart), got [1.0, {hi!r}]")


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
def test_an_output_range_narrower_than_eps_is_refused(fmt):
    """Its area is below eps at every activation: the centroid would be moment / eps, ~0."""
    text, n = ranged(fmt, OUT_RANGE, "1e-300", "2e-300")
    refused(fmt, text, f"{at(fmt, n, 'output.range', '[Output1] Range')}: expected an output range "
                       "at least 2.220446049250313e-16 wide (the centroid divides by max(area, "
                       "eps) and the area is at most the width), got [1e-300, 2e-300]")


@pytest.mark.parametrize("fmt", ["json", "fll", "fis"])
@pytest.mark.parametrize("where,lo,hi", [
    ("output", 1e6, 1e6 + 1e-3), ("output", -1e150, 1e150), ("output", 1.0, 1.0 + 1e-12),
    ("input", -1e300, 1e300), ("input", 0.0, 1e-300), ("input", 5.0, 5.0 + 1e-12),
])
def test_ranges_at_the_edge_are_read_and_evaluate_inside_the_output_range(fmt, where, lo, hi):
    """What the check lets through the evaluators handle: finite outputs inside the range."""
    d = BASE.to_dict()
    var = d["output"] if where == "output" else d["inputs"][1]
    (a, b), var["range"] = var["range"], [lo, hi]
    for t in var["terms"]:                       # the terms keep their place in the range
        t["params"] = [lo + (p - a) / (b - a) * (hi - lo) for p in t["params"]]
    if where == "output":
        d["output"]["default"] = 0.5 * lo + 0.5 * hi
    text = export(fuzzy.FuzzySystem.from_dict(d), fmt)
    fs = read_text(text, fmt, f"s.{fmt}")
    assert fs.output.range == tuple(d["output"]["range"])
    check_evaluates_inside_its_range(fs)


def _scaled(lo: float, hi: float, points: int) -> dict:
    """The base system with its output range [lo, hi] and terms moved into it."""
    d = BASE.to_dict()
    out = d["output"]
    with np.errstate(over="ignore"):
        for t in out["terms"]:
            t["params"] = [lo + p * (hi - lo) for p in t["params"]]
    out.update(range=[lo, hi], points=points, default=lo + 0.5 * (hi - lo))
    return d


@settings(deadline=None, max_examples=examples(200),
          suppress_health_check=[HealthCheck.too_slow])
@given(x=st.sampled_from([0.0, 1.0, -1.0, 3.7, 1e-300, 1e-12, 1e6, -1e15, 1e100, 2.0 ** 520,
                          -1e300]),
       width=st.one_of(st.integers(1, 3000).map(lambda m: ("ulps", m)),
                       st.floats(-60, 308).map(lambda e: ("pow", 10.0 ** e))),
       points=st.sampled_from([2, 3, 11, 101, 1001]))
def test_an_accepted_output_range_evaluates_inside_itself(x, width, points):
    """Whatever range the check accepts (near its edges: a few float steps per sample, widths
    up to the moment bound, magnitudes to 2**520) evaluates to finite values inside it, in every
    format; whatever it refuses is refused naming the output's key."""
    kind, w = width
    hi = x + w * math.ulp(x) if kind == "ulps" else x + w
    if not (math.isfinite(hi) and hi > x):
        return
    try:
        fs = fuzzy.FuzzySystem.from_dict(_scaled(x, hi, points), "s.json")
    except HybridnavError as exc:
        assert str(exc).startswith("s.json: output."), str(exc)
        return
    check_evaluates_inside_its_range(fs)
    for fmt in ("fll", "fis"):
        back = read_text(export(fs, fmt), fmt)
        assert back.output.range == fs.output.range
        check_evaluates_inside_its_range(back)


# ---- names the readers and exporters agree on ---------------------------------------------------

@pytest.mark.parametrize("name", FUZZYLITE_WORDS.split())
def test_fll_and_fis_readers_refuse_the_names_their_exporters_refuse(name):
    """Before, read_fll accepted a term named 'and' that to_fll then refused."""
    text, n = edit("fll", "term: low ZShape 0.1 0.7", f"term: {name} ZShape 0.1 0.7")
    refused("fll", text, f"line {n}: term name: expected a name that is not a keyword in FLL "
                         f"rules ({FUZZYLITE_WORDS}; fuzzylite would misread the rules), got "
                         f"{name!r}")
    text, n = edit("fll", "OutputVariable: w", f"OutputVariable: {name}")
    refused("fll", text, f"line {n}: OutputVariable name: expected a name that is not a keyword "
                         f"in FLL rules ({FUZZYLITE_WORDS}; fuzzylite would misread the rules), "
                         f"got {name!r}")
    text, n = edit("fis", "MF1='low':'zmf',[0.1 0.7]", f"MF1='{name}':'zmf',[0.1 0.7]")
    refused("fis", text, f"line {n}: MF1 name: expected a name that is not a keyword in .fis "
                         f"rules ({FUZZYLITE_WORDS}; fuzzylite would misread the rules), got "
                         f"{name!r}")
    d = BASE.to_dict()                       # JSON carries the name; the exporters refuse it
    d["output"]["terms"][0]["name"] = name
    for r in d["rules"]:
        r["then"] = name if r["then"] == "low" else r["then"]
    fs = fuzzy.FuzzySystem.from_dict(d, "s.json")
    for fmt in ("fll", "fis"):
        with pytest.raises(HybridnavError, match=rf"^s\.json: output\.terms\[0\]\.name: name "
                                                 rf"'{name}' cannot be written to "
                                                 rf"{re.escape('FLL' if fmt == 'fll' else '.fis')}"
                                                 r": expected a name that is not a keyword"):
            export(fs, fmt)


@pytest.mark.parametrize("name", ["x.y", "0lead", "naïve", "a*/b"])
def test_fll_and_fis_readers_refuse_names_that_are_not_identifiers(name):
    text, n = edit("fll", "InputVariable: alpha", f"InputVariable: {name}")
    refused("fll", text, f"line {n}: InputVariable name: expected an identifier (letters, "
                         f"digits, '_', not starting with a digit), got {name!r}")
    text, n = edit("fis", "Name='alpha'", f"Name='{name}'")
    refused("fis", text, f"line {n}: Name: expected an identifier (letters, digits, '_', not "
                         f"starting with a digit), got {name!r}")


@pytest.mark.parametrize("name", ["Very", "AND", "range", "term_1", "_x"])
def test_what_the_fll_and_fis_readers_accept_their_exporters_write(name):
    """Case matters to fuzzylite's rule words; FCL keywords are only FCL's concern."""
    for fmt, old, new in [("fll", "term: low ZShape 0.1 0.7", f"term: {name} ZShape 0.1 0.7"),
                          ("fis", "MF1='low':'zmf',[0.1 0.7]", f"MF1='{name}':'zmf',[0.1 0.7]")]:
        text, _ = edit(fmt, old, new)
        if fmt == "fll":
            text = text.replace("then w is low", f"then w is {name}")
        fs = read_text(text, fmt)
        assert read_text(export(fs, fmt), fmt) == fs


# ---- the command line ---------------------------------------------------------------------------

def test_run_refuses_a_fis_file_the_evaluator_cannot_represent(tmp_path, capsys):
    """Before, `run --planner effc --fis FILE` with the range [-1e308, 1] drove out of bounds."""
    path = tmp_path / "wide.fll"
    text, n = ranged("fll", OUT_RANGE, "-1e308", "1.0")
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["run", "effc-train-1", "--planner", "effc", "--fis", str(path), "-o",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hybridnav: error: {path}: line {n}: range: expected an output range "
                          "with max(|lo|, |hi|) * (hi - lo) <= 2**1000"), err
    assert "Traceback" not in err and not out.exists()
