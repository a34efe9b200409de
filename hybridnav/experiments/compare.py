"""Comparison harness: every planner x scenario x run, serially, on local processes or on Dask.

Each run ``r`` gets the seed ``SeedSequence(seed, spawn_key=(r,))`` — the same for every planner
and scenario (common random numbers), and independent of how the work is spread, so the tables
are identical whatever the number of workers or the backend.

The compared planners are *labelled variants*: ``"effc"``, ``"effc@tuned:fis=tuned/fis.json"``
(see :func:`parse_planner`) or :class:`PlannerSpec` objects, so one planner can be compared with
itself under other parameters. The label is the ``planner`` column of the tables and the legend
of the plots; ``planner_name`` in the runs table is the registry name.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from hybridnav.experiments.convergence import CONVERGENCE_COLUMNS, convergence_rows, plot_convergence
from hybridnav.backends import shared_backend
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.params import short_repr

log = logging.getLogger(__name__)

__all__ = ["RUN_COLUMNS", "PlannerSpec", "compare", "parse_planner", "planner_specs", "run_seed",
           "summarize_runs", "write_comparison"]

#: the columns of ``runs.csv``; ``planner`` is the variant's label, ``planner_name`` the registry
#: name, ``control_effort`` the robot's (empty for models without body rates; see
#: :func:`hybridnav.planners.simulate.simulate`), ``min_robot_clearance`` the clearance to the
#: other robots alone (empty with one robot); later columns are appended so that the older ones
#: keep their positions
RUN_COLUMNS = ["planner", "scenario", "run", "seed", "robot", "outcome", "path_length",
               "time_to_goal", "smoothness", "min_clearance", "compute_time", "planner_name",
               "control_effort", "min_robot_clearance"]
#: summarized metrics; ``time_with_planning`` is derived per run: ``time_to_goal`` plus the
#: robot's planning computation ``compute_time`` (the time a paper means when "generation of each
#: point takes time", FAStep-Kinematic Sec. VIII)
METRICS = ["path_length", "time_to_goal", "smoothness", "min_clearance", "compute_time",
           "time_with_planning", "control_effort", "min_robot_clearance"]
SYNTAX = "NAME, NAME@LABEL or NAME@LABEL:key=value[:key=value...]"
#: metrics summarized over the robots that reached their goal only
REACHED_ONLY = ("path_length", "time_to_goal", "smoothness", "time_with_planning",
                "control_effort")
#: metrics compared between planners with a Mann-Whitney U test (``<metric>_p_vs_<label>``)
TESTED = ("path_length", "time_to_goal", "time_with_planning")


def _cut(text: str) -> str:
    """``text`` as given, or cut (quoted, with its length) when longer than 120 characters."""
    return text if len(text) <= 120 else short_repr(text, 120)


def run_seed(seed: int, run: int) -> int:
    """The seed of run ``run`` of a comparison seeded with ``seed``.

    Parameters
    ----------
    seed : int
        The comparison's seed.
    run : int
        The run's index (the same for every planner and scenario: common random numbers).

    Returns
    -------
    int
        ``SeedSequence(seed, spawn_key=(run,))``'s first 32-bit word.
    """
    return int(np.random.SeedSequence(seed, spawn_key=(run,)).generate_state(1)[0])


@dataclass
class PlannerSpec:
    """One compared planner: its label, its registry name and its parameter overrides.

    Parameters
    ----------
    label : str
        What the ``planner`` column of the tables and the plot legends show; unique in a
        comparison.
    name : str
        The registry name (see ``hybridnav planners``).
    params : dict
        Parameter overrides; strings are parsed as ``--set`` values are.
    text : str, optional
        How the item was written (for error messages); default: :meth:`format`.
    """

    label: str
    name: str
    params: dict[str, Any] = field(default_factory=dict)
    text: str = ""

    def format(self) -> str:
        """The item in the ``--planners`` syntax (values shown with ``str``)."""
        head = self.name if self.label == self.name and not self.params else \
            f"{self.name}@{self.label}"
        return ":".join([head, *(f"{k}={v}" for k, v in self.params.items())])

    def __str__(self) -> str:
        return self.text or self.format()


def parse_planner(text: str) -> PlannerSpec:
    """Parse one ``--planners`` item: ``NAME``, ``NAME@LABEL`` or ``NAME@LABEL:key=value:...``.

    Parameters
    ----------
    text : str
        The item. A variant with parameters must have a label (``effc:fis=x`` is an error,
        ``effc@x:fis=x`` is not); values are kept as strings, to be parsed by the planner's
        parameter declarations like ``--set`` values. Values cannot contain ``:`` or ``,``
        (use ``--set LABEL.key=value`` for those).

    Returns
    -------
    PlannerSpec

    Raises
    ------
    HybridnavError
        A malformed item (named, with the expected syntax).
    """
    item = text.strip()

    def fail(why: str) -> HybridnavError:
        return HybridnavError(f"--planners {_cut(item)}: {why}")

    head, *assignments = item.split(":")
    name, at, label = (part.strip() for part in head.partition("@"))
    if not name:
        raise fail(f"expected {SYNTAX}")
    if at and not label:
        raise fail(f"expected a label after '@' ({SYNTAX})")
    if "@" in label:
        raise fail(f"expected one '@' ({SYNTAX})")
    if assignments and not at:
        raise fail(f"a variant with parameters needs a label: expected {name}@LABEL:key=value")
    params: dict[str, Any] = {}
    for assignment in assignments:
        key, eq, value = (part.strip() for part in assignment.partition("="))
        if not eq or not key:
            raise fail(f"{short_repr(assignment.strip())}: expected key=value ({SYNTAX})")
        if key in params:
            raise fail(f"{key}: set twice")
        params[key] = value
    return PlannerSpec(label or name, name, params, item)


def planner_specs(planners: Sequence[str | PlannerSpec | tuple]) -> list[PlannerSpec]:
    """The compared planners as :class:`PlannerSpec` objects, with unique labels.

    Parameters
    ----------
    planners : sequence
        Items in the ``--planners`` syntax (:func:`parse_planner`), :class:`PlannerSpec` objects,
        or ``(label, name, params)`` tuples.

    Returns
    -------
    list of PlannerSpec

    Raises
    ------
    HybridnavError
        A malformed item, an empty list, a duplicate label, or a label that is the registry name
        of another planner.
    """
    from hybridnav.planners import PLANNERS

    if isinstance(planners, str):
        planners = [planners]
    specs: list[PlannerSpec] = []
    for i, item in enumerate(planners):
        if isinstance(item, PlannerSpec):
            specs.append(item)
        elif isinstance(item, str):
            specs.append(parse_planner(item))
        elif isinstance(item, tuple) and len(item) == 3 and isinstance(item[0], str) \
                and isinstance(item[1], str) and isinstance(item[2], Mapping):
            specs.append(PlannerSpec(item[0], item[1], dict(item[2])))
        else:
            raise HybridnavError(f"planners[{i}]: expected {SYNTAX}, a PlannerSpec or a "
                                 f"(label, name, params) tuple, got {item!r}")
    if not specs:
        raise HybridnavError("--planners: expected at least one planner")
    seen: dict[str, int] = {}
    for i, spec in enumerate(specs):
        if not spec.label.strip():
            raise HybridnavError(f"--planners {_cut(str(spec))}: expected a non-empty label")
        if spec.label in seen:
            raise HybridnavError(
                f"--planners {_cut(str(spec))}: duplicate label {spec.label!r} (items {seen[spec.label] + 1} "
                f"and {i + 1}); give each variant its own label, NAME@LABEL")
        if spec.label != spec.name and spec.label in PLANNERS:
            raise HybridnavError(f"--planners {_cut(str(spec))}: the label {spec.label!r} is the name of "
                                 f"another planner; choose another label")
        seen[spec.label] = i
    return specs


def _absolute_paths(name: str, params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with relative paths of existing files made absolute.

    Worker processes (a Dask worker in particular) need not share this process's working
    directory. Only free-text string parameters are touched, and only values that name a file
    the way :func:`hybridnav.fuzzy.load_any` tells a file from a built-in name (a suffix or a
    directory separator), so built-in names stay names.
    """
    from hybridnav.planners import PLANNERS

    declared = PLANNERS[name].parameters
    out = dict(params)
    for key, value in params.items():
        p = declared.get(key)
        if p is None or p.kind is not str or p.choices is not None or not isinstance(value, str):
            continue
        path = Path(value)
        if (path.suffix or "/" in value or os.sep in value) and not path.is_absolute() \
                and path.exists():
            out[key] = str(path.resolve())
    return out


class _Shared(dict):
    """Run 0's paths in ``table.attrs``. pandas deep-copies ``attrs`` into every filtered or
    grouped frame; the paths are only read, so the copies share them (a copy per filter made
    each one about 100 times slower)."""

    def __deepcopy__(self, memo: dict) -> _Shared:
        return self


@dataclass(frozen=True)
class _Task:
    """One run. ``built`` and ``loaded`` are the planner and scenario ``compare`` built and
    checked once in the calling process: the worker runs them as they are (no parsing,
    validation or file reading per run, and no dependence on the worker's working directory);
    without them (a task made elsewhere) the worker builds them from the names."""

    label: str
    planner: str
    params: tuple
    scenario: str
    run: int
    seed: int
    built: Any = field(default=None, compare=False, repr=False)
    loaded: Any = field(default=None, compare=False, repr=False)


def _execute(task: _Task) -> tuple[list[dict[str, Any]], dict[str, np.ndarray] | None,
                                   pd.DataFrame]:
    """Run one planner on one scenario (in whatever process gets the task): the table rows, for
    run 0 the robots' paths (for the overlay figure), and the swarm searches' convergence."""
    from hybridnav import planners
    from hybridnav.world import load_scenario

    scenario = task.loaded if task.loaded is not None else load_scenario(task.scenario)
    planner = task.built if task.built is not None else \
        planners.get(task.planner, **dict(task.params))
    result = planner.run(scenario, seed=task.seed)
    rows = []
    for r in result.robots:
        s = r.summary()
        rows.append({"planner": task.label, "scenario": scenario.name, "run": task.run,
                     "seed": task.seed, "robot": r.name, **{k: s[k] for k in RUN_COLUMNS[5:11]},
                     "planner_name": task.planner, "control_effort": s.get("control_effort"),
                     "min_robot_clearance": s.get("min_robot_clearance")})
    paths = ({r.name: np.asarray(r.states)[:, :2].copy() for r in result.robots}
             if task.run == 0 else None)
    return rows, paths, convergence_rows(result, task.label, task.run)


#: seconds per run measured in earlier calls of this process, per (label, planner, parameters,
#: scenario): they order the next call's units (``reproduce`` compares the same planners on the
#: same worlds again and again); only the order of work depends on them, never a result
_SECONDS: dict[tuple, float] = {}


def _guess(task: _Task) -> float:
    """The expected seconds of a run: measured before in this process, else a rough guess from
    the scenario (robots x the share of the time limit a straight drive to the goal takes x
    its steps) -- only the ranking of units matters."""
    known = _SECONDS.get((task.label, task.planner, task.params, task.scenario))
    if known is not None:
        return known
    sc = task.loaded
    if sc is None:
        return 1.0
    try:
        w = sc.world.workspace
        diag = float(np.hypot(w[1] - w[0], w[3] - w[2])) or 1.0
        share = sum(min(1.0, 0.1 + float(np.hypot(r.goal[0] - r.start[0],
                                                  r.goal[1] - r.start[1])) / diag)
                    if r.goal is not None else 1.0 for r in sc.robots)
        return 1e-3 * share * sc.steps
    except (AttributeError, TypeError, ValueError, IndexError):
        return 1.0


def _units(tasks: list[_Task], combos: int, runs: int, workers: int) -> list[list[_Task]]:
    """The tasks (``runs`` per planner and scenario, in order) as units of work, longest
    expected first.

    A unit holds runs of one planner on one scenario (a worker pays what a combination's first
    run costs in a process -- its model functions, grids, fuzzy systems -- once per unit). Units
    hold at most ``ceil(tasks / (4 * workers))`` runs, so that every worker gets several and
    the pool's queue balances them; they are handed out longest expected first
    (:func:`_guess`), so the last to start are short and both workers finish together.
    """
    size = max(1, min(runs, -(-len(tasks) // (4 * max(1, workers)))))
    units = [tasks[c * runs + a:c * runs + min(runs, a + size)]
             for c in range(combos) for a in range(0, runs, size)]
    if workers <= 1:
        return units
    cost = [sum(_guess(t) for t in u) for u in units]
    order = sorted(range(len(units)), key=lambda i: -cost[i])          # stable: ties in order
    return [units[i] for i in order]


def _execute_many(tasks: list[_Task]) -> list[tuple]:
    """:func:`_execute` of each task of a unit, in order (in whatever process gets the unit),
    each with its wall time."""
    import time

    out = []
    for t in tasks:
        tic = time.perf_counter()
        result = _execute(t)
        out.append((result, time.perf_counter() - tic))
    return out


def compare(
    planners: Sequence[str | PlannerSpec | tuple],
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

    Everything is checked before any run starts: planner names, parameters and their values,
    labels, and that every planner handles every scenario.

    Parameters
    ----------
    planners : sequence
        The compared planners: names (``["apf", "effc"]``), labelled variants in the
        ``--planners`` syntax (``"effc@tuned:fis=tuned/fis.json"``, see :func:`parse_planner`),
        :class:`PlannerSpec` objects or ``(label, name, params)`` tuples. Labels are unique.
    scenarios : sequence of str
        Scenario names or paths.
    runs : int
        Runs per combination (run ``r`` uses :func:`run_seed`).
    seed : int
        The base seed (run ``r`` of every combination uses ``run_seed(seed, r)``).
    params : dict, optional
        ``{label: {parameter: value}}`` overrides (``--set label.parameter=value``); a plain
        name is its own label. A variant's own parameters win over these.
    workers : int
        Local worker processes (1: in this process).
    dask : str or distributed.Client, optional
        A Dask scheduler address (or a client, or ``"local"`` for a new local cluster) to run
        the tasks on instead (:mod:`hybridnav.backends`, as ``tune`` does).
    progress : callable, optional
        ``progress(done, total)`` after each finished task.

    Returns
    -------
    runs : DataFrame
        One row per run and robot, columns :data:`RUN_COLUMNS`, in the order of ``planners``.
    summary : DataFrame
        :func:`summarize_runs` of it.

    Raises
    ------
    HybridnavError
        A bad planner item, label, parameter or value (naming the item), a scenario a planner
        cannot handle, or ``runs < 1``.

    Notes
    -----
    Relative paths of existing files in string parameters (``fis=tuned/fis.json``) are made
    absolute here, so they name the same file in worker processes with another working
    directory.
    """
    from hybridnav import planners as registry
    from hybridnav.world import load_scenario

    if runs < 1:
        raise HybridnavError(f"runs: expected a positive number of runs, got {runs}")
    specs = planner_specs(planners)
    labels = [spec.label for spec in specs]
    params = {k: dict(v) for k, v in (params or {}).items()}
    unknown = sorted(set(params) - set(labels))
    if unknown:
        raise HybridnavError(f"--set {unknown[0]}.*: {unknown[0]!r} is not one of the compared "
                             f"planners ({', '.join(labels)})")
    loaded = [load_scenario(s) for s in scenarios]
    settings: dict[str, dict[str, Any]] = {}
    built: dict[str, Any] = {}
    for spec in specs:                     # fail before any work starts
        try:
            merged = {**params.get(spec.label, {}), **spec.params}   # the variant's own win
            planner = built[spec.label] = registry.get(spec.name, **merged)
            settings[spec.label] = _absolute_paths(spec.name, merged)
            for scenario in loaded:
                planner.check_scenario(scenario)
        except HybridnavError as exc:
            raise HybridnavError(f"--planners {_cut(str(spec))}: {exc}") from None
    tasks = [_Task(spec.label, spec.name, tuple(sorted(settings[spec.label].items())), s, r,
                   run_seed(seed, r), built[spec.label], sc)
             for spec in specs for s, sc in zip(scenarios, loaded) for r in range(runs)]
    # the planners and scenarios built and checked above travel to the workers as objects
    # (shipped once per unit): no worker re-reads or re-validates them per run
    units = _units(tasks, len(specs) * len(scenarios), runs, workers)
    position = {id(t): i for i, t in enumerate(tasks)}
    done = 0

    def finished(i):
        nonlocal done
        done += len(units[i])
        if progress is not None:
            progress(done, len(tasks))

    # local workers are kept for later calls (shared_backend): they pay their start-up once
    with shared_backend(workers, dask or "") as backend:
        parts = backend.map(_execute_many, [(u,) for u in units], on_done=finished)
    results: list[Any] = [None] * len(tasks)
    for unit, part in zip(units, parts):
        for t, (result, seconds) in zip(unit, part):
            results[position[id(t)]] = result
            if len(_SECONDS) > 4096:
                _SECONDS.clear()
            _SECONDS[(t.label, t.planner, t.params, t.scenario)] = seconds
    rows = [row for result_rows, _, _ in results for row in result_rows]
    names = {spec: sc.name for spec, sc in zip(scenarios, loaded)}
    paths = {(t.label, names[t.scenario]): p for t, (_, p, _) in zip(tasks, results)
             if p is not None}
    curves = [c for _, _, c in results if not c.empty]
    convergence = (pd.concat(curves, ignore_index=True) if curves
                   else pd.DataFrame(columns=CONVERGENCE_COLUMNS))
    table = pd.DataFrame(rows, columns=RUN_COLUMNS)
    order = {label: i for i, label in enumerate(labels)}
    table = table.sort_values(["planner", "scenario", "run", "robot"],
                              key=lambda c: c.map(order) if c.name == "planner" else c,
                              kind="stable").reset_index(drop=True)
    table.attrs.update(units={sc.name: sc.units for sc in loaded},
                       scenarios={sc.name: spec for sc, spec in zip(loaded, scenarios)},
                       paths=_Shared(paths), convergence=_Shared(table=convergence))
    return table, summarize_runs(table)


def summarize_runs(table: pd.DataFrame) -> pd.DataFrame:
    """Per planner x scenario: runs, success rate, and the statistics of every metric.

    ``path_length``, ``time_to_goal``, ``smoothness`` and ``control_effort`` are summarized over
    the robots that reached their goal (a failed run has no meaningful length, and its effort is
    that of an unfinished task); clearance and compute time over all robots. Per metric: mean, std, min, max, median and the 95 % confidence interval of the
    mean (Student's t; ``ci95_lo``, ``ci95_hi``; NaN below two values). ``best_path_length`` and
    ``best_time_to_goal`` are the shortest reached run's length and its own time (``worst_*``:
    the longest), as papers report best and worst cases. For every other planner on the same
    scenario, ``<metric>_p_vs_<label>`` for each metric of :data:`TESTED` holds the two-sided
    Mann-Whitney U test's p-value (:func:`scipy.stats.mannwhitneyu`; NaN where either side has
    no reached run). ``units`` is the scenario's length unit where the table knows it
    (``table.attrs["units"]``, set by :func:`compare`).

    With more than one robot, ``min_robot_clearance_*`` summarize the clearance to the other
    robots alone (over all robots; ``_min`` is the closest any two came), and ``robot_contacts``
    counts the robots that touched another robot (``min_robot_clearance < 0``; such a robot is
    also counted in ``collided``, the simulation ending it there). A table without the column
    (written before it existed) gives NaN there.
    """
    from scipy import stats

    units = table.attrs.get("units", {})
    table = table.assign(time_with_planning=table["time_to_goal"].astype(float)
                         + table["compute_time"].astype(float))
    if "min_robot_clearance" not in table:
        table = table.assign(min_robot_clearance=np.nan)
    out = []
    groups = {key: g for key, g in table.groupby(["planner", "scenario"], sort=False)}
    for (planner, scenario), g in groups.items():
        ok = g[g["outcome"] == "reached"]
        row: dict[str, Any] = {"planner": planner, "scenario": scenario, "robots": len(g),
                               "success_rate": len(ok) / len(g)}
        for outcome in ("collided", "out_of_bounds", "stuck", "timeout"):
            row[outcome] = int((g["outcome"] == outcome).sum())
        row["robot_contacts"] = int((g["min_robot_clearance"].astype(float) < 0).sum())
        for m in METRICS:
            vals = (ok if m in REACHED_ONLY else g)[m].astype(float).dropna()
            for stat in ("mean", "std", "min", "max", "median"):
                row[f"{m}_{stat}"] = getattr(vals, stat)() if len(vals) else np.nan
            n = len(vals)
            half = (stats.t.ppf(0.975, n - 1) * vals.std() / np.sqrt(n)) if n >= 2 else np.nan
            row[f"{m}_ci95_lo"] = row[f"{m}_mean"] - half
            row[f"{m}_ci95_hi"] = row[f"{m}_mean"] + half
        reached = ok.dropna(subset=["path_length"])
        for side, idx in (("best", "idxmin"), ("worst", "idxmax")):
            if len(reached):
                r = reached.loc[getattr(reached["path_length"].astype(float), idx)()]
                row[f"{side}_path_length"] = float(r["path_length"])
                row[f"{side}_time_to_goal"] = float(r["time_to_goal"])
            else:
                row[f"{side}_path_length"] = row[f"{side}_time_to_goal"] = np.nan
        for (other, sc2), g2 in groups.items():
            if sc2 != scenario or other == planner:
                continue
            ok2 = g2[g2["outcome"] == "reached"]
            for m in TESTED:
                a = ok[m].astype(float).dropna().to_numpy()
                b = ok2[m].astype(float).dropna().to_numpy()
                row[f"{m}_p_vs_{other}"] = (float(stats.mannwhitneyu(a, b).pvalue)
                                            if len(a) and len(b) else np.nan)
        row["units"] = units.get(scenario, "")
        out.append(row)
    return pd.DataFrame(out)


def write_comparison(folder: str | Path, table: pd.DataFrame, summary: pd.DataFrame,
                     settings: Mapping[str, Any] | None = None, fmt: str = "png",
                     dpi: int = 120) -> list[str]:
    """Write ``runs.csv``, ``summary.csv``, the comparison plots and, given ``settings`` (what was
    compared: planners, scenarios, runs, seed, ``--set`` values), ``comparison.json`` with them
    and the package version; returns the file names.

    Parameters
    ----------
    folder : str or Path
    table, summary : DataFrame
        From :func:`compare`.
    settings : dict, optional
        What the comparison was run with (written as given, plus ``version``).
    fmt : str
        The plots' format: ``png``, ``pdf`` or ``svg`` (their names carry it).
    dpi : int
        The plots' resolution in dots per inch.
    """
    from hybridnav import __version__
    from hybridnav.fileio import dumps_json
    from hybridnav.plotting import check_dpi, check_format, figure_name, save_figure

    fmt, dpi = check_format(fmt, "fmt"), check_dpi(dpi)

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / "runs.csv", table.to_csv(index=False))
    atomic_write_text(folder / "summary.csv", summary.to_csv(index=False))
    names = ["runs.csv", "summary.csv"]
    if settings is not None:
        atomic_write_text(folder / "comparison.json",
                          dumps_json({"version": __version__, **dict(settings)}))
        names.append("comparison.json")
    for metric, label in (("path_length", "path length, reached runs ({units})"),
                          ("time_to_goal", "time to goal, reached runs (s)"),
                          ("compute_time", "compute time (s)"),
                          ("success_rate", "success rate (share of runs)"),
                          ("min_clearance", "smallest clearance per run ({units})"),
                          ("control_effort", "control effort, reached runs")):
        if metric == "control_effort" and not np.isfinite(
                summary.get("control_effort_mean", pd.Series(dtype=float)).astype(float)).any():
            continue                       # no robot model with body rates: no effort
        name = figure_name(f"compare_{metric}", fmt)
        save_figure(_bars(summary, metric, label), folder / name, dpi=dpi)
        names.append(name)
    first = table[table["run"] == 0]
    for scenario, paths in _paths_by_scenario(table).items():
        rows = first[first["scenario"] == scenario]
        outcomes = {(p, r): o for p, r, o in zip(rows["planner"], rows["robot"], rows["outcome"])}
        fig = _overlay(table.attrs["scenarios"][scenario], paths, outcomes)
        name = figure_name(f"paths_{_file_stem(scenario)}", fmt)
        save_figure(fig, folder / name, dpi=dpi)
        names.append(name)
    convergence = table.attrs.get("convergence", {}).get("table")
    if convergence is not None and not convergence.empty:
        atomic_write_text(folder / "convergence.csv", convergence.to_csv(index=False))
        names.append("convergence.csv")
        labels = list(dict.fromkeys(table["planner"]))
        for scenario, rows in convergence.groupby("scenario", sort=False):
            fig = plot_convergence(scenario, rows, labels)
            if fig is not None:
                name = figure_name(f"convergence_{_file_stem(scenario)}", fmt)
                save_figure(fig, folder / name, dpi=dpi)
                names.append(name)
    return names


def _file_stem(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def _paths_by_scenario(table: pd.DataFrame) -> dict[str, dict[str, dict[str, np.ndarray]]]:
    """``{scenario: {planner label: {robot: (N, 2) path}}}`` of run 0 (when ``compare`` kept
    them in ``table.attrs``)."""
    out: dict[str, dict[str, dict[str, np.ndarray]]] = {}
    if "scenarios" not in table.attrs:
        return out
    for (label, scenario), robots in table.attrs.get("paths", {}).items():
        out.setdefault(scenario, {})[label] = robots
    return out


def _overlay(spec: str, paths: Mapping[str, Mapping[str, np.ndarray]],
             outcomes: Mapping[tuple[str, str], str] | None = None) -> Figure:
    """Every planner's run-0 path on the scenario's map, one colour per planner, each ending
    in its outcome's marker (``outcomes``: ``(planner label, robot) -> outcome``); the legend,
    below the map, lists the planners and the outcome markers drawn."""
    from hybridnav.plotting.scenes import draw_scenario, legend_outside, mark_outcome
    from hybridnav.world import load_scenario

    scenario = load_scenario(spec)
    fig = Figure(figsize=(6.4, 7.0), layout="constrained")
    ax = fig.add_subplot()
    draw_scenario(scenario, ax)
    colours = [f"C{k}" for k in range(10)]
    labelled: set[str] = set()
    for k, (label, robots) in enumerate(paths.items()):
        for j, (robot, xy) in enumerate(robots.items()):
            ax.plot(xy[:, 0], xy[:, 1], color=colours[k % 10], linewidth=1.4,
                    label=label if j == 0 else None, zorder=5)
            outcome = (outcomes or {}).get((label, robot))
            if outcome is not None and len(xy):
                mark_outcome(ax, xy[-1], outcome, labelled, markersize=9)
    legend_outside(ax, ncols=3)
    ax.set_title(f"{scenario.name}: run 0 of every planner")
    return fig


#: metrics that cannot be negative: their intervals are cut at 0 (a success rate's at 0 and 1)
_NONNEGATIVE = ("path_length", "time_to_goal", "compute_time", "control_effort",
                "time_with_planning")


def _bars(summary: pd.DataFrame, metric: str, label: str) -> Figure:
    """Bars per scenario and planner, one panel per length unit where the scenarios' units
    differ (``{units}`` in ``label``): a metric's mean with its 95 % interval of the mean, cut to
    the metric's range; a success rate with its 95 % Wilson interval; ``n = 0`` where no run
    gave a value (a planner that never reached has no length)."""
    from hybridnav.tuner.heldout import wilson

    units_of = (dict(zip(summary["scenario"], summary["units"])) if "units" in summary
                else {})
    groups: dict[str, list[str]] = {}
    for sc in dict.fromkeys(summary["scenario"]):
        key = units_of.get(sc, "") if "{units}" in label else ""
        groups.setdefault(key, []).append(sc)
    fig = Figure(figsize=(7.0, 4.2 * len(groups)), layout="constrained")
    plans = list(dict.fromkeys(summary["planner"]))
    width = 0.8 / max(1, len(plans))
    for row, (unit, scen) in enumerate(groups.items()):
        ax = fig.add_subplot(len(groups), 1, row + 1)
        for i, p in enumerate(plans):
            sub = summary[summary["planner"] == p].set_index("scenario").reindex(scen)
            x = np.arange(len(scen)) + (i - (len(plans) - 1) / 2) * width
            if metric == "success_rate":
                rate = sub[metric].astype(float).to_numpy()
                n = sub["robots"].astype(float).to_numpy() if "robots" in sub else \
                    np.full(len(sub), np.nan)
                ci = np.array([wilson(round(r * k), int(k)) if np.isfinite(r) and k > 0
                               else (np.nan, np.nan) for r, k in zip(rate, n)]).reshape(-1, 2)
                err = np.vstack([rate - ci[:, 0], ci[:, 1] - rate])
                mean = rate
            else:
                mean = sub[f"{metric}_mean"].astype(float).to_numpy()
                if f"{metric}_ci95_lo" in sub:
                    lo = sub[f"{metric}_ci95_lo"].astype(float).to_numpy()
                    hi = sub[f"{metric}_ci95_hi"].astype(float).to_numpy()
                else:
                    sd = sub[f"{metric}_std"].astype(float).to_numpy()
                    lo, hi = mean - sd, mean + sd
                if metric in _NONNEGATIVE:       # no interval below what the metric can be
                    lo = np.maximum(lo, 0.0)
                err = np.vstack([mean - lo, hi - mean])
            bars = ax.bar(x, np.nan_to_num(mean), width, yerr=np.nan_to_num(err), capsize=3,
                          label=p)
            for xi, m in zip(x, mean):
                if not np.isfinite(m):           # nothing to average: say so on the axis
                    ax.annotate("n = 0", (xi, 0), xytext=(0, 2), textcoords="offset points",
                                ha="center", va="bottom", fontsize=7, rotation=90,
                                color=bars.patches[0].get_facecolor() if bars.patches
                                else "black")
        ax.set_xticks(np.arange(len(scen)), scen, rotation=20)
        ax.set_xlabel("scenario")
        text = label.replace("{units}", unit or "scenario units")
        ax.set_ylabel(text)
        if metric == "success_rate":
            ax.set_ylim(0, 1.05)
        ax.legend(fontsize=8)
        ax.set_title("mean and 95 % interval per planner" if metric != "success_rate"
                     else "share of runs that reached, 95 % Wilson interval", fontsize=9)
    return fig
