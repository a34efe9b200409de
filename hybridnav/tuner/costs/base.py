"""The cost protocol: a batch of candidate systems and a context in, an ``(n, m)`` array out.

A cost is a picklable object built once (in the main process) and shipped to the workers as an
object — never as a string re-validated per chunk. Anything expensive it derives (packed worlds,
compiled models) it builds lazily on first use and caches per process (:func:`process_cache`).

To write a cost, subclass :class:`Cost` and implement :meth:`Cost.evaluate`::

    class Overshoot(Cost):
        objective_names = ("overshoot",)

        def evaluate(self, candidates, context):
            y = candidates.evaluate({"e": E, "de": DE})        # (n, samples), one batched call
            return np.abs(y - Y).max(axis=1, keepdims=True)

All objectives are minimized. A cost that can be cross-validated also implements
:meth:`Cost.split` and :meth:`Cost.folds`.
"""

from __future__ import annotations

import uuid
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from hybridnav.errors import HybridnavError

__all__ = ["Candidates", "Context", "Cost", "Evaluation", "evaluate_chunk", "process_cache"]

_PROCESS_CACHE: dict[str, Any] = {}


def process_cache(key: str, build):
    """``build()`` once per process and key (a few entries kept)."""
    if key not in _PROCESS_CACHE:
        if len(_PROCESS_CACHE) >= 16:
            _PROCESS_CACHE.pop(next(iter(_PROCESS_CACHE)))
        _PROCESS_CACHE[key] = build()
    return _PROCESS_CACHE[key]


@dataclass(frozen=True)
class Context:
    """Where an evaluation belongs.

    Attributes
    ----------
    seed : int
        The tuning run's seed (noise streams derive from it).
    role : str
        ``"train"``, ``"validation"``, ``"fold"`` or ``"test"``.
    generation : int
        The generation (and k-fold stage) the evaluation belongs to: a noise key.
    indices : tuple of int, optional
        Per candidate its index in the generation: a noise key, so that results do not depend
        on how a generation is chunked.
    """

    seed: int = 0
    role: str = "train"
    generation: int = 0
    indices: tuple[int, ...] | None = None


class Candidates:
    """A batch of candidate systems: vectors of a :class:`TunableSettings`, decoded lazily.

    Attributes
    ----------
    X : ndarray, shape (n, d)
    settings : TunableSettings
    """

    def __init__(self, settings, X: np.ndarray) -> None:
        self.settings = settings
        self.X = np.array(X, dtype=float, ndmin=2)
        self._tables = None
        self._systems = None

    @classmethod
    def of(cls, system) -> Candidates:
        """One fixed system as a batch of one (scoring a start, judging, coverage)."""
        from hybridnav.tuner.settings import TunableSettings

        return cls(TunableSettings(system, mf=False), np.zeros((1, 0)))

    def __len__(self) -> int:
        return len(self.X)

    @property
    def family(self):
        """The :class:`~hybridnav.fuzzy.family.SystemFamily` every candidate belongs to."""
        return self.settings.family

    @property
    def tables(self):
        """The candidates' sampled tables (one batched evaluation serves them all)."""
        if self._tables is None:
            self._tables = self.settings.tables(self.X)
        return self._tables

    @property
    def systems(self) -> list:
        """The candidates as :class:`~hybridnav.fuzzy.FuzzySystem` objects."""
        if self._systems is None:
            self._systems = self.settings.systems(self.X)
        return self._systems

    def evaluate(self, inputs: Mapping[str, Any]) -> np.ndarray:
        """Every candidate's output at the same ``S`` input samples: ``(n, S)``, one batched
        call (``inputs``: input name -> ``(S,)`` array)."""
        names = self.settings.template.input_names
        if not isinstance(inputs, Mapping) or set(inputs) != set(names):
            raise HybridnavError(f"inputs: expected a mapping with exactly the inputs "
                                 f"{', '.join(names)}, got "
                                 f"{sorted(inputs) if isinstance(inputs, Mapping) else inputs!r}")
        try:
            cols = {k: np.asarray(v, dtype=float).ravel() for k, v in inputs.items()}
        except (TypeError, ValueError):
            raise HybridnavError("inputs: expected arrays of numbers") from None
        sizes = {len(v) for v in cols.values()}
        if len(sizes) != 1:
            raise HybridnavError(f"inputs: expected arrays of one length, got {sorted(sizes)}")
        S = sizes.pop()
        n = len(self)
        member = np.repeat(np.arange(n), S)
        tiled = {k: np.tile(v, n) for k, v in cols.items()}
        return self.family.evaluate(self.tables, member, tiled).reshape(n, S)

    def uncovered(self, grid: int = 41) -> np.ndarray:
        """Per candidate, the fraction of a ``grid``-per-axis grid where no rule fires."""
        if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or grid < 2:
            raise HybridnavError(f"grid: expected an integer >= 2, got {grid!r}")
        return self.family.uncovered(self.tables, int(grid))


@dataclass
class Evaluation:
    """What a cost says about a batch: objectives ``(n, m)``, feasibility ``(n,)`` (a
    validation choice never prefers an infeasible candidate), per candidate a dict of extra
    numbers, and detail rows (e.g. one per world) for ``evaluations.csv``."""

    objectives: np.ndarray
    feasible: np.ndarray | None = None
    info: list[dict[str, Any]] | None = None
    details: list[list[dict[str, Any]]] | None = None

    def __post_init__(self) -> None:
        n = len(self.objectives)
        if self.feasible is None:
            self.feasible = np.ones(n, dtype=bool)
        if self.info is None:
            self.info = [{} for _ in range(n)]
        if self.details is None:
            self.details = [[] for _ in range(n)]

    @staticmethod
    def concat(parts: list[Evaluation]) -> Evaluation:
        return Evaluation(np.vstack([p.objectives for p in parts]),
                          np.concatenate([p.feasible for p in parts]),
                          [i for p in parts for i in p.info],
                          [d for p in parts for d in p.details])


class Cost(ABC):
    """Base class of tuning costs (see the module docstring).

    Attributes
    ----------
    objective_names : tuple of str
        One name per objective (their number is ``n_objectives``).
    """

    objective_names: tuple[str, ...] = ("cost",)

    def __init__(self) -> None:
        self.token = uuid.uuid4().hex

    @property
    def n_objectives(self) -> int:
        """The number of objectives ``m``."""
        return len(self.objective_names)

    @abstractmethod
    def evaluate(self, candidates: Candidates, context: Context) -> np.ndarray:
        """The objectives of every candidate, ``(n, m)`` (all minimized)."""

    def assess(self, candidates: Candidates, context: Context) -> Evaluation:
        """:meth:`evaluate` with feasibility, extra numbers and detail rows (costs that have
        them override this; the tuner calls it)."""
        return Evaluation(self.objectives(self.evaluate(candidates, context), len(candidates)))

    def objectives(self, F: Any, n: int) -> np.ndarray:
        """``F`` as an ``(n, m)`` float array, or a clear error."""
        try:
            if np.iscomplexobj(F):
                raise TypeError("complex")
            F = np.array(F, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise HybridnavError(f"cost {type(self).__name__}: expected an (n, m) array of "
                                 "numbers") from None
        if F.ndim == 1 and self.n_objectives == 1:
            F = F[:, None]
        if F.shape != (n, self.n_objectives):
            raise HybridnavError(f"cost {type(self).__name__}: expected objectives of shape "
                                 f"({n}, {self.n_objectives}), got {F.shape}")
        if np.any(F == -np.inf):
            raise HybridnavError(f"cost {type(self).__name__}: expected objectives that are "
                                 "finite or +inf (the worst), got -inf")
        return np.where(np.isnan(F), np.inf, F)

    def check(self, settings) -> None:
        """Raise a HybridnavError when this cost cannot evaluate systems of ``settings``."""

    def config(self) -> dict[str, Any]:
        """What determines this cost's values (for configuration hashes)."""
        return {"kind": type(self).__name__}

    def describe(self) -> str:
        """One sentence for reports."""
        return f"{type(self).__name__} ({', '.join(self.objective_names)}, minimized)"

    # ---- cross-validation ------------------------------------------------------------------

    def split(self, fraction: float, seed: int) -> tuple[Cost, Cost]:
        """The cost on a ``1 - fraction`` training part and on a ``fraction`` validation part
        of its data."""
        raise HybridnavError(f"{type(self).__name__}: cannot be split into training and "
                             "validation parts; give a validation cost")

    def folds(self, k: int, seed: int) -> list[tuple[Cost, Cost]]:
        """``k`` pairs (cost on the other folds, cost on fold ``j``)."""
        raise HybridnavError(f"{type(self).__name__}: cannot be split into folds")

    # ---- judging ---------------------------------------------------------------------------

    def judge(self, systems: Mapping[str, Any], role: str = "test", *,
              backend=None) -> pd.DataFrame:
        """One row per system: its objectives on this cost's data (nominal context);
        ``backend`` is for costs whose judging runs elsewhere (unused here)."""
        rows = []
        for label, s in systems.items():
            ev = self.assess(Candidates.of(s), Context(role=role))
            rows.append({"set": role, "system": label,
                         **{f"objective_{i}": float(v) for i, v in enumerate(ev.objectives[0])},
                         **ev.info[0]})
        return pd.DataFrame(rows)

    def verdict(self, table: pd.DataFrame, role: str,
                falsified: pd.DataFrame | None = None) -> dict[str, Any]:
        """Checks of the tuned system against its start on a judged table (``falsified`` is for
        costs with a falsification search; unused here)."""
        t = table[table.set == role].set_index("system")
        if not {"start", "tuned"} <= set(t.index):
            return {"checks": [], "better": False, "headline": ""}
        checks = []
        for i, name in enumerate(self.objective_names):
            a, b = t.loc["tuned", f"objective_{i}"], t.loc["start", f"objective_{i}"]
            ok = bool(np.isfinite(a) and (a < b or not np.isfinite(b)))
            checks.append((f"{name}: tuned {a:.4g} vs start {b:.4g} (lower is better)", ok))
        # better: strictly lower on every objective, and finite (a tie is not better)
        better = all(ok for _, ok in checks)
        return {"checks": checks, "better": better,
                "headline": f"on the {role} data the tuned system is "
                            f"{'better' if better else 'NOT better'} than its start "
                            f"({'; '.join(c for c, _ in checks)})"}


def evaluate_chunk(cost: Cost, settings, X: np.ndarray, context: Context) -> Evaluation:
    """One unit of parallel work: ``cost.assess`` of the vectors ``X`` (any process); ``cost``
    and ``settings`` may come as :class:`hybridnav.backends.Shipped` (unpickled once per
    worker)."""
    from hybridnav.backends import unship

    cost, settings = unship(cost), unship(settings)
    ev = cost.assess(Candidates(settings, X), context)
    ev.objectives = cost.objectives(ev.objectives, len(X))
    return ev


def permutation(n: int, seed: int, key: int) -> np.ndarray:
    """A permutation of ``range(n)`` from ``SeedSequence(seed, spawn_key=(key,))``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(key,))).permutation(n)


def fold_of(n: int, k: int, seed: int) -> np.ndarray:
    """The fold of each of ``n`` items: a seeded permutation dealt round robin into ``k``."""
    out = np.zeros(n, dtype=int)
    for pos, i in enumerate(permutation(n, seed, 7)):
        out[int(i)] = pos % k
    return out
