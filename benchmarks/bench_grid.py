"""Grid planners on the MovingAI arena benchmark (Sturtevant 2012): speed and path length.

Part 1 -- optimal search. All 130 queries of ``arena.map.scen``, one after the other, with
``hybridnav.planners.path.gridsearch.astar`` and with ``networkx.astar_path`` on ``grid.to_networkx()``
(the same graph: octile moves, no corner cutting; the same octile heuristic). Each total is the best
of ``--repeat`` passes; building the networkx graph (once, shared by all queries) is reported
separately and not included in networkx's total. Also ``dijkstra``. Every length is checked
against the scen file's optimal length (largest difference printed).

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

Run: ``python benchmarks/bench_grid.py [--repeat 5] [--runs] [--only rfd-slope]
[--buckets 3 6 9 12] [--every 2] [--seeds 3]``.
"""

from __future__ import annotations

import argparse
import math
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
    ap.add_argument("--runs", action="store_true", help="also time the stochastic planners of RUNNERS")
    ap.add_argument("--only", nargs="+", help="run only the RUNNERS whose name contains one of these")
    ap.add_argument("--buckets", type=int, nargs="+", default=[3, 6, 9, 12],
                    help="scen buckets for part 2 (bucket b: optimal length in [4b, 4b+4))")
    ap.add_argument("--every", type=int, default=2, help="part 2 uses every n-th query of those buckets")
    ap.add_argument("--seeds", type=int, default=3, help="part 2 runs per query")
    args = ap.parse_args()
    grid, queries = load_arena()
    bench_search(grid, queries, args.repeat)
    if args.runs:
        sel = [q for q in queries if q.bucket in args.buckets][::args.every]
        print()
        bench_runs(grid, sel, args.seeds, args.only)


if __name__ == "__main__":
    main()
