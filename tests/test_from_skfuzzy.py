"""from_skfuzzy: a scikit-fuzzy ControlSystem brought in evaluates as scikit-fuzzy computes it;
what hybridnav cannot represent is refused, naming it."""

from __future__ import annotations

import numpy as np
import pytest
import skfuzzy as fuzz
from hypothesis import given, settings
from hypothesis import strategies as st
from skfuzzy import control as ctrl

from hybridnav import fuzzy
from hybridnav.errors import HybridnavError
from hybridnav.fuzzy import FuzzySystem, from_skfuzzy


def _compute(cs, inputs):
    sim = ctrl.ControlSystemSimulation(cs)
    out = []
    for row in inputs:
        for k, v in row.items():
            sim.input[k] = v
        sim.compute()
        out.append(next(iter(sim.output.values())))
    return np.array(out)


def tipping():
    """scikit-fuzzy's tipping example, with every shape hybridnav has."""
    quality = ctrl.Antecedent(np.arange(0, 11, 1), "quality")
    service = ctrl.Antecedent(np.linspace(0, 10, 41), "service")
    tip = ctrl.Consequent(np.arange(0, 26, 1), "tip")
    quality["poor"] = fuzz.trimf(quality.universe, [0, 0, 5])
    quality["average"] = fuzz.trimf(quality.universe, [0, 5, 10])
    quality["good"] = fuzz.trapmf(quality.universe, [5, 8, 10, 10])
    service["poor"] = fuzz.zmf(service.universe, 1, 6)
    service["average"] = fuzz.gaussmf(service.universe, 5, 1.5)
    service["good"] = fuzz.smf(service.universe, 4, 9)
    service["odd"] = fuzz.gbellmf(service.universe, 2, 3, 5)
    tip["low"] = fuzz.trimf(tip.universe, [0, 0, 13])
    tip["medium"] = fuzz.trimf(tip.universe, [0, 13, 25])
    tip["high"] = fuzz.sigmf(tip.universe, 18, 0.8)
    rules = [ctrl.Rule(quality["poor"] | service["poor"], tip["low"]),
             ctrl.Rule(service["average"] & ~quality["good"], tip["medium"] % 0.7),
             ctrl.Rule(service["good"] | quality["good"] | service["odd"], tip["high"])]
    return ctrl.ControlSystem(rules)


def test_tipping_evaluates_as_scikit_fuzzy():
    cs = tipping()
    fis = from_skfuzzy(cs, name="tipping")
    assert isinstance(fis, FuzzySystem) and fis.name == "tipping"
    shapes = {t.mf for v in (*fis.inputs, fis.output) for t in v.terms}
    assert shapes == {"trimf", "trapmf", "zmf", "gaussmf", "smf", "gbellmf", "sigmf"}
    rng = np.random.default_rng(0)
    rows = [{"quality": q, "service": s} for q, s in rng.uniform(0, 10, (200, 2))]
    want = _compute(cs, rows)
    got = fis.evaluate(quality=np.array([r["quality"] for r in rows]),
                       service=np.array([r["service"] for r in rows]))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert FuzzySystem.from_skfuzzy(cs).to_dict()["rules"] == fis.to_dict()["rules"]


@settings(max_examples=60, deadline=None)
@given(a=st.floats(-2, 4).map(lambda v: round(v, 3)), w1=st.floats(0.3, 5).map(lambda v: round(v, 3)),
       w2=st.floats(0.3, 5).map(lambda v: round(v, 3)), n=st.integers(5, 60),
       seed=st.integers(0, 2**31 - 1))
def test_triangles_and_trapezoids_anywhere(a, w1, w2, n, seed):
    """Corners (given to 3 decimals, as people write them) between samples, beyond the universe,
    shoulders: recovered so that hybridnav samples the same values, zeros and ones exactly, and
    computes the same output. (A corner 1e-139 off a sample leaves a membership of 1e-139 there,
    which decides whether a rule fires: such a term is refused, see the next test.)"""
    x = np.linspace(0, 5, n)
    inp = ctrl.Antecedent(x, "x")
    inp["t"] = fuzz.trimf(x, [a, a + w1, a + w1 + w2])
    inp["z"] = fuzz.trapmf(x, [a - 1, a, a + w1, a + w1 + w2])
    if not inp["t"].mf.any() or not inp["z"].mf.any():
        return
    out = ctrl.Consequent(np.linspace(0, 1, 21), "y")
    out["lo"] = fuzz.trimf(out.universe, [0, 0, 0.6])
    out["hi"] = fuzz.trapmf(out.universe, [0.3, 0.7, 1, 1])
    cs = ctrl.ControlSystem([ctrl.Rule(inp["t"], out["hi"]), ctrl.Rule(inp["z"], out["lo"])])
    fis = from_skfuzzy(cs)
    for v in fis.inputs + (fis.output,):
        sk = {"x": inp, "y": out}[v.name]
        for t in v.terms:
            np.testing.assert_allclose(fuzzy.mf.sample(t.mf, t.params, sk.universe),
                                       sk[t.name].mf, rtol=0, atol=1e-9)
    xs = np.random.default_rng(seed).uniform(0, 5, 20)
    got = fis.evaluate(x=xs)
    for xi, g in zip(xs, got):
        sim = ctrl.ControlSystemSimulation(cs)
        sim.input["x"] = xi
        try:
            sim.compute()
            want = sim.output.get("y")
        except (ValueError, AssertionError):
            want = None
        if want is None:                           # nothing fired: hybridnav gives its default
            assert g == fis.output.default
        else:
            assert g == pytest.approx(want, abs=1e-9)


def test_what_cannot_be_represented_is_named():
    x = np.linspace(0, 1, 11)
    a = ctrl.Antecedent(x, "a")
    a["wiggle"] = np.abs(np.sin(7 * x))
    o = ctrl.Consequent(x, "o")
    o["x"] = fuzz.trimf(x, [0, 0.5, 1])
    with pytest.raises(HybridnavError, match=r"^from_skfuzzy: a\.wiggle: expected a membership "
                                             r"function hybridnav represents"):
        from_skfuzzy(ctrl.ControlSystem([ctrl.Rule(a["wiggle"], o["x"])]))
    u = ctrl.Antecedent(np.array([0.0, 0.1, 0.5, 1.0]), "u")
    u["t"] = fuzz.trimf(u.universe, [0, 0.5, 1])
    with pytest.raises(HybridnavError, match=r"^from_skfuzzy: u: expected an evenly spaced"):
        from_skfuzzy(ctrl.ControlSystem([ctrl.Rule(u["t"], o["x"])]))
    o2 = ctrl.Consequent(x, "o2", defuzzify_method="mom")
    o2["x"] = fuzz.trimf(x, [0, 0.5, 1])
    a["t"] = fuzz.trimf(x, [0, 0.5, 1])
    with pytest.raises(HybridnavError, match=r"^from_skfuzzy: o2: expected centroid"):
        from_skfuzzy(ctrl.ControlSystem([ctrl.Rule(a["t"], o2["x"])]))
    with pytest.raises(HybridnavError, match=r"^from_skfuzzy: expected one consequent"):
        from_skfuzzy(ctrl.ControlSystem([ctrl.Rule(a["t"], o["x"]), ctrl.Rule(a["t"], o2["x"])]))
    with pytest.raises(HybridnavError, match=r"^from_skfuzzy: expected a skfuzzy\.control"):
        from_skfuzzy("tipping")


def test_round_trip_of_the_built_in_systems():
    """to_skfuzzy then from_skfuzzy gives back each built-in system's evaluation."""
    rng = np.random.default_rng(1)
    for name in fuzzy.builtin_names():
        fis = fuzzy.builtin(name)
        back = from_skfuzzy(fis.to_skfuzzy(), default=fis.output.default)
        X = {v.name: rng.uniform(*v.range, 300) for v in fis.inputs}
        np.testing.assert_allclose(back.evaluate(**X), fis.evaluate(**X), rtol=0, atol=1e-9,
                                   err_msg=name)


def test_the_command_line_reads_a_control_system_in_python(tmp_path, capsys):
    from hybridnav.cli import main

    src = tmp_path / "mysystem.py"
    src.write_text("import sys\nsys.path.insert(0, %r)\n" % str(__import__("pathlib").Path(
        __file__).parent) + "from test_from_skfuzzy import tipping\nCS = tipping()\n")
    assert main(["fis", f"{src}:CS"]) == 0
    assert "CS: 2 inputs, 3 rules, output tip" in capsys.readouterr().out
    assert main(["fis", f"{src}:NOPE"]) == 2
    assert "has no 'NOPE'" in capsys.readouterr().err


def test_terms_are_checked_on_the_points_hybridnav_samples():
    """np.arange(-10, 30, 0.7) is up to 7e-15 off np.linspace, where hybridnav samples: a spike
    on one sample, recovered on arange's points, left 5e-15 on the previous linspace point, so
    a rule fired between them where scikit-fuzzy's fires nothing."""
    x = np.arange(-10, 30, 0.7)
    even = np.linspace(x[0], x[-1], len(x))
    assert np.any(x != even)
    a = ctrl.Antecedent(x, "a")
    spike = np.zeros(len(x))
    spike[44] = 1.0
    a["t"] = spike
    o = ctrl.Consequent(np.linspace(-5, 5, 21), "o")
    o["c"] = fuzz.trimf(o.universe, [-5, -5, 5])
    cs = ctrl.ControlSystem([ctrl.Rule(a["t"], o["c"])])
    fis = from_skfuzzy(cs, default=4.5)
    t = fis.inputs[0].terms[0]
    sampled = fuzzy.mf.sample(t.mf, t.params, even)
    assert np.array_equal(sampled == 0, spike == 0)
    xs = 0.5 * (x[1:] + x[:-1])            # (on arange's points hybridnav interpolates
    #                                          between linspace's, an ulp away: not compared)
    for v, g in zip(xs, fis.evaluate(a=xs)):
        sim = ctrl.ControlSystemSimulation(cs)
        sim.input["a"] = v
        try:
            sim.compute()
            want = sim.output.get("o", 4.5)
        except (ValueError, AssertionError):     # nothing fired: hybridnav gives its default
            want = 4.5
        assert g == pytest.approx(want, abs=1e-9), v


def test_python_files_run_as_imported_and_their_exits_are_errors(tmp_path, capsys):
    """A file with a dataclass under ``from __future__ import annotations`` (dataclasses look
    the module up in sys.modules) loads; sys.exit() in the file, a directory named x.py and a
    missing upper-case .JSON file are errors that say so (exit 2), not an exit with the file's
    code or an import error about a module '/tmp/a'."""
    from hybridnav.cli import main
    from hybridnav.fuzzy import load_any

    src = tmp_path / "withdc.py"
    src.write_text("from __future__ import annotations\nimport dataclasses\n"
                   "import numpy as np\nfrom skfuzzy import control as ctrl\n"
                   "@dataclasses.dataclass\nclass P:\n    lo: float = 0.0\n"
                   "a = ctrl.Antecedent(np.linspace(0, 1, 11), 'a')\na.automf(3)\n"
                   "o = ctrl.Consequent(np.linspace(0, 1, 11), 'o')\no.automf(3)\n"
                   "CS = ctrl.ControlSystem([ctrl.Rule(a['poor'], o['good'])])\nNONE = None\n")
    assert load_any(f"{src}:CS").name == "CS"
    with pytest.raises(HybridnavError, match=r":NONE: expected a hybridnav FuzzySystem or a "
                                             r"skfuzzy\.control\.ControlSystem, got NoneType$"):
        load_any(f"{src}:NONE")
    # a system built with hybridnav's own API is taken as it is
    (tmp_path / "own.py").write_text("from hybridnav.fuzzy import builtin\nSYS = builtin('effc-5rule')\n")
    from hybridnav.fuzzy import builtin

    assert load_any(f"{tmp_path / 'own.py'}:SYS").to_json() == builtin("effc-5rule").to_json()
    # a subclass is taken as its data (what the exports describe), a class is not a system
    (tmp_path / "sub.py").write_text(
        "from hybridnav.fuzzy import FuzzySystem, builtin\n"
        "class Mine(FuzzySystem):\n    def evaluate(self, **kw):\n        raise RuntimeError('own')\n"
        "base = builtin('effc-5rule')\n"
        "SUB = Mine(base.name, base.inputs, base.output, base.rules, base.description)\n"
        "CLS = FuzzySystem\n")
    sub = load_any(f"{tmp_path / 'sub.py'}:SUB")
    assert type(sub) is FuzzySystem and sub.to_json() == builtin("effc-5rule").to_json()
    with pytest.raises(HybridnavError, match=r":CLS: got the class FuzzySystem; expected an "
                                             r"instance"):
        load_any(f"{tmp_path / 'sub.py'}:CLS")
    (tmp_path / "exits.py").write_text("import sys\nsys.exit(3)\n")
    assert main(["fis", f"{tmp_path / 'exits.py'}:CS"]) == 2
    assert "cannot import" in capsys.readouterr().err
    (tmp_path / "dir.py").mkdir()
    with pytest.raises(HybridnavError, match="dir.py: not a file"):
        load_any(f"{tmp_path / 'dir.py'}:CS")
    with pytest.raises(HybridnavError, match="cannot read fuzzy system file"):
        load_any(f"{tmp_path}/a:b/sys.JSON")
