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
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, dumps_json
from hybridnav.tuner.backends import Backend, SerialBackend
from hybridnav.tuner.evaluate import evaluate_chunk
from hybridnav.tuner.genome import GenomeSpace
from hybridnav.tuner.job import Job

log = logging.getLogger(__name__)

__all__ = ["CHECKPOINT_FORMAT", "FitnessMax", "FitnessMin", "Individual", "TuneResult", "tune"]

CHECKPOINT_FORMAT = "hybridnav-tune-checkpoint/1"


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
        Stop after this generation (for tests of interruption; the checkpoint stays).
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

    def evaluate(inds: list[Individual], generation: int, indices: list[int]) -> int:
        """Evaluate ``inds`` in chunks on the backend; returns the number of evaluations."""
        if not inds:
            return 0
        args = []
        for s in range(0, len(inds), chunk):
            part = inds[s:s + chunk]
            args.append((jj, np.array(part, dtype=float), generation, indices[s:s + chunk]))
        results = [r for res in backend.map(evaluate_chunk, args) for r in res]
        for ind, idx, rec in zip(inds, indices, results):
            ind.fitness.values = (rec["fitness"],)
            ind.records = [dict(e, generation=generation, individual=idx, set="train",
                                uncovered=rec["uncovered"]) for e in rec["envs"]]
        return len(inds)

    has_val = bool(job["scenarios"]["validation"])
    vcfg = job["validation"]
    better = (lambda a, b: a < b) if rw["sense"] == "minimize" else (lambda a, b: a > b)

    def validate(inds: list[Individual], generation: int, val: dict[str, Any]) -> None:
        """Score the new candidates on the validation set; update the best validated one."""
        cache = val["cache"]
        genomes = [list(i) for i in inds]
        train = {_gkey(i): i.fitness.values[0] for i in inds}
        todo = [g for g in genomes if _gkey(g) not in cache]
        todo = list({_gkey(g): g for g in todo}.values())
        if todo:
            args = [(jj, np.array(todo[s:s + chunk], dtype=float), generation,
                     list(range(s, min(s + chunk, len(todo)))), "validation")
                    for s in range(0, len(todo), chunk)]
            results = [r for res in backend.map(evaluate_chunk, args) for r in res]
            for g, rec in zip(todo, results):
                cache[_gkey(g)] = {"genes": list(g), "score": rec["fitness"],
                                   "cost": rec["cost"], "uncovered": rec["uncovered"],
                                   "train_fitness": train[_gkey(g)],
                                   "generation": generation, "envs": rec["envs"]}
        scores = [cache[_gkey(g)]["score"] for g in genomes]
        val["gen_best"] = float(min(scores) if rw["sense"] == "minimize" else max(scores))
        for g in genomes:
            entry = cache[_gkey(g)]
            if val["best"] is None or better(entry["score"], val["best"]["score"]):
                improved = (val["best"] is None or abs(entry["score"] - val["best"]["score"])
                            > vcfg["tolerance"])
                val["best"] = dict(entry, generation=generation)
                if improved:
                    val["last_improvement"] = generation

    def candidates(pop: list[Individual], generation: int) -> list[Individual]:
        """The ``validation.top`` best distinct individuals (generation 0: and the start)."""
        ranked = sorted(pop, key=lambda i: i.fitness.values[0],
                        reverse=rw["sense"] != "minimize")
        out, seen = [], set()
        for ind in ranked:
            if _gkey(ind) not in seen:
                seen.add(_gkey(ind))
                out.append(ind)
            if len(out) == vcfg["top"]:
                break
        if generation == 0 and _gkey(pop[0]) not in seen:
            out.append(pop[0])                 # the starting system
        return out

    if resume:
        state = _load_checkpoint(ckpt_path, chash)
        pop = [_ind(d, fit_cls) for d in state["population"]]
        hof = tools.HallOfFame(max(1, elite))
        hof.update([_ind(d, fit_cls) for d in state["hall_of_fame"]])
        logbook = state["logbook"]
        records = state["records"]
        start_gen = state["generation"]
        start_fitness = state["start_fitness"]
        rnd = random.Random()
        rnd.setstate(_tuplify(state["python_random"]))
        rng = np.random.default_rng()
        rng.bit_generator.state = state["numpy_random"]
        elapsed = state["elapsed"]
        val = _load_val(state["validation"])
        stopped = state.get("stopped")
        start_genome = state["start_genome"]
        log.info("resuming %s at generation %d", job.name, start_gen)
    else:
        rnd = random.Random(job.seed)
        rng = np.random.default_rng(job.seed)
        genomes = np.vstack([space.encode()[None], space.random(ga["population"] - 1, rng)])
        pop = [Individual(g, fit_cls) for g in genomes]
        start_genome = list(pop[0])
        stopped = None
        val = {"cache": {}, "best": None, "last_improvement": 0, "gen_best": None}
        tic = time.perf_counter()
        nevals = evaluate(pop, 0, list(range(len(pop))))
        start_fitness = pop[0].fitness.values[0]
        hof = tools.HallOfFame(max(1, elite))
        hof.update(pop)
        records = [r for ind in pop for r in ind.records]
        if has_val:
            validate(candidates(pop, 0), 0, val)
        elapsed = time.perf_counter() - tic
        logbook = [_row(0, nevals, pop, elapsed, val if has_val else None)]
        start_gen = 1
        _save_checkpoint(ckpt_path, job, chash, 1, pop, hof, logbook, records, rnd, rng,
                         start_fitness, elapsed, val, stopped, start_genome)
        if progress:
            progress(logbook[-1])
    for gen in range(start_gen, ga["generations"] + 1):
        if stopped is not None or (stop_after is not None and gen > stop_after):
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
            for ind, row in zip(changed, fixed):
                ind[:] = row.tolist()
        n_ev = evaluate(changed, gen, list(range(len(changed))))
        pop = [_clone(h, fit_cls) for h in hof[:elite]] + offspring
        hof.update(pop)
        records += [r for ind in changed for r in ind.records]
        if has_val:
            validate(candidates(pop, gen), gen, val)
            if vcfg["patience"] and gen - val["last_improvement"] >= vcfg["patience"]:
                stopped = gen
                log.info("early stop at generation %d: no validation improvement since %d",
                         gen, val["last_improvement"])
        elapsed += time.perf_counter() - tic
        logbook.append(_row(gen, n_ev, pop, elapsed, val if has_val else None))
        _save_checkpoint(ckpt_path, job, chash, gen + 1, pop, hof, logbook, records, rnd, rng,
                         start_fitness, elapsed, val, stopped, start_genome)
        if progress:
            progress(logbook[-1])
    if has_val:
        chosen = val["best"]
        best = Individual(chosen["genes"], fit_cls)
        match = [h for h in hof if _gkey(h) == _gkey(best)]
        best.fitness.values = (match[0].fitness.values if match else
                               (float(chosen["train_fitness"]),))
        best_gen, selected = chosen["generation"], "validation"
    else:
        best, best_gen, selected = hof[0], _first_generation(records, logbook, hof[0]), "training"
    system = space.system(np.array(best), name=f"{job.name}-tuned")
    d = system.to_dict()
    d["description"] = (
        f"Tuned by hybridnav {__version__} (job {job.name!r}, seed {job.seed}) from "
        f"{job.start_system().name!r}: generation {best_gen}, chosen by its {selected} score "
        f"over {len(job.scenarios('train'))} training and {len(job.scenarios('validation'))} "
        "validation worlds. Inputs: dtheta = |direction to target - direction to nearest "
        "obstacle| (rad); alpha = d_obstacle / d_target. Output: w, the weight of the "
        "repulsive force in F_w = w F_rep + (1 - w) F_att.")
    from hybridnav.fuzzy import FuzzySystem

    system = FuzzySystem.from_dict(d)
    vinfo: dict[str, Any] = {}
    if has_val:
        start_entry = val["cache"][_gkey(start_genome)]
        vinfo = {"best_score": val["best"]["score"], "best_generation": val["best"]["generation"],
                 "best_envs": val["best"]["envs"], "start_score": start_entry["score"],
                 "start_envs": start_entry["envs"], "stopped": stopped,
                 "candidates": list(val["cache"].values())}
    return TuneResult(best=best, system=system, start_fitness=start_fitness, logbook=logbook,
                      records=records, hall_of_fame=list(hof), validation=vinfo,
                      selected_by=selected, best_generation=best_gen,
                      start_genome=list(start_genome))


def _gkey(genes) -> str:
    """A genome's cache key (exact: floats written with repr)."""
    return ",".join(repr(float(g)) for g in genes)


def _load_val(state: dict[str, Any]) -> dict[str, Any]:
    return {"cache": {_gkey(e["genes"]): e for e in state["cache"]}, "best": state["best"],
            "last_improvement": state["last_improvement"], "gen_best": state["gen_best"]}


def _first_generation(records, logbook, ind) -> int:
    """The generation in which the best training fitness was first reached."""
    target = ind.fitness.values[0]
    for row in logbook:
        if row["min"] == target or row["max"] == target:
            return int(row["gen"])
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


def _save_checkpoint(path: Path, job: Job, chash: str, next_gen: int, pop, hof, logbook,
                     records, rnd: random.Random, rng, start_fitness, elapsed, val, stopped,
                     start_genome) -> None:
    def dump(ind):
        return {"genes": list(ind), "fitness": ind.fitness.values[0] if ind.fitness.valid
                else None, "records": ind.records}

    state = {
        "format": CHECKPOINT_FORMAT, "version": __version__, "job": job.name,
        "config_hash": chash, "generation": next_gen,
        "population": [dump(i) for i in pop], "hall_of_fame": [dump(i) for i in hof],
        "logbook": logbook, "records": records, "start_fitness": start_fitness,
        "python_random": rnd.getstate(), "numpy_random": rng.bit_generator.state,
        "elapsed": elapsed,
        "validation": {"cache": list(val["cache"].values()), "best": val["best"],
                       "last_improvement": val["last_improvement"],
                       "gen_best": val["gen_best"]},
        "stopped": stopped, "start_genome": list(start_genome),
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
