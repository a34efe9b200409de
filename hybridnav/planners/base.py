"""The planner interface: declared parameters, ``run(scenario, seed) -> Result``.

Every planner declares its parameters in :attr:`Planner.parameters` as :class:`hybridnav.params.Param`
entries (default, type, bounds, one-line doc), the same declaration models, optimizers and job files
use; ``hybridnav planners`` lists them and ``hybridnav run --set key=value`` sets them, with the
same validation as Python keyword arguments. An instance's values are :attr:`Planner.values`.

A planner that reproduces a paper declares :attr:`Planner.profiles`: named sets of parameter
values. ``hybridnav`` (the defaults, with this package's improvements) and ``paper`` (the paper's
settings and rules as far as its text gives them) are selected with ``profile=paper`` (``--set
profile=paper``); parameters given explicitly win over the profile's.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from hybridnav.deprecation import RenamedAttribute, warn_renamed
from hybridnav.errors import HybridnavError
from hybridnav.params import Param
from hybridnav.results import Result

__all__ = ["MAX_CANDIDATES", "Param", "Planner", "candidates_table", "parse_assignments",
           "searches_table"]

#: Most candidates :func:`candidates_table` keeps of one search (its best ones)
MAX_CANDIDATES = 64


def parse_assignments(items: Sequence[str]) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``, for ``--set`` options."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise HybridnavError(f"--set {item!r}: expected key=value")
        out[key.strip()] = value
    return out


class Planner(ABC):
    """A navigation method: ``Planner(**params).run(scenario, seed) -> Result``.

    Subclasses set :attr:`name`, :attr:`description`, :attr:`parameters` (the declarations; the
    instance's values are :attr:`values`) and implement :meth:`run`. ``params`` is the old name
    of ``parameters`` (it warns; removed in 0.4.0).
    ``drives`` says which robot models it can drive, by capability (a model qualifies when it has
    every capability of one of the sets; see :attr:`hybridnav.models.Model.capabilities`), and
    ``models`` lists the registered models that qualify (derived, never written by hand);
    ``moving_obstacles`` and ``moving_targets`` say whether it handles ``moving_circle``
    obstacles and ``goal_follow`` targets.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    parameters: ClassVar[dict[str, Param]] = {}
    #: old name of :attr:`parameters`; warns, removed in 0.4.0
    params = RenamedAttribute("parameters")
    drives: ClassVar[tuple[frozenset[str], ...]] = (frozenset({"robot"}),)
    models: ClassVar[tuple[str, ...]] = ()
    moving_obstacles: ClassVar[bool] = True
    moving_targets: ClassVar[bool] = True
    stochastic: ClassVar[bool] = False
    #: named parameter sets (``{"paper": {"distance": "euclidean", ...}}``); ``hybridnav``, the
    #: declared defaults, is always one of them; selected by the ``profile`` parameter
    profiles: ClassVar[dict[str, dict[str, Any]]] = {}
    #: what the ``paper`` profile does and where it still differs from the paper's text
    paper_notes: ClassVar[str] = ""
    #: what even the ``paper`` profile still does differently from the paper's text, one item
    #: each (listed by ``hybridnav planners`` and the reproduction reports)
    paper_deviations: ClassVar[tuple[str, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        declared = cls.__dict__.get("params")
        if isinstance(declared, dict):
            # settings declared under the old name: declare them under the new one, and warn
            if "parameters" in cls.__dict__:
                raise HybridnavError(f"planner {cls.__name__}: expected its settings under "
                                     "parameters only, got params (their old name) as well")
            warn_renamed(f"{cls.__name__}.params", f"{cls.__name__}.parameters")
            cls.parameters = declared
            delattr(cls, "params")
        if cls.profiles:
            _declare_profiles(cls)
        cls.models = _driven(cls.drives)

    def __init__(self, **params: Any) -> None:
        values = {k: p.default for k, p in self.parameters.items()}
        if "profile" in self.parameters:
            values["profile"] = self.parameters["profile"].check(
                "profile", params.get("profile", values["profile"]), f"planner {self.name}: ",
                parse=True)
            values.update(self.profiles[values["profile"]])
        for key, value in params.items():
            if key not in self.parameters:
                raise HybridnavError(
                    f"planner {self.name}: unknown parameter {key!r}; expected one of: "
                    + (", ".join(sorted(self.parameters)) or "(none)"))
            values[key] = self.parameters[key].check(key, value, f"planner {self.name}: ",
                                                     parse=True)
        self.values = values
        #: the parameters the user (or the chosen profile) set: the rest are defaults
        self.given = frozenset(params) | frozenset(
            self.profiles.get(values.get("profile", ""), {}))

    def check_scenario(self, scenario) -> None:
        """Raise :class:`HybridnavError` when the scenario needs what this planner lacks."""
        where = scenario.source or scenario.name
        for i, r in enumerate(scenario.robots):
            if r.model not in self.models:
                raise HybridnavError(
                    f"{where}: robots[{i}].model: planner {self.name} drives "
                    f"{', '.join(self.models)}, got {r.model!r}")
            if r.goal_follow is not None and not self.moving_targets:
                raise HybridnavError(
                    f"{where}: robots[{i}].goal_follow: planner {self.name} does not handle "
                    "moving targets")
        if scenario.world.moving().obstacles and not self.moving_obstacles:
            raise HybridnavError(
                f"{where}: obstacles: planner {self.name} does not handle moving obstacles")

    @abstractmethod
    def run(self, scenario, seed: int | None = None) -> Result:
        """Run the planner on a scenario; every robot ends with one of the five outcomes."""

    def diagnostics(self, scenario, result: Result) -> dict[str, Any]:
        """Planner-specific figures of the last run, ``{file name: Figure}`` (default none)."""
        return {}

    def describe(self) -> Mapping[str, Any]:
        """The parameter values of this instance (written into ``result.json``)."""
        return dict(self.values)


def accepts_inputs(cls: type[Planner], names) -> bool:
    """Whether a planner that takes a fuzzy system (``fuzzy_inputs``, and
    ``optional_fuzzy_inputs`` it also provides) can feed a system with inputs ``names``."""
    names = list(names)
    need = set(cls.fuzzy_inputs)
    may = need | set(getattr(cls, "optional_fuzzy_inputs", ()))
    return len(set(names)) == len(names) and need <= set(names) <= may


def inputs_text(cls: type[Planner]) -> str:
    """``dtheta, alpha (and optionally clearance)``: what :func:`accepts_inputs` accepts."""
    extra = getattr(cls, "optional_fuzzy_inputs", ())
    return ", ".join(cls.fuzzy_inputs) + (
        f" (and optionally {', '.join(extra)})" if extra else "")


def _declare_profiles(cls: type[Planner]) -> None:
    """Add the ``profile`` parameter to a planner with profiles, checking every profile's values
    against the declarations (a wrong profile is a programming error, found at import)."""
    profiles = {"hybridnav": {}, **cls.profiles}
    where = f"planner {cls.name}: profile "
    for name, values in profiles.items():
        for key, value in values.items():
            if key not in cls.parameters or key == "profile":
                raise TypeError(f"{where}{name!r}: unknown parameter {key!r}")
            cls.parameters[key].check(key, value, f"{where}{name!r}: ")
    cls.profiles = profiles
    doc = ("parameter set: 'hybridnav' (the defaults) or 'paper' (the paper's settings and rules, "
           "see 'hybridnav planners'); explicit parameters win")
    cls.parameters = {"profile": Param("hybridnav", doc, choices=tuple(profiles)),
                      **{k: v for k, v in cls.parameters.items() if k != "profile"}}


def _driven(drives) -> tuple[str, ...]:
    """The registered robot models with every capability of one of the sets in ``drives``."""
    from hybridnav.models import MODELS

    return tuple(name for name, cls in MODELS.items()
                 if "robot" in cls.capabilities and any(req <= cls.capabilities for req in drives))


Planner.models = _driven(Planner.drives)


def searches_table(searches: list[np.ndarray]) -> dict[str, np.ndarray]:
    """A robot's swarm searches as the ``swarm_best_<robot>`` extra every swarm planner records:
    the best cost per iteration of each search, stacked as ``plan`` (the search's index),
    ``iteration`` and ``best`` (infinite where the search knew no feasible point yet).

    Parameters
    ----------
    searches : list of ndarray
        One search's best cost per iteration each, in the order they ran.
    """
    if not searches:
        return {"plan": np.zeros(0, dtype=int), "iteration": np.zeros(0, dtype=int),
                "best": np.zeros(0)}
    return {"plan": np.concatenate([np.full(len(b), k) for k, b in enumerate(searches)]),
            "iteration": np.concatenate([np.arange(len(b)) for b in searches]),
            "best": np.concatenate(searches)}


def candidates_table(searches: list[tuple[float, np.ndarray, np.ndarray]]
                     ) -> dict[str, np.ndarray]:
    """A robot's swarm searches as the ``candidates_<robot>`` extra: where each search's final
    candidates were, for an animation to show around each planning step.

    Columns ``plan`` (the search's index, as in ``swarm_best_<robot>``), ``t`` (when the search
    ran), ``x``, ``y`` and ``cost`` (the search's own cost, lower is better; ``inf`` for an
    infeasible candidate). Of each search at most :data:`MAX_CANDIDATES` are kept, its best ones
    (in their order among equals), so the table grows with the steps, not with the swarm's size.

    Parameters
    ----------
    searches : list of (float, ndarray, ndarray)
        Per search in the order they ran: its time, its candidates ``(n, 2)`` and their costs
        ``(n,)`` (NaN counts as ``inf``).
    """
    cols: dict[str, list[np.ndarray]] = {"plan": [], "t": [], "x": [], "y": [], "cost": []}
    for k, (t, X, cost) in enumerate(searches):
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        cost = np.asarray(cost, dtype=float).reshape(len(X))
        cost = np.where(np.isnan(cost), np.inf, cost)
        keep = np.sort(np.argsort(cost, kind="stable")[:MAX_CANDIDATES])
        cols["plan"].append(np.full(len(keep), k))
        cols["t"].append(np.full(len(keep), float(t)))
        cols["x"].append(X[keep, 0])
        cols["y"].append(X[keep, 1])
        cols["cost"].append(cost[keep])
    return {c: np.concatenate(v) if v else np.zeros(0) for c, v in cols.items()}
