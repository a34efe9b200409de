"""One declaration and one message style for every setting (hybridnav.params)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from hybridnav import models, planners
from hybridnav.errors import HybridnavError
from hybridnav.deprecation import HybridnavDeprecationWarning
from hybridnav.params import Param, check_int, check_real, check_value, describe_params
from hybridnav.planners.swarm import OPTIMIZERS

#: "<where><key>: expected <what>, got <value>"
STYLE = re.compile(r"^(?P<where>[^:]+: )?(?P<key>[\w.\[\]]+): expected (?P<what>.+), got (?P<got>.+)$")


@pytest.mark.parametrize("param, text", [
    (Param(1.0, lo=0.0, lo_open=True), "a positive number"),
    (Param(1.0, lo=0.0), "a non-negative number"),
    (Param(1.0), "a finite number"),
    (Param(math.inf, allow_inf=True), "a number"),
    (Param(0.5, lo=0.0, hi=1.0), "a number in [0, 1]"),
    (Param(0.5, lo=0.0, hi=1.0, lo_open=True), "a number in (0, 1]"),
    (Param(0.5, lo=0.0, hi=1.0, hi_open=True), "a number in [0, 1)"),
    (Param(2.0, lo=1.0), "a number in [1, inf)"),
    (Param(2.0, lo=1.0, allow_inf=True), "a number in [1, inf]"),
    (Param(-2.0, hi=0.0), "a number in (-inf, 0]"),
    (Param(3, lo=1), "an integer >= 1"),
    (Param(3, lo=0, lo_open=True), "an integer >= 1"),
    (Param(3, lo=2, hi=10), "an integer in [2, 10]"),
    (Param(3, hi=10, hi_open=True), "an integer <= 9"),
    (Param(True), "true or false"),
    (Param("a", choices=("a", "b")), "one of a, b"),
    (Param("x"), "a string"),
])
def test_every_constraint_is_said_one_way(param, text):
    assert param.describe() == text


@pytest.mark.parametrize("param, value, message", [
    (Param(1.0, lo=0.0, lo_open=True), 0.0, "k: expected a positive number, got 0.0"),
    (Param(1.0, lo=0.0, lo_open=True), -1, "k: expected a positive number, got -1"),
    (Param(1.0), math.nan, "k: expected a finite number, got nan"),
    (Param(1.0), math.inf, "k: expected a finite number, got inf"),
    (Param(1.0), "1", "k: expected a number, got '1'"),
    (Param(1.0), True, "k: expected a number, got True"),
    (Param(1.0), None, "k: expected a number, got None"),
    (Param(3, lo=1), 0, "k: expected an integer >= 1, got 0"),
    (Param(3, lo=1), 2.5, "k: expected an integer, got 2.5"),
    (Param(3, lo=1), False, "k: expected an integer, got False"),
    (Param(3, lo=1), math.inf, "k: expected an integer, got inf"),
    (Param(True), 1, "k: expected true or false, got 1"),
    (Param("a", choices=("a", "b")), "c", "k: expected one of a, b, got 'c'"),
    (Param(0.5, lo=0.0, hi=1.0, hi_open=True), 1.0, "k: expected a number in [0, 1), got 1.0"),
])
def test_bad_values_get_the_one_message(param, value, message):
    with pytest.raises(HybridnavError) as err:
        param.check("k", value)
    assert str(err.value) == message
    with pytest.raises(HybridnavError) as err:
        param.check("k", value, "job.toml: ")
    assert str(err.value) == "job.toml: " + message


def test_good_values_are_converted_and_bounds_are_inclusive_unless_open():
    assert Param(1.0).check("k", 2) == 2.0 and isinstance(Param(1.0).check("k", 2), float)
    assert Param(1.0).check("k", np.float32(0.5)) == 0.5
    assert Param(3).check("k", 4.0) == 4 and isinstance(Param(3).check("k", 4.0), int)
    assert Param(3).check("k", np.int64(7)) == 7
    assert Param(0.5, lo=0.0, hi=1.0).check("k", 0.0) == 0.0
    assert Param(0.5, lo=0.0, hi=1.0).check("k", 1.0) == 1.0
    assert Param(math.inf, lo=0.0, lo_open=True, allow_inf=True).check("k", math.inf) == math.inf


def test_strings_are_parsed_only_when_asked():
    assert Param(1.0).check("k", " 2.5 ", parse=True) == 2.5
    assert Param(3).check("k", "4", parse=True) == 4
    assert Param(True).check("k", "off", parse=True) is False
    with pytest.raises(HybridnavError, match=r"^k: expected an integer, got 'x'$"):
        Param(3).check("k", "x", parse=True)
    with pytest.raises(HybridnavError, match=r"^k: expected true or false, got 'maybe'$"):
        Param(True).check("k", "maybe", parse=True)
    with pytest.raises(HybridnavError, match=r"^k: expected a positive number, got -1.0$"):
        Param(1.0, lo=0.0, lo_open=True).check("k", "-1", parse=True)   # the parsed value


def test_the_function_forms_are_the_same_checker():
    assert check_int("n", 3) == 3
    assert check_real("a", 2, 0.0, lo_open=True) == 2.0
    assert check_value("f: ", "ga.population", 10, int, 2, 100) == 10
    for call, param in [(lambda: check_int("n", 0), Param(1, lo=1)),
                        (lambda: check_real("n", 0.0, 0.0, lo_open=True),
                         Param(1.0, lo=0.0, lo_open=True)),
                        (lambda: check_value("", "n", 0, int, 2, 100), Param(5, lo=2, hi=100))]:
        with pytest.raises(HybridnavError) as a:
            call()
        with pytest.raises(HybridnavError) as b:
            param.check("n", 0 if param.kind is int else 0.0)
        assert str(a.value) == str(b.value)


def _bad_number(p: Param):
    """A value outside ``p``'s constraint (None when every number is allowed)."""
    if p.kind is bool:
        return "maybe"
    if p.choices is not None:
        return "no such choice"
    if p.kind in (int, float):
        if p.lo is not None:
            return p.lo - 1
        if p.hi is not None:
            return p.hi + 1
        return "not a number"
    return None


def _cases():
    for name, cls in models.MODELS.items():
        for key, p in cls.parameters.items():
            bad = _bad_number(p)
            if bad is not None:
                yield pytest.param(lambda n=name, k=key, b=bad: models.get(n, **{k: b}),
                                   f"model {name}: ", key, id=f"model-{name}-{key}")
    for name, cls in planners.PLANNERS.items():
        for key, p in cls.parameters.items():
            bad = _bad_number(p)
            if bad is not None:
                yield pytest.param(lambda n=name, k=key, b=bad: planners.get(n, **{k: b}),
                                   f"planner {name}: ", key, id=f"planner-{name}-{key}")
    for name, fn in OPTIMIZERS.items():
        yield pytest.param(lambda f=fn: f(lambda X: X.sum(1), ([0, 0], [1, 1]), iterations=0),
                           "", "iterations", id=f"optimizer-{name}")


@pytest.mark.parametrize("call, where, key", list(_cases()))
def test_models_planners_and_optimizers_speak_the_same_style(call, where, key):
    with pytest.raises(HybridnavError) as err:
        call()
    m = STYLE.match(str(err.value))
    assert m is not None, str(err.value)
    assert (m["where"] or "") == where and m["key"] == key


def test_job_and_scenario_files_speak_the_same_style(tmp_path):
    from hybridnav.tuner import load_job
    from hybridnav.world import load_scenario

    job = tmp_path / "job.toml"
    job.write_text("[ga]\npopulation = 1\n")
    with pytest.raises(HybridnavError) as err:
        load_job(job)
    assert str(err.value) == f"{job}: ga.population: expected an integer in [2, 100000], got 1"
    scen = tmp_path / "s.toml"
    scen.write_text('name = "s"\nworkspace = [0, 10, 0, 10]\ndt = -0.1\nmax_time = 10.0\n'
                    '[[robots]]\nname = "r"\nmodel = "point_mass"\nstart = [1, 1]\n'
                    'goal = [9, 9]\n')
    with pytest.raises(HybridnavError) as err:
        load_scenario(scen)
    m = STYLE.match(str(err.value))
    assert m is not None and m["where"] == f"{scen}: " and m["key"] == "dt", str(err.value)


def test_listings_show_default_doc_and_constraint():
    lines = describe_params({"k_rho": Param(0.5, "speed gain", lo=0.0, lo_open=True),
                             "law": Param("filter", "xi law", choices=("filter", "paper"))})
    assert lines == ["  k_rho = 0.5    speed gain (a positive number)",
                     "  law = 'filter'    xi law (one of filter, paper)"]


def test_a_model_declares_its_settings_once():
    cls = models.MODELS["unicycle"]
    assert set(cls.parameters) == set(cls.defaults) | set(cls.option_defaults)
    assert cls.option_choices == {"controller": ("go_to_point", "heading")}
    assert cls.infinite_ok == frozenset({"wheel_max", "v_max", "omega_max"})
    m = models.get("unicycle", k_rho=0.7)
    assert m.values["k_rho"] == 0.7
    with pytest.warns(HybridnavDeprecationWarning, match=r"Unicycle\.params .* 0\.4\.0"):
        assert m.params is m.values                             # the old name, until 0.4.0
    assert list(m.param_names) == list(cls.defaults)


def test_a_model_written_with_the_old_five_dicts_still_works():
    import casadi as cs

    from hybridnav.models.base import Model

    class Old(Model):
        name = "old_style"
        plant_state_names = ("x", "y")
        input_names = ("vx", "vy")
        defaults = {"gain": 0.5}
        param_docs = {"gain": "a gain"}
        option_defaults = {"law": "a"}
        option_choices = {"law": ("a", "b")}

        def open_loop(self, x, u, p):
            return cs.vertcat(u[0], u[1])

        def controller(self, x, target, p):
            g = self.p_dict(p)["gain"]
            return cs.vertcat(g * (target[0] - x[0]), g * (target[1] - x[1]))

    assert Old.parameters["gain"] == Param(0.5, "a gain")
    with pytest.raises(HybridnavError, match=r"^model old_style: law: expected one of a, b, "
                                             r"got 'c'$"):
        Old(law="c")
    assert Old(gain=2).values == {"gain": 2.0}


def test_a_planner_written_with_the_old_name_still_works():
    from hybridnav.planners.base import Planner

    with pytest.warns(HybridnavDeprecationWarning, match=r"Old\.params .* Old\.parameters"):
        class Old(Planner):
            name = "old"
            params = {"k": Param(1.0, "a gain", lo=0.0, lo_open=True)}

            def run(self, scenario, seed=None):
                raise NotImplementedError

    with pytest.warns(HybridnavDeprecationWarning):
        assert Old.parameters is Old.params
    assert Old(k="2").values == {"k": 2.0}
    with pytest.raises(HybridnavError, match=r"^planner old: k: expected a positive number"):
        Old(k=0)


def test_the_job_schema_is_the_readme_job_file_and_its_defaults():
    import tomllib
    from pathlib import Path

    from hybridnav.tuner.job import DEFAULT_JOB, SCHEMA

    text = (Path(__file__).parent.parent / "README.md").read_text(encoding="utf-8")
    start = text.index("A complete job file")
    begin = text.index("```toml\n", start) + 8
    block = text[begin:text.index("\n```", begin)]
    readme = tomllib.loads(block)
    readme["free"].setdefault("bounds", {})          # only a commented example there
    assert readme == DEFAULT_JOB
    # [settings] and [optimizer] replace [free] and [ga] when given: their keys are documented
    # in the README's own blocks
    for section in ("settings", "optimizer"):
        for key in SCHEMA[section]:
            assert f"{key} " in text[text.index("## Tuning any fuzzy system"):], key
    for section, keys in SCHEMA.items():
        for key, p in keys.items():
            assert p.doc, f"{section}.{key}"
            if key != "heldout" and section in DEFAULT_JOB:
                assert p.check(f"{section}.{key}", DEFAULT_JOB[section][key]) == \
                    DEFAULT_JOB[section][key]


# ---- found in review ---------------------------------------------------------------------------

def test_command_line_integers_may_be_written_as_numbers():
    assert Param(3, lo=1).check("n", "1e3", parse=True) == 1000
    assert Param(3, lo=1).check("n", "3.0", parse=True) == 3
    with pytest.raises(HybridnavError, match=r"^n: expected an integer, got '2.5'$"):
        Param(3, lo=1).check("n", "2.5", parse=True)
    with pytest.raises(HybridnavError, match=r"^n: expected an integer, got 'inf'$"):
        Param(3, lo=1).check("n", "inf", parse=True)


def test_numpy_bools_huge_ints_and_exact_bounds():
    assert Param(True).check("k", np.True_) is True
    with pytest.raises(HybridnavError, match=r"^x: expected a finite number, got 1000"):
        check_real("x", 10**400)
    assert Param(3, lo=0, hi=math.inf).describe() == "an integer >= 0"
    p = Param(0.1, hi=0.1234567)
    assert p.describe() == "a number in (-inf, 0.1234567]"
    with pytest.raises(HybridnavError, match=r"\(-inf, 0\.1234567\], got 0\.1234569$"):
        p.check("k", 0.1234569)
    assert Param(1.0, hi=5.0, allow_inf=True).describe() == "a number in [-inf, 5]"


def test_bounds_and_choices_are_keyword_only():
    with pytest.raises(TypeError):
        Param("a", "doc", None, None, ("a", "b"))           # the old positional order


def test_a_model_that_overrides_some_old_dicts_keeps_its_parents_bounds():
    from hybridnav.models import PointMass, Unicycle

    class Heading(Unicycle):
        name = "heading_unicycle"
        option_defaults = {"controller": "heading"}

    with pytest.raises(HybridnavError, match=r"^model heading_unicycle: k_rho: expected a positive"):
        Heading(k_rho=-5.0)
    assert Heading().options == {"controller": "heading"}

    class Faster(Unicycle):
        name = "faster"
        defaults = {**Unicycle.defaults, "speed": 0.2}

    assert Faster().values["speed"] == 0.2
    with pytest.raises(HybridnavError, match=r"L: expected a positive number"):
        Faster(L=0.0)

    class IntGain(PointMass):                # an integer default is still a numeric parameter
        name = "int_gain"
        parameters = {**PointMass.parameters, "alpha1": Param(1, "gain")}

    m = IntGain()
    assert m.values["alpha1"] == 1.0 and list(m.p_value()) == [1.0, 0.1]


def test_model_copies_and_the_old_name():
    from hybridnav.models import LbCS, Unicycle

    u = Unicycle()
    v = u.with_params(dt=0.05, k_rho=0.3, radius=0.2)
    assert (v.dt, v.values["k_rho"], v.radius) == (0.05, 0.3, 0.2)
    with pytest.warns(HybridnavDeprecationWarning, match=r"Unicycle\.params .* Unicycle\.values"):
        u.params = {**u.values, "k_rho": 0.4}                   # the old name can be assigned
    assert u.values["k_rho"] == 0.4
    lb = LbCS(obstacles=[(1.0, 1.0, 1.0)]).with_params(rp=0.7)
    assert lb.values["rp"] == 0.7 and lb.radius == 0.7
    for kwargs, message in [(dict(obstacles=5), "obstacles: expected a sequence"),
                            (dict(obstacles=None), "obstacles: expected a sequence"),
                            (dict(radius=0.3, rp=0.5), "radius: the same as rp")]:
        with pytest.raises(HybridnavError, match=message):
            LbCS(**kwargs)
