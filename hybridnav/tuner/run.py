"""A whole tuning job: run the GA, then write the tuned system, its report and its plots.

``DIR`` receives ``fis.json`` (the tuned system), ``logbook.csv`` (gen, evals, min, mean, max,
std, wall_time), ``evaluations.csv`` (every individual's outcome, length and time per training
environment), ``convergence.png``, ``mfs.png`` (start and tuned), ``surface.png``, ``paths.png``
(the starting and the tuned controller on the training and held-out scenarios), ``report.md``,
and the deployment exports: ``fis.fll`` (fuzzylite), ``fis.fis`` (MATLAB), ``fis.fcl``
(IEC 61131-7) and ``effc_fis.h``/``effc_fis.c`` (standalone C).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.plotting import plot_result, save_figure
from hybridnav.tuner.backends import make_backend
from hybridnav.tuner.ga import TuneResult, tune
from hybridnav.tuner.job import Job

log = logging.getLogger(__name__)

__all__ = ["run_job", "write_outputs"]


def run_job(job: Job, out: str | Path, *, resume: bool = False,
            progress: Callable[[dict[str, Any]], None] | None = None,
            dask_client: Any = None) -> tuple[TuneResult, list[str]]:
    """Run ``job`` on its backend, write every output into ``out``; returns the result and the
    names of the files written."""
    out = Path(out)
    be = job["backend"]
    backend = make_backend(be["workers"], dask_client or be["dask"])
    with backend:
        result = tune(job, out, backend=backend, resume=resume, progress=progress)
    return result, write_outputs(job, result, out)


def write_outputs(job: Job, result: TuneResult, out: Path) -> list[str]:
    """Write the tuned system, tables, plots, exports and ``report.md``."""
    from hybridnav import planners
    from hybridnav.fuzzy import plots

    out.mkdir(parents=True, exist_ok=True)
    files = []
    result.system.save(out / "fis.json")
    files.append("fis.json")
    atomic_write_text(out / "logbook.csv", pd.DataFrame(result.logbook).to_csv(index=False))
    atomic_write_text(out / "evaluations.csv", pd.DataFrame(result.records).to_csv(index=False))
    files += ["logbook.csv", "evaluations.csv"]
    save_figure(_convergence(result.logbook, job), out / "convergence.png")
    start = job.start_system()
    fig = Figure(figsize=(11, 7), layout="constrained")
    left, right = fig.subfigures(1, 2)
    plots.plot_memberships(start, fig=left)
    left.suptitle(f"start: {start.name}")
    plots.plot_memberships(result.system, fig=right)
    right.suptitle(f"tuned: {result.system.name}")
    save_figure(fig, out / "mfs.png")
    plots.save_surface_png(result.system, out / "surface.png")
    files += ["convergence.png", "mfs.png", "surface.png"]
    # the starting and the tuned controller on every training and held-out scenario
    pl = job["planner"]
    rows = []
    scen = [("train", s) for s in job.scenarios("train")] + \
           [("held-out", s) for s in job.scenarios("test")]
    fig = Figure(figsize=(8.5, 4.0 * len(scen)), layout="constrained")
    axes = fig.subplots(len(scen), 2, squeeze=False)
    for row, (kind, s) in enumerate(scen):
        for col, (label, system) in enumerate((("start", start), ("tuned", result.system))):
            res = planners.get("effc", fis=system, speed=pl["speed"], max_turn=pl["max_turn"],
                               stuck_window=pl["stuck_window"],
                               stuck_radius=pl["stuck_radius"]).run(s)
            r = res.robots[0]
            plot_result(s, res, ax=axes[row, col])
            axes[row, col].set_title(f"{s.name} ({kind}): {label}", fontsize=9)
            rows.append({"scenario": s.name, "set": kind, "system": label, "outcome": r.outcome,
                         "path_length": r.path_length, "time_to_goal": r.time_to_goal})
    save_figure(fig, out / "paths.png")
    files.append("paths.png")
    files += _exports(result.system, out)
    table = pd.DataFrame(rows)
    atomic_write_text(out / "report.md", _report(job, result, table, files))
    files.append("report.md")
    return files


def _exports(system, out: Path) -> list[str]:
    """Deployment exports (FLL, MATLAB .fis, FCL, C) when the export module is installed."""
    try:
        from hybridnav.fuzzy.export import export_to_file
    except ImportError:
        return []
    names = []
    # FLL and FCL carry the sampled terms: exactly the membership the GA tuned, whatever the
    # universe resolution (formula terms can differ where a narrow term spans few samples)
    for fmt, target, opts in (("fll", "fis.fll", {"sampled": True}), ("fis", "fis.fis", {}),
                              ("fcl", "fis.fcl", {"sampled": True}), ("c", "effc_fis", {})):
        try:
            written = export_to_file(system, fmt, out / target, **opts)
        except HybridnavError as exc:       # e.g. a rule MATLAB's .fis cannot express
            log.warning("no %s export: %s", fmt, exc)
            continue
        names += [Path(p).name for p in written]
    return names


def _convergence(logbook: list[dict[str, Any]], job: Job) -> Figure:
    df = pd.DataFrame(logbook)
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(df["gen"], df["min"], marker="o", label="best")
    ax.plot(df["gen"], df["mean"], label="mean")
    ax.fill_between(df["gen"], df["mean"] - df["std"], df["mean"] + df["std"], alpha=0.2)
    ax.set_xlabel("generation")
    sense = job["reward"]["sense"]
    ax.set_ylabel(f"reward ({sense}d)")
    ax.set_title(f"{job.name}: convergence")
    ax.legend()
    return fig


def _report(job: Job, result: TuneResult, table: pd.DataFrame, files: list[str]) -> str:
    sense = job["reward"]["sense"]
    best = result.best.fitness.values[0]
    better = best < result.start_fitness if sense == "minimize" else best > result.start_fitness
    ga = job["ga"]
    lines = [
        f"# Tuning report: {job.name}", "",
        f"Seed {job.seed}; population {ga['population']}, {ga['generations']} generations; "
        f"starting system `{job['system']['start']}`; free: {job['free']['mf']} MF parameters"
        + (", rule switches" if job["free"]["rule_switches"] else "")
        + (", rule weights" if job["free"]["rule_weights"] else "")
        + (", rule consequents" if job["free"]["rule_consequents"] else "") + ".",
        f"Reward ({sense}): path length when the target is reached, "
        f"{'penalty' if sense == 'minimize' else '-penalty'} {job['reward']['penalty']:g} "
        "otherwise, summed over the training scenarios.", "",
        f"**Training reward: start {result.start_fitness:.4f}, tuned {best:.4f} — the tuned "
        f"system {'beats' if better else 'does not beat'} the starting one.**", "",
        f"The tuned system keeps {len(result.system.rules)} of "
        f"{len(job.start_system().rules)} rules.", "",
        "| scenario | set | system | outcome | path length | time to goal |",
        "|---|---|---|---|---|---|",
    ]
    for r in table.itertuples():
        t = "-" if r.time_to_goal is None or (isinstance(r.time_to_goal, float)
                                              and np.isnan(r.time_to_goal)) \
            else f"{r.time_to_goal:.1f} s"
        lines.append(f"| {r.scenario} | {r.set} | {r.system} | {r.outcome} | "
                     f"{r.path_length:.3f} | {t} |")
    held = table[table.set == "held-out"]
    if len(held):
        ok = held.groupby("system")["outcome"].apply(lambda s: int((s == "reached").sum()))
        lines += ["", f"Held-out scenarios reached: start {ok.get('start', 0)}/"
                      f"{len(held) // 2}, tuned {ok.get('tuned', 0)}/{len(held) // 2}."]
    last = result.logbook[-1]
    lines += ["", f"Wall time {last['wall_time']:.1f} s for "
                  f"{sum(r['evals'] for r in result.logbook)} evaluations.", "",
              "Files: " + ", ".join(files), ""]
    return "\n".join(lines)
