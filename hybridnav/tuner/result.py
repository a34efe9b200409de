"""What a tuning run returns: :class:`TuningResult`, which writes itself with ``save(dir)``."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from hybridnav.fileio import atomic_write_text, dumps_json

__all__ = ["Member", "TuningResult"]


@dataclass
class Member:
    """A member of the Pareto front: its system, training objectives, vector and the front row
    (validation objectives included when there was validation)."""

    system: Any
    objectives: np.ndarray
    x: np.ndarray
    row: dict[str, Any] = field(default_factory=dict)


@dataclass
class TuningResult:
    """The outcome of :func:`hybridnav.tuner.tune`.

    Attributes
    ----------
    system : FuzzySystem
        The returned system: the best on validation when there was validation
        (``selected_by``), else the best on training; with several objectives the front member
        the selection rule picked.
    start : FuzzySystem
    settings : TunableSettings
    x, x_start : ndarray
        Their vectors.
    objectives, start_objectives : ndarray
        Their training objectives (``start_objectives`` from the first generation).
    objective_names : tuple of str
    front : pandas.DataFrame
        The Pareto front, one row per distinct system: ``member``, one
        ``objective_<i>`` column per objective (training),
        ``validation_<i>`` with validation, and ``returned``; one row with one objective.
    members : list of Member
        The front's members with their systems.
    logbook : pandas.DataFrame
        Per generation: ``gen``, ``evals``, ``min``/``mean``/``max``/``std`` of the first
        objective over the carried population, validation columns, ``wall_time``.
    validation : pandas.DataFrame
        Every candidate scored on validation (stage, generation, score, train score, feasible).
    validation_details : pandas.DataFrame
        Their detail rows (e.g. per validation world).
    records : pandas.DataFrame
        Every evaluation on training (per candidate, or per candidate and world).
    heldout : pandas.DataFrame or None
        Start and tuned (and ``apf`` for navigation) judged on validation and test.
    verdicts : dict
        Per role (``validation``, ``test``): ``checks`` (description, passed), ``better`` and a
        ``headline``.
    files : list of str
        The files a job run wrote (``hybridnav tune``; empty from :func:`tune`).
    learning : TuningResult or None
        :func:`hybridnav.tuner.learn`: the rule-learning stage's result.
    validation_cost : Cost or None
        The cost that chose the returned system.
    finished : bool
        False when the run was stopped (``stop_after``) before its budget or early stop.
    patience : int
        The early-stopping patience the run used.
    start_is_candidate : bool
        False when the search could not return the start as it is (its vector is a repaired or
        learned form of it: ``min_overlap``, rule learning); its scores are then its own.
    generations : list of dict
        Per generation, the best system of the carried population (``stage``, ``generation``,
        ``score``: the logbook's ``min``, ``system``); a navigation job writes them to
        ``generations.json`` for :func:`hybridnav.plotting.animate`.
    """

    system: Any
    start: Any
    settings: Any
    x: np.ndarray
    x_start: np.ndarray
    objectives: np.ndarray
    start_objectives: np.ndarray
    objective_names: tuple[str, ...]
    front: pd.DataFrame
    members: list[Member]
    logbook: pd.DataFrame
    validation: pd.DataFrame
    validation_details: pd.DataFrame
    records: pd.DataFrame
    selected_by: str
    best_generation: int
    best_stage: int = 0
    stopped: int | None = None
    folds: list[dict[str, Any]] = field(default_factory=list)
    validation_score: float | None = None
    start_validation_score: float | None = None
    optimizer: dict[str, Any] = field(default_factory=dict)
    cost: str = ""
    seed: int = 0
    wall_time: float = 0.0
    evaluations: int = 0
    config_hash: str = ""
    heldout: pd.DataFrame | None = None
    verdicts: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: falsification in the training loop (hybridnav.tuner.robust): one row per round
    robust: list[dict[str, Any]] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    learning: TuningResult | None = None
    validation_cost: Any = None
    finished: bool = True
    patience: int = 0
    start_is_candidate: bool = True
    generations: list[dict[str, Any]] = field(default_factory=list)

    @property
    def verdict(self) -> dict[str, Any] | None:
        """The verdict on the test set (on validation when there is no test set)."""
        return self.verdicts.get("test") or self.verdicts.get("validation")

    def summary(self) -> dict[str, Any]:
        """The result's numbers as a JSON-ready dict (what ``result.json`` holds)."""
        return {
            "system": self.system.name, "start": self.start.name, "seed": self.seed,
            "cost": self.cost, "optimizer": self.optimizer,
            "objective_names": list(self.objective_names),
            "objectives": self.objectives.tolist(),
            "start_objectives": self.start_objectives.tolist(),
            "selected_by": self.selected_by, "best_generation": self.best_generation,
            "best_stage": self.best_stage, "stopped": self.stopped,
            "validation_score": self.validation_score,
            "start_validation_score": self.start_validation_score,
            "start_is_candidate": self.start_is_candidate, "patience": self.patience,
            "front_size": len(self.members), "evaluations": self.evaluations,
            "wall_time": self.wall_time, "config_hash": self.config_hash,
            "robust": list(self.robust),
            "verdicts": {k: {"better": v["better"], "headline": v.get("headline", ""),
                             "checks": [{"check": c, "passed": ok} for c, ok in v["checks"]]}
                         for k, v in self.verdicts.items()},
        }

    def save(self, out: str | Path) -> list[str]:
        """Write the systems, tables and ``result.json`` into ``out``; returns the file names.

        ``fis.json`` (returned), ``start.json``, ``logbook.csv``, ``evaluations.csv``,
        ``validation.csv`` (with validation), ``heldout.csv`` (when judged), ``pareto.csv``
        and ``front/member_<i>.json`` (several objectives), ``result.json``.
        """
        import json

        from hybridnav.fuzzy import FuzzySystem

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = []
        self.system.save(out / "fis.json")
        self.start.save(out / "start.json")
        files += ["fis.json", "start.json"]
        tables = {"logbook.csv": self.logbook, "evaluations.csv": self.records}
        if len(self.validation_details):
            tables["validation.csv"] = self.validation_details
        elif len(self.validation):
            tables["validation.csv"] = self.validation
        if self.heldout is not None:
            tables["heldout.csv"] = self.heldout
        if len(self.members) > 1 or len(self.objective_names) > 1:
            tables["pareto.csv"] = self.front
            (out / "front").mkdir(exist_ok=True)
            for i, m in enumerate(self.members):
                assert isinstance(m.system, FuzzySystem)
                m.system.save(out / "front" / f"member_{i}.json")
                files.append(f"front/member_{i}.json")
        for fname, df in tables.items():
            atomic_write_text(out / fname, df.to_csv(index=False))
            files.append(fname)
        atomic_write_text(out / "result.json", dumps_json(json.loads(json.dumps(
            self.summary(), default=_plain))))
        files.append("result.json")
        return files

    def __repr__(self) -> str:
        objs = ", ".join(f"{n} {_fmt(a)} (start {_fmt(b)})" for n, a, b in
                         zip(self.objective_names, self.objectives, self.start_objectives))
        return (f"<TuningResult {self.system.name!r}: {objs}; chosen on {self.selected_by}; "
                f"{self.evaluations} evaluations>")


def _fmt(v: float) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def _plain(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)
