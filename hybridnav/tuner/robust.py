"""Falsification in the training loop: worlds an adversary finds join the training set.

After tuning, :func:`robust_rounds` searches (:func:`hybridnav.tuner.falsify.falsify`, the job's
``[falsify]`` world class and swarm) for worlds where the tuned system fails; the worst distinct
ones (collisions only, or every failure: ``robust.failures``) — at most ``robust.cap`` per round,
each a world with its own search seed — are added to the training worlds and tuning continues
from the tuned system. It stops after ``robust.rounds`` rounds or as soon as a search of
``robust.budget`` worlds finds nothing to add. The validation and test sets are never touched:
the returned system is still the best on validation, and the final verdict compares it with
the job's own start on the same held-out worlds. Each round's tuning checkpoints in
``DIR/robust-<r>/`` and resumes like the first.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["robust_rounds"]


def robust_rounds(job, result, backend, out: Path, kw: dict[str, Any],
                  progress: Callable | None, resume: bool, stop_after: int | None):
    """The job's robust rounds after ``result`` (the first tuning): the final result, with
    ``result.robust`` (one row per round: valid worlds, failures, collisions, worlds added)."""
    from hybridnav.tuner.core import _judge, score_start, tune
    from hybridnav.tuner.falsify import CRASH, falsify
    from hybridnav.tuner.settings import TunableSettings

    cfg, fz = job["robust"], job["falsify"]
    start = result.start
    train = job.cost("train")
    rows: list[dict[str, Any]] = []
    table = job.data.get("settings") or job["free"]
    for r in range(1, cfg["rounds"] + 1):
        seed = int(np.random.SeedSequence(job.seed, spawn_key=(17, r)).generate_state(1)[0])
        if kw.get("phase") is not None:
            kw["phase"](f"robust round {r}: falsification search, {cfg['budget']} worlds")
        found = falsify(train, result.system, budget=cfg["budget"],
                        population=min(fz["population"], cfg["budget"]),
                        obstacles=fz["obstacles"], keep=cfg["budget"],
                        optimizer=fz["optimizer"], seed=seed,
                        structures={k: fz[k] for k in ("cups", "corridors", "gaps")})
        pick = [w for w, o in zip(found.worlds, found.outcomes)
                if cfg["failures"] == "all" or o in CRASH][:cfg["cap"]]
        rows.append({"round": r, "searched": found.evaluations, "valid": found.valid,
                     "failures": found.failures, "collisions": found.collisions,
                     "added": len(pick)})
        if not pick:
            break
        worlds = [dataclasses.replace(w, name=f"robust-{r}-{i}") for i, w in enumerate(pick)]
        train = train.with_scenarios(list(train.scenarios) + worlds, "train")
        folder = out / f"robust-{r}"
        again = resume and (folder / "checkpoint.json").exists()
        before = result.generations
        result = tune(result.system, train, **{
            **kw, "settings": TunableSettings.from_table(result.system, table)},
            backend=backend, checkpoint=folder, progress=progress, resume=again,
            stop_after=stop_after, judge=False)
        # the round's generations follow the earlier ones, as later stages
        shift = 1 + max((g["stage"] for g in before), default=-1)
        result.generations = before + [dict(g, stage=g["stage"] + shift)
                                       for g in result.generations]
        if not result.finished:
            result.robust = rows
            return result
    if any(row["added"] for row in rows):
        # the job's own start, scored on the final training set and judged on the untouched
        # held-out sets beside the returned system
        result.start = start
        result.verdicts, result.heldout = {}, None
        val = kw.get("validation") if not isinstance(kw.get("validation"), (int, float)) else None
        score_start(result, start, train, val, kw["seed"])
        _judge(result, start, val, kw.get("test"), backend, kw.get("phase"))
    result.robust = rows
    return result
