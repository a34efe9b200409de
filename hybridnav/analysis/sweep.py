"""Closed-loop sweeps: simulate a grid of initial conditions and tabulate how ``V`` behaves."""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import casadi as cs
import numpy as np
import pandas as pd

from hybridnav.analysis.lyapunov import lyapunov_functions
from hybridnav.models.base import Model
from hybridnav.models.compile import evaluate_rows

__all__ = ["closed_loop_sweep", "grid_starts"]


def grid_starts(model: Model, target: Sequence[float], positions: np.ndarray,
                initial: Mapping[str, Sequence[float]]) -> tuple[np.ndarray, pd.DataFrame]:
    """Every combination of start positions and initial-state values, as model states.

    Parameters
    ----------
    model : Model
    target : (float, float)
        The target every start drives to.
    positions : ndarray, shape (P, 2)
    initial : dict
        State name -> values to combine (e.g. ``{"theta0": [...], "theta1": [...]}``); a value
        list given for ``"theta1"`` as the string ``"theta0"`` copies ``theta0`` (aligned trailer).

    Returns
    -------
    X0 : ndarray, shape (N, nx)
        With controller states set for ``target`` (:meth:`Model.retarget`).
    starts : DataFrame
        One row per start: ``x0, y0`` and the initial values.
    """
    names = list(initial)
    value_lists = [initial[n] for n in names if not isinstance(initial[n], str)]
    free = [n for n in names if not isinstance(initial[n], str)]
    rows, X0 = [], []
    for (px, py), combo in itertools.product(np.asarray(positions, float),
                                             itertools.product(*value_lists)):
        vals = dict(zip(free, combo))
        for n in names:
            if isinstance(initial[n], str):
                vals[n] = vals[initial[n]]
        X0.append(model.initial_state((px, py), target, vals))
        rows.append({"x0": px, "y0": py, **vals})
    return np.array(X0), pd.DataFrame(rows)


def closed_loop_sweep(
    model: Model,
    X0: np.ndarray,
    *,
    target: Sequence[float],
    steps: int,
    V=None,
    goal_radius: float = 0.5,
    jackknife: float = 0.9 * math.pi / 2,
) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """Simulate a batch of closed-loop runs and tabulate ``V`` along each.

    Columns of the table: ``reached`` (came within ``goal_radius``, as a planner's robot stops
    there), ``ended_within`` (still within it at the end), ``final_distance``, ``time_to_goal``
    (first time within ``goal_radius``; NaN exactly when not ``reached``), ``V_monotone`` (``V``
    never increased by more than rounding from one step to the next), ``first_increase_t`` and
    ``max_V_increase`` (the largest rise of ``V`` above its running minimum, relative to
    ``V(0)``; positive exactly when ``V_monotone`` is false), and, for models with ``theta0`` and ``theta1``, ``max_gap`` (largest
    ``|theta0 - theta1|``, wrapped) and ``jackknife`` (``max_gap >= jackknife``).

    Parameters
    ----------
    model : Model
    X0 : ndarray, shape (N, nx)
        Start states.
    target : (float, float)
    steps : int
        Control cycles per run.
    V : casadi.SX, callable or None
        The tabulated function (None: the model's Lyapunov candidate).
    goal_radius : float
        Distance that counts as reached.
    jackknife : float
        Hitch angle (rad) that counts as jackknifed (tractor-trailer).

    Returns
    -------
    table : DataFrame
    traj : ndarray, shape (N, steps + 1, nx)
    Vt : ndarray, shape (N, steps + 1)
    """
    X0 = np.asarray(X0, dtype=float)
    tgt = np.tile(np.asarray(target, dtype=float), (len(X0), 1))
    traj = model.rollout(X0, tgt, steps)
    _, v_num, _, _, _ = lyapunov_functions(model, V, target=target)
    flat = traj.reshape(-1, model.nx)
    Vt = evaluate_rows(cs.Function("V", [model.sym.x], [v_num]), flat)[0]
    Vt = Vt.reshape(len(X0), -1)
    t = np.arange(steps + 1) * model.dt
    dist = np.hypot(traj[..., 0] - target[0], traj[..., 1] - target[1])
    inside = dist <= goal_radius
    first = np.where(inside.any(axis=1), np.argmax(inside, axis=1), -1)
    dV = np.diff(Vt, axis=1)
    slack = 1e-9 * np.maximum(Vt[:, :1], 1e-300)
    up = dV > slack
    first_up = np.where(up.any(axis=1), np.argmax(up, axis=1), -1)
    rise = np.max(Vt - np.minimum.accumulate(Vt, axis=1), axis=1)
    table = pd.DataFrame({
        "reached": first >= 0,
        "ended_within": dist[:, -1] <= goal_radius,
        "final_distance": dist[:, -1],
        "time_to_goal": np.where(first >= 0, t[np.maximum(first, 0)], np.nan),
        "V_monotone": ~up.any(axis=1),
        "first_increase_t": np.where(first_up >= 0, t[np.maximum(first_up, 0)], np.nan),
        "max_V_increase": np.where(up.any(axis=1), rise, 0.0) / np.maximum(Vt[:, 0], 1e-300),
    })
    if {"theta0", "theta1"} <= set(model.state_names):
        i0, i1 = model.state_names.index("theta0"), model.state_names.index("theta1")
        gap = np.abs(np.arctan2(np.sin(traj[..., i0] - traj[..., i1]),
                                np.cos(traj[..., i0] - traj[..., i1])))
        table["max_gap"] = gap.max(axis=1)
        table["jackknife"] = table["max_gap"] >= jackknife
    return table, traj, Vt
