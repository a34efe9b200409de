"""PSO-BA's fitness of candidate path points (eq. 6 of Abed et al. 2022) and the candidate disk
around the robot."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError

__all__ = ["EPS", "disk_candidates", "psoba_fitness"]

#: the paper's epsilon in eq. 6
EPS = 0.001


def psoba_fitness(X: ArrayLike, position: ArrayLike, goal: ArrayLike, st: float,
                  w1: float = 0.5, floor: float = 0.3) -> NDArray[np.float64]:
    """Eq. 6 fitness of candidate path points (higher is better).

    ``1 / (w1 * dn + (1 - w1) * angle / 90 + 0.001)`` with
    ``dn = floor + (1 - floor) * min(|X - goal| / st, 1)`` and ``angle`` the angle in degrees, in
    ``[0, 180]``, between the directions from ``position`` to ``X`` and to ``goal`` (0 for a
    candidate at ``position`` itself or a goal at ``position``).

    Parameters
    ----------
    X : array_like, shape (N, 2)
        Candidates.
    position, goal : array_like, shape (2,)
    st : float
        Distance normalisation (the start-to-goal distance), positive.
    w1 : float
        Weight of the distance, in [0, 1]; the angle's is ``1 - w1``.
    floor : float
        Lower end of the normalised distance, in [0, 1).

    Returns
    -------
    ndarray, shape (N,)
    """
    X = np.asarray(X, dtype=float).reshape(-1, 2)
    p = np.asarray(position, dtype=float).reshape(2)
    g = np.asarray(goal, dtype=float).reshape(2)
    if not st > 0:
        raise HybridnavError(f"st: expected a positive distance, got {st!r}")
    if not 0.0 <= w1 <= 1.0:
        raise HybridnavError(f"w1: expected a weight in [0, 1], got {w1!r}")
    if not 0.0 <= floor < 1.0:
        raise HybridnavError(f"floor: expected a value in [0, 1), got {floor!r}")
    d = np.hypot(X[:, 0] - g[0], X[:, 1] - g[1])
    dn = floor + (1.0 - floor) * np.minimum(d / st, 1.0)
    D = X - p
    gd = g - p
    cross = gd[0] * D[:, 1] - gd[1] * D[:, 0]
    dot = gd[0] * D[:, 0] + gd[1] * D[:, 1]
    angle = np.degrees(np.abs(np.arctan2(cross, dot)))      # 0 when either vector is zero
    return 1.0 / (w1 * dn + (1.0 - w1) * angle / 90.0 + EPS)


def disk_candidates(X: ArrayLike, position: ArrayLike, radius: float) -> NDArray[np.float64]:
    """Map points radially onto the disk of ``radius`` around ``position`` (inside ones stay)."""
    X = np.asarray(X, dtype=float).reshape(-1, 2)
    p = np.asarray(position, dtype=float).reshape(2)
    D = X - p
    n = np.hypot(D[:, 0], D[:, 1])
    scale = np.where(n > radius, radius / np.where(n > 0, n, 1.0), 1.0)
    return p + D * scale[:, None]
