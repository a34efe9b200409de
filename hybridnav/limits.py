"""The documented limits every input is checked against before any work starts.

A scenario, a job, a fuzzy system or a map that would make the program allocate or compute
without bound is refused up front with a :class:`~hybridnav.errors.HybridnavError` naming the
file and the key, instead of running for hours or failing with ``MemoryError`` half-way:

==============================  =============  ====================================================
limit                           value          what it bounds
==============================  =============  ====================================================
:data:`MAX_COORDINATE`          1e6            ``|x|``, ``|y|`` of workspace bounds, obstacles,
                                               starts and goals (and their sizes)
:data:`MAX_POSITION`            1e150          ``|x|``, ``|y|`` of the positions a result folder
                                               holds (trajectories, planned and candidate
                                               points): a run ends when a robot leaves its
                                               workspace, but a diverging model can leave it
                                               by 1e40 in one step (still plotted); near 1e200
                                               Matplotlib's renderer overflows
:data:`MAX_STEPS`               2,000,000      control cycles of one run, ``ceil(max_time / dt)``
:data:`MAX_GRID_CELLS`          20,000,000     cells of an occupancy grid (about 20 MB as booleans,
                                               160 MB as the distances a planner keeps)
:data:`MAX_OBSTACLES`           10,000         obstacles of one scenario
:data:`MAX_VERTICES`            10,000         vertices of one polygon
:data:`MAX_ROBOTS`              1,000          robots of one scenario
:data:`~hybridnav.fileio.MAX_FILE_BYTES`  64 MiB  size of a file read
==============================  =============  ====================================================

The fuzzy readers bound universe points by :data:`hybridnav.fuzzy.export.MAX_POINTS`.
"""

from __future__ import annotations

__all__ = ["MAX_COORDINATE", "MAX_GRID_CELLS", "MAX_OBSTACLES", "MAX_POSITION", "MAX_ROBOTS",
           "MAX_STEPS", "MAX_VERTICES", "grid_cells"]

import math

MAX_COORDINATE = 1e6
#: far beyond any workspace (a diverging model's last step can reach 1e40; that run must still
#: plot) and far below where Matplotlib's renderer overflows (near 1e200)
MAX_POSITION = 1e150
MAX_STEPS = 2_000_000
MAX_GRID_CELLS = 20_000_000
MAX_OBSTACLES = 10_000
MAX_VERTICES = 10_000
MAX_ROBOTS = 1_000


def grid_cells(width: float, height: float, resolution: float) -> float:
    """Cells of a grid over ``width x height`` at ``resolution`` (as a float: it may be huge, or
    ``inf`` where the ratio overflows, e.g. for a subnormal resolution)."""
    def side(length: float) -> float:
        ratio = length / resolution
        return max(1.0, math.ceil(ratio - 1e-9)) if math.isfinite(ratio) else math.inf

    return side(width) * side(height)
