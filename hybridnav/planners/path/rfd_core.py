"""River formation dynamics (RFD) on the free-cell graph of an occupancy grid.

RFD (Rabanal, Rodríguez & Rubio, 2007-2008; applied to robot paths by Redlarski, Pałkowski &
Dąbkowski, 2013 and 2017; the RFD stage of Hassen, Amin & Al-Araji's RFD-PSO, 2023) is a
gradient-based relative of ant colony optimization. Every graph node carries an *altitude*; the
goal is a hole of altitude 0 and every other node starts at the same altitude ``altitude0``.
Drops leave the start, roll preferably down the steepest slopes, and the drops that reach the goal
*erode* the nodes they passed, which deepens the valleys of good paths. Eroded soil is returned to
all nodes as *sediment*, and drops that run into a dead end deposit soil there, which fills it in.
A short path between the start and the goal falls the same height over fewer steps, so it is
steeper, is chosen more often and is eroded more: the river converges on short paths.

One iteration (the pseudo-code of Hassen et al. section 4.1)::

    moveDrops()        # all drops, from the start, until each reaches the goal or evaporates
    analyzePaths()     # best path so far, did all drops follow one path?
    erodePaths()       # lower the nodes of the paths of the drops that reached the goal
    depositSediments() # return the eroded soil to every node; dead ends get the drops' soil

Exact formulas used here
------------------------
The graph is :meth:`OccupancyGrid.adjacency`'s: 8-connected (or 4 with ``diagonal=False``), no
corner cutting by default. ``N`` is the number of free cells (graph nodes), ``D`` the number of
drops (``drops``). Distances inside the algorithm are in *cells* (1 or ``sqrt(2)``), so the
parameters do not depend on the grid's resolution; reported lengths are in world units. With
``a0 = altitude0``, the parameters ``omega``, ``delta``, ``erosion_floor`` and ``deposit`` are
relative to the altitude scale (the code uses ``omega * a0``, ``delta * a0**2``,
``erosion_floor * a0``, ``deposit * a0``), so multiplying ``altitude0`` by a constant multiplies
the altitude field by it and changes nothing else.

* **Initial terrain.** ``altitude(goal) = 0`` throughout the run; every other node starts at
  ``a0`` (flat terrain, standard RFD, ``slope = 0``) or, with ``slope > 0``, at
  ``a0 * (1 + slope * octile(v, goal))`` (a terrain tilted towards the goal, see :func:`rfd`).

* **Gradient** (Hassen et al. eq. 7)::

      gradient(i, j) = (altitude(i) - altitude(j)) / distance(i, j)

* **Move probability** of drop ``k`` at node ``i`` (eq. 8, the standard three-case RFD rule), over
  the neighbours ``j`` the drop may enter (free, a legal move, and not yet visited by this drop in
  this iteration)::

      weight(i, j) = gradient(i, j)                       if gradient(i, j) >  tol   (downhill)
                   = omega                                if |gradient(i, j)| <= tol (flat)
                   = min(delta / |gradient(i, j)|, omega) if gradient(i, j) < -tol   (uphill)
      P_k(i, j) = weight(i, j) / sum_j' weight(i, j')

  ``tol = 1e-12 * a0``. The cap ``omega`` on uphill weights is our addition: without it an
  almost-flat uphill step (``|gradient|`` tiny) would weigh ``delta / |gradient|``, arbitrarily
  more than a flat or downhill step. Uphill steps are penalized once steeper than
  ``delta / omega`` (1e-4 with the defaults).

* **Erosion** (eq. 9), applied after all drops of the iteration have moved, for every drop that
  reached the goal and every step ``i -> j`` of its path (the goal itself is never eroded)::

      erosion(i, j) = E / ((N - 1) * D) * max(gradient(i, j), erosion_floor)
      altitude(i)  -= erosion(i, j)

  with the gradients of the altitudes at the start of the erosion phase (so the order of the
  drops does not matter), and altitudes clipped at 0, the goal's altitude. ``D`` is the *number
  of drops*, as in Hassen et al. ("the total number of drops used (D)") and Redlarski et al. --
  not a path length. ``erosion_floor`` is our reading of the rule that flat and uphill steps are
  eroded by a small constant amount: on flat terrain (every gradient 0 but the last step into
  the goal) nothing else would be eroded, and a river could only grow back from the goal one node
  per iteration. The default ``E = 0.5 * (N - 1)`` means that ``D`` drops taking the same
  downhill step of length 1 remove half of its height difference in one iteration, whatever the
  grid size.

* **Sediment** (eq. 10): the soil eroded in the iteration, ``erosionProduced``, is spread evenly
  over the ``N - 1`` nodes other than the goal::

      altitude(v) += erosionProduced / (N - 1)      for every node v != goal

  so erosion and sediment together leave the total altitude unchanged.

* **Evaporation.** A drop with no node to go to (every neighbour blocked or already visited by
  it: a dead end) evaporates and deposits ``E / ((N - 1) * D) * deposit`` of soil -- what it would
  have eroded on a step of gradient ``deposit`` -- on the node where it got stuck, raising dead
  ends so later drops avoid them. A drop that has made ``max_steps`` moves without reaching the
  goal evaporates without depositing. Drops never revisit a node within an iteration, so every
  path is loop-free and a drop makes at most ``N - 1`` moves.

* **Stopping.** After the iteration in which all ``D`` drops reached the goal along the same path
  (``"converged"``), after ``patience`` consecutive iterations without a shorter best path
  (``"no_improvement"``; this count starts at the first iteration, so a run that finds nothing
  stops too), or after ``iterations`` iterations (``"max_iterations"``). When the goal is not
  reachable from the start at all, no drops are released (``"unreachable"``); when the start is
  the goal, the one-cell path is returned at once (``"converged"``). (With ``drops=1`` the first
  drop to arrive ends the run as ``"converged"``.)

All drops move together: one vectorized numpy step moves every drop still travelling.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.params import check_int, check_real
from hybridnav.planners.path.gridsearch import (
    _MOVES,
    _as_cell,
    _check_endpoint,
    _check_flags,
    _check_grid,
)
from hybridnav.world.grid import OccupancyGrid

__all__ = ["RFD_REASONS", "RFDResult", "rfd"]

log = logging.getLogger(__name__)

_SQRT2 = math.sqrt(2.0)

#: Why :func:`rfd` stopped.
RFD_REASONS: tuple[str, ...] = ("converged", "no_improvement", "max_iterations", "unreachable")

# drop states during an iteration
_MOVING, _ARRIVED, _STUCK, _BUDGET = 0, 1, 2, 3


@dataclass(eq=False)
class RFDResult:
    """Result of :func:`rfd`.

    Attributes
    ----------
    found : bool
        Whether any drop reached the goal.
    cells : ndarray of int, shape (K, 2)
        Best (shortest) path found, ``(col, row)`` cells from start to goal; ``(0, 2)`` if none.
    points : ndarray of float, shape (K, 2)
        World coordinates of the centres of ``cells``.
    length : float
        Length of the best path in world units; ``inf`` if none.
    history : ndarray of float, shape (iterations,)
        Best length after each iteration (``inf`` until a drop first reaches the goal).
    arrivals : ndarray of int, shape (iterations,)
        Number of drops that reached the goal in each iteration.
    altitude : ndarray of float, shape (height, width)
        Final altitude field, ``altitude[row, col]``; NaN on blocked cells; 0 at the goal.
    iterations : int
        Iterations run.
    reason : str
        One of :data:`RFD_REASONS`.
    start, goal : (int, int)
    params : dict
        The parameters used (with defaults resolved).
    """

    found: bool
    cells: NDArray[np.int_]
    points: NDArray[np.float64]
    length: float
    history: NDArray[np.float64]
    arrivals: NDArray[np.int_]
    altitude: NDArray[np.float64]
    iterations: int
    reason: str
    start: tuple[int, int]
    goal: tuple[int, int]
    params: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"RFDResult(found={self.found}, length={self.length:.6g}, cells={self.cells.shape[0]}, "
                f"iterations={self.iterations}, reason={self.reason!r})")


# --------------------------------------------------------------------------------------------
# Graph
# --------------------------------------------------------------------------------------------


@dataclass(eq=False)
class _Graph:
    """Free-cell graph in compact node numbering (free cells in row-major order)."""

    nb: NDArray[np.int64]     # (N, 8) neighbour node per move, -1 where the move is illegal
    nbp: NDArray[np.int64]    # (N, 8) the same with the dummy node N instead of -1
    dist: NDArray[np.float64]  # (8,) move lengths in cells
    cols: NDArray[np.int64]   # (N,) cell column of each node
    rows: NDArray[np.int64]   # (N,) cell row of each node
    node_of: NDArray[np.int64]  # (H, W) node of each cell, -1 on blocked cells


def _build_graph(occ: NDArray[np.bool_], diagonal: bool, corner_cutting: bool) -> _Graph:
    """Neighbour table of the free cells (the edges of :meth:`OccupancyGrid.adjacency`)."""
    H, W = occ.shape
    free = ~occ
    node_of = np.full((H, W), -1, dtype=np.int64)
    rows, cols = np.nonzero(free)
    node_of[rows, cols] = np.arange(rows.size)
    F = np.zeros((H + 2, W + 2), dtype=bool)
    F[1:-1, 1:-1] = free
    P = np.full((H + 2, W + 2), -1, dtype=np.int64)
    P[1:-1, 1:-1] = node_of
    nmoves = 8 if diagonal else 4
    nb = np.full((rows.size, 8), -1, dtype=np.int64)
    for k, (dc, dr) in enumerate(_MOVES[:nmoves]):
        r2, c2 = rows + 1 + dr, cols + 1 + dc
        ok = F[r2, c2]
        if k >= 4 and not corner_cutting:
            ok &= F[rows + 1, c2] & F[r2, cols + 1]
        nb[:, k] = np.where(ok, P[r2, c2], -1)
    dist = np.array([_SQRT2 if dc and dr else 1.0 for dc, dr in _MOVES])
    nbp = np.where(nb >= 0, nb, rows.size)
    return _Graph(nb, nbp, dist, cols.astype(np.int64), rows.astype(np.int64), node_of)


def _reachable(g: _Graph, s: int, t: int) -> bool:
    """Whether ``t`` is reachable from ``s`` (vectorized frontier expansion)."""
    seen = np.zeros(g.nb.shape[0], dtype=bool)
    seen[s] = True
    frontier = np.array([s])
    while frontier.size:
        if seen[t]:
            return True
        nxt = g.nb[frontier].ravel()
        nxt = np.unique(nxt[nxt >= 0])
        nxt = nxt[~seen[nxt]]
        seen[nxt] = True
        frontier = nxt
    return bool(seen[t])


# --------------------------------------------------------------------------------------------
# The three phases (pure functions of arrays, so they can be tested one by one)
# --------------------------------------------------------------------------------------------


def _move_weights(grad: NDArray[np.float64], omega: float, delta: float, tol: float) -> NDArray[np.float64]:
    """Unnormalized move weights of eq. 8 from gradients (any shape).

    ``grad > tol``: ``grad`` (downhill); ``|grad| <= tol``: ``omega`` (flat); ``grad < -tol``:
    ``min(delta / |grad|, omega)`` (uphill). A gradient of ``-inf`` (a move to the dummy node that
    stands for "no neighbour") gets weight 0.
    """
    return np.where(grad > tol, grad, np.minimum(omega, delta / np.maximum(-grad, tol)))


def _move_drops(
    g: _Graph,
    alt: NDArray[np.float64],
    s: int,
    t: int,
    drops: int,
    max_steps: int,
    omega: float,
    delta: float,
    tol: float,
    rng: np.random.Generator,
    visited: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int8], NDArray[np.float64]]:
    """Move all drops from ``s`` until each arrives at ``t`` or evaporates (one numpy step each).

    Returns ``trail`` (steps + 1, D) (node of each drop after each step; a drop that stopped keeps
    its last node), ``nsteps`` (D,) moves made, ``state`` (D,) and ``length`` (D,) in cells.
    ``visited`` (D, N + 1) must be all False on entry; it is all False again on return.
    """
    D = drops
    nbp, invd = g.nbp, 1.0 / g.dist
    altp = np.append(alt, np.inf)  # dummy node N: gradient -inf, weight 0
    cur = np.full(D, s, dtype=np.int64)
    state = np.zeros(D, dtype=np.int8)
    nsteps = np.zeros(D, dtype=np.int64)
    length = np.zeros(D)
    visited[:, s] = True
    trail = [cur.copy()]
    moving = np.ones(D, dtype=bool)
    shrink = 1.0 - 1e-12
    for _ in range(max_steps):
        act = np.flatnonzero(moving)
        if act.size == 0:
            break
        c = cur[act]
        nb = nbp[c]                                                # (A, 8)
        w = _move_weights((altp[c][:, None] - altp[nb]) * invd, omega, delta, tol)
        w[visited[act[:, None], nb]] = 0.0
        cs = np.cumsum(w, axis=1)
        tot = cs[:, -1]
        # roulette wheel: the first move whose cumulative weight exceeds u in [0, tot); u < tot
        # strictly, so the move chosen has a positive weight
        u = rng.random(act.size) * tot * shrink
        go = tot > 0.0
        k = (cs[go] <= u[go, None]).sum(axis=1)
        mk = act[go]
        nxt = nb[go, k]
        cur[mk] = nxt
        visited[mk, nxt] = True
        nsteps[mk] += 1
        length[mk] += g.dist[k]
        stuck = act[~go]
        state[stuck] = _STUCK
        moving[stuck] = False
        arr = mk[nxt == t]
        state[arr] = _ARRIVED
        moving[arr] = False
        trail.append(cur.copy())
    state[moving] = _BUDGET
    T = np.stack(trail)
    # reset the visited flags this iteration set (cheaper than clearing D x N)
    visited[np.arange(D)[None, :], T] = False
    return T, nsteps, state, length


def _path_edges(
    trail: NDArray[np.int64], nsteps: NDArray[np.int64], which: NDArray[np.bool_]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Steps ``(i, j)`` of the paths of the drops selected by ``which`` (all drops' steps stacked)."""
    m = np.arange(trail.shape[0] - 1)[:, None]
    sel = (m < nsteps[None, :]) & which[None, :]
    return trail[:-1][sel], trail[1:][sel]


def _erode(
    alt: NDArray[np.float64],
    src: NDArray[np.int64],
    dst: NDArray[np.int64],
    dist: NDArray[np.float64],
    coef: float,
    erosion_floor: float,
) -> tuple[NDArray[np.float64], float]:
    """Erosion of eq. 9: ``altitude(i) -= coef * max(gradient(i, j), erosion_floor)`` per step.

    ``coef = E / ((N - 1) D)``; all steps use the gradients of ``alt`` as given; altitudes are
    clipped at 0. Returns the new altitudes and the total amount eroded.
    """
    grad = (alt[src] - alt[dst]) / dist
    amount = coef * np.maximum(grad, erosion_floor)
    dec = np.bincount(src, weights=amount, minlength=alt.size)
    new = np.maximum(alt - dec, 0.0)
    return new, float((alt - new).sum())


def _deposit(
    alt: NDArray[np.float64], t: int, eroded: float, stuck_nodes: NDArray[np.int64], amount: float
) -> NDArray[np.float64]:
    """Sediment of eq. 10 (``eroded / (N - 1)`` on every node but the goal) and dead-end deposits."""
    out = alt + eroded / (alt.size - 1) if alt.size > 1 else alt.copy()
    if stuck_nodes.size:
        out += amount * np.bincount(stuck_nodes, minlength=alt.size)
    out[t] = 0.0
    return out


# --------------------------------------------------------------------------------------------
# Public entry point
# --------------------------------------------------------------------------------------------


def rfd(
    grid: OccupancyGrid,
    start: ArrayLike,
    goal: ArrayLike,
    *,
    drops: int = 20,
    iterations: int = 300,
    patience: int = 60,
    seed: int | np.random.Generator | None = None,
    diagonal: bool = True,
    corner_cutting: bool = False,
    altitude0: float = 1.0,
    slope: float = 0.0,
    erosion: float | None = None,
    erosion_floor: float = 0.01,
    omega: float = 1e-3,
    delta: float = 1e-7,
    deposit: float = 0.05,
    max_steps: int | None = None,
) -> RFDResult:
    """River formation dynamics between two cells of a grid.

    See the module docstring for the exact formulas (move probabilities, erosion, sediment,
    evaporation, stopping rules).

    Parameters
    ----------
    grid : OccupancyGrid
    start, goal : (int, int)
        Cells ``(col, row)``, inside the grid and free.
    drops : int
        Number of drops ``D`` released from ``start`` in every iteration.
    iterations : int
        Hard cap on iterations.
    patience : int
        Stop after this many consecutive iterations without a shorter best path.
    seed : int, numpy.random.Generator or None
        Seed of the generator that drives all random choices; equal seeds give equal results.
    diagonal, corner_cutting : bool
        Graph connectivity, as in :func:`hybridnav.planners.path.gridsearch.astar`.
    altitude0 : float
        Initial altitude of every node except the goal (altitude 0).
    slope : float
        0 (default) starts from the flat terrain of standard RFD. A positive value tilts the
        initial terrain towards the goal: node ``v`` starts at
        ``altitude0 * (1 + slope * octile(v, goal))`` (octile distance in cells), so that drops
        head for the goal from the first iteration. This is the "how far away it is from the
        target" that Hassen et al. store with each node at initialization; it makes RFD usable
        on large grids, where drops on flat terrain rarely reach the goal at all (``0.01`` gave
        paths within a few percent of optimal on the 49 x 49 MovingAI arena and the 70 x 70
        RFD-PSO scenario grid in our runs).
    erosion : float or None
        Erosion coefficient ``E`` of eq. 9; None means ``0.5 * (N - 1)``.
    erosion_floor : float
        Smallest gradient (altitude per cell, relative to ``altitude0``) in the erosion formula:
        flat, uphill and gently falling steps erode as if their gradient were ``erosion_floor``;
        0 disables the erosion of flat and uphill steps.
    omega : float
        Weight of a flat move (relative to ``altitude0`` per cell).
    delta : float
        Uphill moves weigh ``delta / |gradient|`` (gradients relative to ``altitude0``), capped
        at ``omega``.
    deposit : float
        Dead-end deposit, as a gradient: a drop that gets stuck leaves
        ``E / ((N - 1) D) * deposit * altitude0`` of soil on its dead end.
    max_steps : int or None
        Moves a drop may make per iteration; None means ``N - 1``, the most a drop that never
        revisits a node can make.

    Returns
    -------
    RFDResult

    Raises
    ------
    HybridnavError
        ``start``/``goal`` not a free cell inside the grid, or a parameter out of range (the
        message names it).

    Examples
    --------
    >>> import numpy as np
    >>> from hybridnav.world.grid import OccupancyGrid
    >>> r = rfd(OccupancyGrid(np.zeros((6, 6), dtype=bool)), (0, 0), (5, 5), seed=1)
    >>> r.found, round(r.length, 4), r.reason, float(r.altitude[5, 5])
    (True, 7.0711, 'converged', 0.0)
    """
    grid = _check_grid(grid)
    diagonal, corner_cutting = _check_flags(diagonal, corner_cutting)
    sc, gc = _as_cell(start, "start"), _as_cell(goal, "goal")
    _check_endpoint(grid, sc, "start")
    _check_endpoint(grid, gc, "goal")
    drops = check_int("drops", drops)
    iterations = check_int("iterations", iterations)
    patience = check_int("patience", patience)
    altitude0 = check_real("altitude0", altitude0, 0.0, lo_open=True)
    slope = check_real("slope", slope, 0.0)
    erosion_floor = check_real("erosion_floor", erosion_floor, 0.0)
    omega = check_real("omega", omega, 0.0, lo_open=True)
    delta = check_real("delta", delta, 0.0, lo_open=True)
    deposit = check_real("deposit", deposit, 0.0)
    if max_steps is not None:
        max_steps = check_int("max_steps", max_steps)
    if isinstance(seed, bool) or not (seed is None or isinstance(seed, np.random.Generator)
                                      or (isinstance(seed, (int, np.integer)) and seed >= 0)):
        raise HybridnavError(f"seed: expected a non-negative integer, a numpy Generator or None, got {seed!r}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)

    g = _build_graph(grid.occ, diagonal, corner_cutting)
    N = g.nb.shape[0]
    s = int(g.node_of[sc[1], sc[0]])
    t = int(g.node_of[gc[1], gc[0]])
    E = 0.5 * (N - 1) if erosion is None else check_real("erosion", erosion, 0.0, lo_open=True)
    steps_cap = max(N - 1, 1) if max_steps is None else max_steps
    params = dict(drops=drops, iterations=iterations, patience=patience, diagonal=diagonal,
                  corner_cutting=corner_cutting, altitude0=altitude0, slope=slope, erosion=E,
                  erosion_floor=erosion_floor, omega=omega, delta=delta, deposit=deposit,
                  max_steps=steps_cap)

    alt = np.full(N, altitude0)
    if slope > 0:
        dx, dy = np.abs(g.cols - gc[0]), np.abs(g.rows - gc[1])
        alt *= 1.0 + slope * (np.maximum(dx, dy) + (_SQRT2 - 1.0) * np.minimum(dx, dy))
    alt[t] = 0.0

    def field_of(a: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.full(grid.shape, np.nan)
        out[g.rows, g.cols] = a
        return out

    def result(cells_nodes: NDArray[np.int64] | None, best: float, hist: list[float], arr: list[int],
               reason: str) -> RFDResult:
        if cells_nodes is None:
            cells = np.zeros((0, 2), dtype=int)
            pts = np.zeros((0, 2))
        else:
            cells = np.column_stack([g.cols[cells_nodes], g.rows[cells_nodes]]).astype(int)
            pts = grid.to_world(cells)
        return RFDResult(cells_nodes is not None, cells, pts, best * grid.resolution,
                         np.asarray(hist, dtype=float) * grid.resolution, np.asarray(arr, dtype=int),
                         field_of(alt), len(hist), reason, sc, gc, params)

    if s == t:
        return result(np.array([s]), 0.0, [0.0], [drops], "converged")
    if not _reachable(g, s, t):
        log.info("rfd: goal %s unreachable from start %s", gc, sc)
        return result(None, math.inf, [], [], "unreachable")

    # scale-free parameters: gradients are compared in units of altitude0 per cell
    tol = 1e-12 * altitude0
    w_omega, w_delta = omega * altitude0, delta * altitude0 * altitude0
    floor = erosion_floor * altitude0
    coef = E / ((N - 1) * drops)
    visited = np.zeros((drops, N + 1), dtype=bool)

    best_len, best_path = math.inf, None
    hist: list[float] = []
    arr: list[int] = []
    stale = 0
    reason = "max_iterations"
    for it in range(iterations):
        T, nsteps, state, length = _move_drops(g, alt, s, t, drops, steps_cap, w_omega, w_delta, tol,
                                               rng, visited)
        arrived = state == _ARRIVED
        # analyzePaths: best path so far; did all drops follow one path?
        improved = False
        if arrived.any():
            k = int(np.flatnonzero(arrived)[np.argmin(length[arrived])])
            if length[k] < best_len - 1e-12:
                best_len = float(length[k])
                best_path = T[:nsteps[k] + 1, k].copy()
                improved = True
        same = bool(arrived.all()) and bool(np.all(nsteps == nsteps[0])) and \
            bool(np.all(T[:, :] == T[:, :1]))
        # erodePaths + depositSediments
        src, dst = _path_edges(T, nsteps, arrived)
        if src.size:
            d = np.where((g.cols[src] != g.cols[dst]) & (g.rows[src] != g.rows[dst]), _SQRT2, 1.0)
            alt, eroded = _erode(alt, src, dst, d, coef, floor)
        else:
            eroded = 0.0
        stuck_nodes = T[nsteps[state == _STUCK], np.flatnonzero(state == _STUCK)]
        alt = _deposit(alt, t, eroded, stuck_nodes, coef * deposit * altitude0)
        hist.append(best_len)
        arr.append(int(arrived.sum()))
        stale = 0 if improved else stale + 1
        if same:
            reason = "converged"
            break
        if stale >= patience:
            reason = "no_improvement"
            break
    log.debug("rfd: %d iterations, best %.6g, %s", len(hist), best_len, reason)
    return result(best_path, best_len, hist, arr, reason)
