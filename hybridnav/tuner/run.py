"""A whole tuning job: run the GA, then judge the result on held-out worlds and write it all.

``DIR`` receives ``fis.json`` (the tuned system: the best on validation), ``start.json`` (the
system it started from), ``logbook.csv`` (gen, evals, min, mean, max, std, val_gen, val_best,
wall_time), ``evaluations.csv`` (every individual's outcome, length, time and clearance per
training environment), ``validation.csv`` (every validated candidate per validation world),
``heldout.csv`` (start, tuned and ``apf`` on every validation and test world) and
``heldout_summary.csv``, ``generations.json`` (the best system of each generation, what
``hybridnav animate DIR`` drives), ``convergence.png`` (training and validation curves), ``mfs.png``
(start and tuned), ``surface.png``, ``coverage.png`` (where no rule fires), ``paths.png`` (the
figures in PDF or SVG instead with ``fmt``),
``report.md`` with the verdict, and the deployment exports: ``fis.fll`` (fuzzylite),
``fis.fis`` (MATLAB), ``fis.fcl`` (IEC 61131-7) and ``effc.h``/``effc.c`` (standalone C, the names
the README's ``main.c`` includes and calls: ``effc_evaluate``, ``EFFC_IN_DTHETA``, ...).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import re
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from hybridnav.backends import Backend, ProcessBackend, SerialBackend, _Kept, make_backend
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, clean_temporaries, locked_folder
from hybridnav.params import DEFAULT_DPI, FIGURE_FORMATS
from hybridnav.plotting import Trace, check_dpi, check_format, figure_name, plot_traces, save_figure
from hybridnav.plotting.labels import axis_label
from hybridnav.plotting.scenes import legend_outside
from hybridnav.tuner.core import tune
from hybridnav.tuner.costs import NavigationCost
from hybridnav.tuner.heldout import summarize
from hybridnav.tuner.job import Job
from hybridnav.tuner.result import TuningResult

log = logging.getLogger(__name__)

__all__ = ["FIGURES", "OUTPUT_FILES", "OUTPUT_FOLDERS", "clear_outputs", "output_files", "run_job",
           "write_generations", "write_outputs"]

#: File name stem of the C export a tuning job writes (effc.h, effc.c; functions effc_*)
C_BASENAME = "effc"


#: What a tuning run writes in its folder: files, and folders with everything in them
#: (``front/`` of a multi-objective run, ``learning/`` of a two-stage run, ``falsified/``, the
#: robust rounds' ``robust-<r>/``). ``--force`` removes exactly these; a test checks that a run
#: writes nothing else.
#: the figures of a run, each in the format chosen (``--format``: png, pdf or svg)
FIGURES = ("convergence", "coverage", "front", "mfs", "paths", "surface")
OUTPUT_FILES = ("checkpoint.json", "evaluations.jsonl", "evaluations.csv", "logbook.csv",
                "result.json", "start.json", "report.md", "fis.json", "fis.fll", "fis.fis",
                "fis.fcl", f"{C_BASENAME}.c", f"{C_BASENAME}.h", f"{C_BASENAME}_safety.c",
                f"{C_BASENAME}_safety.h", "deployment.json", "generations.json", "pareto.csv",
                "validation.csv",
                "heldout.csv", "heldout_summary.csv", "falsified.csv", "falsification.csv",
                *(f"{stem}.{fmt}" for stem in FIGURES for fmt in FIGURE_FORMATS))
OUTPUT_FOLDERS = ("falsified", "front", "learning", "robust-*")
#: what a run writes inside those folders (a file of another name is the user's and stays)
_FOLDER_FILES = re.compile(r"^(falsified-\d+\.toml|member_\d+\.json)$")
_ROBUST = re.compile(r"^robust-\d+$")


def clear_outputs(out: str | Path) -> list[Path]:
    """Remove every output of a previous tuning run from ``out``: the files of
    :data:`OUTPUT_FILES`, in the folders of :data:`OUTPUT_FOLDERS` (``robust-<number>``) the
    files a run writes there, those folders when that leaves them empty, and temporary files.
    Other files (and folders holding them) stay.

    Returns
    -------
    list of Path
        What was removed.
    """
    out = Path(out)
    gone: list[Path] = []

    def remove(path: Path) -> None:
        path.unlink()
        gone.append(path)

    def leave(folder: Path, inner: bool) -> None:
        gone.extend(clean_temporaries(folder))
        if inner:
            with contextlib.suppress(OSError):
                folder.rmdir()                   # only when nothing of the user's is left
                gone.append(folder)

    _walk_outputs(out, remove, leave)
    return gone


def _walk_outputs(out: Path, visit: Callable[[Path], None],
                  leave: Callable[[Path, bool], None] | None = None) -> None:
    """``visit`` every output file of a tuning run in ``out`` (in sorted order, folder by
    folder: ``out``, then the run's folders and the learning folders inside them), and
    ``leave(folder, inner)`` after each folder."""

    def walk(folder: Path, inner: bool) -> None:
        for path in sorted(folder.iterdir()):
            if inner and _is_inner_folder(path, "learning"):
                walk(path, True)
            elif _is_output(path, inner):
                visit(path)
        if leave is not None:
            leave(folder, inner)

    walk(out, False)
    for folder in _output_folders(out):
        walk(folder, True)


def output_files(out: str | Path) -> list[str]:
    """The files of a tuning run in ``out`` (what :func:`clear_outputs` would remove), as paths
    relative to ``out`` (``falsified/falsified-0004.toml``), sorted.

    Parameters
    ----------
    out : str or Path
        A tuning run's folder.
    """
    out = Path(out)
    found: list[str] = []
    _walk_outputs(out, lambda path: found.append(path.relative_to(out).as_posix()))
    return found


def _is_output(path: Path, inner: bool) -> bool:
    """A file a tuning run writes (``inner``: in one of :data:`OUTPUT_FOLDERS`)."""
    return path.is_file() and not path.is_symlink() and (
        path.name in OUTPUT_FILES or (inner and bool(_FOLDER_FILES.match(path.name))))


def _is_inner_folder(path: Path, *names: str) -> bool:
    return path.is_dir() and not path.is_symlink() and path.name in names


def _output_folders(out: Path) -> list[Path]:
    """The folders of :data:`OUTPUT_FOLDERS` in ``out``."""
    return [p for p in sorted(out.iterdir()) if p.is_dir() and not p.is_symlink() and (
        p.name in ("falsified", "front", "learning") or _ROBUST.match(p.name))]


def run_job(job: Job, out: str | Path, *, resume: bool = False, force: bool = False,
            progress: Callable[[dict[str, Any]], None] | None = None,
            dask_client: Any = None, stop_after: int | None = None,
            phase: Callable[[str], None] | None = None, fmt: str = "png",
            dpi: int = DEFAULT_DPI) -> TuningResult:
    """Run ``job`` on its backend and write every output into ``out``.

    The job's objects (:meth:`Job.tunable`, :meth:`Job.cost`, :meth:`Job.optimizer`) go to
    :func:`hybridnav.tuner.tune`; the returned :class:`TuningResult` carries the verdicts and
    the names of every file the job leaves in ``out`` (``result.files``: the outputs, the
    checkpoint and ``evaluations.jsonl``).

    Parameters
    ----------
    job : Job
        From :func:`load_job`.
    out : str or Path
        The output folder (checkpoints, systems, tables, plots, ``report.md``).
    resume : bool
        Continue from the checkpoint in ``out`` (refused when the job changed); temporary files
        a killed run left behind are removed first.
    force : bool
        Start over in a folder that holds a run: every output of the old run is removed first
        (:func:`clear_outputs`).
    progress : callable, optional
        ``progress(row)`` after each generation with its logbook row.
    dask_client : distributed.Client, optional
        Run on this client instead of the job's backend settings.
    stop_after : int, optional
        Stop after this many generations, before writing outputs (tests of interruption).
    phase : callable, optional
        ``phase(message)`` as each phase after the optimizer starts (falsification, figures,
        exports, the C check, the report).
    fmt : str
        The figures' format: ``png``, ``pdf`` or ``svg`` (their names carry it).
    dpi : int
        The figures' resolution in dots per inch.

    Raises
    ------
    HybridnavError
        ``out`` holds a run and neither ``resume`` nor ``force`` is given; another job is
        writing ``out`` (the folder is locked while a job runs: :func:`hybridnav.fileio.\
locked_folder`); ``out`` cannot be written.
    """
    if resume and force:
        raise HybridnavError(f"{out}: expected --resume or --force, not both")
    figures = {"fmt": check_format(fmt, "fmt"), "dpi": check_dpi(dpi)}
    with locked_folder(out, f"tune {job.name}"):
        out = Path(out)
        if resume:
            clean_temporaries(out)
        elif (out / "checkpoint.json").exists() or (out / "result.json").exists():
            if not force:
                held = "checkpoint.json" if (out / "checkpoint.json").exists() else "result.json"
                raise HybridnavError(
                    f"{out}: holds a tuning run ({held}); --resume continues it, --force starts "
                    "over and removes its outputs, or choose another --out")
        if force:
            clear_outputs(out)
        return _run_job(job, out, resume, progress, dask_client, stop_after, phase, figures)


def _run_job(job: Job, out: Path, resume: bool, progress, dask_client,
             stop_after: int | None, phase=None, figures=None) -> TuningResult:
    be = job["backend"]
    with make_backend(be["workers"], dask_client or be["dask"]) as backend:
        kw = job.tune_kwargs()
        lr = job["learning"]
        if lr["max_rules"]:             # two stages: learn the rules, then tune the MFs
            from hybridnav.tuner.core import learn
            from hybridnav.tuner.settings import TunableSettings

            table = job.data.get("settings") or job["free"]
            del kw["settings"]
            kw["rule_optimizer"] = kw.pop("optimizer")
            result = learn(job.start_system(), job.cost("train"), max_rules=lr["max_rules"],
                           keep_rules=lr["keep_rules"], rule_weights=lr["rule_weights"],
                           optimizer=job.optimizer(),
                           settings=lambda learned: TunableSettings.from_table(learned, table),
                           backend=backend, checkpoint=out, progress=progress, resume=resume,
                           stop_after=stop_after, phase=phase, **kw)
        else:
            robust = job["robust"]["rounds"] > 0
            result = tune(job.start_system(), job.cost("train"), backend=backend,
                          checkpoint=out, progress=progress, resume=resume,
                          stop_after=stop_after, phase=phase, **kw)
            if robust and result.finished:     # falsification in the training loop
                from hybridnav.tuner.robust import robust_rounds

                result = robust_rounds(job, result, backend, out, {**kw, "phase": phase},
                                       progress, resume, stop_after)
        if not result.finished or (job["learning"]["max_rules"] and result.learning is None):
            return result
        result.files = write_outputs(job, result, out, backend=backend, phase=phase,
                                     **(figures or {}))
    return result


def write_outputs(job: Job, result: TuningResult, out: Path,
                  backend: Backend | None = None,
                  phase: Callable[[str], None] | None = None, fmt: str = "png",
                  dpi: int = DEFAULT_DPI) -> list[str]:
    """Write the result (:meth:`TuningResult.save`), its plots, the deployment exports and
    ``report.md``; for a navigation job also the held-out summary, the falsification search,
    the coverage and path figures and the software-in-the-loop check of the C export.

    Parameters
    ----------
    job : Job
    result : TuningResult
        From :func:`hybridnav.tuner.tune`.
    out : Path
        The output folder.
    backend : Backend, optional
        Runs the falsification searches and their ``apf`` runs and the path figure's runs
        (default: this process).
    phase : callable, optional
        ``phase(message)`` as each phase starts.
    fmt : str
        The figures' format: ``png``, ``pdf`` or ``svg``.
    dpi : int
        The figures' resolution in dots per inch.

    Returns
    -------
    list of str
        Every file of the run in ``out`` (relative to it): those written here, then what the
        optimizer keeps there (``checkpoint.json``, ``evaluations.jsonl``, ...;
        :func:`output_files`), ``report.md`` last.
    """
    say = phase or (lambda msg: None)
    from hybridnav.fuzzy import plots

    fmt, dpi = check_format(fmt, "fmt"), check_dpi(dpi)

    def save(fig, stem: str, **kw) -> str:
        name = figure_name(stem, fmt)
        save_figure(fig, out / name, dpi=dpi, **kw)
        return name

    backend = backend or SerialBackend()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    nav = job["cost"]["kind"] == "navigation"
    start = result.start
    unc = None
    if nav:
        from hybridnav.tuner.costs.base import Candidates

        # of the systems themselves (the start as given, not a repaired or learned form)
        unc = np.concatenate([Candidates.of(s).uncovered(job["coverage"]["grid"])
                              for s in (start, result.system)])

    def figures() -> tuple[list[str], list[str]]:
        """The figures of the systems and the optimizer's run (none depends on the
        falsification search): those listed before the tables, and the coverage map."""
        first = [save(_convergence(result), "convergence")]
        fig = Figure(figsize=(11, 7), layout="constrained")
        left, right = fig.subfigures(1, 2)
        plots.plot_memberships(start, fig=left)
        left.suptitle(f"start: {start.name}")
        plots.plot_memberships(result.system, fig=right)
        right.suptitle(f"tuned: {result.system.name}")
        first.append(save(fig, "mfs"))
        if len(start.inputs) == 2:
            first.append(save(plots.plot_surface(result.system), "surface", bbox_inches=None))
        if len(result.objective_names) > 1:
            first.append(save(_front(result), "front"))
        later = []
        if nav and len(start.inputs) == 2:          # a map over the two inputs
            later.append(save(_coverage(job, {"start": start, "tuned": result.system}, unc),
                              "coverage"))
        return first, later

    falsified = drawn = None
    serial = isinstance(backend, SerialBackend)
    if nav:
        # the falsification search's rates belong to the verdict: before result.json is written
        cfg = job["falsify"]
        if cfg["budget"]:
            say(f"falsification search: {cfg['budget']} worlds against each of tuned, start "
                "and apf" + ("" if serial else " (the figures drawn meanwhile)"))
        if cfg["budget"] and not serial:
            # the searches run on the workers: this process draws the figures meanwhile (this
            # thread; the searches' thread waits for the workers), the same files
            # A figure that fails is reported where the figures were drawn before (after the
            # search and result.save: the tuned system is written); an interrupt stops the
            # search's thread from writing its files once the workers are done.
            stop = threading.Event()
            with ThreadPoolExecutor(1, thread_name_prefix="hybridnav-falsify") as pool:
                searching = pool.submit(_falsify, job, job.cost("train"), result, backend, out,
                                        stop)
                try:
                    try:
                        drawn = figures()
                    except Exception as exc:    # noqa: BLE001 - raised again below
                        drawn = exc
                    falsified = searching.result()
                except BaseException:           # Ctrl-C: the pool's exit waits for the thread
                    stop.set()
                    raise
        else:
            falsified = _falsify(job, job.cost("train"), result, backend, out)
        _reweigh(job, result, falsified)
    say("writing the tuned system, tables and figures")
    files = result.save(out)
    if isinstance(drawn, Exception):
        raise drawn
    first, later = drawn or figures()
    files += first
    summary = None
    if nav:
        summary = summarize(result.heldout) if result.heldout is not None else pd.DataFrame()
        atomic_write_text(out / "heldout_summary.csv", summary.to_csv(index=False))
        files.append("heldout_summary.csv")
        if falsified is not None:
            files += falsified["files"]
        files += later
    effc = nav and job["cost"]["planner"] == "effc"
    say("exports (FLL, FIS, FCL, C)")
    exported = _exports(result.system, out, C_BASENAME if effc else "fis")
    if nav:                                   # the settings (and filter) it was judged with
        from hybridnav.planners.field.deploy import write_deployment

        first = job.scenarios("train")[0]
        exported += write_deployment(out, C_BASENAME if effc else "fis", job["cost"]["planner"],
                                     dict(job["planner"]), dt=first.dt,
                                     radius=float(first.robots[0].radius))
    sil: list[str] = []
    check = None
    if effc and f"{C_BASENAME}.c" in exported:
        check = (result.system, out / f"{C_BASENAME}.c",
                 job.scenarios("train")[:1] + job.scenarios("test")[:2], dict(job["planner"]))
    # the software-in-the-loop check runs in a process of its own while this one draws the path
    # figure, where the job may use more than one process (local workers: the same files)
    with _SideTask(_sil_lines, *(check or ()),
                   elsewhere=check is not None and _local_workers(backend)) as side:
        if nav:
            say("path figure: start, tuned and apf on the paper's and some test worlds")
            files += _paths(job, result, out, backend, save)
            files += write_generations(job, result, out)
        files += exported
        if check is not None:
            say("software-in-the-loop check: the exported C compiled and run against evaluate"
                + (" (run meanwhile)" if side.elsewhere else ""))
            sil = side.result()
    # and what the optimizer keeps there (checkpoint.json, evaluations.jsonl, the folders of a
    # robust or two-stage run): the list is every file the job leaves
    files += [f for f in output_files(out) if f not in files and f != "report.md"]
    atomic_write_text(out / "report.md", _report(job, result, summary, unc, files, falsified,
                                                 sil, fmt))
    files.append("report.md")
    return files


def write_generations(job: Job, result: TuningResult, out: str | Path) -> list[str]:
    """Write ``generations.json`` into ``out``: the best system of each generation of a
    navigation job (each distinct system once), its planner and settings and the job's world
    sets, what :func:`hybridnav.plotting.animate` drives generation by generation.

    Parameters
    ----------
    job : Job
    result : TuningResult
        Its ``generations``.
    out : str or Path
        The job's output folder.

    Returns
    -------
    list of str
        ``["generations.json"]``, or ``[]`` for a job that is not a navigation job (no world to
        drive on) or a result without generations.
    """
    out = Path(out)
    if job["cost"]["kind"] != "navigation":
        return []
    if not result.generations:
        return []
    systems: list[dict[str, Any]] = []
    index: dict[int, int] = {}
    rows = []
    for g in result.generations:
        k = index.setdefault(id(g["system"]), len(systems))
        if k == len(systems):
            systems.append(g["system"].to_dict())
        rows.append({"stage": int(g["stage"]), "generation": int(g["generation"]),
                     "score": float(g["score"]) if math.isfinite(g["score"]) else None,
                     "system": k})
    data = {"format": "hybridnav-generations/1", "job": job.name,
            "objective": result.objective_names[0], "planner": job["cost"]["planner"],
            "planner_params": dict(job["planner"]),
            "worlds": {k: job["scenarios"][k] for k in ("train", "validation", "test")},
            "base": str(Path(job.base).resolve()), "generations": rows, "systems": systems}
    atomic_write_text(out / "generations.json", json.dumps(data, indent=1))
    return ["generations.json"]


def _path_run(planner: str, params: dict[str, Any], scenario):
    """One run of :func:`_paths` (in whatever process gets it)."""
    from hybridnav import planners

    return planners.get(planner, **params).run(scenario)


def _paths(job: Job, result: TuningResult, out: Path, backend: Backend | None = None,
           save: Callable[..., str] | None = None) -> list[str]:
    """Start, tuned and ``apf`` on the paper's worlds, on every test world where the tuned
    system fails, and on a few more generated test worlds: lockstep batches, the simulation
    the held-out tables come from (worlds it cannot batch: planner runs on ``backend``)."""
    test = job.scenarios("test")
    failed: set[str] = set()
    if result.heldout is not None and len(result.heldout):
        h = result.heldout
        failed = set(h[(h.set == "test") & (h.system == "tuned")
                       & (h.outcome != "reached")].scenario)
    def generated(s) -> bool:
        return "(hybridnav.world.generator)" in (s.description or "")

    shown = [("train", s) for s in job.scenarios("train") if not generated(s)]
    shown += [("test", s) for s in test if not generated(s)]
    shown += [("test: tuned fails", s) for s in test if generated(s) and s.name in failed]
    shown += [("test", s) for s in test
              if generated(s) and s.name not in failed][:max(0, 4 - len(failed))]
    if not shown:
        return []
    # one world per row of three panels (start, tuned, apf); two worlds per row past four, so
    # that the figure stays near a page's proportions (not a strip many times taller than wide)
    per_row = 1 if len(shown) <= 4 else 2
    rows = -(-len(shown) // per_row)
    fig = Figure(figsize=(3.3 * 3 * per_row, 3.9 * rows), layout="constrained")
    grid = fig.subplots(rows, 3 * per_row, squeeze=False)
    axes = np.array([grid[k // per_row, 3 * (k % per_row):3 * (k % per_row) + 3]
                     for k in range(len(shown))]).reshape(len(shown), 3)
    for ax in grid.ravel()[len(shown) * 3:] if len(shown) % per_row else ():
        ax.set_visible(False)
    from hybridnav.tuner.heldout import baseline

    settings = dict(job["planner"])
    runs = (("start", job["cost"]["planner"], {"fis": result.start, **settings}),
            ("tuned", job["cost"]["planner"], {"fis": result.system, **settings}),
            ("apf", "apf", baseline(settings)))          # plain apf, as judged
    traces = _lockstep_traces([s for _, s in shown], runs)
    if traces is None:
        # the runs are independent: on the backend's workers, drawn here in order
        done = (backend or SerialBackend()).map(
            _path_run, [(planner, params, s) for _, s in shown for _, planner, params in runs])
        traces = [[Trace(rr.name, rr.states[:, :2], rr.outcome, rr.path_length, rr.states[-1],
                         float(rr.t[-1])) for rr in res.robots] for res in done]
    for row, (kind, s) in enumerate(shown):
        for col, (label, planner, params) in enumerate(runs):
            tr = traces[row * len(runs) + col]
            plot_traces(s, tr, ax=axes[row, col])
            legend_outside(axes[row, col], fontsize=7, ncols=1)
            outcome = tr[0].outcome if tr else "-"
            axes[row, col].set_title(f"{s.name} ({kind}):\n{label}, {outcome}", fontsize=8)
    if save is None:
        save_figure(fig, out / "paths.png", bbox_inches=None)     # constrained layout fits it
        return ["paths.png"]
    return [save(fig, "paths", bbox_inches=None)]


def _lockstep_traces(scen: list, runs) -> list | None:
    """The runs of :func:`_paths` as lockstep batches (each planner on all the worlds at once,
    exactly what its planner does run by run), in ``(world, run)`` order; ``None`` where the
    lockstep simulation does not apply (worlds it cannot batch, a planner without it)."""
    from hybridnav import planners
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.tuner.evaluate import scenario_set
    from hybridnav.tuner.heldout import uniform

    from hybridnav.planners.field.apf import apf_lockstep

    def batched(planner: str, fuzzy: bool):
        if not fuzzy:                      # the plain baseline
            return apf_lockstep if planner == "apf" else None
        return getattr(planners.PLANNERS[planner], "lockstep", None)

    if not uniform(scen) or any(batched(p, "fis" in prm) is None for _, p, prm in runs):
        return None
    st = scenario_set(scen)
    per_run = []
    for _, planner, params in runs:
        params = dict(params)
        fis = params.pop("fis", None)
        lockstep = batched(planner, fis is not None)
        if fis is None:
            res = lockstep(st, params, record_paths=True)
        else:
            fam = SystemFamily(fis)
            res = lockstep(st, fam, fam.tables_of([fis]), 1, params, record_paths=True)
        per_run.append(res)
    dt = scen[0].dt
    traces = []
    for e, s in enumerate(scen):
        for res in per_run:
            n = int(round(res.time[e, 0] / dt))
            traces.append([Trace(s.robots[0].name, res.paths[e][0, :n + 1], res.outcome[e, 0],
                                 float(res.path_length[e, 0]), res.final_states[e, 0],
                                 float(res.time[e, 0]))])
    return traces


def _reweigh(job: Job, result: TuningResult, falsified: dict[str, Any] | None) -> None:
    """The deployment verdict of the final held-out set again, with the falsification rates."""
    if falsified is None or result.heldout is None:
        return
    which = "test" if "test" in result.verdicts else "validation"
    if which not in result.verdicts:
        return
    cost = job.cost(which)
    v = cost.verdict(result.heldout, which, falsified["rates"])
    if which == "validation" and v.get("headline"):
        v["headline"] += " — on the data that chose the returned system, not an independent test"
    result.verdicts[which] = v


def _falsify(job: Job, cost: NavigationCost, result: TuningResult, backend: Backend,
             out: Path, stop: threading.Event | None = None) -> dict[str, Any] | None:
    """The falsification search against the tuned system, its start and ``apf`` (the same
    budget, swarm and seed): their rates, and the tuned system's worst worlds as TOML files with
    how start and ``apf`` do there."""
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.tuner.falsify import falsify_systems, rates
    from hybridnav.tuner.heldout import _apf_rows
    from hybridnav.world import save_scenario, scenario_to_dict

    cfg = job["falsify"]
    if cfg["budget"] == 0:
        return None
    seed = int(np.random.SeedSequence(job.seed, spawn_key=(13,)).generate_state(1)[0])
    searched = falsify_systems(cost, {"tuned": result.system, "start": result.start,
                                      "apf": "apf"},
                               budget=cfg["budget"], population=cfg["population"],
                               obstacles=cfg["obstacles"], keep=cfg["keep"],
                               optimizer=cfg["optimizer"], seed=seed, backend=backend,
                               structures={k: cfg[k] for k in ("cups", "corridors", "gaps")})
    if stop is not None and stop.is_set():      # interrupted meanwhile: no files
        return None
    res = searched["tuned"]
    table = rates(searched)
    rows, files = [], []
    atomic_write_text(out / "falsification.csv", table.to_csv(index=False))
    files.append("falsification.csv")
    if res.worlds and not (stop is not None and stop.is_set()):
        folder = out / "falsified"
        folder.mkdir(exist_ok=True)
        fam = SystemFamily(result.start)
        sim, _ = cost.with_scenarios(res.worlds, "falsified").simulate(
            fam, fam.tables_of([result.start]), None, noise=False)
        apf = backend.map(_apf_rows, [(json.dumps(scenario_to_dict(w)), dict(job["planner"]))
                                      for w in res.worlds])
        for i, w in enumerate(res.worlds):
            name = f"falsified/{w.name}.toml"
            save_scenario(w, out / name)
            files.append(name)
            rows.append({"world": name, "tuned": res.outcomes[i],
                         "tuned_clearance": res.clearances[i], "tuned_cost": res.costs[i],
                         "start": str(sim.outcome[i, 0]),
                         "start_clearance": float(sim.min_clearance[i, 0]),
                         "apf": apf[i][0]["outcome"],
                         "apf_clearance": apf[i][0]["min_clearance"]})
        atomic_write_text(out / "falsified.csv", pd.DataFrame(rows).to_csv(index=False))
        files.append("falsified.csv")
    return {"result": res, "rows": rows, "files": files, "config": cfg, "rates": table}


def _exports(system, out: Path, c_name: str = C_BASENAME) -> list[str]:
    """Deployment exports (FLL, MATLAB .fis, FCL, C) when the export module is installed."""
    try:
        from hybridnav.fuzzy.export import export_to_file
    except ImportError:
        return []
    names = []
    # FLL and FCL carry the sampled terms: exactly the membership the GA tuned, whatever the
    # universe resolution (formula terms can differ where a narrow term spans few samples)
    for fmt, target, opts in (("fll", "fis.fll", {"sampled": True}), ("fis", "fis.fis", {}),
                              ("fcl", "fis.fcl", {"sampled": True}), ("c", c_name, {})):
        try:
            written = export_to_file(system, fmt, out / target, **opts)
        except HybridnavError as exc:       # e.g. a rule MATLAB's .fis cannot express
            log.warning("no %s export: %s", fmt, exc)
            continue
        names += [Path(p).name for p in written]
    return names


def _convergence(result: TuningResult) -> Figure:
    """Training and validation curves; the legend (below the plot) says what each score is
    and why the validation curves sit above the training ones."""
    df = result.logbook
    fig = Figure(figsize=(6.8, 5.2), layout="constrained")
    ax = fig.add_subplot()
    x = np.arange(len(df)) if "stage" in df else df["gen"]
    ax.plot(x, df["min"], marker="o", markersize=3,
            label="training: the generation's best, on the training worlds")
    ax.plot(x, df["mean"], linewidth=0.8, label="training: the generation's mean")
    if "val_gen" in df:
        ax.plot(x, df["val_gen"], marker="s", markersize=3,
                label="validation: the generation's best candidates re-scored on the "
                      "validation worlds")
        ax.plot(x, df["val_best"], linestyle="--",
                label="validation: best so far on the validation worlds (not trained on, "
                      "hence above the training scores)")
        if "stage" not in df:
            ax.axvline(result.best_generation, color="0.5", linewidth=0.8,
                       label=f"generation {result.best_generation}: the returned system "
                             "(best on validation)")
    if (df["min"] > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("generation" + (" (all k-fold stages)" if "stage" in df else ""))
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))      # generations are whole
    ax.set_ylabel(f"{result.objective_names[0]}, minimized")
    ax.set_title(f"{result.system.name}: training and validation")
    legend_outside(ax, fontsize=7, ncols=1)
    return fig


def _front(result: TuningResult) -> Figure:
    """The Pareto front: the first two objectives (training, and validation when scored), the
    returned member marked."""
    f = result.front
    names = result.objective_names
    fig = Figure(figsize=(6.4, 4.6), layout="constrained")
    ax = fig.add_subplot()
    c = f["objective_2"] if "objective_2" in f else None
    sc = ax.scatter(f["objective_0"], f["objective_1"], c=c, cmap="viridis", s=28,
                    label="front (training)")
    if c is not None:
        fig.colorbar(sc, ax=ax, label=names[2])
    if "validation_0" in f:
        ax.scatter(f["validation_0"], f["validation_1"], marker="x", color="0.4", s=22,
                   label="the same members on validation")
    r = f[f["returned"]]
    ax.scatter(r["objective_0"], r["objective_1"], s=140, facecolors="none",
               edgecolors="red", linewidths=1.5, label="returned (fis.json), training")
    if "validation_0" in f:
        ax.scatter(r["validation_0"], r["validation_1"], s=140, facecolors="none",
                   edgecolors="red", linestyles="--", linewidths=1.2,
                   label="returned, on validation")
    inf = int((~np.isfinite(f[["objective_0", "objective_1"]].to_numpy())).any(axis=1).sum())
    ax.set_xlabel(f"{names[0]}, minimized")
    ax.set_ylabel(f"{names[1]}, minimized")
    ax.set_title(f"Pareto front: {len(f)} members"
                 + (f" ({inf} with an infinite objective not drawn)" if inf else ""))
    ax.legend(fontsize=8)
    return fig


def _coverage(job: Job, systems: dict[str, Any], unc: np.ndarray) -> Figure:
    """Where no rule fires (the output falls back to ``default``), per system."""
    from hybridnav.fuzzy.family import SystemFamily

    grid = job["coverage"]["grid"]
    fig = Figure(figsize=(4.2 * len(systems), 3.8), layout="constrained")
    axes = fig.subplots(1, len(systems), squeeze=False)[0]
    for ax, (label, system), u in zip(axes, systems.items(), unc):
        fam = SystemFamily(system)
        a, b = system.inputs[0], system.inputs[1]
        xa = np.linspace(*a.range, grid)
        xb = np.linspace(*b.range, grid)
        A, B = np.meshgrid(xa, xb, indexing="ij")
        fired = fam.fired(fam.tables_of([system]), np.zeros(A.size, dtype=int),
                          {a.name: A.ravel(), b.name: B.ravel()}).reshape(A.shape)
        ax.pcolormesh(xa, xb, (~fired).T.astype(float), cmap="Reds", vmin=0, vmax=1.5,
                      shading="nearest")
        from hybridnav.planners import fuzzy_units

        units = fuzzy_units(system)
        ax.set_xlabel(axis_label(a.name, units.get(a.name)))
        ax.set_ylabel(axis_label(b.name, units.get(b.name)))
        ax.set_title(f"{label}: no rule fires on {100 * u:.1f} %", fontsize=9)
    fig.suptitle("coverage (red: the output is the default)")
    return fig


def _fmt(v: float, spec: str = ".3f") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def _local_workers(backend: Backend) -> bool:
    """Whether ``backend`` runs local worker processes (so the job may use more than this
    process, and every process sees the output folder)."""
    return isinstance(backend, (ProcessBackend, _Kept))


class _SideTask:
    """``fn(*args)``, in a process of its own while this process does something else
    (``elsewhere``), or here when :meth:`result` is asked for. A process that dies runs the task
    here again; leaving the block (an error, Ctrl-C) ends it and does not wait for it."""

    def __init__(self, fn: Callable, *args: Any, elsewhere: bool) -> None:
        self.fn, self.args, self.elsewhere = fn, args, elsewhere
        self._pool = self._future = None

    def __enter__(self) -> _SideTask:
        if self.elsewhere:
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(1)
            self._future = self._pool.submit(self.fn, *self.args)
        return self

    def result(self) -> Any:
        from concurrent.futures.process import BrokenProcessPool

        if self._future is not None:
            try:
                return self._future.result()
            except BrokenProcessPool:
                log.warning("the process of %s died; running it here", self.fn.__name__)
        return self.fn(*self.args)

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            if exc[0] is not None:
                # the task is not wanted any more: end its process, or the executor's exit
                # hook (at the interpreter's exit) would wait for the running task
                for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
                    proc.terminate()
            self._pool.shutdown(wait=exc[0] is None, cancel_futures=True)


def _sil_lines(system, c_file: Path, worlds: list, planner: dict[str, Any]) -> list[str]:
    """The report's software-in-the-loop check of the C export ``c_file``: the compiled C
    controller against the Python evaluator in closed loop on ``worlds`` (the first training
    and up to two test worlds) with the job's ``planner`` settings."""
    from hybridnav.fuzzy.export.closedloop import verify
    from hybridnav.fuzzy.export.sil import CompiledFIS

    head = ["", "## Software in the loop: the exported C controller", ""]
    try:
        compiled = CompiledFIS(c_file)
    except HybridnavError as exc:
        return head + [f"Not checked: {exc}"]
    rows = verify(system, compiled, worlds, **planner)
    exact = max(r["same_inputs_w_diff"] for r in rows)
    worst = max(max(r["max_state_diff"], r["max_w_diff"]) for r in rows)
    same = all(r["same_outcome"] for r in rows)
    parted = [r["scenario"] for r in rows if not r["max_state_diff"] <= 1e-9]
    margin = planner.get("safety_margin", 0.0)
    lines = head + [
        f"`{C_BASENAME}.c`, compiled with the system C compiler and run in a child process, "
        f"gives the Python evaluator's w on the same inputs to {exact:.1e} "
        f"({'within' if exact <= 1e-9 else 'NOT within'} 1e-9) along the runs below, and drove "
        "the same EFFC closed loop"
        + (f" (with the safety filter at {margin:g} m)" if margin else "") + ": "
        + ("the same outcomes" if same else "DIFFERENT OUTCOMES")
        + (f", states and w within {worst:.2e}." if not parted else
           f"; on {', '.join(parted)} the two loops parted where the loop is discontinuous "
           "(the filter's decision at its margin, or a graze), so their samples are not "
           "compared there.")
        + f" Check again: `hybridnav verify fis.json {C_BASENAME}.c`.", "",
        "| world | outcome | samples | max abs state diff | max abs w diff | w diff, same inputs |",
        "|---|---|---|---|---|---|"]
    lines += [f"| {r['scenario']} | {r['outcome']} | {r['samples']} | {r['max_state_diff']:.2e} "
              f"| {r['max_w_diff']:.2e} | {r['same_inputs_w_diff']:.2e} |" for r in rows]
    return lines


def _report(job: Job, result: TuningResult, summary: pd.DataFrame | None,
            unc: np.ndarray | None, files: list[str], falsified: dict[str, Any] | None = None,
            sil: list[str] | None = None, fmt: str = "png") -> str:
    nav = job["cost"]["kind"] == "navigation"
    opt = result.optimizer
    size = opt.get("population", opt.get("n", opt.get("lambda_")))
    lines = [
        f"# Tuning report: {job.name}", "",
        f"Seed {result.seed}; optimizer {opt['kind']}"
        + (f" (population {size}" if size else " (")
        + f"{', ' if size else ''}{opt['generations']} generations); starting system "
          f"`{job['system']['start']}`; {result.settings.size} free numbers.",
        f"Cost: {result.cost}.",
    ]
    if nav:
        n = {k: len(job.scenarios(k)) for k in ("train", "validation", "test")}
        lines += [f"Worlds: {n['train']} for training, {n['validation']} for validation "
                  f"(choosing the returned system), {n['test']} for the final test (used only "
                  "for this report).", "", _reward_text(job)]
        margin = job["planner"].get("safety_margin", 0.0)
        if margin:
            lines += ["", f"Safety filter: the escape-circle filter kept {margin:g} m beyond the "
                          "robot radius in every run of the fuzzy systems here (tuning, "
                          "validation, test, falsification); `apf` ran without it, as a user "
                          "runs it. The tuned controller is the fuzzy system *with* that filter: "
                          f"`deployment.json` holds the settings, `{C_BASENAME}_safety.c` / "
                          f"`{C_BASENAME}_safety.h` the filter in C."]
    lines.append("")
    # the verdict first: what a user deploys
    for which in ("test", "validation"):
        v = result.verdicts.get(which)
        if not v or not v["checks"]:
            continue
        lines += [f"**Verdict: {v['headline']}.**", ""]
        cut = v.get("safety_checks")
        groups = [("Safety first (the tuned system against apf and its start):",
                   v["checks"][:cut]), ("Then success and length:", v["checks"][cut:])] \
            if cut is not None else [("", v["checks"])]
        for title, checks in groups:
            if title:
                lines += [title, ""]
            lines += [f"- {'pass' if ok else 'FAIL'}: {text}" for text, ok in checks]
            lines.append("")
    vs, ss = result.validation_score, result.start_validation_score
    if len(result.objective_names) > 1:
        f = result.front
        lines += [f"Several objectives ({', '.join(result.objective_names)}): the Pareto front "
                  f"has {len(f)} members (`pareto.csv`, `{figure_name('front', fmt)}`, "
                  "`front/member_<i>.json`); "
                  "`fis.json` is the member select_member picked: "
                  + ("the fewest of the first objective on **validation** among the members "
                     "validation calls feasible, then the second objective."
                     if result.selected_by == "validation" else
                     "the smallest first training objective (no validation set: nothing checks "
                     "that it generalizes).")]
    elif result.selected_by == "validation" and vs is not None:
        lines += [f"Returned system: the best on **validation**, from generation "
                  f"{result.best_generation}"
                  + (f" of k-fold stage {result.best_stage}" if result.folds else "")
                  + f" (validation objective {vs:.4f}"
                  + (f"; start {ss:.4f})." if ss is not None else ").")]
        if ss is not None and not vs < ss:
            lines += ["", "**WARNING: the returned system does not score better than its "
                          "starting system on the validation set. Both are written: `fis.json` "
                          "(returned) and `start.json` (start).**"]
        if not result.folds:
            stopped = result.stopped
            lines += ["", "Early stopping: "
                          + (f"stopped at generation {stopped}" if stopped else "not triggered")
                          + f" (patience {result.patience}, tolerance "
                            f"{job['validation']['tolerance']:g})."]
    elif result.folds:
        last = result.folds[-1]
        lines += [f"No validation set: the returned system is the last k-fold stage's best on "
                  f"its own fold ({result.selected_by}, generation {result.best_generation}; "
                  "the start competed on every fold)."]
        if last.get("generation") == 0 and np.array_equal(result.x, result.x_start):
            lines += ["", "**WARNING: no tuned candidate beat the starting system on the last "
                          "fold: the returned system is the start.**"]
    else:
        lines += ["No validation set: the returned system is the best on training (generation "
                  f"{result.best_generation}); nothing checks that it generalizes."]
    if result.folds:
        scores = [f["score"] for f in result.folds if "score" in f]
        lines += ["", f"k-fold over the training data ({len(result.folds)} folds; each stage "
                      "trained on the other folds and was scored on its own):", "",
                  "| stage | fold | best score on it | generation | early stop |",
                  "|---|---|---|---|---|"]
        for f in result.folds:
            lines.append(f"| {f['stage']} | {f['fold']} | {_fmt(f.get('score'), '.4f')} | "
                         f"{f.get('generation', '-')} "
                         f"| {f['stopped'] if f['stopped'] is not None else '-'} |")
        if scores:
            lines += ["", f"Mean of the fold scores: {float(np.mean(scores)):.4f} (std "
                          f"{float(np.std(scores)):.4f}); each is the best of the candidates "
                          "scored on that fold, so it reads better than an independent "
                          "estimate would."]
    if result.robust:
        cfg = job["robust"]
        added = sum(r["added"] for r in result.robust)
        lines += ["", "## Falsification in the training loop", "",
                  f"Up to {cfg['rounds']} round(s): a search of {cfg['budget']} candidate worlds "
                  f"for the tuned system's {'collisions' if cfg['failures'] == 'collisions' else 'failures'}"
                  f"; at most {cfg['cap']} of the worst joined the training worlds and tuning "
                  "continued from the tuned system (validation and test untouched). "
                  + (f"{added} world(s) added in all." if added else
                     "The search found nothing to add: the first tuning stands."), "",
                  "| round | searched | valid | failures | collisions | added |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['round']} | {r['searched']} | {r['valid']} | {r['failures']} | "
                  f"{r['collisions']} | {r['added']} |" for r in result.robust]
    lr = result.learning
    if not result.start_is_candidate and lr is None:
        lines += ["", "The start breaks the settings' constraints (e.g. min_overlap): the search "
                      "began from its repaired form; the start's scores here are its own."]
    if lr is not None:
        cfg = job["learning"]
        kept = getattr(lr.settings, "kept_rules", 0)
        lines += ["", f"Rule learning (stage 1 of 2): up to {cfg['max_rules']} rules learned from "
                      + (f"{kept} of the start's {len(result.start.rules)} rules (the "
                         "conjunctions of terms a rule slot can hold)" if cfg["keep_rules"]
                         else "an empty rule base")
                      + f" with the start's membership functions: training objective "
                      f"{lr.start_objectives[0]:.4f} -> {lr.objectives[0]:.4f}"
                      + (f", validation {lr.validation_score:.4f}"
                         if lr.validation_score is not None else "")
                      + f" (generation {lr.best_generation}, {lr.evaluations} evaluations). "
                      "Stage 2 tuned the learned system's membership functions; the 'start' "
                      "of the verdicts and tables is the system the job started from."]
    lines += ["", f"Training objective ({result.objective_names[0]}, minimized): start "
                  f"{result.start_objectives[0]:.4f}, returned {result.objectives[0]:.4f}"
                  + (" (each on its own k-fold stage's training folds: not comparable)."
                     if result.folds else "."),
              (f"The tuned system has {len(result.system.rules)} rules (learned):"
               if lr is not None else f"The tuned system keeps {len(result.system.rules)} of "
               f"{len(result.start.rules)} rules:"), "",
              *(f"- {r.sentence(result.system.output.name)}" for r in result.system.rules), ""]
    if nav and unc is not None:
        lines += [f"Coverage (grid {job['coverage']['grid']} per axis over the input ranges): no "
                  f"rule fires on {100 * unc[0]:.1f} % for the start, {100 * unc[1]:.1f} % for "
                  f"the tuned system (allowed: {100 * job['coverage']['max_uncovered']:.1f} %"
                  + (f"; see {figure_name('coverage', fmt)})." if figure_name("coverage", fmt)
                     in files else ")."), ""]
    if nav and summary is not None and len(summary):
        lines += ["## Start vs tuned vs apf on held-out worlds", "",
                  "Nominal runs (no noise). Length and clearance: means over the worlds every "
                  "system reached; 'min clearance' is the smallest over the worlds that system "
                  "reached.", "",
                  "| set | system | reached | 95 % interval | collided | stuck | timeout | "
                  "out of bounds | common worlds | length | clearance | min clearance |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in summary.itertuples():
            lines.append(f"| {r.set} | {r.system} | {r.reached}/{r.worlds} | "
                         f"{_fmt(r.ci_low, '.2f')}-{_fmt(r.ci_high, '.2f')} | {r.collided} | "
                         f"{r.stuck} | {r.timeout} | {r.out_of_bounds} | {r.common_worlds} | "
                         f"{_fmt(r.common_length)} | {_fmt(r.common_clearance)} | "
                         f"{_fmt(r.min_clearance_reached)} |")
    elif result.heldout is not None:
        lines += ["## Start vs tuned on held-out data", "",
                  result.heldout.to_markdown(index=False) if _has_tabulate()
                  else "```\n" + result.heldout.to_string(index=False) + "\n```"]
    if falsified is not None:
        fr, cfg = falsified["result"], falsified["config"]
        lines += ["", "## Falsification: worlds an adversary finds", "",
                  f"A {cfg['optimizer']} search over solvable worlds with {cfg['obstacles']} "
                  f"circles (start, goal, heading, positions and radii)"
                  + "".join(f", up to {cfg[k]} {k}" for k in ("cups", "corridors", "gaps")
                            if cfg[k])
                  + " across the start-goal line for each system, the "
                  f"same budget ({cfg['budget']} candidate worlds) and seed, each search driven "
                  "by its own system's failures (collisions score worst, then traps). Rates are "
                  "over the valid (solvable) worlds tried, with 95 % Wilson intervals.", "",
                  "| system | tried | valid | failures | rate | collisions | rate |",
                  "|---|---|---|---|---|---|---|"]
        for r in falsified["rates"].itertuples():
            lines.append(f"| {r.system} | {r.tried} | {r.valid} | {r.failures} | "
                         f"{_pct(r.failures_rate, r.failures_ci_low, r.failures_ci_high)} | "
                         f"{r.collisions} | "
                         f"{_pct(r.collisions_rate, r.collisions_ci_low, r.collisions_ci_high)} |")
        lines += ["", f"The tuned system's worst worlds (of its {fr.failures} failures in "
                      f"{fr.valid} valid worlds), replayed with its start and apf:"]
        if falsified["rows"]:
            lines += ["", "| world | tuned | clearance | start | apf |", "|---|---|---|---|---|"]
            for r in falsified["rows"]:
                lines.append(f"| `{r['world']}` | {r['tuned']} | {_fmt(r['tuned_clearance'])} "
                             f"| {r['start']} | {r['apf']} |")
            from hybridnav.planners.field.deploy import run_command

            lines += ["", "Replay one: `" + run_command(job["cost"]["planner"],
                                                       dict(job["planner"]), world="<world>",
                                                       out="DIR") + "`."]
        else:
            lines += ["", "No failure found within the budget."]
    lines += sil or []
    wall = result.wall_time + (lr.wall_time if lr is not None else 0.0)
    evals = result.evaluations + (lr.evaluations if lr is not None else 0)
    lines += ["", f"Wall time {wall:.1f} s for {evals} evaluations (tuning only).", "", "Files: " + ", ".join(files + ["report.md"]), ""]
    return "\n".join(lines)


def _pct(rate: float, lo: float, hi: float) -> str:
    if not np.isfinite(rate):
        return "-"
    return f"{100 * rate:.1f} % ({100 * lo:.1f}-{100 * hi:.1f})"


def _has_tabulate() -> bool:
    import importlib.util

    return importlib.util.find_spec("tabulate") is not None


def _reward_text(job: Job) -> str:
    rw = job["reward"]
    if rw["kind"] == "length":
        return (f"Reward (length, minimized): path length when the target is reached, penalty "
                f"{rw['penalty']:g} otherwise, summed over the training worlds.")
    if rw["kind"] == "paper":
        return (f"Reward (paper, maximized): path length when the target is reached, "
                f"-{rw['penalty']:g} otherwise, summed over the training worlds (the objectives "
                "above and in logbook.csv are its negative: every objective is minimized).")
    noise = ", ".join(f"{k} {rw[k]:g}" for k in ("heading_noise", "dtheta_noise", "alpha_noise")
                      if rw[k] > 0)
    return (f"Reward (deploy, minimized; mean over the training worlds): reached: "
            f"{rw['length']:g} x length / distance + {rw['time']:g} x time x speed / distance + "
            f"{rw['clearance']:g} x shortfall of the clearance below {rw['safety_distance']:g} "
            f"robot radii; collision or leaving the workspace {rw['collision']:g}; stuck or "
            f"timeout {rw['failure']:g} + {rw['progress']:g} x distance left / start distance. "
            f"Coverage penalty {job['coverage']['penalty']:g} x the uncovered fraction above "
            f"{job['coverage']['max_uncovered']:g}; validation picks only systems within it. "
            + (f"Noise: {noise}, {rw['repeats']} repeats." if noise else "No noise.")).strip()
