"""A* and Dijkstra on occupancy grids: the MovingAI arena benchmark's own optimal lengths, networkx
on random grids, path validity checked edge by edge against the networkx graph, and errors."""

from __future__ import annotations

import math
from itertools import pairwise

import networkx as nx
import numpy as np
import pytest

from hybridnav.errors import HybridnavError
from hybridnav.planners.path.gridsearch import (
    GridPath,
    astar,
    dijkstra,
    path_cost,
    search_world,
)
from hybridnav.world import builtin_data_path
from hybridnav.world.grid import OccupancyGrid, load_movingai_map, load_movingai_scen

SEARCHES = {"astar": astar, "dijkstra": dijkstra}


@pytest.fixture(scope="module")
def arena():
    return load_movingai_map(builtin_data_path("arena.map")), load_movingai_scen(builtin_data_path("arena.map.scen"))


def assert_valid_path(grid: OccupancyGrid, p: GridPath, G: nx.Graph, corner_cutting: bool = False) -> None:
    """Every step is an edge of the independent networkx graph; the length is the sum of weights."""
    cells = [tuple(c) for c in p.cells.tolist()]
    assert cells[0] == tuple(p.start) and cells[-1] == tuple(p.goal)
    assert not grid.blocked_cells(p.cells).any()
    total = 0.0
    for a, b in pairwise(cells):
        assert G.has_edge(a, b), f"{a} -> {b} is not an edge"
        total += G[a][b]["weight"]
        if not corner_cutting and a[0] != b[0] and a[1] != b[1]:
            # the MovingAI rule, spelled out: both orthogonal cells of a diagonal step are free
            assert not grid.occ[a[1], b[0]] and not grid.occ[b[1], a[0]]
    assert p.length == pytest.approx(total, abs=1e-9)
    np.testing.assert_allclose(p.points, grid.to_world(p.cells))
    assert len(set(cells)) == len(cells)  # no cell twice


# --------------------------------------------------------------------------------------------
# MovingAI benchmark
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["astar", "dijkstra"])
def test_arena_all_130_optimal_lengths(arena, method):
    grid, queries = arena
    assert len(queries) == 130
    search = SEARCHES[method]
    errors = [abs(search(grid, q.start, q.goal).length - q.optimal_length) for q in queries]
    assert max(errors) < 1e-6  # the scen file gives 8 decimals


def test_arena_paths_are_valid_and_astar_expands_less(arena):
    grid, queries = arena
    G = grid.to_networkx()
    n_astar = n_dijkstra = 0
    for q in queries[::7]:
        pa, pd = astar(grid, q.start, q.goal), dijkstra(grid, q.start, q.goal)
        assert_valid_path(grid, pa, G)
        assert_valid_path(grid, pd, G)
        assert pa.found and pa.method == "astar" and pd.method == "dijkstra"
        assert pa.expanded <= pd.expanded
        n_astar += pa.expanded
        n_dijkstra += pd.expanded
    assert n_astar < n_dijkstra / 3


def test_arena_from_the_shared_copy_if_present(arena):
    from pathlib import Path

    shared = Path(__file__).resolve().parents[2] / "shared" / "data" / "movingai"
    if not (shared / "arena.map.scen").is_file():
        pytest.skip("shared benchmark data not available")
    grid = load_movingai_map(shared / "arena.map")
    qs = load_movingai_scen(shared / "arena.map.scen")
    assert all(abs(astar(grid, q.start, q.goal).length - q.optimal_length) < 1e-6 for q in qs)


# --------------------------------------------------------------------------------------------
# networkx on random grids
# --------------------------------------------------------------------------------------------


def _octile(a, b):
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)


@pytest.mark.parametrize("corner_cutting", [False, True])
@pytest.mark.parametrize("diagonal", [True, False])
def test_random_grids_match_networkx(corner_cutting, diagonal):
    rng = np.random.default_rng(1234 + 2 * corner_cutting + diagonal)
    checked = unreachable = 0
    for trial in range(40):
        H, W = rng.integers(1, 16, size=2)
        density = rng.choice([0.0, 0.1, 0.25, 0.4, 0.55])
        occ = rng.random((H, W)) < density
        res = float(rng.choice([1.0, 0.25, 3.0]))
        grid = OccupancyGrid(occ, res, (rng.normal(), rng.normal()))
        free = np.argwhere(~occ)
        if len(free) == 0:
            continue
        G = grid.to_networkx(diagonal=diagonal, corner_cutting=corner_cutting)
        for _ in range(4):
            (r0, c0), (r1, c1) = free[rng.integers(len(free), size=2)]
            s, t = (int(c0), int(r0)), (int(c1), int(r1))
            kw = dict(diagonal=diagonal, corner_cutting=corner_cutting)
            pa = astar(grid, s, t, **kw)
            pd = dijkstra(grid, s, t, **kw)
            try:
                ref = nx.dijkstra_path_length(G, s, t, weight="weight")
            except nx.NetworkXNoPath:
                ref = math.inf
            if math.isfinite(ref):
                if diagonal:
                    def href(a, b, res=res):
                        return res * _octile(a, b)
                else:
                    def href(a, b, res=res):
                        return res * (abs(a[0] - b[0]) + abs(a[1] - b[1]))
                assert nx.astar_path_length(G, s, t, heuristic=href, weight="weight") == pytest.approx(ref)
                assert pa.found and pd.found
                assert pa.length == pytest.approx(ref, rel=1e-12, abs=1e-12)
                assert pd.length == pytest.approx(ref, rel=1e-12, abs=1e-12)
                assert_valid_path(grid, pa, G, corner_cutting)
                assert_valid_path(grid, pd, G, corner_cutting)
                assert path_cost(grid, pa.cells, **kw) == pytest.approx(pa.length)
                checked += 1
            else:
                for p in (pa, pd):
                    assert not p.found and p.length == math.inf
                    assert p.cells.shape == (0, 2) and p.points.shape == (0, 2)
                unreachable += 1
    assert checked > 60 and unreachable > 3


@pytest.mark.parametrize("heuristic", ["octile", "euclidean", "zero", None])
def test_every_heuristic_is_optimal(heuristic, arena):
    grid, queries = arena
    for q in queries[::13]:
        assert astar(grid, q.start, q.goal, heuristic=heuristic).length == pytest.approx(q.optimal_length, abs=1e-6)


def test_manhattan_heuristic_on_4_connected_grid():
    rng = np.random.default_rng(7)
    occ = rng.random((20, 20)) < 0.3
    occ[0, 0] = occ[19, 19] = False
    grid = OccupancyGrid(occ)
    ref = dijkstra(grid, (0, 0), (19, 19), diagonal=False)
    p = astar(grid, (0, 0), (19, 19), diagonal=False, heuristic="manhattan")
    assert p.found == ref.found and p.length == ref.length
    if p.found:
        assert p.length == pytest.approx(nx.dijkstra_path_length(grid.to_networkx(diagonal=False), (0, 0), (19, 19)))


def test_corner_cutting_rule_by_hand():
    # . #       start (0,0), goal (1,1): the diagonal passes the blocked corner (1,0)
    # . .
    occ = np.array([[False, True], [False, False]])
    grid = OccupancyGrid(occ)
    no_cut = astar(grid, (0, 0), (1, 1))
    cut = astar(grid, (0, 0), (1, 1), corner_cutting=True)
    assert no_cut.length == pytest.approx(2.0) and no_cut.cells.tolist() == [[0, 0], [0, 1], [1, 1]]
    assert cut.length == pytest.approx(math.sqrt(2)) and cut.cells.tolist() == [[0, 0], [1, 1]]
    # two diagonal blocks: no way through without cutting corners
    occ = np.array([[False, True], [True, False]])
    assert not astar(OccupancyGrid(occ), (0, 0), (1, 1)).found
    assert astar(OccupancyGrid(occ), (0, 0), (1, 1), corner_cutting=True).length == pytest.approx(math.sqrt(2))


def test_unreachable_goal_is_a_result_not_an_exception():
    occ = np.zeros((8, 9), dtype=bool)
    occ[:, 4] = True  # full wall
    grid = OccupancyGrid(occ)
    for search in (astar, dijkstra):
        p = search(grid, (0, 0), (8, 7))
        assert not p.found and p.length == math.inf and len(p) == 0
        assert p.expanded == 8 * 4  # the whole left part, then the heap runs dry


def test_tie_breaking_expands_only_the_path_on_open_ground():
    # every cell on an optimal staircase has the same f; preferring the larger g walks straight
    # to the goal, where plain f-order would expand the whole band of equal-f cells
    grid = OccupancyGrid(np.zeros((40, 60), dtype=bool))
    for s, t in (((0, 0), (59, 39)), ((0, 5), (59, 30)), ((3, 3), (50, 3))):
        p = astar(grid, s, t)
        assert p.expanded == len(p)


def test_start_equals_goal():
    grid = OccupancyGrid(np.zeros((3, 3), dtype=bool))
    p = astar(grid, (1, 2), (1, 2))
    assert p.found and p.length == 0.0 and p.cells.tolist() == [[1, 2]] and p.expanded == 1


def test_resolution_scales_length_and_world_points():
    rng = np.random.default_rng(3)
    occ = rng.random((12, 17)) < 0.2
    occ[1, 1] = occ[10, 15] = False
    a = astar(OccupancyGrid(occ), (1, 1), (15, 10))
    b = astar(OccupancyGrid(occ, 0.5, (-3.0, 2.0)), (1, 1), (15, 10))
    assert b.length == pytest.approx(0.5 * a.length)
    np.testing.assert_array_equal(a.cells, b.cells)
    np.testing.assert_allclose(b.points, np.array([-3.0, 2.0]) + (a.cells + 0.5) * 0.5)


def test_search_world_maps_points_to_cells():
    occ = np.zeros((10, 20), dtype=bool)
    occ[2:10, 8] = True
    grid = OccupancyGrid(occ, 0.5, (1.0, -2.0))
    p = search_world(grid, (1.1, -1.9), (10.9, 2.9))
    assert p.start == (0, 0) and p.goal == (19, 9)
    q = astar(grid, (0, 0), (19, 9))
    assert p.length == pytest.approx(q.length)
    d = search_world(grid, (1.1, -1.9), (10.9, 2.9), method="dijkstra")
    assert d.method == "dijkstra" and d.length == pytest.approx(q.length)
    with pytest.raises(HybridnavError, match=r"^goal: cell \(8, 5\) \(world point \(5.2, 0.6\)\) is blocked"):
        search_world(grid, (1.1, -1.9), (5.2, 0.6))
    with pytest.raises(HybridnavError, match=r"^start: .*outside"):
        search_world(grid, (0.0, 0.0), (5.0, 0.0))
    with pytest.raises(HybridnavError, match="^method"):
        search_world(grid, (1.1, -1.9), (10.9, 2.9), method="bfs")
    with pytest.raises(HybridnavError, match="^start: expected a finite world point"):
        search_world(grid, (np.nan, 0.0), (10.9, 2.9))


def test_in_place_edit_of_the_grid_is_seen():
    # the per-grid cache of move masks must notice edits of occ
    grid = OccupancyGrid(np.zeros((5, 5), dtype=bool))
    assert astar(grid, (0, 2), (4, 2)).length == pytest.approx(4.0)
    grid.occ[:, 2] = True
    assert not astar(grid, (0, 2), (4, 2)).found
    grid.occ[4, 2] = False
    # (0,2) (1,3) (1,4) (2,4) (3,4) (4,3) (4,2): the gap cell (2,4) is entered and left straight
    assert astar(grid, (0, 2), (4, 2)).length == pytest.approx(4 + 2 * math.sqrt(2))
    grid.occ = np.zeros((5, 5), dtype=bool)
    assert astar(grid, (0, 2), (4, 2)).length == pytest.approx(4.0)


# --------------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("search", [astar, dijkstra])
def test_bad_endpoints_name_the_argument(search):
    occ = np.zeros((4, 5), dtype=bool)
    occ[1, 2] = True
    grid = OccupancyGrid(occ)
    with pytest.raises(HybridnavError, match=r"^start: cell \(2, 1\) is blocked"):
        search(grid, (2, 1), (0, 0))
    with pytest.raises(HybridnavError, match=r"^goal: cell \(2, 1\) is blocked"):
        search(grid, (0, 0), (2, 1))
    with pytest.raises(HybridnavError, match=r"^goal: cell \(5, 0\) is outside the 5x4 grid"):
        search(grid, (0, 0), (5, 0))
    with pytest.raises(HybridnavError, match=r"^start: cell \(0, -1\) is outside"):
        search(grid, (0, -1), (0, 0))
    with pytest.raises(HybridnavError, match="^start: expected a cell"):
        search(grid, (0.5, 1), (0, 0))
    with pytest.raises(HybridnavError, match="^goal: expected a cell"):
        search(grid, (0, 0), (1, 2, 3))
    with pytest.raises(HybridnavError, match="^grid: expected an OccupancyGrid"):
        search(occ, (0, 0), (1, 1))
    with pytest.raises(HybridnavError, match="^diagonal"):
        search(grid, (0, 0), (1, 1), diagonal="yes")
    # numpy integers and integral floats are fine
    assert search(grid, np.array([0, 0]), (4.0, 3.0)).found


def test_bad_heuristic():
    grid = OccupancyGrid(np.zeros((3, 3), dtype=bool))
    with pytest.raises(HybridnavError, match="^heuristic: expected one of"):
        astar(grid, (0, 0), (2, 2), heuristic="chebyshev")
    with pytest.raises(HybridnavError, match="^heuristic: 'manhattan' overestimates"):
        astar(grid, (0, 0), (2, 2), heuristic="manhattan")
    with pytest.raises(TypeError):
        dijkstra(grid, (0, 0), (2, 2), heuristic="octile")


def test_path_cost_checks_moves():
    occ = np.zeros((3, 3), dtype=bool)
    occ[0, 1] = True
    grid = OccupancyGrid(occ, 2.0)
    assert path_cost(grid, [[0, 0]]) == 0.0
    assert path_cost(grid, [[0, 0], [0, 1], [1, 2]]) == pytest.approx(2.0 + 2.0 * math.sqrt(2))
    with pytest.raises(HybridnavError, match=r"^cells\[1\]: diagonal move \(0, 0\) -> \(1, 1\) cuts"):
        path_cost(grid, [[0, 0], [1, 1]])
    assert path_cost(grid, [[0, 0], [1, 1]], corner_cutting=True) == pytest.approx(2.0 * math.sqrt(2))
    with pytest.raises(HybridnavError, match=r"^cells\[1\]: cell \(1, 0\) is outside the grid or blocked"):
        path_cost(grid, [[0, 0], [1, 0]])
    with pytest.raises(HybridnavError, match=r"^cells\[2\]: move \(0, 1\) -> \(2, 1\) is not a step"):
        path_cost(grid, [[0, 0], [0, 1], [2, 1]])
    with pytest.raises(HybridnavError, match=r"^cells\[1\]: move .* 4-neighbour"):
        path_cost(grid, [[0, 1], [1, 2]], diagonal=False)
    with pytest.raises(HybridnavError, match="^cells: expected a non-empty"):
        path_cost(grid, np.zeros((0, 2), dtype=int))
    with pytest.raises(HybridnavError, match="^cells: expected"):
        path_cost(grid, [[0.0, 0.0]])


def test_docstrings_are_numpydoc():
    import inspect

    for f in (astar, dijkstra, search_world, path_cost):
        doc = inspect.getdoc(f)
        assert "Parameters\n----------" in doc and "Returns\n-------" in doc
        for name in inspect.signature(f).parameters:
            assert name in doc, (f.__name__, name)
