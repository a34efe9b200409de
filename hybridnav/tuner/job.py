"""Tuning jobs: the TOML file, its validation, the built-in EFFC job and the configuration hash.

A job is validated completely before any work starts; every error names the file and the key.
Scenario sets (``scenarios.train``, ``scenarios.validation``, ``scenarios.test``) are lists whose
items are built-in names, scenario files, or generated sets ``{generate = N, seed = S, ...}``
(:mod:`hybridnav.worldgen`; the other keys are generator settings).
The configuration hash covers everything that determines the result (GA settings, free
parameters and bounds, the starting system's content, the training and validation scenarios'
content, reward, coverage, validation and planner settings, seed) and nothing that does not
(backend, workers, chunk size, the test scenarios), so a checkpoint resumes on any backend but
refuses a changed job.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav import models
from hybridnav.errors import HybridnavError
from hybridnav.fileio import parse_toml, read_text_file
from hybridnav.params import Param, check_value

__all__ = ["DEFAULT_JOB", "SCHEMA", "Job", "load_job", "quick"]

_POS = {"lo": 0.0}                  # a non-negative number
_UNIT = {"lo": 0.0, "hi": 1.0}       # a fraction

#: Every key of a job file, declared once: default, what it does, type and bounds. The built-in
#: job (:data:`DEFAULT_JOB`) is their defaults; ``validate_job`` checks a file against them.
SCHEMA: dict[str, dict[str, Param]] = {
    "ga": {
        "population": Param(100, "individuals per generation", lo=2, hi=100_000),
        "generations": Param(25, "generations after the initial one", lo=0, hi=100_000),
        "tournament": Param(3, "tournament size", lo=1),
        "elite": Param(2, "hall-of-fame members copied into every new generation", lo=0),
        "crossover": Param("sbx", "sbx (bounded simulated binary) or blend",
                           choices=("sbx", "blend")),
        "crossover_prob": Param(0.9, "probability that a pair is crossed", **_UNIT),
        "sbx_eta": Param(15.0, "SBX distribution index", **_POS),
        "blend_alpha": Param(0.3, "blend crossover alpha", **_POS),
        "mutation": Param("polynomial", "polynomial (bounded) or gaussian",
                          choices=("polynomial", "gaussian")),
        "mutation_prob": Param(0.3, "probability that an individual mutates", **_UNIT),
        "gene_prob": Param(0.2, "probability that a gene of a mutant mutates", **_UNIT),
        "polynomial_eta": Param(20.0, "polynomial mutation distribution index", **_POS),
        "gaussian_sigma": Param(0.1, "Gaussian mutation std, fraction of each gene's range",
                                **_POS),
        "init_local": Param(0.5, "generation 0: fraction drawn around the starting system",
                            **_UNIT),
        "init_sigma": Param(0.1, "their Gaussian spread, fraction of each gene's range",
                            **_POS),
    },
    "system": {"start": Param("effc-5rule", "the starting system: a built-in name or a "
                                            "hybridnav-fis/1 file (relative to the job file)")},
    "free": {
        "mf": Param(["dtheta", "alpha", "w"], "variables whose membership functions are tuned"),
        "rule_switches": Param(True, "learn which rules stay on"),
        "rule_weights": Param(False, "learn the rule weights"),
        "rule_consequents": Param(False, "learn the rules' output terms"),
        "bounds": Param({}, "optional [lo, hi] per variable (replaces range and margin)"),
        "margin": Param(0.25, "term positions may pass the range ends by this times its width",
                        **_UNIT),
    },
    "scenarios": {
        "train": Param(["effc-train-1", "effc-train-2", {"generate": 30, "seed": 1}],
                       "the training worlds: names, files or generated sets"),
        "validation": Param([{"generate": 24, "seed": 2}], "the worlds that choose the "
                                                           "returned system"),
        "test": Param(["effc-env-a", "effc-env-b", {"generate": 30, "seed": 3}],
                      "the worlds only reported"),
        "heldout": Param([], "the old name of test"),
    },
    "reward": {
        "kind": Param("deploy", "deploy, length or paper", choices=("deploy", "length", "paper")),
        "sense": Param("minimize", "minimize (maximize: kind = paper only)",
                       choices=("minimize", "maximize")),
        "penalty": Param(100.0, "kind = length / paper: a failed run's cost", **_POS),
        "collision": Param(20.0, "a collision or leaving the workspace", **_POS),
        "failure": Param(10.0, "stuck or timeout ...", **_POS),
        "progress": Param(5.0, "... plus this times distance left / start distance", **_POS),
        "length": Param(1.0, "times path length / start-goal distance, when reached", **_POS),
        "time": Param(0.0, "times time x speed / start-goal distance, when reached", **_POS),
        "clearance": Param(2.0, "times the shortfall of the minimum clearance below "
                                "safety_distance", **_POS),
        "safety_distance": Param(1.0, "in robot radii", **_POS),
        "repeats": Param(1, "noisy simulations per world, averaged (> 1 needs noise)",
                         lo=1, hi=1000),
        "heading_noise": Param(0.0, "std of the noise on the commanded heading (rad)", **_POS),
        "dtheta_noise": Param(0.0, "std of the noise added to dtheta (rad)", **_POS),
        "alpha_noise": Param(0.0, "std of the relative noise on alpha", **_POS),
    },
    "coverage": {
        "grid": Param(41, "points per input axis", lo=2, hi=1001),
        "max_uncovered": Param(0.0, "largest allowed fraction where no rule fires", **_UNIT),
        "penalty": Param(100.0, "cost per uncovered fraction beyond it", **_POS),
    },
    "validation": {
        "top": Param(3, "candidates scored on validation per generation", lo=1, hi=1000),
        "patience": Param(10, "generations without improvement before stopping (0: never)",
                          lo=0),
        "tolerance": Param(0.0, "an improvement must exceed this", **_POS),
        "kfold": Param(0, "k >= 2: k-fold over the training worlds", lo=0, hi=100),
    },
    "falsify": {
        "budget": Param(600, "candidate worlds searched after tuning (0: off)", lo=0,
                        hi=100_000),
        "population": Param(30, "worlds per swarm iteration", lo=2, hi=1000),
        "obstacles": Param(6, "circles per candidate world", lo=1, hi=50),
        "keep": Param(5, "worst failure worlds written", lo=1, hi=100),
        "optimizer": Param("pso", "pso, bat or firefly", choices=("pso", "bat", "firefly")),
    },
    "planner": {
        "speed": Param(0.1, "robot speed (m/s)", lo=0.0, lo_open=True),
        "max_turn": Param(math.pi / 4, "largest heading change per control cycle (rad)",
                          lo=0.0, lo_open=True, hi=math.pi),
        "stuck_window": Param(10.0, "seconds without progress that count as stuck", **_POS),
        "stuck_radius": Param(2.0, "the no-progress disk, in goal radii", **_POS),
    },
    "backend": {
        "workers": Param(1, "local worker processes", lo=1),
        "dask": Param("", "a Dask scheduler address or 'local'"),
        "chunk": Param(50, "individuals per unit of parallel work", lo=1),
    },
}

#: The built-in job: the EFFC paper's GA (population 100, 25 generations) starting from its
#: 5-rule system and learning its membership functions and which rules matter, trained on the
#: paper's two training environments plus generated worlds, the returned system chosen on a
#: separate generated validation set, and reported on the paper's comparison environments and
#: a generated test set.
DEFAULT_JOB: dict[str, Any] = {
    "name": "effc", "seed": 0,
    **{section: {k: copy.deepcopy(p.default) for k, p in keys.items() if k != "heldout"}
       for section, keys in SCHEMA.items()},
}

_QUICK = {"population": 12, "generations": 3}

#: the scenario sets of a job; ``heldout`` is the old name of ``test``
SETS = ("train", "validation", "test")


@dataclass
class Job:
    """A validated tuning job (see :data:`DEFAULT_JOB` for the keys)."""

    data: dict[str, Any]
    source: str | None = None
    base: Path = field(default_factory=Path.cwd)

    # ---- convenient views -----------------------------------------------------------------

    @property
    def name(self) -> str:
        return self.data["name"]

    @property
    def seed(self) -> int:
        return self.data["seed"]

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.data[section]

    def resolve(self, spec: str) -> str:
        """A file reference relative to the job file (built-in names are left alone)."""
        if spec.endswith((".json", ".toml")) or "/" in spec or os.sep in spec:
            p = Path(spec)
            return str(p if p.is_absolute() else self.base / p)
        return spec

    def start_system(self):
        """The starting fuzzy system."""
        from hybridnav import fuzzy

        return fuzzy.load(self.resolve(self.data["system"]["start"]))

    def scenarios(self, which: str = "train") -> list:
        """The scenarios of a set (``train``, ``validation`` or ``test``), loaded or generated."""
        return _load_set(json.dumps(self.data["scenarios"][which], sort_keys=True),
                         str(self.base))

    def folds(self) -> list[int]:
        """The k-fold assignment of the training worlds (``validation.kfold``): a permutation
        seeded by the job's seed, dealt round robin into the folds."""
        n = len(self.scenarios("train"))
        k = self.data["validation"]["kfold"]
        perm = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(7,))) \
            .permutation(n)
        out = [0] * n
        for pos, i in enumerate(perm):
            out[int(i)] = pos % k if k >= 2 else 0
        return out

    def with_seed(self, seed: int | None) -> Job:
        if seed is None:
            return self
        d = copy.deepcopy(self.data)
        d["seed"] = int(seed)
        return Job(d, self.source, self.base)

    def with_backend(self, workers: int | None = None, dask: str | None = None) -> Job:
        d = copy.deepcopy(self.data)
        if workers is not None:
            d["backend"]["workers"] = int(workers)
        if dask is not None:
            d["backend"]["dask"] = dask
        return Job(d, self.source, self.base)

    def config_hash(self) -> str:
        """SHA-256 of everything that determines the result (not the backend)."""
        from hybridnav.world import scenario_to_dict

        d = {k: v for k, v in self.data.items() if k not in ("backend", "name", "falsify")}
        d = copy.deepcopy(d)
        d["scenarios"].pop("test", None)
        d["system"] = self.start_system().to_dict()
        d["train_content"] = [scenario_to_dict(s) for s in self.scenarios("train")]
        d["validation_content"] = [scenario_to_dict(s) for s in self.scenarios("validation")]
        text = json.dumps(d, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def to_dict(self) -> dict[str, Any]:
        return copy.deepcopy(self.data)


def quick(job: Job) -> Job:
    """The small smoke-run version of a job (population 12, 3 generations, a falsification
    budget of at most 60 worlds; the same scenario sets)."""
    d = copy.deepcopy(job.data)
    d["ga"].update(_QUICK)
    d["ga"]["elite"] = min(d["ga"]["elite"], d["ga"]["population"] - 1)
    d["falsify"]["budget"] = min(d["falsify"]["budget"], 60)
    d["name"] = f"{d['name']}-quick"
    return Job(d, job.source, job.base)


def load_job(path: str | os.PathLike | None = None) -> Job:
    """Load and validate a job file; ``None`` gives the built-in EFFC job."""
    if path is None:
        return validate_job(copy.deepcopy(DEFAULT_JOB), None, Path.cwd())
    p = Path(path)
    raw = parse_toml(read_text_file(p, "job file"), str(p), "job file")
    return validate_job(raw, str(p), p.parent)


def validate_job(raw: dict[str, Any], source: str | None, base: Path) -> Job:
    """Merge ``raw`` over the defaults and check every key (errors name file and key)."""
    where = f"{source}: " if source else "job: "

    def fail(key: str, msg: str) -> HybridnavError:
        return HybridnavError(f"{where}{key}: {msg}")

    data = copy.deepcopy(DEFAULT_JOB)
    unknown = sorted(set(raw) - set(data))
    if unknown:
        raise fail(unknown[0], f"unknown key; expected one of: {', '.join(sorted(data))}")
    for key in ("name",):
        if key in raw:
            if not isinstance(raw[key], str) or not raw[key].strip():
                raise fail(key, f"expected a non-empty string, got {raw[key]!r}")
            data[key] = raw[key]
    if "seed" in raw:
        data["seed"] = check_value(where, "seed", raw["seed"], int, 0)
    for section, schema in SCHEMA.items():
        if section not in raw:
            continue
        table = raw[section]
        if not isinstance(table, dict):
            raise fail(section, f"expected a table [{section}], got {type(table).__name__}")
        bad = sorted(set(table) - set(schema))
        if bad:
            raise fail(f"{section}.{bad[0]}", "unknown key; expected one of: "
                       + ", ".join(sorted(schema)))
        for key, value in table.items():
            data[section][key] = schema[key].check(f"{section}.{key}", value, where)
    ga = data["ga"]
    if ga["elite"] >= ga["population"]:
        raise fail("ga.elite", f"expected fewer elites than the population "
                               f"({ga['population']}), got {ga['elite']}")
    if ga["tournament"] > ga["population"]:
        raise fail("ga.tournament", f"expected at most the population ({ga['population']}), "
                                    f"got {ga['tournament']}")
    rw = data["reward"]
    if "reward" in raw and "sense" in raw["reward"] and "kind" not in raw["reward"]:
        # job files written before reward.kind: sense alone chose the old conventions
        rw["kind"] = "paper" if rw["sense"] == "maximize" else "length"
    if rw["kind"] == "paper":
        rw["sense"] = "maximize"
    elif rw["sense"] == "maximize":
        raise fail("reward.sense", f"expected minimize for reward.kind = {rw['kind']!r} "
                                   "(maximize is the paper's convention, reward.kind = 'paper')")
    noisy = any(rw[k] > 0 for k in ("heading_noise", "dtheta_noise", "alpha_noise"))
    if rw["repeats"] > 1 and not noisy:
        raise fail("reward.repeats", "repeats > 1 only make sense with heading_noise, "
                                     "dtheta_noise or alpha_noise > 0 (without noise every "
                                     "repeat is identical)")
    sc = data["scenarios"]
    given = raw.get("scenarios", {}) if isinstance(raw.get("scenarios"), dict) else {}
    if "heldout" in given:
        if "test" in given:
            raise fail("scenarios.heldout", "expected either test or its old name heldout, "
                                            "not both")
        sc["test"] = sc["heldout"]
    sc.pop("heldout", None)
    if "train" in given:               # a job that names its own training set: no generated
        if "validation" not in given:  # default sets beside it
            sc["validation"] = []
        if "test" not in given and "heldout" not in given:
            sc["test"] = ["effc-env-a", "effc-env-b"]
    for key in SETS:
        for i, item in enumerate(sc[key]):
            if isinstance(item, str):
                if not item:
                    raise fail(f"scenarios.{key}[{i}]", "expected a scenario name or path, "
                                                        "got an empty string")
            elif isinstance(item, dict):
                from hybridnav.worldgen import generator_from_table

                generator_from_table(item, where, f"scenarios.{key}[{i}]")
            else:
                raise fail(f"scenarios.{key}[{i}]", "expected a scenario name or path, or a "
                                                    "generated set {generate = N, seed = S}, "
                                                    f"got {item!r}")
    if not sc["train"]:
        raise fail("scenarios.train", "expected at least one training scenario")
    job = Job(data, source, base)
    # the referenced files must load, and fit together, before any work starts
    try:
        system = job.start_system()
    except HybridnavError as exc:
        raise fail("system.start", str(exc)) from None
    names = {v.name for v in (*system.inputs, system.output)}
    for v in data["free"]["mf"]:
        if not isinstance(v, str) or v not in names:
            raise fail("free.mf", f"expected variable names of {system.name!r} "
                                  f"({', '.join(sorted(names))}), got {v!r}")
    for v, b in data["free"]["bounds"].items():
        if v not in names:
            raise fail(f"free.bounds.{v}", f"not a variable of {system.name!r}")
        if (not isinstance(b, list) or len(b) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in b)
                or not all(math.isfinite(x) for x in b) or not b[0] < b[1]):
            raise fail(f"free.bounds.{v}", f"expected [lo, hi] with lo < hi, got {b!r}")
    if set(system.input_names) != {"dtheta", "alpha"}:
        raise fail("system.start", f"the EFFC controller needs the inputs dtheta and alpha, "
                                   f"{system.name!r} has {', '.join(system.input_names)}")
    for which in SETS:
        try:
            loaded = job.scenarios(which)
        except HybridnavError as exc:
            raise HybridnavError(f"{where}scenarios.{which}{exc}") from None
        for i, s in enumerate(loaded):
            if which != "test" and (len(s.robots) != 1 or s.robots[0].goal is None
                                    or "heading_control" not in
                                    models.MODELS[s.robots[0].model].capabilities):
                raise fail(f"scenarios.{which}[{i}]", f"{s.source or s.name}: expected a "
                           "scenario with exactly one unicycle robot and a fixed goal")
        if which != "test" and loaded:
            keys = {(s.dt, s.robots[0].radius, tuple(sorted(s.robots[0].params.items())))
                    for s in loaded}
            if len(keys) > 1:
                raise fail(f"scenarios.{which}", "expected one robot model for the whole set "
                           "(the same dt, robot radius and parameters), so that one batched "
                           f"step serves them all; got {len(keys)} different ones")
    k = data["validation"]["kfold"]
    if k >= 2 and k > len(job.scenarios("train")):
        raise fail("validation.kfold", f"expected at most the number of training worlds "
                                       f"({len(job.scenarios('train'))}), got {k}")
    if data["free"]["mf"] == [] and not any(
            data["free"][k] for k in ("rule_switches", "rule_weights", "rule_consequents")):
        raise fail("free", "nothing is free: set free.mf or a free.rule_* switch")
    return job


@functools.lru_cache(maxsize=16)
def _load_set(items_json: str, base: str) -> list:
    """The scenarios of one set (cached: generated worlds are drawn once per process)."""
    from hybridnav.world import load_scenario
    from hybridnav.worldgen import generator_from_table

    out = []
    for i, item in enumerate(json.loads(items_json)):
        if isinstance(item, str):
            spec = item
            if spec.endswith((".json", ".toml")) or "/" in spec or os.sep in spec:
                p = Path(spec)
                spec = str(p if p.is_absolute() else Path(base) / p)
            try:
                out.append(load_scenario(spec))
            except HybridnavError as exc:
                raise HybridnavError(f"[{i}]: {exc}") from None
        else:
            gen, count, seed = generator_from_table(item, "", f"[{i}]")
            try:
                out += gen.generate(count, seed)
            except HybridnavError as exc:
                raise HybridnavError(f"[{i}]: {exc}") from None
    names = [s.name for s in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise HybridnavError(f": expected distinct scenario names, {dup[0]!r} appears twice")
    return out
