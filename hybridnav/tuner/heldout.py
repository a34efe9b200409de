"""Judging a tuned system as a user would: start vs tuned vs ``apf`` on worlds tuning never used.

:meth:`hybridnav.tuner.NavigationCost.judge` runs the starting system, the tuned system (both
nominal: no noise) and the plain ``apf`` planner (through the backend) on a set of worlds;
:func:`run_systems` does it for any systems; :func:`summarize` gives per set and system the success rate with a
95 % Wilson interval, the collisions and other failures, and the mean path length and clearance
on the worlds that *every* system reached (so that lengths compare like with like), and
:func:`verdict` checks the acceptance conditions one by one.
"""

from __future__ import annotations

import json
import math
from typing import Any

import pandas as pd

__all__ = ["planner_rows", "run_systems", "summarize", "uniform", "verdict", "wilson"]

COLUMNS = ["set", "scenario", "system", "outcome", "path_length", "time", "min_clearance"]


def _lockstep_rows(which: str, scen, labels, res) -> list[dict[str, Any]]:
    """Rows of a lockstep result whose member ``m`` is the system ``labels[m]``."""
    rows = []
    for e, s in enumerate(scen):
        for m, label in enumerate(labels):
            reached = res.outcome[e, m] == "reached"
            rows.append({"set": which, "scenario": s.name, "system": label,
                         "outcome": str(res.outcome[e, m]),
                         "path_length": float(res.path_length[e, m]),
                         "time": float(res.time[e, m]) if reached else math.nan,
                         "min_clearance": float(res.min_clearance[e, m])})
    return rows


def _robot_row(which: str, scenario: str, label: str, r) -> dict[str, Any]:
    """The row of one robot of a planner's ``Result``."""
    return {"set": which, "scenario": scenario, "system": label, "outcome": r.outcome,
            "path_length": r.path_length,
            "time": math.nan if r.time_to_goal is None else r.time_to_goal,
            "min_clearance": r.min_clearance}


def wilson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval of a success rate ``k / n`` (scipy's ``binomtest``)."""
    if n == 0:
        return (math.nan, math.nan)
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return (float(ci.low), float(ci.high))


def _apf_rows(scenario_json: str, params: dict[str, Any]) -> dict[str, Any]:
    """One ``apf`` run (in whatever process gets the task)."""
    from hybridnav import planners
    from hybridnav.world import scenario_from_dict

    s = scenario_from_dict(json.loads(scenario_json))
    r = planners.get("apf", **params).run(s).robots[0]
    return {"outcome": r.outcome, "path_length": r.path_length, "time": r.time_to_goal,
            "min_clearance": r.min_clearance}


def run_systems(systems: dict[str, Any], scenarios, *, speed: float = 0.1,
                max_turn: float = math.pi / 4, stuck_window: float = 10.0,
                stuck_radius: float = 2.0, apf: bool = True, set_name: str = "test"
                ) -> pd.DataFrame:
    """Rows like :func:`compare_systems` for any fuzzy systems (label -> ``FuzzySystem``) on any
    single-unicycle scenarios of one robot model: each system simulated on all of them in one
    lockstep batch (exactly what the ``effc`` planner does), plus ``apf`` (a lockstep batch too:
    what its planner does)."""
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.tuner.evaluate import lockstep_effc, scenario_set

    scen = list(scenarios)
    st = scenario_set(scen)
    pl = {"speed": speed, "max_turn": max_turn, "stuck_window": stuck_window,
          "stuck_radius": stuck_radius}
    rows = []
    for label, system in systems.items():
        fam = SystemFamily(system)
        res = lockstep_effc(st, fam, fam.tables_of([system]), 1, pl)
        rows += _lockstep_rows(set_name, scen, [label], res)
    if apf:
        from hybridnav.planners.field.apf import apf_lockstep

        rows += _lockstep_rows(set_name, scen, ["apf"], apf_lockstep(st, pl))
    return pd.DataFrame(rows, columns=COLUMNS)


def uniform(scen) -> bool:
    """Whether the lockstep simulation can run these scenarios together (one unicycle robot
    with a goal, one robot model)."""
    keys = {(s.dt, len(s.robots), s.robots[0].model, s.robots[0].goal is None,
             s.robots[0].radius, tuple(sorted(s.robots[0].params.items()))) for s in scen}
    return len(keys) == 1 and next(iter(keys))[1:4] == (1, "unicycle", False)


def planner_rows(which: str, scen, systems: dict[str, Any], planner: str,
                 params: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of the planner run by run (scenarios the lockstep simulation cannot batch)."""
    from hybridnav import planners

    rows = []
    for s in scen:
        for label, system in systems.items():
            p = planners.get(planner, fis=system, **params)
            rows += [_robot_row(which, s.name, label, r) for r in p.run(s).robots]
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
