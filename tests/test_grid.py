"""Occupancy grids: MovingAI parsing (checked against the benchmark's own optimal lengths),
coordinate conventions and rasterization."""

from __future__ import annotations

from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from hybridnav.errors import HybridnavError
from hybridnav.world import (
    Circle,
    Rectangle,
    Segment,
    World,
    builtin_data_path,
    load_scenario,
)
from hybridnav.world.grid import (
    OccupancyGrid,
    build_grid,
    load_movingai_map,
    load_movingai_scen,
    parse_movingai_map,
    rasterize,
    resolve_map,
)

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "movingai"
PKG_MAP = builtin_data_path("arena.map")
PKG_SCEN = builtin_data_path("arena.map.scen")


def _map_text():
    return PKG_MAP.read_text(encoding="utf-8")


def test_builtin_data_is_a_copy_of_the_benchmark():
    if not SHARED.is_dir():
        pytest.skip("shared benchmark data not available")
    assert PKG_MAP.read_text() == (SHARED / "arena.map").read_text()
    assert PKG_SCEN.read_text() == (SHARED / "arena.map.scen").read_text()


def test_arena_map_dims_and_cells():
    g = load_movingai_map(PKG_MAP)
    lines = _map_text().splitlines()
    header = dict(ln.split() for ln in lines[1:3])
    H, W = int(header["height"]), int(header["width"])
    assert g.shape == (H, W) == (49, 49)
    assert g.resolution == 1.0 and g.origin == (0.0, 0.0)
    rows = lines[4:4 + H]
    # occ[y, x] is the file's character at line y (after the header), column x
    expected = np.array([[c != "." for c in row] for row in rows])
    np.testing.assert_array_equal(g.occ, expected)
    assert g.occ.sum() == sum(row.count("T") for row in rows)


def test_arena_scen_records_and_passable_ends():
    g = load_movingai_map(PKG_MAP)
    q = load_movingai_scen(PKG_SCEN)
    assert len(q) == 130
    assert all(r.map == "arena.map" and (r.width, r.height) == (49, 49) for r in q)
    assert q[0].start == (19, 26) and q[0].goal == (19, 29) and q[0].optimal_length == pytest.approx(3.0)
    S = np.array([r.start for r in q])
    G = np.array([r.goal for r in q])
    assert not g.blocked_cells(S).any()
    assert not g.blocked_cells(G).any()
    # the world point at the centre of MovingAI cell (x, y) is (x + 0.5, y + 0.5)
    np.testing.assert_array_equal(g.to_cell(S + 0.5), S)
    assert g.is_free(S + 0.5).all()


def test_octile_shortest_paths_match_movingai_optimal_lengths():
    """Independent reference: the benchmark's published optimal lengths (octile, no corner cutting)."""
    g = load_movingai_map(PKG_MAP)
    q = load_movingai_scen(PKG_SCEN)
    S = g.cell_index([r.start for r in q])
    G = g.cell_index([r.goal for r in q])
    D = dijkstra(g.adjacency(diagonal=True, corner_cutting=False), indices=S)
    lengths = D[np.arange(len(q)), G]
    np.testing.assert_allclose(lengths, [r.optimal_length for r in q], atol=1e-6)
    # corner cutting can only shorten paths, and does so for some query on this map
    Dc = dijkstra(g.adjacency(corner_cutting=True), indices=S)[np.arange(len(q)), G]
    assert np.all(Dc <= lengths + 1e-9) and np.any(Dc < lengths - 1e-9)
    # the networkx graph is the same graph
    nxg = g.to_networkx()
    for r in q[-5:]:
        assert nx.dijkstra_path_length(nxg, r.start, r.goal) == pytest.approx(r.optimal_length, abs=1e-6)


def test_cell_world_conversions():
    g = OccupancyGrid(np.zeros((4, 6), bool), resolution=0.5, origin=(-1.0, 2.0))
    assert g.extent == (-1.0, 2.0, 2.0, 4.0)
    cells = np.array([[0, 0], [5, 3], [2, 1]])
    centres = g.to_world(cells)
    np.testing.assert_allclose(centres, [[-0.75, 2.25], [1.75, 3.75], [0.25, 2.75]])
    np.testing.assert_array_equal(g.to_cell(centres), cells)
    np.testing.assert_array_equal(g.to_cell([[-1.01, 2.0]]), [[-1, 0]])
    np.testing.assert_array_equal(g.in_bounds([[-1, 0], [5, 3], [6, 0]]), [False, True, False])
    assert g.blocked_cells([[-1, 0], [0, 0]]).tolist() == [True, False]


@pytest.mark.parametrize(
    "text, line",
    [
        ("type octile\nheight 2\nwidth 3\nmap\n...\n.X.\n", 6),  # unknown terrain
        ("type octile\nheight 2\nwidth 3\nmap\n...\n..\n", 6),  # short row
        ("type octile\nheight 3\nwidth 3\nmap\n...\n...\n", 7),  # missing row
        ("type octile\nheigth 2\nwidth 3\nmap\n...\n...\n", 2),  # bad header key
    ],
)
def test_map_parse_errors_name_file_and_line(tmp_path, text, line):
    p = tmp_path / "bad.map"
    p.write_text(text)
    with pytest.raises(HybridnavError) as e:
        load_movingai_map(p)
    assert "bad.map" in str(e.value) and f"line {line}" in str(e.value)


def test_map_terrain_classes():
    g = parse_movingai_map("type octile\nheight 1\nwidth 8\nmap\n.GS@OTW.\n")
    np.testing.assert_array_equal(g.occ[0], [False, False, False, True, True, True, True, False])


def test_scen_parse_errors(tmp_path):
    p = tmp_path / "bad.scen"
    p.write_text("version 1\n0\tarena.map\t49\t49\t1\t2\t3\n")
    with pytest.raises(HybridnavError, match=r"bad\.scen: line 2"):
        load_movingai_scen(p)
    p.write_text("0\tarena.map\n")
    with pytest.raises(HybridnavError, match=r"bad\.scen: line 1"):
        load_movingai_scen(p)


def test_resolve_map(tmp_path):
    assert resolve_map("movingai:arena").name == "arena.map"
    with pytest.raises(HybridnavError, match="grid.map"):
        resolve_map("movingai:nosuchmap")
    (tmp_path / "m.map").write_text("type octile\nheight 1\nwidth 1\nmap\n.\n")
    assert resolve_map("m.map", str(tmp_path / "s.toml")) == tmp_path / "m.map"
    with pytest.raises(HybridnavError, match=r"s\.toml: grid\.map"):
        resolve_map("other.map", str(tmp_path / "s.toml"))


def test_rasterize_circle_matches_analytic_cell_centres():
    w = World((0.0, 10.0, 0.0, 8.0), (Circle((4.0, 3.0), 2.2),))
    for inflate in (0.0, 0.5):
        g = rasterize(w, 0.25, inflate=inflate)
        assert g.shape == (32, 40) and g.origin == (0.0, 0.0)
        rows, cols = np.mgrid[0:32, 0:40]
        cx, cy = (cols + 0.5) * 0.25, (rows + 0.5) * 0.25
        expected = np.hypot(cx - 4.0, cy - 3.0) < 2.2 + inflate
        np.testing.assert_array_equal(g.occ, expected)


def test_rasterize_thin_wall_separates_and_partial_cells():
    w = World((0.0, 10.3, 0.0, 10.0), (Segment((0.0, 5.05), (10.3, 5.05)), Rectangle((1.0, 1.0), (2.0, 2.0))))
    g = rasterize(w, 1.0)
    assert g.shape == (10, 11)
    lab, n = ndimage.label(~g.occ)  # 4-connectivity
    a = g.to_cell([[5.0, 1.0]])[0]
    b = g.to_cell([[5.0, 9.0]])[0]
    assert lab[a[1], a[0]] != lab[b[1], b[0]]
    assert g.occ[:, 10].all()  # last column: centre x = 10.5 lies outside the workspace
    assert g.occ[1, 1] and not g.occ[0, 0]
    # moving nothing: a world without obstacles rasterizes empty (no border frame by default)
    assert not rasterize(World((0, 4, 0, 4)), 1.0).occ.any()
    assert rasterize(World((0, 4, 0, 4)), 1.0, inflate=0.6, border=True).occ.sum() == 12
    with pytest.raises(HybridnavError, match="resolution"):
        rasterize(w, 0.0)


def test_build_grid_for_scenarios():
    arena = load_scenario("arena")
    g = build_grid(arena)
    np.testing.assert_array_equal(g.occ, load_movingai_map(PKG_MAP).occ)
    assert g.extent == arena.world.workspace
    # inflation on a map blocks the free neighbours of blocked cells
    gi = build_grid(arena, inflate=0.6)
    assert gi.occ.sum() > g.occ.sum() and np.all(gi.occ[g.occ])
    rfd = load_scenario("rfd-pso-700")
    gr = build_grid(rfd)
    assert gr.resolution == 10.0 and gr.shape == (70, 70)
    assert not gr.is_free([[330.0, 330.0]])[0] and gr.is_free([list(rfd.robots[0].start)])[0]
    assert build_grid(rfd, resolution=20.0).shape == (35, 35)
    fastep = load_scenario("fastep-s1")  # no [grid]: default resolution is 1/100 of the workspace
    assert build_grid(fastep).shape == (100, 100)


def test_rasterize_equals_every_cell_against_every_obstacle():
    """rasterize prunes each obstacle to the cells near its box; the grid is the one that tests
    every cell centre against every obstacle (generated worlds with cups, corridors and gaps,
    moving circles at a time, inflation and the border)."""
    from hybridnav.world.generator import WorldGenerator
    from hybridnav.world.obstacles import MovingCircle, Segment

    gen = WorldGenerator(cups=(1, 1), corridors=(1, 1), gaps=(1, 1))
    worlds = [s.world for s in gen.generate(4, seed=5)]
    worlds.append(World((-1.0, 3.0, 0.0, 2.0), (
        MovingCircle((0.5, 0.5), 0.3, 1.1, 0.5), Segment((2.9, -5.0), (2.9, 5.0)),
        Circle((10.0, 10.0), 0.5))))
    for w in worlds:
        for res, inflate, border, t in ((0.05, 0.0, False, None), (0.13, 0.21, True, None),
                                        (0.07, 0.1, False, 1.5)):
            g = rasterize(w, res, inflate, t=t, border=border)
            H, W = g.occ.shape
            cols, rows = np.meshgrid(np.arange(W), np.arange(H))
            P = g.to_world(np.column_stack([cols.ravel(), rows.ravel()]))
            obs = [o for o in w.obstacles if t is not None or not isinstance(o, MovingCircle)]
            solids = World(w.workspace, tuple(o for o in obs if not isinstance(o, Segment)))
            walls = World(w.workspace, tuple(o for o in obs if isinstance(o, Segment)))
            want = solids.clearance(P, t=t or 0.0) < inflate
            want |= walls.clearance(P) < max(inflate, res / 2.0)
            want |= w.border_clearance(P) < (inflate if border else 0.0)
            assert np.array_equal(g.occ, want.reshape(H, W))


@pytest.mark.parametrize("t", [float("inf"), float("-inf"), float("nan")])
def test_rasterize_refuses_a_time_that_is_not_finite(t):
    """At t = inf a static circle's box (centre + t * 0) is NaN: the pruned rasterize dropped
    the circle (12 blocked cells became 0); a non-finite time is refused instead."""
    w = World((0.0, 10.0, 0.0, 10.0), (Circle((5.0, 5.0), 1.0),))
    with pytest.raises(HybridnavError, match=r"^t: expected a finite time or None, got "):
        rasterize(w, 0.5, t=t)
    assert rasterize(w, 0.5, t=1e6).occ.sum() == rasterize(w, 0.5).occ.sum() == 12
