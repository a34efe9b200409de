"""Standard test functions, vectorized: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``(N,)``.

All four have the global minimum 0; :data:`FUNCTIONS` gives their usual search boxes and minimizers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FUNCTIONS", "TestFunction", "ackley", "rastrigin", "rosenbrock", "sphere"]


def sphere(X: ArrayLike) -> NDArray[np.float64]:
    """``sum x_i^2``; minimum 0 at the origin."""
    X = np.asarray(X, dtype=float)
    return np.einsum("ij,ij->i", X, X)


def rosenbrock(X: ArrayLike) -> NDArray[np.float64]:
    """``sum 100 (x_{i+1} - x_i^2)^2 + (1 - x_i)^2`` (d >= 2); minimum 0 at ``(1, ..., 1)``."""
    X = np.asarray(X, dtype=float)
    return np.sum(100.0 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1.0 - X[:, :-1]) ** 2, axis=1)


def rastrigin(X: ArrayLike) -> NDArray[np.float64]:
    """``10 d + sum x_i^2 - 10 cos(2 pi x_i)``; minimum 0 at the origin, local minima near
    every integer point."""
    X = np.asarray(X, dtype=float)
    return 10.0 * X.shape[1] + np.sum(X**2 - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


def ackley(X: ArrayLike) -> NDArray[np.float64]:
    """``-20 exp(-0.2 sqrt(mean x_i^2)) - exp(mean cos(2 pi x_i)) + 20 + e``; minimum 0 at the
    origin."""
    X = np.asarray(X, dtype=float)
    # written with expm1 so that the value at the origin is exactly 0
    a = -20.0 * np.expm1(-0.2 * np.sqrt(np.mean(X**2, axis=1)))
    b = -np.e * np.expm1(np.mean(np.cos(2.0 * np.pi * X), axis=1) - 1.0)
    return a + b


class TestFunction(NamedTuple):
    """A test function with its usual box (per coordinate) and its minimizer (per coordinate)."""

    f: Callable[[ArrayLike], NDArray[np.float64]]
    lower: float
    upper: float
    xstar: float

    __test__ = False  # not a pytest test class

    def bounds(self, d: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The ``d``-dimensional box ``(lower, upper)``."""
        return np.full(d, self.lower), np.full(d, self.upper)


#: name -> (function, lower, upper, minimizer coordinate); every minimum value is 0.
FUNCTIONS: dict[str, TestFunction] = {
    "sphere": TestFunction(sphere, -5.12, 5.12, 0.0),
    "rosenbrock": TestFunction(rosenbrock, -5.0, 10.0, 1.0),
    "rastrigin": TestFunction(rastrigin, -5.12, 5.12, 0.0),
    "ackley": TestFunction(ackley, -32.768, 32.768, 0.0),
}
