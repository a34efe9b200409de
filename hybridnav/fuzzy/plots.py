"""Plots of fuzzy systems with matplotlib's object API (``Figure``; no pyplot, no backend switch).

- :func:`plot_memberships`: the terms of every variable, as sampled on its universe.
- :func:`plot_surface`: the control surface, the output over two inputs (the first two unless
  chosen; other inputs held at mid-range). A one-input system gets the output curve.
- :func:`save_memberships_png`, :func:`save_surface_png`: the same, written atomically (PNG, or
  PDF or SVG by the path's suffix; :func:`hybridnav.plotting.save_figure`).

Axes carry the variables' units where the planner that feeds the system declares them
(:func:`hybridnav.planners.fuzzy_units`: EFFC's ``dtheta`` in rad, ``alpha`` and ``w``
dimensionless); a system no planner takes is labelled by its variable names alone.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.engine import universe
from hybridnav.fuzzy.mf import sample
from hybridnav.fuzzy.system import FuzzySystem

__all__ = ["plot_memberships", "plot_surface", "save_memberships_png", "save_surface_png"]

log = logging.getLogger(__name__)


def _units(system: FuzzySystem, units: Mapping[str, str] | None) -> dict[str, str]:
    from hybridnav.planners import fuzzy_units

    return dict(fuzzy_units(system) if units is None else units)


def plot_memberships(system: FuzzySystem, fig: Figure | None = None,
                     units: Mapping[str, str] | None = None) -> Figure:
    """Draw the membership functions of every input and of the output, one panel each.

    Parameters
    ----------
    system : FuzzySystem
    fig : matplotlib.figure.Figure, optional
        Figure to draw into (it is cleared); a new one is made otherwise.
    units : mapping, optional
        Variable name -> unit (``""``: dimensionless); default what the planner that feeds
        the system declares (:func:`hybridnav.planners.fuzzy_units`).

    Returns
    -------
    matplotlib.figure.Figure
        Panels in file order (inputs, then the output). Curves are the sampled terms joined by
        straight lines, which is exactly the membership the evaluator interpolates; the output
        panel marks ``default`` with a dotted line.
    """
    from hybridnav.plotting.labels import axis_label

    units = _units(system, units)
    variables = [*system.inputs, system.output]
    if fig is None:
        fig = Figure(figsize=(6.4, 2.2 * len(variables)), layout="constrained")
    else:
        fig.clear()
    axes = fig.subplots(len(variables), 1, squeeze=False)[:, 0]
    for ax, v in zip(axes, variables):
        x = universe(v)
        for t in v.terms:
            ax.plot(x, sample(t.mf, t.params, x), label=f"{t.name} ({t.mf})")
        if v is system.output:
            ax.axvline(system.output.default, color="0.4", linestyle=":", linewidth=1.0,
                       label="default")
            ax.set_title(f"output {v.name}")
        else:
            ax.set_title(f"input {v.name}")
        ax.set_xlim(*v.range)
        ax.set_ylim(-0.03, 1.05)
        ax.set_xlabel(axis_label(v.name, units.get(v.name)), labelpad=1)
        ax.set_ylabel(axis_label("membership", ""))
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, frameon=False)
    fig.suptitle(system.name)
    return fig


def plot_surface(system: FuzzySystem, fig: Figure | None = None, inputs: tuple[str, str] | None = None,
                 fixed: Mapping[str, float] | None = None, resolution: int = 161,
                 units: Mapping[str, str] | None = None) -> Figure:
    """Draw the control surface: the output over two inputs, as a heatmap with contour lines
    and a colour bar (the output's range).

    Parameters
    ----------
    system : FuzzySystem
    fig : matplotlib.figure.Figure, optional
        Figure to draw into (it is cleared); a new one is made otherwise.
    inputs : (str, str), optional
        The two inputs on the axes; default the first two. Ignored for a one-input system, which
        is drawn as the output curve over its input.
    fixed : mapping, optional
        Values for the other inputs; default the middle of their ranges.
    resolution : int
        Grid points per axis.
    units : mapping, optional
        Variable name -> unit, as for :func:`plot_memberships`.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    HybridnavError
        Unknown input names, the same input twice, or ``resolution < 2``.
    """
    from hybridnav.plotting.labels import axis_label

    if resolution < 2:
        raise HybridnavError(f"resolution: expected an integer >= 2, got {resolution}")
    units = _units(system, units)

    def label(name: str) -> str:
        return axis_label(name, units.get(name))

    names = system.input_names
    by_name = {v.name: v for v in system.inputs}
    fixed = dict(fixed or {})
    for k in fixed:
        if k not in by_name:
            raise HybridnavError(f"fixed: no input named {k!r} (inputs: {', '.join(names)})")
    if fig is None:
        fig = Figure(figsize=(6.4, 5.2), layout="constrained")
    else:
        fig.clear()
    out = system.output
    if len(names) == 1:
        v = system.inputs[0]
        x = np.linspace(*v.range, max(resolution, 201))
        ax = fig.add_subplot()
        ax.plot(x, system.evaluate(**{v.name: x}))
        ax.set_xlabel(label(v.name))
        ax.set_ylabel(label(out.name))
        ax.set_ylim(*out.range)
        ax.set_title(f"{system.name}: {out.name}({v.name})")
        return fig
    pair = tuple(inputs) if inputs is not None else names[:2]
    if len(pair) != 2 or pair[0] == pair[1] or any(p not in by_name for p in pair):
        raise HybridnavError(f"inputs: expected two different input names out of "
                             f"{', '.join(names)}, got {inputs!r}")
    vx, vy = by_name[pair[0]], by_name[pair[1]]
    gx, gy = np.meshgrid(np.linspace(*vx.range, resolution), np.linspace(*vy.range, resolution))
    args = {n: float(fixed.get(n, 0.5 * (v.range[0] + v.range[1])))
            for n, v in by_name.items() if n not in pair}
    z = system.evaluate(**{vx.name: gx, vy.name: gy}, **args)
    # a heatmap with contour lines: every region visible at once (a 3-D view hides some) and
    # fine enough for a narrow split
    ax = fig.add_subplot()
    mesh = ax.pcolormesh(gx, gy, z, cmap="viridis", vmin=out.range[0], vmax=out.range[1],
                         shading="auto")
    if np.nanmax(z) > np.nanmin(z):
        cs = ax.contour(gx, gy, z, levels=8, colors="white", linewidths=0.6)
        ax.clabel(cs, fontsize=7, fmt="%.2g")
    fig.colorbar(mesh, ax=ax, label=label(out.name))
    ax.set_xlabel(label(vx.name))
    ax.set_ylabel(label(vy.name))
    held = ", ".join(f"{k} = {v:g}" + (f" {units[k]}" if units.get(k) else "")
                     for k, v in args.items())
    ax.set_title(f"{system.name}: control surface" + (f" ({held})" if held else ""))
    return fig


def _save(fig: Figure, path: str | os.PathLike[str], dpi: int) -> Path:
    from hybridnav.plotting.output import save_figure

    return save_figure(fig, path, dpi=dpi, bbox_inches=None)   # constrained layout fits it


def save_memberships_png(system: FuzzySystem, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    """Write :func:`plot_memberships` to a picture file atomically and return the path (PNG;
    ``.pdf`` or ``.svg`` in ``path`` write those).

    Parameters
    ----------
    system : FuzzySystem
    path : str or path-like
    dpi : int
        Dots per inch, in ``[10, 1200]``.
    """
    return _save(plot_memberships(system), path, dpi)


def save_surface_png(system: FuzzySystem, path: str | os.PathLike[str], dpi: int = 120,
                     **kwargs: object) -> Path:
    """Write :func:`plot_surface` (``kwargs`` passed on) to a picture file atomically (PNG;
    ``.pdf`` or ``.svg`` in ``path`` write those).

    Parameters
    ----------
    system : FuzzySystem
    path : str or path-like
    dpi : int
        Dots per inch, in ``[10, 1200]``.
    **kwargs
        Passed to :func:`plot_surface`.
    """
    return _save(plot_surface(system, **kwargs), path, dpi)  # type: ignore[arg-type]
