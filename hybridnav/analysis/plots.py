"""Plots of the stability analysis (matplotlib ``Figure`` API: headless, no pyplot state).

Axes carry units: ``length`` is the length unit of the scenario the analysis runs on (the
functions' ``length`` argument; without it positions are labelled without one), the states'
units are the model's :attr:`~hybridnav.models.base.Model.state_units`, ``V``'s its
``candidate_unit``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as cs
import numpy as np
from matplotlib.colors import ListedColormap, TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.patches import Circle as CirclePatch

from hybridnav.analysis.lyapunov import Equilibrium, LyapunovReport, lyapunov_functions
from hybridnav.analysis.region import Box, as_box
from hybridnav.models.base import Model
from hybridnav.plotting import save_figure
from hybridnav.plotting.labels import LENGTH, axis_label, resolve_unit
from hybridnav.plotting.scenes import legend_outside

__all__ = ["plot_basin", "plot_eigenvalues", "plot_lbcs_field", "plot_phase_portrait", "plot_sweep",
           "plot_V_time", "plot_vdot_map", "save_figure"]


def _slice(model: Model, box: Box, fixed: Mapping[str, float] | None, n: int):
    """States on an ``n x n`` grid over (x, y); other states fixed (default: box middle)."""
    xs = np.linspace(box.lower[0], box.upper[0], n)
    ys = np.linspace(box.lower[1], box.upper[1], n)
    XX, YY = np.meshgrid(xs, ys)
    X = np.tile((box.lower + box.upper) / 2, (n * n, 1))
    X[:, 0], X[:, 1] = XX.ravel(), YY.ravel()
    for k, v in (fixed or {}).items():
        X[:, model.state_names.index(k)] = v
    return XX, YY, X


def _xy_labels(ax, model, length: str | None) -> None:
    """``x (m)``, ``y (m)``: the model's first two states in their declared units."""
    units = getattr(model, "state_units", {})
    names = list(getattr(model, "state_names", ("x", "y")))[:2]
    ax.set_xlabel(axis_label(names[0], units.get(names[0]), length))
    ax.set_ylabel(axis_label(names[1], units.get(names[1]), length))


def _held(model, names, values, length: str | None) -> str:
    """``theta = 0 rad, xi = 0 rad``: the other states of a slice with their units."""
    units = getattr(model, "state_units", {})
    out = []
    for k, v in zip(names, values):
        u = resolve_unit(units.get(k), length)
        out.append(f"{k} = {v:.3g}" + (f" {u}" if u else ""))
    return ", ".join(out)


def _v_rate_label(model, length: str | None) -> str:
    """``dV/dt (m²/s)`` from the model's ``candidate_unit`` (``dV/dt`` where V has no unit)."""
    u = resolve_unit(getattr(model, "candidate_unit", None), length)
    return axis_label("dV/dt", f"{u}/s" if u else None)


def plot_vdot_map(model: Model, V=None, *, target: Sequence[float], region, report:
                  LyapunovReport | None = None, fixed: Mapping[str, float] | None = None,
                  n: int = 201, ax=None, length: str | None = None) -> Figure:
    """Heat map of ``Vdot`` over (x, y), other states fixed; counterexample and target marked.

    Positive values (red) are where ``V`` grows. Inadmissible states (inside LbCS obstacles) are
    blank. ``length`` is the scenario's length unit (the axes' and, for the model's own
    candidate, the colour bar's).
    """
    model_p, v_num, vdot_num, _, _ = lyapunov_functions(model, V, target=target)
    box = as_box(model_p, region)
    XX, YY, X = _slice(model_p, box, fixed, n)
    d = np.asarray(cs.Function("vd", [model_p.sym.x], [vdot_num]).map(len(X))(X.T)).ravel()
    d[~model_p.admissible(X)] = np.nan
    D = d.reshape(XX.shape)
    fig = Figure(figsize=(6.4, 6.0), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    finite = D[np.isfinite(D)]
    lim = float(np.max(np.abs(finite))) if finite.size else 1.0
    norm = TwoSlopeNorm(vmin=-lim if lim > 0 else -1, vcenter=0.0, vmax=lim if lim > 0 else 1)
    mesh = ax.pcolormesh(XX, YY, D, cmap="RdBu_r", norm=norm, shading="auto")
    fig.colorbar(mesh, ax=ax, label=_v_rate_label(model_p, length) if V is None else "dV/dt")
    if finite.size and np.nanmin(D) < 0 < np.nanmax(D):
        ax.contour(XX, YY, D, levels=[0.0], colors="k", linewidths=0.8)
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k", linestyle="none",
            label="target")
    if report is not None and report.counterexample is not None:
        ax.plot(*report.counterexample[:2], marker="X", color="k", markersize=11, linestyle="none",
                label=f"counterexample (Vdot = {report.worst_vdot:.3g})")
    others = _held(model_p, model_p.state_names[2:], X[0, 2:], length)
    ax.set_title(f"{model_p.name}: dV/dt" + (f" at {others}" if others else ""))
    _xy_labels(ax, model_p, length)
    ax.set_aspect("equal")
    legend_outside(ax)
    return fig


#: the streamlines' colours: plasma without its pale yellow end (invisible on white)
_SPEED_CMAP = "plasma"
_SPEED_CMAP_TOP = 0.85


def plot_phase_portrait(model: Model, *, target: Sequence[float], region,
                        fixed: Mapping[str, float] | None = None, n: int = 41,
                        trajectories: np.ndarray | None = None, ax=None,
                        length: str | None = None, colorbar: bool = True) -> Figure:
    """Streamlines of the closed-loop (xdot, ydot) over (x, y), other states fixed.

    With ``colorbar`` the streamlines are coloured by the speed (log scale) with a labelled
    colour bar; without, they are drawn in one dark colour (over another map:
    :func:`plot_lbcs_field`). ``length`` is the scenario's length unit.
    """
    box = as_box(model, region)
    XX, YY, X = _slice(model, box, fixed, n)
    f = cs.Function("F", [model.sym.x, model.sym.target, model.sym.p], [model.closed_loop()])
    F = np.asarray(f.map(len(X))(X.T, np.asarray(target, float), model.p_value()))
    U, W = F[0].reshape(XX.shape), F[1].reshape(XX.shape)
    bad = ~model.admissible(X).reshape(XX.shape) | ~np.isfinite(U) | ~np.isfinite(W)
    U, W = np.where(bad, np.nan, U), np.where(bad, np.nan, W)
    fig = Figure(figsize=(6.4, 5.6), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    speed = np.hypot(U, W)
    if colorbar:
        from matplotlib import colormaps

        from matplotlib.colors import LogNorm

        cmap = ListedColormap(colormaps[_SPEED_CMAP](np.linspace(0.0, _SPEED_CMAP_TOP, 256)))
        finite = speed[np.isfinite(speed) & (speed > 0)]
        top = float(finite.max()) if finite.size else 1.0
        low = max(float(finite.min()), 1e-6 * top) if finite.size else 1e-6
        sp = ax.streamplot(XX, YY, U, W, color=np.clip(speed, low, top), cmap=cmap,
                           norm=LogNorm(vmin=low, vmax=top), density=1.2, linewidth=0.8,
                           arrowsize=0.8)
        fig.colorbar(sp.lines, ax=ax, label=axis_label("speed", "length/s", length))
    else:
        ax.streamplot(XX, YY, U, W, color="0.15", density=1.2, linewidth=0.6, arrowsize=0.8)
    if trajectories is not None:
        for i, tr in enumerate(trajectories):
            ax.plot(tr[:, 0], tr[:, 1], color="C3", linewidth=1.2,
                    label="run from the scenario's start" if i == 0 else None)
            ax.plot(tr[0, 0], tr[0, 1], "o", color="C3", markersize=3)
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k",
            linestyle="none", label="target")
    ax.set_xlim(box.lower[0], box.upper[0])
    ax.set_ylim(box.lower[1], box.upper[1])
    ax.set_aspect("equal")
    others = _held(model, model.state_names[2:], X[0, 2:], length)
    ax.set_title(f"{model.name}: closed-loop phase portrait" + (f" at {others}" if others else ""))
    _xy_labels(ax, model, length)
    legend_outside(ax)
    return fig


def plot_V_time(t: np.ndarray, Vt: np.ndarray, labels: Sequence[str] | None = None,
                title: str = "V along closed-loop runs", ax=None, color_by=None,
                color_label: str | None = None, v_label: str = "V") -> Figure:
    """``V(t)`` curves on a log scale.

    Parameters
    ----------
    t : ndarray
        Times (s).
    Vt : ndarray
        One curve per row.
    labels : sequence of str, optional
        A legend entry per curve (for a few curves).
    title : str
    ax : matplotlib.axes.Axes, optional
    color_by : array, optional
        A value per curve (e.g. the start's distance to the target): the curves are coloured by
        it, with a colour bar labelled ``color_label`` (a family of curves, no legend).
    color_label : str, optional
    v_label : str
        The y axis label (``V`` with its unit).
    """
    fig = Figure(figsize=(6.4, 4.0), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    curves = np.atleast_2d(Vt)
    colors = [None] * len(curves)
    if color_by is not None:
        from matplotlib import colormaps
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        c = np.asarray(color_by, dtype=float)
        norm = Normalize(vmin=float(np.min(c)), vmax=float(np.max(c)) if np.ptp(c) > 0
                         else float(np.min(c)) + 1.0)
        cmap = colormaps["viridis"]
        colors = [cmap(norm(v)) for v in c]
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax,
                     label=color_label or "curve value")
    for i, v in enumerate(curves):
        ax.semilogy(t, np.maximum(v, 1e-300), linewidth=1.0, color=colors[i],
                    label=None if labels is None else labels[i])
    ax.set_xlabel(axis_label("t", "s"))
    ax.set_ylabel(v_label)
    ax.set_title(title)
    if labels is not None:
        ax.legend(fontsize=7)
    return fig


def _multiplicities(ev: np.ndarray) -> list[tuple[complex, int]]:
    """Distinct eigenvalues and how often each occurs (equal to 1e-9 of the spectrum's scale)."""
    scale = max(1.0, float(np.max(np.abs(ev)))) if ev.size else 1.0
    out: list[tuple[complex, int]] = []
    for z in ev:
        for k, (w, m) in enumerate(out):
            if abs(z - w) <= 1e-9 * scale:
                out[k] = (w, m + 1)
                break
        else:
            out.append((complex(z), 1))
    return out


def plot_eigenvalues(reports: Mapping[str, object], ax=None) -> Figure:
    """Eigenvalues of several linearizations (``LinearizationReport``) in the complex plane
    (continuous time: 1/s); a repeated eigenvalue is annotated with its multiplicity (``×2``)."""
    fig = Figure(figsize=(6.8, 4.6), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    markers = "osd^v<>ph"
    for i, (name, rep) in enumerate(reports.items()):
        ev = np.asarray(rep.eigenvalues)
        sc = ax.scatter(ev.real + 0.0, ev.imag, marker=markers[i % len(markers)], s=50,
                        alpha=0.8,
                        label=f"{name} ({'stable' if rep.stable else 'not asympt. stable'})")
        for z, m in _multiplicities(ev):
            if m > 1:
                ax.annotate(f"×{m}", (z.real + 0.0, z.imag), xytext=(6, 4 + 9 * i),
                            textcoords="offset points", fontsize=9,
                            color=sc.get_facecolor()[0], fontweight="bold")
    ax.axvline(0.0, color="k", linewidth=0.8)
    ax.axhline(0.0, color="k", linewidth=0.5)
    ax.set_xlabel(axis_label("Re λ", "1/s"))
    ax.set_ylabel(axis_label("Im λ", "1/s"))
    ax.set_title("eigenvalues of the linearizations (×k: k-fold)")
    legend_outside(ax, ncols=1)
    return fig


def plot_lbcs_field(model: Model, *, target: Sequence[float], region,
                    equilibria: Sequence[Equilibrium] = (), n: int = 241,
                    trajectories: np.ndarray | None = None, ax=None,
                    length: str | None = None) -> Figure:
    """The LbCS function (log contours), its flow and its stationary points (``length``: the
    scenario's length unit)."""
    box = as_box(model, region)
    XX, YY, X = _slice(model, box, None, n)
    _, v_num, _, _, _ = lyapunov_functions(model, None, target=target)
    L = np.asarray(cs.Function("L", [model.sym.x], [v_num]).map(len(X))(X.T)).ravel()
    L[~model.admissible(X)] = np.nan
    fig = Figure(figsize=(6.4, 6.2), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    cs_ = ax.contourf(XX, YY, np.log10(L.reshape(XX.shape) + 1e-12), levels=30, cmap="viridis")
    fig.colorbar(cs_, ax=ax, label="log10 L (the LbCS function)")
    for ox, oy, r in model.options.get("obstacles", ()):
        ax.add_patch(CirclePatch((ox, oy), r, color="0.3", zorder=3))
    plot_phase_portrait(model, target=target, region=region, n=41, ax=ax,
                        trajectories=trajectories, length=length, colorbar=False)
    kinds = {"stable": ("v", "red", "local minimum"), "saddle": ("X", "orange", "saddle"),
             "unstable": ("^", "white", "maximum"), "degenerate": ("s", "pink", "degenerate")}
    seen = set()
    for e in equilibria:
        if e.is_target:
            continue
        m, c, lab = kinds[e.kind]
        ax.plot(*e.state[:2], marker=m, color=c, markersize=12, markeredgecolor="k", zorder=6,
                linestyle="none", label=None if lab in seen else lab)
        seen.add(lab)
    ax.set_title("LbCS: L, its flow and stationary points")
    legend_outside(ax)
    return fig


def plot_sweep(table, traj: np.ndarray, *, target: Sequence[float], ax=None,
               title: str = "closed-loop sweep", length: str | None = None) -> Figure:
    """Paths of a sweep, coloured by whether V decreased monotonically and the target was
    reached (``length``: the scenario's length unit)."""
    fig = Figure(figsize=(6.2, 6.2), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    styles = {(True, True): ("C2", "reached, V monotone"),
              (False, True): ("C1", "reached, V not monotone"),
              (True, False): ("C0", "not reached, V monotone"),
              (False, False): ("C3", "not reached")}
    seen = set()
    for i, row in enumerate(table.itertuples()):
        col, lab = styles[(bool(row.V_monotone), bool(row.reached))]
        ax.plot(traj[i, :, 0], traj[i, :, 1], color=col, linewidth=0.6, alpha=0.6,
                label=None if lab in seen else lab)
        seen.add(lab)
        if getattr(row, "jackknife", False):
            ax.plot(traj[i, 0, 0], traj[i, 0, 1], "kx", markersize=6,
                    label=None if "jackknifed" in seen else "start of a jackknifed run")
            seen.add("jackknifed")
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k", zorder=5,
            linestyle="none", label="target")
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel(axis_label("x", LENGTH, length))
    ax.set_ylabel(axis_label("y", LENGTH, length))
    legend_outside(ax)
    return fig


def plot_basin(model: Model, *, target: Sequence[float], region, levels: Mapping[str, tuple]
               = {}, fixed: Mapping[str, float] | None = None, n: int = 101, ax=None,
               basin_grid=None, length: str | None = None) -> Figure:
    """The true region of attraction (batched simulation on a grid) beside certified level sets.

    Parameters
    ----------
    model : Model
    target : (float, float)
    region : dict or Box
        Bounds of the plotted ``x``, ``y``.
    fixed : dict, optional
        Values of the other states (default 0, see :func:`hybridnav.analysis.roa.basin`).
    n : int
        Grid points per axis.
    ax : matplotlib.axes.Axes, optional
        Draw into it (default: a new figure).
    levels : dict
        ``{label: (V, level)}``: each certified sublevel set ``{V <= level}`` (``V`` a candidate as
        accepted by :func:`hybridnav.analysis.check_lyapunov`, ``None`` for the model's own) is
        drawn as a contour (``level = inf``: the whole plot, said in the title). The legend,
        below the map, lists what is drawn: the two simulated regions present and the level
        sets whose contour crosses the plot.
    basin_grid : tuple, optional
        ``(xs, ys, converged)`` from :func:`hybridnav.analysis.roa.basin`, when already computed.
    length : str, optional
        The scenario's length unit (the axes).
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from hybridnav.analysis.roa import basin

    box = as_box(model, region)
    xs, ys, conv = basin_grid if basin_grid is not None else basin(
        model, target=target, region=box, fixed=fixed, n=n)
    XX, YY = np.meshgrid(xs, ys)
    grid = np.zeros((XX.size, model.nx))
    grid[:, 0], grid[:, 1] = XX.ravel(), YY.ravel()
    for k, v in (fixed or {}).items():
        grid[:, model.state_names.index(k)] = v
    free = model.admissible(grid).reshape(XX.shape)
    img = np.where(free, conv.astype(float), np.nan)
    fig = Figure(figsize=(6.4, 6.4), layout="constrained") if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    # each simulated region its own labelled mesh (the legend's patches stand for these)
    handles = []
    share = 100 * np.nanmean(img)
    for value, colour, text in ((1.0, "#a6dba0", f"converges in simulation ({share:.0f} % of "
                                                  "the grid)"),
                                (0.0, "#d9d9d9", "does not converge")):
        part = np.where(img == value, 1.0, np.nan)
        if np.isfinite(part).any():
            ax.pcolormesh(XX, YY, part, cmap=ListedColormap([colour]), vmin=0, vmax=1,
                          shading="auto", label=text)
            handles.append(Patch(facecolor=colour, edgecolor="none", label=text))
    colors = ["k", "tab:blue", "tab:purple", "tab:red"]
    whole = []
    for i, (label, (V, level)) in enumerate(levels.items()):
        c = colors[i % len(colors)]
        if level is None or not np.isfinite(level):
            whole.append(label)            # no contour to draw: said in the title
            continue
        _, v_num, _, _, _ = lyapunov_functions(model, V, target=target)
        vals = np.asarray(cs.Function("V", [model.sym.x], [v_num]).map(len(grid))(grid.T))
        vals = np.where(free.ravel(), vals.ravel(), np.nan).reshape(XX.shape)
        if np.nanmin(vals) <= level <= np.nanmax(vals):
            text = f"{label}: V <= {level:.4g}"
            cset = ax.contour(XX, YY, vals, levels=[level], colors=c, linewidths=1.8)
            cset.set_label(text)
            handles.append(Line2D([], [], color=c, lw=2, label=text))
    for ox, oy, r in model.options.get("obstacles", ()):
        ax.add_patch(CirclePatch((ox, oy), r, color="0.3", zorder=3))
    (star,) = ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k",
                      linestyle="none", label="target")
    handles.append(star)
    ax.set_xlim(xs[0], xs[-1])
    ax.set_ylim(ys[0], ys[-1])
    ax.set_aspect("equal")
    _xy_labels(ax, model, length)
    ax.set_title(f"{model.name}: region of attraction, simulated and certified"
                 + "".join(f"\n{w}: certified on all of the plane" for w in whole), fontsize=10)
    legend_outside(ax, fontsize=7, handles=handles)
    return fig
