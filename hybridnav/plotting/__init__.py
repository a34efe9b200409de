"""Figures: scenarios and runs (:mod:`~hybridnav.plotting.scenes`), the planners' diagnostics
(:mod:`~hybridnav.plotting.diagnostics`) and animations of runs and tuning jobs
(:mod:`~hybridnav.plotting.animation`), headless-safe (no pyplot, no backend switching).

The analysis figures (trajectories in state space, Lyapunov level sets, basins) are in
:mod:`hybridnav.analysis.plots`.
"""

from hybridnav.plotting.animation import Animated, animate, animate_result, animate_runs
from hybridnav.plotting.diagnostics import (
    plot_gain_search,
    plot_planned,
    plot_potential,
    plot_pso_ba,
    plot_signals,
    plot_steps,
    plot_waypoints,
)
from hybridnav.plotting.scenes import (
    Trace,
    draw_moving_obstacles,
    draw_scenario,
    plot_result,
    plot_traces,
    save_figure,
    save_scenario_png,
)

__all__ = ["Animated", "Trace", "animate", "animate_result", "animate_runs",
           "draw_moving_obstacles", "draw_scenario", "plot_gain_search", "plot_planned", "plot_potential",
           "plot_pso_ba", "plot_result", "plot_signals", "plot_traces", "plot_steps", "plot_waypoints", "save_figure",
           "save_scenario_png"]
