"""Convergence of the swarm searches inside the planners, over the runs of a comparison.

Every planner that searches with a swarm records, per robot, the best cost after each iteration
of every search in ``swarm_best_<robot>`` (``plan``, ``iteration``, ``best``): the path planners'
PSO (one search per run), PBPF's gain search (one) and the step planners' optimizer (one search
per step). :func:`convergence_rows` flattens a run's records; :func:`plot_convergence` draws a
scenario's curves, one panel per planner: the median over runs and the 10-90 % band of the best
cost per iteration where a run is one search, and of each step's final best cost per step where
a run is many. A search with no feasible point yet counts as infinite cost (so a median is drawn
only where at least half the runs have one).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

__all__ = ["CONVERGENCE_COLUMNS", "convergence_rows", "plot_convergence"]

CONVERGENCE_COLUMNS = ["planner", "scenario", "run", "robot", "plan", "iteration", "best"]


def convergence_rows(result, label: str, run: int) -> pd.DataFrame:
    """The swarm searches of one run as rows of :data:`CONVERGENCE_COLUMNS` (empty if the
    planner searches with no swarm).

    Parameters
    ----------
    result : Result
        A planner's run.
    label : str
        The planner's label in the comparison.
    run : int
        The run's index.
    """
    frames = []
    for r in result.robots:
        rec = result.extras.get(f"swarm_best_{r.name}")
        if not rec or not len(rec["best"]):
            continue
        best = np.asarray(rec["best"], dtype=float)
        frames.append(pd.DataFrame({
            "planner": label, "scenario": result.scenario, "run": run, "robot": r.name,
            "plan": np.asarray(rec["plan"], dtype=int),
            "iteration": np.asarray(rec["iteration"], dtype=int), "best": best}))
    if not frames:
        return pd.DataFrame(columns=CONVERGENCE_COLUMNS)
    return pd.concat(frames, ignore_index=True)[CONVERGENCE_COLUMNS]


def _curves(rows: pd.DataFrame) -> tuple[str, pd.DataFrame]:
    """``(x label, per-run curves)``: best per iteration where every run is one search, else
    each search's final best per step (rows: runs x robots, columns: x)."""
    if rows["plan"].max() == 0:
        wide = rows.pivot_table(index=["run", "robot"], columns="iteration", values="best",
                                aggfunc="first", dropna=False)
        return "iteration", wide
    last = rows.sort_values("iteration").groupby(["run", "robot", "plan"]).last()["best"]
    return "step: one search each, its final best", last.unstack("plan")


def plot_convergence(scenario: str, rows: pd.DataFrame,
                     labels: Mapping[str, Any] | None = None) -> Figure | None:
    """One panel per planner: median and 10-90 % band over runs of the best cost.

    Parameters
    ----------
    scenario : str
        The scenario's name (the title).
    rows : DataFrame
        :data:`CONVERGENCE_COLUMNS` rows of that scenario.
    labels : mapping, optional
        The planner labels in panel order (default: as they come).

    Returns
    -------
    Figure or None
        None when no planner searched with a swarm.
    """
    if rows.empty:
        return None
    order = list(labels) if labels is not None else list(dict.fromkeys(rows["planner"]))
    order = [lb for lb in order if (rows["planner"] == lb).any()]
    cols = min(3, len(order))
    nrows = -(-len(order) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.2 * nrows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, cols, squeeze=False)).ravel()
    for ax, label in zip(axes, order):
        xlabel, wide = _curves(rows[rows["planner"] == label])
        x = np.asarray(wide.columns, dtype=float)
        values = wide.to_numpy(dtype=float)      # inf: no feasible point yet; nan: no such step
        if not np.isfinite(values).any():
            ax.set_title(f"{label}: no feasible point", fontsize=9)
            continue
        with np.errstate(all="ignore"):
            lo, med, hi = np.nanpercentile(values, [10, 50, 90], axis=0)

        def finite(v):
            return np.where(np.isfinite(v), v, np.nan)     # drawn where finite only

        ax.fill_between(x, finite(lo), finite(hi), alpha=0.25, color="C0", linewidth=0,
                        label="10-90 % of runs")
        ax.plot(x, finite(med), color="C0", label=f"median of {len(values)} run(s)")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("best cost: the search's objective")
        ax.set_title(label, fontsize=9)
        ax.legend(fontsize=7)
    for ax in axes[len(order):]:
        ax.set_visible(False)
    fig.suptitle(f"{scenario}: convergence of the swarm searches")
    return fig
