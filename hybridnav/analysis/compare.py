"""Comparison harness: every planner x scenario x run, serially, on local processes or on Dask.

Each run ``r`` gets the seed ``SeedSequence(seed, spawn_key=(r,))`` — the same for every planner
and scenario (common random numbers), and independent of how the work is spread, so the tables
are identical whatever the number of workers or the backend.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text

log = logging.getLogger(__name__)

__all__ = ["RUN_COLUMNS", "compare", "run_seed", "summarize_runs", "write_comparison"]

RUN_COLUMNS = ["planner", "scenario", "run", "seed", "robot", "outcome", "path_length",
               "time_to_goal", "smoothness", "min_clearance", "compute_time"]
METRICS = ["path_length", "time_to_goal", "smoothness", "min_clearance", "compute_time"]
#: metrics summarized over the robots that reached their goal only
REACHED_ONLY = ("path_length", "time_to_goal", "smoothness")


def run_seed(seed: int, run: int) -> int:
    """The seed of run ``run`` of a comparison seeded with ``seed``."""
    return int(np.random.SeedSequence(seed, spawn_key=(run,)).generate_state(1)[0])


@dataclass(frozen=True)
class _Task:
    planner: str
    params: tuple
    scenario: str
    run: int
    seed: int


def _execute(task: _Task) -> list[dict[str, Any]]:
    """Run one planner on one scenario (in whatever process gets the task)."""
    from hybridnav import planners
    from hybridnav.world import load_scenario

    scenario = load_scenario(task.scenario)
    result = planners.get(task.planner, **dict(task.params)).run(scenario, seed=task.seed)
    rows = []
    for r in result.robots:
        s = r.summary()
        rows.append({"planner": task.planner, "scenario": scenario.name, "run": task.run,
                     "seed": task.seed, "robot": r.name, **{k: s[k] for k in RUN_COLUMNS[5:]}})
    return rows


def compare(
    planners: Sequence[str],
    scenarios: Sequence[str],
    runs: int,
    *,
    seed: int = 0,
    params: Mapping[str, Mapping[str, Any]] | None = None,
    workers: int = 1,
    dask: str | Any | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run every combination and return ``(runs, summary)`` tables.

    Parameters
    ----------
    planners, scenarios : sequence of str
        Planner names; scenario names or paths.
    runs : int
        Runs per combination (run ``r`` uses :func:`run_seed`).
    params : dict, optional
        ``{planner: {parameter: value}}`` overrides.
    workers : int
        Local worker processes (1: in this process).
    dask : str or distributed.Client, optional
        A Dask scheduler address (or a client) to run the tasks on instead.
    progress : callable, optional
        ``progress(done, total)`` after each finished task.
    """
    from hybridnav import planners as registry
    from hybridnav.world import load_scenario

    if runs < 1:
        raise HybridnavError(f"runs: expected a positive number of runs, got {runs}")
    params = {k: dict(v) for k, v in (params or {}).items()}
    unknown = sorted(set(params) - set(planners))
    if unknown:
        raise HybridnavError(f"--set {unknown[0]}.*: {unknown[0]!r} is not one of the compared "
                             f"planners ({', '.join(planners)})")
    for p in planners:                     # fail before any work starts
        planner = registry.get(p, **params.get(p, {}))
        params[p] = planner.describe()
        for s in scenarios:
            planner.check_scenario(load_scenario(s))
    tasks = [_Task(p, tuple(sorted(params[p].items())), s, r, run_seed(seed, r))
             for p in planners for s in scenarios for r in range(runs)]
    rows: list[dict[str, Any]] = []
    done = 0

    def finished(result_rows):
        nonlocal done
        rows.extend(result_rows)
        done += 1
        if progress is not None:
            progress(done, len(tasks))

    if dask is not None:
        from distributed import Client, as_completed as dask_completed

        client = dask if isinstance(dask, Client) else Client(dask)
        try:
            futures = client.map(_execute, tasks, pure=False)
            for fut in dask_completed(futures):
                finished(fut.result())
        finally:
            if client is not dask:
                client.close()
    elif workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(_execute, t) for t in tasks]
            for fut in as_completed(futures):
                finished(fut.result())
    else:
        for t in tasks:
            finished(_execute(t))
    table = pd.DataFrame(rows, columns=RUN_COLUMNS)
    order = {p: i for i, p in enumerate(planners)}
    table = table.sort_values(["planner", "scenario", "run", "robot"],
                              key=lambda c: c.map(order) if c.name == "planner" else c,
                              kind="stable").reset_index(drop=True)
    return table, summarize_runs(table)


def summarize_runs(table: pd.DataFrame) -> pd.DataFrame:
    """Per planner x scenario: runs, success rate, and mean/std/min/max of every metric.

    ``path_length``, ``time_to_goal`` and ``smoothness`` are summarized over the robots that
    reached their goal (a failed run has no meaningful length); clearance and compute time over
    all robots.
    """
    out = []
    for (planner, scenario), g in table.groupby(["planner", "scenario"], sort=False):
        ok = g[g["outcome"] == "reached"]
        row: dict[str, Any] = {"planner": planner, "scenario": scenario, "robots": len(g),
                               "success_rate": len(ok) / len(g)}
        for outcome in ("collided", "out_of_bounds", "stuck", "timeout"):
            row[outcome] = int((g["outcome"] == outcome).sum())
        for m in METRICS:
            vals = (ok if m in REACHED_ONLY else g)[m].astype(float).dropna()
            for stat in ("mean", "std", "min", "max"):
                row[f"{m}_{stat}"] = getattr(vals, stat)() if len(vals) else np.nan
        out.append(row)
    return pd.DataFrame(out)


def write_comparison(folder: str | Path, table: pd.DataFrame, summary: pd.DataFrame) -> list[str]:
    """Write ``runs.csv``, ``summary.csv`` and the comparison plots; returns the file names."""
    from hybridnav.plotting import save_figure

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / "runs.csv", table.to_csv(index=False))
    atomic_write_text(folder / "summary.csv", summary.to_csv(index=False))
    names = ["runs.csv", "summary.csv"]
    for metric, label in (("path_length", "path length (reached)"),
                          ("time_to_goal", "time to goal [s] (reached)"),
                          ("success_rate", "success rate")):
        save_figure(_bars(summary, metric, label), folder / f"compare_{metric}.png")
        names.append(f"compare_{metric}.png")
    return names


def _bars(summary: pd.DataFrame, metric: str, label: str) -> Figure:
    fig = Figure(figsize=(7.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    scen = list(dict.fromkeys(summary["scenario"]))
    plans = list(dict.fromkeys(summary["planner"]))
    width = 0.8 / max(1, len(plans))
    for i, p in enumerate(plans):
        sub = summary[summary["planner"] == p].set_index("scenario").reindex(scen)
        x = np.arange(len(scen)) + (i - (len(plans) - 1) / 2) * width
        if metric == "success_rate":
            ax.bar(x, sub[metric], width, label=p)
        else:
            ax.bar(x, sub[f"{metric}_mean"], width, yerr=sub[f"{metric}_std"].fillna(0),
                   capsize=3, label=p)
    ax.set_xticks(np.arange(len(scen)), scen, rotation=20)
    ax.set_ylabel(label)
    ax.legend(fontsize=8)
    ax.set_title(label)
    return fig
