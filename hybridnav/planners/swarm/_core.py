"""Machinery shared by the swarm optimizers: validation, budgets, evaluation, results.

Nothing here knows about robots: an objective is any callable ``f(X) -> values`` taking an
``(N, d)`` array of points and returning ``N`` values (lower is better).
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.params import check_int, check_real  # noqa: F401  (the optimizers import them from here)

__all__ = ["BoundedObjective", "BoundsLike", "History", "Objective", "OptResult", "SeedLike"]

log = logging.getLogger("hybridnav.planners.swarm")

#: A vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values.
Objective = Callable[[NDArray[np.float64]], ArrayLike]
#: Anything :func:`numpy.random.default_rng` accepts.
SeedLike = int | np.random.Generator | np.random.SeedSequence | None
#: ``(lower, upper)``, two sequences of length ``d`` (or an object with ``lb`` and ``ub``).
BoundsLike = Any


@dataclass(frozen=True)
class History:
    """What an optimizer recorded after initialization (row 0) and after every iteration.

    Attributes
    ----------
    best : ndarray, shape (nit + 1,)
        Best value found so far (over every evaluated point); non-increasing for every method.
    population_best : ndarray, shape (nit + 1,)
        Best value in the population the method carries (swarm, archive, bats). Non-increasing
        for the elitist methods (``fastep``, ``acor``, ``bat``) and equal to ``best`` for
        ``acor``; ``fastep`` and ``bat`` can evaluate a better point that no member moves to.
    mean : ndarray, shape (nit + 1,)
        Mean value of the carried population (``inf`` when a member has the value ``inf``).
    nfev : ndarray of int, shape (nit + 1,)
        Cumulative number of evaluated points.
    extra : dict of str to ndarray
        Method-specific per-iteration quantities, e.g. ``alpha`` (firefly step size used in
        iteration ``t``, with ``nan`` in row 0), ``loudness`` and ``pulse_rate`` (bat means).
    """

    best: NDArray[np.float64]
    population_best: NDArray[np.float64]
    mean: NDArray[np.float64]
    nfev: NDArray[np.int64]
    extra: dict[str, NDArray[np.float64]] = field(default_factory=dict)


@dataclass(frozen=True)
class OptResult:
    """The result of a swarm optimizer.

    Attributes
    ----------
    x : ndarray, shape (d,)
        Best point found (over every evaluated point).
    fun : float
        Its objective value (``inf`` if every evaluated value was ``inf`` or NaN).
    nfev : int
        Number of evaluated points (never more than ``max_evals``).
    ncalls : int
        Number of calls of the objective: one for the initial population plus one per iteration.
    nit : int
        Number of iterations (generations) run.
    history : History
        Per-iteration record.
    population : ndarray, shape (n, d)
        Final population (swarm positions, ACOR archive sorted best first, bat positions).
    values : ndarray, shape (n,)
        Their objective values.
    method : str
        Name of the optimizer (a key of :data:`OPTIMIZERS`).
    params : dict
        The parameters the optimizer ran with (budgets and method parameters, not the seed).
    message : str
        Why it stopped: ``"iterations"``, ``"max_evals"`` or ``"target"``.
    state : dict of str to ndarray
        Method-specific final state (e.g. PSO ``velocity``, bat ``loudness`` and ``pulse_rate``).
    """

    x: NDArray[np.float64]
    fun: float
    nfev: int
    ncalls: int
    nit: int
    history: History
    population: NDArray[np.float64]
    values: NDArray[np.float64]
    method: str
    params: dict[str, Any]
    message: str
    state: dict[str, NDArray[Any]] = field(default_factory=dict)


class BoundedObjective:
    """An objective that can say cheaply how good a point can at best be.

    ``f(X) = f.refine(X, f.lower_bound(X))``; for every row ``f(X) >= f.lower_bound(X)`` (a NaN
    value counts as ``+inf``, a NaN bound bounds nothing), a row's value does not depend on the
    other rows, and a row whose bound is ``+inf`` has the value ``+inf``. Optimizers that carry
    only their best points (``acor``: the archive; ``fastep``: a firefly's move is taken only
    when it is better) use the bound to skip the exact value of points whose bound already rules
    them out (:meth:`Run.refine` only where it can change the run): the run is the same as with
    every value computed, for the cost of the points that can matter. Other optimizers call it
    as a plain objective.

    Parameters
    ----------
    lower_bound : callable
        ``lower_bound(X) -> (N,)`` bounds.
    refine : callable
        ``refine(X, B) -> (N,)`` exact values, given ``B = lower_bound(X)`` (it may reuse them).
    costly : bool
        Whether an exact value costs much more than a call of ``refine`` (then an optimizer may
        take a second call to skip more points; otherwise it asks in one call for every point
        it may need). Speed only: the run is the same either way.
    """

    def __init__(self, lower_bound: Callable[[NDArray[np.float64]], ArrayLike],
                 refine: Callable[[NDArray[np.float64], NDArray[np.float64]], ArrayLike],
                 costly: bool = True) -> None:
        self.lower_bound = lower_bound
        self.refine = refine
        self.costly = bool(costly)

    def __call__(self, X: NDArray[np.float64]) -> ArrayLike:
        return self.refine(X, np.asarray(self.lower_bound(X), dtype=float))


def decisive(B: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bounds to decide with: a NaN bound (which bounds nothing) as ``-inf``."""
    return np.where(np.isnan(B), -math.inf, B)


# --------------------------------------------------------------------------------------------
# validation helpers


def check_bounds(bounds: BoundsLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Validate ``bounds`` = ``(lower, upper)``: 1-D, same length >= 1, finite, lower < upper."""
    if hasattr(bounds, "lb") and hasattr(bounds, "ub"):  # scipy.optimize.Bounds
        bounds = (bounds.lb, bounds.ub)
    if isinstance(bounds, (str, bytes)) or not hasattr(bounds, "__len__") or len(bounds) != 2:
        raise HybridnavError("bounds: expected (lower, upper), two sequences of length d, got "
                             f"{bounds!r}")
    try:
        lower = np.array(bounds[0], dtype=float, ndmin=1)
        upper = np.array(bounds[1], dtype=float, ndmin=1)
    except (TypeError, ValueError):
        raise HybridnavError("bounds: expected (lower, upper), two sequences of numbers, got "
                             f"{bounds!r}") from None
    if lower.ndim != 1 or upper.ndim != 1:
        raise HybridnavError(f"bounds: lower and upper must be 1-D, got shapes {lower.shape} and "
                             f"{upper.shape}")
    if lower.size == 0 or lower.shape != upper.shape:
        raise HybridnavError(f"bounds: lower and upper must have the same length d >= 1, got "
                             f"{lower.size} and {upper.size}")
    for side, arr in (("lower", lower), ("upper", upper)):
        if not np.all(np.isfinite(arr)):
            i = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise HybridnavError(f"bounds: {side}[{i}] = {arr[i]} is not finite")
    bad = np.flatnonzero(~(lower < upper))
    if bad.size:
        i = int(bad[0])
        raise HybridnavError(f"bounds: lower[{i}] = {lower[i]:g} is not below upper[{i}] = "
                             f"{upper[i]:g}")
    return lower, upper


def mean_value(values: NDArray[np.float64]) -> float:
    """Mean of objective values; ``inf`` if any is ``inf`` (``-inf`` if any is ``-inf`` and none
    is ``inf``), without the NaN of ``inf - inf``."""
    if np.all(np.isfinite(values)):
        return float(np.mean(values))
    return math.inf if np.any(values == math.inf) else -math.inf


# --------------------------------------------------------------------------------------------
# geometry helpers


def fold(X: NDArray[np.float64], lower: NDArray[np.float64],
         upper: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Reflect points into the box as often as needed (mirror walls at the bounds).

    Returns the folded points and a mask of the components that were reflected an odd number of
    times (their direction of motion is reversed).
    """
    span = upper - lower
    y = np.mod(X - lower, 2.0 * span)
    flipped = y > span
    y = np.where(flipped, 2.0 * span - y, y)
    out = np.clip(lower + y, lower, upper)  # guard against rounding at the walls
    return out, flipped


def uniform_population(rng: np.random.Generator, lower: NDArray[np.float64],
                       upper: NDArray[np.float64], n: int,
                       init: ArrayLike | None) -> NDArray[np.float64]:
    """``n`` points: the rows of ``init`` first, then uniformly random points in the box."""
    d = lower.size
    X = lower + (upper - lower) * rng.random((n, d))
    if init is None:
        return X
    try:
        P = np.array(init, dtype=float, ndmin=2)
    except (TypeError, ValueError):
        raise HybridnavError(f"init: expected an (m, {d}) array of numbers") from None
    if P.ndim != 2 or P.shape[1] != d:
        raise HybridnavError(f"init: expected an (m, {d}) array of points, got shape {P.shape}")
    if P.shape[0] > n:
        raise HybridnavError(f"init: {P.shape[0]} points given for a population of {n}")
    outside = np.flatnonzero(~np.all(np.isfinite(P) & (P >= lower) & (P <= upper), axis=1))
    if outside.size:
        raise HybridnavError(f"init: point {int(outside[0])} = {P[outside[0]].tolist()} is "
                             "outside bounds")
    X[:P.shape[0]] = P
    return X


# --------------------------------------------------------------------------------------------
# a run: budget, evaluation, history


class Run:
    """One optimizer run: validated problem, budget bookkeeping, evaluation and history.

    Parameters
    ----------
    method : str
        Name of the optimizer, for the result.
    f, bounds, iterations, max_evals, target, seed
        As in the optimizers.
    """

    def __init__(self, method: str, f: Objective, bounds: BoundsLike, iterations: int | None,
                 max_evals: int | None, target: float | None, seed: SeedLike) -> None:
        if not callable(f):
            raise HybridnavError(f"f: expected a callable f(X) -> values, got {f!r}")
        self.method = method
        self.f = f
        self.lower, self.upper = check_bounds(bounds)
        self.span = self.upper - self.lower
        self.d = self.lower.size
        if iterations is None and max_evals is None:
            raise HybridnavError("iterations: give a budget: iterations and/or max_evals")
        self.iterations = None if iterations is None else check_int("iterations", iterations, 1)
        self.max_evals = None if max_evals is None else check_int("max_evals", max_evals, 1)
        self.target = None if target is None else check_real("target", target)
        try:
            self.rng = np.random.default_rng(seed)
        except (TypeError, ValueError) as exc:
            raise HybridnavError(f"seed: expected an integer >= 0, a SeedSequence or a "
                                 f"numpy Generator, got {seed!r} ({exc})") from None
        self.nfev = 0
        self.ncalls = 0
        self.nit = 0
        self.best_x = np.full(self.d, np.nan)
        self.best_f = math.inf
        self.message = ""
        self._hist: dict[str, list[float]] = {"best": [], "population_best": [], "mean": [],
                                              "nfev": []}
        self._extra: dict[str, list[float]] = {}

    # budget ---------------------------------------------------------------------------------

    def check_budget(self, n_init: int, per_iteration: int) -> None:
        """Refuse a ``max_evals`` that does not cover the initial population."""
        if self.max_evals is not None and self.max_evals < n_init:
            raise HybridnavError(f"max_evals: {self.max_evals} is below the {n_init} evaluations "
                                 "of the initial population")
        self.per_iteration = per_iteration

    def planned_iterations(self, n_init: int, per_iteration: int) -> int:
        """The number of iterations the budget allows (used by schedules such as PSO's ``w``)."""
        t = math.inf if self.iterations is None else self.iterations
        if self.max_evals is not None:
            t = min(t, (self.max_evals - n_init) // per_iteration)
        return int(t)

    def more(self) -> bool:
        """Whether another iteration fits in the budget (sets :attr:`message` when not)."""
        if self.target is not None and self.best_f <= self.target:
            self.message = "target"
            return False
        if self.iterations is not None and self.nit >= self.iterations:
            self.message = "iterations"
            return False
        if self.max_evals is not None and self.nfev + self.per_iteration > self.max_evals:
            self.message = "max_evals"
            return False
        self.nit += 1
        return True

    # evaluation -----------------------------------------------------------------------------

    def evaluate(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Call the objective once on all rows of ``X``; NaN counts as ``+inf``."""
        values = self._values(self.f(X), X.shape[0])
        self.account(X, values)
        return values

    def _values(self, raw: Any, n: int, what: str = "f") -> NDArray[np.float64]:
        """``raw`` as ``n`` floats, NaN as ``+inf`` (``what``: the callable, for the message)."""
        try:
            values = np.array(raw, dtype=float)
        except (TypeError, ValueError):
            raise HybridnavError(f"{what}: returned {type(raw).__name__} that is not an array of "
                                 "real numbers") from None
        if values.shape != (n,):
            raise HybridnavError(f"{what}: returned shape {values.shape} for {n} points; expected "
                                 f"({n},): one value per row of X")
        values[np.isnan(values)] = math.inf
        return values

    def account(self, X: NDArray[np.float64], values: NDArray[np.float64]) -> None:
        """Count one call of the objective on the rows of ``X`` with these ``values`` (budget,
        best point so far)."""
        first = self.ncalls == 0
        self.ncalls += 1
        self.nfev += X.shape[0]
        i = int(np.argmin(values))
        if first or values[i] < self.best_f:  # ties keep the earlier point
            self.best_f = float(values[i])
            self.best_x = X[i].copy()

    # bounded objectives: evaluate only where a value can matter -----------------------------

    @property
    def bounded(self) -> bool:
        """Whether the objective offers lower bounds (:func:`bounded_objective`), so an optimizer
        may skip the exact value of points whose bound already decides their fate."""
        return callable(getattr(self.f, "lower_bound", None)) and callable(
            getattr(self.f, "refine", None))

    def lower_bound(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """The objective's lower bounds of the rows of ``X`` (``f(X) >= bound`` row by row; a
        NaN bound bounds nothing, see :func:`decisive`). Not a call of the objective: no budget
        is counted (:meth:`account` does that once the values are in)."""
        B = np.array(self.f.lower_bound(X), dtype=float)
        if B.shape != (X.shape[0],):
            raise HybridnavError(f"f.lower_bound: returned shape {B.shape} for {X.shape[0]} "
                                 "points; expected one bound per row of X")
        return B

    def refine(self, X: NDArray[np.float64], B: NDArray[np.float64],
               rows: NDArray[np.int_]) -> NDArray[np.float64]:
        """The exact values of the rows ``rows`` of ``X`` whose bounds are ``B`` (as
        :meth:`lower_bound` returned them), NaN as ``+inf``; no bookkeeping."""
        if not len(rows):
            return np.zeros(0)
        return self._values(self.f.refine(X[rows], B[rows]), len(rows), "f.refine")

    # history --------------------------------------------------------------------------------

    def record(self, values: NDArray[np.float64], **extra: float) -> None:
        """Append one history row; ``values`` are those of the carried population."""
        self._hist["best"].append(self.best_f)
        self._hist["population_best"].append(float(np.min(values)))
        self._hist["mean"].append(mean_value(values))
        self._hist["nfev"].append(self.nfev)
        for key, val in extra.items():
            self._extra.setdefault(key, []).append(float(val))

    def result(self, population: NDArray[np.float64], values: NDArray[np.float64],
               params: Mapping[str, Any], state: Mapping[str, NDArray[Any]] | None = None
               ) -> OptResult:
        """Package the run as an :class:`OptResult`."""
        if not self.message:
            self.message = "iterations"
        history = History(
            best=np.array(self._hist["best"]),
            population_best=np.array(self._hist["population_best"]),
            mean=np.array(self._hist["mean"]),
            nfev=np.array(self._hist["nfev"], dtype=np.int64),
            extra={k: np.array(v) for k, v in self._extra.items()},
        )
        all_params = {"iterations": self.iterations, "max_evals": self.max_evals,
                      "target": self.target, **params}
        log.debug("%s: %d iterations, %d evaluations, best %.6g (%s)", self.method, self.nit,
                  self.nfev, self.best_f, self.message)
        return OptResult(x=self.best_x.copy(), fun=self.best_f, nfev=self.nfev,
                         ncalls=self.ncalls, nit=self.nit, history=history,
                         population=population.copy(), values=values.copy(), method=self.method,
                         params=all_params, message=self.message, state=dict(state or {}))
