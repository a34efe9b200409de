"""A safety filter for constant-speed unicycles: keep an escape circle free.

The EFFC paper's robot moves at constant ``speed`` and turns at most ``max_turn`` per control
cycle ``dt``. Turning at that rate for good, it drives round a circle of radius
``rho = speed dt / max_turn`` (1.3 cm for the paper's robot) centred ``rho`` to its left (or
right). Call a state **safe** when one of those two circles, widened by the robot radius and a
``margin``, is free of obstacles and inside the workspace: from a safe state the robot can
circle for ever without touching anything. The set of safe states is invariant under the
filter below, so a robot that starts safe never collides with a static obstacle nor leaves the
workspace (moving obstacles are taken where they are now; the guarantee is for static worlds).

Each cycle the controller wants a heading change ``want`` (the field's direction, clipped to
``max_turn``). The filter follows the exact arc of that change for one cycle and keeps it when
the state it ends in is safe; otherwise it tries ``candidates`` heading changes spread over
``[-max_turn, max_turn]`` and takes the safe one nearest to ``want`` (there is always one when
the robot was safe: turning on along the free circle). If none is safe (a robot that started
unsafe) it takes the one whose better circle has the most room. Far from everything (clearance
above ``margin + 2 rho + 2 speed dt``) nothing can be unsafe and nothing is computed.

This is a control barrier function on the heading rate with the escape circle as the barrier
(a state-dependent, one-step-lookahead filter); it changes the command only when it must
(measured: in about 0.5 % of the control cycles of generated worlds). The planners switch it
on with ``safety_margin > 0`` (:class:`hybridnav.planners.field.base.FieldPlanner`); the
tuner's lockstep runs (NumPy and compiled) apply the same test.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["escape_filter", "escape_radius"]

#: heading changes tried when the wanted one ends unsafe
CANDIDATES = 9


def escape_radius(speed: float, dt: float, max_turn: float) -> float:
    """The radius of the circle a robot turning at ``max_turn`` per cycle drives round."""
    return float(speed) * float(dt) / float(max_turn)


def _arc_end(P: np.ndarray, theta: np.ndarray, d: np.ndarray, step: float):
    """End points and headings of arcs of length ``step`` from ``P`` (n, 2) at headings
    ``theta`` (n,) turning by ``d`` (n, S) at a constant rate."""
    th1 = theta[:, None] + d
    small = np.abs(d) < 1e-12
    safe_d = np.where(small, 1.0, d)
    R = step / safe_d
    dx = np.where(small, step * np.cos(theta)[:, None], R * (np.sin(th1) - np.sin(theta)[:, None]))
    dy = np.where(small, step * np.sin(theta)[:, None], R * (np.cos(theta)[:, None] - np.cos(th1)))
    return P[:, None, 0] + dx, P[:, None, 1] + dy, th1


def escape_filter(X: np.ndarray, V: np.ndarray, *, speed: float, dt: float, max_turn: float,
                  margin: float, radius: np.ndarray,
                  clearance: Callable[[np.ndarray, np.ndarray], np.ndarray],
                  here: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The commands ``V`` (n, 2) of unicycles in states ``X`` (n, >= 3: x, y, heading) made
    safe (module docstring).

    Parameters
    ----------
    X : ndarray, shape (n, nx)
    V : ndarray, shape (n, 2)
        The commanded velocities (their directions matter).
    speed, dt, max_turn : float
        The robots' constant speed, control cycle and largest heading change per cycle.
    margin : float
        Room kept beyond the robot radius.
    radius : ndarray, shape (n,)
        The robots' footprint radii.
    clearance : callable
        ``clearance(Q, rows)``: the signed distance from the points ``Q`` (m, 2) to the nearest
        obstacle or the workspace border, for the robots ``rows`` (m,) (their worlds and time).
    here : ndarray, shape (n,), optional
        ``clearance`` at the robots' positions, when already known.

    Returns
    -------
    (V, changed)
        The safe commands (length ``speed``; unchanged rows as given) and which rows changed.
    """
    from hybridnav.errors import HybridnavError

    if not (max_turn > 0 and speed > 0 and dt > 0):
        raise HybridnavError(f"escape_filter: expected a positive speed, dt and max_turn, got "
                             f"{speed!r}, {dt!r}, {max_turn!r}")
    X = np.asarray(X, dtype=float)
    V = np.array(V, dtype=float, copy=True)
    n = len(X)
    if X.ndim != 2 or X.shape[1] < 3 or V.shape != (n, 2):
        raise HybridnavError(f"escape_filter: expected states (n, >= 3) and commands (n, 2), got "
                             f"{X.shape} and {V.shape}")
    changed = np.zeros(n, dtype=bool)
    if n == 0 or margin <= 0:
        return V, changed
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (n,))
    rho = escape_radius(speed, dt, max_turn)
    step = float(speed) * float(dt)
    rows = np.arange(n)
    if here is None:
        here = clearance(X[:, :2], rows)
    # beyond this, every end point and circle is far enough: nothing to test
    near = ~(np.asarray(here) - radius >= margin + 2 * rho + 2 * step + 1e-12)
    idx = np.flatnonzero(near & np.all(np.isfinite(V), axis=1))
    if not len(idx):
        return V, changed
    P, theta = X[idx, :2], X[idx, 2]
    want = np.remainder(np.arctan2(V[idx, 1], V[idx, 0]) - theta + np.pi, 2 * np.pi) - np.pi
    want = np.clip(want, -max_turn, max_turn)
    d = np.concatenate([want[:, None], np.broadcast_to(
        np.linspace(-max_turn, max_turn, CANDIDATES), (len(idx), CANDIDATES))], axis=1)
    x1, y1, th1 = _arc_end(P, theta, d, step)
    nx_, ny_ = -np.sin(th1), np.cos(th1)
    S = d.shape[1]
    Q = np.stack([np.stack([x1, y1], -1), np.stack([x1 + rho * nx_, y1 + rho * ny_], -1),
                  np.stack([x1 - rho * nx_, y1 - rho * ny_], -1)], axis=1)   # (m, 3, S, 2)
    owner = np.repeat(idx, 3 * S)
    c = clearance(Q.reshape(-1, 2), owner).reshape(len(idx), 3, S)
    need = radius[idx, None] + margin
    circle = np.maximum(c[:, 1], c[:, 2]) - rho
    ok = (c[:, 0] >= need) & (circle >= need)
    keep = ok[:, 0]                                   # the wanted change ends safe
    dist = np.abs(d - want[:, None])
    score = np.where(ok, -dist, -np.inf)
    best = np.argmax(score, axis=1)
    none = ~ok.any(axis=1)
    best[none] = np.argmax(np.where(np.isnan(circle[none]), -np.inf, circle[none]), axis=1)
    pick = theta + d[np.arange(len(idx)), best]
    fix = ~keep
    rows_fix = idx[fix]
    V[rows_fix] = speed * np.stack([np.cos(pick[fix]), np.sin(pick[fix])], axis=1)
    changed[rows_fix] = True
    return V, changed
