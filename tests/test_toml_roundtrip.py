"""TOML written by hybridnav (``toml_dumps``, :mod:`tomli_w`) reads back to the same data:
arbitrary nested tables, scenario files and job files (hypothesis)."""

from __future__ import annotations

import copy
import functools
import math
import tomllib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridnav.errors import HybridnavError
from hybridnav.tuner.job import load_job
from hybridnav.world import load_scenario, save_scenario, scenario_to_dict, toml_dumps
from hybridnav.world.generator import WorldGenerator

# any text, control characters (DEL, NUL, escapes) and non-BMP characters included
TEXT = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
SCALARS = (st.booleans() | st.integers(-2**63, 2**63 - 1)
           | st.floats(allow_nan=True, allow_infinity=True) | TEXT)
VALUES = st.recursive(
    SCALARS, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(TEXT, inner, max_size=4),
    max_leaves=20)
TABLES = st.dictionaries(TEXT, VALUES, max_size=6)


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a)
                                                      == math.copysign(1, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@settings(max_examples=150, deadline=None)
@given(TABLES)
def test_any_table_round_trips(data):
    assert _same(tomllib.loads(toml_dumps(data)), data)


def test_none_numpy_and_tuples():
    data = {"a": None, "b": (1, 2.5), "c": np.float64(0.25), "d": np.arange(3),
            "e": {"f": None, "g": np.bool_(True)}}
    assert tomllib.loads(toml_dumps(data)) == {"b": [1, 2.5], "c": 0.25, "d": [0, 1, 2],
                                               "e": {"g": True}}
    with pytest.raises(HybridnavError, match=r"^x\[1\]: cannot write NoneType as TOML"):
        toml_dumps({"x": [1, None]})
    with pytest.raises(HybridnavError, match=r"^t\.o: cannot write object as TOML"):
        toml_dumps({"t": {"o": object()}})


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), name=TEXT.filter(lambda s: s.strip() != ""),
       description=TEXT)
def test_scenario_files_round_trip(tmp_path_factory, seed, name, description):
    """A generated world with any name and description (the DEL character included, which the
    former writer wrote raw) saved and loaded is the same scenario."""
    s = WorldGenerator(segments=(0, 2), rectangles=(0, 2)).generate(1, seed=seed)[0]
    d = scenario_to_dict(s)
    d["name"], d["description"] = name, description
    from hybridnav.world import scenario_from_dict

    s2 = scenario_from_dict(d)
    path = tmp_path_factory.mktemp("s") / "world.toml"
    save_scenario(s2, path)
    assert scenario_to_dict(load_scenario(str(path))) == scenario_to_dict(s2)


@functools.lru_cache(maxsize=1)
def _builtin():
    return load_job(None).to_dict()


def _builtin_job():
    return copy.deepcopy(_builtin())


@settings(max_examples=4, deadline=None)
@given(name=st.text(st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), min_size=1,
                    max_size=10).filter(lambda s: s.strip() != ""),
       seed=st.integers(0, 2**31 - 1))
def test_job_files_round_trip(tmp_path_factory, name, seed):
    """The built-in job (with small generated sets: loading generates them), renamed and
    reseeded, written and loaded: the same job."""
    d = _builtin_job()
    d["name"], d["seed"] = name, seed
    d["scenarios"] = {"train": ["effc-train-1", {"generate": 2, "seed": seed % 1000}],
                      "validation": [{"generate": 2, "seed": 2, "cups": [0, 1], "name": "trap"}],
                      "test": ["effc-env-a"]}
    path = tmp_path_factory.mktemp("j") / "job.toml"
    path.write_text(toml_dumps(d), encoding="utf-8")
    try:
        job = load_job(str(path))
    except HybridnavError as exc:           # a name the job refuses: said so, naming the key
        assert "name" in str(exc)
        return
    assert job.to_dict() == d


def test_what_toml_cannot_hold_is_an_error_naming_its_key():
    """A 0-d array is its number (was TypeError: iteration over a 0-d array); a lone surrogate
    (undecodable bytes of a command line: generate --set name=$'a\\xff') is refused naming the
    key (was UnicodeEncodeError when the file was written); keys 1 and "1" are refused instead
    of one silently replacing the other; a document that is not a table is refused."""
    assert tomllib.loads(toml_dumps({"a": np.array(5.0), "b": np.array(True)})) == \
        {"a": 5.0, "b": True}
    with pytest.raises(HybridnavError, match=r"^t\.name: cannot write 'a\\udcff' as TOML"):
        toml_dumps({"t": {"name": "a\udcff"}})
    with pytest.raises(HybridnavError, match=r"^t: cannot write '\\ud800'"):
        toml_dumps({"t": {"\ud800": 1}})
    with pytest.raises(HybridnavError, match=r"^t\.1: two keys written as '1'"):
        toml_dumps({"t": {1: "x", "1": "y"}})
    with pytest.raises(HybridnavError, match=r"^cannot write list as a TOML document"):
        toml_dumps([1])


def test_generate_refuses_a_name_that_is_not_utf8(tmp_path, capsys):
    from hybridnav.cli import main

    assert main(["generate", "--count", "1", "--set", "name=a\udcff", "--out",
                 str(tmp_path / "w")]) == 2
    assert "name: cannot write 'a\\udcff-0-000' as TOML (not UTF-8" in capsys.readouterr().err
