"""Harmonic artificial potential field (Connolly et al. 1990; Feder & Slotine 1997).

Laplace's equation is solved on the scenario's occupancy grid (obstacles inflated by the robot
radius): obstacle cells and the area outside the workspace are held at 1, the goal disk at 0, and
every free cell is the mean of its four neighbours (5-point stencil, one sparse direct solve with
``scipy.sparse.linalg.spsolve``). A harmonic function has no local minima in the free space, so
descending its gradient (central differences, bilinearly interpolated at the robot's position)
leads to the goal from every connected free cell. Static worlds and fixed goals only.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse.linalg import spsolve

from hybridnav.errors import HybridnavError
from hybridnav.planners.base import Param
from hybridnav.planners.field.base import COMMON, FieldPlanner
from hybridnav.planners.simulate import Simulation
from hybridnav.world.grid import OccupancyGrid, build_grid

__all__ = ["HAPF", "harmonic_field"]


def harmonic_field(grid: OccupancyGrid, goal_cells: np.ndarray) -> np.ndarray:
    """Solve Laplace's equation on ``grid``: blocked = 1 (also outside), goal cells = 0.

    Parameters
    ----------
    grid : OccupancyGrid
    goal_cells : ndarray of bool, shape (height, width)
        Cells held at 0.

    Returns
    -------
    ndarray, shape (height, width)
        The potential, 1 on blocked cells.
    """
    occ = grid.occ
    h, w = occ.shape
    fixed = occ | goal_cells
    free = ~fixed
    index = -np.ones(occ.shape, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    phi = np.where(goal_cells, 0.0, 1.0)
    n = int(free.sum())
    if n == 0:
        return phi
    rows, cols, vals = [], [], []
    rhs = np.zeros(n)
    r, c = np.nonzero(free)
    me = index[r, c]
    rows.append(me)
    cols.append(me)
    vals.append(np.full(n, 4.0))
    for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        rr, cc = r + dr, c + dc
        inside = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        rr_c, cc_c = np.clip(rr, 0, h - 1), np.clip(cc, 0, w - 1)
        neighbour_free = inside & free[rr_c, cc_c]
        rows.append(me[neighbour_free])
        cols.append(index[rr_c, cc_c][neighbour_free])
        vals.append(np.full(int(neighbour_free.sum()), -1.0))
        # Dirichlet neighbours: outside the grid or blocked -> 1, goal -> 0
        boundary_value = np.where(inside, phi[rr_c, cc_c], 1.0)
        rhs += np.where(neighbour_free, 0.0, boundary_value)
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n))
    phi = phi.copy()
    phi[free] = spsolve(A.tocsc(), rhs)
    return phi


class HAPF(FieldPlanner):
    """Harmonic potential field on the occupancy grid: no local minima by construction."""

    name = "hapf"
    description = "harmonic potential field: Laplace's equation on the grid, gradient descent"
    moving_obstacles = False
    moving_targets = False
    parameters: ClassVar[dict[str, Param]] = {
        "resolution": Param(0.0, "grid cell size (0: the scenario's [grid] resolution, else 1/100 "
                                 "of the shorter workspace side)", lo=0.0),
        "margin": Param(0.0, "extra clearance added to the robot radius when inflating obstacles",
                        lo=0.0),
        **COMMON,
    }

    def prepare(self, scenario, rng):
        fields = []
        for i, r in enumerate(scenario.robots):
            res = self.values["resolution"] or None
            grid = build_grid(scenario, resolution=res, inflate=r.radius + self.values["margin"])
            centers = grid.to_world(np.argwhere(np.ones(grid.shape, dtype=bool))[:, ::-1])
            xs = np.unique(centers[:, 0])
            ys = np.unique(centers[:, 1])
            d = np.hypot(centers[:, 0] - r.goal[0], centers[:, 1] - r.goal[1])
            goal = (d <= max(r.goal_radius, 0.75 * grid.resolution)).reshape(grid.shape[0], -1)
            goal &= ~grid.occ
            if not goal.any():
                raise HybridnavError(
                    f"{scenario.source or scenario.name}: robots[{i}].goal: no free grid cell "
                    f"within the goal radius at resolution {grid.resolution:g}; refine the grid")
            phi = harmonic_field(grid, goal)
            gy, gx = np.gradient(phi, ys, xs)
            fields.append((
                RegularGridInterpolator((ys, xs), gx, bounds_error=False, fill_value=0.0),
                RegularGridInterpolator((ys, xs), gy, bounds_error=False, fill_value=0.0),
                phi, grid,
            ))
        return fields

    def extras(self, scenario, state) -> dict[str, Any]:
        """Each robot's harmonic potential on its grid (``harmonic_potential_<robot>``) and the
        grid's extent (``harmonic_grid_<robot>``: ``x0, x1, y0, y1``)."""
        out: dict[str, Any] = {}
        for r, (_, _, phi, grid) in zip(scenario.robots, state):
            x0, x1, y0, y1 = grid.extent
            out[f"harmonic_potential_{r.name}"] = np.asarray(phi, dtype=float)
            out[f"harmonic_grid_{r.name}"] = {"x0": [x0], "x1": [x1], "y0": [y0], "y1": [y1]}
        return out

    def diagnostics(self, scenario, result):
        """``signals.png`` and ``harmonic_field.png`` (the potential of the first robot)."""
        from hybridnav.plotting import plot_potential

        out = dict(super().diagnostics(scenario, result))
        fig = plot_potential(scenario, result)
        if fig is not None:
            out["harmonic_field.png"] = fig
        return out

    def velocity(self, state, sim: Simulation, idx, P, goals):
        V = np.zeros((len(idx), 2))
        for j, i in enumerate(idx):
            ix, iy, _, _ = state[i]
            q = P[j][::-1][None]          # (y, x)
            V[j] = -float(ix(q)[0]), -float(iy(q)[0])
            if not np.any(V[j]):
                sim.stop(int(i), "stuck")
        return V
