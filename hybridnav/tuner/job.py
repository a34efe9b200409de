"""Tuning jobs: the TOML file, its validation, the built-in EFFC job and the configuration hash.

A job is validated completely before any work starts; every error names the file and the key.
The configuration hash covers everything that determines the result (GA settings, free
parameters and bounds, the starting system's content, the training scenarios' content, reward,
planner settings, seed) and nothing that does not (backend, workers, chunk size, held-out
scenarios), so a checkpoint resumes on any backend but refuses a changed job.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError

__all__ = ["DEFAULT_JOB", "Job", "load_job", "quick"]

#: The built-in job: the EFFC paper's GA (population 100, 25 generations) on its two training
#: environments, starting from its 5-rule system and learning which rules matter.
DEFAULT_JOB: dict[str, Any] = {
    "name": "effc",
    "seed": 0,
    "ga": {
        "population": 100, "generations": 25, "tournament": 3, "elite": 2,
        "crossover": "sbx", "crossover_prob": 0.9, "sbx_eta": 15.0, "blend_alpha": 0.3,
        "mutation": "polynomial", "mutation_prob": 0.3, "gene_prob": 0.2,
        "polynomial_eta": 20.0, "gaussian_sigma": 0.1,
    },
    "system": {"start": "effc-5rule"},
    "free": {"mf": ["dtheta", "alpha", "w"], "rule_switches": True, "rule_weights": False,
             "rule_consequents": False, "bounds": {}},
    "scenarios": {"train": ["effc-train-1", "effc-train-2"],
                  "heldout": ["effc-env-a", "effc-env-b"]},
    "reward": {"sense": "minimize", "penalty": 100.0, "repeats": 1, "heading_noise": 0.0},
    "planner": {"speed": 0.1, "max_turn": math.pi / 4, "stuck_window": 10.0,
                "stuck_radius": 2.0},
    "backend": {"workers": 1, "dask": "", "chunk": 50},
}

_QUICK = {"population": 12, "generations": 3}

_SCHEMA: dict[str, dict[str, tuple]] = {
    # section: key -> (type, lo, hi, choices)
    "ga": {
        "population": (int, 2, None, None), "generations": (int, 0, None, None),
        "tournament": (int, 1, None, None), "elite": (int, 0, None, None),
        "crossover": (str, None, None, ("sbx", "blend")),
        "crossover_prob": (float, 0.0, 1.0, None), "sbx_eta": (float, 0.0, None, None),
        "blend_alpha": (float, 0.0, None, None),
        "mutation": (str, None, None, ("polynomial", "gaussian")),
        "mutation_prob": (float, 0.0, 1.0, None), "gene_prob": (float, 0.0, 1.0, None),
        "polynomial_eta": (float, 0.0, None, None), "gaussian_sigma": (float, 0.0, None, None),
    },
    "system": {"start": (str, None, None, None)},
    "free": {"mf": (list, None, None, None), "rule_switches": (bool, None, None, None),
             "rule_weights": (bool, None, None, None),
             "rule_consequents": (bool, None, None, None), "bounds": (dict, None, None, None)},
    "scenarios": {"train": (list, None, None, None), "heldout": (list, None, None, None)},
    "reward": {"sense": (str, None, None, ("minimize", "maximize")),
               "penalty": (float, 0.0, None, None), "repeats": (int, 1, None, None),
               "heading_noise": (float, 0.0, None, None)},
    "planner": {"speed": (float, 1e-9, None, None), "max_turn": (float, 1e-6, math.pi, None),
                "stuck_window": (float, 0.0, None, None),
                "stuck_radius": (float, 0.0, None, None)},
    "backend": {"workers": (int, 1, None, None), "dask": (str, None, None, None),
                "chunk": (int, 1, None, None)},
}


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
        """The training (or held-out) scenarios, loaded."""
        from hybridnav.world import load_scenario

        return [load_scenario(self.resolve(s)) for s in self.data["scenarios"][which]]

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

        d = {k: v for k, v in self.data.items() if k not in ("backend", "name")}
        d = copy.deepcopy(d)
        d["scenarios"].pop("heldout", None)
        d["system"] = self.start_system().to_dict()
        d["train_content"] = [scenario_to_dict(s) for s in self.scenarios("train")]
        text = json.dumps(d, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def to_dict(self) -> dict[str, Any]:
        return copy.deepcopy(self.data)


def quick(job: Job) -> Job:
    """The small smoke-run version of a job (population 12, 3 generations)."""
    d = copy.deepcopy(job.data)
    d["ga"].update(_QUICK)
    d["ga"]["elite"] = min(d["ga"]["elite"], d["ga"]["population"] - 1)
    d["name"] = f"{d['name']}-quick"
    return Job(d, job.source, job.base)


def load_job(path: str | os.PathLike | None = None) -> Job:
    """Load and validate a job file; ``None`` gives the built-in EFFC job."""
    if path is None:
        return validate_job(copy.deepcopy(DEFAULT_JOB), None, Path.cwd())
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise HybridnavError(f"{p}: cannot read the job file ({exc.strerror or exc})") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HybridnavError(f"{p}: not valid TOML: {exc}") from None
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
        if isinstance(raw["seed"], bool) or not isinstance(raw["seed"], int) or raw["seed"] < 0:
            raise fail("seed", f"expected a non-negative integer, got {raw['seed']!r}")
        data["seed"] = raw["seed"]
    for section, schema in _SCHEMA.items():
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
            data[section][key] = _check(fail, f"{section}.{key}", value, *schema[key])
    ga = data["ga"]
    if ga["elite"] >= ga["population"]:
        raise fail("ga.elite", f"expected fewer elites than the population "
                               f"({ga['population']}), got {ga['elite']}")
    if ga["tournament"] > ga["population"]:
        raise fail("ga.tournament", f"expected at most the population ({ga['population']}), "
                                    f"got {ga['tournament']}")
    rw = data["reward"]
    if rw["repeats"] > 1 and rw["heading_noise"] == 0:
        raise fail("reward.repeats", "repeats > 1 only make sense with heading_noise > 0 "
                                     "(without noise every repeat is identical)")
    for key in ("train", "heldout"):
        items = data["scenarios"][key]
        if not all(isinstance(s, str) and s for s in items):
            raise fail(f"scenarios.{key}", f"expected a list of scenario names or paths, got "
                                           f"{items!r}")
    if not data["scenarios"]["train"]:
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
    for which in ("train", "heldout"):
        for i, spec in enumerate(data["scenarios"][which]):
            try:
                from hybridnav.world import load_scenario

                s = load_scenario(job.resolve(spec))
            except HybridnavError as exc:
                raise fail(f"scenarios.{which}[{i}]", str(exc)) from None
            if which == "train" and (len(s.robots) != 1 or s.robots[0].goal is None
                                     or s.robots[0].model != "unicycle"):
                raise fail(f"scenarios.train[{i}]", "expected a scenario with exactly one "
                                                    "unicycle robot and a fixed goal")
    if data["free"]["mf"] == [] and not any(
            data["free"][k] for k in ("rule_switches", "rule_weights", "rule_consequents")):
        raise fail("free", "nothing is free: set free.mf or a free.rule_* switch")
    return job


def _check(fail, key: str, value: Any, kind: type, lo, hi, choices):
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind in (int, float):
        ok = isinstance(value, kind) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise fail(key, f"expected {kind.__name__}, got {value!r}")
    if kind is float and not math.isfinite(value):
        raise fail(key, f"expected a finite number, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise fail(key, f"expected a value in [{lo}, {hi if hi is not None else 'inf'}], got "
                        f"{value!r}")
    if choices is not None and value not in choices:
        raise fail(key, f"expected one of {', '.join(choices)}, got {value!r}")
    return value
