"""River formation dynamics: path quality against A*, validity against the networkx graph,
determinism, stopping reasons, the altitude invariants, each phase's formula, and errors."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from hybridnav.errors import HybridnavError
from hybridnav.planners.path import rfd_core
from hybridnav.planners.path.gridsearch import astar, path_cost
from hybridnav.planners.path.rfd_core import RFD_REASONS, RFDResult, rfd
from hybridnav.world import builtin_data_path
from hybridnav.world.grid import OccupancyGrid, load_movingai_map


def open_grid(h=8, w=8):
    return OccupancyGrid(np.zeros((h, w), dtype=bool))


def wall_grid():
    # a wall from the top edge down, the gap at the bottom: start and goal on either side
    occ = np.zeros((12, 12), dtype=bool)
    occ[2:12, 6] = True
    return OccupancyGrid(occ)


def assert_valid(grid: OccupancyGrid, r: RFDResult, diagonal=True, corner_cutting=False) -> None:
    G = grid.to_networkx(diagonal=diagonal, corner_cutting=corner_cutting)
    cells = [tuple(c) for c in r.cells.tolist()]
    assert cells[0] == r.start and cells[-1] == r.goal
    assert len(set(cells)) == len(cells)  # drops never revisit a node
    total = sum(G[a][b]["weight"] for a, b in pairwise(cells))  # KeyError if not an edge
    assert r.length == pytest.approx(total, rel=1e-12)
    assert r.length == pytest.approx(path_cost(grid, r.cells, diagonal=diagonal, corner_cutting=corner_cutting))
    np.testing.assert_allclose(r.points, grid.to_world(r.cells))


# --------------------------------------------------------------------------------------------
# path quality
# --------------------------------------------------------------------------------------------


def test_open_grid_often_optimal():
    grid = open_grid()
    opt = astar(grid, (0, 0), (7, 7)).length
    ratios = []
    for seed in range(8):
        r = rfd(grid, (0, 0), (7, 7), seed=seed)
        assert r.found and r.reason == "converged"
        assert_valid(grid, r)
        ratios.append(r.length / opt)
    ratios = np.array(ratios)
    assert ratios.min() >= 1 - 1e-12  # never shorter than the optimum
    assert ratios.max() <= 1.15
    assert np.sum(ratios < 1 + 1e-9) >= 4  # the exact optimum in most runs


def test_wall_grid_within_factor():
    grid = wall_grid()
    opt = astar(grid, (0, 6), (11, 6)).length
    ratios = []
    for seed in range(5):
        r = rfd(grid, (0, 6), (11, 6), seed=seed)
        assert r.found
        assert_valid(grid, r)
        # the best length only improves, and the history ends at the result
        h = r.history[np.isfinite(r.history)]
        assert np.all(np.diff(h) <= 0) and h[-1] == r.length
        ratios.append(r.length / opt)
    assert min(ratios) >= 1 - 1e-12 and max(ratios) <= 1.4 and np.mean(ratios) <= 1.2


def test_sloped_terrain_on_the_arena_benchmark():
    # the arena scenario's longest query; tilted initial terrain (see `slope`)
    grid = load_movingai_map(builtin_data_path("arena.map"))
    r = rfd(grid, (3, 45), (39, 11), seed=0, slope=0.01)
    assert r.found and r.reason == "converged"
    assert_valid(grid, r)
    assert 51.84 - 1e-2 <= r.length <= 1.1 * 51.84


def test_four_connected_and_corner_cutting_options():
    rng = np.random.default_rng(2)
    occ = rng.random((9, 9)) < 0.25
    occ[0, 0] = occ[8, 8] = False
    grid = OccupancyGrid(occ, resolution=0.5)
    for diagonal, cc in ((False, False), (True, True), (True, False)):
        ref = astar(grid, (0, 0), (8, 8), diagonal=diagonal, corner_cutting=cc)
        r = rfd(grid, (0, 0), (8, 8), seed=3, diagonal=diagonal, corner_cutting=cc, slope=0.01)
        assert r.found == ref.found
        if r.found:
            assert_valid(grid, r, diagonal, cc)
            assert ref.length - 1e-9 <= r.length <= 1.5 * ref.length


# --------------------------------------------------------------------------------------------
# determinism and stopping
# --------------------------------------------------------------------------------------------


def test_deterministic_for_a_seed():
    grid = wall_grid()
    a = rfd(grid, (0, 6), (11, 6), seed=42, iterations=15)
    b = rfd(grid, (0, 6), (11, 6), seed=42, iterations=15)
    c = rfd(grid, (0, 6), (11, 6), seed=np.random.default_rng(42), iterations=15)
    for other in (b, c):
        np.testing.assert_array_equal(a.cells, other.cells)
        np.testing.assert_array_equal(a.history, other.history)
        np.testing.assert_array_equal(a.arrivals, other.arrivals)
        np.testing.assert_array_equal(a.altitude, other.altitude)
    d = rfd(grid, (0, 6), (11, 6), seed=43, iterations=15)
    assert not np.array_equal(np.nan_to_num(a.altitude), np.nan_to_num(d.altitude))


def test_altitude_scale_changes_nothing_else():
    # parameters are relative to altitude0; a power of two scales every float exactly
    grid = wall_grid()
    a = rfd(grid, (0, 6), (11, 6), seed=5, iterations=20)
    b = rfd(grid, (0, 6), (11, 6), seed=5, iterations=20, altitude0=4.0)
    np.testing.assert_array_equal(a.cells, b.cells)
    np.testing.assert_array_equal(4.0 * a.altitude, b.altitude)


def test_converges_in_one_iteration_in_a_corridor():
    occ = np.ones((3, 9), dtype=bool)
    occ[1, :] = False
    grid = OccupancyGrid(occ, resolution=2.0)
    r = rfd(grid, (0, 1), (8, 1), seed=0)
    assert r.reason == "converged" and r.iterations == 1
    assert r.length == pytest.approx(16.0) and r.arrivals.tolist() == [20]
    assert r.cells.tolist() == [[c, 1] for c in range(9)]


def test_stopping_reasons():
    grid = open_grid(15, 15)
    r = rfd(grid, (0, 3), (14, 9), seed=0, iterations=2)
    assert r.reason == "max_iterations" and r.iterations == 2 and len(r.history) == 2
    r = rfd(grid, (0, 3), (14, 9), seed=0, patience=2)
    # the last improvement, then exactly `patience` iterations without one
    assert r.reason == "no_improvement"
    assert r.history[-1] == r.history[-2] == r.history[-3] < r.history[-4]
    assert set(RFD_REASONS) == {"converged", "no_improvement", "max_iterations", "unreachable"}


def test_no_run_hangs_when_nothing_arrives():
    # a single step per drop: nobody reaches a goal 10 cells away; patience ends the run
    grid = open_grid(3, 12)
    r = rfd(grid, (0, 1), (11, 1), seed=0, max_steps=1, patience=5, iterations=1000)
    assert not r.found and r.reason == "no_improvement" and r.iterations == 5
    assert r.length == math.inf and r.cells.shape == (0, 2)
    assert np.all(np.isinf(r.history)) and r.arrivals.sum() == 0


def test_unreachable_goal():
    occ = np.zeros((6, 7), dtype=bool)
    occ[:, 3] = True
    grid = OccupancyGrid(occ)
    r = rfd(grid, (0, 0), (6, 5), seed=0)
    assert not r.found and r.reason == "unreachable" and r.iterations == 0
    assert r.length == math.inf and r.cells.shape == (0, 2) and r.history.shape == (0,)
    # without corner cutting two diagonal blocks separate the grid too
    occ = np.array([[False, True], [True, False]])
    assert rfd(OccupancyGrid(occ), (0, 0), (1, 1)).reason == "unreachable"
    assert rfd(OccupancyGrid(occ), (0, 0), (1, 1), corner_cutting=True).length == pytest.approx(math.sqrt(2))


def test_start_is_goal():
    r = rfd(open_grid(3, 3), (1, 1), (1, 1))
    assert r.found and r.length == 0.0 and r.cells.tolist() == [[1, 1]] and r.reason == "converged"


# --------------------------------------------------------------------------------------------
# invariants of the altitude field
# --------------------------------------------------------------------------------------------


def test_altitude_field_invariants():
    grid = wall_grid()
    r = rfd(grid, (0, 6), (11, 6), seed=1, deposit=0.0)
    A = r.altitude
    assert A.shape == grid.shape
    assert np.all(np.isnan(A[grid.occ])) and np.all(np.isfinite(A[~grid.occ]))
    assert A[6, 11] == 0.0  # the goal, (col, row) = (11, 6)
    assert np.all(A[~grid.occ] >= 0.0)
    # erosion + sediment conserve soil: without dead-end deposits the total stays (N - 1) * a0
    n_free = int((~grid.occ).sum())
    assert np.nansum(A) == pytest.approx(n_free - 1, rel=1e-9)
    # the river: the best path lies in a valley
    on = np.zeros(grid.shape, dtype=bool)
    on[r.cells[:-1, 1], r.cells[:-1, 0]] = True
    assert A[on].mean() < A[~on & ~grid.occ].mean()


def test_dead_end_deposits_add_soil():
    grid = wall_grid()
    r = rfd(grid, (0, 6), (11, 6), seed=1, iterations=10, deposit=1.0)
    n_free = int((~grid.occ).sum())
    assert np.nansum(r.altitude) > n_free - 1


def test_erosion_lowers_the_path_and_sediment_conserves_soil():
    rng = np.random.default_rng(0)
    alt = np.concatenate([rng.uniform(0.5, 1.0, 9), [0.0]])  # node 9 is the goal
    path = np.array([0, 3, 4, 7, 9])
    src, dst = path[:-1], path[1:]
    dist = np.array([1.0, math.sqrt(2), 1.0, 1.0])
    new, eroded = rfd_core._erode(alt, src, dst, dist, coef=0.1, erosion_floor=0.01)
    grad = (alt[src] - alt[dst]) / dist
    expect = alt.copy()
    expect[src] -= 0.1 * np.maximum(grad, 0.01)
    np.testing.assert_allclose(new, np.maximum(expect, 0.0))
    assert np.all(new[src] < alt[src])  # every node the drop left is lowered
    off = np.setdiff1d(np.arange(10), src)
    np.testing.assert_array_equal(new[off], alt[off])  # others untouched, the goal too
    assert eroded == pytest.approx((alt - new).sum())
    # two drops on the same step erode twice
    new2, _ = rfd_core._erode(alt, np.array([0, 0]), np.array([3, 3]), np.ones(2), 0.1, 0.0)
    assert new2[0] == pytest.approx(alt[0] - 0.2 * max(alt[0] - alt[3], 0.0))
    # sediment: eroded / (N - 1) on every node but the goal; deposits on dead ends
    dep = rfd_core._deposit(new, 9, eroded, np.array([2, 2, 5]), 0.25)
    assert dep[9] == 0.0
    assert dep.sum() == pytest.approx(alt.sum() + 3 * 0.25)
    assert dep[2] - new[2] == pytest.approx(eroded / 9 + 0.5)


def test_move_weights_follow_eq8():
    g = np.array([[0.5, 0.0, -0.01, -1e-9, -np.inf]])
    w = rfd_core._move_weights(g, omega=1e-3, delta=1e-7, tol=1e-12)
    np.testing.assert_allclose(w[0], [0.5, 1e-3, 1e-5, 1e-3, 0.0])


def test_drop_moves_sample_the_normalized_weights():
    # one step of many drops from the centre of a 3x3 grid with a hand-made altitude field
    grid = OccupancyGrid(np.zeros((3, 3), dtype=bool))
    G = rfd_core._build_graph(grid.occ, True, False)
    s = int(G.node_of[1, 1])
    alt = np.ones(9)
    alt[G.node_of[1, 2]] = 0.8      # (col 2, row 1): downhill by 0.2, straight
    alt[G.node_of[2, 2]] = 0.7      # (2, 2): downhill by 0.3 over sqrt(2)
    alt[G.node_of[0, 1]] = 1.5      # (1, 0): uphill
    D = 40000
    visited = np.zeros((D, 10), dtype=bool)
    T, nsteps, _, _ = rfd_core._move_drops(G, alt, s, int(G.node_of[0, 0]), D, 1, 1e-3, 1e-4, 1e-12,
                                               np.random.default_rng(0), visited)
    assert not visited.any()  # reset for the next iteration
    assert np.all(nsteps == 1)
    nb = G.nb[s]
    grad = (alt[s] - alt[nb]) / G.dist
    w = rfd_core._move_weights(grad, 1e-3, 1e-4, 1e-12)
    p = w / w.sum()
    freq = np.array([(T[1] == v).mean() for v in nb])
    assert np.all(np.abs(freq - p) <= 4 * np.sqrt(p * (1 - p) / D) + 1e-12), (freq, p)
    assert p[list(nb).index(G.node_of[2, 2])] == pytest.approx(0.3 / math.sqrt(2) / w.sum())


def test_graph_matches_grid_adjacency():
    rng = np.random.default_rng(9)
    occ = rng.random((7, 8)) < 0.3
    grid = OccupancyGrid(occ)
    for diagonal, cc in ((True, False), (True, True), (False, False)):
        G = rfd_core._build_graph(occ, diagonal, cc)
        ours = set()
        for i in range(G.nb.shape[0]):
            for k, j in enumerate(G.nb[i]):
                if j >= 0:
                    a = (int(G.cols[i]), int(G.rows[i]))
                    b = (int(G.cols[j]), int(G.rows[j]))
                    ours.add((min(a, b), max(a, b), G.dist[k]))
        ref = {(min(a, b), max(a, b), w) for a, b, w in grid.to_networkx(diagonal, cc).edges(data="weight")}
        assert {(a, b) for a, b, _ in ours} == {(a, b) for a, b, _ in ref}
        wref = {(a, b): w2 for a, b, w2 in ref}
        assert all(math.isclose(w, wref[(a, b)]) for a, b, w in ours)


# --------------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------------


def test_bad_input_names_the_argument():
    occ = np.zeros((5, 5), dtype=bool)
    occ[2, 2] = True
    grid = OccupancyGrid(occ)
    cases = [
        (dict(start=(2, 2)), r"^start: cell \(2, 2\) is blocked"),
        (dict(goal=(5, 0)), r"^goal: cell \(5, 0\) is outside"),
        (dict(start=(0.5, 0)), "^start: expected a cell"),
        (dict(drops=0), "^drops: expected an integer >= 1"),
        (dict(drops=2.5), "^drops"),
        (dict(iterations=0), "^iterations"),
        (dict(patience=True), "^patience"),
        (dict(max_steps=0), "^max_steps"),
        (dict(omega=0.0), "^omega: expected a positive"),
        (dict(delta=-1.0), "^delta"),
        (dict(altitude0=math.nan), "^altitude0"),
        (dict(slope=-0.1), "^slope: expected a non-negative"),
        (dict(erosion=0), "^erosion: expected a positive"),
        (dict(erosion_floor="x"), "^erosion_floor"),
        (dict(deposit=math.inf), "^deposit"),
        (dict(seed="abc"), "^seed"),
        (dict(seed=-1), "^seed"),
        (dict(diagonal=None), "^diagonal"),
    ]
    for kw, msg in cases:
        args = {"start": (0, 0), "goal": (4, 4)}
        args.update(kw)
        s, t = args.pop("start"), args.pop("goal")
        with pytest.raises(HybridnavError, match=msg):
            rfd(grid, s, t, **args)
    with pytest.raises(HybridnavError, match="^grid"):
        rfd(occ, (0, 0), (4, 4))
    with pytest.raises(TypeError):
        rfd(grid, (0, 0), (4, 4), evaporation=0.1)


def test_docstring_documents_every_parameter():
    import inspect

    doc = inspect.getdoc(rfd)
    for name in inspect.signature(rfd).parameters:
        assert name in doc, name
    mod = inspect.getdoc(rfd_core)
    for phrase in ("E / ((N - 1) * D)", "erosionProduced / (N - 1)", "delta / |gradient(i, j)|"):
        assert phrase in mod
