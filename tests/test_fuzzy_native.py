"""The C single-sample evaluator (hybridnav/fuzzy/_native.c): bit for bit the Python path.

``FuzzySystem.evaluate`` with one sample switches to it after ``_native.AFTER`` calls (or at
``use_native()``). These tests build it once into a temporary cache folder and check: equality
with ``CompiledSystem.evaluate_scalar`` (``==``, NaN for NaN) on the built-in systems and on random
systems with NOT/OR/AND trees, weights (0, tiny), many output terms (the dense branch), no rule
firing, NaN, infinite and out-of-range inputs; the evaluate API around it; the fallback where
there is no compiler; the lazy switch that never waits for the compiler; and the cache.
"""

from __future__ import annotations

import copy
import math
import pickle
import threading

import numpy as np
import pytest
from fuzzy_strategies import antecedents, examples, terms, variables
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridnav import fuzzy
from hybridnav.fuzzy import FuzzySystem, _native


def _reset(monkeypatch, cache) -> None:
    """A process that has not loaded or built the module yet, with ``cache`` as its cache."""
    monkeypatch.setenv("HYBRIDNAV_CACHE_DIR", str(cache))
    monkeypatch.delenv(_native.ENV, raising=False)
    monkeypatch.setattr(_native, "_module", None)
    monkeypatch.setattr(_native, "_state", "idle")
    monkeypatch.setattr(_native, "_thread", None)
    monkeypatch.setattr(_native, "_lock", threading.Lock())


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A cache folder holding the compiled module (built once for this module's tests)."""
    folder = tmp_path_factory.mktemp("hybridnav-cache")
    mp = pytest.MonkeyPatch()
    try:
        _reset(mp, folder)
        if _native.library_path() is None:
            pytest.skip("no C compiler or no Python.h here")
        assert _native.build(wait=True)
        yield folder
    finally:
        mp.undo()


@pytest.fixture
def native(cache, monkeypatch):
    """The module loaded from ``cache``."""
    _reset(monkeypatch, cache)
    assert _native.build(wait=True)
    return _native._module


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def check(fs: FuzzySystem, rows) -> int:
    """The C evaluator equals the Python path on every row, and defers to it exactly where it
    takes its direct centroid (all activations tiny); returns how many it deferred."""
    eng = fs._engine
    ev, retry = _native.evaluator(eng, fs.input_names)
    assert ev is not None and not retry
    direct = eng._direct
    calls = []
    eng._direct = lambda cuts: calls.append(1) or direct(cuts)
    deferred = 0
    for row in rows:
        x = [float(v) for v in row]
        calls.clear()
        want = eng.evaluate_scalar(x)
        got = ev.scalar(x)
        assert (got is None) == bool(calls), (x, got, want)
        if got is None:
            deferred += 1
        else:
            assert same(got, want), (x, got, want)
        kw = ev.kw(dict(zip(fs.input_names, x)))
        assert kw is None if got is None else (type(kw) is np.float64 and same(kw, want))
    return deferred


def edge_inputs(fs: FuzzySystem, n: int, rng: np.random.Generator) -> np.ndarray:
    """Inside and outside the ranges, the ends, universe samples, NaN and infinities."""
    cols = []
    for v in fs.inputs:
        lo, hi = v.range
        w = hi - lo
        grid = np.linspace(lo, hi, v.points)
        c = rng.uniform(lo - 0.3 * w, hi + 0.3 * w, n)
        k = rng.permutation(n)
        c[k[: n // 4]] = rng.choice(grid, n // 4)
        c[k[n // 4]] = lo
        c[k[n // 4 + 1]] = hi
        c[k[n // 4 + 2]] = np.nextafter(lo, -np.inf)
        c[k[n // 4 + 3]] = np.nextafter(hi, np.inf)
        c[k[n // 4 + 4]] = -np.inf
        c[k[n // 4 + 5]] = np.inf
        c[k[n // 4 + 6]] = np.nan
        cols.append(c)
    return np.stack(cols, axis=1)


# ------------------------------------------------------------------------------- equality

@pytest.mark.parametrize("name", fuzzy.builtin_names())
def test_builtins_equal_the_python_path_bit_for_bit(native, name):
    fs = fuzzy.builtin(name)
    rng = np.random.default_rng(7)
    X = edge_inputs(fs, 3000, rng)
    assert check(fs, X) <= 3  # the direct path: activations below 1e-6 only
    # a grid over the first two inputs (the others mid-range), universe samples included
    g = [np.linspace(v.range[0], v.range[1], 61) for v in fs.inputs]
    mid = [0.5 * (v.range[0] + v.range[1]) for v in fs.inputs]
    rows = [[a, b, *mid[2:]] for a in g[0] for b in g[1]]
    check(fs, rows)


@st.composite
def odd_systems(draw) -> dict:
    """Random systems: NOT/OR/AND trees, weights 0, 1, random or tiny, 1-7 output terms (more
    than four: the dense plain-universe branch), output terms that no rule names."""
    n_in = draw(st.integers(1, 3))
    inputs = [draw(variables(f"x{i}", min_terms=1)) for i in range(n_in)]
    lo = draw(st.floats(-5.0, 5.0))
    hi = lo + draw(st.floats(0.1, 10.0))
    points = draw(st.integers(2, 201))
    n_out = draw(st.integers(1, 7))
    out = {"name": "y", "range": [lo, hi], "points": points,
           "terms": draw(terms(lo, hi, points, n_out)), "defuzz": "centroid",
           "default": draw(st.floats(lo, hi))}
    names = [t["name"] for t in out["terms"]]
    rules = draw(st.lists(st.fixed_dictionaries({
        "if": antecedents(inputs),
        "then": st.sampled_from(names),
        "weight": st.one_of(st.just(1.0), st.floats(0.0, 1.0), st.sampled_from([0.0, 0.5]),
                            st.sampled_from([1e-300, 1e-30, 1e-12, 1e-7])),
    }), min_size=1, max_size=8))
    return {"format": "hybridnav-fis/1", "name": "odd", "inputs": inputs, "output": out,
            "rules": rules}


@pytest.mark.slow
# 100 random systems of 60 edge inputs each in the default run (300 took 12 s of CPU);
# HYBRIDNAV_FUZZ_EXAMPLES=N runs N
@settings(deadline=None, max_examples=examples(100), suppress_health_check=[
    HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large])
@given(d=odd_systems(), seed=st.integers(0, 2**32 - 1))
def test_random_systems_equal_the_python_path_bit_for_bit(native, d, seed):
    fs = FuzzySystem.from_dict(d)
    check(fs, edge_inputs(fs, 60, np.random.default_rng(seed)))


def test_the_special_cases_by_name(native):
    """NOT terms, weights, OR rules, the default where nothing fires, NaN, the direct path."""
    d = {"format": "hybridnav-fis/1", "name": "special",
         "inputs": [{"name": "a", "range": [0.0, 1.0], "points": 11,
                     "terms": [{"name": "lo", "mf": "trimf", "params": [0.0, 0.0, 0.4]},
                               {"name": "hi", "mf": "trimf", "params": [0.6, 1.0, 1.0]}]},
                    {"name": "b", "range": [-1.0, 1.0], "points": 21,
                     "terms": [{"name": "neg", "mf": "zmf", "params": [-1.0, 0.0]},
                               {"name": "pos", "mf": "smf", "params": [0.0, 1.0]}]}],
         "output": {"name": "y", "range": [0.0, 10.0], "points": 51,
                    "terms": [{"name": f"t{j}", "mf": "gaussmf", "params": [2.0 * j, 1.0]}
                              for j in range(6)],
                    "defuzz": "centroid", "default": 4.25},
         "rules": [{"if": {"not": ["a", "lo"]}, "then": "t1", "weight": 0.5},
                   {"if": {"or": [["a", "hi"], ["b", "pos"]]}, "then": "t4", "weight": 1.0},
                   {"if": {"and": [["a", "lo"], {"not": ["b", "neg"]}]}, "then": "t0",
                    "weight": 1e-30},
                   {"if": ["b", "neg"], "then": "t5", "weight": 0.0}]}
    fs = FuzzySystem.from_dict(d)
    assert len(fs._engine.out_terms) == 4 and fs._engine._subsets_py
    assert fs.use_native()
    for a, b in [(0.0, -1.0), (0.0, 0.0), (0.05, -0.2), (0.5, 0.3), (1.0, 1.0), (2.0, -3.0)]:
        want = fs._engine.evaluate_scalar([a, b])
        assert same(fs.evaluate(a=a, b=b), want)
    # nothing fires: a = 0 is "lo" fully, NOT lo = 0, b = -1 is not "pos"; t5's weight is 0
    assert fs.evaluate(a=0.0, b=-1.0) == 4.25
    assert math.isnan(fs.evaluate(a=math.nan, b=0.0)) and math.isnan(fs.evaluate(a=0.2, b=math.nan))
    # every activation ~1e-30: the C evaluator defers to the Python path's direct centroid
    x = [0.0, -0.5]
    assert fs._native.scalar(x) is None
    assert fs.evaluate(a=0.0, b=-0.5) == fs._engine.evaluate_scalar(x)
    # more than four output terms named by rules: the dense branch
    d["rules"] += [{"if": ["a", "hi"], "then": f"t{j}", "weight": 0.3} for j in (2, 3)]
    fs = FuzzySystem.from_dict(d)
    assert len(fs._engine.out_terms) == 6 and not fs._engine._subsets_py
    check(fs, edge_inputs(fs, 500, np.random.default_rng(1)))


# ------------------------------------------------------------------------------ the API

def test_evaluate_api_with_the_c_evaluator(native):
    fs = fuzzy.builtin("effc-5rule")
    py = fuzzy.builtin("effc-5rule")
    assert fs.use_native() and fs._native is not None
    assert py._native is None
    for kw in [{"dtheta": 0.4, "alpha": 1}, {"dtheta": True, "alpha": 0},
               {"alpha": 0.3, "dtheta": 0.2}, {"dtheta": np.float64(0.4), "alpha": np.float64(1.5)},
               {"dtheta": -9, "alpha": 9e9}, {"dtheta": math.inf, "alpha": -math.inf}]:
        got = fs.evaluate(**kw)
        assert type(got) is np.float64 and got == py.evaluate(**kw)
    assert math.isnan(fs.evaluate(dtheta=math.nan, alpha=1.0))
    # not Python numbers: the general path (size-1 arrays through the C evaluator too)
    assert fs.evaluate(dtheta=np.array(0.4), alpha=1.0) == py.evaluate(dtheta=0.4, alpha=1.0)
    assert fs.evaluate(dtheta=[0.4], alpha=1.0).tolist() == [py.evaluate(dtheta=0.4, alpha=1.0)]
    assert isinstance(fs.evaluate(dtheta=np.float32(0.4), alpha=1.0), np.float64)
    x = np.linspace(0, 1.6, 7)
    assert fs.evaluate(dtheta=x, alpha=x).tolist() == py.evaluate(dtheta=x, alpha=x).tolist()
    # errors as before
    with pytest.raises(TypeError, match="missing alpha"):
        fs.evaluate(dtheta=0.1)
    with pytest.raises(TypeError, match="unexpected beta"):
        fs.evaluate(dtheta=0.1, alpha=0.2, beta=3)
    with pytest.raises(OverflowError):
        fs.evaluate(dtheta=10**400, alpha=0.2)
    with pytest.raises(OverflowError):
        py.evaluate(dtheta=10**400, alpha=0.2)
    # copies are rebuilt from JSON: they start on the Python path, with the same results
    for other in (copy.copy(fs), pickle.loads(pickle.dumps(fs))):
        assert other._native is None and other == fs
        assert other.evaluate(dtheta=0.3, alpha=0.7) == fs.evaluate(dtheta=0.3, alpha=0.7)


class Half(float):
    """A float subclass with its own __float__: float(v) calls it, as the C evaluator must."""

    def __float__(self) -> float:
        return 0.5 * super().__float__()


def test_number_subclasses_convert_as_float_does(native):
    fs = fuzzy.builtin("effc-2rule")
    assert fs.use_native()
    assert fs.evaluate(dtheta=Half(1.2), alpha=0.5) == fs._engine.evaluate_scalar([0.6, 0.5])


# ------------------------------------------------------------------ switching and fallback

def test_the_switch_comes_after_AFTER_evaluations_and_loads_from_the_cache(cache, monkeypatch):
    _reset(monkeypatch, cache)
    builds = _native._builds
    fs = fuzzy.builtin("effc-2rule")
    for k in range(_native.AFTER - 1):
        fs.evaluate(dtheta=0.001 * k, alpha=0.5)
    assert fs._native is None and _native._module is None  # nothing loaded yet
    fs.evaluate(dtheta=0.3, alpha=0.5)
    assert fs._native is not None and fs._fast is not None
    assert _native._builds == builds                        # loaded, not compiled


def test_a_build_runs_in_the_background_and_no_call_waits(tmp_path, monkeypatch):
    _reset(monkeypatch, tmp_path)
    monkeypatch.setattr(_native, "AFTER", 5)
    builds = _native._builds
    fs = fuzzy.builtin("effc-2rule")
    for k in range(5):
        fs.evaluate(dtheta=0.1 * k, alpha=0.5)
    t = _native._thread
    assert t is not None and fs._native is None  # started, not waited for
    assert fs._countdown == 5                     # asks again 5 evaluations later
    t.join(120)
    assert _native._builds == builds + 1 and _native.library_path().is_file()
    for k in range(5):
        fs.evaluate(dtheta=0.1 * k, alpha=0.5)
    assert fs._native is not None
    # another process (nothing loaded) with the same cache loads it: no second build
    _reset(monkeypatch, tmp_path)
    assert fuzzy.builtin("effc-5rule").use_native() and _native._builds == builds + 1
    assert not list(tmp_path.rglob("*.lock")) and not list(tmp_path.rglob("*.tmp"))


@pytest.mark.parametrize("missing", ["_compiler", "_include"])
def test_no_compiler_keeps_the_python_path(tmp_path, monkeypatch, missing):
    """No C compiler, or no Python.h: never built, never asked for again."""
    _reset(monkeypatch, tmp_path)
    monkeypatch.setattr(_native, missing, lambda: None)
    monkeypatch.setattr(_native, "AFTER", 3)
    fs = fuzzy.builtin("effc-5rule")
    ref = fuzzy.builtin("effc-5rule")._engine
    assert _native.library_path() is None and not _native.build()
    assert not fs.use_native() and _native.available() is False
    for k in range(10):
        x = [0.15 * k, 0.2 * k]
        assert fs.evaluate(dtheta=x[0], alpha=x[1]) == ref.evaluate_scalar(x)
    assert fs._native is None and fs._countdown > 10**9  # never asks again
    assert _native._thread is None and not list(tmp_path.iterdir())


def test_a_compiler_that_fails_keeps_the_python_path(tmp_path, monkeypatch):
    _reset(monkeypatch, tmp_path)
    monkeypatch.setenv("CC", "false")
    fs = fuzzy.builtin("effc-2rule")
    assert not fs.use_native() and _native.available() is False
    assert fs.evaluate(dtheta=0.2, alpha=0.3) == fuzzy.builtin("effc-2rule").evaluate(
        dtheta=0.2, alpha=0.3)
    assert not list(tmp_path.rglob("*.lock"))


def test_the_environment_variable_turns_it_off(tmp_path, monkeypatch):
    _reset(monkeypatch, tmp_path)
    monkeypatch.setenv(_native.ENV, "0")
    assert _native.library_path() is None
    assert not fuzzy.builtin("effc-2rule").use_native()


def test_a_mismatch_with_the_python_path_keeps_it(native, monkeypatch, caplog):
    fs = fuzzy.builtin("effc-2rule")
    real = fs._engine.evaluate_scalar
    monkeypatch.setattr(fs._engine, "evaluate_scalar", lambda x: real(x) + 1e-9)
    assert not fs.use_native()
    assert "keeping the Python path" in caplog.text


# --------------------------------------------------------------------------------- cache

def test_the_module_is_keyed_by_its_source_and_changed_systems_get_their_own_tables(
        cache, monkeypatch, tmp_path):
    _reset(monkeypatch, cache)
    path = _native.library_path()
    assert path.is_file()
    # a changed C source is another file: never a stale module
    src = _native._source()
    monkeypatch.setattr(_native, "_source", lambda: src + "\n/* changed */\n")
    assert _native.library_path() != path
    monkeypatch.setattr(_native, "_source", lambda: src)
    assert _native.library_path() == path
    # systems share the module; a changed system evaluates as itself
    d = fuzzy.builtin("effc-2rule").to_dict()
    a = FuzzySystem.from_dict(d)
    d["output"]["terms"][0]["params"][1] += 0.1
    d["rules"][0]["weight"] = 0.7
    b = FuzzySystem.from_dict(d)
    assert a.use_native() and b.use_native()
    x = [0.4, 0.6]
    assert a.evaluate(dtheta=x[0], alpha=x[1]) != b.evaluate(dtheta=x[0], alpha=x[1])
    assert a.evaluate(dtheta=x[0], alpha=x[1]) == a._engine.evaluate_scalar(x)
    assert b.evaluate(dtheta=x[0], alpha=x[1]) == b._engine.evaluate_scalar(x)


def test_a_module_that_does_not_load_is_removed(tmp_path, monkeypatch, caplog):
    _reset(monkeypatch, tmp_path)
    path = _native.library_path()
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a shared library")
    assert not fuzzy.builtin("effc-2rule").use_native()
    assert not path.exists() and "does not load" in caplog.text
