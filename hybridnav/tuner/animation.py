"""Animations of tuning jobs: generation by generation, the best system of that generation
driving on one of the job's worlds (what ``hybridnav animate TUNE_DIR`` writes).

A navigation job's folder holds ``generations.json`` (:func:`hybridnav.tuner.write_generations`):
the best system of the carried population after each generation (the logbook's ``min``), the
job's planner and its settings and the job's world sets. :func:`animate_tuning` runs each
distinct system with that planner on the chosen world (a nominal run: no noise) and draws the
runs one after the other with :func:`hybridnav.plotting.animate_runs`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.fileio import check_writable, read_json
from hybridnav.params import short_repr
from hybridnav.plotting.animation import (
    GENERATIONS_FILE,
    Animated,
    _check_settings,
    _format,
    _is_tuning,
    animate_runs,
)
from hybridnav.resultspec import Metric
from hybridnav.tuner.job import load_scenario_set

__all__ = ["animate_tuning", "is_tuning_folder"]

#: a generation's stage and number: whole numbers as the logbook counts them
_COUNT = Metric("count")
#: a generation's score (the logbook's ``min``): a finite number, or null where it had none
_SCORE = Metric("number", null=True)


def is_tuning_folder(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` is one ``hybridnav tune`` wrote (``generations.json``, or its
    checkpoint and logbook).

    Parameters
    ----------
    folder : str or path-like
    """
    return _is_tuning(Path(folder))


def animate_tuning(folder: str | os.PathLike[str], path: str | os.PathLike[str] | None = None,
                   *, world: str | None = None, fps: float = 4.0, dpi: int = 80,
                   max_frames: int = 150, fmt: str | None = None) -> Animated:
    """Write an animation of a tuning job: generation by generation, the best system of that
    generation driving the robots on one of the job's worlds, titled ``generation g: score s``
    (``score``: the training objective, the logbook's ``min``).

    Parameters
    ----------
    folder : str or path-like
        A folder ``hybridnav tune`` wrote for a navigation job (with ``generations.json``).
    path : str or path-like, optional
        The ``.gif`` or ``.mp4`` to write; default ``<folder>/animation.gif``.
    world : str, optional
        The name of one of the job's worlds (default: its first test world, else its first
        validation world, else its first training world).
    fps, dpi, max_frames, fmt :
        As for :func:`hybridnav.plotting.animate` (a generation gets up to 8 frames of its run,
        fewer when there are many generations).

    Returns
    -------
    hybridnav.plotting.Animated

    Raises
    ------
    HybridnavError
        No ``generations.json`` (a job run before hybridnav 0.3.0, or not a navigation job),
        a damaged one (naming the key), a world the job does not have, and what
        :func:`hybridnav.plotting.animate` refuses.
    """
    from hybridnav import planners

    folder = Path(folder)
    if not folder.is_dir():
        raise HybridnavError(f"{folder}: no such folder (expected a folder written by "
                             "'hybridnav tune')")
    path = Path(path) if path is not None else folder / "animation.gif"
    # the settings and the file to write before anything is read or run
    fps, dpi, max_frames = _check_settings(fps, dpi, max_frames)
    fmt = _format(path, fmt)
    check_writable(path)
    gens, systems, planner, params, scenario = _read_generations(folder, world)
    if planner not in planners.PLANNERS:
        raise HybridnavError(f"{folder / GENERATIONS_FILE}: planner: expected one of "
                             f"{', '.join(sorted(planners.PLANNERS))}, got {short_repr(planner)}")
    kfold = len({g["stage"] for g in gens}) > 1
    # each generation's planner made before any runs: its settings come from generations.json,
    # so a refused one is named by the file and its keys (the planner's own message after)
    made: dict[int, Any] = {}
    for g in gens:
        k = g["system"]
        if k not in made:
            try:
                made[k] = planners.get(planner, **{**params, "fis": systems[k]})
            except HybridnavError as exc:
                raise HybridnavError(f"{folder / GENERATIONS_FILE}: planner_params (planner "
                                     f"{short_repr(planner)}, fis systems[{k}]): {exc}") from None
    done: dict[int, Any] = {}
    runs = []
    for g in gens:
        k = g["system"]
        if k not in done:
            done[k] = made[k].run(scenario)
        score = "-" if g.get("score") is None else f"{float(g['score']):.4g}"
        runs.append((f"generation {g['generation']}"
                     + (f" (stage {g['stage']})" if kfold else "") + f": score {score}",
                     done[k]))
    return animate_runs(scenario, runs, path, fps=fps, dpi=dpi, max_frames=max_frames, fmt=fmt)


def _read_generations(folder: Path, world: str | None):
    """The generations, systems, planner, its settings and the world of a tuning folder."""
    from hybridnav import fuzzy

    path = folder / GENERATIONS_FILE
    if not path.is_file():
        raise HybridnavError(f"{path}: no such file: a navigation tuning job run by hybridnav "
                             "0.3.0 or later writes it (its best system per generation); run "
                             "the job again to animate it")
    # strict: a number past Python's digit limit, NaN or 1e999 is refused at its key
    data = read_json(path, "generations file")

    def bad(key: str, what: str, got: Any) -> HybridnavError:
        return HybridnavError(f"{path}: {key}: expected {what}, got {short_repr(got)}")

    if not isinstance(data, dict) or data.get("format") != "hybridnav-generations/1":
        raise bad("format", "'hybridnav-generations/1'",
                  data.get("format") if isinstance(data, dict) else data)
    planner, params = data.get("planner"), data.get("planner_params")
    if not isinstance(planner, str) or not isinstance(params, dict):
        raise bad("planner", "a planner name with its planner_params object", planner)
    sets = data.get("worlds")
    if not isinstance(sets, dict) or not all(isinstance(sets.get(k), list)
                                             for k in ("train", "validation", "test")):
        raise bad("worlds", "an object of train, validation and test lists", sets)
    systems = data.get("systems")
    if not isinstance(systems, list) or not systems:
        raise bad("systems", "a non-empty list of fuzzy systems", systems)
    loaded = []
    for i, d in enumerate(systems):
        try:
            loaded.append(fuzzy.FuzzySystem.from_dict(d))
        except HybridnavError as exc:
            raise HybridnavError(f"{path}: systems[{i}]: {exc}") from None
        except (TypeError, KeyError, ValueError, AttributeError) as exc:
            raise HybridnavError(f"{path}: systems[{i}]: expected a fuzzy system "
                                 f"({type(exc).__name__}: {exc})") from None
    gens = data.get("generations")
    if not isinstance(gens, list) or not gens:
        raise bad("generations", "a non-empty list", gens)
    for i, g in enumerate(gens):
        if not isinstance(g, dict) or not {"stage", "generation", "system"} <= g.keys():
            raise bad(f"generations[{i}]", "an object of stage, generation, system (an index "
                      f"into systems, < {len(loaded)}) and score (a number or null)", g)
        system = g["system"]
        if type(system) is not int or not 0 <= system < len(loaded):
            raise bad(f"generations[{i}].system", f"an index into systems (an integer in [0, "
                      f"{len(loaded) - 1}])", system)
        for key, declared in (("stage", _COUNT), ("generation", _COUNT), ("score", _SCORE)):
            problem = declared.problem(g.get(key))
            if problem:                    # 10**400 or NaN: never formatted below
                raise HybridnavError(f"{path}: generations[{i}].{key}: {problem}")
    base = data.get("base", "")
    if not isinstance(base, str):
        raise bad("base", "the job file's folder", base)
    scenario = None
    names: list[str] = []
    for which in ("test", "validation", "train"):          # item by item: generate no more
        for i, item in enumerate(sets[which]):
            scen = load_scenario_set([item], base or str(folder), f"{path}: worlds.{which}", i)
            names += [s.name for s in scen]
            hit = scen[:1] if world is None else [s for s in scen if s.name == world]
            if hit:
                scenario = hit[0]
                break
        if scenario is not None:
            break
    if scenario is None:
        raise HybridnavError(f"{path}: world: expected the name of one of the job's worlds "
                             f"({short_repr(names, 300)}), got {short_repr(world)}"
                             if world is not None else f"{path}: worlds: the job has no world")
    return gens, loaded, planner, params, scenario
