"""Figures of the planners' diagnostics, drawn from a :class:`~hybridnav.results.Result` alone.

Every function reads what it draws from ``result.extras`` (the tables and arrays a planner records
during its run, written beside ``result.json`` and read back with it), so a figure can be redrawn
from a result folder long after the run. The planners' ``diagnostics(scenario, result)`` methods
choose which of these apply; ``hybridnav run`` writes them next to ``path.png``.

The extras each figure reads (``<robot>`` is a robot name) are declared, with their columns and
what each holds, in :data:`hybridnav.resultspec.EXTRAS`: the writer and the reader check them
against it, and :func:`extras_of` hands a figure only the declared columns.

========================  ==================================================================
figure                    extras
========================  ==================================================================
:func:`plot_signals`      ``signals_<robot>``: ``t`` and one column per traced signal
:func:`plot_potential`    ``harmonic_potential_<robot>`` (array), ``harmonic_grid_<robot>``
:func:`plot_gain_search`  ``swarm_best_<robot>``: ``plan``, ``iteration`` (generation), ``best``
:func:`plot_planned`      ``planned_<robot>`` (``x``, ``y``), ``rfd_seed_<robot>``,
                          ``rfd_path_<robot>``, ``swarm_best_<robot>`` (``plan``, ``iteration``, ``best``)
:func:`plot_steps`        ``steps_<robot>``: ``t``, ``cost``, ``xdot``, ``ydot``, ...
:func:`plot_waypoints`    ``waypoints_<robot>``: ``t``, ``x``, ``y``, ``cost``
:func:`plot_pso_ba`       ``path_points_<robot>``: ``t``, ``x``, ``y``, ``mode``, ``fitness``,
                          ``alpha``, ``gamma``
========================  ==================================================================
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from hybridnav.plotting.labels import LENGTH, axis_label
from hybridnav.plotting.scenes import legend_outside, plot_result
from hybridnav.results import Result, path_length
from hybridnav.resultspec import EXTRAS, Table, declared

__all__ = ["extras_of", "plot_gain_search", "plot_planned", "plot_potential", "plot_pso_ba",
           "plot_signals", "plot_steps", "plot_waypoints"]


def extras_of(result: Result, prefix: str) -> dict[str, Mapping[str, np.ndarray] | np.ndarray]:
    """The extras named ``<prefix>_<robot>``, as robot name -> extra, in the robots' order.

    ``prefix`` must be declared in :data:`hybridnav.resultspec.EXTRAS`; a table comes with its
    declared columns only, so a figure cannot read a column the declaration does not promise.

    Parameters
    ----------
    result : Result
    prefix : str
        A key of :data:`hybridnav.resultspec.EXTRAS`.
    """
    spec = EXTRAS[prefix]
    out = {}
    for r in result.robots:
        value = result.extras.get(f"{prefix}_{r.name}")
        if value is not None:
            out[r.name] = declared(spec, value) if isinstance(spec, Table) else value
    return out


def plot_signals(result: Result, units: Mapping[str, str] | None = None,
                 length: str | None = None) -> Figure | None:
    """Every robot's traced signals over time, one panel per signal (None: nothing traced).

    Parameters
    ----------
    result : Result
    units : mapping, optional
        The signals' declared units (the planner's ``signal_units``; see
        :mod:`hybridnav.plotting.labels`).
    length : str, optional
        The scenario's length unit.
    """
    units = dict(units or {})
    traces = extras_of(result, "signals")
    keys = sorted({k for rec in traces.values() for k in rec if k != "t"})
    if not keys:
        return None
    fig = Figure(figsize=(7.0, 2.0 + 1.6 * len(keys)), layout="constrained")
    axes = fig.subplots(len(keys), 1, sharex=True, squeeze=False)[:, 0]
    for name, rec in traces.items():
        for ax, key in zip(axes, keys):
            if key in rec:
                ax.plot(rec["t"], rec[key], label=name, linewidth=1.0)
                ax.set_ylabel(axis_label(key, units.get(key), length))
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel(axis_label("t", "s"))
    axes[0].set_title(f"{result.planner}: signals along the run")
    return fig


def plot_potential(scenario, result: Result) -> Figure | None:
    """The harmonic potential of the first robot that has one, under the run's paths.

    Parameters
    ----------
    scenario : Scenario
        The scenario of the run (its obstacles are drawn).
    result : Result
        The run, with the extras the figure reads (see the module docstring).
    """
    potentials, grids = extras_of(result, "harmonic_potential"), extras_of(result, "harmonic_grid")
    for r in result.robots:
        phi, grid = potentials.get(r.name), grids.get(r.name)
        if phi is None or grid is None:
            continue
        fig = Figure(figsize=(6.6, 6.0), layout="constrained")
        ax = fig.add_subplot()
        extent = tuple(float(grid[k][0]) for k in ("x0", "x1", "y0", "y1"))
        im = ax.imshow(np.log10(np.maximum(1.0 - phi, 1e-16)), origin="lower", extent=extent,
                       cmap="magma", zorder=0)
        fig.colorbar(im, ax=ax, label=axis_label("log10(1 - phi)", ""))
        plot_result(scenario, result, ax=ax)
        ax.set_title(f"{scenario.name}: harmonic potential of {r.name}")
        return fig
    return None


def plot_gain_search(result: Result, length: str | None = None) -> Figure | None:
    """Best fitness per generation of an offline gain search, per robot.

    Parameters
    ----------
    result : Result
    length : str, optional
        The scenario's length unit (the fitness is a penalized path length).
    """
    logs = extras_of(result, "swarm_best")
    if not logs:
        return None
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    for name, log in logs.items():
        ax.plot(log["iteration"], log["best"], marker="o", label=name)
    ax.set_xlabel("generation")
    ax.set_ylabel(axis_label("best fitness: path length + penalties", LENGTH, length))
    ax.set_title("pseudo-bacterial gain search")
    ax.legend(fontsize=8)
    return fig


def plot_planned(scenario, result: Result) -> Figure | None:
    """The run with the planned paths (dashed), RFD paths and seeds, and the swarm's best cost.

    Parameters
    ----------
    scenario : Scenario
        The scenario of the run (its obstacles are drawn).
    result : Result
        The run, with the extras the figure reads (see the module docstring).
    """
    plans = extras_of(result, "planned")
    if not plans:
        return None
    opts = extras_of(result, "swarm_best")
    fig = Figure(figsize=(11.5 if opts else 6.6, 6.2), layout="constrained")
    axes = fig.subplots(1, 2, width_ratios=(1.35, 1.0)) if opts else [fig.add_subplot()]
    ax = axes[0]
    plot_result(scenario, result, ax=ax)
    seeds, rfd = extras_of(result, "rfd_seed"), extras_of(result, "rfd_path")
    for i, r in enumerate(result.robots):
        col = f"C{i % 10}"
        if r.name in seeds:
            pts = np.column_stack([seeds[r.name]["x"], seeds[r.name]["y"]])
            ax.plot(*pts.T, ":", color="0.3", linewidth=1.0, zorder=6,
                    label=f"{r.name}: RFD seed, length {path_length(pts):.4g} {scenario.units}")
        if r.name in rfd:
            pts = np.column_stack([rfd[r.name]["x"], rfd[r.name]["y"]])
            ax.plot(*pts.T, "-", color="tab:cyan", linewidth=0.9, zorder=6, alpha=0.8,
                    label=f"{r.name}: RFD path, length {path_length(pts):.4g} {scenario.units}")
        plan = plans.get(r.name)
        if plan is not None and len(plan["x"]):
            pts = np.column_stack([plan["x"], plan["y"]])
            ax.plot(*pts.T, "--", color=col, marker=".", markersize=5, linewidth=1.2, zorder=9,
                    label=f"{r.name}: planned, length {path_length(pts):.4g} {scenario.units} "
                          f"({r.metrics.get('planning_time', 0.0):.2g} s)")
    legend_outside(ax, fontsize=7)
    ax.set_title(f"{scenario.name}: {result.planner}, planned (dashed) and travelled paths")
    if opts:
        bx = axes[1]
        for i, r in enumerate(result.robots):
            if r.name in opts:
                bx.plot(opts[r.name]["iteration"], opts[r.name]["best"], color=f"C{i % 10}",
                        label=r.name)
        bx.set_xlabel("iteration")
        bx.set_ylabel(axis_label("best cost: length + penalties", LENGTH, scenario.units))
        best = np.concatenate([o["best"] for o in opts.values()])
        if best.size and best.max() > 10 * best.min() > 0:     # penalties dominate the start
            bx.set_yscale("log")
        bx.legend(fontsize=8)
        bx.set_title("swarm best cost")
    return fig


def plot_steps(result: Result, length: str | None = None) -> Figure | None:
    """The cost of the current step and the controller's velocity, per control cycle.

    Parameters
    ----------
    result : Result
    length : str, optional
        The scenario's length unit (of the velocity).
    """
    tables = extras_of(result, "steps")
    if not tables:
        return None
    fig = Figure(figsize=(7.0, 6.8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for name, tab in tables.items():
        axes[0].plot(tab["t"], tab["cost"], linewidth=1.0, label=name)
        axes[1].plot(tab["t"], tab["xdot"], linewidth=1.0, label=name)
        axes[2].plot(tab["t"], tab["ydot"], linewidth=1.0, label=name)
    axes[0].set_ylabel("step cost f: the planner's objective")
    axes[1].set_ylabel(axis_label("xdot", "length/s", length))
    axes[2].set_ylabel(axis_label("ydot", "length/s", length))
    axes[2].set_xlabel(axis_label("t", "s"))
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"{result.planner}: cost of the current step and controller signals")
    return fig


def plot_waypoints(scenario, result: Result) -> Figure | None:
    """The run with every step's waypoint marked (None when no robot planned a step: the
    figure would be ``path.png`` again).

    Parameters
    ----------
    scenario : Scenario
        The scenario of the run (its obstacles are drawn).
    result : Result
        The run, with the extras the figure reads (see the module docstring).
    """
    steps = {name: pts for name, pts in extras_of(result, "waypoints").items() if len(pts["x"])}
    if not steps:
        return None
    fig = plot_result(scenario, result)
    ax = fig.axes[0]
    for name, pts in steps.items():
        ax.plot(pts["x"], pts["y"], "x", markersize=6, label=f"{name}: waypoints ({len(pts['x'])})")
    legend_outside(ax, fontsize=7)
    return fig


#: PSO-BA path-point modes and how they are marked
_PSO_BA_MARKS = {"goal": ("o", "PSO-BA"), "repaired": ("x", "local search"),
                 "wall": ("^", "wall following"), "track": ("*", "goal")}


def plot_pso_ba(scenario, result: Result) -> Figure | None:
    """PSO-BA's path points by how each was found, their fitness and the PSO-tuned parameters.

    Parameters
    ----------
    scenario : Scenario
        The scenario of the run (its obstacles are drawn).
    result : Result
        The run, with the extras the figure reads (see the module docstring).
    """
    traces = extras_of(result, "path_points")
    if not traces:
        return None
    fig = Figure(figsize=(12.0, 6.4), layout="constrained")
    left, right = fig.subfigures(1, 2, width_ratios=(1.3, 1.0))
    ax = left.add_subplot()
    plot_result(scenario, result, ax=ax)
    for i, (name, tr) in enumerate(traces.items()):
        col = f"C{i % 10}"
        for mode, (mk, label) in _PSO_BA_MARKS.items():
            sel = tr["mode"] == mode
            if sel.any():
                ax.plot(tr["x"][sel], tr["y"][sel], mk, color=col, markersize=4, zorder=9,
                        markerfacecolor="none", label=f"{name}: {label} ({int(sel.sum())})")
    legend_outside(ax, fontsize=7)
    axes = right.subplots(2, 1, sharex=True)
    for i, (name, tr) in enumerate(traces.items()):
        sel = np.isin(tr["mode"], ("goal", "repaired"))
        if not sel.any():
            continue
        col = f"C{i % 10}"
        t = tr["t"][sel]
        axes[0].plot(t, tr["fitness"][sel], ".-", color=col, linewidth=0.8, label=name)
        axes[1].plot(t, tr["alpha"][sel], "o", color=col, markersize=3, label=f"{name}: alpha")
        axes[1].plot(t, tr["gamma"][sel], "s", color=col, markersize=3, markerfacecolor="none",
                     label=f"{name}: gamma")
    axes[0].set_ylabel("fitness of the path point (eq. 6)")
    axes[0].legend(fontsize=7)
    axes[1].set_ylabel(axis_label("PSO-tuned bat parameters", ""))
    axes[1].set_xlabel(axis_label("t", "s"))
    axes[1].legend(fontsize=7)
    axes[0].set_title("PSO-BA searches")
    return fig
