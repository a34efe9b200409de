"""Occupancy grids: rasterized worlds and MovingAI benchmark maps.

Convention
----------
An :class:`OccupancyGrid` stores ``occ[row, col]`` (True = blocked) with ``height`` rows and
``width`` columns. Cell ``(col, row)`` is the square

    ``[x0 + col*res, x0 + (col+1)*res) x [y0 + row*res, y0 + (row+1)*res)``

where ``(x0, y0) = origin`` is the lower-left corner of cell ``(0, 0)`` in world coordinates and
``res = resolution``. So the column index grows with x and the row index grows with y.

Cells are addressed as ``(col, row)`` pairs, i.e. ``(x, y)`` order, in ``(N, 2)`` integer arrays.

MovingAI maps use exactly this convention with ``origin = (0, 0)`` and ``resolution = 1``: the
benchmark's ``(x, y)`` is ``(column, row)`` with row 0 the *first* line of the file, so
world ``y`` equals the file's row number and a MovingAI cell ``(x, y)`` has its centre at
world ``(x + 0.5, y + 0.5)``. (Drawn with y up, as :mod:`hybridnav.plotting` does, a map appears
flipped upside down relative to its text file; distances and paths are unaffected.)

MovingAI terrain: ``.`` ``G`` (ground) and ``S`` (swamp) are passable; ``@`` ``O`` (out of
bounds), ``T`` (trees) and ``W`` (water) are blocked. Water is "passable only from water" in the
benchmark's rules; hybridnav treats it as blocked.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError, where
from hybridnav.fileio import decode_text, read_text_file
from hybridnav.limits import MAX_GRID_CELLS, grid_cells
from hybridnav.params import short_repr
from hybridnav.world.builtin import builtin_data_path
from hybridnav.world.obstacles import MovingCircle, Segment
from hybridnav.world.scenario import Scenario
from hybridnav.world.world import World

__all__ = [
    "OccupancyGrid",
    "connected",
    "world_point",
    "MovingAIQuery",
    "PASSABLE",
    "BLOCKED",
    "rasterize",
    "build_grid",
    "load_movingai_map",
    "parse_movingai_map",
    "load_movingai_scen",
    "resolve_map",
]

log = logging.getLogger(__name__)

#: MovingAI terrain characters treated as passable.
PASSABLE = frozenset(".GS")
#: MovingAI terrain characters treated as blocked (``W`` water included, see module docstring).
BLOCKED = frozenset("@OTW")

_SQRT2 = math.sqrt(2.0)
_BLOCKED_CODES = np.frombuffer("".join(sorted(BLOCKED)).encode("ascii"), dtype=np.uint8)


@dataclass(eq=False)
class OccupancyGrid:
    """A boolean occupancy grid (see the module docstring for the coordinate convention).

    Parameters
    ----------
    occ : ndarray of bool, shape (height, width)
        True where the cell is blocked; ``occ[row, col]``.
    resolution : float
        Cell side length in world units.
    origin : (float, float)
        World coordinates of the lower-left corner of cell ``(0, 0)``.
    source : str or None
        Where the grid came from (map file), for messages.
    """

    occ: NDArray[np.bool_]
    resolution: float = 1.0
    origin: tuple[float, float] = (0.0, 0.0)
    source: str | None = None

    def __post_init__(self) -> None:
        self.occ = np.asarray(self.occ, dtype=bool)
        if self.occ.ndim != 2 or 0 in self.occ.shape:
            raise HybridnavError(f"occ: expected a non-empty 2-D boolean array, got shape {self.occ.shape}")
        self.resolution = float(self.resolution)
        if not (self.resolution > 0 and math.isfinite(self.resolution)):
            raise HybridnavError(f"resolution: expected a positive number, got {self.resolution!r}")
        self.origin = (float(self.origin[0]), float(self.origin[1]))

    @property
    def height(self) -> int:
        """Number of rows."""
        return int(self.occ.shape[0])

    @property
    def width(self) -> int:
        """Number of columns."""
        return int(self.occ.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``."""
        return (self.height, self.width)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """World rectangle covered: ``(xmin, xmax, ymin, ymax)`` (matplotlib's ``extent``)."""
        x0, y0 = self.origin
        return (x0, x0 + self.width * self.resolution, y0, y0 + self.height * self.resolution)

    def to_cell(self, P: ArrayLike) -> NDArray[np.int_]:
        """Cell ``(col, row)`` containing each world point (may be out of bounds).

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray of int, shape (N, 2)
        """
        P = np.atleast_2d(np.asarray(P, dtype=float))
        return np.floor((P - np.asarray(self.origin)) / self.resolution).astype(int)

    def to_world(self, cells: ArrayLike) -> NDArray[np.float64]:
        """World coordinates of cell centres.

        Parameters
        ----------
        cells : array_like of int, shape (N, 2)
            ``(col, row)`` pairs.

        Returns
        -------
        ndarray, shape (N, 2)
        """
        C = np.atleast_2d(np.asarray(cells, dtype=float))
        return np.asarray(self.origin) + (C + 0.5) * self.resolution

    def in_bounds(self, cells: ArrayLike) -> NDArray[np.bool_]:
        """Whether ``(col, row)`` cells lie inside the grid, shape (N,)."""
        C = np.atleast_2d(np.asarray(cells))
        return (C[:, 0] >= 0) & (C[:, 0] < self.width) & (C[:, 1] >= 0) & (C[:, 1] < self.height)

    def blocked_cells(self, cells: ArrayLike) -> NDArray[np.bool_]:
        """Whether ``(col, row)`` cells are blocked; out-of-bounds cells count as blocked, shape (N,)."""
        C = np.atleast_2d(np.asarray(cells, dtype=int))
        ok = self.in_bounds(C)
        out = np.ones(C.shape[0], dtype=bool)
        out[ok] = self.occ[C[ok, 1], C[ok, 0]]
        return out

    def is_free(self, P: ArrayLike) -> NDArray[np.bool_]:
        """Whether world points fall in free cells of the grid, shape (N,)."""
        return ~self.blocked_cells(self.to_cell(P))

    def cell_index(self, cells: ArrayLike) -> NDArray[np.int_]:
        """Flat node index ``row * width + col`` of ``(col, row)`` cells (the :meth:`adjacency` order)."""
        C = np.atleast_2d(np.asarray(cells, dtype=int))
        return C[:, 1] * self.width + C[:, 0]

    def _edges(self, diagonal: bool, corner_cutting: bool) -> tuple[NDArray[np.int_], NDArray[np.int_], NDArray[np.float64]]:
        """Edge list (flat indices i < j, weights) between free cells."""
        free = ~self.occ
        H, W = self.shape
        idx = np.arange(H * W).reshape(H, W)
        src, dst, wts = [], [], []

        def add(dr: int, dc: int, w: float, extra: NDArray[np.bool_] | None = None) -> None:
            r0, r1 = max(0, -dr), H - max(0, dr)
            c0, c1 = max(0, -dc), W - max(0, dc)
            ok = free[r0:r1, c0:c1] & free[r0 + dr:r1 + dr, c0 + dc:c1 + dc]
            if extra is not None:
                ok &= extra
            src.append(idx[r0:r1, c0:c1][ok])
            dst.append(idx[r0 + dr:r1 + dr, c0 + dc:c1 + dc][ok])
            wts.append(np.full(int(ok.sum()), w))

        res = self.resolution
        add(0, 1, res)
        add(1, 0, res)
        if diagonal:
            for dc in (1, -1):
                c0, c1 = max(0, -dc), W - max(0, dc)
                extra = None
                if not corner_cutting:
                    # both orthogonal neighbours of the diagonal step must be free
                    extra = free[0:H - 1, c0 + dc:c1 + dc] & free[1:H, c0:c1]
                add(1, dc, res * _SQRT2, extra)
        return np.concatenate(src), np.concatenate(dst), np.concatenate(wts)

    def adjacency(self, diagonal: bool = True, corner_cutting: bool = False):
        """Sparse symmetric adjacency matrix of free cells, weighted by step length in world units.

        Parameters
        ----------
        diagonal : bool
            Include diagonal steps (length ``sqrt(2) * resolution``); octile movement.
        corner_cutting : bool
            Allow a diagonal step when one of its two orthogonal neighbours is blocked. MovingAI's
            optimal lengths assume False.

        Returns
        -------
        scipy.sparse.csr_matrix, shape (height*width, height*width)
            Node ``row * width + col`` (see :meth:`cell_index`).
        """
        from scipy.sparse import coo_matrix

        i, j, w = self._edges(diagonal, corner_cutting)
        n = self.height * self.width
        m = coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(n, n))
        return m.tocsr()

    def to_networkx(self, diagonal: bool = True, corner_cutting: bool = False):
        """The free-cell graph as a :class:`networkx.Graph`.

        Nodes are ``(col, row)`` tuples of free cells; edges carry ``weight`` (world units).

        Parameters
        ----------
        diagonal, corner_cutting : bool
            As in :meth:`adjacency`.
        """
        import networkx as nx

        i, j, w = self._edges(diagonal, corner_cutting)
        g = nx.Graph()
        rows, cols = np.nonzero(~self.occ)
        g.add_nodes_from(zip(cols.tolist(), rows.tolist()))
        W = self.width
        g.add_weighted_edges_from(
            zip(zip((i % W).tolist(), (i // W).tolist()), zip((j % W).tolist(), (j // W).tolist()), w.tolist())
        )
        return g


# --------------------------------------------------------------------------------------------
# Rasterization
# --------------------------------------------------------------------------------------------


def rasterize(
    world: World,
    resolution: float,
    inflate: float = 0.0,
    t: float | None = None,
    border: bool = False,
) -> OccupancyGrid:
    """Rasterize a world's obstacles onto a grid covering its workspace.

    The grid's origin is ``(xmin, ymin)``; it has ``ceil((xmax-xmin)/resolution)`` columns and
    ``ceil((ymax-ymin)/resolution)`` rows. A cell is blocked when

    * its centre's clearance to a solid obstacle (circle, rectangle, polygon) is ``< inflate``
      (with ``inflate = 0``: the centre lies inside the obstacle), or
    * its centre is closer than ``max(inflate, resolution/2)`` to a segment obstacle — zero-thickness
      walls get half a cell of thickness so that they always separate the grid (for 4-connected and
      for corner-cutting-free 8-connected movement), or
    * its centre lies outside the workspace (only in the last row/column when the workspace size is
      not a multiple of ``resolution``), or, with ``border=True``, closer than ``inflate`` to the
      workspace boundary.

    Parameters
    ----------
    world : World
    resolution : float
        Cell size, positive.
    inflate : float
        Clearance required around obstacles (e.g. the robot radius), non-negative.
    t : float or None
        None rasterizes static obstacles only; a (finite) time includes moving circles at that
        time.
    border : bool
        Also keep ``inflate`` away from the workspace boundary.

    Returns
    -------
    OccupancyGrid
    """
    res = float(resolution)
    if not (res > 0 and math.isfinite(res)):
        raise HybridnavError(f"resolution: expected a positive number, got {resolution!r}")
    inflate = float(inflate)
    if not (inflate >= 0 and math.isfinite(inflate)):
        raise HybridnavError(f"inflate: expected a non-negative number, got {inflate!r}")
    if t is not None and not math.isfinite(float(t)):
        # (at an infinite time a static circle's box, centre + t * 0, is NaN: it was dropped)
        raise HybridnavError(f"t: expected a finite time or None, got {t!r}")
    xmin, xmax, ymin, ymax = world.workspace
    cells = grid_cells(xmax - xmin, ymax - ymin, res)
    if cells > MAX_GRID_CELLS:
        raise HybridnavError(f"resolution: expected a grid of at most {MAX_GRID_CELLS} cells "
                             f"(hybridnav.limits.MAX_GRID_CELLS), got {cells:.4g} cells of "
                             f"{res:g} over the workspace {list(world.workspace)}; choose a "
                             "coarser grid.resolution")
    W = max(1, int(math.ceil((xmax - xmin) / res - 1e-9)))
    H = max(1, int(math.ceil((ymax - ymin) / res - 1e-9)))
    cols, rows = np.meshgrid(np.arange(W), np.arange(H))
    grid = OccupancyGrid(np.zeros((H, W), dtype=bool), res, (xmin, ymin))
    P = grid.to_world(np.column_stack([cols.ravel(), rows.ravel()]))
    obs = tuple(o for o in world.obstacles if t is not None or not isinstance(o, MovingCircle))
    tt = 0.0 if t is None else float(t)
    blocked = (world.border_clearance(P) < (inflate if border else 0.0)).reshape(H, W)
    if obs:
        # obstacle by obstacle, over the cells near its box only: a cell is blocked when some
        # obstacle is closer than its threshold, and a cell farther than the threshold from
        # the box (plus the obstacle's pad, plus a cell of slack for rounding) cannot be
        obs_world = World(world.workspace, obs)
        lo, hi, pad = obs_world.boxes(tt)
        P2 = P.reshape(H, W, 2)
        for k, o in enumerate(obs):
            keep = max(inflate, res / 2.0) if isinstance(o, Segment) else inflate
            reach = keep + pad[k] + res
            span = (-1.0, float(max(W, H) + 1))
            c0, r0 = np.clip(np.floor((lo[k] - reach - (xmin, ymin)) / res - 0.5),
                             *span).astype(int)
            c1, r1 = np.clip(np.ceil((hi[k] + reach - (xmin, ymin)) / res - 0.5),
                             *span).astype(int)
            c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, W - 1), min(r1, H - 1)
            if c0 > c1 or r0 > r1:
                continue
            Q = P2[r0:r1 + 1, c0:c1 + 1].reshape(-1, 2)
            d = World(world.workspace, (o,)).clearance(Q, t=tt)
            blocked[r0:r1 + 1, c0:c1 + 1] |= (d < keep).reshape(r1 - r0 + 1, c1 - c0 + 1)
    grid.occ = blocked
    log.debug("rasterized %dx%d grid, %d blocked cells", W, H, int(blocked.sum()))
    return grid


def _dilate(grid: OccupancyGrid, inflate: float) -> OccupancyGrid:
    """Block free cells whose centre is within ``inflate`` of a blocked cell (approximately)."""
    if inflate <= 0 or not grid.occ.any():
        return grid
    from scipy.ndimage import distance_transform_edt

    d = distance_transform_edt(~grid.occ) * grid.resolution - grid.resolution / 2.0
    return OccupancyGrid(grid.occ | (d < inflate), grid.resolution, grid.origin, grid.source)


# --------------------------------------------------------------------------------------------
# MovingAI
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MovingAIQuery:
    """One line of a MovingAI ``.scen`` file.

    Attributes
    ----------
    bucket : int
    map : str
        Map file name as written in the scen file.
    width, height : int
        Map size.
    start, goal : (int, int)
        Cells ``(x, y)`` = ``(col, row)``.
    optimal_length : float
        Octile shortest-path length (no corner cutting).
    """

    bucket: int
    map: str
    width: int
    height: int
    start: tuple[int, int]
    goal: tuple[int, int]
    optimal_length: float


def _read_text(path: Any) -> tuple[str, str]:
    """Read a path or importlib Traversable; return (text, name for messages)."""
    name = str(path)
    if hasattr(path, "read_bytes") and not isinstance(path, (str, os.PathLike)):
        try:                                   # a packaged file (importlib Traversable)
            return decode_text(path.read_bytes(), name, "file"), name
        except OSError as exc:
            raise HybridnavError(f"{name}: cannot read file ({exc.strerror or exc})") from None
    return read_text_file(path, "file"), name


def parse_movingai_map(text: str, source: str = "<string>") -> OccupancyGrid:
    """Parse the text of a MovingAI ``.map`` file.

    Parameters
    ----------
    text : str
        File contents: ``type octile``, ``height H``, ``width W``, ``map``, then ``H`` rows of
        ``W`` characters.
    source : str
        Name used in error messages.

    Returns
    -------
    OccupancyGrid
        ``occ[row, col]`` with row 0 the first map line; ``resolution = 1``, ``origin = (0, 0)``.

    Raises
    ------
    HybridnavError
        Malformed header, wrong row count or length, unknown terrain character; the message gives
        the file and line number.
    """
    lines = text.splitlines()
    header: dict[str, str] = {}
    i = 0
    while i < len(lines):
        ln = lines[i].strip()
        i += 1
        if not ln:
            continue
        if ln == "map":
            break
        parts = ln.split()
        if len(parts) != 2 or parts[0] not in ("type", "height", "width"):
            # the line itself is not shown: a file that is not a map may hold anything
            raise HybridnavError(f"{where(source, f'line {i}')}: expected a MovingAI map header "
                                 "line ('type octile', 'height H', 'width W' or 'map'), got a "
                                 f"line of {len(ln)} characters that is none of them")
        header[parts[0]] = parts[1]
    else:
        raise HybridnavError(f"{where(source, f'line {i}')}: expected a 'map' line ending the header")
    for k in ("height", "width"):
        if k not in header:
            raise HybridnavError(f"{where(source, 'header')}: missing '{k}' line")
    try:
        H, W = int(header["height"]), int(header["width"])
    except ValueError:
        raise HybridnavError(f"{where(source, 'header')}: expected integer height and width, "
                             f"got {short_repr(header['height'], 30)}, "
                             f"{short_repr(header['width'], 30)}") from None
    if H <= 0 or W <= 0:
        raise HybridnavError(f"{where(source, 'header')}: expected positive height and width, got {H}, {W}")
    if H * W > MAX_GRID_CELLS:
        raise HybridnavError(f"{where(source, 'header')}: expected a map of at most "
                             f"{MAX_GRID_CELLS} cells (hybridnav.limits.MAX_GRID_CELLS), got height "
                             f"{short_repr(H, 30)} x width {short_repr(W, 30)}")
    rows = lines[i:]
    while rows and not rows[-1].strip():
        rows.pop()
    if len(rows) != H:
        raise HybridnavError(f"{where(source, f'line {i + min(len(rows), H) + 1}')}: expected {H} map rows "
                             f"(header height), got {len(rows)}")
    occ = np.empty((H, W), dtype=bool)
    allowed = PASSABLE | BLOCKED
    for r, row in enumerate(rows):
        lineno = i + r + 1
        row = row.rstrip("\r\n")
        if len(row) != W:
            raise HybridnavError(f"{where(source, f'line {lineno}')}: expected {W} characters (header width), "
                                 f"got {len(row)}")
        bad = set(row) - allowed
        if bad:
            raise HybridnavError(f"{where(source, f'line {lineno}')}: expected terrain characters "
                                 f"{''.join(sorted(allowed))!r}, got {len(bad)} other "
                                 f"character(s) (first {short_repr(min(bad), 12)})")
        occ[r] = np.isin(np.frombuffer(row.encode("ascii"), dtype=np.uint8), _BLOCKED_CODES)
    return OccupancyGrid(occ, 1.0, (0.0, 0.0), source)


def load_movingai_map(path: str | os.PathLike[str] | Any) -> OccupancyGrid:
    """Load a MovingAI ``.map`` file (see :func:`parse_movingai_map`).

    Parameters
    ----------
    path : str, path-like or importlib.resources Traversable
    """
    text, name = _read_text(path)
    return parse_movingai_map(text, name)


def load_movingai_scen(path: str | os.PathLike[str] | Any) -> list[MovingAIQuery]:
    """Load a MovingAI ``.scen`` file.

    Parameters
    ----------
    path : str, path-like or importlib.resources Traversable
        ``version 1`` line, then rows ``bucket map width height start_x start_y goal_x goal_y
        optimal_length`` (tab-separated).

    Returns
    -------
    list of MovingAIQuery

    Raises
    ------
    HybridnavError
        Malformed line; the message gives the file and line number.
    """
    text, name = _read_text(path)
    out: list[MovingAIQuery] = []
    lines = text.splitlines()
    if not lines or not lines[0].strip().startswith("version"):
        raise HybridnavError(f"{where(name, 'line 1')}: expected 'version 1'")
    for n, ln in enumerate(lines[1:], start=2):
        if not ln.strip():
            continue
        f = ln.rstrip("\r\n").split("\t") if "\t" in ln else ln.split()
        if len(f) != 9:
            raise HybridnavError(f"{where(name, f'line {n}')}: expected 9 fields (bucket map width height "
                                 f"start_x start_y goal_x goal_y optimal_length), got {len(f)}")
        try:
            b, w, h, sx, sy, gx, gy = (int(f[k]) for k in (0, 2, 3, 4, 5, 6, 7))
            opt = float(f[8])
        except ValueError:
            raise HybridnavError(f"{where(name, f'line {n}')}: expected integers and a final number, got {ln!r}") from None
        out.append(MovingAIQuery(b, f[1], w, h, (sx, sy), (gx, gy), opt))
    return out


# --------------------------------------------------------------------------------------------
# Scenario grids
# --------------------------------------------------------------------------------------------


def resolve_map(spec: str, source: str | None = None) -> Any:
    """Locate a grid map: ``"movingai:NAME"`` or a path (relative to the scenario file).

    Parameters
    ----------
    spec : str
        ``"movingai:NAME"`` for ``hybridnav/scenarios/data/NAME.map``, or a file path.
    source : str or None
        Scenario file; relative paths are resolved against its directory.

    Returns
    -------
    pathlib.Path or importlib.resources Traversable

    Raises
    ------
    HybridnavError
        The map does not exist.
    """
    if spec.startswith("movingai:"):
        name = spec[len("movingai:"):]
        entry = builtin_data_path(f"{name}.map")
        if not name or len(name) > 200 or "/" in name or not entry.is_file():
            raise HybridnavError(f"{where(source, 'grid.map')}: unknown built-in map "
                                 f"{short_repr(spec)}; expected "
                                 f"'movingai:NAME' with NAME.map in hybridnav/scenarios/data")
        return entry
    p = Path(spec)
    if not p.is_absolute() and source is not None:
        p = Path(source).parent / p
    if not p.is_file():
        raise HybridnavError(f"{where(source, 'grid.map')}: expected an existing .map file, {str(p)!r} not found")
    return p


def build_grid(scenario: Scenario, resolution: float | None = None, inflate: float = 0.0) -> OccupancyGrid:
    """The occupancy grid of a scenario.

    With ``[grid] map`` the map is loaded, scaled to ``grid.resolution`` and placed with its cell
    ``(0, 0)`` at the workspace's ``(xmin, ymin)``; ``inflate`` then blocks free cells whose centre is
    closer than ``inflate`` to a blocked cell (approximately: centre distance minus half a cell).
    Otherwise the world's static obstacles are rasterized (:func:`rasterize`).

    Parameters
    ----------
    scenario : Scenario
    resolution : float, optional
        Overrides ``grid.resolution``. Without either, rasterization uses 1/100 of the shorter
        workspace side.
    inflate : float
        Clearance around obstacles (e.g. the robot radius).

    Returns
    -------
    OccupancyGrid
    """
    spec = scenario.grid
    xmin, xmax, ymin, ymax = scenario.world.workspace
    res = resolution if resolution is not None else (spec.resolution if spec is not None else None)
    if spec is not None and spec.map is not None:
        og = load_movingai_map(resolve_map(spec.map, scenario.source))
        og = OccupancyGrid(og.occ, float(res), (xmin, ymin), og.source)
        return _dilate(og, float(inflate))
    if res is None:
        res = min(xmax - xmin, ymax - ymin) / 100.0
        log.info("scenario %s has no [grid]; rasterizing at resolution %g", scenario.name, res)
    return rasterize(scenario.world, float(res), inflate=inflate)


def world_point(name: str, P: Any) -> NDArray[np.float64]:
    """``P`` as a finite world point ``(x, y)``, else a HybridnavError naming ``name``.

    Parameters
    ----------
    name : str
        What the point is (``"start"``, ``"goal"``), for the message.
    P : array_like, shape (2,)

    Returns
    -------
    ndarray, shape (2,)
    """
    try:
        p = np.asarray(P, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise HybridnavError(f"{name}: expected a world point (x, y), got {short_repr(P)}") \
            from None
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise HybridnavError(f"{name}: expected a finite world point (x, y), got {short_repr(P)}")
    return p


def connected(grid: OccupancyGrid, a: ArrayLike, b: ArrayLike) -> bool:
    """Whether a grid path joins the cells of the world points ``a`` and ``b``.

    The moves are those of the planners' default search (8-connected without corner cutting: a
    diagonal move needs both cells beside it free), which join exactly the cells that 4-connected
    moves join; so this is one connected-component labelling (:func:`scipy.ndimage.label`), not a
    search. A point outside the grid or in a blocked cell is joined to nothing.

    Parameters
    ----------
    grid : OccupancyGrid
    a, b : array_like, shape (2,)
        World coordinates ``(x, y)``.

    Returns
    -------
    bool

    Raises
    ------
    HybridnavError
        A point that is not a finite ``(x, y)`` pair.
    """
    from scipy import ndimage

    points = np.vstack([world_point("a", a), world_point("b", b)])
    cells = np.floor((points - np.asarray(grid.origin)) / grid.resolution)
    h, w = grid.shape
    if not ((cells >= 0).all() and (cells[:, 0] < w).all() and (cells[:, 1] < h).all()):
        return False                         # (before the cast: a far point fits no int)
    (ca, ra), (cb, rb) = (tuple(int(v) for v in c) for c in cells)
    if grid.occ[ra, ca] or grid.occ[rb, cb]:
        return False
    labels, _ = ndimage.label(~grid.occ)          # the default structure: 4-connected
    return bool(labels[ra, ca] == labels[rb, cb])
