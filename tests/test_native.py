"""The compiled control cycle (hybridnav.native) against the NumPy path it replaces.

The kernels compute what the NumPy code computes, operation for operation, except that sums run
in another order: the fuzzy family's outputs agree to rounding (1e-12 of the universe), and a
short lockstep run (before rounding differences can grow through a closed loop) gives the same
states, outcomes, lengths and clearances. Without a compiler, or switched off, every caller
falls back to NumPy.
"""

from __future__ import annotations

import dataclasses
import logging
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridnav import fuzzy, native
from hybridnav.fuzzy.family import SystemFamily
from hybridnav.native import lockstep as kernel
from hybridnav.planners.field.effc import effc_lockstep
from hybridnav.tuner.evaluate import scenario_set
from hybridnav.world import load_scenario
from hybridnav.world.schema import scenario_from_dict
from hybridnav.world.writer import scenario_to_dict
from hybridnav.world.generator import WorldGenerator

from fuzzy_strategies import antecedents, variables

pytestmark = pytest.mark.skipif(not kernel.available(), reason="no C compiler: NumPy path only")


def numpy_path(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with the compiled kernels switched off."""
    old = os.environ.get("HYBRIDNAV_NATIVE")
    os.environ["HYBRIDNAV_NATIVE"] = "0"
    try:
        return fn(*args, **kwargs)
    finally:
        if old is None:
            del os.environ["HYBRIDNAV_NATIVE"]
        else:
            os.environ["HYBRIDNAV_NATIVE"] = old


@st.composite
def families(draw):
    """A random template (2-3 inputs, AND/OR/NOT rules, weights) and 1-4 members whose MF
    parameters, weights and consequents differ."""
    n_in = draw(st.integers(1, 3))
    ins = [draw(variables(f"x{i}")) for i in range(n_in)]
    out = draw(variables("y", min_points=21))
    rules = draw(st.lists(st.fixed_dictionaries({
        "if": antecedents(ins), "then": st.sampled_from([t["name"] for t in out["terms"]]),
        "weight": st.sampled_from([1.0, 0.5, 0.0, 0.25])}), min_size=1, max_size=5))
    spec = {"format": "hybridnav-fis/1", "name": "random", "inputs": ins,
            "output": {**out, "defuzz": "centroid", "default": draw(st.floats(out["range"][0], out["range"][1]))},
            "rules": [{"if": r["if"], "then": r["then"], "weight": r["weight"]} for r in rules]}
    template = fuzzy.FuzzySystem.from_dict(spec)
    fam = SystemFamily(template)
    K = draw(st.integers(1, 4))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    T = len(template.output.terms)
    tables = fam.tables(
        [[[t.params for t in v.terms] for v in template.inputs]] * K,
        [[t.params for t in template.output.terms]] * K,
        weights=rng.choice([0.0, 0.3, 1.0], (K, len(template.rules))),
        consequents=rng.integers(0, T, (K, len(template.rules))))
    # members differ in their sampled tables too (scaled copies stay in [0, 1])
    for k in range(1, K):
        tables.output[k] *= rng.uniform(0.2, 1.0)
        for table in tables.inputs:
            table[k] *= rng.uniform(0.2, 1.0)
    return fam, tables, rng


def _inputs(fam, rng, B):
    X = {}
    for v in fam.inputs:
        lo, hi = v.range
        x = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), B)
        x[rng.random(B) < 0.05] = np.nan
        x[rng.random(B) < 0.05] = lo
        x[rng.random(B) < 0.05] = hi
        X[v.name] = x
    return X


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(families())
def test_family_kernel_equals_the_numpy_evaluation(case):
    fam, tables, rng = case
    B = 400
    member = rng.integers(0, tables.size, B)
    X = _inputs(fam, rng, B)
    want = numpy_path(fam.evaluate, tables, member, X)
    got = kernel.family_evaluate(fam, tables, member, X)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    scale = 1.0 + np.max(np.abs(fam.output.range))
    assert np.nanmax(np.abs(got - want), initial=0.0) <= 1e-12 * scale


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(families())
def test_bisection_on_monotone_runs_changes_no_bit(case):
    """Large batches find the output terms' level crossings by bisection on their monotone runs
    (kernel.monotone_runs), small ones scan every sample: the outputs are the same to the bit
    (the same crossing intervals), also for terms cut into many runs (more than the kernel
    bisects: scanned)."""
    fam, tables, rng = case
    B = 300
    member = rng.integers(0, tables.size, B)
    X = _inputs(fam, rng, B)
    for wiggle in (False, True):
        if wiggle:                               # a comb: more turns than _MAX_TURNS
            tables.output[..., ::3] *= 0.5
        big = kernel.family_evaluate(fam, tables, member, X)
        small = np.concatenate([kernel.family_evaluate(fam, tables, member[i:i + 100],
                                                       {k: v[i:i + 100] for k, v in X.items()})
                                for i in range(0, B, 100)])
        assert np.array_equal(big, small, equal_nan=True)


def test_monotone_runs_mark_each_turn():
    out = np.array([[[0, 1, 1, 2, 1, 1, 0, 0, 3], [0, 0, 0, 0, 0, 0, 0, 0, 0],
                     [1, 2, np.nan, 3, 4, 5, 6, 7, 8]]], dtype=float)
    runs = kernel.monotone_runs(out, most=2)
    assert runs[0, 0].tolist() == [2, 3, 7]      # up to sample 3, down to 7 (flat keeps the
    assert runs[0, 1].tolist()[0] == 0           # direction), up again; flat: one run
    assert runs[0, 2].tolist()[0] == -1          # a NaN sample: scanned
    assert kernel.monotone_runs(out, most=1)[0, 0, 0] == -1     # more turns than bisected


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(families(), st.integers(0, 2**32 - 1))
def test_family_kernel_equals_numpy_with_learned_antecedents(case, seed):
    fam, tables, _ = case
    rng = np.random.default_rng(seed)
    top = [2 * len(v.terms) for v in fam.inputs]
    codes = np.stack([rng.integers(0, t + 1, (tables.size, len(fam.rules))) for t in top],
                     axis=2)
    codes[rng.random(codes.shape[:2]) < 0.1] = 0            # rules that fire fully
    tables = dataclasses.replace(tables, antecedents=codes)
    member = rng.integers(0, tables.size, 300)
    X = _inputs(fam, rng, 300)
    want = numpy_path(fam.evaluate, tables, member, X)
    got = kernel.family_evaluate(fam, tables, member, X)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    scale = 1.0 + np.max(np.abs(fam.output.range))
    assert np.nanmax(np.abs(got - want), initial=0.0) <= 1e-12 * scale


def test_family_kernel_keeps_the_edge_cases():
    """Nothing fires: the default; a NaN input: NaN; inputs beyond the range: clipped."""
    fis = fuzzy.builtin("effc-2rule")
    fam = SystemFamily(fis)
    tables = fam.tables_of([fis])
    tables.weights[:] = 0.0                                  # no rule fires
    out = kernel.family_evaluate(fam, tables, np.zeros(3, int),
                                 {"dtheta": [0.1, np.nan, 1.0], "alpha": [0.5, 0.5, np.nan]})
    assert out[0] == fis.output.default and np.isnan(out[1:]).all()
    tables = fam.tables_of([fis])
    a = kernel.family_evaluate(fam, tables, np.zeros(2, int),
                               {"dtheta": [-5.0, 50.0], "alpha": [1e300, -1.0]})
    r = fis.inputs
    b = kernel.family_evaluate(fam, tables, np.zeros(2, int),
                               {"dtheta": [r[0].range[0], r[0].range[1]],
                                "alpha": [r[1].range[1], r[1].range[0]]})
    assert np.array_equal(a, b)


def _scenarios(max_time):
    gen = WorldGenerator(segments=(1, 2), rectangles=(0, 2))
    scen = [load_scenario("effc-env-a"), load_scenario("effc-env-b")] + gen.generate(4, seed=5)
    d = scenario_to_dict(scen[-1])              # a world with a moving circle as well
    d["name"] = "moving"
    d["obstacles"].append({"type": "moving_circle", "center": [2.0, 2.0], "radius": 0.3,
                           "velocity": 0.05, "heading": 0.7})
    scen.append(scenario_from_dict(d))
    return [dataclasses.replace(s, max_time=max_time) for s in scen]


PLANNER = {"speed": 0.1, "max_turn": np.pi / 4, "stuck_window": 5.0, "stuck_radius": 2.0}


@pytest.mark.parametrize("noise", [False, True])
@pytest.mark.parametrize("name", ["effc-5rule", "effc-safe"])
def test_compiled_cycle_equals_the_numpy_cycle(noise, name):
    """Every state of a 20-second run (200 cycles, outcomes tested every cycle) of 3 systems on
    7 worlds (circles, polygons, segments, a moving circle), with and without noise; also for
    a system with the optional third input (clearance)."""
    scen = _scenarios(20.0)
    st_ = scenario_set(scen)
    fis = fuzzy.builtin(name)
    fam = SystemFamily(fis)
    tables = fam.tables_of([fis] * 3)
    tables.output[1] *= 0.7                      # three different members
    tables.weights[2, :2] = 0.3
    repeats = 2
    nz = None
    if noise:
        rng = np.random.default_rng(3)
        nz = rng.normal(0.0, 1.0, (3, len(scen), 3 * repeats, 201)) * np.array(
            [0.2, 0.1, 0.1])[:, None, None, None]
    args = (st_, fam, tables, 3 * repeats, PLANNER)
    kw = {"repeats": repeats, "noise": nz, "record_paths": True}
    want = numpy_path(effc_lockstep, *args, **kw)
    got = effc_lockstep(*args, **kw)
    assert (got.outcome == want.outcome).all()
    assert set(want.outcome.ravel()) >= {"collided", "timeout", "stuck"} or noise \
        or name != "effc-5rule"
    for a, b in zip(got.paths, want.paths):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.path_length, want.path_length, rtol=1e-9)
    np.testing.assert_allclose(got.min_clearance, want.min_clearance, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.final_distance, want.final_distance, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got.time, want.time)


def test_compiled_cycle_finds_the_same_stuck_and_reached_robots():
    """A full-length run: outcomes agree (rounding differences may grow through the closed loop
    but do not change what happens on these worlds)."""
    scen = _scenarios(60.0)
    st_ = scenario_set(scen)
    fis = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(fis)
    args = (st_, fam, fam.tables_of([fis]), 1, {**PLANNER, "stuck_window": 10.0})
    want = numpy_path(effc_lockstep, *args)
    got = effc_lockstep(*args)
    assert (got.outcome == want.outcome).all()
    np.testing.assert_allclose(got.path_length, want.path_length, rtol=1e-6)


def test_without_a_compiler_every_caller_falls_back(monkeypatch, tmp_path, caplog):
    monkeypatch.setenv("HYBRIDNAV_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setattr(native, "_LOADED", {})
    monkeypatch.setattr(native, "_KERNELS", {})
    assert native.build("probe", "int f(void) { return 1; }") is None
    from hybridnav.native import attract, boxes

    assert attract._library() is None and boxes._library() is None
    assert kernel.family_evaluate(*_one_member(), {"dtheta": [0.1], "alpha": [0.2]}) is None
    fam, tables, member = _one_member()
    out = fam.evaluate(tables, member, {"dtheta": [0.1], "alpha": [0.2]})    # NumPy
    assert np.isfinite(out).all()
    monkeypatch.setenv("CC", "gcc")
    with caplog.at_level(logging.WARNING, logger="hybridnav.native"):
        assert native.build("broken", "this is not C") is None
    assert "compiling broken" in caplog.text
    assert not list(tmp_path.glob("native/*.so"))


def test_a_built_library_is_reused_and_a_changed_source_rebuilt(monkeypatch, tmp_path):
    monkeypatch.setenv("HYBRIDNAV_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(native, "_LOADED", {})
    a = native.build("probe", "int f(void) { return 1; }")
    assert a is not None and a.f() == 1
    monkeypatch.setattr(native, "_LOADED", {})
    b = native.build("probe", "int f(void) { return 1; }")
    assert len(list(tmp_path.glob("native/probe-*.so"))) == 1 and b.f() == 1
    c = native.build("probe", "int f(void) { return 2; }")
    assert c.f() == 2 and len(list(tmp_path.glob("native/probe-*.so"))) == 2


def _one_member():
    fis = fuzzy.builtin("effc-2rule")
    fam = SystemFamily(fis)
    return fam, fam.tables_of([fis]), np.zeros(1, int)


def test_tables_the_kernel_cannot_read_safely_go_to_numpy():
    """Members, consequents, rule codes or shapes out of range (tables are mutable after
    ``tables()`` checked them) never reach C: the NumPy path runs and raises or ignores as it
    always did."""
    fam, tables, _ = _one_member()
    x = {"dtheta": [0.1, 0.2], "alpha": [0.3, 0.4]}
    for member in ([0, 1], [-1, 0], [0, 10**6]):
        assert kernel.family_evaluate(fam, tables, np.array(member), x) is None
    with pytest.raises(IndexError):
        fam.evaluate(tables, np.array([0, 1]), x)
    bad = dataclasses.replace(tables, consequents=tables.consequents + 5)
    assert kernel.family_evaluate(fam, bad, np.zeros(2, int), x) is None
    codes = np.full((1, len(fam.rules), 2), 99)
    assert kernel.family_evaluate(fam, dataclasses.replace(tables, antecedents=codes),
                                  np.zeros(2, int), x) is None
    short = dataclasses.replace(tables, output=tables.output[:, :, :5])
    assert kernel.family_evaluate(fam, short, np.zeros(2, int), x) is None
    assert kernel.family_evaluate(fam, tables, np.zeros(2, int),
                                  {"dtheta": [0.1], "alpha": [0.3, 0.4]}) is None


def test_effc_arguments_the_kernel_cannot_take_go_to_numpy():
    scen = _scenarios(3.0)[:2]
    st_ = scenario_set(scen)
    fis = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(fis)
    tables = fam.tables_of([fis])
    with pytest.raises(IndexError):                          # 2 members of a 1-member table
        effc_lockstep(st_, fam, tables, 2, PLANNER)
    wide = np.zeros((3, len(scen) + 2, 1, 31))               # noise for other worlds
    want = numpy_path(effc_lockstep, st_, fam, tables, 1, PLANNER, noise=wide[:, :2].copy())
    with pytest.raises(IndexError):
        numpy_path(effc_lockstep, st_, fam, tables, 1, PLANNER, noise=wide[:, :, :, :0])
    got = effc_lockstep(st_, fam, tables, 1, PLANNER, noise=wide[:, :2].copy())
    assert (got.outcome == want.outcome).all()


def test_a_stuck_window_longer_than_the_run_is_never_tested():
    """Cut to the run's length (no ring buffer of 2^32 cycles, no int overflow in C)."""
    scen = _scenarios(5.0)[:2]
    st_ = scenario_set(scen)
    fis = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(fis)
    args = (st_, fam, fam.tables_of([fis]), 1)
    huge = effc_lockstep(*args, {**PLANNER, "stuck_window": 429496729.7})
    none = effc_lockstep(*args, {**PLANNER, "stuck_window": 0.0})
    assert (huge.outcome == none.outcome).all() and "stuck" not in set(huge.outcome.ravel())
    assert (numpy_path(effc_lockstep, *args, {**PLANNER, "stuck_window": 1e12}).outcome
            == none.outcome).all()


def test_a_truncated_library_in_the_cache_is_built_again(monkeypatch, tmp_path):
    monkeypatch.setenv("HYBRIDNAV_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(native, "_LOADED", {})
    code = "int f(void) { return 7; }"
    assert native.build("probe", code).f() == 7
    (so,) = tmp_path.glob("native/probe-*.so")
    whole = so.read_bytes()
    part = tmp_path / "part"
    part.write_bytes(whole[:1000])                           # a partial copy (a new file: the
    os.replace(part, so)                                     # loaded one stays mapped)
    monkeypatch.setattr(native, "_LOADED", {})
    assert native.build("probe", code).f() == 7
    assert so.read_bytes() == whole                          # built again, not loaded


def test_processes_sharing_the_cache_build_a_library_once(tmp_path):
    """Two processes asking for the same new library at once: one builds it, the other waits
    for it and loads it (no half-written pair, no second build)."""
    import subprocess
    import sys

    code = ("import time, hybridnav.native as n; "
            "lib = n.build('race', 'int f(void) { return 5; }'); print(lib.f())")
    env = {**os.environ, "HYBRIDNAV_CACHE_DIR": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [o.strip() for o, _ in outs] == ["5", "5", "5"]
    assert not any("does not match" in e for _, e in outs)
    assert len(list(tmp_path.glob("native/race-*.so"))) == 1


@pytest.mark.parametrize("margin", [0.0, 0.05])
def test_the_candidate_grid_changes_no_bit(monkeypatch, margin):
    """The compiled cycle searching only each cell's candidate obstacles
    (``WorldStack.cells``; ``kernel.CELLS``) gives the same runs bit for bit as searching every
    obstacle, with the escape filter (whose clearance queries reach outside the workspace) on
    and off, on generated worlds with circles, segments and rectangles."""
    gen = WorldGenerator(segments=(1, 3), rectangles=(1, 3))
    scen = [dataclasses.replace(s, max_time=40.0)
            for s in [load_scenario("effc-env-a"), load_scenario("effc-env-b")]
            + gen.generate(8, seed=11)]
    fis = fuzzy.builtin("effc-safe")
    fam = SystemFamily(fis)
    tables = fam.tables_of([fis] * 2)
    tables.output[1] *= 0.6
    planner = {**PLANNER, "safety_margin": margin}
    runs = []
    for cells in (0, 32):
        monkeypatch.setattr(kernel, "CELLS", cells)
        st_ = scenario_set(scen)
        runs.append(effc_lockstep(st_, fam, tables, 2, planner, record_paths=True))
    a, b = runs
    assert (a.outcome == b.outcome).all()
    assert len(set(a.outcome.ravel())) >= 2
    for f in ("path_length", "time", "min_clearance", "final_distance"):
        assert np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True), f
    for p, q in zip(a.paths, b.paths):
        assert np.array_equal(p, q)


@pytest.mark.parametrize("params", [
    {},                                                       # the planner's defaults
    {"rho0": 1.5, "eta": 0.3, "sigma0": 0.4, "safety_margin": 0.05},
    {"force_tol": 0.2, "xi": 2.0},                            # local minima: stuck
])
def test_compiled_apf_cycle_equals_the_numpy_cycle(params):
    """APF's lockstep run (apf_lockstep: the attraction, every obstacle's repulsion within
    rho0, the local-minimum test, the optional escape filter) compiled and in NumPy: the same
    outcomes, paths, lengths and clearances on worlds with circles, polygons, segments and a
    moving circle."""
    from hybridnav.planners.field.apf import apf_lockstep

    st_ = scenario_set(_scenarios(30.0))
    kw = {"record_paths": True}
    want = numpy_path(apf_lockstep, st_, {**PLANNER, **params}, **kw)
    got = apf_lockstep(st_, {**PLANNER, **params}, **kw)
    assert (got.outcome == want.outcome).all()
    assert len(set(want.outcome.ravel())) >= 2
    for a, b in zip(got.paths, want.paths):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.path_length, want.path_length, rtol=1e-9)
    np.testing.assert_allclose(got.min_clearance, want.min_clearance, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got.time, want.time)
