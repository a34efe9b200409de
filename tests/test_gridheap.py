"""The compiled heap search (hybridnav/native/gridheap.c) against the Python loop it runs for
(``gridsearch._search`` with the kernel off): the same cells, length and ``expanded`` exactly, for
every heuristic and move rule, resolutions whose costs round, ties, unreachable goals, start ==
goal and heaps that grow past their first allocation; and ``dijkstra``'s scipy route (taken where
no kernel is available) against the compiled search."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav.errors import HybridnavError
from hybridnav.native import gridheap
from hybridnav.planners.path import gridsearch
from hybridnav.planners.path.gridsearch import HEURISTICS, astar, dijkstra
from hybridnav.world.grid import OccupancyGrid

pytestmark = pytest.mark.skipif(not gridheap.available(), reason="no compiled kernels here")


def _same(a, b):
    assert (a.found, a.length, a.expanded, a.method, a.params) == (
        b.found, b.length, b.expanded, b.method, b.params)
    np.testing.assert_array_equal(a.cells, b.cells)
    np.testing.assert_array_equal(a.points, b.points)
    assert a.cells.dtype == b.cells.dtype and a.cells.shape == b.cells.shape


def _grids(rng, count):
    for i in range(count):
        h, w = rng.integers(2, 40, size=2)
        density = rng.choice([0.0, 0.1, 0.25, 0.4])
        occ = rng.random((h, w)) < density
        res = float(rng.choice([1.0, 0.1, 0.37, 2.5]))
        yield OccupancyGrid(occ, res, (float(rng.normal()), float(rng.normal())))


def _free_pairs(rng, grid, k):
    free = np.argwhere(~grid.occ)
    if not len(free):
        return []
    pick = free[rng.integers(len(free), size=(k, 2))]
    return [((int(a[1]), int(a[0])), (int(b[1]), int(b[0]))) for a, b in pick]


def _python_loop(monkeypatch):
    monkeypatch.setattr(gridheap, "_library", lambda: None)


@pytest.mark.parametrize("heuristic", HEURISTICS)
def test_compiled_search_is_the_python_loop(monkeypatch, heuristic):
    rng = np.random.default_rng(HEURISTICS.index(heuristic))
    cases = []
    for grid in _grids(rng, 25):
        for diagonal, cc in ((True, False), (True, True), (False, False)):
            if heuristic == "manhattan" and diagonal:
                continue                        # refused: not admissible
            for s, t in _free_pairs(rng, grid, 4):
                cases.append((grid, s, t, diagonal, cc))
    got = [astar(g, s, t, heuristic=heuristic, diagonal=d, corner_cutting=c)
           for g, s, t, d, c in cases]
    _python_loop(monkeypatch)
    for (g, s, t, d, c), a in zip(cases, got):
        _same(a, astar(g, s, t, heuristic=heuristic, diagonal=d, corner_cutting=c))


def test_start_is_goal_unreachable_and_a_large_heap(monkeypatch):
    walled = np.zeros((30, 30), dtype=bool)
    walled[:, 15] = True                      # two halves: the goal is unreachable
    big = OccupancyGrid(np.random.default_rng(5).random((150, 150)) < 0.2)
    free = np.argwhere(~big.occ)
    s, t = tuple(int(v) for v in free[0][::-1]), tuple(int(v) for v in free[-1][::-1])
    cases = [(OccupancyGrid(walled), (0, 0), (0, 0)), (OccupancyGrid(walled), (0, 0), (29, 29)),
             (big, s, t)]
    got = [(astar(g, a, b, heuristic=h), dijkstra(g, a, b)) for g, a, b in cases
           for h in ("octile", "zero")]
    assert not got[2][0].found and got[2][0].expanded == 15 * 30      # the start's half, closed
    assert got[4][1].expanded > 1024            # heap entries beyond the first allocation
    _python_loop(monkeypatch)
    ref = [(astar(g, a, b, heuristic=h), dijkstra(g, a, b)) for g, a, b in cases
           for h in ("octile", "zero")]
    for (a1, d1), (a2, d2) in zip(got, ref):
        _same(a1, a2)
        _same(d1, d2)                           # compiled search against scipy's route


def test_dijkstra_scipy_route_matches_the_compiled_search(monkeypatch):
    rng = np.random.default_rng(11)
    cases = [(g, s, t, d) for g in _grids(rng, 30) for d in (True, False)
             for s, t in _free_pairs(rng, g, 3)]
    got = [dijkstra(g, s, t, diagonal=d) for g, s, t, d in cases]
    monkeypatch.setattr(gridheap, "available", lambda: False)
    for (g, s, t, d), a in zip(cases, got):
        _same(a, dijkstra(g, s, t, diagonal=d))


def test_the_kernel_refuses_nothing_it_was_given():
    # the compiled search's result object is the one the Python loop builds (a GridPath)
    p = astar(OccupancyGrid(np.zeros((3, 3), dtype=bool)), (0, 0), (2, 2))
    assert isinstance(p, gridsearch.GridPath) and p.cells.tolist() == [[0, 0], [1, 1], [2, 2]]


@pytest.mark.parametrize("res", [1e-320, 1e307, float("inf")])
def test_a_resolution_whose_keys_are_not_finite_is_refused_on_both_routes(monkeypatch, res):
    grid = OccupancyGrid(np.zeros((2, 18), dtype=bool))
    grid.resolution = res
    msgs = []
    for route in ("compiled", "loop"):
        if route == "loop":
            monkeypatch.setattr(gridheap, "_library", lambda: None)
        for search in (lambda: astar(grid, (0, 0), (17, 1)), lambda: dijkstra(grid, (0, 0), (17, 1))):
            with pytest.raises(HybridnavError) as err:
                search()
            msgs.append(str(err.value))
    assert len(set(msgs)) == 1
    assert msgs[0].startswith("resolution: expected a cell size between ")
    assert "for a search on this 18 x 2 grid" in msgs[0] and msgs[0].endswith(f"got {res!r}")
