"""Many worlds queried at once: each point asks its own world, in one vectorized call.

Lockstep training simulates every (environment, member) pair together. Asking each
environment's :class:`hybridnav.world.World` in turn costs one Python round per environment per
control cycle, which dominates when there are dozens of training worlds. A :class:`WorldStack`
packs the worlds' obstacles into padded arrays — circles ``(E, C, 2)``, polygon and segment edges
``(E, Ed, 2)`` grouped per obstacle — and answers ``nearest`` / ``clearance`` /
``border_clearance`` for points ``P`` (N, 2) with their environment indices ``env`` (N,).

The answers are exactly :meth:`World.nearest` / :meth:`World.clearance` /
:meth:`World.border_clearance` of each point's own world, bit for bit: the same floating-point
operations per (point, obstacle) pair, and ties between obstacles broken by the obstacle's index
in its world, as ``World`` does.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridnav.world import World
from hybridnav.world.geometry import _cross, _nearest_on_circle, _project

__all__ = ["WorldStack"]


class WorldStack:
    """The obstacles of ``worlds`` (static and moving circles, segments, polygons) packed."""

    def __init__(self, worlds: Sequence[World]) -> None:
        self.worlds = list(worlds)
        E = len(self.worlds)
        C = max([w._c_idx.size for w in self.worlds] + [0])
        G = max([w._g_idx.size for w in self.worlds] + [0])
        Ed = max([len(w._eA) for w in self.worlds] + [0])
        K = max([len(w.obstacles) for w in self.worlds] + [0])
        self.K = K
        self.has_obstacles = np.array([bool(w.obstacles) for w in self.worlds])
        self.c0 = np.full((E, C, 2), np.inf)
        self.cv = np.zeros((E, C, 2))
        self.cr = np.zeros((E, C))
        self.moving = any(w._c_moving for w in self.worlds)
        self.eA = np.zeros((E, Ed, 2))
        self.eB = np.zeros((E, Ed, 2))
        self.owner = np.full((E, Ed), -1)           # group (edge obstacle) index within world
        self.closed = np.zeros((E, G), dtype=bool)
        # column of obstacle k of world e in the concatenation [circles (C) | groups (G) | inf]
        self.perm = np.full((E, max(K, 1)), C + G)
        self.ws = np.array([w.workspace for w in self.worlds], dtype=float).reshape(E, 4)
        for e, w in enumerate(self.worlds):
            nc = w._c_idx.size
            self.c0[e, :nc] = w._c0
            self.cv[e, :nc] = w._cv
            self.cr[e, :nc] = w._cr
            self.perm[e, w._c_idx] = np.arange(nc)
            ne = len(w._eA)
            self.eA[e, :ne] = w._eA
            self.eB[e, :ne] = w._eB
            ends = np.append(w._g_start[1:], ne)
            for g, (a, b) in enumerate(zip(w._g_start, ends)):
                self.owner[e, a:b] = g
            self.closed[e, :w._g_idx.size] = w._g_closed
            self.perm[e, w._g_idx] = C + np.arange(w._g_idx.size)
        self.g_start = np.zeros((E, G + 1), dtype=np.int64)   # edges of group g: [g_start[g], g_start[g + 1])
        for e, w in enumerate(self.worlds):
            ng = w._g_idx.size
            self.g_start[e, :ng] = w._g_start
            self.g_start[e, ng:] = len(w._eA)
        self.C, self.G = C, G
        self._cells: dict[int, tuple | None] = {}
        self._kof: np.ndarray | None = None

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_lockstep_layout", None)       # models and start states: rebuilt on use
        return state

    def column_obstacle(self) -> np.ndarray:
        """``(E, C + G)``: the index in its world of the obstacle each column holds (padding
        columns: ``K``), the inverse of :attr:`perm`."""
        if self._kof is None:               # asked once per compiled run: kept
            E, CG = len(self.worlds), self.C + self.G
            kof = np.full((E, CG), self.K, dtype=np.int64)
            for e, w in enumerate(self.worlds):
                k = np.arange(len(w.obstacles))
                kof[e, self.perm[e, k]] = k
            self._kof = kof
        return self._kof

    def cells(self, per_side: int = 32):
        """Candidate lists for an exact nearest-obstacle search: each world's workspace, widened
        by a quarter of its size, cut into ``per_side`` x ``per_side`` cells, and for each cell
        the columns ([circles | groups]) that can be nearest to some point of it.

        Signed distances are 1-Lipschitz, so from a cell's centre ``c`` with half-diagonal ``h``
        a column ``j`` can be nearest somewhere in the cell only if ``d_j(c) - h <= min_k d_k(c)
        + h``; the others are strictly farther everywhere in the cell (a tolerance covers
        rounding), so searching the candidates alone gives the same nearest obstacle, the same
        distance and the same tie-break as searching all. ``None`` for moving obstacles.

        Returns ``(geo (E, 4): x0, y0, cells per unit x, per unit y; offsets (E * n * n + 1,);
        columns (int32))``, cell ``(ix, iy)`` of world ``e`` at ``(e * n + iy) * n + ix``.
        """
        if per_side in self._cells:
            return self._cells[per_side]
        if self.moving or not self.K:
            self._cells[per_side] = None
            return None
        E, n = len(self.worlds), int(per_side)
        x0, x1, y0, y1 = (self.ws[:, i] for i in range(4))
        wx, wy = x1 - x0, y1 - y0
        x0, y0, wx, wy = x0 - wx / 4, y0 - wy / 4, wx * 1.5, wy * 1.5
        sx, sy = wx / n, wy / n
        geo = np.stack([x0, y0, 1.0 / sx, 1.0 / sy], axis=1)
        u = np.arange(n) + 0.5
        cx = x0[:, None, None] + u[None, None, :] * sx[:, None, None]   # (E, 1, n): ix
        cy = y0[:, None, None] + u[None, :, None] * sy[:, None, None]   # (E, n, 1): iy
        P = np.stack(np.broadcast_arrays(cx, cy), axis=-1).reshape(-1, 2)
        env = np.repeat(np.arange(E), n * n)
        h = 0.5 * np.hypot(sx, sy)[env]
        tol = 1e-9 * (1.0 + np.abs(self.ws).max(axis=1) + np.hypot(wx, wy))[env]
        D = self._distances(P, env, 0.0, False)[1][:, :self.C + self.G]
        with np.errstate(invalid="ignore"):
            keep = (D <= (D.min(axis=1) + 2.0 * h + tol)[:, None]) & np.isfinite(D)
        counts = keep.sum(axis=1)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        columns = np.nonzero(keep)[1].astype(np.int32)
        self._cells[per_side] = (geo, offsets, columns)
        return self._cells[per_side]

    def _distances(self, P: np.ndarray, env: np.ndarray, t: float, want_points: bool):
        n = len(P)
        C, G = self.C, self.G
        D = np.full((n, C + G + 1), np.inf)
        Cn = Qe = de = None
        if C:
            Cn = self.c0[env] + float(t) * self.cv[env] if self.moving else self.c0[env]
            diff = P[:, None, :] - Cn
            with np.errstate(invalid="ignore"):
                D[:, :C] = np.hypot(diff[..., 0], diff[..., 1]) - self.cr[env]
        if G:
            A, B, own = self.eA[env], self.eB[env], self.owner[env]
            de, Qe = _project(P[:, None, :], A, B)
            cr = _cross(B - A, P[:, None, :] - A)
            for g in range(G):
                m = own == g
                dmin = np.min(np.where(m, de, np.inf), axis=1)
                inside = (np.min(np.where(m, cr, np.inf), axis=1) > 0.0) & self.closed[env, g]
                D[:, C + g] = np.where(inside, -dmin, dmin)
        # obstacle order of each point's world (padding columns are +inf)
        Dk = np.take_along_axis(D, self.perm[env], axis=1)
        return Dk, D, Cn, de, Qe

    def clearance(self, P: np.ndarray, env: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Signed clearance of each point in its own world (``+inf`` without obstacles)."""
        if not self.K:
            return np.full(len(P), np.inf)
        Dk = self._distances(np.asarray(P, dtype=float), np.asarray(env), t, False)[0]
        return np.min(Dk, axis=1)

    def nearest(self, P: np.ndarray, env: np.ndarray, t: float = 0.0):
        """Clearance ``(N,)`` and nearest obstacle surface point ``(N, 2)`` (NaN without
        obstacles), as :meth:`World.nearest` of each point's world."""
        P = np.asarray(P, dtype=float)
        env = np.asarray(env)
        n = len(P)
        near = np.full((n, 2), np.nan)
        if not self.K:
            return np.full(n, np.inf), near
        Dk, D, Cn, de, Qe = self._distances(P, env, t, True)
        k = np.argmin(Dk, axis=1)
        rows = np.arange(n)
        clear = Dk[rows, k]
        col = self.perm[env, k]
        has = self.has_obstacles[env]
        is_c = has & (col < self.C)
        if is_c.any():
            sel = np.flatnonzero(is_c)
            c = col[sel]
            near[sel] = _nearest_on_circle(P[sel], Cn[sel, c], self.cr[env[sel], c])
        is_g = has & (col >= self.C) & (col < self.C + self.G)
        if is_g.any():
            sel = np.flatnonzero(is_g)
            g = col[sel] - self.C
            masked = np.where(self.owner[env[sel]] == g[:, None], de[sel], np.inf)
            e = np.argmin(masked, axis=1)
            near[sel] = Qe[sel, e]
        clear = np.where(has, clear, np.inf)
        return clear, near

    def nearest_each(self, P: np.ndarray, env: np.ndarray, t: float = 0.0):
        """Signed clearance ``(N, K)`` to every obstacle of each point's world (``+inf`` in the
        padding columns) and the nearest surface point on each ``(N, K, 2)``, in each world's
        obstacle order, as :meth:`World.nearest_each`."""
        P = np.asarray(P, dtype=float)
        env = np.asarray(env)
        n = len(P)
        if not self.K:
            return np.full((n, 0), np.inf), np.zeros((n, 0, 2))
        Dk, _, Cn, de, Qe = self._distances(P, env, t, True)
        pts = np.full((n, self.C + self.G + 1, 2), np.nan)
        if self.C:                   # every circle of every point's world in one call
            with np.errstate(invalid="ignore"):
                pts[:, :self.C] = _nearest_on_circle(
                    np.repeat(P, self.C, axis=0), Cn.reshape(-1, 2),
                    self.cr[env].reshape(-1)).reshape(n, self.C, 2)
        rows = np.arange(n)
        for g in range(self.G):
            masked = np.where(self.owner[env] == g, de, np.inf)
            pts[:, self.C + g] = Qe[rows, np.argmin(masked, axis=1)]
        near = np.take_along_axis(pts, self.perm[env][:, :, None], axis=1)
        return Dk, near

    def border_clearance(self, P: np.ndarray, env: np.ndarray) -> np.ndarray:
        """Signed distance to each point's workspace boundary (positive inside)."""
        P = np.asarray(P, dtype=float)
        ws = self.ws[np.asarray(env)]
        dx_in = np.minimum(P[:, 0] - ws[:, 0], ws[:, 1] - P[:, 0])
        dy_in = np.minimum(P[:, 1] - ws[:, 2], ws[:, 3] - P[:, 1])
        inside = np.minimum(dx_in, dy_in)
        dx = np.maximum(0.0, -dx_in)
        dy = np.maximum(0.0, -dy_in)
        return np.where(inside >= 0.0, inside, -np.hypot(dx, dy))
