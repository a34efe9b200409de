"""The reward of a chunk of genomes: every (genome, environment, repeat) simulated in lockstep.

Each control cycle is one batched fuzzy evaluation for all robots of the chunk
(:class:`hybridnav.fuzzy.family.SystemFamily`) and one batched model step
(:func:`hybridnav.planners.lockstep.lockstep_field`) — no Python loop per individual per step.

Reward per environment (``reward.sense``):

``"minimize"`` (default)
    the travelled distance if the robot reaches the target (no collision, inside the workspace),
    else ``penalty``; summed over the environments and minimized.
``"maximize"``
    the EFFC paper's literal convention: the distance on success, ``-penalty`` on failure,
    summed and maximized. (The paper says the GA maximizes this while wanting short paths, which
    contradicts itself: maximizing rewards long detours. It is here so that its effect can be
    seen; ``minimize`` is the consistent reading.)

With ``heading_noise > 0`` the commanded heading of every robot is perturbed each cycle by
Gaussian noise whose generator is ``SeedSequence(seed, spawn_key=(generation, individual,
environment, repeat))`` — so results do not depend on how the population is chunked or where the
chunks run — and each environment's reward is averaged over ``repeats`` simulations.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from hybridnav.fuzzy.family import SystemFamily
from hybridnav.planners.effc import effc_force, effc_inputs
from hybridnav.planners.lockstep import lockstep_field

__all__ = ["evaluate_chunk"]


@functools.lru_cache(maxsize=4)
def _context(job_json: str):
    """Per-process cache: the job, its scenarios, genome space and system family."""
    import json

    from hybridnav.tuner.genome import GenomeSpace
    from hybridnav.tuner.job import validate_job

    raw = json.loads(job_json)
    job = validate_job(raw["data"], raw["source"], __import__("pathlib").Path(raw["base"]))
    template = job.start_system()
    space = GenomeSpace(template, job["free"])
    family = SystemFamily(template)
    scenarios = job.scenarios("train")
    return job, space, family, scenarios


def evaluate_chunk(job_json: str, genomes: np.ndarray, generation: int,
                   indices: list[int]) -> list[dict[str, Any]]:
    """Rewards and per-environment records of the genomes of one chunk.

    Parameters
    ----------
    job_json : str
        The job (``Job`` as JSON with its source and base folder), so any worker can rebuild it.
    genomes : ndarray, shape (k, genes)
    generation : int
        The generation these evaluations belong to (seeds the noise).
    indices : list of int
        Each genome's index in its generation (seeds the noise).

    Returns
    -------
    list of dict
        Per genome: ``fitness`` and ``envs`` (scenario, outcome, reached fraction, length, time,
        reward per environment).
    """
    job, space, family, scenarios = _context(job_json)
    genomes = np.atleast_2d(np.asarray(genomes, dtype=float))
    K = len(genomes)
    rw, pl = job["reward"], job["planner"]
    repeats = rw["repeats"]
    inp, out, weights, cons, _ = space.arrays(genomes)
    tables = family.tables(inp, out, weights, cons)
    E = len(scenarios)
    radius = np.array([s.model(s.robots[0]).radius for s in scenarios])
    dt = scenarios[0].dt
    steps = int(math.ceil(max(s.max_time for s in scenarios) / dt - 1e-9)) + 1
    noise = None
    if rw["heading_noise"] > 0:
        # one stream per (generation, individual, environment, repeat), drawn once per chunk
        noise = np.empty((E, K * repeats, steps))
        for e in range(E):
            for k in range(K):
                for r in range(repeats):
                    ss = np.random.SeedSequence(job.seed, spawn_key=(generation, indices[k], e, r))
                    noise[e, k * repeats + r] = np.random.default_rng(ss).normal(
                        0.0, rw["heading_noise"], steps)

    def field(env, members, P, goals, t):
        n = len(members)
        dtheta, alpha = np.empty(n), np.empty(n)
        f_att, f_rep = np.empty((n, 2)), np.empty((n, 2))
        for e in np.unique(env):
            sel = env == e
            d, a, fa, fr = effc_inputs(scenarios[e].world, P[sel], goals[sel], radius[e], t)
            dtheta[sel], alpha[sel], f_att[sel], f_rep[sel] = d, a, fa, fr
        w = family.evaluate(tables, members // repeats, {"dtheta": dtheta, "alpha": alpha})
        F = effc_force(w, f_att, f_rep)
        if noise is not None:
            ang = noise[env, members, min(int(round(t / dt)), steps - 1)]
            c, s_ = np.cos(ang), np.sin(ang)
            F = np.stack([c * F[:, 0] - s_ * F[:, 1], s_ * F[:, 0] + c * F[:, 1]], axis=1)
        return F

    overrides = {"controller": "heading", "speed": pl["speed"], "max_turn": pl["max_turn"]}
    res = lockstep_field(scenarios, K * repeats, field, model_overrides=overrides,
                         speed=pl["speed"], stuck_window=pl["stuck_window"],
                         stuck_radius=pl["stuck_radius"])
    reached = res.outcome == "reached"                            # (E, K * repeats)
    length = res.path_length
    if rw["sense"] == "minimize":
        reward = np.where(reached, length, rw["penalty"])
    else:
        reward = np.where(reached, length, -rw["penalty"])
    shape = (E, K, repeats)
    reward = reward.reshape(shape).mean(axis=2)                   # (E, K)
    out_records = []
    for k in range(K):
        envs = []
        for e, s in enumerate(scenarios):
            cols = slice(k * repeats, (k + 1) * repeats)
            envs.append({
                "scenario": s.name,
                "outcome": str(res.outcome[e, k * repeats]),
                "reached": float(np.mean(reached[e, cols])),
                "length": float(np.mean(length[e, cols])),
                "time": float(np.mean(res.time[e, cols])),
                "reward": float(reward[e, k]),
            })
        out_records.append({"fitness": float(reward[:, k].sum()), "envs": envs})
    return out_records
