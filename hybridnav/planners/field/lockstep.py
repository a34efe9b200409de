"""Many copies of single-robot runs in lockstep: one batched model step per control cycle.

Offline tuning (the GA tuner, PBPF's bacterial search) evaluates a population of controllers on
a few environments. :func:`lockstep_field` simulates every (environment, member) pair at once:
each control cycle is one vectorized field evaluation per environment and **one** batched model
step for all robots, never a Python loop per individual per step. Outcomes follow
:func:`hybridnav.planners.simulate.simulate` (collided, out_of_bounds, reached, stuck, timeout).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hybridnav.errors import HybridnavError

__all__ = ["Batch", "LockstepResult", "finish", "lockstep_field", "prepare", "stuck_cycles"]

OUTCOME_CODES = ("running", "reached", "collided", "out_of_bounds", "stuck", "timeout")


@dataclass
class LockstepResult:
    """Per (environment, member) outcomes and metrics; arrays of shape ``(n_env, n_members)``."""

    outcome: np.ndarray          # str
    path_length: np.ndarray
    time: np.ndarray             # time to goal when reached, else the time the run ended
    min_clearance: np.ndarray
    final_distance: np.ndarray
    paths: list | None = None    # per environment: (n_members, steps + 1, 2), when recorded
    final_states: np.ndarray | None = None   # (n_env, n_members, nx): each robot's last state


def lockstep_field(
    scenarios: Sequence,
    n_members: int,
    field: Callable[[int, object, np.ndarray, np.ndarray, np.ndarray, float], np.ndarray],
    *,
    model_overrides: dict | None = None,
    speed: float = 0.1,
    stuck_window: float = 10.0,
    stuck_radius: float = 2.0,
    record_paths: bool = False,
    stack=None,
    field_state: bool = False,
    safety: dict | None = None,
) -> LockstepResult:
    """Simulate ``n_members`` controllers on each single-robot scenario, all in lockstep.

    Parameters
    ----------
    scenarios : sequence of Scenario
        Each with exactly one robot and a fixed goal; their robots must share one model (same
        name, parameters and ``dt``) so that one compiled batched step serves all.
    n_members : int
        Copies per scenario (the population).
    field : callable
        ``field(env, members, P, goals, t) -> V``: desired velocities ``(m, 2)`` of the
        still-running robots, given their environment indices ``env`` (m,), their members
        (indices into the population) and positions ``P`` (m, 2) — one call per control cycle
        for the whole batch.
        A NaN row means "local minimum": the robot is ``stuck``; a zero row (balanced forces)
        keeps the robot's previous command, as :class:`hybridnav.planners.field.base.FieldPlanner`
        does.
    model_overrides : dict, optional
        Options for the robot model (e.g. the unicycle heading controller).
    speed : float
        The velocity's length (the field gives the direction).
    stuck_window, stuck_radius :
        No-progress test: seconds, and a radius in goal radii.
    record_paths : bool
        Also return every robot's positions per control cycle (for plots; costs memory).
    stack : WorldStack, optional
        The scenarios' worlds packed (:class:`hybridnav.planners.field.worldstack.WorldStack`); built
        here when not given. Collision and bounds tests ask it for all robots at once.
    field_state : bool
        Pass the robots' whole states ``(m, nx)`` (x, y, heading, ...) to ``field`` instead of
        their positions (controllers that steer relative to the heading).
    safety : dict, optional
        ``{"margin": m, "max_turn": a}`` with ``m > 0``: the escape-circle safety filter
        (:mod:`hybridnav.planners.field.safety`) on the commands of heading-controlled robots.
    """
    b = prepare(scenarios, n_members, model_overrides, stack)
    model, stack, N, dt, steps = b.model, b.stack, b.N, b.dt, b.steps
    budget, env, member, goals, goal_r, X = b.budget, b.env, b.member, b.goals, b.goal_r, b.X
    status = np.zeros(N, dtype=int)              # index into OUTCOME_CODES
    last = np.zeros((N, 2))                      # last non-zero command per robot
    length = np.zeros(N)
    t_end = np.full(N, np.nan)
    min_clear = np.full(N, np.inf)
    window = stuck_cycles(stuck_window, dt, steps)
    ring = np.zeros((window + 1, N, 2)) if window else None
    paths = np.zeros((N, steps + 1, 2)) if record_paths else None
    if record_paths:
        paths[:, 0] = X[:, :2]
    _check(stack, model, env, X, 0.0, status, min_clear, t_end, goals, goal_r)
    filtering = bool(safety and safety.get("margin", 0) > 0
                     and getattr(model, "options", {}).get("controller") == "heading")
    if filtering:
        from hybridnav.planners.field.safety import escape_filter
    for k in range(steps):
        run = status == 0
        if not run.any():
            break
        t = k * dt
        V = np.zeros((N, 2))
        sel = np.flatnonzero(run)
        V[sel] = field(env[sel], member[sel], X[sel] if field_state else X[sel, :2],
                       goals[sel], t)
        norm = np.hypot(V[:, 0], V[:, 1])
        dead = run & np.isnan(norm)              # NaN: the field says "local minimum"
        status[dead] = OUTCOME_CODES.index("stuck")
        t_end[dead] = t
        V = V * (speed / np.where(norm > 0, norm, 1.0))[:, None]
        zero = ~(norm > 0)                       # balanced forces keep the previous command
        V[zero] = last[zero]
        last[~zero] = V[~zero]
        run = status == 0
        if filtering:
            sel = np.flatnonzero(run)
            V[sel], _ = escape_filter(
                X[sel], V[sel], speed=speed, dt=dt, max_turn=safety["max_turn"],
                margin=safety["margin"], radius=np.full(len(sel), model.radius),
                clearance=lambda Q, rows, t=t: np.minimum(
                    stack.clearance(Q, env[sel][rows], t),
                    stack.border_clearance(Q, env[sel][rows])))
        Xn = model.step(X, model.carrot(X, V))
        step_len = np.hypot(*(Xn[:, :2] - X[:, :2]).T)
        length[run] += step_len[run]
        X[run] = Xn[run]
        tn = (k + 1) * dt
        if record_paths:
            paths[:, k + 1] = X[:, :2]
        _check(stack, model, env, X, tn, status, min_clear, t_end, goals, goal_r, run)
        if window:
            ring[(k + 1) % (window + 1)] = X[:, :2]
            if k + 1 >= window:
                # the full test only where it can hold: a window that fits in a disk of radius
                # r starts and ends within 2 r of each other
                oldest = ring[(k + 2) % (window + 1)]
                cand = np.flatnonzero((status == 0) & (np.hypot(*(X[:, :2] - oldest).T)
                                                       < 2 * stuck_radius * goal_r))
                if len(cand):
                    w = ring[:, cand]
                    span = np.max(np.hypot(*(w - w.mean(axis=0)).transpose(2, 0, 1)), axis=0)
                    stuck = cand[span < stuck_radius * goal_r[cand]]
                    status[stuck] = OUTCOME_CODES.index("stuck")
                    t_end[stuck] = tn
        over = (status == 0) & (k + 1 >= budget)
        status[over] = OUTCOME_CODES.index("timeout")
        t_end[over] = tn
    return finish(b, status, length, t_end, min_clear, paths)

@dataclass
class Batch:
    """The robots of a lockstep run, row ``n = env * M + member`` (what :func:`prepare` sets
    up; the NumPy loop and the compiled control cycle start from it)."""

    scenarios: Sequence
    model: object
    stack: object
    E: int
    M: int
    N: int
    dt: float
    steps: int
    budget: np.ndarray
    env: np.ndarray
    member: np.ndarray
    goals: np.ndarray
    goal_r: np.ndarray
    X: np.ndarray


def prepare(scenarios: Sequence, n_members: int, model_overrides: dict | None = None,
            stack=None) -> Batch:
    """Check the scenarios and lay out their robots (see :func:`lockstep_field`)."""
    if not scenarios:
        raise HybridnavError("scenarios: expected at least one training scenario")
    if stack is None:
        from hybridnav.planners.field.worldstack import WorldStack
        stack = WorldStack([s.world for s in scenarios])
    # a stack kept by the caller (a tuning job's training set) keeps the checked layout too:
    # building 40 models and their start states costs ~0.1 s per call otherwise
    key = (tuple(id(s) for s in scenarios), repr(sorted((model_overrides or {}).items())))
    cache = stack.__dict__.setdefault("_lockstep_layout", {})
    if key not in cache:
        cache[key] = (list(scenarios), *_layout(scenarios, model_overrides))
    _, model, X0, goals0, goal_r0, budget0 = cache[key]
    E, M = len(scenarios), int(n_members)
    N = E * M
    dt = model.dt
    steps = int(math.ceil(max(s.max_time for s in scenarios) / dt - 1e-9))
    budget = np.repeat(budget0, M)
    env = np.repeat(np.arange(E), M)
    member = np.tile(np.arange(M), E)
    goals = np.repeat(goals0, M, axis=0)
    goal_r = np.repeat(goal_r0, M)
    X = np.repeat(X0, M, axis=0)
    return Batch(list(scenarios), model, stack, E, M, N, dt, steps, budget, env, member, goals,
                 goal_r, X)


def _layout(scenarios: Sequence, model_overrides: dict | None):
    """The checked model and each scenario's start state, goal, goal radius and step budget."""
    models = []
    for s in scenarios:
        if len(s.robots) != 1 or s.robots[0].goal is None:
            raise HybridnavError(
                f"{s.source or s.name}: robots: lockstep training needs exactly one robot with a "
                "fixed goal")
        models.append(s.model(s.robots[0], **(model_overrides or {})))
    model = models[0]
    if any(m._key() != model._key() for m in models):
        raise HybridnavError(
            "scenarios: the training scenarios' robots must share one model, its parameters and "
            "dt (one batched step serves them all)")
    dt = model.dt
    budget = np.array([int(math.ceil(s.max_time / dt - 1e-9)) for s in scenarios])
    goals = np.array([s.robots[0].goal for s in scenarios], dtype=float).reshape(-1, 2)
    goal_r = np.array([s.robots[0].goal_radius for s in scenarios], dtype=float)
    X0 = np.vstack([model.initial_state(s.robots[0].start, s.robots[0].goal, s.robots[0].initial)
                    for s in scenarios])
    return model, X0, goals, goal_r, budget


def finish(b: Batch, status: np.ndarray, length: np.ndarray, t_end: np.ndarray,
           min_clear: np.ndarray, paths: np.ndarray | None) -> LockstepResult:
    """The result of a run whose loop has ended: robots still running time out."""
    left = status == 0
    status[left] = OUTCOME_CODES.index("timeout")
    t_end[left] = b.steps * b.dt
    shape = (b.E, b.M)
    return LockstepResult(
        outcome=np.array(OUTCOME_CODES, dtype=object)[status].reshape(shape),
        path_length=length.reshape(shape), time=t_end.reshape(shape),
        min_clearance=min_clear.reshape(shape),
        final_distance=np.hypot(*(b.X[:, :2] - b.goals).T).reshape(shape),
        paths=None if paths is None else [paths[b.env == e] for e in range(b.E)],
        final_states=b.X.reshape(b.E, b.M, -1).copy(),
    )


def stuck_cycles(stuck_window: float, dt: float, steps: int) -> int:
    """The no-progress window in control cycles (0: no test). A window longer than the run can
    never be tested; it is cut to ``steps + 1`` cycles (the same outcome, no ring buffer of the
    window's length)."""
    if not stuck_window > 0:
        return 0
    return int(round(min(stuck_window / dt, steps + 1)))


def _check(stack, model, env, X, t, status, min_clear, t_end, goals, goal_r, which=None):
    """Collision / bounds / goal tests at time ``t`` for the robots in ``which``, all
    environments at once."""
    which = (status == 0) if which is None else which & (status == 0)
    sel = np.flatnonzero(which)
    if not len(sel):
        return
    centers, radii = model.footprint(X[sel])
    m = len(radii)
    flat = centers.reshape(-1, 2)
    env_f = np.repeat(env[sel], m)
    clear = (stack.clearance(flat, env_f, t).reshape(len(sel), m) - radii[None]).min(axis=1)
    min_clear[sel] = np.minimum(min_clear[sel], clear)
    inside = (stack.border_clearance(flat, env_f) >= float(radii.max())).reshape(
        len(sel), m).all(axis=1)
    reached = np.hypot(*(X[sel, :2] - goals[sel]).T) <= goal_r[sel]
    code = np.where(clear < 0, OUTCOME_CODES.index("collided"),
                    np.where(~inside, OUTCOME_CODES.index("out_of_bounds"),
                             np.where(reached, OUTCOME_CODES.index("reached"), 0)))
    ended = code > 0
    status[sel[ended]] = code[ended]
    t_end[sel[ended]] = t
