"""Grid Dijkstra (hybridnav.planners.path.gridsearch.dijkstra): the same answer as the heap search
it replaced, exactly (cells, length, expanded), lengths equal to scipy.sparse.csgraph's and the
MovingAI optimum, legal paths, unreachable goals, start == goal, and a cache that never goes stale.

The heap search is still there: ``astar(..., heuristic="zero")`` is the old Dijkstra loop (h = 0,
the same heap keys), so it is the reference for the exact comparisons. ``dijkstra`` runs that
search compiled where a compiler is found and scipy's csgraph (with the rebuilt tie order)
elsewhere: every test runs on both routes, the reference staying the Python loop."""

from __future__ import annotations

import math
import threading
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse.csgraph import connected_components
from scipy.sparse.csgraph import dijkstra as csgraph_dijkstra

from hybridnav.planners.path import gridsearch
from hybridnav.planners.path.gridsearch import GridPath, astar, dijkstra, path_cost
from hybridnav.world import builtin_data_path
from hybridnav.world.grid import OccupancyGrid, load_movingai_map, load_movingai_scen

@pytest.fixture(autouse=True, params=["compiled", "scipy"])
def route(request, monkeypatch):
    """dijkstra's two routes; the reference astar(..., "zero") is the Python loop in both."""
    from hybridnav.native import gridheap

    if request.param == "compiled" and not gridheap.available():
        pytest.skip("no compiled kernels here")
    if request.param == "scipy":
        monkeypatch.setattr(gridheap, "available", lambda: False)
    real = gridsearch._search

    def reference_loop(grid, start, goal, diagonal, corner_cutting, heuristic, method):
        if method == "astar":
            with monkeypatch.context() as m:
                m.setattr(gridheap, "_library", lambda: None)
                return real(grid, start, goal, diagonal, corner_cutting, heuristic, method)
        return real(grid, start, goal, diagonal, corner_cutting, heuristic, method)

    monkeypatch.setattr(gridsearch, "_search", reference_loop)
    return request.param


SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "movingai"


def heap_search(grid, s, t, **kw) -> GridPath:
    """The heap-based Dijkstra dijkstra() used to run (A* with a zero heuristic)."""
    return astar(grid, s, t, heuristic="zero", **kw)


def assert_same(a: GridPath, b: GridPath) -> None:
    assert (a.found, a.length, a.expanded) == (b.found, b.length, b.expanded)
    np.testing.assert_array_equal(a.cells, b.cells)
    np.testing.assert_array_equal(a.points, b.points)
    assert a.cells.dtype == b.cells.dtype


def assert_legal(grid: OccupancyGrid, p: GridPath, diagonal: bool = True,
                 corner_cutting: bool = False) -> None:
    """Every move is a step to a free 8- (or 4-) neighbour, no diagonal cuts a blocked corner
    unless allowed, no cell twice, and the length is the sum of the steps."""
    C = p.cells
    assert tuple(C[0]) == tuple(p.start) and tuple(C[-1]) == tuple(p.goal)
    assert not grid.blocked_cells(C).any()
    d = np.abs(np.diff(C, axis=0))
    assert np.all(d.max(axis=1, initial=1) == 1)
    diag = d.sum(axis=1) == 2
    if not diagonal:
        assert not diag.any()
    if not corner_cutting:
        a, b = C[:-1][diag], C[1:][diag]
        assert not grid.occ[a[:, 1], b[:, 0]].any() and not grid.occ[b[:, 1], a[:, 0]].any()
    assert len({tuple(c) for c in C.tolist()}) == len(C)
    assert p.length == pytest.approx(path_cost(grid, C, diagonal=diagonal, corner_cutting=corner_cutting),
                                      rel=1e-12)


def random_grid(rng: np.random.Generator, H: int, W: int) -> np.ndarray:
    kind = rng.integers(3)
    if kind == 0:  # noise, up to the percolation threshold
        return rng.random((H, W)) < rng.choice([0.0, 0.1, 0.25, 0.4])
    occ = np.zeros((H, W), dtype=bool)
    if kind == 1:  # rectangles
        for _ in range(rng.integers(1, 12)):
            r, c = rng.integers(H), rng.integers(W)
            occ[r:r + rng.integers(1, max(2, H // 3)), c:c + rng.integers(1, max(2, W // 3))] = True
    else:  # walls with one gap each: long detours
        for c in range(2, W, 5):
            occ[:, c] = True
            g = rng.integers(H)
            occ[g:g + 2, c] = False
    return occ


# --------------------------------------------------------------------------------------------
# the same answer as the heap search
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_same_cells_length_and_expanded_as_the_heap_search(seed):
    rng = np.random.default_rng(seed)
    checked = decided_by_ties = 0
    for _ in range(60):
        H, W = (int(x) for x in rng.integers(1, 45, size=2))
        occ = random_grid(rng, H, W)
        # resolutions whose sums round differently along equally long paths
        grid = OccupancyGrid(occ, float(rng.choice([1.0, 0.25, 0.1, 3.0, 7.3])), (rng.normal(), rng.normal()))
        free = np.argwhere(~occ)
        if len(free) == 0:
            continue
        for _ in range(4):
            (r0, c0), (r1, c1) = free[rng.integers(len(free), size=2)]
            s, t = (int(c0), int(r0)), (int(c1), int(r1))
            for kw in ({}, {"corner_cutting": True}, {"diagonal": False}):
                flags = {"diagonal": True, "corner_cutting": False, **kw}
                p = dijkstra(grid, s, t, **kw)
                assert_same(p, heap_search(grid, s, t, **kw))
                assert p.method == "dijkstra" and p.params == flags
                checked += 1
                if p.found:
                    # the nodes strictly nearer plus the goal, unless ties (or float noise) decide
                    D = csgraph_dijkstra(grid.adjacency(**flags), indices=grid.cell_index([s])[0])
                    decided_by_ties += p.expanded != np.count_nonzero(D < p.length) + 1
    assert checked > 600 and decided_by_ties > 20


def test_same_as_the_heap_search_on_larger_mazes():
    # goals far beyond the obstacle-free distance: several continuations of the limited search
    rng = np.random.default_rng(11)
    for H, W, kind in ((90, 120, "noise"), (100, 100, "walls"), (60, 200, "rectangles")):
        if kind == "noise":
            occ = rng.random((H, W)) < 0.3
        elif kind == "walls":
            occ = np.zeros((H, W), dtype=bool)
            for c in range(3, W, 6):
                occ[:, c] = True
                occ[rng.integers(H), c] = False
        else:
            occ = random_grid(np.random.default_rng(5), H, W)
        grid = OccupancyGrid(occ, 0.1)
        free = np.argwhere(~occ)
        for _ in range(6):
            (r0, c0), (r1, c1) = free[rng.integers(len(free), size=2)]
            s, t = (int(c0), int(r0)), (int(c1), int(r1))
            assert_same(dijkstra(grid, s, t), heap_search(grid, s, t))


# --------------------------------------------------------------------------------------------
# optimal lengths: scipy.sparse.csgraph and the MovingAI benchmark
# --------------------------------------------------------------------------------------------


def _arena_checks(grid: OccupancyGrid, queries) -> None:
    D = csgraph_dijkstra(grid.adjacency(diagonal=True, corner_cutting=False), indices=grid.cell_index(
        [q.start for q in queries]))
    goals = grid.cell_index([q.goal for q in queries])
    for i, q in enumerate(queries):
        p = dijkstra(grid, q.start, q.goal)
        assert p.found and p.length == D[i, goals[i]]  # the same floating-point number
        assert abs(p.length - q.optimal_length) < 1e-6  # the scen file gives 8 decimals
        assert_legal(grid, p)


def test_arena_lengths_equal_scipy_csgraph_and_movingai():
    grid = load_movingai_map(builtin_data_path("arena.map"))
    queries = load_movingai_scen(builtin_data_path("arena.map.scen"))
    assert len(queries) == 130
    _arena_checks(grid, queries)


def test_arena_from_the_shared_copy_if_present():
    if not (SHARED / "arena.map.scen").is_file():
        pytest.skip("shared benchmark data not available")
    _arena_checks(load_movingai_map(SHARED / "arena.map"), load_movingai_scen(SHARED / "arena.map.scen"))


@pytest.mark.parametrize("diagonal, corner_cutting", [(True, False), (True, True), (False, False)])
def test_lengths_equal_scipy_csgraph_on_random_grids(diagonal, corner_cutting):
    rng = np.random.default_rng(7 + 2 * diagonal + corner_cutting)
    found = unreachable = 0
    for _ in range(40):
        H, W = (int(x) for x in rng.integers(2, 60, size=2))
        occ = random_grid(rng, H, W)
        grid = OccupancyGrid(occ, float(rng.choice([1.0, 0.5, 2.5])))
        free = np.argwhere(~occ)
        if len(free) < 2:
            continue
        A = grid.adjacency(diagonal=diagonal, corner_cutting=corner_cutting)
        for _ in range(3):
            (r0, c0), (r1, c1) = free[rng.integers(len(free), size=2)]
            s, t = (int(c0), int(r0)), (int(c1), int(r1))
            ref = csgraph_dijkstra(A, indices=grid.cell_index([s])[0])[grid.cell_index([t])[0]]
            p = dijkstra(grid, s, t, diagonal=diagonal, corner_cutting=corner_cutting)
            assert p.length == ref
            if p.found:
                assert_legal(grid, p, diagonal, corner_cutting)
                found += 1
            else:
                unreachable += 1
    assert found > 60 and unreachable >= 2


# --------------------------------------------------------------------------------------------
# unreachable goals, start == goal
# --------------------------------------------------------------------------------------------


def test_unreachable_goal_as_before():
    occ = np.zeros((8, 9), dtype=bool)
    occ[:, 4] = True  # a full wall
    grid = OccupancyGrid(occ)
    p = dijkstra(grid, (0, 0), (8, 7))
    assert not p.found and p.length == math.inf and len(p) == 0
    assert p.cells.shape == (0, 2) and p.points.shape == (0, 2)
    assert p.expanded == 8 * 4  # the whole left part: the heap search runs dry there
    assert_same(p, heap_search(grid, (0, 0), (8, 7)))
    # diagonal steps through a blocked corner only with corner cutting
    occ = np.array([[False, True], [True, False]])
    assert not dijkstra(OccupancyGrid(occ), (0, 0), (1, 1)).found
    assert dijkstra(OccupancyGrid(occ), (0, 0), (1, 1), corner_cutting=True).length == math.sqrt(2)


def test_unreachable_expands_the_start_component():
    rng = np.random.default_rng(3)
    occ = rng.random((30, 40)) < 0.45  # many components
    grid = OccupancyGrid(occ)
    _, label = connected_components(grid.adjacency(), directed=False)
    free = np.flatnonzero(~occ.ravel())
    n = 0
    for a, b in zip(free[::7], free[3::11]):
        if label[a] == label[b]:
            continue
        s, t = (int(a % 40), int(a // 40)), (int(b % 40), int(b // 40))
        p = dijkstra(grid, s, t)
        assert not p.found and p.expanded == np.count_nonzero(label == label[a])
        assert_same(p, heap_search(grid, s, t))
        n += 1
    assert n > 20


def test_start_equals_goal():
    occ = np.ones((3, 3), dtype=bool)
    occ[1, 1] = occ[0, 0] = False
    for grid in (OccupancyGrid(np.zeros((3, 3), dtype=bool), 0.5, (1.0, 2.0)), OccupancyGrid(occ)):
        for kw in ({}, {"diagonal": False}, {"corner_cutting": True}):
            p = dijkstra(grid, (1, 1), (1, 1), **kw)
            assert p.found and p.length == 0.0 and p.expanded == 1
            assert p.cells.tolist() == [[1, 1]]
            np.testing.assert_array_equal(p.points, grid.to_world([[1, 1]]))
            assert_same(p, heap_search(grid, (1, 1), (1, 1), **kw))


# --------------------------------------------------------------------------------------------
# the cached graph
# --------------------------------------------------------------------------------------------


def test_the_cached_graph_follows_edits_of_the_grid():
    grid = OccupancyGrid(np.zeros((6, 6), dtype=bool))
    assert dijkstra(grid, (0, 2), (5, 2)).length == 5.0
    grid.occ[:, 3] = True  # in place
    assert not dijkstra(grid, (0, 2), (5, 2)).found
    grid.occ[5, 3] = False
    assert_same(dijkstra(grid, (0, 2), (5, 2)), heap_search(grid, (0, 2), (5, 2)))
    grid.occ = np.zeros((6, 6), dtype=bool)  # reassigned
    assert dijkstra(grid, (0, 2), (5, 2)).length == 5.0
    grid.resolution = 0.5  # the edge lengths
    assert dijkstra(grid, (0, 2), (5, 2)).length == 2.5
    grid.occ = np.zeros((6, 9), dtype=bool)  # another shape
    assert dijkstra(grid, (0, 2), (8, 2)).length == 4.0
    # the move rules are separate graphs of the same grid
    grid.occ[0:2, 1] = True
    for kw in ({}, {"diagonal": False}, {"corner_cutting": True}, {}):
        assert_same(dijkstra(grid, (0, 0), (3, 0), **kw), heap_search(grid, (0, 0), (3, 0), **kw))


def test_threads_sharing_a_grid_get_the_sequential_answers():
    # continued searches write into the shared graph's spare row (under a lock)
    rng = np.random.default_rng(4)
    occ = rng.random((60, 60)) < 0.3
    grid = OccupancyGrid(occ)
    free = np.argwhere(~occ)
    pairs = [((int(a[1]), int(a[0])), (int(b[1]), int(b[0])))
             for a, b in zip(free[rng.integers(len(free), size=24)], free[rng.integers(len(free), size=24)])]
    expected = [dijkstra(grid, s, t) for s, t in pairs]
    results: dict[int, list[GridPath]] = {}

    def work(k):
        results[k] = [dijkstra(grid, s, t) for s, t in (pairs if k % 2 else pairs[::-1])]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for k, got in results.items():
        for a, b in zip(got if k % 2 else got[::-1], expected):
            assert_same(a, b)


# --------------------------------------------------------------------------------------------
# the reproduction that uses the dijkstra planner
# --------------------------------------------------------------------------------------------


def test_the_alley_map_plan_is_unchanged():
    """rfdpso-table3's alley row runs the dijkstra planner: its grid path (on the grid inflated by
    the robot's radius and the 0.25-cell margin) is the heap search's, with the stored length."""
    from hybridnav import planners
    from hybridnav.world import load_scenario

    plan = planners.get("dijkstra").plans(load_scenario("rfd-pso-alley"))[0]
    search = plan.info["search"]
    assert plan.found and search.method == "dijkstra"
    # 27 straight and 7 diagonal steps
    assert plan.metrics["grid_length"] == pytest.approx(27 + 7 * math.sqrt(2), abs=1e-9)
    assert plan.metrics["expanded"] == 179 and len(search) == 35
    assert_same(search, heap_search(plan.info["grid"], search.start, search.goal))
