"""Hostile names cannot change what an export means (issue 15).

A name reaches every exported text. Variable and term names that are not identifiers are refused
by every text format, naming the key; the JSON format keeps them exactly. Free text (the system's
name and description) is written only where it cannot open or close a comment or a string: the
export of a system with a hostile name evaluates bit for bit like the export of the same system
named ``plain`` (compiled with gcc -Werror, run through fuzzylite), and the exact name comes back
from the metadata.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_fuzzy_export import FUZZYLITE, evaluate, fuzzylite_eval, needs_fuzzylite, random_inputs
from test_fuzzy_export_c import CC, build, run

from hybridnav import HybridnavError, fuzzy
from hybridnav.cli import main
from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.export import export, read_text
from hybridnav.params import short_repr

#: the attack of the issue: a term name that closes the C comment and redefines the default
INJECTION = "low */\n#undef EFFC_5RULE_DEFAULT\n#define EFFC_5RULE_DEFAULT ((effc_5rule_real)1.0)\n/*"
HOSTILE = [INJECTION, "a*/b", "/*", "*/", "q'uote", 'd"q', "new\nline", "cr\rreturn", "#hash",
           "back\\slash", "tri??/", "??=", "per%cent", "naïve", "tab\tbed", "(*x*)", "//x",
           "x y", "0lead", "nul\0byte", "{brace}", "semi;colon", "-dash", "dot.ted"]
FORMATS = ("fll", "fis", "fcl", "c")


def _renamed(system: FuzzySystem, where: str, name: str) -> FuzzySystem:
    """``system`` with one variable or term renamed (the rules follow the rename)."""
    d = json.loads(json.dumps(system.to_dict()))
    if where == "output.terms[0].name":
        old, d["output"]["terms"][0]["name"] = d["output"]["terms"][0]["name"], name
        for r in d["rules"]:
            r["then"] = name if r["then"] == old else r["then"]
        return FuzzySystem.from_dict(d)
    var = d["inputs"][0] if where == "inputs[0].name" else d["inputs"][1]
    vname = var["name"]
    if where == "inputs[0].name":
        var["name"] = name
    else:
        old, var["terms"][1]["name"] = var["terms"][1]["name"], name

    def walk(a):
        if isinstance(a, list) and len(a) == 2 and all(isinstance(x, str) for x in a):
            if a[0] == vname and where == "inputs[0].name":
                a[0] = name
            elif a[0] == vname and a[1] == old:
                a[1] = name
        elif isinstance(a, dict):
            for v in a.values():
                walk(v)
        elif isinstance(a, list):
            for v in a:
                walk(v)

    for r in d["rules"]:
        walk(r["if"])
    return FuzzySystem.from_dict(d)


KEYS = ("output.terms[0].name", "inputs[0].name", "inputs[1].terms[1].name")


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("key", KEYS)
@pytest.mark.parametrize("name", HOSTILE, ids=repr)
def test_a_hostile_variable_or_term_name_is_refused_with_its_key(fmt, key, name):
    try:
        fs = _renamed(fuzzy.builtin("effc-5rule"), key, name)
    except HybridnavError as exc:          # the system itself refuses it (empty, duplicate, ...)
        assert key.split("[")[0] in str(exc)
        return
    with pytest.raises(HybridnavError) as err:
        export(fs, fmt)
    assert key in str(err.value) and short_repr(name) in str(err.value)   # long names cut


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("name", ["END_VAR", "VAR", "if", "then", "very", "RULEBLOCK"])
def test_a_keyword_is_refused_only_where_it_is_one(fmt, name):
    """FCL keywords (any case) in FCL; fuzzylite's rule words in the formats fuzzylite reads;
    any identifier in C."""
    fs = _renamed(fuzzy.builtin("effc-5rule"), "inputs[1].terms[1].name", name)
    fcl = name.lower() in ("end_var", "if", "then", "ruleblock")
    fuzzylite = name in ("if", "then", "very")
    if fmt == "c" or (fmt == "fcl" and not (fcl or fuzzylite)) or \
            (fmt in ("fll", "fis") and not fuzzylite):
        export(fs, fmt)
    else:
        with pytest.raises(HybridnavError, match=r"inputs\[1\]\.terms\[1\]\.name"):
            export(fs, fmt)


@pytest.mark.parametrize("name", HOSTILE[:8], ids=repr)
def test_json_keeps_a_hostile_name_exactly(tmp_path, name):
    fs = _renamed(fuzzy.builtin("effc-5rule"), "output.terms[0].name", name)
    back = FuzzySystem.from_dict(json.loads(export(fs, "json")))
    assert back.output.terms[0].name == name
    X = random_inputs(fs, 200, np.random.default_rng(0))
    np.testing.assert_array_equal(evaluate(back, X), evaluate(fs, X))


def _named(name: str, description: str | None = None) -> FuzzySystem:
    d = fuzzy.builtin("effc-5rule").to_dict()
    d["name"] = name
    if description is None:
        d.pop("description", None)
    else:
        d["description"] = description
    return FuzzySystem.from_dict(d)


SYSTEM_NAMES = [n for n in HOSTILE if n.strip() and "\0" not in n]


@pytest.mark.skipif(CC is None, reason="no C compiler")
@pytest.mark.parametrize("name", SYSTEM_NAMES, ids=repr)
def test_c_of_a_hostile_system_name_compiles_and_means_the_system(tmp_path, name):
    fs = _named(name, description=INJECTION)
    X = random_inputs(fs, 400, np.random.default_rng(1))
    (tmp_path / "h").mkdir()
    (tmp_path / "p").mkdir()
    exe = build(tmp_path / "h", fs)            # -Wall -Wextra -Werror -pedantic, no warnings
    plain = build(tmp_path / "p", _named("plain"))
    got = run(exe, X)
    np.testing.assert_array_equal(got, run(plain, X))
    np.testing.assert_allclose(got, evaluate(fs, X), rtol=0, atol=1e-12)


@needs_fuzzylite
@pytest.mark.parametrize("fmt", ("fll", "fis", "fcl"))
@pytest.mark.parametrize("name", SYSTEM_NAMES, ids=repr)
def test_fuzzylite_reads_a_hostile_system_name_as_the_plain_system(tmp_path, fmt, name):
    fs = _named(name, description=INJECTION)
    X = random_inputs(fs, 300, np.random.default_rng(2), outside=0.0)
    text = export(fs, fmt)
    (tmp_path / "h").mkdir()
    (tmp_path / "p").mkdir()
    got = fuzzylite_eval(tmp_path / "h", text, fmt, X)
    want = fuzzylite_eval(tmp_path / "p", export(_named("plain"), fmt), fmt, X)
    np.testing.assert_array_equal(np.nan_to_num(got, nan=-7.0), np.nan_to_num(want, nan=-7.0))
    if fmt in ("fll", "fis"):                    # the exact name travels in the metadata
        back = read_text(text, fmt)
        assert back.name == name


def test_the_cli_refuses_a_hostile_fis_with_the_file_and_key(tmp_path, capsys):
    fs = _renamed(fuzzy.builtin("effc-5rule"), "output.terms[0].name", "low */")
    path = tmp_path / "evil.json"
    fs.save(path)
    assert main(["export", str(path), "--format", "c", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "output.terms[0].name" in err and "'low */'" in err and "Traceback" not in err
    assert not list(tmp_path.glob("out*"))


def test_the_issue_attack_cannot_produce_c(tmp_path):
    """The term name of the issue: refused; before, it compiled and returned 1.0 for 0.5."""
    fs = _renamed(fuzzy.builtin("effc-5rule"), "output.terms[0].name", INJECTION)
    with pytest.raises(HybridnavError, match=r"output\.terms\[0\]\.name"):
        export(fs, "c")
