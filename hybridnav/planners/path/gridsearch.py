"""Optimal search on occupancy grids: A* and Dijkstra with octile moves.

The graph is the free-cell graph of an :class:`~hybridnav.world.grid.OccupancyGrid` exactly as
:meth:`OccupancyGrid.adjacency` and :meth:`OccupancyGrid.to_networkx` define it:

* a cell ``(col, row)`` connects to its 4 orthogonal neighbours (cost ``resolution``) and, with
  ``diagonal=True``, to its 4 diagonal neighbours (cost ``sqrt(2) * resolution``);
* without ``corner_cutting`` (the default, and the MovingAI rule) a diagonal step is allowed only
  when *both* orthogonal cells it passes between are free.

Both return the optimal length (which of several equally short paths is returned is unspecified,
but it is deterministic). Both run one heap search (:func:`_search`), compiled
(``hybridnav/native/gridheap.c``: ~0.15 us per expanded node) where a compiler is found, else as a
Python loop (:mod:`heapq`); the two give the same cells, length and ``expanded`` (the kernel runs
the same keys, tie rule and updates). The search runs on flat indices of the grid padded with one
ring of blocked cells, and a per-cell bitmask of legal moves (computed once with numpy, cached per
grid while its ``occ`` is unchanged) selects the legal ``(offset, cost)`` pairs: no bounds,
obstacle or corner tests in the loop. A* breaks ties between equal ``f = g + h`` in favour of the
larger ``g`` (the node closer to the goal), with ``f`` quantized so that float rounding does not
hide exact ties; on the MovingAI arena this expands ~3.5x fewer nodes than without tie-breaking.
The heuristics offered are admissible and consistent for the connectivity they are allowed with,
so every node is expanded at most once. Dijkstra is the same search with ``h = 0``.

Without the compiled kernel, Dijkstra runs :func:`scipy.sparse.csgraph.dijkstra` (compiled) on the
same padded graph, stored
as a CSR matrix that is cached per grid like the move masks, with a distance ``limit``: first the
obstacle-free distance to the goal (a lower bound, and the answer whenever some obstacle-free
shortest path exists); when the goal lies beyond it, the search continues from the rim of the
explored ball through a virtual source node (one extra CSR row whose edges carry the rim's
distances), with a new limit from an A*-style lower bound over the rim. Its distances are the
same floating-point numbers the heap search computes (both take the smallest ``g(u) + cost``
over the neighbours, and adding a positive step is monotone), so the path is rebuilt from them
with the heap search's own tie rule and the result -- cells, length, ``expanded`` -- is the one
``astar(..., heuristic="zero")`` gives (see :class:`_HeapOrder`); scipy's predecessors are not
used, as they break ties differently. Unreachable goals are answered from cached connected
components without a search. The cached graph takes ~12 bytes per edge (~100 bytes per free
cell: ~17 MB for 400 x 400 cells), held while the grid object lives.

Functions
---------
astar, dijkstra
    Search between two cells ``(col, row)``.
search_world
    The same between two world points (each mapped to the cell that contains it).
path_cost
    Check a cell path move by move and return its length.
"""

from __future__ import annotations

import functools
import heapq
import logging
import math
import sys
import threading
import weakref
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.native import gridheap
from hybridnav.world.grid import OccupancyGrid, world_point

__all__ = ["HEURISTICS", "GridPath", "astar", "dijkstra", "path_cost", "search_world"]

log = logging.getLogger(__name__)

_SQRT2 = math.sqrt(2.0)

#: Heuristic names accepted by :func:`astar`.
HEURISTICS: tuple[str, ...] = ("octile", "euclidean", "manhattan", "zero")

# Shrinks the heuristic by a relative 1e-12 so that float rounding in h (compared with the summed
# step costs in g) can never make it overestimate.
_H_SHRINK = 1.0 - 1e-12


@dataclass(eq=False)
class GridPath:
    """Result of a grid search.

    Attributes
    ----------
    found : bool
        Whether the goal is reachable.
    cells : ndarray of int, shape (K, 2)
        ``(col, row)`` cells from start to goal inclusive; shape ``(0, 2)`` when not found.
    points : ndarray of float, shape (K, 2)
        World coordinates of the cell centres of ``cells``.
    length : float
        Path length in world units (sum of step costs); ``inf`` when not found.
    expanded : int
        Number of nodes expanded (popped from the heap and closed). For :func:`dijkstra`, the number
        its heap search would close: the nodes nearer than the goal, the goal, and the equally near
        nodes it pops first (computed from the distances; scipy may scan a few more, up to its limit).
    start, goal : (int, int)
        The cells searched between.
    method : str
        ``"astar"`` or ``"dijkstra"``.
    params : dict
        The options used (``diagonal``, ``corner_cutting``, and ``heuristic`` for A*).
    """

    found: bool
    cells: NDArray[np.int_]
    points: NDArray[np.float64]
    length: float
    expanded: int
    start: tuple[int, int]
    goal: tuple[int, int]
    method: str
    params: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.cells.shape[0])

    def __repr__(self) -> str:
        return (f"GridPath(method={self.method!r}, found={self.found}, length={self.length:.6g}, "
                f"cells={len(self)}, expanded={self.expanded})")


# --------------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------------


def _check_grid(grid: Any) -> OccupancyGrid:
    if not isinstance(grid, OccupancyGrid):
        raise HybridnavError(f"grid: expected an OccupancyGrid, got {type(grid).__name__}")
    return grid


def _as_cell(value: Any, name: str) -> tuple[int, int]:
    """A ``(col, row)`` pair of integers (integral floats accepted)."""
    if type(value) is tuple and len(value) == 2 and type(value[0]) is int and type(value[1]) is int:
        return value
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise HybridnavError(f"{name}: expected a cell (col, row) of two integers, got {value!r}") from None
    if a.shape != (2,) or not np.all(np.isfinite(a)) or not np.all(a == np.round(a)):
        raise HybridnavError(f"{name}: expected a cell (col, row) of two integers, got {value!r}")
    return int(a[0]), int(a[1])


def _check_endpoint(grid: OccupancyGrid, cell: tuple[int, int], name: str, extra: str = "") -> None:
    c, r = cell
    if not (0 <= c < grid.width and 0 <= r < grid.height):
        raise HybridnavError(f"{name}: cell {cell}{extra} is outside the {grid.width}x{grid.height} grid "
                             f"(expected 0 <= col < {grid.width}, 0 <= row < {grid.height})")
    if grid.occ[r, c]:
        raise HybridnavError(f"{name}: cell {cell}{extra} is blocked; expected a free cell")


def _check_flags(diagonal: Any, corner_cutting: Any) -> tuple[bool, bool]:
    for nm, v in (("diagonal", diagonal), ("corner_cutting", corner_cutting)):
        if not isinstance(v, (bool, np.bool_)):
            raise HybridnavError(f"{nm}: expected True or False, got {v!r}")
    return bool(diagonal), bool(corner_cutting)


# --------------------------------------------------------------------------------------------
# Core search
# --------------------------------------------------------------------------------------------


# The 8 moves as (dcol, drow); bit k of a cell's move mask says whether move k is legal there.
_MOVES: tuple[tuple[int, int], ...] = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, 1), (1, -1), (-1, -1))


def _move_masks(occ: NDArray[np.bool_], diagonal: bool, corner_cutting: bool) -> tuple[bytes, int]:
    """Legal-move bitmask of every cell of the grid padded by one blocked ring (vectorized).

    Returns the row-major masks of the ``(H + 2) x (W + 2)`` padded grid as bytes (0 for blocked
    and ring cells) and the padded width. Bit ``k`` is set when move ``_MOVES[k]`` leads to a free
    cell and, for a diagonal move without corner cutting, both orthogonal cells it passes between
    are free -- the same edges as :meth:`OccupancyGrid.adjacency`.
    """
    H, W = occ.shape
    F = np.zeros((H + 2, W + 2), dtype=bool)
    F[1:-1, 1:-1] = ~occ

    def sh(dc: int, dr: int) -> NDArray[np.bool_]:  # F at (row + dr, col + dc), interior cells
        return F[1 + dr:H + 1 + dr, 1 + dc:W + 1 + dc]

    inner = sh(0, 0)
    mask = np.zeros((H, W), dtype=np.uint8)
    for k, (dc, dr) in enumerate(_MOVES):
        if k >= 4 and not diagonal:
            break
        ok = inner & sh(dc, dr)
        if k >= 4 and not corner_cutting:
            ok &= sh(dc, 0) & sh(0, dr)
        mask |= ok.astype(np.uint8) << k
    out = np.zeros((H + 2, W + 2), dtype=np.uint8)
    out[1:-1, 1:-1] = mask
    return out.tobytes(), W + 2


_MASK_CACHE: weakref.WeakKeyDictionary[OccupancyGrid, dict] = weakref.WeakKeyDictionary()


def _cached_masks(grid: OccupancyGrid, diagonal: bool, corner_cutting: bool) -> tuple[bytes, int]:
    """:func:`_move_masks` of ``grid``, reused while its ``occ`` content is unchanged.

    Repeated queries on one grid (benchmarks, RFD-PSO restarts) skip the O(H W) numpy pass; a
    byte comparison of ``occ`` detects in-place edits and reassignment.
    """
    occ = np.ascontiguousarray(grid.occ, dtype=bool)
    key = (occ.shape, diagonal, corner_cutting)
    raw = occ.tobytes()
    try:
        entry = _MASK_CACHE.setdefault(grid, {})
    except TypeError:  # not weak-referenceable (a subclass with __slots__): no cache
        return _move_masks(occ, diagonal, corner_cutting)
    hit = entry.get(key)
    if hit is not None and hit[0] == raw:
        return hit[1]
    out = _move_masks(occ, diagonal, corner_cutting)
    if len(entry) >= 4:
        entry.clear()
    entry[key] = (raw, out)
    return out


@functools.lru_cache(maxsize=64)
def _move_table(Wp: int, res: float) -> tuple[tuple[tuple[int, float], ...], ...]:
    """For each of the 256 masks, the legal ``(flat offset, cost)`` pairs of the padded grid."""
    steps = [(dc + dr * Wp, res * (_SQRT2 if dc and dr else 1.0)) for dc, dr in _MOVES]
    return tuple(tuple(steps[k] for k in range(8) if m >> k & 1) for m in range(256))


@functools.lru_cache(maxsize=64)
def _move_tables_by_kind(Wp: int, res: float) -> tuple[tuple, tuple]:
    """:func:`_move_table` split into the straight and the diagonal moves of each mask."""
    table = _move_table(Wp, res)
    straight = tuple(tuple(e for e in moves if e[1] == res) for moves in table)
    diagonal = tuple(tuple(e for e in moves if e[1] != res) for moves in table)
    return straight, diagonal


def _kernel_heuristic(Hp: int, Wp: int, gx: int, gy: int, res: float, heuristic: str,
                      diagonal: bool) -> tuple:
    """The heuristic as :func:`hybridnav.native.gridheap.search` takes it: the name and the
    numbers :func:`_heuristic_table` computes it from, or that table (Euclidean: NumPy's hypot)."""
    if heuristic == "euclidean":
        return ("table", _heuristic_table(Hp, Wp, gx, gy, res, heuristic, diagonal))
    if heuristic == "octile" and not diagonal:
        heuristic = "manhattan"
    return (heuristic, Wp, float(gx), float(gy), _SQRT2 - 1.0, res * _H_SHRINK)


def _heuristic_table(Hp: int, Wp: int, gx: int, gy: int, res: float, heuristic: str, diagonal: bool) -> array:
    """Heuristic of every padded cell, computed with numpy.

    Returned as an ``array('d')`` (a copy of the numpy buffer): indexing it creates Python floats
    only for the cells the search touches, where ``tolist()`` would create one per cell.
    """
    if heuristic == "zero":
        return array("d", bytes(8 * Hp * Wp))
    dx = np.abs(np.arange(Wp, dtype=float) - gx)[None, :]
    dy = np.abs(np.arange(Hp, dtype=float) - gy)[:, None]
    if heuristic == "euclidean":
        h = np.hypot(dx, dy)
    elif heuristic == "manhattan" or not diagonal:
        h = dx + dy
    else:  # octile
        h = np.maximum(dx, dy) + (_SQRT2 - 1.0) * np.minimum(dx, dy)
    h *= res * _H_SHRINK
    return array("d", h.tobytes())


def _search(
    grid: OccupancyGrid,
    start: tuple[int, int],
    goal: tuple[int, int],
    diagonal: bool,
    corner_cutting: bool,
    heuristic: str,
    method: str,
) -> GridPath:
    masks, Wp = _cached_masks(grid, diagonal, corner_cutting)
    n = len(masks)
    res = _resolution(grid, n)
    s = (start[1] + 1) * Wp + start[0] + 1
    t = (goal[1] + 1) * Wp + goal[0] + 1
    hargs = (grid.height + 2, Wp, goal[0] + 1, goal[1] + 1, res, heuristic, diagonal)

    # Heap keys use f quantized to q, so that float rounding does not hide exact ties (which the
    # larger-g rule then breaks). With octile, Manhattan or zero heuristics every f is an exact
    # a + b*sqrt(2) (a, b integers below ~n), and two different such values differ by far more than
    # q: the quantization merges only values that are equal, and optimality is exact. (With the
    # Euclidean heuristic it could reorder f values closer than q, costing at most q per step.)
    # The max() keeps f / q below 2**52 on very large grids.
    q = res * _quantum(n)
    params = {"diagonal": diagonal, "corner_cutting": corner_cutting}
    if method == "astar":
        params["heuristic"] = heuristic
    offs, costs = _move_arrays(Wp, res)
    done = gridheap.search(masks, s, t, offs, costs, q, _kernel_heuristic(*hargs))  # compiled
    if done is not None:
        flat, length, expanded = done
        return _grid_path(grid, start, goal, flat, length, expanded, Wp, method, params)
    table = _move_table(Wp, res)
    h = _heuristic_table(*hargs)
    INF = math.inf
    g = array("d", [INF]) * n
    parent = array("q", [-1]) * n
    closed = bytearray(n)
    g[s] = 0.0
    heap: list[tuple[float, float, int]] = [(h[s] // q, -0.0, s)]
    push, pop = heapq.heappush, heapq.heappop
    expanded = 0
    found = False
    while heap:
        _, _, u = pop(heap)
        if closed[u]:
            continue  # stale entry of an already closed node
        closed[u] = 1
        expanded += 1
        if u == t:
            found = True
            break
        gu = g[u]
        for off, cost in table[masks[u]]:  # legal moves only: no bounds, obstacle or corner tests
            v = u + off
            nv = gu + cost
            if nv < g[v] and not closed[v]:
                g[v] = nv
                parent[v] = u
                # f is quantized so that float noise does not hide exact ties; on ties the
                # larger g first (for Dijkstra, h = 0 and the -nv key changes nothing)
                push(heap, ((nv + h[v]) // q, -nv, v))

    if not found:
        return _grid_path(grid, start, goal, None, math.inf, expanded, Wp, method, params)
    idx = [t]
    while idx[-1] != s:
        idx.append(parent[idx[-1]])
    flat = np.array(idx[::-1], dtype=np.int64)
    return _grid_path(grid, start, goal, flat, float(g[t]), expanded, Wp, method, params)


def _resolution(grid: OccupancyGrid, n: int) -> float:
    """The grid's resolution as a Python float, refused where the search's keys would not be
    finite, ordered numbers: the quantum ``q`` of :func:`_search` must be a normal float and
    every ``f = g + h <= 2 sqrt(2) n res`` finite (a float32 resolution is taken at its value)."""
    res = float(grid.resolution)
    if not (math.isfinite(res) and res * _quantum(n) >= sys.float_info.min
            and math.isfinite(2.0 * _SQRT2 * n * res)):
        raise HybridnavError(
            f"resolution: expected a cell size between {sys.float_info.min / _quantum(n):.3g} "
            f"and {sys.float_info.max / (2.0 * _SQRT2 * n):.3g} for a search on this "
            f"{grid.width} x {grid.height} grid (path lengths and the search's keys must be finite "
            f"normal floats), got {grid.resolution!r}")
    return res


def _quantum(n: int) -> float:
    """The heap keys' quantum of a search on ``n`` padded cells, in cells (times the resolution:
    ``q`` of :func:`_search`)."""
    return max(1e-9, 1e-15 * n)


def _grid_path(grid: OccupancyGrid, start, goal, flat: NDArray[np.int64] | None, length: float,
               expanded: int, Wp: int, method: str, params: dict) -> GridPath:
    """The :class:`GridPath` of a search's padded flat path (None: not found)."""
    if flat is None:
        empty = np.zeros((0, 2), dtype=int)
        return GridPath(False, empty, np.zeros((0, 2)), math.inf, expanded, start, goal, method, params)
    cells = np.empty((len(flat), 2), dtype=int)
    np.divmod(flat, Wp, out=(cells[:, 1], cells[:, 0]))
    cells -= 1
    return GridPath(True, cells, grid.to_world(cells), length, expanded, start, goal, method, params)


@functools.lru_cache(maxsize=64)
def _move_arrays(Wp: int, res: float) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The 8 moves' flat offsets and costs (bit ``k`` of a mask), as :func:`_move_table` has them."""
    offs = np.array([dc + dr * Wp for dc, dr in _MOVES], dtype=np.int64)
    costs = np.array([res * (_SQRT2 if dc and dr else 1.0) for dc, dr in _MOVES], dtype=np.float64)
    offs.flags.writeable = costs.flags.writeable = False
    return offs, costs


# --------------------------------------------------------------------------------------------
# Dijkstra on scipy's csgraph
# --------------------------------------------------------------------------------------------

# Each continuation of a Dijkstra search (see _dijkstra) sets its limit this much above the rim's
# A*-style lower bound on the goal's distance: a larger margin scans more nodes past the goal, a
# smaller one needs more continuations (each a scipy call and a few numpy passes over the grid).
_LIMIT_MARGIN = 1.05
# ... and scans the whole component when the first ball is estimated to hold this much of it.
_FULL_SCAN = 0.6


class _Graph:
    """The padded free-cell graph of one grid and move rules, as scipy's csgraph takes it.

    Nodes are the flat indices of the padded grid (as in :func:`_search`). The CSR arrays have
    room for one more row, node ``n``: the virtual source of a continued search, whose edges are
    written into the spare tail under ``lock``. ``base`` is the ``n x n`` graph without it (views
    of the same arrays, never written). ``label`` and ``sizes`` are the connected components.
    """

    def __init__(self, masks: bytes, Wp: int, res: float) -> None:
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import connected_components, dijkstra

        self.masks, self.Wp, self.n = masks, Wp, len(masks)
        n = self.n
        m = np.frombuffer(masks, dtype=np.uint8)
        legal = (m[:, None] >> np.arange(8, dtype=np.uint8)) & 1 == 1  # (n, 8), row-major CSR order
        offs, cost = _move_arrays(Wp, res)
        rows, ks = np.nonzero(legal)
        E = rows.size
        self.E = E
        self.data = np.empty(E + n, dtype=np.float64)
        self.data[:E] = cost[ks]
        self.indices = np.empty(E + n, dtype=np.int32)
        self.indices[:E] = rows + offs[ks]
        self.indptr = np.zeros(n + 2, dtype=np.int32)
        np.cumsum(legal.sum(axis=1), out=self.indptr[1:n + 1])
        self.base = csr_matrix((self.data[:E], self.indices[:E], self.indptr[:n + 1]), shape=(n, n),
                               copy=False)
        _, label = connected_components(self.base, directed=True, connection="weak")
        self.sizes = np.bincount(label).tolist()
        free = np.zeros((n // Wp + 1, Wp + 1), dtype=np.int64)  # summed-area table of free cells
        free[1:, 1:] = (m != 0).reshape(-1, Wp).cumsum(axis=0).cumsum(axis=1)
        # memoryviews: indexing them gives Python numbers, quicker than numpy scalars
        self.label, self.free = memoryview(label), memoryview(free)
        self.table = _move_table(Wp, res)
        self.straight, self.diag = _move_tables_by_kind(Wp, res)
        self.lock = threading.Lock()
        self._csr_matrix, self.dijkstra = csr_matrix, dijkstra

    def free_cells(self, c0: int, r0: int, c1: int, r1: int) -> int:
        """Number of free cells in padded columns ``c0..c1``, rows ``r0..r1`` (clipped)."""
        c0, r0 = max(c0, 0), max(r0, 0)
        c1, r1 = min(c1, self.Wp - 1), min(r1, self.n // self.Wp - 1)
        if c0 > c1 or r0 > r1:
            return 0
        f = self.free
        return f[r1 + 1, c1 + 1] - f[r0, c1 + 1] - f[r1 + 1, c0] + f[r0, c0]

    def continued(self, seeds: NDArray[np.int_], dist: NDArray[np.float64], limit: float) -> NDArray[np.float64]:
        """Distances up to ``limit`` from a virtual source joined to each ``seeds[i]`` by an edge
        of length ``dist[i] > 0`` (scipy's ``dijkstra`` has no start distances of its own)."""
        n, E, k = self.n, self.E, seeds.size
        with self.lock:  # the tail of the shared arrays is this call's
            self.data[E:E + k] = dist
            self.indices[E:E + k] = seeds
            self.indptr[n + 1] = E + k
            g = self._csr_matrix((self.data[:E + k], self.indices[:E + k], self.indptr),
                                 shape=(n + 1, n + 1), copy=False)
            return self.dijkstra(g, indices=n, limit=limit, min_only=True)[:n]


_GRAPH_CACHE: weakref.WeakKeyDictionary[OccupancyGrid, dict] = weakref.WeakKeyDictionary()


def _cached_graph(grid: OccupancyGrid, diagonal: bool, corner_cutting: bool) -> _Graph:
    """The :class:`_Graph` of ``grid``, reused while its ``occ`` content and resolution are unchanged.

    As in :func:`_cached_masks`, a byte comparison of ``occ`` on every call detects in-place edits
    and reassignment; the resolution (the edge lengths) is part of the key.
    """
    occ = np.ascontiguousarray(grid.occ, dtype=bool)
    key = (occ.shape, diagonal, corner_cutting, float(grid.resolution))
    raw = occ.tobytes()
    try:
        entry = _GRAPH_CACHE.setdefault(grid, {})
    except TypeError:  # not weak-referenceable (a subclass with __slots__): no cache
        return _Graph(*_move_masks(occ, diagonal, corner_cutting), float(grid.resolution))
    hit = entry.get(key)
    if hit is not None and hit[0] == raw:
        return hit[1]
    out = _Graph(*_move_masks(occ, diagonal, corner_cutting), float(grid.resolution))
    if len(entry) >= 4:
        entry.clear()
    entry[key] = (raw, out)
    return out


class _HeapOrder:
    """Where nodes come in the pop order of :func:`_search` with ``h = 0``, from the distances.

    That heap pops ``(g // q, -g, node)`` entries, and pushes a node again at every improvement
    of its ``g``; a node is closed at its first pop. Its distance fixes ``g // q``, but two
    improvements can differ by float rounding alone (equally long paths summed in another
    order) and fall in the same quantum; the first of them (the larger) is then the entry that
    pops. So a node's place is ``(Q, -first, node)``: ``Q = dist // q``, ``first`` the first value
    pushed in quantum ``Q``, which is that of the neighbour popped first among those whose
    ``dist + step`` lands in ``Q`` -- usually all of them give ``dist`` itself.
    """

    def __init__(self, dist, masks: bytes, table, q: float, s: int) -> None:
        self.dist, self.masks, self.table, self.q = dist, masks, table, q
        self.first: dict[int, float] = {s: 0.0}

    def key(self, v: int) -> tuple[float, float, int]:
        return (self.dist[v] // self.q, -self._first(v), v)

    def before(self, v: int, t: int) -> bool:
        """Whether ``v`` pops before ``t`` (two different nodes of the same quantum)."""
        ft, dv = self._first(t), self.dist[v]
        if dv > ft or (dv == ft and v < t):  # first(v) >= dist(v) decides without v's neighbours
            return True
        fv = self._first(v)
        return fv > ft or (fv == ft and v < t)

    def _first(self, v: int) -> float:
        first, dist, q = self.first, self.dist, self.q
        stack = [v]
        while stack:  # iterative: each node pushed here needs nodes of smaller quanta only
            u = stack[-1]
            if u in first:
                stack.pop()
                continue
            du = dist[u]
            near = du + 2.0 * q  # every val is >= du; those in du's quantum are below this
            moves = self.table[self.masks[u]]
            for off, cost in moves:
                if du < dist[u + off] + cost < near:
                    break
            else:  # every push in du's quantum was du itself
                first[u] = du
                stack.pop()
                continue
            qu = du // q
            cands = []
            for off, cost in moves:
                val = dist[u + off] + cost
                if val < near and val // q == qu:
                    cands.append((u + off, val))
            if all(val == du for _, val in cands):
                first[u] = du
                stack.pop()
                continue
            # the pushes come in the pop order of these neighbours; their own first values
            # matter only between neighbours of the same quantum
            quanta = [dist[w] // q for w, _ in cands]
            shared = {x for x in quanta if quanta.count(x) > 1}
            need = [w for (w, _), x in zip(cands, quanta) if x in shared and w not in first]
            if need:
                stack.extend(need)
                continue
            first[u] = min(zip(quanta, cands),
                           key=lambda e: (e[0], -first[e[1][0]] if e[0] in shared else 0.0, e[1][0]))[1][1]
            stack.pop()
        return first[v]


def _dijkstra(grid: OccupancyGrid, start: tuple[int, int], goal: tuple[int, int], diagonal: bool,
              corner_cutting: bool) -> GridPath:
    """The result of ``_search(..., "zero", "dijkstra")``: that search compiled, else computed
    with scipy (module docstring)."""
    if gridheap.available():
        return _search(grid, start, goal, diagonal, corner_cutting, "zero", "dijkstra")
    G = _cached_graph(grid, diagonal, corner_cutting)
    Wp, n = G.Wp, G.n
    res = _resolution(grid, n)
    sc, sr, tc, tr = start[0] + 1, start[1] + 1, goal[0] + 1, goal[1] + 1  # padded
    s, t = sr * Wp + sc, tr * Wp + tc
    params = {"diagonal": diagonal, "corner_cutting": corner_cutting}
    if s == t:
        return _grid_path(grid, start, goal, np.array([s], dtype=np.int64), 0.0, 1, Wp,
                          "dijkstra", params)
    if G.label[s] != G.label[t]:  # the heap search closes all of the start's component, in vain
        return _grid_path(grid, start, goal, None, math.inf, G.sizes[G.label[s]], Wp, "dijkstra",
                          params)

    q = res * _quantum(n)
    dx, dy = abs(sc - tc), abs(sr - tr)
    free_dist = (max(dx, dy) + (_SQRT2 - 1.0) * min(dx, dy)) if diagonal else float(dx + dy)
    # Every node whose distance is within 3 q of the goal's must be in (their order decides
    # `expanded`); the first limit is at least 2 resolutions, so that a continuation's rim never
    # holds the start (a zero-length edge from the virtual source).
    limit = max(res * free_dist * (1.0 + 1e-9), 2.0 * res) + 4.0 * q
    c0, c1 = (sc, tc) if sc < tc else (tc, sc)
    r0, r1 = (sr, tr) if sr < tr else (tr, sr)
    f = G.free  # summed-area table: the free cells of the box between start and goal
    if f[r1 + 1, c1 + 1] - f[r0, c1 + 1] - f[r1 + 1, c0] + f[r0, c0] < (dx + 1) * (dy + 1):
        # An obstacle between them: the goal may lie beyond that limit. When the ball up to it
        # would hold most of the start's component anyway (estimated from the free cells of its
        # bounding square), scan the component at once.
        r = int(free_dist) + 1  # the ball (an octagon, or a diamond) fills ~0.71 (0.5) of the square
        ball = G.free_cells(sc - r, sr - r, sc + r, sr + r) * (0.71 if diagonal else 0.5)
        if ball >= _FULL_SCAN * G.sizes[G.label[s]]:
            limit = math.inf
    dist = G.dijkstra(G.base, indices=s, limit=limit, min_only=True)  # min_only: a little faster
    while not dist[t] + 3.0 * q <= limit:
        # The goal lies beyond: continue from the rim (the nodes with a neighbour outside the ball
        # have dist > limit - sqrt(2) res), with an A*-style bound: any path to the goal leaves
        # through the rim, so it is at least min(dist + the obstacle-free distance to the goal).
        rim = np.flatnonzero(dist > limit - _SQRT2 * res)
        rim = rim[dist[rim] <= limit]
        ddx = np.abs(rim % Wp - tc)
        ddy = np.abs(rim // Wp - tr)
        h = (np.maximum(ddx, ddy) + (_SQRT2 - 1.0) * np.minimum(ddx, ddy)) if diagonal else ddx + ddy
        bound = float(np.min(dist[rim] + res * h))
        new_limit = max(bound * _LIMIT_MARGIN, limit + 2.0 * res) + 4.0 * q
        more = G.continued(rim, dist[rim], new_limit)
        dist = np.where(dist <= limit, dist, more)  # inside the old ball, `more` may be too long
        limit = new_limit

    dv = memoryview(dist)  # Python floats, as _search computes them
    gt = dv[t]
    order = None  # the heap order, needed only where ties are to be broken
    # expanded: the nodes popped before the goal, and the goal
    lo, hi = gt - 3.0 * q, gt + 3.0 * q
    expanded = int(np.count_nonzero(dist < lo)) + 1
    near = np.flatnonzero((dist >= lo) & (dist <= hi)).tolist()
    if len(near) > 1:  # nodes as near as the goal (ties, or float noise): the heap order decides
        qt = gt // q
        order = _HeapOrder(dv, G.masks, G.table, q, s)
        for v in near:
            if v != t:
                qv = dv[v] // q
                expanded += qv < qt or (qv == qt and order.before(v, t))
    # The path: _search makes a node's parent the neighbour popped first among those giving its
    # distance (it replaces a parent only on a strict improvement). A diagonal one is nearer the
    # start by (sqrt(2) - 1) resolution, so popped before any straight one; between two of a kind,
    # their heap order decides.
    straight, diag, masks = G.straight, G.diag, G.masks
    idx = [t]
    v = t
    while v != s:
        gv, m = dv[v], masks[v]
        u = -1  # the parent; -2: more than one candidate (plain loops: quicker than comprehensions)
        for moves in (diag[m], straight[m]):
            for off, cost in moves:
                if dv[v + off] + cost == gv:
                    u = v + off if u == -1 else -2
            if u != -1:
                break
        if u == -2:
            if order is None:
                order = _HeapOrder(dv, G.masks, G.table, q, s)
            u = min((v + off for off, cost in moves if dv[v + off] + cost == gv), key=order.key)
        v = u
        idx.append(v)
    idx.reverse()
    return _grid_path(grid, start, goal, np.array(idx, dtype=np.int64), gt, expanded, Wp,
                      "dijkstra", params)


def _prepare(grid: Any, start: Any, goal: Any, diagonal: Any, corner_cutting: Any):
    grid = _check_grid(grid)
    diagonal, corner_cutting = _check_flags(diagonal, corner_cutting)
    s = _as_cell(start, "start")
    t = _as_cell(goal, "goal")
    _check_endpoint(grid, s, "start")
    _check_endpoint(grid, t, "goal")
    return grid, s, t, diagonal, corner_cutting


def _check_heuristic(heuristic: Any, diagonal: bool) -> str:
    if heuristic is None:
        return "zero"
    if not isinstance(heuristic, str) or heuristic not in HEURISTICS:
        raise HybridnavError(f"heuristic: expected one of {', '.join(HEURISTICS)}, got {heuristic!r}")
    if heuristic == "manhattan" and diagonal:
        raise HybridnavError("heuristic: 'manhattan' overestimates diagonal moves (not admissible); "
                             "use 'octile' or 'euclidean', or diagonal=False")
    return heuristic


def astar(
    grid: OccupancyGrid,
    start: Sequence[int] | ArrayLike,
    goal: Sequence[int] | ArrayLike,
    *,
    diagonal: bool = True,
    corner_cutting: bool = False,
    heuristic: str | None = "octile",
) -> GridPath:
    """Shortest path between two cells by A*.

    Parameters
    ----------
    grid : OccupancyGrid
    start, goal : (int, int)
        Cells ``(col, row)``; both must be inside the grid and free.
    diagonal : bool
        8-connected octile moves (straight step ``resolution``, diagonal step
        ``sqrt(2) * resolution``); False gives 4-connected moves.
    corner_cutting : bool
        Allow a diagonal step past a blocked orthogonal neighbour. False (default) requires both
        orthogonal cells of a diagonal step to be free, the MovingAI benchmark rule.
    heuristic : {"octile", "euclidean", "manhattan", "zero"} or None
        Distance-to-goal estimate in world units. ``"octile"`` is the exact obstacle-free distance
        of 8-connected moves (with ``diagonal=False`` it becomes Manhattan distance); all choices
        are admissible and consistent for the connectivity they are allowed with
        (``"manhattan"`` only with ``diagonal=False``). ``"zero"`` / None is Dijkstra's order.

    Returns
    -------
    GridPath
        ``found=False`` with ``length = inf`` and an empty path when the goal is unreachable.

    Raises
    ------
    HybridnavError
        ``start`` or ``goal`` is not a cell, lies outside the grid, or is blocked (the message
        names which); an unknown ``heuristic``.

    Examples
    --------
    >>> from hybridnav.world.grid import OccupancyGrid
    >>> import numpy as np
    >>> occ = np.zeros((3, 4), dtype=bool); occ[0:2, 1] = True
    >>> p = astar(OccupancyGrid(occ), (0, 0), (3, 0))
    >>> round(p.length, 6), p.cells.tolist()
    (6.414214, [[0, 0], [0, 1], [0, 2], [1, 2], [2, 2], [3, 1], [3, 0]])
    """
    grid, s, t, diagonal, corner_cutting = _prepare(grid, start, goal, diagonal, corner_cutting)
    h = _check_heuristic(heuristic, diagonal)
    return _search(grid, s, t, diagonal, corner_cutting, h, "astar")


def dijkstra(
    grid: OccupancyGrid,
    start: Sequence[int] | ArrayLike,
    goal: Sequence[int] | ArrayLike,
    *,
    diagonal: bool = True,
    corner_cutting: bool = False,
) -> GridPath:
    """Shortest path between two cells by Dijkstra's algorithm (stops when the goal is closed).

    The search is :func:`astar`'s with ``h = 0`` (compiled where a compiler is found). Without
    the compiled kernel it runs in :func:`scipy.sparse.csgraph.dijkstra` on a graph cached per
    grid (rebuilt when ``occ`` or ``resolution`` changes), with a distance limit instead of a stop
    at the goal, and reproduces that heap search's result exactly (ties as
    ``astar(..., heuristic="zero")`` breaks them).

    Parameters
    ----------
    grid : OccupancyGrid
    start, goal : (int, int)
        Cells ``(col, row)``; both must be inside the grid and free.
    diagonal, corner_cutting : bool
        As in :func:`astar`.

    Returns
    -------
    GridPath
        ``found=False`` with ``length = inf`` when the goal is unreachable.

    Raises
    ------
    HybridnavError
        ``start`` or ``goal`` is not a cell, lies outside the grid, or is blocked.
    """
    grid, s, t, diagonal, corner_cutting = _prepare(grid, start, goal, diagonal, corner_cutting)
    return _dijkstra(grid, s, t, diagonal, corner_cutting)


def search_world(
    grid: OccupancyGrid,
    start: ArrayLike,
    goal: ArrayLike,
    *,
    method: str = "astar",
    diagonal: bool = True,
    corner_cutting: bool = False,
    heuristic: str | None = "octile",
) -> GridPath:
    """Shortest grid path between two world points.

    Each point is mapped to the cell that contains it (:meth:`OccupancyGrid.to_cell`); the path's
    ``points`` are cell centres, so the first and last points are the centres of those cells, not
    the given points.

    Parameters
    ----------
    grid : OccupancyGrid
    start, goal : array_like, shape (2,)
        World coordinates ``(x, y)``.
    method : {"astar", "dijkstra"}
    diagonal, corner_cutting, heuristic
        As in :func:`astar` (``heuristic`` is ignored by Dijkstra).

    Returns
    -------
    GridPath

    Raises
    ------
    HybridnavError
        A point is not a finite ``(x, y)`` pair, falls outside the grid or in a blocked cell.
    """
    grid = _check_grid(grid)
    cells = []
    for name, P in (("start", start), ("goal", goal)):
        p = world_point(name, P)
        c = tuple(int(v) for v in grid.to_cell(p)[0])
        _check_endpoint(grid, c, name, f" (world point ({p[0]:g}, {p[1]:g}))")
        cells.append(c)
    if method == "astar":
        return astar(grid, cells[0], cells[1], diagonal=diagonal, corner_cutting=corner_cutting,
                     heuristic=heuristic)
    if method == "dijkstra":
        return dijkstra(grid, cells[0], cells[1], diagonal=diagonal, corner_cutting=corner_cutting)
    raise HybridnavError(f"method: expected 'astar' or 'dijkstra', got {method!r}")


def path_cost(
    grid: OccupancyGrid,
    cells: ArrayLike,
    *,
    diagonal: bool = True,
    corner_cutting: bool = False,
) -> float:
    """Length of a cell path in world units, after checking every move (vectorized).

    Parameters
    ----------
    grid : OccupancyGrid
    cells : array_like of int, shape (K, 2)
        ``(col, row)`` cells, ``K >= 1``.
    diagonal, corner_cutting : bool
        Which moves are legal (as in :func:`astar`).

    Returns
    -------
    float
        Sum of step costs (``resolution`` or ``sqrt(2) * resolution``); 0 for a single cell.

    Raises
    ------
    HybridnavError
        ``cells`` is not a ``(K, 2)`` integer array, a cell is outside or blocked, a move is not
        to an 8- (or 4-) neighbour, or a diagonal move cuts a blocked corner; the message gives the
        index of the offending cell or move.
    """
    grid = _check_grid(grid)
    diagonal, corner_cutting = _check_flags(diagonal, corner_cutting)
    C = np.asarray(cells)
    if C.ndim != 2 or C.shape[1] != 2 or C.shape[0] == 0 or not np.issubdtype(C.dtype, np.integer):
        raise HybridnavError(f"cells: expected a non-empty (K, 2) integer array, got shape {C.shape} "
                             f"dtype {C.dtype}")
    bad = np.flatnonzero(grid.blocked_cells(C))
    if bad.size:
        k = int(bad[0])
        raise HybridnavError(f"cells[{k}]: cell {tuple(C[k].tolist())} is outside the grid or blocked")
    d = np.diff(C, axis=0)
    ad = np.abs(d)
    step = ad.max(axis=1, initial=0)
    nd = ad.sum(axis=1)
    bad = np.flatnonzero((step != 1) | ((nd == 2) & (not diagonal)))
    if bad.size:
        k = int(bad[0])
        raise HybridnavError(f"cells[{k + 1}]: move {tuple(C[k].tolist())} -> {tuple(C[k + 1].tolist())} "
                             f"is not a step to a {'8' if diagonal else '4'}-neighbour")
    isdiag = nd == 2
    if not corner_cutting and isdiag.any():
        a = C[:-1][isdiag]
        dd = d[isdiag]
        side1 = grid.occ[a[:, 1], a[:, 0] + dd[:, 0]]
        side2 = grid.occ[a[:, 1] + dd[:, 1], a[:, 0]]
        cut = np.flatnonzero(side1 | side2)
        if cut.size:
            k = int(np.flatnonzero(isdiag)[cut[0]])
            raise HybridnavError(f"cells[{k + 1}]: diagonal move {tuple(C[k].tolist())} -> "
                                 f"{tuple(C[k + 1].tolist())} cuts a blocked corner")
    n_diag = int(isdiag.sum())
    return float(grid.resolution * ((len(d) - n_diag) + _SQRT2 * n_diag))
