"""Occupancy grids and MovingAI maps: moved to :mod:`hybridnav.world.grid` in 0.3.0.

This alias keeps ``from hybridnav.grid import ...`` working for one version.
"""

from hybridnav.world.grid import *  # noqa: F403
from hybridnav.world.grid import __all__  # noqa: F401
