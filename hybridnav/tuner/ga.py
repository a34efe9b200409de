"""The genetic algorithm (DEAP operators), with checkpoints after every generation.

Classes are defined here at import time (no ``creator.create`` at run time), so individuals
pickle to any worker. Each generation: tournament selection, SBX (bounded) or blend crossover,
polynomial (bounded) or Gaussian mutation, repair, evaluation of the changed individuals in
chunks on the backend, and elitism through a hall of fame whose best ``elite`` members enter the
next generation unchanged. Generation 0 is the initial population: the starting system's genome
plus random ones.

DEAP's operators draw from Python's ``random`` module. So that nothing else in the process (a Dask
client's threads, user code) can shift that stream, the run gives them a private
``random.Random`` seeded from the job (:func:`_deap_random` swaps it into DEAP's operator
modules for the duration of the run).

**Validation and early stopping.** After every generation the ``validation.top`` best distinct
individuals (by training fitness; in generation 0 the starting system too) are scored on the
job's validation set (same chunks and backend; scores cached per genome). The job returns the
individual with the best **validation** score — not the best on training — and stops early when
that score has not improved by more than ``validation.tolerance`` for ``validation.patience``
generations (0: never). Without a validation set the best on training is returned.

After every generation ``checkpoint.json`` is written atomically with the population, the hall of
fame, the logbook, the records, the validation state, the *next* generation's number (and the
early-stop generation, if any), that ``random`` state, the NumPy generator state and the job's
configuration hash. ``resume`` continues from it — refusing a checkpoint of a different
configuration; a resume after an early stop does nothing — and ends with exactly the result an
uninterrupted run gives.
"""

from __future__ import annotations

import contextlib
import json
import logging
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from deap import base, tools

from hybridnav import __version__
from hybridnav.backends import Backend, SerialBackend
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, dumps_json
from hybridnav.tuner.evaluate import evaluate_chunk
from hybridnav.tuner.genome import GenomeSpace
from hybridnav.tuner.job import Job

log = logging.getLogger(__name__)

__all__ = ["CHECKPOINT_FORMAT", "FitnessMax", "FitnessMin", "Individual", "TuneResult", "tune"]

CHECKPOINT_FORMAT = "hybridnav-tune-checkpoint/2"


class FitnessMin(base.Fitness):
    """Smaller reward is better (``reward.sense = "minimize"``)."""

    weights = (-1.0,)


class FitnessMax(base.Fitness):
    """Larger reward is better (``reward.sense = "maximize"``)."""

    weights = (1.0,)


class Individual(list):
    """A genome (list of floats) with a ``fitness`` and its per-environment ``records``."""

    def __init__(self, genes=(), fitness_class: type = FitnessMin) -> None:
        super().__init__(float(g) for g in genes)
        self.fitness = fitness_class()
        self.records: list[dict[str, Any]] = []


@dataclass
class TuneResult:
    """What a tuning run leaves: the chosen genome and system, the logbook, every evaluation.

    ``best`` is the individual returned: the best on validation when the job has a validation
    set (``selected_by = "validation"``), else the best on training. ``validation`` holds the
    chosen individual's validation score and generation, the start's score, every validated
    candidate and the early-stop generation (None when the run went to the end).
    """

    best: Individual
    system: Any
    start_fitness: float
    logbook: list[dict[str, Any]]
    records: list[dict[str, Any]] = field(default_factory=list)
    hall_of_fame: list[Individual] = field(default_factory=list)
    validation: dict[str, Any] = field(default_factory=dict)
    selected_by: str = "training"
    best_generation: int = 0
    start_genome: list[float] = field(default_factory=list)
    best_stage: int = 0


def _job_json(job: Job) -> str:
    return json.dumps({"data": job.data, "source": job.source, "base": str(job.base)})


@contextlib.contextmanager
def _deap_random(rnd: random.Random):
    """Make DEAP's selection, crossover and mutation operators draw from ``rnd``."""
    from deap.tools import crossover, mutation, selection

    modules = (selection, crossover, mutation)
    saved = [m.random for m in modules]
    for m in modules:
        m.random = rnd
    try:
        yield
    finally:
        for m, r in zip(modules, saved):
            m.random = r


def tune(job: Job, out: str | Path, *, backend: Backend | None = None, resume: bool = False,
         progress: Callable[[dict[str, Any]], None] | None = None,
         stop_after: int | None = None) -> TuneResult:
    """Run the GA of ``job``, checkpointing into ``out``.

    Parameters
    ----------
    job : Job
    out : path
        Folder for ``checkpoint.json`` (created).
    backend : Backend, optional
        Where chunks are evaluated (default: this process).
    resume : bool
        Continue from ``out/checkpoint.json``.
    progress : callable, optional
        Called after every generation with that generation's logbook row.
    stop_after : int, optional
        Stop after this many generations in all (for tests of interruption; the checkpoint
        stays).

    Notes
    -----
    With ``validation.kfold = k >= 2`` the training worlds are split into ``k`` folds (a
    permutation seeded by the job's seed) and the GA runs ``k`` stages of ``ga.generations``
    generations: stage ``j`` trains on the other folds, scores its best individuals on fold
    ``j`` (early stopping on that score) and hands its final population to stage ``j + 1`` (as
    MATLAB's ``tunefis`` with ``KFoldValue`` passes each fold's result on). The returned system
    is the best on the job's validation set over all stages, or — without one — the best of the
    last stage on its fold.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    backend = backend or SerialBackend()
    ga, rw = job["ga"], job["reward"]
    fit_cls = FitnessMin if rw["sense"] == "minimize" else FitnessMax
    space = GenomeSpace(job.start_system(), job["free"])
    jj = _job_json(job)
    chash = job.config_hash()
    ckpt_path = out / "checkpoint.json"
    low, up = space.lower.tolist(), space.upper.tolist()
    sigma = (ga["gaussian_sigma"] * (space.upper - space.lower)).tolist()
    chunk = job["backend"]["chunk"]
    elite = ga["elite"]
    vcfg = job["validation"]
    kfold = vcfg["kfold"] if vcfg["kfold"] >= 2 else 0
    stages = max(1, kfold)
    G = ga["generations"]
    has_val = bool(job["scenarios"]["validation"])
    better = (lambda a, b: a < b) if rw["sense"] == "minimize" else (lambda a, b: a > b)

    def train_set(stage: int) -> str:
        return f"train-f{stage}" if kfold else "train"

    def select_set(stage: int) -> str | None:
        """The set that early stopping watches in a stage."""
        return f"fold{stage}" if kfold else ("validation" if has_val else None)

    def evaluate(inds: list[Individual], stage: int, generation: int,
                 indices: list[int]) -> int:
        """Evaluate ``inds`` in chunks on the backend; returns the number of evaluations."""
        if not inds:
            return 0
        key = stage * (G + 1) + generation          # distinct noise in every stage
        args = []
        for s in range(0, len(inds), chunk):
            part = inds[s:s + chunk]
            args.append((jj, np.array(part, dtype=float), key, indices[s:s + chunk],
                         train_set(stage)))
        results = [r for res in backend.map(evaluate_chunk, args) for r in res]
        for ind, idx, rec in zip(inds, indices, results):
            ind.fitness.values = (rec["fitness"],)
            ind.records = [dict(e, stage=stage, generation=generation, individual=idx,
                                set=train_set(stage), uncovered=rec["uncovered"])
                           for e in rec["envs"]]
        return len(inds)

    def score(which: str, inds: list[Individual], generation: int, track: dict[str, Any],
              stage: int) -> None:
        """Score the new candidates on ``which``; update ``track``'s best."""
        cache = track["cache"]
        train = {_gkey(i): i.fitness.values[0] for i in inds}
        genomes = [list(i) for i in inds]
        todo = list({_gkey(g): g for g in genomes if _gkey(g) not in cache}.values())
        if todo:
            args = [(jj, np.array(todo[s:s + chunk], dtype=float), generation,
                     list(range(s, min(s + chunk, len(todo)))), which)
                    for s in range(0, len(todo), chunk)]
            results = [r for res in backend.map(evaluate_chunk, args) for r in res]
            for g, rec in zip(todo, results):
                cache[_gkey(g)] = {"genes": list(g), "score": rec["fitness"],
                                   "cost": rec["cost"], "uncovered": rec["uncovered"],
                                   "train_fitness": train[_gkey(g)], "stage": stage,
                                   "generation": generation, "envs": rec["envs"]}
        scores = [cache[_gkey(g)]["score"] for g in genomes]
        track["gen_best"] = float(min(scores) if rw["sense"] == "minimize" else max(scores))
        max_unc = job["coverage"]["max_uncovered"] + 1e-12
        for g in genomes:
            entry = cache[_gkey(g)]
            ok, best_ok = entry["uncovered"] <= max_unc, (
                track["best"] is not None and track["best"]["uncovered"] <= max_unc)
            if ok != best_ok and track["best"] is not None:     # feasibility first
                if not ok:
                    continue
                track["best"] = dict(entry, stage=stage, generation=generation)
                track["last_improvement"] = generation
                continue
            if track["best"] is None or better(entry["score"], track["best"]["score"]):
                improved = (track["best"] is None or abs(entry["score"] - track["best"]["score"])
                            > vcfg["tolerance"])
                track["best"] = dict(entry, stage=stage, generation=generation)
                if improved:
                    track["last_improvement"] = generation

    def candidates(pop: list[Individual], include_first: bool) -> list[Individual]:
        """The ``validation.top`` best distinct individuals (and ``pop[0]``, the start)."""
        ranked = sorted(pop, key=lambda i: i.fitness.values[0],
                        reverse=rw["sense"] != "minimize")
        out_, seen = [], set()
        for ind in ranked:
            if _gkey(ind) not in seen:
                seen.add(_gkey(ind))
                out_.append(ind)
            if len(out_) == vcfg["top"]:
                break
        if include_first and _gkey(pop[0]) not in seen:
            out_.append(pop[0])
        return out_

    def after_generation(pop, stage, gen, st) -> None:
        """Validation bookkeeping and early stopping after a generation has been evaluated."""
        cands = candidates(pop, gen == 0 and stage == 0)
        if kfold:
            score(select_set(stage), cands, gen, st["fold"], stage)
        if has_val:
            score("validation", cands, gen, st["val"], stage)
        watch = st["fold"] if kfold else (st["val"] if has_val else None)
        if watch is not None and vcfg["patience"] and \
                gen - watch["last_improvement"] >= vcfg["patience"] and gen < G:
            st["stopped"] = gen
            log.info("early stop in stage %d at generation %d: no improvement on %s since %d",
                     stage, gen, select_set(stage), watch["last_improvement"])

    def row(gen, stage, n_ev, pop, elapsed, st):
        r = _row(gen, n_ev, pop, elapsed, st["val"] if has_val else None)
        if kfold:
            r = {"stage": stage, **r}
            r["fold_gen"] = st["fold"]["gen_best"]
            r["fold_best"] = st["fold"]["best"]["score"]
            r["wall_time"] = r.pop("wall_time")
        return r

    def new_track():
        return {"cache": {}, "best": None, "last_improvement": 0, "gen_best": None}

    if resume:
        state = _load_checkpoint(ckpt_path, chash)
        pop = [_ind(d, fit_cls) for d in state["population"]]
        hof = tools.HallOfFame(max(1, elite))
        hof.update([_ind(d, fit_cls) for d in state["hall_of_fame"]])
        logbook = state["logbook"]
        records = state["records"]
        stage, start_gen = state["stage"], state["generation"]
        start_fitness = state["start_fitness"]
        rnd = random.Random()
        rnd.setstate(_tuplify(state["python_random"]))
        rng = np.random.default_rng()
        rng.bit_generator.state = state["numpy_random"]
        elapsed = state["elapsed"]
        st = {"val": _load_track(state["validation"]), "fold": _load_track(state["fold"]),
              "stopped": state["stopped"]}
        folds_done = state["folds_done"]
        start_genome = state["start_genome"]
        log.info("resuming %s at stage %d, generation %d", job.name, stage, start_gen)
    else:
        rnd = random.Random(job.seed)
        rng = np.random.default_rng(job.seed)
        genomes = _initial_population(space, ga, rng)
        pop = [Individual(g, fit_cls) for g in genomes]
        start_genome = list(pop[0])
        st = {"val": new_track(), "fold": new_track(), "stopped": None}
        folds_done: list[dict[str, Any]] = []
        stage, logbook, records, elapsed = 0, [], [], 0.0
        start_fitness = None
        start_gen = 0
        hof = None
    done_gens = len(logbook)
    while stage < stages:
        if start_gen == 0:                     # a stage begins: (re-)evaluate the population
            if stop_after is not None and done_gens > stop_after:
                break
            tic = time.perf_counter()
            for ind in pop:
                del ind.fitness.values
            nevals = evaluate(pop, stage, 0, list(range(len(pop))))
            if start_fitness is None:
                start_fitness = pop[0].fitness.values[0]
            hof = tools.HallOfFame(max(1, elite))
            hof.update(pop)
            records += [r for ind in pop for r in ind.records]
            after_generation(pop, stage, 0, st)
            elapsed += time.perf_counter() - tic
            logbook.append(row(0, stage, nevals, pop, elapsed, st))
            done_gens += 1
            start_gen = 1
            _save_checkpoint(ckpt_path, job, chash, stage, 1, pop, hof, logbook, records, rnd,
                             rng, start_fitness, elapsed, st, folds_done, start_genome)
            if progress:
                progress(logbook[-1])
        for gen in range(start_gen, G + 1):
            if st["stopped"] is not None or (stop_after is not None and done_gens > stop_after):
                break
            tic = time.perf_counter()
            with _deap_random(rnd):
                offspring = [_clone(i, fit_cls) for i in tools.selTournament(
                    pop, len(pop) - elite, ga["tournament"])]
                for a, b in zip(offspring[::2], offspring[1::2]):
                    if rnd.random() < ga["crossover_prob"]:
                        if ga["crossover"] == "sbx":
                            tools.cxSimulatedBinaryBounded(a, b, ga["sbx_eta"], low, up)
                        else:
                            tools.cxBlend(a, b, ga["blend_alpha"])
                        del a.fitness.values, b.fitness.values
                for ind in offspring:
                    if rnd.random() < ga["mutation_prob"]:
                        if ga["mutation"] == "polynomial":
                            tools.mutPolynomialBounded(ind, ga["polynomial_eta"], low, up,
                                                       ga["gene_prob"])
                        else:
                            tools.mutGaussian(ind, 0.0, sigma, ga["gene_prob"])
                        del ind.fitness.values
            changed = [i for i in offspring if not i.fitness.valid]
            if changed:
                fixed = space.repair(np.array(changed, dtype=float))
                for ind, r_ in zip(changed, fixed):
                    ind[:] = r_.tolist()
            n_ev = evaluate(changed, stage, gen, list(range(len(changed))))
            pop = [_clone(h, fit_cls) for h in hof[:elite]] + offspring
            hof.update(pop)
            records += [r for ind in changed for r in ind.records]
            after_generation(pop, stage, gen, st)
            elapsed += time.perf_counter() - tic
            logbook.append(row(gen, stage, n_ev, pop, elapsed, st))
            done_gens += 1
            _save_checkpoint(ckpt_path, job, chash, stage, gen + 1, pop, hof, logbook, records,
                             rnd, rng, start_fitness, elapsed, st, folds_done, start_genome)
            if progress:
                progress(logbook[-1])
        else:
            gen = G + 1
        interrupted = st["stopped"] is None and gen <= G
        if interrupted:
            break
        # the stage is over (all generations or early stop): next fold, or the end
        if kfold:
            folds_done.append({"stage": stage, "fold": select_set(stage),
                               "stopped": st["stopped"], **st["fold"]["best"]})
            st["fold"] = new_track()
        if stage + 1 < stages:
            stage, start_gen = stage + 1, 0
            st["stopped"] = None
            _save_checkpoint(ckpt_path, job, chash, stage, 0, pop, hof, logbook, records,
                             rnd, rng, start_fitness, elapsed, st, folds_done, start_genome)
        else:
            if kfold or st["stopped"] is not None:
                _save_checkpoint(ckpt_path, job, chash, stage, G + 1, pop, hof, logbook,
                                 records, rnd, rng, start_fitness, elapsed, st, folds_done,
                                 start_genome, finished=True)
            break
    if has_val:
        chosen, selected = st["val"]["best"], "validation"
    elif kfold and folds_done:
        chosen, selected = folds_done[-1], f"fold {folds_done[-1]['fold'][4:]}"
    else:
        chosen, selected = None, "training"
    if chosen is not None:
        best = Individual(chosen["genes"], fit_cls)
        best.fitness.values = (float(chosen["train_fitness"]),)
        best_gen = chosen["generation"]
    else:
        best, best_gen = hof[0], _first_generation(logbook, hof[0])
    best_stage = chosen.get("stage", 0) if chosen is not None else stage
    system = space.system(np.array(best), name=f"{job.name}-tuned", description=(
        f"Tuned by hybridnav {__version__} (job {job.name!r}, seed {job.seed}) from "
        f"{job.start_system().name!r}: generation {best_gen}"
        + (f" of stage {best_stage}" if kfold else "")
        + f", chosen by its {selected} score over {len(job.scenarios('train'))} training and "
        f"{len(job.scenarios('validation'))} validation worlds. Inputs: dtheta = |direction "
        "to target - direction to nearest obstacle| (rad); alpha = d_obstacle / d_target. "
        "Output: w, the weight of the repulsive force in F_w = w F_rep + (1 - w) F_att."))
    vinfo: dict[str, Any] = {}
    if has_val:
        start_entry = st["val"]["cache"].get(_gkey(start_genome))
        vinfo = {"best_score": st["val"]["best"]["score"],
                 "best_generation": best_gen, "best_envs": st["val"]["best"]["envs"],
                 "start_score": start_entry["score"] if start_entry else None,
                 "start_envs": start_entry["envs"] if start_entry else [],
                 "stopped": st["stopped"] if not kfold else None,
                 "candidates": list(st["val"]["cache"].values())}
    if kfold:
        vinfo["folds"] = folds_done
    return TuneResult(best=best, system=system, start_fitness=start_fitness, logbook=logbook,
                      records=records, hall_of_fame=list(hof), validation=vinfo,
                      selected_by=selected, best_generation=best_gen,
                      start_genome=list(start_genome), best_stage=best_stage)


def _initial_population(space: GenomeSpace, ga: dict[str, Any],
                        rng: np.random.Generator) -> np.ndarray:
    """Generation 0: the starting system, then ``ga.init_local`` of the population drawn around
    it (Gaussian, ``ga.init_sigma`` of each gene's range, repaired) and the rest uniformly."""
    n = ga["population"]
    x0 = space.encode()
    n_local = int(round(ga["init_local"] * (n - 1)))
    span = space.upper - space.lower
    local = space.repair(x0 + rng.normal(0.0, 1.0, (n_local, space.size)) * ga["init_sigma"]
                         * span)
    return np.vstack([x0[None], local, space.random(n - 1 - n_local, rng)])


def _gkey(genes) -> str:
    """A genome's cache key (exact: floats written with repr)."""
    return ",".join(repr(float(g)) for g in genes)


def _load_track(state: dict[str, Any]) -> dict[str, Any]:
    return {"cache": {_gkey(e["genes"]): e for e in state["cache"]}, "best": state["best"],
            "last_improvement": state["last_improvement"], "gen_best": state["gen_best"]}


def _first_generation(logbook, ind) -> int:
    """The generation in which the best training fitness was first reached."""
    target = ind.fitness.values[0]
    for r in logbook:
        if r["min"] == target or r["max"] == target:
            return int(r["gen"])
    return int(logbook[-1]["gen"])


def _row(gen: int, nevals: int, pop: list[Individual], wall: float,
         val: dict[str, Any] | None = None) -> dict[str, Any]:
    f = np.array([i.fitness.values[0] for i in pop])
    row = {"gen": gen, "evals": nevals, "min": float(f.min()), "mean": float(f.mean()),
           "max": float(f.max()), "std": float(f.std())}
    if val is not None:
        row["val_gen"] = val["gen_best"]
        row["val_best"] = val["best"]["score"]
    row["wall_time"] = wall
    return row


def _clone(ind: Individual, fit_cls) -> Individual:
    new = Individual(ind, fit_cls)
    if ind.fitness.valid:
        new.fitness.values = ind.fitness.values
    new.records = list(ind.records)
    return new


def _ind(d: dict[str, Any], fit_cls) -> Individual:
    ind = Individual(d["genes"], fit_cls)
    if d.get("fitness") is not None:
        ind.fitness.values = (float(d["fitness"]),)
    ind.records = d.get("records", [])
    return ind


def _tuplify(obj):
    return tuple(_tuplify(v) for v in obj) if isinstance(obj, list) else obj


def _save_checkpoint(path: Path, job: Job, chash: str, stage: int, next_gen: int, pop, hof,
                     logbook, records, rnd: random.Random, rng, start_fitness, elapsed,
                     st: dict[str, Any], folds_done: list, start_genome,
                     finished: bool = False) -> None:
    def dump(ind):
        return {"genes": list(ind), "fitness": ind.fitness.values[0] if ind.fitness.valid
                else None, "records": ind.records}

    def track(t):
        return {"cache": list(t["cache"].values()), "best": t["best"],
                "last_improvement": t["last_improvement"], "gen_best": t["gen_best"]}

    state = {
        "format": CHECKPOINT_FORMAT, "version": __version__, "job": job.name,
        "config_hash": chash, "stage": stage, "generation": next_gen, "finished": finished,
        "population": [dump(i) for i in pop], "hall_of_fame": [dump(i) for i in hof],
        "logbook": logbook, "records": records, "start_fitness": start_fitness,
        "python_random": rnd.getstate(), "numpy_random": rng.bit_generator.state,
        "elapsed": elapsed, "validation": track(st["val"]), "fold": track(st["fold"]),
        "stopped": st["stopped"], "folds_done": folds_done, "start_genome": list(start_genome),
    }
    atomic_write_text(path, dumps_json(state))


def _load_checkpoint(path: Path, chash: str) -> dict[str, Any]:
    try:
        state = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise HybridnavError(f"{path}: no checkpoint to resume from (run without --resume "
                             "first)") from None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise HybridnavError(f"{path}: unreadable checkpoint ({exc})") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise HybridnavError(f"{path}: format: expected {CHECKPOINT_FORMAT!r}, got "
                             f"{state.get('format') if isinstance(state, dict) else state!r}")
    if state.get("config_hash") != chash:
        raise HybridnavError(
            f"{path}: config_hash: this checkpoint was written by a different job configuration "
            f"(checkpoint {str(state.get('config_hash'))[:12]}, job {chash[:12]}); resume with "
            "the same job file and seed, or start a new run in another folder")
    return state
