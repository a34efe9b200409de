"""hybridnav.fuzzy: the JSON contract, validation messages, scikit-fuzzy structure, evaluate API, plots.

Agreement of ``evaluate`` with scikit-fuzzy on random systems is in ``test_fuzzy_skfuzzy.py``.
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from hybridnav import HybridnavError, fuzzy
from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.mf import MF_PARAMS, sample

# scikit-fuzzy 0.5.0 calls np.maximum(a, b, out) positionally, which NumPy 2.4 deprecates
pytestmark = pytest.mark.filterwarnings(
    "ignore:Passing more than 2 positional arguments:DeprecationWarning")

BASE = {
    "format": "hybridnav-fis/1",
    "name": "apf_weight",
    "inputs": [
        {"name": "dtheta", "range": [0.0, 1.5707963267948966], "points": 101,
         "terms": [{"name": "small", "mf": "zmf", "params": [0.2, 1.2]},
                   {"name": "large", "mf": "smf", "params": [0.2, 1.2]}]},
        {"name": "alpha", "range": [0.0, 2.0], "points": 101,
         "terms": [{"name": "near", "mf": "zmf", "params": [0.3, 1.5]},
                   {"name": "far", "mf": "smf", "params": [0.3, 1.5]}]},
    ],
    "output": {"name": "w", "range": [0.0, 1.0], "points": 101,
               "terms": [{"name": "low", "mf": "zmf", "params": [0.1, 0.7]},
                         {"name": "high", "mf": "smf", "params": [0.3, 0.9]}],
               "defuzz": "centroid", "default": 0.5},
    "rules": [
        {"if": {"or": [["dtheta", "large"], ["alpha", "near"]]}, "then": "high", "weight": 1.0},
        {"if": {"and": [["dtheta", "small"], ["alpha", "far"]]}, "then": "low", "weight": 1.0},
    ],
}


def base() -> dict:
    return copy.deepcopy(BASE)


def sk_compute(system: FuzzySystem, **inputs: float) -> float | None:
    """scikit-fuzzy's answer for one sample (None when it produces no output)."""
    from skfuzzy import control as ctrl

    cs = system.to_skfuzzy()
    sim = ctrl.ControlSystemSimulation(cs, cache=False)
    used = {a.label for a in cs.antecedents}
    for k, v in inputs.items():
        if k in used:
            sim.input[k] = v
    sim.compute()
    return sim.output.get(system.output.name)


# ----------------------------------------------------------------------------------- JSON I/O

def test_design_example_loads_and_round_trips(tmp_path):
    fs = FuzzySystem.from_dict(base())
    assert fs.input_names == ("dtheta", "alpha")
    d = fs.to_dict()
    assert d == base()  # the README's example is already in canonical form
    path = fs.save(tmp_path / "sub" / "sys.json")
    again = fuzzy.load(path)
    assert again == fs and again.to_dict() == d
    assert fuzzy.loads(fs.to_json()) == fs
    assert json.loads(path.read_text()) == d
    assert not list(path.parent.glob(".*tmp*"))  # no temporary left behind
    x, y = np.linspace(-0.1, 1.7, 7), np.linspace(-0.1, 2.1, 7)
    np.testing.assert_array_equal(again.evaluate(dtheta=x, alpha=y), fs.evaluate(dtheta=x, alpha=y))


def test_optional_keys_round_trip():
    d = base()
    d["description"] = "a test"
    d["rules"][0]["description"] = "rule one"
    del d["rules"][1]["weight"]  # optional, defaults to 1
    fs = FuzzySystem.from_dict(d)
    assert fs.description == "a test" and fs.rules[0].description == "rule one"
    assert fs.rules[1].weight == 1.0
    out = fs.to_dict()
    assert out["description"] == "a test" and out["rules"][0]["description"] == "rule one"
    assert out["rules"][1]["weight"] == 1.0
    assert FuzzySystem.from_dict(out) == fs


def test_constructor_validates_parts():
    fs = FuzzySystem.from_dict(base())
    again = FuzzySystem(fs.name, fs.inputs, fs.output, fs.rules, description="x")
    assert again.description == "x" and again.to_dict()["inputs"] == fs.to_dict()["inputs"]
    bad_rule = fuzzy.Rule(fuzzy.TermRef("dtheta", "nope"), "low")
    with pytest.raises(HybridnavError, match=r"^rules\[0\]\.if: input 'dtheta' has no term 'nope'"):
        FuzzySystem(fs.name, fs.inputs, fs.output, [bad_rule])


def test_copies_and_process_transport_rebuild_from_json():
    import pickle  # only as multiprocessing/Dask use it between our own processes

    fs = fuzzy.builtin("effc-5rule")
    for other in (copy.deepcopy(fs), pickle.loads(pickle.dumps(fs))):
        assert other == fs and other is not fs and other.source == fs.source
        x = np.linspace(0, 1.6, 9)
        np.testing.assert_array_equal(other.evaluate(dtheta=x, alpha=x), fs.evaluate(dtheta=x, alpha=x))


def test_public_api_is_documented():
    from hybridnav.fuzzy import plots

    for mod in (fuzzy, plots):
        for name in mod.__all__:
            obj = getattr(mod, name)
            if callable(obj):
                assert obj.__doc__ and obj.__doc__.strip(), f"{mod.__name__}.{name}"
    for meth in ("from_dict", "to_dict", "save", "to_skfuzzy", "evaluate"):
        assert "Returns" in getattr(FuzzySystem, meth).__doc__ or meth == "to_dict"


def test_save_is_atomic_on_failure(tmp_path, monkeypatch):
    fs = FuzzySystem.from_dict(base())
    path = tmp_path / "sys.json"
    path.write_text("old")
    monkeypatch.setattr(FuzzySystem, "to_json", lambda self: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        fs.save(path)
    assert path.read_text() == "old"


# ---------------------------------------------------------------------------------- validation

def _set(path, value):
    def mutate(d):
        obj = d
        for k in path[:-1]:
            obj = obj[k]
        obj[path[-1]] = value
    return mutate


def _del(path):
    def mutate(d):
        obj = d
        for k in path[:-1]:
            obj = obj[k]
        del obj[path[-1]]
    return mutate


ERRORS = [
    # (mutation, exact key path in the message, a fragment of what was expected)
    (_set(["inputs", 0, "terms", 1, "mf"], "sinmf"), "inputs[0].terms[1].mf",
     "unknown membership function 'sinmf'"),
    (_set(["inputs", 0, "terms", 1, "params"], [0.2, 1.2, 3.0]), "inputs[0].terms[1].params",
     "expected 2 numbers for smf, got 3"),
    (_set(["inputs", 0, "terms", 0, "params"], [0.2]), "inputs[0].terms[0].params",
     "expected 2 numbers for zmf, got 1"),
    (_set(["inputs", 0, "terms", 0, "params"], [1.2, 0.2]), "inputs[0].terms[0].params",
     "expected a < b for zmf"),
    (_set(["inputs", 1, "terms", 1, "params"], [0.5, 0.5]), "inputs[1].terms[1].params",
     "expected a < b for smf"),
    (_set(["output", "terms", 0], {"name": "low", "mf": "trimf", "params": [0.5, 0.2, 0.9]}),
     "output.terms[0].params", "expected a <= b <= c for trimf"),
    (_set(["output", "terms", 0], {"name": "low", "mf": "trapmf", "params": [0, 0.5, 0.4, 1]}),
     "output.terms[0].params", "expected a <= b <= c <= d for trapmf"),
    (_set(["output", "terms", 1], {"name": "high", "mf": "gaussmf", "params": [0.5, 0.0]}),
     "output.terms[1].params", "expected sigma > 0 for gaussmf"),
    (_set(["output", "terms", 1], {"name": "high", "mf": "gaussmf", "params": [0.5, -0.1]}),
     "output.terms[1].params", "expected sigma > 0 for gaussmf"),
    (_set(["output", "terms", 1], {"name": "high", "mf": "gbellmf", "params": [0.0, 2, 0.5]}),
     "output.terms[1].params", "expected width a > 0 for gbellmf"),
    (_set(["output", "terms", 1], {"name": "high", "mf": "gbellmf", "params": [0.2, -1, 0.5]}),
     "output.terms[1].params", "expected slope b > 0 for gbellmf"),
    (_set(["rules", 0, "if", "or", 0], ["speed", "large"]), "rules[0].if.or[0]",
     "no input named 'speed'"),
    (_set(["rules", 1, "if", "and", 1], ["alpha", "huge"]), "rules[1].if.and[1]",
     "input 'alpha' has no term 'huge'"),
    (_set(["rules", 1, "if"], {"not": {"and": [["dtheta", "small"], ["beta", "x"]]}}),
     "rules[1].if.not.and[1]", "no input named 'beta'"),
    (_set(["rules", 1, "then"], "medium"), "rules[1].then", "output 'w' has no term 'medium'"),
    (_set(["rules", 1, "if"], {"xor": [["dtheta", "small"]]}), "rules[1].if",
     "exactly one key 'and', 'or' or 'not'"),
    (_set(["rules", 1, "if"], {"and": []}), "rules[1].if.and", "non-empty array"),
    (_set(["rules", 1, "if"], ["dtheta"]), "rules[1].if", "expected [input, term]"),
    (_set(["inputs", 1, "range"], [2.0, 2.0]), "inputs[1].range",
     "expected a range [lo, hi] with lo < hi"),
    (_set(["inputs", 1, "range"], [2.0, 0.0]), "inputs[1].range",
     "expected a range [lo, hi] with lo < hi"),
    (_set(["inputs", 1, "range"], [0.0]), "inputs[1].range", "expected 2 numbers"),
    (_set(["output", "points"], 1), "output.points", "expected an integer from 2 to 1000000, got 1"),
    (_set(["inputs", 0, "range", 1], math.nan), "inputs[0].range[1]", "expected a finite number"),
    (_set(["inputs", 0, "terms", 0, "params", 0], math.inf), "inputs[0].terms[0].params[0]",
     "expected a finite number"),
    (_set(["output", "default"], math.nan), "output.default", "expected a finite number"),
    (_set(["rules", 0, "weight"], -math.inf), "rules[0].weight", "expected a finite number"),
    (_set(["rules", 0, "weight"], 1.5), "rules[0].weight", "expected a number in [0, 1]"),
    (_set(["rules", 1, "weight"], -0.1), "rules[1].weight", "expected a number in [0, 1]"),
    (_set(["inputs", 0, "color"], "red"), "inputs[0].color", "unknown key"),
    (_set(["output", "terms", 0, "shape"], 1), "output.terms[0].shape", "unknown key"),
    (_set(["rules", 0, "else"], "low"), "rules[0].else", "unknown key"),
    (_set(["version"], 2), "version", "unknown key"),
    (_del(["output", "default"]), "output.default", "missing required key"),
    (_del(["inputs", 0, "points"]), "inputs[0].points", "missing required key"),
    (_del(["rules", 0, "then"]), "rules[0].then", "missing required key"),
    (_del(["name"]), "name", "missing required key"),
    (_del(["format"]), "format", "missing required key"),
    (_set(["inputs", 0, "points"], 101.0), "inputs[0].points",
     "expected an integer from 2 to 1000000, got number 101.0"),
    (_set(["inputs", 0, "points"], True), "inputs[0].points",
     "expected an integer from 2 to 1000000, got boolean"),
    (_set(["name"], 3), "name", "expected a string, got number 3"),
    (_set(["inputs", 0, "terms"], {}), "inputs[0].terms", "expected an array"),
    (_set(["inputs", 0, "terms"], []), "inputs[0].terms", "at least one term"),
    (_set(["inputs", 0, "terms", 0, "params"], "0.2,1.2"), "inputs[0].terms[0].params",
     "expected an array, got string"),
    (_set(["inputs", 0, "terms", 0, "params", 1], "1.2"), "inputs[0].terms[0].params[1]",
     "expected a number, got string"),
    (_set(["rules", 0, "weight"], "1"), "rules[0].weight", "expected a number, got string"),
    (_set(["output"], []), "output", "expected an object"),
    (_set(["rules"], []), "rules", "at least one rule"),
    (_set(["inputs"], []), "inputs", "at least one input"),
    (_set(["inputs", 0, "terms", 1, "name"], "small"), "inputs[0].terms[1].name",
     "duplicate term name 'small'"),
    (_set(["output", "terms", 1, "name"], "low"), "output.terms[1].name",
     "duplicate term name 'low'"),
    (_set(["inputs", 1, "name"], "dtheta"), "inputs[1].name", "duplicate input name 'dtheta'"),
    (_set(["output", "name"], "alpha"), "output.name", "also an input name"),
    (_set(["output", "defuzz"], "mom"), "output.defuzz", "unknown defuzzification 'mom'"),
    (_set(["format"], "hybridnav-fis/2"), "format", "unsupported format version 'hybridnav-fis/2'"),
    (_set(["format"], "fis"), "format", "expected \"hybridnav-fis/1\""),
    (_set(["output", "default"], 1.5), "output.default", "inside the output range [0.0, 1.0]"),
    (_set(["output", "default"], -0.01), "output.default", "inside the output range"),
]


@pytest.mark.parametrize("mutate,key,expected", ERRORS, ids=[e[1] + ":" + e[2][:24] for e in ERRORS])
def test_validation_error_names_file_key_and_expectation(tmp_path, mutate, key, expected):
    d = base()
    mutate(d)
    path = tmp_path / "sys.json"
    path.write_text(json.dumps(d))  # NaN/Infinity are written as JSON's non-standard tokens
    with pytest.raises(HybridnavError) as info:
        fuzzy.load(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {key}: "), msg
    assert expected in msg, msg
    with pytest.raises(HybridnavError) as info2:  # from_dict: the same without the file
        FuzzySystem.from_dict(d)
    assert str(info2.value).startswith(f"{key}: ")
    with pytest.raises(HybridnavError) as info3:
        FuzzySystem.from_dict(d, source="sys.json")
    assert str(info3.value).startswith(f"sys.json: {key}: ")


def test_validation_errors_are_value_errors():
    d = base()
    d["output"]["default"] = 7.0
    with pytest.raises(ValueError):
        FuzzySystem.from_dict(d)


def test_json_syntax_error_names_file_and_line(tmp_path):
    text = json.dumps(base(), indent=2).splitlines()
    text[5] = text[5].rstrip(",")  # break the 6th line
    path = tmp_path / "broken.json"
    path.write_text("\n".join(text))
    with pytest.raises(HybridnavError, match=r"broken\.json: line (6|7) column \d+: invalid JSON"):
        fuzzy.load(path)


def test_duplicate_json_key_and_unreadable_file(tmp_path):
    with pytest.raises(HybridnavError, match=r"^x\.json: duplicate key 'name'"):
        fuzzy.loads('{"format": "hybridnav-fis/1", "name": "a", "name": "b"}', "x.json")
    missing = tmp_path / "nope.json"
    with pytest.raises(HybridnavError, match=r"nope\.json: cannot read fuzzy system file"):
        fuzzy.load(missing)
    with pytest.raises(HybridnavError, match=r"fuzzy system 'nope': expected a built-in name"):
        fuzzy.load("nope")
    with pytest.raises(HybridnavError, match=r"^top\.json: expected an object"):
        fuzzy.loads("[1, 2]", "top.json")


# ------------------------------------------------------------------------------------ built-ins

def test_builtins_are_the_papers_tables():
    assert fuzzy.builtin_names() == ["effc-2rule", "effc-5rule", "effc-safe", "effc-tuned",
                                     "steer-7rule"]
    five, two = fuzzy.builtin("effc-5rule"), fuzzy.load("effc-2rule")
    for fs in (five, two):
        assert fs.input_names == ("dtheta", "alpha")
        assert fs.inputs[0].range == (0.0, math.pi / 2) and fs.inputs[1].range == (0.0, 2.0)
        assert fs.output.name == "w" and fs.output.range == (0.0, 1.0)
        assert all(t.mf in ("zmf", "smf") for v in (*fs.inputs, fs.output) for t in v.terms)
        assert "repulsive" in fs.description and "F_w = w F_rep + (1 - w) F_att" in fs.description
        assert all(r.weight == 1.0 for r in fs.rules)
    T, A = fuzzy.TermRef, fuzzy.And
    assert [(r.antecedent, r.then) for r in five.rules] == [
        (A((T("alpha", "low"), T("dtheta", "high"))), "low"),
        (A((T("alpha", "low"), T("dtheta", "low"))), "high"),
        (T("dtheta", "high"), "low"),
        (A((T("alpha", "high"), T("dtheta", "high"))), "low"),
        (T("alpha", "low"), "low"),
    ]
    assert [(r.antecedent, r.then) for r in two.rules] == [
        (A((T("alpha", "low"), T("dtheta", "low"))), "high"),  # Table 2 = Table 1 rules 2, 3
        (T("dtheta", "high"), "low"),
    ]
    # behaviour: an obstacle close and in the target direction -> w high; off to the side -> low
    assert two.evaluate(dtheta=0.05, alpha=0.05) > 0.7
    assert two.evaluate(dtheta=1.5, alpha=0.2) < 0.3
    assert five.evaluate(dtheta=1.5, alpha=1.9) < 0.3
    # nothing fires (aligned, obstacle much farther than the target): the file's default
    assert two.evaluate(dtheta=0.0, alpha=2.0) == two.output.default == 0.5
    assert sk_compute(two, dtheta=0.0, alpha=2.0) is None


# ------------------------------------------------------------------------------ scikit-fuzzy

def test_to_skfuzzy_structure():
    from skfuzzy import control as ctrl

    d = base()
    d["rules"][1]["weight"] = 0.25
    d["rules"].append({"if": {"not": ["alpha", "far"]}, "then": "low", "weight": 0.5})
    fs = FuzzySystem.from_dict(d)
    cs = fs.to_skfuzzy()
    assert isinstance(cs, ctrl.ControlSystem)
    ants = {a.label: a for a in cs.antecedents}
    cons = {c.label: c for c in cs.consequents}
    assert set(ants) == {"dtheta", "alpha"} and set(cons) == {"w"}
    for v in fs.inputs:
        a = ants[v.name]
        np.testing.assert_array_equal(a.universe, np.linspace(*v.range, v.points))
        assert list(a.terms) == [t.name for t in v.terms]
        for t in v.terms:  # our sampling is bit-for-bit scikit-fuzzy's
            np.testing.assert_array_equal(a[t.name].mf, sample(t.mf, t.params, a.universe))
    w = cons["w"]
    assert w.defuzzify_method == "centroid" and list(w.terms) == ["low", "high"]
    np.testing.assert_array_equal(w.universe, np.linspace(0.0, 1.0, 101))
    rules = sorted(cs.rules, key=lambda r: r.label)
    assert [r.label for r in rules] == ["rule0", "rule1", "rule2"]
    assert [str(r.antecedent) for r in rules] == [
        "dtheta[large] OR alpha[near]", "dtheta[small] AND alpha[far]", "NOT-alpha[far]"]
    assert [(r.consequent[0].term.label, r.consequent[0].weight) for r in rules] == [
        ("high", 1.0), ("low", 0.25), ("low", 0.5)]
    for x, y in [(0.1, 0.2), (1.3, 1.9), (0.7, 0.9)]:
        assert abs(fs.evaluate(dtheta=x, alpha=y) - sk_compute(fs, dtheta=x, alpha=y)) < 1e-12


def test_nested_and_or_chains_map_to_binary_skfuzzy_operators():
    d = base()
    d["rules"][0]["if"] = {"and": [["dtheta", "large"], {"or": [["alpha", "near"],
                                   ["alpha", "far"], {"not": ["dtheta", "small"]}]}]}
    fs = FuzzySystem.from_dict(d)
    r0 = next(r for r in fs.to_skfuzzy().rules if r.label == "rule0")
    assert str(r0.antecedent) == \
        "dtheta[large] AND ((alpha[near] OR alpha[far]) OR (NOT-dtheta[small]))"


# --------------------------------------------------------------------------------- evaluate API

def test_evaluate_shapes_and_scalars():
    fs = FuzzySystem.from_dict(base())
    x = np.linspace(0, 1.5, 3)[:, None]
    y = np.linspace(0, 2, 4)
    z = fs.evaluate(dtheta=x, alpha=y)
    assert z.shape == (3, 4) and z.dtype == np.float64
    for i in range(3):
        for j in range(4):
            assert z[i, j] == pytest.approx(fs.evaluate(dtheta=float(x[i, 0]), alpha=float(y[j])),
                                            abs=1e-13)
    s = fs.evaluate(dtheta=0.4, alpha=1)
    assert isinstance(s, np.float64) and np.ndim(s) == 0
    assert isinstance(fs.evaluate(dtheta=np.float64(0.4), alpha=np.array(1.0)), np.float64)
    assert fs.evaluate(dtheta=[0.4], alpha=1.0).shape == (1,)
    assert fs.evaluate(dtheta=np.zeros((0, 2)), alpha=1.0).shape == (0, 2)
    big = np.random.default_rng(3).uniform(0, 1.6, 5000)  # several chunks
    out = fs.evaluate(dtheta=big, alpha=big[::-1])
    assert out.shape == (5000,)
    idx = [0, 2047, 2048, 4999]
    np.testing.assert_allclose(out[idx], [fs.evaluate(dtheta=big[i], alpha=big[::-1][i])
                                          for i in idx], atol=1e-13)


def test_evaluate_clips_and_propagates_nan():
    fs = FuzzySystem.from_dict(base())
    lo = fs.evaluate(dtheta=0.0, alpha=0.0)
    assert fs.evaluate(dtheta=-3.0, alpha=-np.inf) == lo
    out = fs.evaluate(dtheta=np.array([-3.0, np.nan, 9.0, np.inf, 0.0, math.pi / 2]),
                      alpha=np.array([0.0, 1.0, 2.0, 1e9, 0.0, 2.0]))
    assert out[0] == out[4] and np.isnan(out[1])
    assert out[2] == out[3] == out[5]
    assert out[0] == pytest.approx(lo, abs=1e-14)  # batch and scalar paths sum in other orders
    assert np.isnan(fs.evaluate(dtheta=math.nan, alpha=1.0))
    assert math.isnan(fs.evaluate(dtheta=0.3, alpha=[math.nan])[0])


def test_evaluate_keyword_errors():
    fs = FuzzySystem.from_dict(base())
    with pytest.raises(TypeError, match="missing alpha"):
        fs.evaluate(dtheta=0.1)
    with pytest.raises(TypeError, match="unexpected beta"):
        fs.evaluate(dtheta=0.1, alpha=0.2, beta=3)
    with pytest.raises(ValueError):
        fs.evaluate(dtheta=np.zeros(3), alpha=np.zeros(4))


def test_no_rule_fired_gives_default_where_skfuzzy_gives_nothing():
    d = base()
    d["rules"] = [{"if": ["dtheta", "large"], "then": "high", "weight": 1.0}]
    d["output"]["default"] = 0.125
    fs = FuzzySystem.from_dict(d)
    out = fs.evaluate(dtheta=np.array([0.0, 0.1, 0.18, 0.21]), alpha=0.0)  # samples <= 0.2 are 0
    assert out[:3].tolist() == [0.125] * 3 and out[3] != 0.125
    assert sk_compute(fs, dtheta=0.1, alpha=0.0) is None
    d["rules"][0]["weight"] = 0.0  # a zero weight never fires
    assert FuzzySystem.from_dict(d).evaluate(dtheta=1.5, alpha=0.0) == 0.125


def test_skfuzzy_cache_returns_stale_output_when_nothing_fires():
    """Why the reference simulations in these tests use ``cache=False``."""
    from skfuzzy import control as ctrl

    fs = fuzzy.builtin("effc-2rule")
    sim = ctrl.ControlSystemSimulation(fs.to_skfuzzy())  # cache=True, the default
    answers = []
    for x, y in [(0.0, 2.0), (1.0, 1.0), (0.0, 2.0)]:
        sim.input["dtheta"], sim.input["alpha"] = x, y
        sim.compute()
        answers.append(sim.output.get("w"))
    assert answers[0] is None and answers[2] == answers[1]  # the cached run repeats the last one
    assert fs.evaluate(dtheta=0.0, alpha=2.0) == 0.5


def test_fuzzy_imports_neither_tuner_planners_cli_nor_skfuzzy():
    code = ("import sys, hybridnav.fuzzy as f; f.builtin('effc-2rule').evaluate(dtheta=0.1, alpha=0.2);"
            "bad = [m for m in sys.modules if m.split('.')[:2] in (['hybridnav', 'tuner'], "
            "['hybridnav', 'planners'], ['hybridnav', 'cli']) or m == 'skfuzzy'];"
            "print(bad); sys.exit(1 if bad else 0)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stdout + res.stderr


# ------------------------------------------------------------------------------------------ plots

PNG = b"\x89PNG\r\n\x1a\n"


def test_plots_write_pngs(tmp_path):
    from matplotlib.figure import Figure

    from hybridnav.fuzzy import plots

    fs = fuzzy.builtin("effc-5rule")
    fig = plots.plot_memberships(fs)
    assert isinstance(fig, Figure) and len(fig.axes) == 3
    labels = [t.get_text() for t in fig.axes[2].get_legend().get_texts()]
    assert labels == ["low (zmf)", "high (smf)", "default"]
    p1 = plots.save_memberships_png(fs, tmp_path / "m.png")
    p2 = plots.save_surface_png(fs, tmp_path / "s.png", resolution=15)
    for p in (p1, p2):
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 5000
    assert sorted(q.name for q in tmp_path.iterdir()) == ["m.png", "s.png"]
    surf = plots.plot_surface(fs, resolution=9)
    ax, bar = surf.axes
    # the units EFFC, which feeds this system, declares
    assert ax.get_xlabel() == "dtheta (rad)" and ax.get_ylabel() == "alpha (dimensionless)"
    assert bar.get_ylabel() == "w (dimensionless)"
    mesh = ax.collections[0]                    # the heatmap: the output on the grid
    gx, gy = np.meshgrid(np.linspace(*fs.inputs[0].range, 9), np.linspace(*fs.inputs[1].range, 9))
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(9, 9),
                               fs.evaluate(dtheta=gx, alpha=gy))
    assert mesh.get_clim() == fs.output.range


def test_surface_for_one_and_three_inputs(tmp_path):
    from hybridnav.fuzzy import plots

    d = base()
    d["inputs"].append({"name": "v", "range": [0.0, 4.0], "points": 21,
                        "terms": [{"name": "slow", "mf": "gaussmf", "params": [0.0, 1.0]}]})
    d["rules"].append({"if": ["v", "slow"], "then": "low", "weight": 0.5})
    fs = FuzzySystem.from_dict(d)
    fig = plots.plot_surface(fs, resolution=7)
    assert "v = 2" in fig.axes[0].get_title()  # the third input held at mid-range
    fig = plots.plot_surface(fs, inputs=("v", "alpha"), fixed={"dtheta": 0.1}, resolution=7)
    assert fig.axes[0].get_xlabel() == "v" and "dtheta = 0.1" in fig.axes[0].get_title()
    with pytest.raises(HybridnavError, match="fixed: no input named 'x'"):
        plots.plot_surface(fs, fixed={"x": 1.0})
    with pytest.raises(HybridnavError, match="inputs: expected two different input names"):
        plots.plot_surface(fs, inputs=("v", "v"))
    one = FuzzySystem.from_dict({**base(), "inputs": base()["inputs"][:1], "rules": [
        {"if": ["dtheta", "large"], "then": "high"}, {"if": ["dtheta", "small"], "then": "low"}]})
    p = plots.save_surface_png(one, tmp_path / "one.png")
    assert p.read_bytes()[:8] == PNG
    line = plots.plot_surface(one).axes[0].lines[0]
    np.testing.assert_allclose(line.get_ydata(), one.evaluate(dtheta=line.get_xdata()))


@pytest.mark.parametrize("mf", sorted(MF_PARAMS))
def test_mf_sampling_is_bitwise_skfuzzy(mf):
    import skfuzzy

    x = np.linspace(-1.0, 3.0, 57)
    params = {"zmf": [0.1, 1.7], "smf": [-0.5, 0.1], "trimf": [0.0, 0.0, 1.0],
              "trapmf": [-2.0, 0.5, 0.5, 2.0], "gaussmf": [1.0, 0.3], "gbellmf": [0.5, 2.5, 1.0],
              "sigmf": [1.0, -6.0]}[mf]
    ref = (getattr(skfuzzy, mf)(x, params) if mf in ("trimf", "trapmf")
           else getattr(skfuzzy, mf)(x, *params))
    np.testing.assert_array_equal(sample(mf, params, x), ref)
