"""Which parts of a workspace are far from everything: a grid of cells nothing comes near, for
pruning collision checks in constant time per query box (:meth:`World.clear_map`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hybridnav.world.geometry import FloatArray

__all__ = ["ClearMap"]


class ClearMap:
    """The cells of a world's workspace farther than ``reach`` from every static obstacle and
    from the workspace border, and a query: is every point of a box in such cells?

    The workspace is cut into square cells (``cells`` along its longer side). A cell is clear
    when the Euclidean distance from the cell to each obstacle's box (:meth:`World.boxes`) exceeds
    the obstacle's pad plus ``reach`` and the cell lies inside the workspace shrunk by ``reach``,
    each with a slack of ``1e-9`` of the workspace's scale. A summed-area table of the other
    cells (and of a ring round the workspace) answers :meth:`free` for a box with four look-ups:
    the box, widened by the slack, overlaps only clear cells. Every point of a free box is then
    farther than ``reach`` from every obstacle and inside the workspace by more than ``reach``
    -- a sound test, up to rounding far below the slack. Moving circles are left out.

    Parameters
    ----------
    world : World
    reach : float
    cells : int
        Cells along the longer side of the workspace.
    """

    def __init__(self, world, reach: float, cells: int = 128) -> None:
        xmin, xmax, ymin, ymax = world.workspace
        self.reach = float(reach)
        self.origin = (xmin, ymin)
        self.h = h = max(xmax - xmin, ymax - ymin) / cells
        self.slack = 1e-9 * (1.0 + max(abs(v) for v in world.workspace) + abs(self.reach))
        thr = self.reach + 2 * self.slack
        gx = max(1, math.ceil((xmax - xmin) / h))
        gy = max(1, math.ceil((ymax - ymin) / h))
        x0 = xmin + np.arange(gx) * h
        y0 = ymin + np.arange(gy) * h
        x1, y1 = x0 + h, y0 + h
        clear = (((x0 - xmin >= thr) & (xmax - x1 >= thr))[:, None]
                 & ((y0 - ymin >= thr) & (ymax - y1 >= thr))[None, :])
        lo, hi, pad = world.static().boxes()
        for k in range(len(pad)):
            gapx = np.maximum(np.maximum(lo[k, 0] - x1, x0 - hi[k, 0]), 0.0)
            gapy = np.maximum(np.maximum(lo[k, 1] - y1, y0 - hi[k, 1]), 0.0)
            clear &= gapx[:, None] ** 2 + gapy[None, :] ** 2 >= (thr + pad[k]) ** 2
        blocked = np.ones((gx + 2, gy + 2), dtype=np.int64)      # a ring of blocked cells
        blocked[1:-1, 1:-1] = ~clear
        self.table = np.zeros((gx + 3, gy + 3), dtype=np.int64)
        self.table[1:, 1:] = blocked.cumsum(axis=0).cumsum(axis=1)
        self.flat = self.table.ravel()
        self.shape = (gx, gy)

    def free(self, lo: FloatArray, hi: FloatArray) -> NDArray[np.bool_]:
        """Whether every point of each box ``[lo, hi]`` (shape (..., 2)) is farther than
        ``reach`` from every static obstacle and inside the workspace by more than ``reach``
        (False for boxes with NaN corners)."""
        gx, gy = self.shape
        s, (ox, oy), h = self.slack, self.origin, self.h
        # cell indices + 1 (0 and g + 1: the ring), a low corner's NaN to the ring before the
        # box, a high corner's to the ring after it
        i0 = np.fmin(np.fmax(np.floor((lo[..., 0] - (ox + s)) / h), -1.0), gx).astype(np.intp)
        i1 = np.fmax(np.fmin(np.floor((hi[..., 0] - (ox - s)) / h), gx), -1.0).astype(np.intp)
        j0 = np.fmin(np.fmax(np.floor((lo[..., 1] - (oy + s)) / h), -1.0), gy).astype(np.intp)
        j1 = np.fmax(np.fmin(np.floor((hi[..., 1] - (oy - s)) / h), gy), -1.0).astype(np.intp)
        t, w = self.flat, self.table.shape[1]
        a0, a1 = (i0 + 1) * w, (i1 + 2) * w
        b0, b1 = j0 + 1, j1 + 2
        blocked = t.take(a1 + b1) - t.take(a0 + b1) - t.take(a1 + b0) + t.take(a0 + b0)
        return (blocked == 0) & (i0 <= i1) & (j0 <= j1)
