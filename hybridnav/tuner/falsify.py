"""Looking for failures before a user does: a swarm search for worlds where a system fails.

A world of the generator's class is a vector ``x = (sx, sy, gx, gy, theta, (cx, cy, r) * n,
(on, s, lateral, a, b) * m)``: start, goal, initial heading (an offset from the goal direction,
within the generator's ``heading_jitter``), ``n`` circles and ``m`` structures that trap reactive
controllers (:data:`STRUCTURES`: cups facing the start, corridors, narrow gaps; each present when
its ``on`` gene is >= 0.5, centred ``s`` of the way from start to goal and ``lateral`` off the
line, sized ``a``, ``b`` within the generator's ranges). :func:`falsify` minimizes, with one of the
project's swarm optimizers (:mod:`hybridnav.planners.swarm`; PSO by default), *minus* the
deploy cost of the system in that world (:meth:`NavigationCost.run_costs`: a collision
costs more than getting stuck, which costs more than any detour) — so the search climbs towards
collisions, then traps. Every candidate world obeys the generator's rules: circles that would
overlap the start or goal footprint (plus ``margin``) or leave a gap narrower than ``min_gap``
are dropped, start and goal are at least ``min_distance`` apart, and the world must be
solvable (:func:`hybridnav.world.generator.solvable`); a candidate breaking a rule scores ``+inf``.
Each swarm iteration simulates all its worlds in one lockstep batch.

The worst distinct worlds where the system did not reach its goal are kept (sorted by cost),
ready to be written as scenario TOML files. The searched system is a fuzzy system (run by the
cost's planner) or ``"apf"`` (the plain potential field with the cost's planner settings), so
that a tuned system, its start and the simplest baseline can be searched with the same budget
and seed and their failure and collision rates compared (:func:`falsify_systems`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

from hybridnav.world.generator import WorldGenerator, _no_narrow_gap, _shape, solvable

__all__ = ["FalsifyResult", "falsify", "falsify_systems", "rates", "world_from_vector"]

#: the structures a search vector can hold: (the generator's two size ranges, its parts)
STRUCTURES = {"cups": ("cup_width", "cup_depth"),
              "corridors": ("corridor_width", "corridor_length"),
              "gaps": ("gap_width", "gap_wall")}

#: outcomes that count as collisions (touching an obstacle or leaving the workspace)
CRASH = ("collided", "out_of_bounds")


@dataclass
class FalsifyResult:
    """The worlds found (worst first), how many candidates were tried and how many were valid."""

    worlds: list = field(default_factory=list)      # Scenario
    costs: list[float] = field(default_factory=list)
    outcomes: list[str] = field(default_factory=list)
    clearances: list[float] = field(default_factory=list)
    evaluations: int = 0
    valid: int = 0
    failures: int = 0                                # valid worlds where the system failed
    collisions: int = 0                              # ... by colliding or leaving the workspace


def _structures(structures: dict[str, int] | None) -> list[str]:
    """The structure kinds of a search vector, in order (``{"cups": 1}`` -> ``["cups"]``)."""
    from hybridnav.errors import HybridnavError

    out = []
    for kind, count in (structures or {}).items():
        if kind not in STRUCTURES:
            raise HybridnavError(f"falsify: structures.{kind}: unknown; expected one of "
                                 + ", ".join(STRUCTURES))
        if not isinstance(count, int) or isinstance(count, bool) or not 0 <= count <= 10:
            raise HybridnavError(f"falsify: structures.{kind}: expected an integer in [0, 10], "
                                 f"got {count!r}")
        out += [kind] * count
    return out


def bounds(gen: WorldGenerator, n: int, structures: dict[str, int] | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """The search box of worlds with ``n`` circles and ``structures`` (kind -> count).

    Start and goal range over the generator's own span (``0.15 size - jitter`` to ``0.85 size +
    jitter`` for the diagonal layout, the whole workspace less the robot radius otherwise); the
    heading is an offset from the goal direction within ``heading_jitter`` when the generator
    heads the robot at its goal, else any angle.
    """
    L, r = gen.size, gen.robot_radius
    if gen.layout == "diagonal":
        a, b = max(r, 0.15 * L - gen.jitter), min(L - r, 0.85 * L + gen.jitter)
    else:
        a, b = r, L - r
    h = gen.heading_jitter if gen.heading == "goal" else math.pi
    lo = [a, a, a, a, -h] + [0.0, 0.0, gen.radius[0]] * n
    hi = [b, b, b, b, h] + [L, L, gen.radius[1]] * n
    for kind in _structures(structures):
        ra, rb = (getattr(gen, k) for k in STRUCTURES[kind])
        lo += [0.0, 0.35, -gen.lateral, ra[0], rb[0]]
        hi += [1.0, 0.65, gen.lateral, ra[1], rb[1]]
    return np.array(lo), np.array(hi)


def _structure_parts(kind: str, g: np.ndarray, start: np.ndarray, goal: np.ndarray
                     ) -> list[dict]:
    from hybridnav.world.generator import corridor_parts, cup_parts, gap_parts

    along = goal - start
    u = along / max(float(np.hypot(*along)), 1e-12)
    c = start + g[1] * along + g[2] * np.array([-u[1], u[0]])
    if kind == "cups":
        return cup_parts(c, u, g[3], g[4])
    if kind == "corridors":
        return corridor_parts(c, u, g[3], g[4])
    return gap_parts(c, u, g[3], g[4], g[4])


def world_from_vector(x: np.ndarray, gen: WorldGenerator, name: str,
                      structures: dict[str, int] | None = None):
    """The scenario of one search vector, or None when it breaks the generator's rules (a
    structure that is on must fit: clear of start and goal, no narrow gap to what is placed;
    a circle that breaks a rule is left out)."""
    from hybridnav.errors import HybridnavError
    from hybridnav.world import scenario_from_dict

    x = np.asarray(x, dtype=float)
    start, goal, theta = x[0:2], x[2:4], float(x[4])
    if gen.heading == "goal":                  # an offset from the direction to the goal
        theta = math.remainder(math.atan2(goal[1] - start[1], goal[0] - start[0]) + theta,
                               2 * math.pi)
    if math.dist(start, goal) < gen.min_distance:
        return None
    keep = gen.robot_radius + gen.margin
    obstacles, placed = [], []
    kinds = _structures(structures)
    ncirc = (len(x) - 5 - 5 * len(kinds)) // 3
    genes = x[5 + 3 * ncirc:].reshape(-1, 5)
    for kind, g in zip(kinds, genes):
        if g[0] < 0.5:
            continue
        parts = _structure_parts(kind, g, start, goal)
        shapes = [_shape(o) for o in parts]
        if not all(np.all(sh.clearance(np.array([start, goal])) >= keep) for sh in shapes):
            return None
        if gen.min_gap > 0 and not all(_no_narrow_gap(sh, placed, gen.size, gen.min_gap)
                                       for sh in shapes):
            return None
        obstacles += parts
        placed += shapes
    for c in x[5:5 + 3 * ncirc].reshape(-1, 3):
        obs = {"type": "circle", "center": [float(c[0]), float(c[1])], "radius": float(c[2])}
        shape = _shape(obs)
        if np.any(shape.clearance(np.array([start, goal])) < keep):
            continue
        if gen.min_gap > 0 and not _no_narrow_gap(shape, placed, gen.size, gen.min_gap):
            continue
        obstacles.append(obs)
        placed.append(shape)
    data = {
        "name": name, "description": "found by hybridnav's falsification search",
        "units": "m", "dt": gen.dt, "max_time": gen.max_time,
        "workspace": {"xmin": 0.0, "xmax": gen.size, "ymin": 0.0, "ymax": gen.size},
        "obstacles": obstacles,
        "robots": [{"name": "robot", "model": "unicycle",
                    "start": [float(start[0]), float(start[1])],
                    "goal": [float(goal[0]), float(goal[1])], "goal_radius": gen.goal_radius,
                    "radius": gen.robot_radius, "initial": {"theta": theta}}],
    }
    try:
        scen = scenario_from_dict(data, source=f"falsification world {name}")
    except HybridnavError:
        return None
    return scen if solvable(scen, gen.resolution) else None


def falsify(cost, system, *, budget: int = 600, population: int = 30,
            obstacles: int = 6, keep: int = 5, optimizer: str = "pso",
            generator: WorldGenerator | None = None, seed: int = 0,
            progress=None, structures: dict[str, int] | None = None) -> FalsifyResult:
    """Search worlds where ``system`` fails.

    Parameters
    ----------
    cost : NavigationCost
        Its planner, planner settings and reward define the search's cost.
    system : FuzzySystem or "apf"
        The controller searched: a fuzzy system run by the cost's planner, or the plain
        ``apf`` planner with the cost's planner settings (:func:`hybridnav.tuner.heldout.baseline`:
        without the safety filter).
    budget : int
        Candidate worlds to try in all (the swarm's ``max_evals``).
    population : int
        Swarm size (worlds simulated together per iteration).
    obstacles : int
        Circles per world.
    keep : int
        Worlds to return (the worst distinct failures).
    optimizer : str
        A name of :data:`hybridnav.planners.swarm.OPTIMIZERS`.
    generator : WorldGenerator, optional
        The world class (sizes, radii, robot, margins); default EFFC scale with a coarser
        solvability grid (0.05).
    seed : int
        Seeds the swarm.
    progress : callable, optional
        ``progress(evaluated, budget)`` after each swarm iteration.
    structures : dict, optional
        Structures in the search space, kind (``cups``, ``corridors``, ``gaps``) -> count; the
        search switches each on or off.
    """
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.planners.swarm import minimize

    from hybridnav.params import check_value

    keep = check_value("falsify: ", "keep", keep, int, 0)
    budget = check_value("falsify: ", "budget", budget, int, 1)
    population = check_value("falsify: ", "population", population, int, 2)
    if budget < population:
        from hybridnav.errors import HybridnavError

        raise HybridnavError(f"falsify: budget: expected at least the population ({population} "
                             f"worlds: the search's first iteration), got {budget}")
    if isinstance(system, str):
        if system != "apf":
            from hybridnav.errors import HybridnavError

            raise HybridnavError(f"falsify: system: expected a FuzzySystem or 'apf', got "
                                 f"{system!r}")
        from hybridnav.planners.field.apf import apf_lockstep
        from hybridnav.tuner.heldout import baseline

        def simulate(on):
            return apf_lockstep(on.packed, baseline(dict(on.planner_params)))
    else:
        family = SystemFamily(system)
        tables = family.tables_of([system])

        def simulate(on):
            return on.simulate(family, tables, None, noise=False)[0]
    gen = generator or WorldGenerator(resolution=0.05)
    lo, hi = bounds(gen, obstacles, structures)
    seen: list[tuple[float, Any, str, float]] = []
    count = {"evals": 0, "valid": 0, "fail": 0, "crash": 0}

    def f(X: np.ndarray) -> np.ndarray:
        out = np.full(len(X), np.inf)
        worlds, rows = [], []
        for i, x in enumerate(X):
            w = world_from_vector(x, gen, f"falsified-{count['evals'] + i:04d}", structures)
            if w is not None:
                worlds.append(w)
                rows.append(i)
        count["evals"] += len(X)
        if worlds:
            on = cost.with_scenarios(worlds, "falsification")
            res = simulate(on)
            value = on.run_costs(res)[:, 0]
            out[rows] = -value
            count["valid"] += len(worlds)
            for w, c, o, cl in zip(worlds, value, res.outcome[:, 0], res.min_clearance[:, 0]):
                if o != "reached":
                    count["fail"] += 1
                    count["crash"] += o in CRASH
                    seen.append((float(c), w, str(o), float(cl)))
        if progress:
            progress(count["evals"], budget)
        return out

    minimize(optimizer, f, (lo, hi), n=population, iterations=None, max_evals=budget,
             seed=seed)
    seen.sort(key=lambda t: -t[0])
    res = FalsifyResult(evaluations=count["evals"], valid=count["valid"],
                        failures=count["fail"], collisions=count["crash"])
    kept: list = []
    for c, w, o, cl in (seen if keep else []):
        if any(_same(w, k) for k in kept):
            continue
        kept.append(w)
        res.worlds.append(w)
        res.costs.append(c)
        res.outcomes.append(o)
        res.clearances.append(cl)
        if len(kept) == keep:
            break
    return res


def falsify_systems(cost, systems: dict[str, Any], *, seed: int = 0, backend=None,
                    **kwargs: Any) -> dict[str, FalsifyResult]:
    """:func:`falsify` of every system (label -> ``FuzzySystem`` or ``"apf"``) with the same
    budget, swarm, world class and seed: their failure and collision rates compare (each search
    is driven by its own system's failures, as an adversary would be).

    The searches are independent: given a ``backend`` (:mod:`hybridnav.backends`) they run on
    its workers, one search per task (the same results: each depends on its seed only); a
    ``progress`` callback keeps them in this process.
    """
    from hybridnav.backends import SerialBackend

    labels = list(systems)
    if backend is None or isinstance(backend, SerialBackend) or len(labels) < 2 \
            or kwargs.get("progress") is not None:
        return {label: falsify(cost, systems[label], seed=seed, **kwargs) for label in labels}
    found = backend.map(_falsify_one, [(cost, systems[label], seed, kwargs) for label in labels])
    return dict(zip(labels, found))


def _falsify_one(cost, system, seed: int, kwargs: dict[str, Any]) -> FalsifyResult:
    """One search of :func:`falsify_systems` (in whatever process gets it)."""
    return falsify(cost, system, seed=seed, **kwargs)


def rates(results: dict[str, FalsifyResult]) -> "pd.DataFrame":
    """Per searched system: valid worlds, failures and collisions with their rates and 95 %
    Wilson intervals."""
    import pandas as pd

    from hybridnav.tuner.heldout import wilson

    rows = []
    for label, r in results.items():
        row: dict[str, Any] = {"system": label, "tried": r.evaluations, "valid": r.valid}
        for key, k in (("failures", r.failures), ("collisions", r.collisions)):
            lo, hi = wilson(k, r.valid)
            row.update({key: k, f"{key}_rate": k / r.valid if r.valid else math.nan,
                        f"{key}_ci_low": lo, f"{key}_ci_high": hi})
        rows.append(row)
    return pd.DataFrame(rows)


def _same(a, b, tol: float = 0.05) -> bool:
    """Two worlds are the same find when start, goal and obstacles differ by less than tol."""
    ra, rb = a.robots[0], b.robots[0]
    if math.dist(ra.start, rb.start) > tol or math.dist(ra.goal, rb.goal) > tol:
        return False
    ca, cb = sorted(map(_numbers, a.world.obstacles)), sorted(map(_numbers, b.world.obstacles))
    return len(ca) == len(cb) and all(
        p[0] == q[0] and len(p) == len(q) and max(abs(u - v) for u, v in zip(p[1:], q[1:])) <= tol
        for p, q in zip(ca, cb))


def _numbers(o) -> tuple:
    """An obstacle of a search world as (kind, numbers...): circles and segments."""
    if hasattr(o, "center"):
        return (0, *o.center, o.radius)
    return (1, *o.a, *o.b)
