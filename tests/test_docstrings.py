"""Package-wide documentation checks, python-control style: every public function documents the
parameters it has (and no others) in numpydoc style, and the functions exported at package level
document theirs at all; every function that takes ``**kwargs`` refuses a keyword it does not
know, with the key in the message."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import shutil
import tempfile
import warnings
from pathlib import Path

import casadi as cs
import numpy as np
import pytest
from numpydoc.docscrape import NumpyDocString

import hybridnav
import hybridnav.planners
from hybridnav import HybridnavError

MODULES = sorted(m.name for m in pkgutil.walk_packages(hybridnav.__path__, "hybridnav."))
#: the packages users import from (their ``__all__`` is the API of the README)
API = ("hybridnav", "hybridnav.analysis", "hybridnav.tuner", "hybridnav.planners",
       "hybridnav.models", "hybridnav.world", "hybridnav.fuzzy", "hybridnav.results",
       "hybridnav.params", "hybridnav.planners.swarm", "hybridnav.plotting", "hybridnav.backends",
       "hybridnav.experiments.compare", "hybridnav.deprecation")


def _public():
    """(qualified name, function, drop first argument) of every public function and method."""
    seen = set()
    for name in MODULES:
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", ()):
            obj = getattr(module, attr, None)
            if getattr(obj, "__module__", None) != name or id(obj) in seen:
                continue
            seen.add(id(obj))
            if inspect.isfunction(obj):
                yield f"{name}.{attr}", obj, False
            elif inspect.isclass(obj):
                if "__init__" in obj.__dict__:
                    yield f"{name}.{attr}", obj, True          # documented on the class
                for key, member in obj.__dict__.items():
                    if key.startswith("_"):
                        continue
                    fn = member.__func__ if isinstance(member, (staticmethod, classmethod)) \
                        else member
                    if inspect.isfunction(fn):
                        yield (f"{name}.{attr}.{key}", fn,
                               not isinstance(member, staticmethod))


def _documented(doc: str) -> set[str]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parsed = NumpyDocString(doc)
    names = set()
    for p in parsed["Parameters"] + parsed["Other Parameters"]:
        names |= {n.strip().lstrip("*") for n in p.name.split(",") if n.strip()}
    return names


def _signature(obj, drop_first: bool) -> list[inspect.Parameter]:
    fn = obj.__init__ if inspect.isclass(obj) else obj
    params = list(inspect.signature(fn).parameters.values())
    return [p for p in params[1 if drop_first else 0:] if not p.name.startswith("_")]


PUBLIC = list(_public())


def test_the_scan_finds_the_api():
    names = {q for q, _, _ in PUBLIC}
    assert {"hybridnav.analysis.roa.estimate_roa", "hybridnav.params.Param",
            "hybridnav.planners.base.Planner.run"} <= names
    assert len(PUBLIC) > 300


@pytest.mark.parametrize("qualname, obj, drop", PUBLIC, ids=[q for q, _, _ in PUBLIC])
def test_a_parameters_section_is_complete_and_current(qualname, obj, drop):
    documented = _documented(inspect.getdoc(obj) or "")
    if not documented:
        return                                   # prose-only docstrings: see the next test
    params = _signature(obj, drop)
    names = {p.name for p in params}
    assert not names - documented, f"{qualname}: undocumented {sorted(names - documented)}"
    if not any(p.kind is p.VAR_KEYWORD for p in params):    # **kwargs may list their keys
        assert not documented - names, f"{qualname}: documents absent {sorted(documented - names)}"


def _api_functions():
    for name in API:
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", ()):
            obj = getattr(module, attr)
            if inspect.isfunction(obj):
                yield f"{name}.{attr}", obj


@pytest.mark.parametrize("qualname, fn", list(_api_functions()),
                         ids=[q for q, _ in _api_functions()])
def test_package_level_functions_document_their_parameters(qualname, fn):
    params = [p for p in _signature(fn, False)
              if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    if len(params) >= 2:
        assert _documented(inspect.getdoc(fn) or ""), f"{qualname}: no Parameters section"


# ---- keyword arguments -----------------------------------------------------------------------

def _quad(X):
    return np.sum(np.asarray(X) ** 2, axis=1)


_CC = shutil.which("gcc") or shutil.which("cc")


def _compiled():
    """The C export of effc-2rule, compiled (for the calls below)."""
    from hybridnav import fuzzy
    from hybridnav.fuzzy.export import export
    from hybridnav.fuzzy.export.sil import CompiledFIS

    with tempfile.TemporaryDirectory(prefix="hybridnav-doc-") as folder:  # loaded, then gone
        export(fuzzy.builtin("effc-2rule"), "c", Path(folder) / "effc")
        return CompiledFIS(Path(folder) / "effc.c")


def _kwargs_calls():
    """How to call each public function that takes ``**kwargs`` with one unknown keyword."""
    from hybridnav import fuzzy, models, planners
    from hybridnav.fuzzy.export import export, export_to_file
    from hybridnav.models.lbcs import LbCS
    from hybridnav.planners import swarm
    from hybridnav.world import load_scenario

    box = ([0.0, 0.0], [1.0, 1.0])
    calls = {
        "hybridnav.models.get": lambda: models.get("point_mass", bogus=1.0),
        "hybridnav.models.base.Model.with_params":
            lambda: models.get("unicycle").with_params(bogus=1.0),
        "hybridnav.models.lbcs.LbCS.with_params":
            lambda: LbCS(obstacles=[(1.0, 1.0, 1.0)]).with_params(bogus=1.0),
        "hybridnav.models.lbcs.LbCS.from_scenario":
            lambda: LbCS.from_scenario(load_scenario("aco-local-minimum"), bogus=1.0),
        "hybridnav.world.scenario.Scenario.model":
            lambda: load_scenario("fastep-s1").model("R1", bogus=1.0),
        "hybridnav.planners.get": lambda: planners.get("apf", bogus=1.0),
        "hybridnav.planners.swarm.minimize": lambda: swarm.minimize("pso", _quad, box,
                                                                    iterations=2, bogus=1.0),
        "hybridnav.fuzzy.system.FuzzySystem.evaluate":
            lambda: fuzzy.builtin("effc-5rule").evaluate(dtheta=0.1, alpha=0.5, bogus=1.0),
        "hybridnav.fuzzy.export.export":
            lambda: export(fuzzy.builtin("effc-5rule"), "fll", bogus=True),
        "hybridnav.fuzzy.export.export_to_file":
            lambda: export_to_file(fuzzy.builtin("effc-5rule"), "fll", None, bogus=True),
    }
    if _CC:
        calls["hybridnav.fuzzy.export.sil.CompiledFIS.evaluate"] = \
            lambda: _compiled().evaluate(dtheta=0.1, alpha=0.5, bogus=1.0)
        from hybridnav.fuzzy.export.closedloop import verify

        calls["hybridnav.fuzzy.export.closedloop.verify"] = lambda: verify(
            fuzzy.builtin("effc-2rule"), _compiled(), [load_scenario("effc-env-a")], bogus=1.0)
    for name, cls in models.MODELS.items():
        calls[f"{cls.__module__}.{cls.__name__}"] = lambda cls=cls: cls(bogus=1.0)
    for name, cls in planners.PLANNERS.items():
        calls[f"{cls.__module__}.{cls.__name__}"] = lambda cls=cls: cls(bogus=1.0)
    from hybridnav.tuner.optimizers import OPTIMIZERS

    for name, cls in OPTIMIZERS.items():
        calls[f"{cls.__module__}.{cls.__name__}"] = lambda cls=cls: cls(bogus=1.0)
    from hybridnav.analysis import as_system
    from hybridnav.tuner import DataCost, learn

    x = cs.SX.sym("x")
    calls["hybridnav.analysis.system.System.with_params"] = lambda: as_system(
        (x, -x)).with_params(bogus=1.0)
    calls["hybridnav.fuzzy.system.FuzzySystem.to_casadi"] = lambda: fuzzy.builtin(
        "effc-5rule").to_casadi(dtheta=0.1, alpha=0.5, bogus=1.0)
    calls["hybridnav.tuner.core.learn"] = lambda: learn(
        fuzzy.builtin("effc-2rule"), DataCost([[0.1, 0.5]], [0.5]), max_rules=2, bogus=1.0)
    from hybridnav.tuner import NavigationCost
    from hybridnav.tuner.falsify import falsify_systems

    calls["hybridnav.tuner.falsify.falsify_systems"] = lambda: falsify_systems(
        NavigationCost([load_scenario("effc-train-1")]), {"apf": "apf"}, budget=30, bogus=1.0)
    return calls


#: functions whose ``**kwargs`` are not checked here, and why
EXEMPT = {
    "hybridnav.fuzzy.plots.save_surface_png": "matplotlib's plot_surface keywords",
    "hybridnav.planners.field.base.FieldPlanner.trace": "signal names are free",
    "hybridnav.progress.PlainProgress.set_postfix": "tqdm's interface: any names, shown as given",
    "hybridnav.models.base.Model": "abstract; every registered model is called above",
    "hybridnav.planners.base.Planner": "abstract; every registered planner is called above",
    "hybridnav.planners.field.base.FieldPlanner": "abstract; every registered planner is "
                                                  "called above",
    "hybridnav.tuner.optimizers.base.Optimizer": "abstract; every registered optimizer is "
                                                 "called above",
}
if not _CC:
    EXEMPT.update(dict.fromkeys(("hybridnav.fuzzy.export.sil.CompiledFIS.evaluate",
                                 "hybridnav.fuzzy.export.closedloop.verify"), "needs a C compiler"))


def _kwargs_functions():
    for qualname, obj, drop in PUBLIC:
        fn = obj.__init__ if inspect.isclass(obj) else obj
        try:
            params = inspect.signature(fn).parameters.values()
        except (TypeError, ValueError):
            continue
        if any(p.kind is p.VAR_KEYWORD for p in params):
            yield qualname


def test_every_function_taking_kwargs_is_checked_here():
    known = set(_kwargs_calls()) | set(EXEMPT)
    missing = sorted(set(_kwargs_functions()) - known)
    assert not missing, f"add a call for: {missing}"


@pytest.mark.parametrize("qualname", sorted(_kwargs_calls()))
def test_an_unknown_keyword_is_refused_by_name(qualname):
    # HybridnavError, or TypeError where a call's signature is wrong as Python reports it
    # (FuzzySystem.evaluate's inputs are its keywords)
    with pytest.raises((HybridnavError, TypeError), match="bogus"):
        _kwargs_calls()[qualname]()
