"""The reward of a chunk of genomes: every (genome, environment, repeat) simulated in lockstep.

Each control cycle is one batched fuzzy evaluation for all robots of the chunk
(:class:`hybridnav.fuzzy.family.SystemFamily`), one batched nearest-obstacle query over all
environments (:class:`hybridnav.planners.field.worldstack.WorldStack`) and one batched model step
(:func:`hybridnav.planners.field.lockstep.lockstep_field`) — no Python loop per individual, per
environment or per step.

Cost of one run (``reward.kind``):

``"deploy"`` (default; minimized)
    reached: ``length * L / D + time * T v / D + clearance * max(0, 1 - c / s)``, with ``L``
    the path length, ``T`` the time to goal, ``v`` the planner speed, ``D`` the start-goal
    distance less the goal radius, ``c`` the run's minimum clearance (footprint to obstacle)
    and ``s = safety_distance`` robot radii; collided or out of bounds: ``collision``; stuck or
    timeout: ``failure + progress * min(1, d_end / d_start)`` (distance left to the goal).
    The fitness is the **mean** over environments (each averaged over ``repeats``) plus the
    coverage penalty.
``"length"``
    the path length when the target is reached, else ``penalty``; summed, minimized.
``"paper"``
    the EFFC paper's literal convention: the distance on success, ``-penalty`` on failure,
    summed and maximized. (The paper says the GA maximizes this while wanting short paths, which
    contradicts itself: maximizing rewards long detours. It is here so that its effect can be
    seen.)

**Coverage.** A system must not rely on the "no rule fired" ``default``: the fraction of a
``coverage.grid``-per-axis grid over the input ranges where no rule fires is measured for every
genome; the fitness is worsened by ``coverage.penalty * excess``, the excess of that fraction over
``coverage.max_uncovered`` (with the default 100, one per cent uncovered costs as much as a
whole path), which gives the GA a slope towards covering systems. The validation selection is
strict: a candidate above ``max_uncovered`` is never chosen over one within it.

**Noise.** With ``heading_noise``, ``dtheta_noise`` or ``alpha_noise`` > 0, every cycle the
commanded heading is rotated by ``N(0, heading_noise)``, ``dtheta`` gets ``N(0, dtheta_noise)``
added and ``alpha`` is scaled by ``1 + N(0, alpha_noise)`` (clipped at 0) — the EFFC paper's
sensor uncertainty — each run drawing from
``SeedSequence(seed, spawn_key=(generation, individual, environment, repeat))``: results do not
depend on how the population is chunked or where the chunks run. Validation runs use one fixed
stream per (environment, repeat), the same for every candidate, so that validation scores are
comparable across generations.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav.fuzzy.family import SystemFamily
from hybridnav.planners.field.effc import effc_force, effc_inputs_from
from hybridnav.planners.field.lockstep import LockstepResult, lockstep_field
from hybridnav.planners.field.worldstack import WorldStack

__all__ = ["VALIDATION_KEY", "evaluate_chunk", "lockstep_effc", "run_costs", "scenario_set",
           "simulate_genomes", "simulate_on"]

#: First spawn-key entry of the validation noise streams (training uses the generation there).
VALIDATION_KEY = 2**31 - 1


@dataclass
class _Set:
    scenarios: list
    stack: WorldStack
    radius: np.ndarray           # robot radius per environment


@functools.lru_cache(maxsize=4)
def _context(job_json: str):
    """Per-process cache: the job, its genome space, system family and packed scenario sets."""
    from hybridnav.tuner.genome import GenomeSpace
    from hybridnav.tuner.job import validate_job

    raw = json.loads(job_json)
    job = validate_job(raw["data"], raw["source"], Path(raw["base"]))
    template = job.start_system()
    space = GenomeSpace(template, job["free"])
    family = SystemFamily(template)
    return job, space, family, {}


def _set(job_json: str, which: str) -> _Set:
    """A scenario set: ``train``, ``validation``, ``test``, or for k-fold ``train-f{j}`` (the
    training worlds outside fold ``j``) and ``fold{j}``."""
    job, _, _, sets = _context(job_json)
    if which not in sets:
        if which.startswith("train-f") or which.startswith("fold"):
            j = int(which.rsplit("f", 1)[1] if which.startswith("train-f") else which[4:])
            folds = job.folds()
            scen = [s for f, s in zip(folds, job.scenarios("train")) if (f == j)
                    == which.startswith("fold")]
        else:
            scen = job.scenarios(which)
        sets[which] = scenario_set(scen)
    return sets[which]


def _noise(job, E: int, keys: list[tuple[int, int]], repeats: int, steps: int):
    """Per (environment, member * repeats) noise arrays ``(3, E, K*R, steps)``, or None."""
    rw = job["reward"]
    sig = np.array([rw["heading_noise"], rw["dtheta_noise"], rw["alpha_noise"]])
    if not np.any(sig > 0):
        return None
    out = np.empty((3, E, len(keys) * repeats, steps))
    for e in range(E):
        for k, (a, b) in enumerate(keys):
            for r in range(repeats):
                ss = np.random.SeedSequence(job.seed, spawn_key=(a, b, e, r))
                out[:, e, k * repeats + r] = (np.random.default_rng(ss).normal(0.0, 1.0, (3, steps))
                                              * sig[:, None])
    return out


def simulate_genomes(job_json: str, which: str, genomes: np.ndarray,
                     keys: list[tuple[int, int]] | None = None, *, noise: bool = True,
                     record_paths: bool = False) -> tuple[LockstepResult, int]:
    """Simulate every genome on every scenario of a set (``repeats`` times with noise).

    Parameters
    ----------
    job_json : str
        The job as JSON (see :func:`evaluate_chunk`).
    which : {"train", "validation", "test"}
        The set (its scenarios must share one robot model).
    genomes : ndarray, shape (K, genes)
    keys : list of (int, int), optional
        Per genome the first two spawn-key entries of its noise streams; default
        ``(VALIDATION_KEY, 0)`` for all (common random numbers).
    noise : bool
        False: the nominal runs (one repeat, no noise).
    record_paths : bool
        Also record every robot's positions (see
        :func:`hybridnav.planners.field.lockstep.lockstep_field`).

    Returns
    -------
    (LockstepResult, repeats)
        Arrays of shape ``(E, K * repeats)``, member ``k * repeats + r``.
    """
    return simulate_on(job_json, _set(job_json, which), genomes, keys, noise=noise,
                       record_paths=record_paths)


def scenario_set(scenarios) -> _Set:
    """Scenarios packed for :func:`simulate_on` (one robot model for all)."""
    return _Set(list(scenarios), WorldStack([s.world for s in scenarios]),
                np.array([s.robots[0].radius for s in scenarios]))


def simulate_on(job_json: str, st: _Set, genomes: np.ndarray,
                keys: list[tuple[int, int]] | None = None, *, noise: bool = True,
                record_paths: bool = False) -> tuple[LockstepResult, int]:
    """:func:`simulate_genomes` on any packed scenario set (:func:`scenario_set`)."""
    job, space, family, _ = _context(job_json)
    genomes = np.atleast_2d(np.asarray(genomes, dtype=float))
    K = len(genomes)
    rw, pl = job["reward"], job["planner"]
    repeats = rw["repeats"] if noise else 1
    inp, out, weights, cons, _ = space.arrays(genomes)
    tables = family.tables(inp, out, weights, cons)
    scenarios = st.scenarios
    E = len(scenarios)
    dt = scenarios[0].dt
    steps = int(math.ceil(max(s.max_time for s in scenarios) / dt - 1e-9)) + 1
    keys = keys if keys is not None else [(VALIDATION_KEY, 0)] * K
    nz = _noise(job, E, keys, repeats, steps) if noise else None
    res = lockstep_effc(st, family, tables, K * repeats, pl, repeats=repeats, noise=nz,
                        record_paths=record_paths)
    return res, repeats


def lockstep_effc(st: _Set, family: SystemFamily, tables, n_members: int,
                  planner: dict[str, Any], *, repeats: int = 1, noise: np.ndarray | None = None,
                  record_paths: bool = False) -> LockstepResult:
    """``n_members`` EFFC controllers on every world of ``st``, in one lockstep batch.

    Member ``m`` uses the fuzzy system ``m // repeats`` of ``tables`` (a ``family`` table set);
    ``noise`` (``(3, E, n_members, steps)``: heading, ``dtheta``, relative ``alpha``) perturbs
    each cycle. ``planner`` holds ``speed``, ``max_turn``, ``stuck_window`` and
    ``stuck_radius``. Without noise this is exactly what the ``effc`` planner does, run by run.
    """
    scenarios = st.scenarios
    dt = scenarios[0].dt
    radius = st.radius
    last = None if noise is None else noise.shape[3] - 1

    def field(env, members, P, goals, t):
        clear, near = st.stack.nearest(P, env, t)
        dtheta, alpha, f_att, f_rep = effc_inputs_from(P, goals, clear, near, radius[env])
        if noise is not None:
            i = min(int(round(t / dt)), last)
            dtheta = dtheta + noise[1, env, members, i]
            alpha = np.maximum(alpha * (1.0 + noise[2, env, members, i]), 0.0)
        w = family.evaluate(tables, members // repeats, {"dtheta": dtheta, "alpha": alpha})
        F = effc_force(w, f_att, f_rep)
        F = np.where(np.isinf(clear)[:, None], f_att, F)     # no obstacle: go to the goal
        if noise is not None:
            ang = noise[0, env, members, i]
            c, s_ = np.cos(ang), np.sin(ang)
            F = np.stack([c * F[:, 0] - s_ * F[:, 1], s_ * F[:, 0] + c * F[:, 1]], axis=1)
        return F

    overrides = {"controller": "heading", "speed": planner["speed"],
                 "max_turn": planner["max_turn"]}
    return lockstep_field(scenarios, n_members, field, model_overrides=overrides,
                          speed=planner["speed"], stuck_window=planner["stuck_window"],
                          stuck_radius=planner["stuck_radius"], record_paths=record_paths,
                          stack=st.stack)


def run_costs(job, scenarios, res: LockstepResult) -> np.ndarray:
    """The cost (reward) of every run, ``(E, M)``, by ``reward.kind``."""
    rw = job["reward"]
    outcome = res.outcome
    reached = outcome == "reached"
    if rw["kind"] == "length":
        return np.where(reached, res.path_length, rw["penalty"])
    if rw["kind"] == "paper":
        return np.where(reached, res.path_length, -rw["penalty"])
    start = np.array([s.robots[0].start for s in scenarios], dtype=float)
    goal = np.array([s.robots[0].goal for s in scenarios], dtype=float)
    goal_r = np.array([s.robots[0].goal_radius for s in scenarios])
    radius = np.array([s.robots[0].radius for s in scenarios])
    d0 = np.hypot(*(goal - start).T)
    D = np.maximum(d0 - goal_r, goal_r)[:, None]
    ok = (rw["length"] * res.path_length / D
          + rw["time"] * np.nan_to_num(res.time) * job["planner"]["speed"] / D)
    safety = rw["safety_distance"] * radius[:, None]
    if rw["clearance"] > 0 and np.any(safety > 0):
        short = np.clip(1.0 - res.min_clearance / np.where(safety > 0, safety, 1.0), 0.0, 1.0)
        ok = ok + rw["clearance"] * np.where(safety > 0, short, 0.0)
    crash = (outcome == "collided") | (outcome == "out_of_bounds")
    left = np.minimum(1.0, res.final_distance / np.maximum(d0, 1e-12)[:, None])
    fail = rw["failure"] + rw["progress"] * left
    return np.where(reached, ok, np.where(crash, rw["collision"], fail))


def uncovered_fraction(job_json: str, genomes: np.ndarray) -> np.ndarray:
    """Per genome, the fraction of the input grid where no rule fires."""
    job, space, family, _ = _context(job_json)
    inp, out, weights, cons, _ = space.arrays(np.atleast_2d(genomes))
    return family.uncovered(family.tables(inp, out, weights, cons), job["coverage"]["grid"])


def evaluate_chunk(job_json: str, genomes: np.ndarray, generation: int,
                   indices: list[int], which: str = "train") -> list[dict[str, Any]]:
    """Rewards and per-environment records of the genomes of one chunk.

    Parameters
    ----------
    job_json : str
        The job (``Job`` as JSON with its source and base folder), so any worker can rebuild it.
    genomes : ndarray, shape (k, genes)
    generation : int
        The generation these evaluations belong to (seeds the training noise).
    indices : list of int
        Each genome's index in its generation (seeds the training noise).
    which : {"train", "validation"}
        The set; validation runs share one noise stream per environment and repeat.

    Returns
    -------
    list of dict
        Per genome: ``fitness``, ``cost`` (without the coverage penalty), ``uncovered`` and
        ``envs`` (scenario, outcome, reached fraction, length, time, clearance, reward per
        environment).
    """
    job, _, _, _ = _context(job_json)
    genomes = np.atleast_2d(np.asarray(genomes, dtype=float))
    K = len(genomes)
    keys = [(generation, i) for i in indices] if which.startswith("train") else None
    res, repeats = simulate_genomes(job_json, which, genomes, keys)
    scenarios = _set(job_json, which).scenarios
    E = len(scenarios)
    cost = run_costs(job, scenarios, res).reshape(E, K, repeats).mean(axis=2)     # (E, K)
    kind = job["reward"]["kind"]
    total = cost.mean(axis=0) if kind == "deploy" else cost.sum(axis=0)
    cov = job["coverage"]
    unc = uncovered_fraction(job_json, genomes)
    pen = cov["penalty"] * np.maximum(unc - cov["max_uncovered"], 0.0)
    fitness = total - pen if kind == "paper" else total + pen
    reached = (res.outcome == "reached").reshape(E, K, repeats)
    out_records = []
    for k in range(K):
        envs = []
        for e, s in enumerate(scenarios):
            cols = slice(k * repeats, (k + 1) * repeats)
            envs.append({
                "scenario": s.name,
                "outcome": str(res.outcome[e, k * repeats]),
                "reached": float(np.mean(reached[e, k])),
                "length": float(np.mean(res.path_length[e, cols])),
                "time": float(np.mean(res.time[e, cols])),
                "clearance": float(np.min(res.min_clearance[e, cols])),
                "reward": float(cost[e, k]),
            })
        out_records.append({"fitness": float(fitness[k]), "cost": float(total[k]),
                            "uncovered": float(unc[k]), "envs": envs})
    return out_records
