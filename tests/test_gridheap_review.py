"""Review reproducers for 9fdcb2a (the compiled grid heap search, hybridnav/native/gridheap.c).

Each test asserts the behaviour the commit claims (compiled search == Python loop: cells,
length bits, expanded) or, where both routes are wrong, the correct behaviour (a found path of
the optimal length, or a HybridnavError naming the resolution). All fail at 9fdcb2a.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hybridnav.errors import HybridnavError
from hybridnav.native import gridheap
from hybridnav.planners.path import gridsearch
from hybridnav.planners.path.gridsearch import astar, path_cost
from hybridnav.world.grid import OccupancyGrid

pytestmark = [pytest.mark.skipif(not gridheap.available(), reason="no compiled kernels here"),
              pytest.mark.filterwarnings("ignore::RuntimeWarning")]


def _outcome(fn):
    """A comparable summary of a search: the result's bits, or the exception's type and text."""
    try:
        p = fn()
    except Exception as exc:  # noqa: BLE001 -- the type is part of the outcome
        return ("raised", type(exc).__name__, str(exc))
    return (p.found, float(p.length).hex(), p.expanded, p.cells.tolist())


def _both(monkeypatch, fn):
    compiled = _outcome(fn)
    with monkeypatch.context() as m:
        m.setattr(gridheap, "_library", lambda: None)
        loop = _outcome(fn)
    return compiled, loop


def test_tiny_resolution_key_quantum_underflows_routes_disagree(monkeypatch):
    # q = res * 1e-9 underflows to 0.0 for res below ~2.5e-315: the Python loop raises a bare
    # ZeroDivisionError from `f // q`, the kernel divides by zero silently and returns a path.
    grid = OccupancyGrid(np.zeros((1, 2), dtype=bool), 1e-320)
    compiled, loop = _both(monkeypatch, lambda: astar(grid, (0, 0), (1, 0)))
    assert "ZeroDivisionError" not in (compiled[1], loop[1])
    assert compiled == loop


def test_huge_resolution_nan_keys_routes_disagree(monkeypatch):
    # res = 1e307: h overflows to inf far from the goal, f // q is nan, the heap order is no
    # longer total and heapq and the C heap pop differently (different cells and expanded).
    grid = OccupancyGrid(np.zeros((2, 18), dtype=bool), 1e307)
    compiled, loop = _both(monkeypatch, lambda: astar(grid, (0, 0), (17, 1), heuristic="euclidean"))
    assert compiled == loop


def test_huge_resolution_unreachable_expanded_differs(monkeypatch):
    grid = OccupancyGrid(np.zeros((2, 18), dtype=bool), 1e307)
    compiled, loop = _both(monkeypatch, lambda: astar(grid, (0, 0), (17, 1), heuristic="octile"))
    assert compiled == loop


def test_huge_resolution_reachable_goal_is_found_or_refused():
    # (both routes, pre-existing) the goal is reachable with a finite length (1.74e308) but the
    # nan keys close cells with too large a g, their successors overflow and found is False
    grid = OccupancyGrid(np.zeros((2, 18), dtype=bool), 1e307)
    best = path_cost(grid, [[i, 0] for i in range(17)] + [[17, 1]])
    assert np.isfinite(best)
    try:
        p = astar(grid, (0, 0), (17, 1), heuristic="octile")
    except HybridnavError as exc:
        assert "resolution" in str(exc)
    else:
        assert p.found and p.length == best


def test_float32_resolution_poisons_the_move_cost_cache_for_a_valid_grid():
    # _move_arrays is lru-cached on (Wp, res); np.float32(0.5) == 0.5 hashes alike, so a grid
    # whose resolution was set to np.float32(0.5) stores a float32 cost array that a valid grid
    # of the same width then gets: the kernel reads 64 bytes from a 32-byte buffer as doubles.
    gridsearch._move_arrays.cache_clear()
    gridsearch._move_table.cache_clear()
    occ = np.zeros((5, 9), dtype=bool)
    good = OccupancyGrid(occ, 0.5)
    ref = _outcome(lambda: astar(good, (0, 0), (8, 4)))
    gridsearch._move_arrays.cache_clear()
    gridsearch._move_table.cache_clear()
    other = OccupancyGrid(occ.copy(), 0.5)
    other.resolution = np.float32(0.5)
    astar(other, (0, 0), (8, 4))
    assert _outcome(lambda: astar(good, (0, 0), (8, 4))) == ref


def test_float32_resolution_kernel_reads_garbage_costs(monkeypatch):
    # a numpy float32 resolution (assigned after construction) gives the kernel a float32 cost
    # array it reads as doubles: length 5.2e-11 for a 0.807 path; expected: the search of
    # float(resolution), on both routes
    occ = np.zeros((6, 7), dtype=bool)
    grid = OccupancyGrid(occ, 1.0)
    grid.resolution = np.float32(0.1)
    plain = OccupancyGrid(occ, float(np.float32(0.1)))

    def fresh(fn):          # the move caches hold np.float32(0.1) == float(np.float32(0.1)) alike
        gridsearch._move_arrays.cache_clear()
        gridsearch._move_table.cache_clear()
        return fn()

    compiled, loop = _both(monkeypatch, lambda: fresh(lambda: astar(grid, (0, 0), (6, 5))))
    want = _outcome(lambda: fresh(lambda: astar(plain, (0, 0), (6, 5))))
    assert compiled == want
    assert loop == want


def test_scipy_route_with_float32_resolution_terminates():
    # HYBRIDNAV_NATIVE=0 (pre-existing scipy route): the parent walk never matches
    # dv[u] + cost == g(v) in float32 and loops forever, growing idx (7 GB after 11 min)
    code = textwrap.dedent("""
        import numpy as np
        from hybridnav.planners.path.gridsearch import dijkstra
        from hybridnav.world.grid import OccupancyGrid
        g = OccupancyGrid(np.zeros((6, 7), dtype=bool))
        g.resolution = np.float32(0.1)
        print(dijkstra(g, (0, 0), (6, 5)).found)
    """)
    env = dict(os.environ, HYBRIDNAV_NATIVE="0")
    try:
        proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail("dijkstra (scipy route) did not return within 30 s")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "True"
