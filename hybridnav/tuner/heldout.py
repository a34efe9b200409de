"""Judging a tuned system as a user would: start vs tuned vs ``apf`` on worlds tuning never used.

:func:`compare_systems` runs the starting system, the tuned system (both nominal: no noise, in
one lockstep batch per set) and the plain ``apf`` planner (through the backend) on the job's
validation and test sets; :func:`summarize` gives per set and system the success rate with a
95 % Wilson interval, the collisions and other failures, and the mean path length and clearance
on the worlds that *every* system reached (so that lengths compare like with like), and
:func:`verdict` checks the acceptance conditions one by one.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["compare_systems", "run_systems", "summarize", "verdict", "wilson"]

SYSTEMS = ("start", "tuned", "apf")


def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95 % Wilson score interval of a success rate ``k / n``."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def _apf_rows(scenario_json: str, params: dict[str, Any]) -> dict[str, Any]:
    """One ``apf`` run (in whatever process gets the task)."""
    from hybridnav import planners
    from hybridnav.world import scenario_from_dict

    s = scenario_from_dict(json.loads(scenario_json))
    r = planners.get("apf", **params).run(s).robots[0]
    return {"outcome": r.outcome, "path_length": r.path_length, "time": r.time_to_goal,
            "min_clearance": r.min_clearance}


def compare_systems(job, job_json: str, genomes: dict[str, np.ndarray], backend,
                    sets: tuple[str, ...] = ("validation", "test")) -> pd.DataFrame:
    """One row per (set, scenario, system): outcome, path length, time, minimum clearance.

    ``genomes`` maps system labels (``start``, ``tuned``) to genomes of the job's genome space;
    ``apf`` runs with the job's planner speed and turn limit.
    """
    from hybridnav.tuner.evaluate import simulate_genomes
    from hybridnav.world import scenario_to_dict

    rows = []
    labels = list(genomes)
    pl = job["planner"]
    apf_params = {"speed": pl["speed"], "max_turn": pl["max_turn"],
                  "stuck_window": pl["stuck_window"], "stuck_radius": pl["stuck_radius"]}
    for which in sets:
        scen = job.scenarios(which)
        if not scen:
            continue
        G = np.array([genomes[k] for k in labels])
        if _uniform(scen):
            res, _ = simulate_genomes(job_json, which, G, noise=False)
            for e, s in enumerate(scen):
                for m, label in enumerate(labels):
                    reached = res.outcome[e, m] == "reached"
                    rows.append({"set": which, "scenario": s.name, "system": label,
                                 "outcome": str(res.outcome[e, m]),
                                 "path_length": float(res.path_length[e, m]),
                                 "time": float(res.time[e, m]) if reached else math.nan,
                                 "min_clearance": float(res.min_clearance[e, m])})
        else:                               # robots of different models: one run at a time
            rows += _planner_runs(job, which, scen, genomes)
        args = [(json.dumps(scenario_to_dict(s)), apf_params) for s in scen]
        for s, r in zip(scen, backend.map(_apf_rows, args)):
            rows.append({"set": which, "scenario": s.name, "system": "apf", **r,
                         "time": math.nan if r["time"] is None else r["time"]})
    return pd.DataFrame(rows, columns=["set", "scenario", "system", "outcome", "path_length",
                                       "time", "min_clearance"])


def run_systems(systems: dict[str, Any], scenarios, *, speed: float = 0.1,
                max_turn: float = math.pi / 4, stuck_window: float = 10.0,
                stuck_radius: float = 2.0, apf: bool = True, set_name: str = "test"
                ) -> pd.DataFrame:
    """Rows like :func:`compare_systems` for any fuzzy systems (label -> ``FuzzySystem``) on any
    single-unicycle scenarios of one robot model: each system simulated on all of them in one
    lockstep batch (exactly what the ``effc`` planner does), plus ``apf`` run by its planner."""
    from hybridnav import planners
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.planners.effc import effc_force, effc_inputs_from
    from hybridnav.planners.lockstep import lockstep_field
    from hybridnav.planners.worldstack import WorldStack

    scen = list(scenarios)
    stack = WorldStack([s.world for s in scen])
    radius = np.array([s.robots[0].radius for s in scen])
    rows = []
    for label, system in systems.items():
        fam = SystemFamily(system)
        tables = fam.tables_of([system])

        def field(env, members, P, goals, t):
            clear, near = stack.nearest(P, env, t)
            d, a, fa, fr = effc_inputs_from(P, goals, clear, near, radius[env])
            F = effc_force(fam.evaluate(tables, members, {"dtheta": d, "alpha": a}), fa, fr)
            return np.where(np.isinf(clear)[:, None], fa, F)

        res = lockstep_field(scen, 1, field, model_overrides={
            "controller": "heading", "speed": speed, "max_turn": max_turn}, speed=speed,
            stuck_window=stuck_window, stuck_radius=stuck_radius, stack=stack)
        for e, s in enumerate(scen):
            ok = res.outcome[e, 0] == "reached"
            rows.append({"set": set_name, "scenario": s.name, "system": label,
                         "outcome": str(res.outcome[e, 0]),
                         "path_length": float(res.path_length[e, 0]),
                         "time": float(res.time[e, 0]) if ok else math.nan,
                         "min_clearance": float(res.min_clearance[e, 0])})
    if apf:
        p = planners.get("apf", speed=speed, max_turn=max_turn, stuck_window=stuck_window,
                         stuck_radius=stuck_radius)
        for s in scen:
            r = p.run(s).robots[0]
            rows.append({"set": set_name, "scenario": s.name, "system": "apf",
                         "outcome": r.outcome, "path_length": r.path_length,
                         "time": math.nan if r.time_to_goal is None else r.time_to_goal,
                         "min_clearance": r.min_clearance})
    return pd.DataFrame(rows, columns=["set", "scenario", "system", "outcome", "path_length",
                                       "time", "min_clearance"])


def _uniform(scen) -> bool:
    keys = {(s.dt, len(s.robots), s.robots[0].model, s.robots[0].goal is None,
             s.robots[0].radius, tuple(sorted(s.robots[0].params.items()))) for s in scen}
    return len(keys) == 1 and next(iter(keys))[1:4] == (1, "unicycle", False)


def _planner_runs(job, which, scen, genomes):
    from hybridnav import planners
    from hybridnav.tuner.genome import GenomeSpace

    space = GenomeSpace(job.start_system(), job["free"])
    pl = job["planner"]
    rows = []
    for s in scen:
        for label, g in genomes.items():
            p = planners.get("effc", fis=space.system(np.asarray(g)), speed=pl["speed"],
                             max_turn=pl["max_turn"], stuck_window=pl["stuck_window"],
                             stuck_radius=pl["stuck_radius"])
            for r in p.run(s).robots:
                rows.append({"set": which, "scenario": s.name, "system": label,
                             "outcome": r.outcome, "path_length": r.path_length,
                             "time": math.nan if r.time_to_goal is None else r.time_to_goal,
                             "min_clearance": r.min_clearance})
    return rows


def summarize(table: pd.DataFrame) -> pd.DataFrame:
    """Per set and system: worlds, reached (rate, 95 % interval), failures by kind, and the mean
    length and clearance over the worlds every system reached; the smallest clearance over the
    worlds the system itself reached."""
    out = []
    for which, g in table.groupby("set", sort=False):
        ok = g[g.outcome == "reached"]
        systems = list(dict.fromkeys(g.system))
        common = set.intersection(*[set(ok[ok.system == s].scenario) for s in systems]) \
            if systems else set()
        for s in systems:
            h = g[g.system == s]
            n, k = len(h), int((h.outcome == "reached").sum())
            lo, hi = wilson(k, n)
            c = h[h.scenario.isin(common)]
            mine = h[h.outcome == "reached"]
            out.append({
                "set": which, "system": s, "worlds": n, "reached": k,
                "success_rate": k / n if n else math.nan, "ci_low": lo, "ci_high": hi,
                "collided": int((h.outcome == "collided").sum()),
                "out_of_bounds": int((h.outcome == "out_of_bounds").sum()),
                "stuck": int((h.outcome == "stuck").sum()),
                "timeout": int((h.outcome == "timeout").sum()),
                "common_worlds": len(common),
                "common_length": float(c.path_length.mean()) if len(c) else math.nan,
                "common_clearance": float(c.min_clearance.mean()) if len(c) else math.nan,
                "min_clearance_reached": float(mine.min_clearance.min()) if len(mine)
                else math.nan,
            })
    return pd.DataFrame(out)


def verdict(summary: pd.DataFrame, which: str, robot_radius: float) -> dict[str, Any]:
    """The acceptance checks of the tuned system on one set.

    Returns
    -------
    dict
        ``checks``: list of (description, passed); ``better``: all passed.
    """
    s = summary[summary.set == which].set_index("system")
    if not {"start", "tuned"} <= set(s.index):
        return {"checks": [], "better": False}
    t, st = s.loc["tuned"], s.loc["start"]
    checks = [
        (f"reaches at least as many worlds as its start ({t.reached} vs {st.reached})",
         bool(t.reached >= st.reached)),
        (f"collides no more often than its start ({t.collided} vs {st.collided})",
         bool(t.collided <= st.collided)),
        (f"is shorter on the {int(t.common_worlds)} worlds all systems reached "
         f"({t.common_length:.3f} vs {st.common_length:.3f})",
         bool(t.common_length < st.common_length)),
        (f"keeps at least half the robot radius ({robot_radius / 2:g}) from obstacles on every "
         f"world it reaches (smallest {t.min_clearance_reached:.3f})",
         bool(t.min_clearance_reached >= robot_radius / 2)),
    ]
    if "apf" in s.index:
        a = s.loc["apf"]
        checks.insert(1, (f"reaches at least as many worlds as apf ({t.reached} vs "
                          f"{a.reached})", bool(t.reached >= a.reached)))
    return {"checks": checks, "better": all(ok for _, ok in checks)}
