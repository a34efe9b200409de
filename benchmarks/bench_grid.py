"""Grid planners on the MovingAI arena benchmark (Sturtevant 2012): speed and path length.

Part 1 -- optimal search. All 130 queries of ``arena.map.scen``, one after the other, with
``hybridnav.planners.path.gridsearch.astar`` and with ``networkx.astar_path`` on ``grid.to_networkx()``
(the same graph: octile moves, no corner cutting; the same octile heuristic). Each total is the best
of ``--repeat`` passes; building the networkx graph (once, shared by all queries) is reported
separately and not included in networkx's total. Also ``dijkstra``. Every length is checked
against the scen file's optimal length (largest difference printed).

Part 1b -- ``dijkstra`` against :func:`scipy.sparse.csgraph.dijkstra` on the same graph
(``grid.adjacency()``: octile moves, no corner cutting): on the arena's 130 queries and on two
400 x 400 grids (``--size``; one of rectangles, one of 20 % random blocked cells) with ``--pairs``
random start/goal pairs each. scipy's call is the natural one for a query, ``dijkstra(A,
indices=start)`` (all distances from the start; it has no goal to stop at), and, for reference,
the same with ``return_predecessors=True`` and the cell path read from them (hybridnav's output: it
returns the cell path, length and expanded count), and with ``limit=`` the optimal length (which
needs the answer in advance). Each variant's time is its best of ``--repeat`` passes over the
queries, the variants' passes alternating (the machine is shared). Graph builds are
timed once per grid and not counted in the per-query times (hybridnav caches its graph on the grid
object; scipy's adjacency is built by the caller); a second ratio adds each side's build spread
over the grid's queries. Lengths must equal scipy's exactly. The arena also times the same heap
search as a Python loop (``astar(..., heuristic="zero")`` with the compiled kernels off: the same
answer; ``dijkstra`` runs it compiled, ``hybridnav/native/gridheap.c``, and scipy's csgraph only
where no compiler is found).

Part 2 -- stochastic planners (``--runs``). Each entry of :data:`RUNNERS` maps a name to a function
``(grid, query, seed) -> path length``; it is run once per seed on every ``--every``-th query of
the selected ``--buckets``, and reported as time per run and path length / optimal length
(mean, max) and the number of runs that found no path. To compare another planner, add one
function to :data:`RUNNERS`; nothing else changes.

The planners ``rfd-pso`` and ``pso-ba`` run as whole planners (:func:`planner_runner`): the built-in
``arena`` scenario with the query's start and goal cell centres, its point-mass robot (radius 0.4
cells) driven in the closed loop, the map's cells as obstacles. A run's time is planning plus the
simulated drive (both planners plan inside or before that loop); its length is the *travelled*
path length when the robot reaches the goal (``inf`` otherwise). Travelled paths are continuous
(any-angle), so they can be shorter than the octile optimum: ratios below 1 are expected. A run
that raises counts as no path and the first error of each runner is printed.

Run: ``python benchmarks/bench_grid.py [--repeat 5] [--size 400] [--pairs 20] [--runs]
[--only rfd-slope] [--buckets 3 6 9 12] [--every 2] [--seeds 3]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable
from itertools import pairwise

import numpy as np

from hybridnav.planners.path.gridsearch import astar, dijkstra
from hybridnav.planners.path.planners import RFDPSOPlanner
from hybridnav.planners.path.rfd_core import rfd
from hybridnav.planners.psoba.planner import PSOBAPlanner
from hybridnav.world import builtin_data_path, load_scenario
from hybridnav.world.grid import (
    MovingAIQuery,
    OccupancyGrid,
    load_movingai_map,
    load_movingai_scen,
)

_S = math.sqrt(2.0) - 1.0


def load_arena() -> tuple[OccupancyGrid, list[MovingAIQuery]]:
    return load_movingai_map(builtin_data_path("arena.map")), load_movingai_scen(builtin_data_path("arena.map.scen"))


def octile(a: tuple[int, int], b: tuple[int, int]) -> float:
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return max(dx, dy) + _S * min(dx, dy)


def best_time(fn: Callable[[], list[float]], repeat: int) -> tuple[float, list[float]]:
    best, out = math.inf, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


# --------------------------------------------------------------------------------------------
# Part 1: A* against networkx
# --------------------------------------------------------------------------------------------


def bench_search(grid: OccupancyGrid, queries: list[MovingAIQuery], repeat: int) -> None:
    import networkx as nx

    t0 = time.perf_counter()
    G = grid.to_networkx()
    t_graph = time.perf_counter() - t0

    def nx_len(path: list[tuple[int, int]]) -> float:
        return sum(G[a][b]["weight"] for a, b in pairwise(path))

    runs = {
        "hybridnav astar": lambda: [astar(grid, q.start, q.goal).length for q in queries],
        "hybridnav dijkstra": lambda: [dijkstra(grid, q.start, q.goal).length for q in queries],
        "networkx astar_path": lambda: [nx_len(nx.astar_path(G, q.start, q.goal, heuristic=octile, weight="weight"))
                                        for q in queries],
    }
    opt = np.array([q.optimal_length for q in queries])
    times = {}
    print(f"arena.map: {grid.width}x{grid.height}, {int((~grid.occ).sum())} free cells, {len(queries)} queries; "
          f"best of {repeat} passes")
    print(f"  networkx graph build (once, not counted below): {t_graph * 1e3:7.2f} ms")
    for name, fn in runs.items():
        t, lengths = best_time(fn, repeat)
        times[name] = t
        err = float(np.max(np.abs(np.array(lengths) - opt)))
        print(f"  {name:<22} {t * 1e3:8.2f} ms total  {t / len(queries) * 1e6:8.1f} us/query   "
              f"max |length - optimal| = {err:.1e}")
    r = times["networkx astar_path"] / times["hybridnav astar"]
    print(f"  ratio networkx astar_path / hybridnav astar: {r:.2f}x")


# --------------------------------------------------------------------------------------------
# Part 1b: dijkstra against scipy.sparse.csgraph.dijkstra
# --------------------------------------------------------------------------------------------


def large_grids(size: int) -> dict[str, OccupancyGrid]:
    """Two ``size x size`` grids: rectangles on open ground, and 20 % random blocked cells."""
    rng = np.random.default_rng(2024)
    rooms = np.zeros((size, size), dtype=bool)
    for _ in range(size // 8):
        r, c = rng.integers(size, size=2)
        h, w = rng.integers(2, size // 10, size=2)
        rooms[r:r + h, c:c + w] = True
    return {"rectangles": OccupancyGrid(rooms), "20% random cells": OccupancyGrid(rng.random((size, size)) < 0.2)}


def random_pairs(grid: OccupancyGrid, n: int, seed: int = 0) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """``n`` start/goal cells drawn uniformly from the largest connected part of the free cells."""
    from scipy.sparse.csgraph import connected_components

    _, label = connected_components(grid.adjacency(), directed=False)
    free = np.flatnonzero(~grid.occ.ravel())
    big = free[label[free] == np.bincount(label[free]).argmax()]
    ends = np.random.default_rng(seed).choice(big, size=(n, 2))
    W = grid.width
    return [((int(a % W), int(a // W)), (int(b % W), int(b // W))) for a, b in ends]


def _python_loop(fn: Callable[[], float]) -> float:
    """``fn()`` with the compiled heap search off (gridsearch's Python loop runs)."""
    from hybridnav.native import gridheap

    real = gridheap._library
    gridheap._library = lambda: None
    try:
        return fn()
    finally:
        gridheap._library = real


def bench_vs_scipy(name: str, grid: OccupancyGrid, pairs, repeat: int, optimal: list[float] | None = None,
                   heap: bool = False) -> None:
    from scipy.sparse.csgraph import dijkstra as csgraph_dijkstra

    t0 = time.perf_counter()
    A = grid.adjacency()
    t_adj = time.perf_counter() - t0
    # hybridnav's graph build: a first query on a fresh copy of the grid, less that query's best time
    fresh = OccupancyGrid(grid.occ.copy(), grid.resolution, grid.origin)
    t0 = time.perf_counter()
    dijkstra(fresh, *pairs[0])
    t_first = time.perf_counter() - t0
    t_own_build = max(t_first - best_time(lambda: [dijkstra(fresh, *pairs[0])], 3)[0], 0.0)

    S = grid.cell_index([p[0] for p in pairs]).tolist()
    G = grid.cell_index([p[1] for p in pairs]).tolist()
    if optimal is None:
        optimal = [float(csgraph_dijkstra(A, indices=s)[g]) for s, g in zip(S, G)]

    def scipy_path(i: int) -> float:
        """What a caller of scipy writes for hybridnav's output: predecessors, then the cell path."""
        d, pred = csgraph_dijkstra(A, indices=S[i], return_predecessors=True)
        node, path = G[i], [G[i]]
        while node != S[i]:
            node = int(pred[node])
            path.append(node)
        flat = np.array(path[::-1])
        np.column_stack([flat % grid.width, flat // grid.width])
        return float(d[G[i]])

    ours, ref = "hybridnav dijkstra", "scipy dijkstra(A, indices=s)"
    runs = {
        ours: lambda i: dijkstra(grid, *pairs[i]).length,
        ref: lambda i: float(csgraph_dijkstra(A, indices=S[i])[G[i]]),
        "  ... with the path": scipy_path,
        "  ... limit=optimal length": lambda i: float(
            csgraph_dijkstra(A, indices=S[i], limit=optimal[i] + 1e-6)[G[i]]),
    }
    if heap:
        runs["heap search, Python loop"] = lambda i: _python_loop(
            lambda: astar(grid, *pairs[i], heuristic="zero").length)
    n = len(pairs)
    tot = dict.fromkeys(runs, math.inf)
    lengths: dict[str, list[float]] = {}
    for _ in range(repeat):  # passes of the variants alternate, so that load changes hit all alike
        for k, fn in runs.items():
            t0 = time.perf_counter()
            lengths[k] = [fn(i) for i in range(n)]
            tot[k] = min(tot[k], time.perf_counter() - t0)
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"{name}: {grid.width}x{grid.height}, {int((~grid.occ).sum())} free cells, {n} queries; best of "
          f"{repeat} passes, alternating; load {load}")
    print(f"  graph builds (once per grid, not counted below): grid.adjacency() {t_adj * 1e3:.1f} ms, "
          f"hybridnav's cached move masks {t_own_build * 1e3:.1f} ms")
    for k, t in tot.items():
        print(f"  {k:<30} {t / n * 1e6:10.1f} us/query")
    err = max(abs(a - b) for a, b in zip(lengths[ours], lengths[ref]))
    print(f"  ratio hybridnav dijkstra / scipy dijkstra: {tot[ours] / tot[ref]:.2f}x per query, "
          f"{(tot[ours] + t_own_build) / (tot[ref] + t_adj):.2f}x with each graph build spread over the {n} "
          f"queries ({tot[ours] / tot['  ... with the path']:.2f}x against scipy with the path, "
          f"{tot[ours] / tot['  ... limit=optimal length']:.2f}x against limit=optimal); "
          f"max |length - scipy's| = {err:.1e}")
    if heap:
        print(f"  speed-up over the Python loop: {tot['heap search, Python loop'] / tot[ours]:.1f}x")


# --------------------------------------------------------------------------------------------
# Part 2: stochastic planners, per run
# --------------------------------------------------------------------------------------------

def planner_runner(cls, **params) -> Callable[[OccupancyGrid, MovingAIQuery, int], float]:
    """A runner driving the robot of the ``arena`` scenario with a planner class on a query."""
    import dataclasses

    base = load_scenario("arena")
    errors: list[str] = []

    def run(grid: OccupancyGrid, q: MovingAIQuery, seed: int) -> float:
        robot = dataclasses.replace(base.robots[0], start=(q.start[0] + 0.5, q.start[1] + 0.5),
                                    goal=(q.goal[0] + 0.5, q.goal[1] + 0.5))
        scenario = dataclasses.replace(base, robots=[robot])
        try:
            r = cls(**params).run(scenario, seed=seed).robots[0]
        except Exception as exc:  # noqa: BLE001 -- a benchmark reports failures, never stops
            if not errors:
                print(f"  ({cls.name}: {q.start}->{q.goal}: {type(exc).__name__}: {exc}; such runs "
                      "count as no path)")
            errors.append(repr(exc))
            return math.inf
        return r.path_length if r.outcome == "reached" else math.inf

    return run


#: name -> function(grid, query, seed) returning the path length (inf when no path was found).
RUNNERS: dict[str, Callable[[OccupancyGrid, MovingAIQuery, int], float]] = {
    "rfd (flat, standard)": lambda grid, q, seed: rfd(grid, q.start, q.goal, seed=seed).length,
    "rfd (slope=0.01)": lambda grid, q, seed: rfd(grid, q.start, q.goal, seed=seed, slope=0.01).length,
    "rfd-pso": planner_runner(RFDPSOPlanner),
    "pso-ba": planner_runner(PSOBAPlanner),
}


def bench_runs(grid: OccupancyGrid, queries: list[MovingAIQuery], seeds: int, only: list[str] | None) -> None:
    print(f"stochastic planners: {len(queries)} queries x {seeds} seeds "
          f"(optimal lengths {min(q.optimal_length for q in queries):.1f}..{max(q.optimal_length for q in queries):.1f})")
    print(f"  {'planner':<24} {'time/run':>10} {'mean len/opt':>13} {'max len/opt':>12} {'no path':>8}")
    for name, fn in RUNNERS.items():
        if only and not any(o in name for o in only):
            continue
        times, ratios = [], []
        for q in queries:
            for seed in range(seeds):
                t0 = time.perf_counter()
                length = fn(grid, q, seed)
                times.append(time.perf_counter() - t0)
                ratios.append(length / q.optimal_length)
        rr = np.array(ratios)
        fin = rr[np.isfinite(rr)]
        mean = f"{fin.mean():.3f}" if fin.size else "-"
        mx = f"{fin.max():.3f}" if fin.size else "-"
        print(f"  {name:<24} {np.mean(times) * 1e3:8.1f} ms {mean:>13} {mx:>12} {int((~np.isfinite(rr)).sum()):>8}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="passes over the 130 queries (best is kept)")
    ap.add_argument("--size", type=int, default=400, help="side of the two large grids of part 1b")
    ap.add_argument("--pairs", type=int, default=20, help="random start/goal pairs on each large grid")
    ap.add_argument("--runs", action="store_true", help="also time the stochastic planners of RUNNERS")
    ap.add_argument("--only", nargs="+", help="run only the RUNNERS whose name contains one of these")
    ap.add_argument("--buckets", type=int, nargs="+", default=[3, 6, 9, 12],
                    help="scen buckets for part 2 (bucket b: optimal length in [4b, 4b+4))")
    ap.add_argument("--every", type=int, default=2, help="part 2 uses every n-th query of those buckets")
    ap.add_argument("--seeds", type=int, default=3, help="part 2 runs per query")
    args = ap.parse_args()
    grid, queries = load_arena()
    bench_search(grid, queries, args.repeat)
    print()
    bench_vs_scipy("arena.map", grid, [(q.start, q.goal) for q in queries], args.repeat,
                   [q.optimal_length for q in queries], heap=True)
    for name, big in large_grids(args.size).items():
        bench_vs_scipy(name, big, random_pairs(big, args.pairs), args.repeat)
    if args.runs:
        sel = [q for q in queries if q.bucket in args.buckets][::args.every]
        print()
        bench_runs(grid, sel, args.seeds, args.only)


if __name__ == "__main__":
    main()
