"""FuzzySystem.evaluate against scikit-fuzzy's ControlSystemSimulation.compute() on random systems.

Hypothesis draws systems with every membership function (valid random parameters, some of them
snapped to universe samples so that cut levels hit sample values exactly), 1-3 inputs with 2-4
terms, random and/or/not rule trees, random weights, 11-201 points, and inputs inside and outside
the ranges (clipping) and on universe samples. Where scikit-fuzzy produces no output (no rule
fired) ``evaluate`` must return the file's ``default``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.engine import _crossing_table

pytestmark = pytest.mark.filterwarnings(
    "ignore:Passing more than 2 positional arguments:DeprecationWarning")

TOL = 1e-9
from fuzzy_strategies import MFS, antecedents, examples, terms, variables  # noqa: E402,F401


@st.composite
def systems(draw) -> dict:
    n_in = draw(st.integers(1, 3))
    inputs = [draw(variables(f"x{i}")) for i in range(n_in)]
    out = draw(variables("y"))
    out["defuzz"] = "centroid"
    out["default"] = draw(st.floats(*out["range"]))
    names = [t["name"] for t in out["terms"]]
    rules = draw(st.lists(st.fixed_dictionaries({
        "if": antecedents(inputs),
        "then": st.sampled_from(names),
        "weight": st.one_of(st.just(1.0), st.floats(0.0, 1.0), st.sampled_from([0.0, 0.5])),
    }), min_size=1, max_size=6))
    return {"format": "hybridnav-fis/1", "name": "h", "inputs": inputs, "output": out,
            "rules": rules}


def reference(fs: FuzzySystem, cols: list[np.ndarray]) -> np.ndarray:
    """scikit-fuzzy per sample (NaN where it gives no output).

    ``cache=False``: with its cache on, scikit-fuzzy answers a repeated input for which no rule
    fired with the previous sample's output.
    """
    from skfuzzy import control as ctrl

    cs = fs.to_skfuzzy()
    sim = ctrl.ControlSystemSimulation(cs, cache=False)
    used = {a.label for a in cs.antecedents}
    out = np.empty(len(cols[0]))
    for k in range(len(out)):
        for name, c in zip(fs.input_names, cols):
            if name in used:  # inputs no rule names are not part of a skfuzzy system
                sim.input[name] = float(c[k])
        sim.compute()
        out[k] = sim.output.get(fs.output.name, np.nan)
    return out


@pytest.mark.slow
# 100 random systems in the default run (HYBRIDNAV_FUZZ_EXAMPLES=N runs N)
@settings(deadline=None, max_examples=examples(100), suppress_health_check=[HealthCheck.too_slow])
@given(d=systems(), seed=st.integers(0, 2**32 - 1))
def test_evaluate_matches_skfuzzy(d, seed):
    fs = FuzzySystem.from_dict(d)
    assert FuzzySystem.from_dict(fs.to_dict()) == fs  # JSON round trip of random systems
    rng = np.random.default_rng(seed)
    n = 16
    cols = []
    for v in fs.inputs:
        lo, hi = v.range
        w = hi - lo
        grid = np.linspace(lo, hi, v.points)
        c = rng.uniform(lo - 0.3 * w, hi + 0.3 * w, n)  # outside the range: clipping
        c[:5] = rng.choice(grid, 5)  # exactly on universe samples
        c[5] = lo
        c[6] = hi
        rng.shuffle(c)
        cols.append(c)
    ref = reference(fs, cols)
    got = fs.evaluate(**dict(zip(fs.input_names, cols)))
    fired = ~np.isnan(ref)
    if fired.any():
        # Where the strongest activation c is tiny, the crossing points (where a term falls to
        # c) carry rounding of about 1e-16 of the term's scale, i.e. 1e-16 / c relative to the
        # clipped area: both implementations are only that accurate there (a derandomized run
        # found c = 1.7e-11 giving 3e-9 apart, ours the closer to the exact integral).
        act = max_activation(fs, cols)
        width = fs.output.range[1] - fs.output.range[0]
        tol = TOL + width * 1e-15 / np.maximum(act, 1e-300)
        assert np.all(np.abs(got[fired] - ref[fired]) <= tol[fired])
    assert np.all(got[~fired] == fs.output.default)
    # the scalar (batch-of-one) path agrees with the batch path
    one = np.array([fs.evaluate(**{nm: float(c[k]) for nm, c in zip(fs.input_names, cols)})
                    for k in range(n)])
    np.testing.assert_allclose(one, got, rtol=0, atol=1e-12)


def max_activation(fs: FuzzySystem, cols: list[np.ndarray]) -> np.ndarray:
    """The strongest rule activation (firing strength x weight) of each sample."""
    from hybridnav.fuzzy.family import SystemFamily

    fam = SystemFamily(fs)
    tables = fam.tables_of([fs])
    mu = {}
    for i, (v, x) in enumerate(zip(fs.inputs, cols)):
        xs = np.linspace(v.range[0], v.range[1], v.points)
        for j in range(len(v.terms)):
            mu[(i, j)] = np.interp(x, xs, tables.inputs[i][0, j])
    return np.max([fam._fire(r.antecedent, mu) * r.weight for r in fs.rules], axis=0)


@pytest.mark.parametrize("n_terms", [4, 5, 7])
def test_many_output_terms_dense_path(n_terms):
    """More than SUBSETS_MAX output terms in rules: the (M, B) path, checked the same way."""
    from hybridnav.fuzzy.engine import SUBSETS_MAX

    assert n_terms > SUBSETS_MAX
    centers = np.linspace(0.0, 10.0, n_terms)
    out_terms = [{"name": f"o{j}", "mf": mf, "params": p} for j, (mf, p) in enumerate(
        [("trimf", [c - 3.0, c, c + 2.5]) if j % 3 == 0 else ("gaussmf", [c, 1.3]) if j % 3 == 1
         else ("trapmf", [c - 2.0, c - 0.4, c + 0.3, c + 1.9]) for j, c in enumerate(centers)])]
    inputs = [{"name": "a", "range": [-1.0, 1.0], "points": 41,
               "terms": [{"name": f"a{j}", "mf": "gaussmf", "params": [float(m), 0.4]}
                         for j, m in enumerate(np.linspace(-1, 1, n_terms))]},
              {"name": "b", "range": [0.0, 3.0], "points": 17,
               "terms": [{"name": "lo", "mf": "zmf", "params": [0.5, 2.0]},
                         {"name": "hi", "mf": "sigmf", "params": [1.5, 4.0]}]}]
    rules = [{"if": {"and": [["a", f"a{j}"], ["b", "lo" if j % 2 else "hi"]]}, "then": f"o{j}",
              "weight": 1.0 - 0.1 * j} for j in range(n_terms)]
    rules.append({"if": {"not": ["b", "hi"]}, "then": "o0", "weight": 0.3})
    fs = FuzzySystem.from_dict({"format": "hybridnav-fis/1", "name": "many", "inputs": inputs,
                                "output": {"name": "y", "range": [0.0, 10.0], "points": 101,
                                           "terms": out_terms, "defuzz": "centroid",
                                           "default": 5.0},
                                "rules": rules})
    assert len(fs._engine.out_terms) == n_terms
    rng = np.random.default_rng(n_terms)
    cols = [rng.uniform(-1.3, 1.3, 120), rng.uniform(-0.5, 3.5, 120)]
    ref = reference(fs, cols)
    got = fs.evaluate(a=cols[0], b=cols[1])
    fired = ~np.isnan(ref)
    assert fired.sum() > 100
    assert np.max(np.abs(got[fired] - ref[fired])) <= TOL
    assert np.all(got[~fired] == 5.0)
    one = [fs.evaluate(a=float(x), b=float(y)) for x, y in zip(*cols)]
    np.testing.assert_allclose(one, got, rtol=0, atol=1e-12)


@settings(deadline=None, max_examples=200)
@given(f=st.lists(st.sampled_from([0.0, 0.25, 0.5, 1.0]) | st.floats(0.0, 1.0), min_size=2,
                  max_size=40),
       ys=st.lists(st.floats(0.0, 1.0, exclude_min=True) | st.sampled_from([0.25, 0.5, 1.0]),
                   min_size=1, max_size=10))
def test_crossing_table_is_skfuzzys_interp_universe(f, ys):
    f = np.array(f)
    levels, table = _crossing_table(f)
    for y in ys:
        want = np.nonzero(np.diff(f >= y))[0]  # skfuzzy's _interp_universe_fast for y > 0
        row = table[np.searchsorted(levels, y)]
        assert row[row >= 0].tolist() == want.tolist()


def test_tiny_activations_match_skfuzzy_batch_and_scalar():
    """All activations ~1e-177: the centroid is moment / eps, tiny, not rounding noise."""
    fs = FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "tiny",
        "inputs": [{"name": "x0", "range": [0.0, 1.0], "points": 11,
                    "terms": [{"name": "t0", "mf": "zmf", "params": [0.0, 0.3]}]}],
        "output": {"name": "y", "range": [1.0, 3.5], "points": 29,
                   "terms": [{"name": "t2", "mf": "trapmf",
                              "params": [1.0, 1.0, 1.0, 1.4464285714285714]}],
                   "defuzz": "centroid", "default": 1.0},
        "rules": [{"if": ["x0", "t0"], "then": "t2", "weight": 6.681712657784575e-177}]})
    x = np.linspace(0.0, 0.25, 9)
    ref = reference(fs, [x])
    assert np.abs(fs.evaluate(x0=x) - ref).max() <= 1e-170
    assert abs(fs.evaluate(x0=float(x[1])) - ref[1]) <= 1e-170
