"""Plots of the stability analysis (matplotlib ``Figure`` API: headless, no pyplot state)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as cs
import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.patches import Circle as CirclePatch

from hybridnav.analysis.lyapunov import Equilibrium, LyapunovReport, lyapunov_functions
from hybridnav.analysis.region import Box, as_box
from hybridnav.models.base import Model
from hybridnav.plotting import save_figure

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


def plot_vdot_map(model: Model, V=None, *, target: Sequence[float], region, report:
                  LyapunovReport | None = None, fixed: Mapping[str, float] | None = None,
                  n: int = 201, ax=None) -> Figure:
    """Heat map of ``Vdot`` over (x, y), other states fixed; counterexample and target marked.

    Positive values (red) are where ``V`` grows. Inadmissible states (inside LbCS obstacles) are
    blank.
    """
    model_p, v_num, vdot_num, _, _ = lyapunov_functions(model, V, target=target)
    box = as_box(model_p, region)
    XX, YY, X = _slice(model_p, box, fixed, n)
    d = np.asarray(cs.Function("vd", [model_p.sym.x], [vdot_num]).map(len(X))(X.T)).ravel()
    d[~model_p.admissible(X)] = np.nan
    D = d.reshape(XX.shape)
    fig = Figure(figsize=(6.4, 5.2)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    finite = D[np.isfinite(D)]
    lim = float(np.max(np.abs(finite))) if finite.size else 1.0
    norm = TwoSlopeNorm(vmin=-lim if lim > 0 else -1, vcenter=0.0, vmax=lim if lim > 0 else 1)
    mesh = ax.pcolormesh(XX, YY, D, cmap="RdBu_r", norm=norm, shading="auto")
    fig.colorbar(mesh, ax=ax, label="dV/dt")
    if finite.size and np.nanmin(D) < 0 < np.nanmax(D):
        ax.contour(XX, YY, D, levels=[0.0], colors="k", linewidths=0.8)
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k", label="target")
    if report is not None and report.counterexample is not None:
        ax.plot(*report.counterexample[:2], marker="X", color="k", markersize=11,
                label=f"counterexample (Vdot = {report.worst_vdot:.3g})")
    others = [f"{k} = {v:.3g}" for k, v in zip(model_p.state_names[2:], X[0, 2:])]
    ax.set_title(f"{model_p.name}: dV/dt" + (f" at {', '.join(others)}" if others else ""))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8)
    return fig


def plot_phase_portrait(model: Model, *, target: Sequence[float], region,
                        fixed: Mapping[str, float] | None = None, n: int = 41,
                        trajectories: np.ndarray | None = None, ax=None) -> Figure:
    """Streamlines of the closed-loop (xdot, ydot) over (x, y), other states fixed."""
    box = as_box(model, region)
    XX, YY, X = _slice(model, box, fixed, n)
    f = cs.Function("F", [model.sym.x, model.sym.target, model.sym.p], [model.closed_loop()])
    F = np.asarray(f.map(len(X))(X.T, np.asarray(target, float), model.p_value()))
    U, W = F[0].reshape(XX.shape), F[1].reshape(XX.shape)
    bad = ~model.admissible(X).reshape(XX.shape) | ~np.isfinite(U) | ~np.isfinite(W)
    U, W = np.where(bad, np.nan, U), np.where(bad, np.nan, W)
    fig = Figure(figsize=(6.0, 5.4)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    speed = np.hypot(U, W)
    ax.streamplot(XX, YY, U, W, color=np.log10(speed + 1e-12), cmap="viridis", density=1.2,
                  linewidth=0.7, arrowsize=0.8)
    if trajectories is not None:
        for tr in trajectories:
            ax.plot(tr[:, 0], tr[:, 1], color="C3", linewidth=1.2)
            ax.plot(tr[0, 0], tr[0, 1], "o", color="C3", markersize=3)
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k")
    ax.set_xlim(box.lower[0], box.upper[0])
    ax.set_ylim(box.lower[1], box.upper[1])
    ax.set_aspect("equal")
    ax.set_title(f"{model.name}: closed-loop phase portrait")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    return fig


def plot_V_time(t: np.ndarray, Vt: np.ndarray, labels: Sequence[str] | None = None,
                title: str = "V along closed-loop runs", ax=None) -> Figure:
    """``V(t)`` curves on a log scale."""
    fig = Figure(figsize=(6.4, 4.0)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    for i, v in enumerate(np.atleast_2d(Vt)):
        ax.semilogy(t, np.maximum(v, 1e-300), linewidth=1.0,
                    label=None if labels is None else labels[i])
    ax.set_xlabel("t [s]")
    ax.set_ylabel("V")
    ax.set_title(title)
    if labels is not None:
        ax.legend(fontsize=7)
    return fig


def plot_eigenvalues(reports: Mapping[str, object], ax=None) -> Figure:
    """Eigenvalues of several linearizations (``LinearizationReport``) in the complex plane."""
    fig = Figure(figsize=(6.0, 4.2)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    markers = "osd^v<>ph"
    for i, (name, rep) in enumerate(reports.items()):
        ev = np.asarray(rep.eigenvalues)
        ax.scatter(ev.real + 0.0, ev.imag, marker=markers[i % len(markers)], s=50, alpha=0.8,
                   label=f"{name} ({'stable' if rep.stable else 'not asympt. stable'})")
    ax.axvline(0.0, color="k", linewidth=0.8)
    ax.axhline(0.0, color="k", linewidth=0.5)
    ax.set_xlabel("Re")
    ax.set_ylabel("Im")
    ax.set_title("eigenvalues of the linearizations")
    ax.legend(fontsize=8)
    return fig


def plot_lbcs_field(model: Model, *, target: Sequence[float], region,
                    equilibria: Sequence[Equilibrium] = (), n: int = 241,
                    trajectories: np.ndarray | None = None, ax=None) -> Figure:
    """The LbCS function (log contours), its flow and its stationary points."""
    box = as_box(model, region)
    XX, YY, X = _slice(model, box, None, n)
    _, v_num, _, _, _ = lyapunov_functions(model, None, target=target)
    L = np.asarray(cs.Function("L", [model.sym.x], [v_num]).map(len(X))(X.T)).ravel()
    L[~model.admissible(X)] = np.nan
    fig = Figure(figsize=(6.4, 5.6)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    cs_ = ax.contourf(XX, YY, np.log10(L.reshape(XX.shape) + 1e-12), levels=30, cmap="viridis")
    fig.colorbar(cs_, ax=ax, label="log10 L")
    for ox, oy, r in model.options.get("obstacles", ()):
        ax.add_patch(CirclePatch((ox, oy), r, color="0.3", zorder=3))
    plot_phase_portrait(model, target=target, region=region, n=41, ax=ax,
                        trajectories=trajectories)
    kinds = {"stable": ("v", "red", "local minimum"), "saddle": ("X", "orange", "saddle"),
             "unstable": ("^", "white", "maximum"), "degenerate": ("s", "pink", "degenerate")}
    seen = set()
    for e in equilibria:
        if e.is_target:
            continue
        m, c, lab = kinds[e.kind]
        ax.plot(*e.state[:2], marker=m, color=c, markersize=12, markeredgecolor="k", zorder=6,
                label=None if lab in seen else lab)
        seen.add(lab)
    ax.set_title("LbCS: L, its flow and stationary points")
    if seen:
        ax.legend(loc="upper left", fontsize=8)
    return fig


def plot_sweep(table, traj: np.ndarray, *, target: Sequence[float], ax=None,
               title: str = "closed-loop sweep") -> Figure:
    """Paths of a sweep, coloured by whether V decreased monotonically and the target was reached."""
    fig = Figure(figsize=(6.2, 5.6)) if ax is None else ax.figure
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
            ax.plot(traj[i, 0, 0], traj[i, 0, 1], "kx", markersize=6)
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k", zorder=5)
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.legend(fontsize=8, loc="best")
    return fig


def plot_basin(model: Model, *, target: Sequence[float], region, levels: Mapping[str, tuple]
               = {}, fixed: Mapping[str, float] | None = None, n: int = 101, ax=None,
               basin_grid=None) -> Figure:
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
        drawn as a contour (``level = inf``: the whole plot, noted in the legend).
    basin_grid : tuple, optional
        ``(xs, ys, converged)`` from :func:`hybridnav.analysis.roa.basin`, when already computed.
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D

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
    fig = Figure(figsize=(6.4, 5.6)) if ax is None else ax.figure
    ax = ax or fig.add_subplot()
    ax.pcolormesh(XX, YY, img, cmap=ListedColormap(["#d9d9d9", "#a6dba0"]), vmin=0, vmax=1,
                  shading="auto")
    handles = [Line2D([], [], color="#a6dba0", lw=8,
                      label=f"converges in simulation ({100 * np.nanmean(img):.0f} % of the grid)"),
               Line2D([], [], color="#d9d9d9", lw=8, label="does not converge")]
    colors = ["k", "tab:blue", "tab:purple", "tab:red"]
    for i, (label, (V, level)) in enumerate(levels.items()):
        c = colors[i % len(colors)]
        if level is None or not np.isfinite(level):
            handles.append(Line2D([], [], color=c, lw=2, label=f"{label}: all of the plane"))
            continue
        _, v_num, _, _, _ = lyapunov_functions(model, V, target=target)
        vals = np.asarray(cs.Function("V", [model.sym.x], [v_num]).map(len(grid))(grid.T))
        vals = np.where(free.ravel(), vals.ravel(), np.nan).reshape(XX.shape)
        if np.nanmin(vals) <= level <= np.nanmax(vals):
            ax.contour(XX, YY, vals, levels=[level], colors=c, linewidths=1.8)
        handles.append(Line2D([], [], color=c, lw=2, label=f"{label}: V <= {level:.4g}"))
    for ox, oy, r in model.options.get("obstacles", ()):
        ax.add_patch(CirclePatch((ox, oy), r, color="0.3", zorder=3))
    ax.plot(*target, marker="*", color="gold", markersize=14, markeredgecolor="k")
    ax.set_xlim(xs[0], xs[-1])
    ax.set_ylim(ys[0], ys[-1])
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"{model.name}: region of attraction, simulated and certified")
    ax.legend(handles=handles, loc="upper left", fontsize=7)
    return fig
