"""The generated C99 code against FuzzySystem.evaluate: compiled with gcc -std=c99 -Wall -Wextra
-Wconversion -Wdouble-promotion -Werror -pedantic (double and float builds), run through a small driver on random inputs (inside and outside the ranges,
on universe samples, NaN), equal within 1e-9 in double (hypothesis systems: every membership
function, nested and/or/not rules, weights, 2-201 points); float builds within 1e-4 of the range.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export import ZOO, evaluate, max_strength, random_inputs, systems

from hybridnav import HybridnavError, fuzzy
from hybridnav.fuzzy import FuzzySystem
from hybridnav.fuzzy.export import c_identifier, export, to_c

CC = shutil.which("gcc") or shutil.which("cc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (gcc or cc) on PATH")
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wconversion", "-Wdouble-promotion", "-Werror",
          "-pedantic", "-O2"]

DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "{base}.h"

/* reads rows of {P}_N_INPUTS numbers from stdin, prints one output per row (%.17g) */
int main(void)
{{
    char buf[64];
    {p}_real in[{P}_N_INPUTS];
    int i = 0;
    while (scanf("%63s", buf) == 1) {{
        in[i++] = ({p}_real)strtod(buf, NULL);
        if (i == {P}_N_INPUTS) {{
            printf("%.17g\n", (double){p}_evaluate(in));
            i = 0;
        }}
    }}
    return 0;
}}
"""


def build(tmp_path: Path, fs: FuzzySystem, *, defines: tuple[str, ...] = (),
          **options: object) -> Path:
    """Export ``fs`` as C into ``tmp_path``, compile it with a driver, return the executable."""
    code = export(fs, "c", tmp_path / "fis", **options)
    p = c_identifier(code.basename)
    (tmp_path / "driver.c").write_text(DRIVER.format(base=code.basename, p=p, P=p.upper()))
    exe = tmp_path / "driver"
    res = subprocess.run([CC, *CFLAGS, *defines, "-o", str(exe), str(tmp_path / "driver.c"),
                          str(tmp_path / "fis.c")], capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""  # no warnings either
    return exe


def run(exe: Path, X: np.ndarray) -> np.ndarray:
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in X) + "\n"
    res = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True,
                         timeout=60)
    return np.array([float(v) for v in res.stdout.split()])


@pytest.mark.parametrize("name", ["effc-5rule", "effc-2rule"])
def test_builtins_match_evaluate(tmp_path, name):
    fs = fuzzy.builtin(name)
    exe = build(tmp_path, fs)
    X = random_inputs(fs, 2000, np.random.default_rng(0))
    X[5, 0] = np.nan
    got, want = run(exe, X), evaluate(fs, X)
    assert np.isnan(got[5]) and np.isnan(want[5])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.any(want == fs.output.default)  # some samples fire no rule: the default


def test_zoo_matches_evaluate(tmp_path):
    fs = FuzzySystem.from_dict(ZOO)
    exe = build(tmp_path, fs)
    X = random_inputs(fs, 3000, np.random.default_rng(1))
    np.testing.assert_allclose(run(exe, X), evaluate(fs, X), rtol=0, atol=1e-9)


def skfuzzy_reference(fs: FuzzySystem, X: np.ndarray) -> np.ndarray:
    """scikit-fuzzy's ControlSystemSimulation per sample (NaN where it gives no output)."""
    import warnings

    from skfuzzy import control as ctrl

    cs = fs.to_skfuzzy()
    sim = ctrl.ControlSystemSimulation(cs, cache=False)
    used = {a.label for a in cs.antecedents}
    out = np.empty(len(X))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # skfuzzy 0.5.0 on NumPy >= 2.4
        for k, row in enumerate(X):
            for name, v in zip(fs.input_names, row):
                if name in used:
                    sim.input[name] = float(v)
            sim.compute()
            out[k] = sim.output.get(fs.output.name, np.nan)
    return out


@pytest.mark.slow
@settings(deadline=None, max_examples=30, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(d=systems(descriptions=False), seed=st.integers(0, 2**32 - 1))
def test_random_systems_match_evaluate(tmp_path_factory, d, seed):
    """One compile per system; 200 inputs each, within 1e-9 of ``evaluate``.

    Where every rule activation is below 1e-12 (weights like 1e-38) the aggregated area is at
    the level of rounding errors and the centroid is ``moment / eps``: there ``evaluate``'s
    closed-form crossing corrections can be off by their own rounding (~1e-20 in area, so up to
    ~1e-6 in the output), and the C code is checked against scikit-fuzzy itself instead.
    """
    fs = FuzzySystem.from_dict(d)
    exe = build(tmp_path_factory.mktemp("c"), fs)
    X = random_inputs(fs, 200, np.random.default_rng(seed))
    got, want = run(exe, X), evaluate(fs, X)
    strength = max_strength(fs, X)
    tiny = strength < 1e-12
    # Where the strongest activation c is small, the crossing points (where a term falls to c)
    # carry rounding of about 1e-16 of the term's scale, i.e. 1e-16 / c relative to the clipped
    # area, in both implementations (a CI run found c ~ 3e-10 giving 1.8e-9 apart): the bound
    # is the problem's conditioning, as in the scikit-fuzzy agreement test.
    width = fs.output.range[1] - fs.output.range[0]
    tol = 1e-9 + width * 1e-15 / np.maximum(strength, 1e-300)
    assert np.all(np.abs(got[~tiny] - want[~tiny]) <= tol[~tiny])
    if tiny.any():
        ref = skfuzzy_reference(fs, X[tiny])
        fired = ~np.isnan(ref)
        np.testing.assert_allclose(got[tiny][fired], ref[fired], rtol=0, atol=1e-9)
        assert np.all(got[tiny][~fired] == fs.output.default)


@pytest.mark.filterwarnings("ignore:Passing more than 2 positional arguments:DeprecationWarning")
def test_tiny_activations_follow_skfuzzy(tmp_path):
    """The degenerate case above, pinned: scikit-fuzzy and the C code give ~1e-23 (area below
    eps), ``evaluate`` gives -6.5e-7 (rounding in its crossing correction; reported upstream)."""
    d = {"format": "hybridnav-fis/1", "name": "tiny",
         "inputs": [{"name": "x0", "range": [0.0, 1.0], "points": 2,
                     "terms": [{"name": "t0", "mf": "zmf", "params": [0.0, 0.3]}]}],
         "output": {"name": "y", "range": [0.0, 1.90625], "points": 180,
                    "terms": [{"name": "t0", "mf": "zmf", "params": [0.0, 1.0]}],
                    "defuzz": "centroid", "default": 0.0},
         "rules": [{"if": ["x0", "t0"], "then": "t0", "weight": 1.175494351e-38}]}
    fs = FuzzySystem.from_dict(d)
    X = np.array([[0.0], [0.5]])
    got = run(build(tmp_path, fs), X)
    np.testing.assert_allclose(got, skfuzzy_reference(fs, X), rtol=1e-9, atol=0)
    assert np.all(np.abs(got) < 1e-20) and np.all(np.abs(evaluate(fs, X)) < 1e-5)


@pytest.mark.parametrize("how", ["macro", "option"])
def test_float_build(tmp_path, how):
    fs = FuzzySystem.from_dict(ZOO)
    p = c_identifier("fis").upper()
    if how == "macro":
        exe = build(tmp_path, fs, defines=(f"-D{p}_REAL=float",))
    else:
        exe = build(tmp_path, fs, real="float")
        assert f"#define {p}_REAL float" in (tmp_path / "fis.h").read_text()
    X = random_inputs(fs, 1000, np.random.default_rng(2))
    got, want = run(exe, X), evaluate(fs, X)
    width = fs.output.range[1] - fs.output.range[0]
    assert np.max(np.abs(got - want)) / width < 1e-4
    assert np.max(np.abs(got - want)) > 0  # it really is single precision


def test_code_is_standalone(tmp_path):
    fs = fuzzy.builtin("effc-5rule")
    code = to_c(fs)
    assert code.basename == "effc_5rule"
    # its own header and the freestanding <stdint.h> only (no libc, no libm)
    assert re.findall(r"#include\s+(\S+)", code.source) == ["<stdint.h>", '"effc_5rule.h"']
    assert re.findall(r"#include\s+(\S+)", code.header) == []
    for word in ("malloc", "calloc", "realloc", "free(", "static double", "math.h"):
        assert word not in code.source
    assert "double effc_5rule_evaluate" not in code.header  # the type is the REAL macro
    assert "effc_5rule_real effc_5rule_evaluate(const effc_5rule_real in[EFFC_5RULE_N_INPUTS]);" \
        in code.header
    assert "#define EFFC_5RULE_IN_DTHETA 0" in code.header
    assert "#define EFFC_5RULE_DEFAULT ((effc_5rule_real)0.5)" in code.header
    # compiles on its own as C99 and links without libm
    res = subprocess.run([CC, *CFLAGS, "-c", "-o", str(tmp_path / "x.o"), "-x", "c", "-"],
                         input=code.header.replace('#include "effc_5rule.h"', "") + "\n",
                         capture_output=True, text=True, cwd=tmp_path, check=False)
    assert res.returncode == 0, res.stderr


def test_names_become_identifiers():
    d = fuzzy.builtin("effc-2rule").to_dict()
    d["name"] = "3 wheel/robot"
    code = to_c(FuzzySystem.from_dict(d))
    assert code.basename == "fis_3_wheel_robot" and "fis_3_wheel_robot_evaluate" in code.header
    d["inputs"][1]["name"] = "DTHETA"
    d["rules"] = [{"if": ["DTHETA", "low"], "then": "low"}]
    with pytest.raises(HybridnavError, match="clashing C macros"):
        to_c(FuzzySystem.from_dict(d))
    with pytest.raises(HybridnavError, match="invalid file base name"):
        to_c(fuzzy.builtin("effc-2rule"), "a/b")


@settings(deadline=None, max_examples=200)
@given(f=st.lists(st.sampled_from([0.0, 0.25, 0.5, 1.0]) | st.floats(0.0, 1.0), min_size=2,
                  max_size=60))
def test_crossing_buffer_bound(f):
    """max_crossings is the widest row of the evaluator's own crossing table (all levels y > 0);
    the C buffers, sized by the monotone runs, hold it (test_monotone_runs_bound_the_crossings)."""
    from hybridnav.fuzzy.engine import _crossing_table
    from hybridnav.fuzzy.export.c import max_crossings

    f = np.array(f)
    assert max_crossings(f) == _crossing_table(f)[1].shape[1]


@settings(deadline=None, max_examples=300)
@given(f=st.lists(st.sampled_from([0.0, 0.25, 0.5, 1.0]) | st.floats(0.0, 1.0), min_size=2,
                  max_size=60))
def test_monotone_runs_bound_the_crossings(f):
    """The table path looks for one crossing per monotone run of a term (binary search): the
    runs partition the intervals, each is monotone (also rounded to float), and at every level
    y > 0 each run holds at most one of the intervals scikit-fuzzy inserts a point in."""
    from hybridnav.fuzzy.engine import _crossing_table
    from hybridnav.fuzzy.export.c import monotone_runs

    f = np.array(f)
    runs = monotone_runs(f)
    assert runs[0][0] == 0 and runs[-1][1] == len(f) - 1
    assert all(b == c for (_, b), (c, _) in zip(runs, runs[1:]))
    for g in (f, f.astype(np.float32).astype(float)):
        for a, b in runs:
            d = np.diff(g[a:b + 1])
            assert a < b or len(f) == 1
            assert np.all(d >= 0) or np.all(d <= 0)
    levels, table = _crossing_table(f)
    run_of = np.concatenate([[r] * (b - a) for r, (a, b) in enumerate(runs)])
    for row in table[1:]:
        hits = run_of[row[row >= 0]]
        assert len(hits) == len(set(hits.tolist()))


def test_plain_integral_paths(tmp_path):
    """Up to four output terms (as evaluate's scalar path) the plain-universe integral comes from
    subset prefix-sum tables, beyond that from the sample weights; both agree with evaluate (the
    builtins and ZOO above)."""
    few, many = to_c(fuzzy.builtin("effc-tuned")).source, to_c(FuzzySystem.from_dict(ZOO)).source
    assert "effc_tuned_sub2_pq" in few and "effc_tuned_w[" not in few
    assert "zoo_w[" in many and "zoo_sub0_lv" not in many and "zoo_lower_bound" not in many


@pytest.mark.parametrize("span", [(-1e300, 1e300), (0.0, 1e-300), (1.0, 1.0 + 1e-12)])
def test_extreme_input_ranges_match_evaluate(tmp_path, span):
    """An input's interval is guessed from the uniform grid and corrected against the samples;
    where (M - 1) / (hi - lo) or the guess is not finite in double or float (the first two
    spans), the code falls back to binary search. Both give numpy's interval."""
    from hybridnav.fuzzy.engine import universe
    from hybridnav.fuzzy.export.c import _uniform_inverse

    d = fuzzy.builtin("effc-2rule").to_dict()
    a, b = span
    d["inputs"][1]["range"] = [a, b]
    for term in d["inputs"][1]["terms"]:
        term["params"] = [a + (b - a) * 0.1, a + (b - a) * 0.5]
    fs = FuzzySystem.from_dict(d)
    assert (_uniform_inverse(universe(fs.inputs[1])) > 0) == (span[0] == 1.0)
    exe = build(tmp_path, fs)
    X = random_inputs(fs, 1000, np.random.default_rng(7))
    np.testing.assert_allclose(run(exe, X), evaluate(fs, X), rtol=0, atol=1e-12)


@pytest.mark.parametrize("real", ["double", "float"])
def test_nan_in_nan_out_survives_fast_math(tmp_path, real):
    """The NaN policy: a NaN input returns NaN; the check tests the bits, so -ffast-math (which
    lets gcc drop ``v != v``) keeps it."""
    fs = fuzzy.builtin("effc-tuned")
    exe = build(tmp_path, fs, defines=("-ffast-math",), real=real)
    X = random_inputs(fs, 200, np.random.default_rng(5))
    X[[3, 7], 0] = np.nan
    X[[11], 1] = np.nan
    got = run(exe, X)
    assert np.isnan(got[[3, 7, 11]]).all()
    ok = ~np.isnan(X).any(axis=1)
    tol = 1e-9 if real == "double" else 1e-4
    np.testing.assert_allclose(got[ok], evaluate(fs, X[ok]), rtol=0, atol=tol)


def test_the_readme_main_c_compiles_against_the_tuners_export(tmp_path):
    """The README's main.c, as it is written there, against the C files ``hybridnav tune`` writes
    (the same stem) and against ``hybridnav export ... -o build/effc``."""
    from hybridnav.tuner.run import C_BASENAME

    readme = (Path(__file__).parent.parent / "README.md").read_text(encoding="utf-8")
    main_c = re.search(r"```c\n(.*?)```", readme, re.S).group(1)
    assert C_BASENAME == "effc" and '#include "effc.h"' in main_c
    (tmp_path / "main.c").write_text(main_c)
    export(fuzzy.builtin("effc-tuned"), "c", tmp_path / C_BASENAME)
    exe = tmp_path / "main"
    res = subprocess.run([CC, *CFLAGS, "-o", str(exe), str(tmp_path / "main.c"),
                          str(tmp_path / "effc.c")], capture_output=True, text=True, check=False)
    assert res.returncode == 0 and res.stderr == "", res.stderr
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    want = float(fuzzy.builtin("effc-tuned").evaluate(dtheta=0.3, alpha=0.15))
    assert out.startswith("w = ") and abs(float(out.split("=")[1]) - want) < 1e-6


def _one_term(out_range, points, mf, params):
    """A system whose single output term's cut equals the input: xi in [0, 1], 'up' the line."""
    return FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "fis",
        "inputs": [{"name": "xi", "range": [0.0, 1.0], "points": 2,
                    "terms": [{"name": "up", "mf": "trimf", "params": [0.0, 1.0, 1.0]}]}],
        "output": {"name": "oi", "range": list(out_range), "points": points,
                   "terms": [{"name": "o", "mf": mf, "params": list(params)}],
                   "defuzz": "centroid", "default": 0.0},
        "rules": [{"if": ["xi", "up"], "then": "o", "weight": 1.0}]})


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("out_range, points, mf, params, cut", [
    ((0.0, 0.1), 2, "zmf", (0.0, 0.03), 1.4128e-11),
    ((0.0, 0.1), 3, "trimf", (0.0, 0.0, 0.05), 1e-12),
    ((-1e9, 1e9), 3, "gbellmf", (6e8, 30.0, 0.0), 1e-12),
    ((-1e9, 1e9), 3, "gbellmf", (6e8, 30.0, 0.0), 1e-9),
    ((-1e9, 1e9), 3, "gbellmf", (6e8, 30.0, 0.0), 1e-7),
])
def test_tiny_activations_equal_skfuzzy_bit_for_bit(tmp_path, out_range, points, mf, params,
                                                     cut):
    """Where the aggregated area is tiny both evaluators compute the polyline itself, with
    np.interp at the crossing points, as scikit-fuzzy does (a review found evaluate's direct
    path interpolating differently: 0.088 apart from skfuzzy at cut 1e-7 on the wide range)."""
    fs = _one_term(out_range, points, mf, params)
    X = np.array([[cut]])
    c = run(build(tmp_path, fs), X)[0]
    assert c == fs.evaluate(xi=cut) == skfuzzy_reference(fs, X)[0]


def test_ranges_whose_tables_would_overflow_never_reach_the_c_export():
    """The ranges that made the C tables overflow (samples, centroid weights) are refused when
    the system is read (``spec.range_problem``), so ``to_c`` never sees them; its own check of
    the tables stays as a second line."""
    d = fuzzy.builtin("effc-2rule").to_dict()
    d["inputs"][1]["range"] = [-1.7e308, 1.7e308]
    with pytest.raises(HybridnavError, match=r"inputs\[1\]\.range: expected a range whose "
                                             r"width hi - lo is finite in double"):
        FuzzySystem.from_dict(d)
    with pytest.raises(HybridnavError, match=r"output\.range: expected an output range with "
                                             r"max\(\|lo\|, \|hi\|\) \* \(hi - lo\) <= 2\*\*1000"):
        _one_term((0.0, 1e200), 11, "trimf", (0.0, 5e199, 1e200))


def test_the_direct_path_needs_no_stack_of_the_universes_size(tmp_path):
    """20001 output points and a tiny activation (the direct path) under a 64 KiB stack: the
    direct centroid visits the points one segment at a time (it used to keep two arrays of the
    universe's size on the stack: 320 KB here, a segfault at 600000 points)."""
    import resource

    fs = _one_term((0.0, 1.0), 20001, "trimf", (0.2, 0.5, 0.8))
    code = to_c(fs)
    stack = int(re.search(r"about (\d+) bytes", code.header).group(1))
    assert stack < 1024
    exe = build(tmp_path, fs)
    X = np.array([[1e-9], [0.5], [1.0]])

    def small_stack():
        resource.setrlimit(resource.RLIMIT_STACK, (64 * 1024, 64 * 1024))

    text = "\n".join(repr(float(v)) for v in X[:, 0]) + "\n"
    res = subprocess.run([str(exe)], input=text, capture_output=True, text=True, timeout=60,
                         preexec_fn=small_stack, check=False)
    assert res.returncode == 0, res.returncode
    got = np.array([float(v) for v in res.stdout.split()])
    np.testing.assert_allclose(got, evaluate(fs, X), rtol=0, atol=1e-12)


@pytest.mark.parametrize("flags", [("-Os",), ("-O0",), ("-O3",), ("-Og",),
                                   ("-O1", "-fsanitize=address,undefined")],
                         ids=lambda f: " ".join(f))
def test_other_optimization_levels_and_sanitizers_build_clean(tmp_path, flags):
    """-Werror with the strict warnings at other levels (gcc's flow analysis differs: -Os and
    the sanitizers warned about the crossing buffers of one-term systems), and the sanitized
    build runs clean and right."""
    systems = [_one_term((0.0, 1.0), 101, "zmf", (0.1, 0.6)),
               _one_term((0.0, 1.0), 2, "trapmf", (-1.0, -0.5, 2.0, 3.0)),
               FuzzySystem.from_dict(ZOO)]
    for k, fs in enumerate(systems):
        d = tmp_path / str(k)
        d.mkdir()
        code = export(fs, "c", d / "fis")
        p = c_identifier(code.basename)
        (d / "driver.c").write_text(DRIVER.format(base=code.basename, p=p, P=p.upper()))
        exe = d / "driver"
        cmd = [CC, *CFLAGS[:-1], *flags, "-o", str(exe), str(d / "driver.c"), str(d / "fis.c")]
        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if res.returncode and "sanitize" in " ".join(flags) and "cannot find" in res.stderr:
            pytest.skip("no sanitizer runtime")  # pragma: no cover - toolchain without libasan
        assert res.returncode == 0 and res.stderr == "", res.stderr
        X = random_inputs(fs, 300, np.random.default_rng(k))
        np.testing.assert_allclose(run(exe, X), evaluate(fs, X), rtol=0, atol=1e-9)


def _exact_centroid(fs: FuzzySystem, cuts: list[float]) -> float:
    """scikit-fuzzy's polyline for these cuts (its float crossing points and np.interp values),
    integrated in exact rational arithmetic."""
    from fractions import Fraction

    from hybridnav.fuzzy.engine import universe
    from hybridnav.fuzzy.mf import sample

    o = fs.output
    xs = universe(o)
    F = [sample(t.mf, t.params, xs) for t in o.terms]
    new = []
    for f, c in zip(F, cuts):
        above = f >= c
        i = np.flatnonzero(above[:-1] != above[1:])
        new.append(xs[i] + (c - f[i]) * (xs[i + 1] - xs[i]) / (f[i + 1] - f[i]))
    u = np.union1d(xs, np.concatenate(new))
    y = np.max([np.minimum(c, np.interp(u, xs, f)) for f, c in zip(F, cuts)], axis=0)
    X, Y = [Fraction(v) for v in u], [Fraction(v) for v in y]
    area = mom = Fraction(0)
    for x1, x2, y1, y2 in zip(X[:-1], X[1:], Y[:-1], Y[1:]):
        area += (x2 - x1) * (y1 + y2) / 2
        mom += (x2 - x1) * (x1 * (2 * y1 + y2) + x2 * (y1 + 2 * y2)) / 6
    return float(mom / area)


@pytest.mark.parametrize("n_terms", [2, pytest.param(4, marks=pytest.mark.long),
                                     pytest.param(5, marks=pytest.mark.long)])
def test_an_output_range_far_from_zero_keeps_its_digits(tmp_path, n_terms):
    """Moments about the range's midpoint: on [1e6, 1e6 + 1] with 5001 points the C result is
    within 1e-9 of the exact centroid (absolute moments were 6e-8 off with four or more terms)."""
    lo = 1e6
    terms = [{"name": "o0", "mf": "smf", "params": [lo + 0.4, lo + 0.9]},
             {"name": "o1", "mf": "trapmf", "params": [lo - 1, lo - 0.5, lo + 2, lo + 3]},
             {"name": "o2", "mf": "sigmf", "params": [lo + 0.5, 20.0]},
             {"name": "o3", "mf": "gaussmf", "params": [lo + 0.5, 0.1]},
             {"name": "o4", "mf": "trimf", "params": [lo + 0.1, lo + 0.3, lo + 0.6]}][:n_terms]
    levels = [0.1, 0.8, 0.3, 1.0, 0.45][:n_terms]
    fs = FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "fis",
        "inputs": [{"name": f"x{j}", "range": [0.0, 1.0], "points": 2,
                    "terms": [{"name": "up", "mf": "trimf", "params": [0.0, 1.0, 1.0]}]}
                   for j in range(n_terms)],
        "output": {"name": "oi", "range": [lo, lo + 1], "points": 5001, "terms": terms,
                   "defuzz": "centroid", "default": lo},
        "rules": [{"if": [f"x{j}", "up"], "then": f"o{j}", "weight": 1.0}
                  for j in range(n_terms)]})
    got = run(build(tmp_path, fs), np.array([levels]))[0]
    assert abs(got - _exact_centroid(fs, levels)) < 1e-9
