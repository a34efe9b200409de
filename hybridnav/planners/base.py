"""The planner interface: declared parameters, ``run(scenario, seed) -> Result``.

Every planner declares its parameters as :class:`Param` entries (default, type, bounds, one-line
doc); ``hybridnav planners`` lists them and ``hybridnav run --set key=value`` sets them, with the
same validation as Python keyword arguments.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from hybridnav.errors import HybridnavError
from hybridnav.results import Result

__all__ = ["Param", "Planner", "parse_assignments"]


@dataclass(frozen=True)
class Param:
    """A planner parameter: default value, type, bounds or choices, and what it does."""

    default: Any
    doc: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple | None = None

    @property
    def kind(self) -> type:
        return type(self.default)

    def check(self, planner: str, key: str, value: Any) -> Any:
        """Validate and convert ``value`` (strings from the command line are parsed)."""
        kind = self.kind
        if isinstance(value, str) and kind is not str:
            value = _parse(planner, key, value, kind)
        if kind is bool:
            if not isinstance(value, bool):
                raise HybridnavError(f"planner {planner}: {key}: expected true or false, got "
                                     f"{value!r}")
        elif kind in (int, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise HybridnavError(f"planner {planner}: {key}: expected a number, got {value!r}")
            if kind is int:
                if float(value) != int(value):
                    raise HybridnavError(
                        f"planner {planner}: {key}: expected an integer, got {value!r}")
                value = int(value)
            else:
                value = float(value)
                if not math.isfinite(value):
                    raise HybridnavError(
                        f"planner {planner}: {key}: expected a finite number, got {value!r}")
            if (self.lo is not None and value < self.lo) or (self.hi is not None
                                                              and value > self.hi):
                raise HybridnavError(
                    f"planner {planner}: {key}: expected a value in [{self.lo}, {self.hi}], got "
                    f"{value!r}")
        elif not isinstance(value, kind):
            raise HybridnavError(f"planner {planner}: {key}: expected {kind.__name__}, got "
                                 f"{value!r}")
        if self.choices is not None and value not in self.choices:
            raise HybridnavError(f"planner {planner}: {key}: expected one of "
                                 f"{', '.join(map(str, self.choices))}, got {value!r}")
        return value


def _parse(planner: str, key: str, text: str, kind: type) -> Any:
    text = text.strip()
    if kind is bool:
        low = text.lower()
        if low in ("true", "yes", "1", "on"):
            return True
        if low in ("false", "no", "0", "off"):
            return False
        raise HybridnavError(f"planner {planner}: {key}: expected true or false, got {text!r}")
    try:
        return int(text) if kind is int else float(text)
    except ValueError:
        raise HybridnavError(
            f"planner {planner}: {key}: expected {'an integer' if kind is int else 'a number'}, "
            f"got {text!r}") from None


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

    Subclasses set :attr:`name`, :attr:`description`, :attr:`params` and implement :meth:`run`.
    ``drives`` says which robot models it can drive, by capability (a model qualifies when it has
    every capability of one of the sets; see :attr:`hybridnav.models.Model.capabilities`), and
    ``models`` lists the registered models that qualify (derived, never written by hand);
    ``moving_obstacles`` and ``moving_targets`` say whether it handles ``moving_circle``
    obstacles and ``goal_follow`` targets.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    params: ClassVar[dict[str, Param]] = {}
    drives: ClassVar[tuple[frozenset[str], ...]] = (frozenset({"robot"}),)
    models: ClassVar[tuple[str, ...]] = ()
    moving_obstacles: ClassVar[bool] = True
    moving_targets: ClassVar[bool] = True
    stochastic: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.models = _driven(cls.drives)

    def __init__(self, **params: Any) -> None:
        values = {k: p.default for k, p in self.params.items()}
        for key, value in params.items():
            if key not in self.params:
                raise HybridnavError(
                    f"planner {self.name}: unknown parameter {key!r}; expected one of: "
                    + (", ".join(sorted(self.params)) or "(none)"))
            values[key] = self.params[key].check(self.name, key, value)
        self.values = values

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


def _driven(drives) -> tuple[str, ...]:
    """The registered robot models with every capability of one of the sets in ``drives``."""
    from hybridnav.models import MODELS

    return tuple(name for name, cls in MODELS.items()
                 if "robot" in cls.capabilities and any(req <= cls.capabilities for req in drives))


Planner.models = _driven(Planner.drives)
