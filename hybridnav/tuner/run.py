"""A whole tuning job: run the GA, then judge the result on held-out worlds and write it all.

``DIR`` receives ``fis.json`` (the tuned system: the best on validation), ``start.json`` (the
system it started from), ``logbook.csv`` (gen, evals, min, mean, max, std, val_gen, val_best,
wall_time), ``evaluations.csv`` (every individual's outcome, length, time and clearance per
training environment), ``validation.csv`` (every validated candidate per validation world),
``heldout.csv`` (start, tuned and ``apf`` on every validation and test world) and
``heldout_summary.csv``, ``convergence.png`` (training and validation curves), ``mfs.png``
(start and tuned), ``surface.png``, ``coverage.png`` (where no rule fires), ``paths.png``,
``report.md`` with the verdict, and the deployment exports: ``fis.fll`` (fuzzylite),
``fis.fis`` (MATLAB), ``fis.fcl`` (IEC 61131-7) and ``effc.h``/``effc.c`` (standalone C, the names
the README's ``main.c`` includes and calls: ``effc_evaluate``, ``EFFC_IN_DTHETA``, ...).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from hybridnav.backends import Backend, SerialBackend, make_backend
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.plotting import plot_result, save_figure
from hybridnav.tuner.ga import TuneResult, _job_json, tune
from hybridnav.tuner.heldout import compare_systems, summarize, verdict
from hybridnav.tuner.job import Job

log = logging.getLogger(__name__)

__all__ = ["run_job", "write_outputs"]

#: File name stem of the C export a tuning job writes (effc.h, effc.c; functions effc_*)
C_BASENAME = "effc"


def run_job(job: Job, out: str | Path, *, resume: bool = False,
            progress: Callable[[dict[str, Any]], None] | None = None,
            dask_client: Any = None) -> tuple[TuneResult, list[str]]:
    """Run ``job`` on its backend, write every output into ``out``; returns the result and the
    names of the files written.

    Parameters
    ----------
    job : Job
        From :func:`load_job`.
    out : str or Path
        The output folder (checkpoints, systems, tables, plots, ``report.md``).
    resume : bool
        Continue from the checkpoint in ``out`` (refused when the job changed).
    progress : callable, optional
        ``progress(info)`` after each generation (``info``: generation, best, mean, ...).
    dask_client : distributed.Client, optional
        Run on this client instead of the job's backend settings.
    """
    out = Path(out)
    be = job["backend"]
    backend = make_backend(be["workers"], dask_client or be["dask"])
    with backend:
        result = tune(job, out, backend=backend, resume=resume, progress=progress)
        files = write_outputs(job, result, out, backend=backend)
    return result, files


def write_outputs(job: Job, result: TuneResult, out: Path,
                  backend: Backend | None = None) -> list[str]:
    """Judge the result on the validation and test sets; write the systems, tables, plots,
    exports and ``report.md``.

    Parameters
    ----------
    job : Job
    result : TuneResult
        From :func:`tune`.
    out : Path
        The output folder.
    backend : Backend, optional
        Runs the judging simulations (default: the job's).
    """
    from hybridnav import planners
    from hybridnav.fuzzy import plots
    from hybridnav.tuner.evaluate import uncovered_fraction

    backend = backend or SerialBackend()
    out.mkdir(parents=True, exist_ok=True)
    files = []
    start = job.start_system()
    result.system.save(out / "fis.json")
    start.save(out / "start.json")
    files += ["fis.json", "start.json"]
    atomic_write_text(out / "logbook.csv", pd.DataFrame(result.logbook).to_csv(index=False))
    atomic_write_text(out / "evaluations.csv", pd.DataFrame(result.records).to_csv(index=False))
    files += ["logbook.csv", "evaluations.csv"]
    if result.validation.get("candidates"):
        vrows = [dict(e, generation=c["generation"], score=c["score"], uncovered=c["uncovered"])
                 for c in result.validation["candidates"] for e in c["envs"]]
        atomic_write_text(out / "validation.csv", pd.DataFrame(vrows).to_csv(index=False))
        files.append("validation.csv")
    # start, tuned and apf on the worlds tuning never trained on
    jj = _job_json(job)
    genomes = {"start": np.array(result.start_genome), "tuned": np.array(result.best)}
    table = compare_systems(job, jj, genomes, backend)
    summary = summarize(table)
    atomic_write_text(out / "heldout.csv", table.to_csv(index=False))
    atomic_write_text(out / "heldout_summary.csv", summary.to_csv(index=False))
    files += ["heldout.csv", "heldout_summary.csv"]
    unc = uncovered_fraction(jj, np.vstack([genomes["start"], genomes["tuned"]]))
    falsified = _falsify(job, jj, genomes, backend, out)
    if falsified is not None:
        files += falsified["files"]
    save_figure(_convergence(result.logbook, job, result), out / "convergence.png")
    fig = Figure(figsize=(11, 7), layout="constrained")
    left, right = fig.subfigures(1, 2)
    plots.plot_memberships(start, fig=left)
    left.suptitle(f"start: {start.name}")
    plots.plot_memberships(result.system, fig=right)
    right.suptitle(f"tuned: {result.system.name}")
    save_figure(fig, out / "mfs.png")
    plots.save_surface_png(result.system, out / "surface.png")
    save_figure(_coverage(job, {"start": start, "tuned": result.system}, unc),
                out / "coverage.png")
    files += ["convergence.png", "mfs.png", "surface.png", "coverage.png"]
    # paths: the paper's worlds and a few generated test worlds
    shown = [("train", s) for s in job.scenarios("train") if not s.name.startswith("gen-")]
    test = job.scenarios("test")
    shown += [("test", s) for s in test if not s.name.startswith("gen-")]
    shown += [("test", s) for s in test if s.name.startswith("gen-")][:4]
    if shown:
        fig = Figure(figsize=(8.5, 4.0 * len(shown)), layout="constrained")
        axes = fig.subplots(len(shown), 2, squeeze=False)
        for row, (kind, s) in enumerate(shown):
            for col, (label, system) in enumerate((("start", start),
                                                   ("tuned", result.system))):
                res = planners.get("effc", fis=system, **job["planner"]).run(s)
                plot_result(s, res, ax=axes[row, col])
                axes[row, col].set_title(f"{s.name} ({kind}): {label}", fontsize=9)
        save_figure(fig, out / "paths.png")
        files.append("paths.png")
    files += _exports(result.system, out)
    sil = _sil_lines(job, result.system, out) if f"{C_BASENAME}.c" in files else []
    radius = job.scenarios("train")[0].robots[0].radius
    atomic_write_text(out / "report.md", _report(job, result, summary, unc, radius, files,
                                                 falsified, sil))
    files.append("report.md")
    return files


def _falsify(job: Job, jj: str, genomes: dict[str, np.ndarray], backend: Backend,
             out: Path) -> dict[str, Any] | None:
    """The falsification search against the tuned system; its worst worlds as TOML files and
    how start and ``apf`` do there."""
    from hybridnav.tuner.evaluate import scenario_set, simulate_on
    from hybridnav.tuner.falsify import falsify
    from hybridnav.tuner.heldout import _apf_rows
    from hybridnav.world import save_scenario, scenario_to_dict

    cfg = job["falsify"]
    if cfg["budget"] == 0:
        return None
    seed = int(np.random.SeedSequence(job.seed, spawn_key=(13,)).generate_state(1)[0])
    res = falsify(jj, genomes["tuned"], budget=cfg["budget"], population=cfg["population"],
                  obstacles=cfg["obstacles"], keep=cfg["keep"], optimizer=cfg["optimizer"],
                  seed=seed)
    rows, files = [], []
    if res.worlds:
        folder = out / "falsified"
        folder.mkdir(exist_ok=True)
        sim, _ = simulate_on(jj, scenario_set(res.worlds), genomes["start"][None], noise=False)
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
                         "apf": apf[i]["outcome"], "apf_clearance": apf[i]["min_clearance"]})
        atomic_write_text(out / "falsified.csv", pd.DataFrame(rows).to_csv(index=False))
        files.append("falsified.csv")
    return {"result": res, "rows": rows, "files": files, "config": cfg}


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
                              ("fcl", "fis.fcl", {"sampled": True}), ("c", C_BASENAME, {})):
        try:
            written = export_to_file(system, fmt, out / target, **opts)
        except HybridnavError as exc:       # e.g. a rule MATLAB's .fis cannot express
            log.warning("no %s export: %s", fmt, exc)
            continue
        names += [Path(p).name for p in written]
    return names


def _convergence(logbook: list[dict[str, Any]], job: Job, result: TuneResult) -> Figure:
    df = pd.DataFrame(logbook)
    fig = Figure(figsize=(6.8, 4.2), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(df["gen"], df["min"], marker="o", markersize=3, label="training: best")
    ax.plot(df["gen"], df["mean"], linewidth=0.8, label="training: mean")
    if "val_gen" in df:
        ax.plot(df["gen"], df["val_gen"], marker="s", markersize=3,
                label="validation: best of generation")
        ax.plot(df["gen"], df["val_best"], linestyle="--", label="validation: best so far")
        ax.axvline(result.best_generation, color="0.5", linewidth=0.8)
    sense = job["reward"]["sense"]
    if sense == "minimize" and (df["min"] > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel(f"fitness ({sense}d; {job['reward']['kind']} reward)")
    ax.set_title(f"{job.name}: training and validation")
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
        ax.set_xlabel(a.name)
        ax.set_ylabel(b.name)
        ax.set_title(f"{label}: no rule fires on {100 * u:.1f} %", fontsize=9)
    fig.suptitle("coverage (red: the output is the default)")
    return fig


def _fmt(v: float, spec: str = ".3f") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def _sil_lines(job: Job, system, out: Path) -> list[str]:
    """The report's software-in-the-loop check of the C export: the compiled C controller against
    the Python evaluator in closed loop on the first training and (up to) two test worlds."""
    from hybridnav.analysis.sil import verify
    from hybridnav.fuzzy.export.sil import CompiledFIS

    head = ["", "## Software in the loop: the exported C controller", ""]
    try:
        compiled = CompiledFIS(out / f"{C_BASENAME}.c")
    except HybridnavError as exc:
        return head + [f"Not checked: {exc}"]
    worlds = job.scenarios("train")[:1] + job.scenarios("test")[:2]
    rows = verify(system, compiled, worlds, **job["planner"])
    worst = max(max(r["max_state_diff"], r["max_w_diff"]) for r in rows)
    same = all(r["same_outcome"] for r in rows)
    lines = head + [f"`{C_BASENAME}.c`, compiled with the system C compiler and called through "
                    "ctypes, drove the same EFFC closed loop as the Python evaluator: "
                    f"{'the same outcomes, ' if same else 'DIFFERENT OUTCOMES, '}largest "
                    f"difference of states and w {worst:.2e} "
                    f"({'within' if worst <= 1e-9 and same else 'NOT within'} 1e-9). Check "
                    f"again: `hybridnav verify fis.json {C_BASENAME}.c`.", "",
                    "| world | outcome | samples | max abs state diff | max abs w diff |",
                    "|---|---|---|---|---|"]
    lines += [f"| {r['scenario']} | {r['outcome']} | {r['samples']} | {r['max_state_diff']:.2e} "
              f"| {r['max_w_diff']:.2e} |" for r in rows]
    return lines


def _report(job: Job, result: TuneResult, summary: pd.DataFrame, unc: np.ndarray,
            radius: float, files: list[str], falsified: dict[str, Any] | None = None,
            sil: list[str] | None = None) -> str:
    rw, ga = job["reward"], job["ga"]
    sense = rw["sense"]
    n = {k: len(job.scenarios(k)) for k in ("train", "validation", "test")}
    lines = [
        f"# Tuning report: {job.name}", "",
        f"Seed {job.seed}; population {ga['population']}, {ga['generations']} generations; "
        f"starting system `{job['system']['start']}`; free: {job['free']['mf']} MF parameters"
        + (", rule switches" if job["free"]["rule_switches"] else "")
        + (", rule weights" if job["free"]["rule_weights"] else "")
        + (", rule consequents" if job["free"]["rule_consequents"] else "") + ".",
        f"Worlds: {n['train']} for training, {n['validation']} for validation (choosing the "
        f"returned system), {n['test']} for the final test (used only for this report).", "",
        _reward_text(job), "",
    ]
    # the verdict first: what a user deploys
    for which in ("test", "validation"):
        v = verdict(summary, which, radius)
        if not v["checks"]:
            continue
        word = "better" if v["better"] else "NOT better"
        lines += [f"**Verdict on the {which} set ({n[which]} worlds): the tuned system is "
                  f"{word} than its start.**", ""]
        lines += [f"- {'pass' if ok else 'FAIL'}: {text}" for text, ok in v["checks"]]
        lines.append("")
    val = result.validation
    if "best_score" in val:
        vs, ss = val["best_score"], val["start_score"]
        beat = ss is None or (vs < ss if sense == "minimize" else vs > ss)
        lines += [f"Returned system: the best on **validation**, from generation "
                  f"{result.best_generation}"
                  + (f" of k-fold stage {result.best_stage}" if val.get("folds") else "")
                  + f" (validation score {vs:.4f}"
                  + (f"; start {ss:.4f})." if ss is not None else ").")]
        if not beat:
            lines += ["", "**WARNING: the returned system does not score better than its "
                          "starting system on the validation set. Both are written: `fis.json` "
                          "(returned) and `start.json` (start).**"]
        if not val.get("folds"):
            stopped = val["stopped"]
            lines += ["", "Early stopping: "
                          + (f"stopped at generation {stopped}" if stopped else "not triggered")
                          + f" (patience {job['validation']['patience']}, tolerance "
                            f"{job['validation']['tolerance']:g})."]
    elif val.get("folds"):
        lines += [f"No validation set: the returned system is the last k-fold stage's best on "
                  f"its own fold ({result.selected_by}, generation {result.best_generation})."]
    else:
        lines += ["No validation set: the returned system is the best on training (generation "
                  f"{result.best_generation}); nothing checks that it generalizes."]
    if val.get("folds"):
        k = len(val["folds"])
        scores = [f["score"] for f in val["folds"]]
        lines += ["", f"k-fold over the training worlds ({k} folds; each stage trained on the "
                      "other folds and was scored on its own):", "",
                  "| stage | fold | best score on it | generation | early stop |",
                  "|---|---|---|---|---|"]
        for f in val["folds"]:
            lines.append(f"| {f['stage']} | {f['fold']} | {f['score']:.4f} | {f['generation']} "
                         f"| {f['stopped'] if f['stopped'] is not None else '-'} |")
        lines += ["", f"Cross-validation estimate (mean of the fold scores): "
                      f"{float(np.mean(scores)):.4f} (std {float(np.std(scores)):.4f})."]
    best = result.best.fitness.values[0]
    lines += ["", f"Training fitness: start {result.start_fitness:.4f}, returned {best:.4f}.",
              f"The tuned system keeps {len(result.system.rules)} of "
              f"{len(job.start_system().rules)} rules:", "",
              *(f"- {r.sentence(result.system.output.name)}" for r in result.system.rules), "",
              f"Coverage (grid {job['coverage']['grid']} x {job['coverage']['grid']} over the "
              f"input ranges): no rule fires on {100 * unc[0]:.1f} % for the start, "
              f"{100 * unc[1]:.1f} % for the tuned system (allowed: "
              f"{100 * job['coverage']['max_uncovered']:.1f} %; see coverage.png).", "",
              "## Start vs tuned vs apf on held-out worlds", "",
              "Nominal runs (no noise). Length and clearance: means over the worlds every system "
              "reached; 'min clearance' is the smallest over the worlds that system reached.", "",
              "| set | system | reached | 95 % interval | collided | stuck | timeout | "
              "out of bounds | common worlds | length | clearance | min clearance |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary.itertuples():
        lines.append(f"| {r.set} | {r.system} | {r.reached}/{r.worlds} | "
                     f"{_fmt(r.ci_low, '.2f')}-{_fmt(r.ci_high, '.2f')} | {r.collided} | "
                     f"{r.stuck} | {r.timeout} | {r.out_of_bounds} | {r.common_worlds} | "
                     f"{_fmt(r.common_length)} | {_fmt(r.common_clearance)} | "
                     f"{_fmt(r.min_clearance_reached)} |")
    if falsified is not None:
        fr, cfg = falsified["result"], falsified["config"]
        lines += ["", "## Falsification: worlds where the tuned system fails", "",
                  f"A {cfg['optimizer']} search over solvable worlds with {cfg['obstacles']} "
                  f"circles (start, goal, heading, positions and radii) tried {fr.evaluations} "
                  f"candidates, {fr.valid} of them valid and solvable; the tuned system failed "
                  f"in {fr.failures}."]
        if falsified["rows"]:
            lines += ["", "| world | tuned | clearance | start | apf |", "|---|---|---|---|---|"]
            for r in falsified["rows"]:
                lines.append(f"| `{r['world']}` | {r['tuned']} | {_fmt(r['tuned_clearance'])} "
                             f"| {r['start']} | {r['apf']} |")
            lines += ["", "Replay one: `hybridnav run <world> --planner effc --fis fis.json "
                          "--out DIR`."]
        else:
            lines += ["", "No failure found within the budget."]
    lines += sil or []
    last = result.logbook[-1]
    lines += ["", f"Wall time {last['wall_time']:.1f} s for "
                  f"{sum(r['evals'] for r in result.logbook)} evaluations (tuning only).", "",
              "Files: " + ", ".join(files), ""]
    return "\n".join(lines)


def _reward_text(job: Job) -> str:
    rw = job["reward"]
    if rw["kind"] == "length":
        return (f"Reward (length, minimized): path length when the target is reached, penalty "
                f"{rw['penalty']:g} otherwise, summed over the training worlds.")
    if rw["kind"] == "paper":
        return (f"Reward (paper, maximized): path length when the target is reached, "
                f"-{rw['penalty']:g} otherwise, summed over the training worlds.")
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
