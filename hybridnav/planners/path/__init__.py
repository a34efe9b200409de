"""Plan-then-track planners — ``astar``, ``dijkstra``, ``pso``, ``rfd``, ``rfd-pso``
(:mod:`.planners`) — on occupancy grids (:mod:`.gridsearch`) and river formation dynamics
(:mod:`.rfd_core`)."""

from hybridnav.planners.path.planners import (
    AStarPlanner,
    DijkstraPlanner,
    PathPlanner,
    PSOPathPlanner,
    RFDPlanner,
    RFDPSOPlanner,
)

__all__ = ["AStarPlanner", "DijkstraPlanner", "PSOPathPlanner", "PathPlanner", "RFDPSOPlanner",
           "RFDPlanner"]
