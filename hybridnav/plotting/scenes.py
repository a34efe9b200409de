"""Drawing scenarios with matplotlib (headless-safe: no pyplot, no backend switching)."""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle as CirclePatch
from matplotlib.patches import FancyArrowPatch
from matplotlib.patches import Polygon as PolygonPatch
from matplotlib.patches import Rectangle as RectanglePatch

from hybridnav.errors import HybridnavError
from hybridnav.plotting.labels import LENGTH, axis_label
from hybridnav.plotting.output import DEFAULT_DPI, save_figure
from hybridnav.params import short_repr
from hybridnav.world import Circle, MovingCircle, Polygon, Rectangle, Scenario, Segment

__all__ = ["Trace", "draw_moving_obstacles", "draw_scenario", "legend_outside", "mark_outcome",
           "plot_result", "plot_traces", "save_figure", "save_scenario_png"]

log = logging.getLogger(__name__)

_OBSTACLE_STYLE = {"facecolor": "0.35", "edgecolor": "black", "linewidth": 0.8}
_MOVING_STYLE = {"facecolor": "tab:red", "edgecolor": "darkred", "linewidth": 0.8, "alpha": 0.75}


def draw_scenario(scenario: Scenario, ax: Axes | None = None, t: float = 0.0, show_grid: bool = True,
                  *, moving: bool = True) -> Axes:
    """Draw a scenario: workspace, obstacles, grid map, robots, starts and goals.

    Parameters
    ----------
    scenario : Scenario
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new :class:`matplotlib.figure.Figure` (no pyplot) is made otherwise.
    t : float
        Time at which moving circles are drawn (their velocity is drawn as an arrow, and their
        position at ``t = 0`` as a dashed outline when ``t != 0``).
    show_grid : bool
        Draw the scenario's map grid (only for ``[grid] map`` scenarios) with ``imshow``.
    moving : bool
        Draw the moving circles (False: leave them to :func:`draw_moving_obstacles`, e.g. for the
        frames of an animation, which redraw only them).

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        fig = Figure(figsize=(6.4, 6.4), layout="constrained")
        ax = fig.add_subplot()
    world = scenario.world
    xmin, xmax, ymin, ymax = world.workspace
    span = max(xmax - xmin, ymax - ymin)

    if show_grid and scenario.grid is not None and scenario.grid.map is not None:
        from hybridnav.world.grid import build_grid

        og = build_grid(scenario)
        ax.imshow(og.occ, origin="lower", extent=og.extent, cmap="Greys", vmin=0, vmax=1.6,
                  interpolation="nearest", zorder=0)

    ax.add_patch(RectanglePatch((xmin, ymin), xmax - xmin, ymax - ymin, fill=False, edgecolor="black",
                                linewidth=1.5, zorder=1))

    for o in world.obstacles:
        if isinstance(o, Circle):
            ax.add_patch(CirclePatch(o.center, o.radius, zorder=2, **_OBSTACLE_STYLE))
        elif isinstance(o, (Polygon, Rectangle)):
            ax.add_patch(PolygonPatch(o.vertices, closed=True, zorder=2, **_OBSTACLE_STYLE))
        elif isinstance(o, Segment):
            ax.plot([o.a[0], o.b[0]], [o.a[1], o.b[1]], color="black", linewidth=2.5, zorder=2,
                    solid_capstyle="round")
    if moving:
        draw_moving_obstacles(scenario, ax, t)

    colors = [f"C{i % 10}" for i in range(len(scenario.robots))]
    starts = {r.name: np.asarray(r.start) for r in scenario.robots}
    for r, col in zip(scenario.robots, colors):
        s = starts[r.name]
        model = scenario.model(r, jit=False)
        target = r.goal if r.goal is not None else starts.get(r.goal_follow, s)
        centers, radii = model.footprint(model.initial_state(s, target, r.initial)[None])
        for c, rad in zip(centers[0], radii):   # the model's covering disks (one for a disk robot)
            ax.add_patch(CirclePatch(c, rad, facecolor=col, edgecolor="black", alpha=0.35,
                                     linewidth=0.8, zorder=4))
        ax.plot(*s, marker="o", color=col, markersize=6, markeredgecolor="black", zorder=5)
        ax.annotate(r.name, s, xytext=(5, 5), textcoords="offset points", color=col, fontsize=9,
                    fontweight="bold", zorder=6)
        if r.goal is not None:
            g = np.asarray(r.goal)
            ax.add_patch(CirclePatch(g, r.goal_radius, fill=False, edgecolor=col, linestyle="--",
                                     linewidth=1.0, zorder=4))
            ax.plot(*g, marker="*", color=col, markersize=12, markeredgecolor="black", zorder=5)
            ax.annotate(f"{r.name} goal", g, xytext=(5, -12), textcoords="offset points", color=col,
                        fontsize=8, zorder=6)
        elif r.goal_follow is not None and r.goal_follow in starts:
            ax.add_patch(FancyArrowPatch(tuple(s), tuple(starts[r.goal_follow]), arrowstyle="-|>",
                                         mutation_scale=12, color=col, linestyle=":", linewidth=1.2,
                                         shrinkA=6, shrinkB=6, zorder=4))

    pad = 0.03 * span
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel(axis_label("x", LENGTH, scenario.units))
    ax.set_ylabel(axis_label("y", LENGTH, scenario.units))
    title = scenario.name if t == 0.0 else f"{scenario.name} (t = {t:g} s)"
    ax.set_title(title)
    return ax


def draw_moving_obstacles(scenario: Scenario, ax: Axes, t: float = 0.0) -> list[Artist]:
    """Draw the scenario's moving circles where they are at time ``t``, with their velocity as an
    arrow and their position at ``t = 0`` as a dashed outline when ``t != 0``.

    Parameters
    ----------
    scenario : Scenario
    ax : matplotlib.axes.Axes
    t : float
        Time, seconds.

    Returns
    -------
    list of matplotlib.artist.Artist
        What was added (an animation removes them before it draws the next frame). They do not
        change the axes' data limits (the limits :func:`draw_scenario` sets stay).
    """
    xmin, xmax, ymin, ymax = scenario.world.workspace
    span = max(xmax - xmin, ymax - ymin)
    added: list[Artist] = []
    for o in scenario.world.obstacles:
        if not isinstance(o, MovingCircle):
            continue
        c = o.center_at(t)
        if t != 0.0:
            added.append(ax.add_artist(CirclePatch(o.center, o.radius, fill=False,
                                                  edgecolor="darkred", linestyle="--",
                                                  linewidth=0.8, zorder=2)))
        added.append(ax.add_artist(CirclePatch(c, o.radius, zorder=3, **_MOVING_STYLE)))
        if o.velocity > 0:
            u = np.array([math.cos(o.heading), math.sin(o.heading)])
            tail = c + u * o.radius
            head = tail + u * max(0.06 * span, 10.0 * o.velocity * scenario.dt)
            added.append(ax.add_artist(FancyArrowPatch(tuple(tail), tuple(head), arrowstyle="-|>",
                                                      mutation_scale=12, color="darkred",
                                                      linewidth=1.2, zorder=3)))
    return added


def save_scenario_png(scenario: Scenario, path: str | os.PathLike[str], t: float = 0.0,
                      dpi: int = DEFAULT_DPI) -> Path:
    """Draw a scenario and write it to a picture file atomically (PNG, or the format of the
    suffix: see :func:`~hybridnav.plotting.output.save_figure`).

    Parameters
    ----------
    scenario : Scenario
    path : str or path-like
        Destination; the image is written to a temporary file in the same directory and then
        moved into place with :func:`os.replace`.
    t : float
        Time for moving obstacles, in ``[0, scenario.max_time]``.
    dpi : int

    Returns
    -------
    pathlib.Path
        The written path.
    """
    path = Path(path)
    if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)) \
            or not 0.0 <= t <= scenario.max_time:
        raise HybridnavError(f"t: expected a time in [0, {scenario.max_time:g}] s (the "
                             f"scenario's max_time), got {short_repr(t)}")
    fig = Figure(figsize=(6.4, 6.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_scenario(scenario, ax=ax, t=t)
    save_figure(fig, path, dpi=dpi, bbox_inches=None)
    log.debug("wrote %s", path)
    return path


_OUTCOME_MARK = {"reached": ("*", "green"), "collided": ("X", "red"),
                 "out_of_bounds": ("X", "purple"), "stuck": ("s", "orange"),
                 "timeout": ("D", "gray")}


def mark_outcome(ax: Axes, point, outcome: str, labelled: set[str] | None = None,
                 markersize: float = 11) -> None:
    """Mark where a run ended with its outcome's marker (reached: green star, collided: red X,
    out of bounds: purple X, stuck: orange square, timeout: grey diamond).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    point : (float, float)
        The end of the run.
    outcome : str
    labelled : set of str, optional
        Outcomes that already have a legend entry; the first marker of each outcome gets one
        (``"end: <outcome>"``) and is added. None: no legend entry.
    markersize : float
    """
    mark, mcol = _OUTCOME_MARK.get(outcome, ("o", "black"))
    label = None
    if labelled is not None and outcome not in labelled:
        labelled.add(outcome)
        label = f"end: {outcome}"
    ax.plot(*point, linestyle="none", marker=mark, color=mcol, markersize=markersize,
            markeredgecolor="black", zorder=8, label=label)


def legend_outside(ax: Axes, fontsize: float = 8, ncols: int = 2, handles=None):
    """The axes' legend below it (it covers no data; constrained layout makes room); None when
    nothing is labelled.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    fontsize : float
    ncols : int
    handles : list of artists, optional
        Stand-ins for drawn artists, each with the label of the artist it stands for (default:
        the axes' labelled artists).
    """
    from matplotlib.transforms import offset_copy

    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    else:
        labels = [h.get_label() for h in handles]
    # the outcome markers (mark_outcome) after what they end
    order = sorted(range(len(labels)), key=lambda i: labels[i].startswith("end: "))
    handles, labels = [handles[i] for i in order], [labels[i] for i in order]
    if not handles:
        return None
    # anchored a fixed distance below the axes: under the tick labels and the x label
    below = offset_copy(ax.transAxes, fig=ax.figure, y=-3.4 * ax.xaxis.label.get_size(),
                        units="points")
    return ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                     bbox_transform=below, fontsize=fontsize, ncols=min(ncols, len(handles)),
                     frameon=False)


@dataclass(frozen=True)
class Trace:
    """One robot's run as :func:`plot_traces` draws it: its ``xy`` path ``(n, 2)``, outcome,
    path length, final state (for the footprint; ``None`` draws none) and end time."""

    name: str
    xy: np.ndarray
    outcome: str
    path_length: float
    state: np.ndarray | None
    t_end: float


def plot_traces(scenario: Scenario, traces, ax: Axes | None = None) -> Figure:
    """The scenario with every robot's path, its final footprint and outcome marker, and a
    legend below the map (paths with their lengths, the outcome markers drawn).

    Moving obstacles are drawn where they are at the end of the longest run.

    Parameters
    ----------
    scenario : Scenario
    traces : sequence of Trace
        In the order of the scenario's robots (the footprint uses the robot of that name).
    ax : matplotlib.axes.Axes, optional
        Draw into it (default: a new figure).
    """
    t_end = max((float(r.t_end) for r in traces), default=0.0)
    if ax is None:
        fig = Figure(figsize=(6.6, 6.4), layout="constrained")
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    draw_scenario(scenario, ax=ax, t=t_end)
    models = {r.name: scenario.model(r, jit=False) for r in scenario.robots}
    labelled: set[str] = set()
    for i, rr in enumerate(traces):
        col = f"C{i % 10}"
        xy = rr.xy
        ax.plot(xy[:, 0], xy[:, 1], color=col, linewidth=1.6, zorder=7,
                label=f"{rr.name}: {rr.outcome}, length {rr.path_length:.3g} {scenario.units}")
        model = models.get(rr.name)
        if model is not None and rr.state is not None and len(rr.state) == model.nx:
            centers, radii = model.footprint(np.asarray(rr.state)[None])
            for c, rad in zip(centers[0], radii):
                ax.add_patch(CirclePatch(c, rad, fill=False, edgecolor=col, linewidth=1.0,
                                         zorder=7))
        mark_outcome(ax, xy[-1], rr.outcome, labelled)
    legend_outside(ax)
    return fig


def plot_result(scenario: Scenario, result, ax: Axes | None = None) -> Figure:
    """The scenario with every robot's path, its final footprint and outcome marker
    (:func:`plot_traces` of a :class:`hybridnav.results.Result`).

    Moving obstacles are drawn where they are at the end of the longest run.

    Parameters
    ----------
    scenario : Scenario
    result : Result
    ax : matplotlib.axes.Axes, optional
        Draw into it (default: a new figure).
    """
    traces = [Trace(rr.name, rr.states[:, :2], rr.outcome, rr.path_length, rr.states[-1],
                    float(rr.t[-1])) for rr in result.robots]
    fig = plot_traces(scenario, traces, ax=ax)
    ax = ax if ax is not None else fig.axes[0]
    ax.set_title(f"{scenario.name}: {result.planner} (seed {short_repr(result.seed, 24)})")
    return fig
