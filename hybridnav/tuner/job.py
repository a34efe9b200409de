"""Tuning jobs: the TOML file, its validation, the built-in EFFC job and the configuration hash.

A job is validated completely before any work starts; every error names the file and the key.
Scenario sets (``scenarios.train``, ``scenarios.validation``, ``scenarios.test``) are lists whose
items are built-in names, scenario files, or generated sets ``{generate = N, seed = S, ...}``
(:mod:`hybridnav.world.generator`; the other keys are generator settings).
A job is a thin front over the tuning objects: :meth:`Job.tunable` (the
:class:`~hybridnav.tuner.TunableSettings`), :meth:`Job.cost` (navigation, data or python),
:meth:`Job.optimizer` and :meth:`Job.validation_arg` are what :func:`hybridnav.tuner.tune`
takes; ``run_job`` passes them. The configuration hash that guards a resume is computed by
``tune`` from those objects' content (not the backend, workers, chunk size or test set).
"""

from __future__ import annotations

import copy
import functools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hybridnav import models
from hybridnav.backends import DASK_ADDRESS
from hybridnav.errors import HybridnavError
from hybridnav.fileio import parse_toml, read_text_file
from hybridnav.params import Param, check_value, short_repr
from hybridnav.tuner.costs.navigation import COVERAGE, PLANNER, REWARD

__all__ = ["DEFAULT_JOB", "SCHEMA", "Job", "load_job", "load_scenario_set", "quick"]

_POS = {"lo": 0.0}                  # a non-negative number
_UNIT = {"lo": 0.0, "hi": 1.0}       # a fraction

#: The generated worlds with structures that trap reactive controllers in the built-in sets:
#: one of each class at most, besides up to three circles
TRAPS: dict[str, Any] = {"cups": [0, 1], "corridors": [0, 1], "gaps": [0, 1], "walls": [0, 1],
                         "circles": [0, 3], "name": "trap"}

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
    "cost": {
        "kind": Param("navigation", "navigation (a planner on worlds), data (samples) or python "
                                    "(your function)", choices=("navigation", "data", "python")),
        "planner": Param("effc", "kind = navigation: the planner that takes the fuzzy system"),
        "data": Param("", "kind = data: a CSV file whose columns are the inputs and the output"),
        "output": Param("", "kind = data: the output column (default: the last)"),
        "metric": Param("rmse", "kind = data: rmse or mae", choices=("rmse", "mae")),
        "validation": Param(0.0, "kind = data: fraction of the samples held out for validation "
                                 "(0: none)", lo=0.0, hi=0.9),
        "test": Param("", "kind = data: a CSV file of test samples, only reported"),
        "function": Param("", "kind = python: module:function (the module may sit beside the "
                              "job file)"),
        "batch": Param(False, "kind = python: f(candidates, context) per chunk instead of "
                              "f(system) per candidate"),
        "objectives": Param(1, "python: the number of objectives; navigation: a list of "
                               "reward, failure, collision, length, clearance (several: NSGA2)",
                            kind=object),
    },
    "optimizer": {"kind": Param("ga", "ga, cmaes, pso or nsga2 (its own settings beside kind; "
                                      "without this table [ga] holds the GA's)",
                                choices=("ga", "cmaes", "pso", "nsga2"))},
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
    "settings": {
        "free": Param(["dtheta", "alpha", "w"], "variables, terms (var.term) or parameters "
                                                 "(var.term[i]) whose MF parameters are tuned"),
        "fixed": Param([], "paths fixed again (e.g. w.low)"),
        "rule_switches": Param(True, "learn which rules stay on"),
        "rule_weights": Param(False, "learn the rule weights"),
        "rule_consequents": Param(False, "learn the rules' output terms"),
        "bounds": Param({}, "optional [lo, hi] per variable (replaces range and margin)"),
        "margin": Param(0.25, "term positions may pass the range ends by this times its width",
                        **_UNIT),
        "rules": Param([], "1-based numbers of the rules the rule_* settings apply to (empty: "
                           "all)"),
        "min_overlap": Param(0.0, "neighbouring terms' supports overlap by at least this "
                                  "fraction of the range (0: not enforced)", **_UNIT),
    },
    "scenarios": {
        "train": Param(["effc-train-1", "effc-train-2", {"generate": 30, "seed": 1},
                        {"generate": 8, "seed": 11, **TRAPS}],
                       "the training worlds: names, files or generated sets"),
        "validation": Param([{"generate": 24, "seed": 2}, {"generate": 6, "seed": 12, **TRAPS}],
                            "the worlds that choose the returned system"),
        "test": Param(["effc-env-a", "effc-env-b", {"generate": 30, "seed": 3},
                       {"generate": 8, "seed": 13, **TRAPS}],
                      "the worlds only reported"),
        "heldout": Param([], "the old name of test (warns; removed in 0.4.0)"),
    },
    "reward": REWARD,
    "coverage": COVERAGE,
    "learning": {
        "max_rules": Param(0, "learn a rule base of up to this many rules first, then tune its "
                              "MFs (0: tune only)", lo=0, hi=1000),
        "keep_rules": Param(True, "start from the system's rules (false: an empty rule base)"),
        "rule_weights": Param(False, "learn rule weights too"),
    },
    "validation": {
        "top": Param(3, "candidates scored on validation per generation", lo=1, hi=1000),
        "patience": Param(-1, "generations without improvement before stopping (0: never; -1: "
                              "the optimizer's default: GA 10, PSO 15, CMA-ES and NSGA-II 0)",
                          lo=-1),
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
        "cups": Param(1, "cups facing the start the search may place (each switched on or off "
                         "by the search)", lo=0, hi=10),
        "corridors": Param(1, "corridors the search may place", lo=0, hi=10),
        "gaps": Param(1, "narrow gaps the search may place", lo=0, hi=10),
    },
    "robust": {
        "rounds": Param(1, "falsification rounds after tuning whose finds join the training "
                           "worlds before tuning continues (0: off; stops early when a search "
                           "finds nothing to add)", lo=0, hi=10),
        "budget": Param(300, "candidate worlds each round's search tries", lo=2, hi=100_000),
        "cap": Param(8, "worlds added per round at most", lo=1, hi=100),
        "failures": Param("collisions", "which finds join training: collisions (touching an "
                                        "obstacle or leaving the workspace) or all (also stuck "
                                        "and timeout)", choices=("collisions", "all")),
    },
    "planner": PLANNER,
    "backend": {
        "workers": Param(1, "local worker processes (at most the cores and the chunks)",
                         lo=1, hi=256),
        "dask": DASK_ADDRESS,
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
       for section, keys in SCHEMA.items() if section not in ("settings", "optimizer")},
}
#: sections that replace an older one when given ([settings] for [free], [optimizer] for [ga])
_OPTIONAL = ("settings", "optimizer")

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
        if spec.endswith((".json", ".toml", ".fis", ".fll", ".csv")) or "/" in spec \
                or os.sep in spec:
            p = Path(spec)
            return str(p if p.is_absolute() else self.base / p)
        return spec

    def start_system(self):
        """The starting fuzzy system (a built-in name, or a ``.json``, ``.fll`` or MATLAB
        ``.fis`` file)."""
        from hybridnav import fuzzy

        return fuzzy.load_any(self.resolve(self.data["system"]["start"]))

    def scenarios(self, which: str = "train") -> list:
        """The scenarios of a set (``train``, ``validation`` or ``test``), loaded or generated."""
        return _load_set(json.dumps(self.data["scenarios"][which], sort_keys=True),
                         str(self.base))

    def with_seed(self, seed: int | None) -> Job:
        if seed is None:
            return self
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise HybridnavError(f"--seed: expected a non-negative integer, got {seed!r}")
        d = copy.deepcopy(self.data)
        d["seed"] = int(seed)
        return Job(d, self.source, self.base)

    def with_backend(self, workers: int | None = None, dask: str | None = None) -> Job:
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or workers < 1):
            raise HybridnavError(f"--workers: expected an integer >= 1, got {workers!r}")
        d = copy.deepcopy(self.data)
        if workers is not None:
            d["backend"]["workers"] = int(workers)
        if dask is not None:
            d["backend"]["dask"] = DASK_ADDRESS.check("--dask", dask)
        return Job(d, self.source, self.base)

    # ---- the tuning objects ------------------------------------------------------------

    def tunable(self):
        """The :class:`~hybridnav.tuner.TunableSettings` of ``[settings]`` (or ``[free]``)."""
        from hybridnav.tuner.settings import TunableSettings

        table = self.data.get("settings") or self.data["free"]
        return TunableSettings.from_table(self.start_system(), table)

    def cost(self, which: str = "train"):
        """The cost on a set (``train``, ``validation``, ``test``), or None for an empty set."""
        c = self.data["cost"]
        if c["kind"] == "navigation":
            from hybridnav.tuner.costs import NavigationCost

            scen = self.scenarios(which)
            if not scen:
                return None
            objs = c["objectives"] if isinstance(c["objectives"], list) else ["reward"]
            return NavigationCost(scen, planner=c["planner"], planner_params=self["planner"],
                                  reward=self["reward"], coverage=self["coverage"], name=which,
                                  strict=which != "test", objectives=objs)
        if c["kind"] == "data":
            from hybridnav.tuner.costs import DataCost

            if which == "validation":
                return None                       # a fraction of the data: validation_arg
            path = c["data"] if which == "train" else c["test"]
            if not path:
                return None
            p = Path(path)                        # a data file is a path, never a name
            return DataCost.from_csv(p if p.is_absolute() else self.base / p,
                                     c["output"] or None, metric=c["metric"],
                                     prefer=self.start_system().output.name)
        from hybridnav.tuner.costs import FunctionCost

        if which != "train":
            return None
        return FunctionCost(c["function"], batch=c["batch"], objectives=c["objectives"],
                            path=str(self.base))

    def optimizer(self):
        """The optimizer of ``[optimizer]``, or the GA of ``[ga]``."""
        from hybridnav.tuner.optimizers import (
            GA,
            SBX,
            Blend,
            Gaussian,
            Polynomial,
            make_optimizer,
        )

        if self.data.get("optimizer"):
            return make_optimizer(self.data["optimizer"], f"{self.source or 'job'}: ")
        g = self["ga"]
        objs = self["cost"]["objectives"]
        if (isinstance(objs, list) and len(objs) > 1) or (isinstance(objs, int) and objs > 1):
            from hybridnav.tuner.optimizers import NSGA2

            return NSGA2(population=max(4, -(-g["population"] // 4) * 4),
                         generations=g["generations"])
        cx = SBX(g["sbx_eta"]) if g["crossover"] == "sbx" else Blend(g["blend_alpha"])
        mut = (Polynomial(g["polynomial_eta"], g["gene_prob"]) if g["mutation"] == "polynomial"
               else Gaussian(g["gaussian_sigma"], g["gene_prob"]))
        return GA(population=g["population"], generations=g["generations"],
                  tournament=g["tournament"], elite=g["elite"], crossover=cx,
                  crossover_prob=g["crossover_prob"], mutation=mut,
                  mutation_prob=g["mutation_prob"], init_local=g["init_local"],
                  init_sigma=g["init_sigma"])

    def tune_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`hybridnav.tuner.tune` this job means (all but the
        system, the cost, the backend and the checkpoint)."""
        v = self["validation"]
        return {"settings": self.tunable(), "optimizer": self.optimizer(),
                "validation": self.validation_arg(), "test": self.cost("test"),
                "seed": self.seed, "chunk": self["backend"]["chunk"], "top": v["top"],
                "patience": None if v["patience"] < 0 else v["patience"],
                "tolerance": v["tolerance"],
                "name": f"{self.name}-tuned"}

    def validation_arg(self):
        """What :func:`~hybridnav.tuner.tune` takes as ``validation``: k-fold, a validation
        cost, a fraction of the data, or None."""
        from hybridnav.tuner.core import KFold

        k = self["validation"]["kfold"]
        val = self.cost("validation")
        if k >= 2:
            return KFold(k, val)
        if self["cost"]["kind"] == "data" and self["cost"]["validation"] > 0:
            return float(self["cost"]["validation"])
        return val

    def to_dict(self) -> dict[str, Any]:
        return copy.deepcopy(self.data)


def quick(job: Job) -> Job:
    """The small smoke-run version of a job (population 12, 3 generations, a falsification
    budget of at most 60 worlds; the same scenario sets)."""
    d = copy.deepcopy(job.data)
    d["ga"].update(_QUICK)
    d["ga"]["elite"] = min(d["ga"]["elite"], d["ga"]["population"] - 1)
    d["ga"]["tournament"] = min(d["ga"]["tournament"], d["ga"]["population"])
    opt = d.get("optimizer")
    if opt:
        opt["generations"] = 3
        for key in ("population", "n"):
            if key in opt or (key == "population" and opt.get("kind", "ga") in ("ga", "nsga2")) \
                    or (key == "n" and opt.get("kind") == "pso"):
                opt[key] = 12
        if opt.get("kind", "ga") == "ga":
            opt["elite"] = min(opt.get("elite", 2), 11)
            opt["tournament"] = min(opt.get("tournament", 3), 12)
    d["falsify"]["budget"] = min(d["falsify"]["budget"], 60)
    d["robust"]["budget"] = min(d["robust"]["budget"], 60)
    if d["falsify"]["budget"]:            # the swarm's first iteration must fit the budget
        d["falsify"]["population"] = min(d["falsify"]["population"], d["falsify"]["budget"])
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
    allowed = set(data) | set(_OPTIONAL)
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise fail(unknown[0], f"unknown key; expected one of: {', '.join(sorted(allowed))}")
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
        if section == "optimizer":             # kind and that optimizer's own settings
            from hybridnav.tuner.optimizers import make_optimizer

            make_optimizer(table, where)
            data["optimizer"] = copy.deepcopy(table)
            continue
        if section == "settings":
            if "free" in raw:
                raise fail("settings", "expected either [settings] or its old name [free], "
                                       "not both")
            data["settings"] = {k: copy.deepcopy(p.default) for k, p in schema.items()}
        bad = sorted(set(table) - set(schema))
        if bad:
            raise fail(f"{section}.{bad[0]}", "unknown key; expected one of: "
                       + ", ".join(sorted(schema)))
        for key, value in table.items():
            data[section][key] = schema[key].check(f"{section}.{key}", value, where)
        for name, b in (table.get("bounds", {}) if section in ("free", "settings") else {}).items():
            key = f"{section}.bounds.{name}"          # the tuner's bounds: two finite numbers
            if not isinstance(b, list) or len(b) != 2:
                raise fail(key, f"expected [lo, hi], got {short_repr(b)}")
            for i, x in enumerate(b):
                check_value(where, f"{key}[{i}]", x, float)
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
    job = Job(data, source, base)
    try:
        system = job.start_system()
    except HybridnavError as exc:
        raise fail("system.start", str(exc)) from None
    if data["robust"]["rounds"] and (data["learning"]["max_rules"]
                                     or data["validation"]["kfold"] >= 2
                                     or data["cost"]["kind"] != "navigation"):
        given = raw.get("robust") if isinstance(raw.get("robust"), dict) else {}
        if given.get("rounds"):
            raise fail("robust.rounds", "expected 0 with rule learning, k-fold or a cost that is "
                                        "not navigation (falsification adds worlds to a "
                                        "navigation job's training set), got "
                                        f"{data['robust']['rounds']}")
        data["robust"]["rounds"] = 0                # the default does not apply to such a job
    fz = data["falsify"]
    if fz["budget"] and fz["budget"] < fz["population"]:
        raise fail("falsify.budget", f"expected 0 (off) or at least falsify.population "
                                     f"({fz['population']} worlds: the search's first iteration), "
                                     f"got {fz['budget']}")
    if data["cost"]["kind"] == "navigation":     # the planner's inputs first: the clearest error
        from hybridnav import planners

        cls = planners.PLANNERS.get(data["cost"]["planner"])
        wanted = getattr(cls, "fuzzy_inputs", None)
        if wanted is None:
            raise fail("cost.planner", "expected a planner that takes a fuzzy system (effc), "
                                       f"got {data['cost']['planner']!r}")
        from hybridnav.planners.base import accepts_inputs, inputs_text

        if not accepts_inputs(cls, system.input_names):
            raise fail("system.start", f"the {data['cost']['planner']} planner provides the "
                                       f"fuzzy inputs {inputs_text(cls)}; {system.name!r} has "
                                       f"{', '.join(system.input_names)}")
    every = [*system.input_names, system.output.name]
    if data["learning"]["max_rules"] and data.get("settings") and data["settings"]["rules"]:
        raise fail("settings.rules", "expected no rule numbers with [learning] (the learned "
                                     "rules are not known before stage 1)")
    if "free" not in raw and "settings" not in raw:    # every variable of the start system
        data["free"]["mf"] = every
    if "settings" in raw and "free" not in raw["settings"]:
        data["settings"]["free"] = every
    try:
        settings = job.tunable()
    except HybridnavError as exc:
        raise fail("settings" if "settings" in data else "free", str(exc)) from None
    if settings.size == 0:
        raise fail("settings" if "settings" in data else "free",
                   "nothing is free: free a variable or a rule setting")
    kind = data["cost"]["kind"]
    objs = data["cost"]["objectives"]
    if kind == "python" and (isinstance(objs, bool) or not isinstance(objs, int)
                             or not 1 <= objs <= 10):
        raise fail("cost.objectives", f"expected an integer in [1, 10] for kind = 'python', "
                                      f"got {objs!r}")
    if kind == "data" and objs != 1:
        raise fail("cost.objectives", "a data cost has one objective (its metric); objectives "
                                      "are for kind = 'navigation' or 'python'")
    if kind == "navigation" and objs != 1:
        from hybridnav.tuner.costs.navigation import MEASURES

        if not (isinstance(objs, list) and objs and all(isinstance(o, str) for o in objs)
                and all(o in MEASURES for o in objs) and len(set(objs)) == len(objs)):
            raise fail("cost.objectives", f"expected a list of distinct names of "
                                          f"{', '.join(MEASURES)}, got {short_repr(objs)}")
    k = data["validation"]["kfold"]
    if kind != "navigation" and "scenarios" in raw:
        raise fail("scenarios", f"expected no worlds for cost.kind = {kind!r} (they are the "
                                "data of a navigation cost)")
    if kind != "data" and data["cost"]["validation"] > 0:
        raise fail("cost.validation", f"a fraction of samples held out is for cost.kind = "
                                      f"'data', not {kind!r}")
    if kind == "python" and k >= 2:
        raise fail("validation.kfold", "a python cost cannot be split into folds (it has no "
                                       "data the tuner knows of)")
    if kind == "data" and k >= 2 and data["cost"]["validation"] > 0:
        raise fail("cost.validation", "expected either a held-out fraction or "
                                      "validation.kfold, not both")
    if kind == "navigation":
        _check_scenarios(data, raw, where, fail, job)
        try:
            job.cost("train").check(settings)
        except HybridnavError as exc:
            raise fail("system.start", str(exc)) from None
    else:
        c = data["cost"]
        if kind == "data" and not c["data"]:
            raise fail("cost.data", "expected a CSV file of samples for cost.kind = 'data'")
        if kind == "python" and not c["function"]:
            raise fail("cost.function", "expected 'module:function' for cost.kind = 'python'")
        for key in (("data", "test") if kind == "data" else ("function",)):
            if not c[key]:
                continue
            try:
                built = job.cost("train" if key != "test" else "test")
                if built is not None:
                    built.check(settings)
            except HybridnavError as exc:
                raise fail(f"cost.{key}", str(exc)) from None
            if key == "data" and k >= 2 and k > len(built.y):
                raise fail("validation.kfold", f"expected at most the number of samples "
                                               f"({len(built.y)}), got {k}")
    if data["validation"]["kfold"] >= 2 and kind == "navigation" and data["validation"]["kfold"] \
            > len(job.scenarios("train")):
        raise fail("validation.kfold", f"expected at most the number of training worlds "
                                       f"({len(job.scenarios('train'))}), got "
                                       f"{data['validation']['kfold']}")
    return job


def _check_scenarios(data: dict[str, Any], raw: dict[str, Any], where: str, fail, job: Job
                     ) -> None:
    """The scenario sets of a navigation job: given right, loadable, one robot model each."""
    sc = data["scenarios"]
    given = raw.get("scenarios", {}) if isinstance(raw.get("scenarios"), dict) else {}
    if "heldout" in given:
        from hybridnav.deprecation import warn_renamed

        warn_renamed(f"{where}scenarios.heldout", "scenarios.test")
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
                from hybridnav.world.generator import generator_from_table

                generator_from_table(item, where, f"scenarios.{key}[{i}]")
            else:
                raise fail(f"scenarios.{key}[{i}]", "expected a scenario name or path, or a "
                                                    "generated set {generate = N, seed = S}, "
                                                    f"got {item!r}")
    if not sc["train"]:
        raise fail("scenarios.train", "expected at least one training scenario")
    for which in SETS:
        try:
            loaded = job.scenarios(which)
        except HybridnavError as exc:
            raise HybridnavError(f"{where}scenarios.{which}{exc}") from None
        from hybridnav import planners

        drives = planners.PLANNERS[data["cost"]["planner"]].models
        for i, s in enumerate(loaded):
            bad = [r.model for r in s.robots if r.model not in drives]
            if bad:
                raise fail(f"scenarios.{which}[{i}]", f"{s.source or s.name}: the "
                           f"{data['cost']['planner']} planner drives {', '.join(drives)}, got "
                           f"{bad[0]!r}")
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


def load_scenario_set(items: list, base: str | os.PathLike, where: str, first: int = 0) -> list:
    """The scenarios of a set as a job lists them: built-in names, scenario files (relative to
    ``base``) and generated sets ``{generate = N, seed = S, ...}``.

    Parameters
    ----------
    items : list
        The set's items, as ``scenarios.train`` (``validation``, ``test``) of a job holds them.
    base : str or path-like
        The folder relative file names are in (the job file's).
    where : str
        What the messages start with (e.g. ``"job.toml: scenarios.test"``).
    first : int
        The index of ``items[0]`` in the whole set, for the messages (items loaded one at a
        time name their place in the set).

    Returns
    -------
    list of Scenario

    Raises
    ------
    HybridnavError
        An item that is not a scenario, a file, or a generated set, or scenarios of one name.
    """
    if not isinstance(items, list):
        raise HybridnavError(f"{where}: expected a list of scenario names, files and generated "
                             f"sets, got {type(items).__name__}")
    try:
        return list(_load_set(json.dumps(items, sort_keys=True), str(base), int(first)))
    except HybridnavError as exc:
        raise HybridnavError(f"{where}{exc}") from None


@functools.lru_cache(maxsize=16)
def _load_set(items_json: str, base: str, first: int = 0) -> list:
    """The scenarios of one set (cached: generated worlds are drawn once per process)."""
    from hybridnav.world import load_scenario
    from hybridnav.world.generator import generator_from_table

    out = []
    for i, item in enumerate(json.loads(items_json), start=first):
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
