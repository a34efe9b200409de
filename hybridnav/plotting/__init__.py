"""Figures: scenarios and runs (:mod:`~hybridnav.plotting.scenes`), the planners' diagnostics
(:mod:`~hybridnav.plotting.diagnostics`) and animations of runs and tuning jobs
(:mod:`~hybridnav.plotting.animation`), headless-safe (no pyplot, no backend switching).

Every figure is written by :func:`~hybridnav.plotting.output.save_figure` (formats and
resolutions in :mod:`~hybridnav.plotting.output`); axis labels carry their units through
:mod:`~hybridnav.plotting.labels`.

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
from hybridnav.plotting.labels import axis_label
from hybridnav.plotting.output import (
    DEFAULT_DPI,
    FORMATS,
    MAX_DPI,
    check_dpi,
    check_format,
    figure_name,
    save_figure,
)
from hybridnav.plotting.scenes import (
    Trace,
    draw_moving_obstacles,
    draw_scenario,
    plot_result,
    plot_traces,
    save_scenario_png,
)

__all__ = ["DEFAULT_DPI", "FORMATS", "MAX_DPI", "Animated", "Trace", "animate", "animate_result",
           "animate_runs", "axis_label", "check_dpi", "check_format", "draw_moving_obstacles",
           "draw_scenario", "figure_name", "plot_gain_search", "plot_planned", "plot_potential",
           "plot_pso_ba", "plot_result", "plot_signals", "plot_traces", "plot_steps", "plot_waypoints", "save_figure",
           "save_scenario_png"]
