"""The one step interface every tuning optimizer has: ``setup / ask / tell / state``.

An optimizer searches a box of real vectors (:class:`Problem`: bounds, the starting vector, a
repair function, the number of objectives); every objective is **minimized**. The tuning loop
(:func:`hybridnav.tuner.tune`) drives it::

    opt.setup(problem, seed)
    while not opt.done:
        X = opt.ask()            # (k, d) vectors to evaluate, already repaired
        opt.tell(X, F)           # their objectives, (k, m)

and writes checkpoints, resumes, evaluates on any backend, tracks validation and stops early
once for all optimizers. :meth:`Optimizer.state` is JSON-ready and
:meth:`Optimizer.set_state` restores it exactly (random generators included), so a resumed run
is the uninterrupted one.

Settings are declared with :class:`hybridnav.params.Param` in ``parameters`` and checked on
construction (``GA(population=0)`` fails naming the key and what was expected).
"""

from __future__ import annotations

import random
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.params import Param

__all__ = ["Optimizer", "Problem", "rng_state", "set_rng_state"]


@dataclass
class Problem:
    """What an optimizer searches: a box, a starting point, a repair, ``n_obj`` objectives."""

    lower: np.ndarray
    upper: np.ndarray
    x0: np.ndarray
    repair: Callable[[np.ndarray], np.ndarray] = field(default=lambda X: X)
    n_obj: int = 1

    @property
    def dim(self) -> int:
        return int(self.lower.size)

    def clip(self, X: np.ndarray) -> np.ndarray:
        """Clip to the box and repair."""
        return self.repair(np.clip(X, self.lower, self.upper))


class Optimizer(ABC):
    """Base class: declared settings, a generation counter and the step interface.

    Subclasses set ``name``, ``parameters`` (``Param`` per setting; ``generations`` is the
    budget every optimizer has) and implement ``_setup``, ``ask``, ``tell``, ``population``,
    ``_state`` and ``_set_state``.
    """

    name: ClassVar[str] = ""
    multiobjective: ClassVar[bool] = False
    #: generations without a validation improvement before :func:`tune` stops early, when its
    #: ``patience`` is not given (0: never)
    default_patience: ClassVar[int] = 10
    parameters: ClassVar[dict[str, Param]] = {}

    def __init__(self, **settings: Any) -> None:
        unknown = sorted(set(settings) - set(self.parameters))
        if unknown:
            raise HybridnavError(f"{self.name}: {unknown[0]}: unknown setting; expected one of: "
                                 f"{', '.join(sorted(self.parameters))}")
        self.values = {k: p.default for k, p in self.parameters.items()}
        for k, v in settings.items():
            self.values[k] = self.parameters[k].check(k, v, f"{self.name}: ")
        self._check()
        self.problem: Problem | None = None
        self.generation = 0          # generations told so far in this stage (0: initial)

    def _check(self) -> None:
        """Cross-setting checks (raise HybridnavError)."""

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.values.items()
                         if v != self.parameters[k].default)
        return f"{type(self).__name__}({args})"

    def config(self) -> dict[str, Any]:
        """The optimizer's name and settings (for reports and configuration hashes)."""
        return {"kind": self.name, **self.values}

    @property
    def generations(self) -> int:
        """Generations after the initial one (the budget of a stage)."""
        return int(self.values["generations"])

    @property
    def done(self) -> bool:
        """Whether the stage's budget is used up."""
        return self.generation > self.generations

    def setup(self, problem: Problem, seed: int) -> None:
        """Start a run on ``problem``; all randomness from ``seed``."""
        if problem.n_obj > 1 and not self.multiobjective:
            raise HybridnavError(f"optimizer {self.name}: the cost has {problem.n_obj} "
                                 "objectives; expected one (use NSGA2 for several)")
        self.problem = problem
        self.generation = 0
        self._setup(problem, int(seed))

    @abstractmethod
    def _setup(self, problem: Problem, seed: int) -> None:
        """The optimizer's own start: generators seeded from ``seed``, generation 0."""

    @abstractmethod
    def ask(self) -> np.ndarray:
        """The vectors to evaluate next, ``(k, d)``, inside the box and repaired."""

    @abstractmethod
    def tell(self, X: np.ndarray, F: np.ndarray) -> None:
        """The objectives ``(k, m)`` of the vectors of the last :meth:`ask`."""

    @abstractmethod
    def population(self) -> tuple[np.ndarray, np.ndarray]:
        """The population the optimizer carries and its objectives: ``(n, d)``, ``(n, m)``."""

    def new_stage(self) -> None:
        """The cost changed (next k-fold stage): the carried values are stale; the next
        :meth:`ask` starts a new stage at generation 0 from the current population."""
        self.generation = 0
        self._new_stage()

    @abstractmethod
    def _new_stage(self) -> None:
        """Forget the values the carried population had on the previous stage's cost."""

    def state(self) -> dict[str, Any]:
        """JSON-ready state: with :meth:`set_state` the run continues exactly."""
        return {"optimizer": self.name, "generation": self.generation, **self._state()}

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state` (after :meth:`setup` on the same problem)."""
        if state.get("optimizer") != self.name:
            raise HybridnavError(f"checkpoint: optimizer: expected {self.name!r}, got "
                                 f"{state.get('optimizer')!r}")
        self.generation = int(state["generation"])
        self._set_state(state)

    @abstractmethod
    def _state(self) -> dict[str, Any]:
        """The optimizer's own JSON-ready state (random generators included)."""

    @abstractmethod
    def _set_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`_state`."""


def rng_state(rng: np.random.Generator) -> dict[str, Any]:
    """A NumPy generator's state, JSON-ready."""
    return rng.bit_generator.state


def set_rng_state(state: dict[str, Any]) -> np.random.Generator:
    """A NumPy generator in the state :func:`rng_state` returned."""
    rng = np.random.default_rng()
    rng.bit_generator.state = state
    return rng


def random_state(rnd: random.Random) -> list:
    """A ``random.Random``'s state, JSON-ready."""
    return list(rnd.getstate())


def set_random_state(state) -> random.Random:
    """A ``random.Random`` in the state :func:`random_state` returned."""
    def tup(o):
        return tuple(tup(v) for v in o) if isinstance(o, list) else o

    rnd = random.Random()
    rnd.setstate(tup(state))
    return rnd


