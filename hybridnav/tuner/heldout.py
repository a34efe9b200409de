"""Judging a tuned system as a user would: start vs tuned vs ``apf`` on worlds tuning never used.

:meth:`hybridnav.tuner.NavigationCost.judge` runs the starting system, the tuned system (both
nominal: no noise) and the plain ``apf`` planner (through the backend) on a set of worlds;
:func:`run_systems` does it for any systems; :func:`summarize` gives per set and system the success rate with a
95 % Wilson interval, the collisions and other failures, and the mean path length and clearance
on the worlds that *every* system reached (so that lengths compare like with like), and
:func:`verdict` weighs the tuned system against its start and against ``apf``: safety first
(collisions, clearance, the falsification search's collision rate), then success, then length.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["baseline", "planner_rows", "run_systems", "summarize", "uniform", "verdict",
           "wilson"]

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


def baseline(params: dict[str, Any]) -> dict[str, Any]:
    """The ``apf`` baseline's settings from a tuned controller's planner settings: the same
    speed, turn limit and stuck test, but plain ``apf`` as a user runs it — the safety filter
    (``safety_margin``) is the tuned controller's own and is not lent to the baseline."""
    return {k: v for k, v in params.items() if k != "safety_margin"}


def _apf_rows(scenario_json: str, params: dict[str, Any]) -> list[dict[str, Any]]:
    """One ``apf`` run (in whatever process gets the task): a row per robot, as the fuzzy
    systems' runs have (:func:`planner_rows`), so that multi-robot worlds count alike."""
    from hybridnav import planners
    from hybridnav.world import scenario_from_dict

    s = scenario_from_dict(json.loads(scenario_json))
    return [{"outcome": r.outcome, "path_length": r.path_length,
             "time": math.nan if r.time_to_goal is None else r.time_to_goal,
             "min_clearance": r.min_clearance}
            for r in planners.get("apf", **baseline(params)).run(s).robots]


def run_systems(systems: dict[str, Any], scenarios, *, speed: float = 0.1,
                max_turn: float = math.pi / 4, stuck_window: float = 10.0,
                stuck_radius: float = 2.0, apf: bool = True, set_name: str = "test",
                safety_margin: float = 0.0) -> pd.DataFrame:
    """Rows like :func:`compare_systems` for any fuzzy systems (label -> ``FuzzySystem``) on any
    single-unicycle scenarios of one robot model: each system simulated on all of them in one
    lockstep batch (exactly what the ``effc`` planner does, with ``safety_margin`` its safety
    filter), plus plain ``apf`` (a lockstep batch too: what its planner does)."""
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.tuner.evaluate import lockstep_effc, scenario_set

    scen = list(scenarios)
    st = scenario_set(scen)
    pl = {"speed": speed, "max_turn": max_turn, "stuck_window": stuck_window,
          "stuck_radius": stuck_radius, "safety_margin": safety_margin}
    rows = []
    for label, system in systems.items():
        fam = SystemFamily(system)
        res = lockstep_effc(st, fam, fam.tables_of([system]), 1, pl)
        rows += _lockstep_rows(set_name, scen, [label], res)
    if apf:
        from hybridnav.planners.field.apf import apf_lockstep

        rows += _lockstep_rows(set_name, scen, ["apf"], apf_lockstep(st, baseline(pl)))
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
                # NaN on a reached world (an unknown clearance) makes the smallest unknown
                "min_clearance_reached": float(mine.min_clearance.min(skipna=False))
                if len(mine) else math.nan,
                "common_min_clearance": float(c.min_clearance.min(skipna=False))
                if len(c) else math.nan,
            })
    return pd.DataFrame(out)


def _paired(table: pd.DataFrame | None, a: str, b: str, worlds: set) -> str:
    """' (a - b per world: mean m, 95 % interval lo to hi)' of the clearance on ``worlds``."""
    if table is None or len(worlds) < 2:
        return ""
    from scipy import stats

    t = table[table.scenario.isin(worlds)].pivot_table(index="scenario", columns="system",
                                                       values="min_clearance", aggfunc="min")
    d = (t[a] - t[b]).to_numpy(dtype=float)
    d = d[np.isfinite(d)]                    # a world without obstacles has no clearance
    if len(d) < 2:
        return ""
    m, se = float(d.mean()), float(d.std(ddof=1) / math.sqrt(len(d)))
    lo, hi = (m, m) if se == 0 else stats.t.interval(0.95, len(d) - 1, loc=m, scale=se)
    return f"; per world {a} - {b}: mean {m:+.3f} m, 95 % interval {lo:+.3f} to {hi:+.3f}"


def _count(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"{k} of {n} ({100 * lo:.0f}-{100 * hi:.0f} %)"


def verdict(summary: pd.DataFrame, which: str, robot_radius: float,
            falsified: pd.DataFrame | None = None, table: pd.DataFrame | None = None
            ) -> dict[str, Any]:
    """Whether the tuned system can replace ``apf`` and its start, figure by figure.

    Safety figures come first and each is compared with ``apf`` and with the start: collisions
    (and leaving the workspace) on the set's worlds, the smallest clearance on the worlds every
    system reached (like with like), and — when ``falsified`` (:func:`hybridnav.tuner.falsify.
    rates` of searches with the same budget and seed) is given — the rate of collisions an
    adversarial search finds. Then success (reached worlds), then path length against the start.
    Counts carry 95 % Wilson intervals; the clearance comparison the per-world difference's
    mean and t-interval (``table``: the judged rows, optional).

    Returns
    -------
    dict
        ``checks``: list of (description, passed), safety first; ``safe``: no safety figure is
        worse than apf's (True without apf only if none is worse than the start's);
        ``better_than_start``: every comparison with the start passed; ``better``: ready to
        deploy — safe, reaches at least as many worlds as apf, and better than its start;
        ``headline``: the conclusion in words, naming the figures.
    """
    if "set" not in summary or "system" not in summary:       # an empty summary
        return {"checks": [], "better": False, "safe": False, "better_than_start": False,
                "headline": ""}
    s = summary[summary.set == which].set_index("system")
    if not {"start", "tuned"} <= set(s.index):
        return {"checks": [], "better": False, "safe": False, "better_than_start": False,
                "headline": ""}
    t = s.loc["tuned"]
    others = [o for o in ("apf", "start") if o in s.index]
    n = int(t.worlds)
    crash = {k: int(s.loc[k, "collided"] + s.loc[k, "out_of_bounds"]) for k in s.index}
    common = int(t.common_worlds)
    worlds = set(table[table.outcome == "reached"].groupby("scenario").system.nunique()
                 .loc[lambda c: c == len(s)].index) if table is not None else set()
    checks: list[tuple[str, bool]] = []
    kind: dict[str, list[str]] = {o: [] for o in others}      # failed figures per comparator

    def add(text: str, ok: bool, against: str, figure: str) -> None:
        checks.append((text, ok))
        if not ok:
            kind[against].append(figure)

    for o in others:
        name = "apf" if o == "apf" else "its start"
        add(f"collides or leaves the workspace in {_count(crash['tuned'], n)} {which} worlds; "
            f"{name} in {_count(crash[o], n)}", crash["tuned"] <= crash[o], o, "collisions")
    for o in others:
        name = "apf" if o == "apf" else "its start"
        a, b = float(t.common_min_clearance), float(s.loc[o, "common_min_clearance"])
        if common == 0:
            continue
        add(f"smallest clearance on the {common} worlds every system reached {a:.3f} m; "
            f"{name} {b:.3f} m" + _paired(table, "tuned", o, worlds), bool(a >= b), o,
            "clearance")
    if falsified is not None and len(falsified):
        f = falsified.set_index("system")
        ft = f.loc["tuned"] if "tuned" in f.index else None
        for o in others:
            name = "apf" if o == "apf" else "its start"
            if ft is None or o not in f.index:         # no evidence is not a pass
                add(f"the falsification search has no rows for {'the tuned system' if ft is None else name}"
                    ": collision rates not compared", False, o, "collisions under falsification")
                continue
            fo = f.loc[o]
            # a search with no valid world found nothing: no evidence either way
            ok = bool(ft.valid > 0 and fo.valid > 0 and (
                ft.collisions == 0 or ft.collisions_rate <= fo.collisions_rate))
            add(f"an adversarial search ({int(ft.tried)} worlds each, the same seed) makes "
                f"it collide in {_count(int(ft.collisions), int(ft.valid))} valid worlds; "
                f"{name} in {_count(int(fo.collisions), int(fo.valid))}", ok, o,
                "collisions under falsification")
    if t.reached:                    # (to a micrometre: the filter keeps r / 2 to rounding)
        lowest = float(t.min_clearance_reached)
        add(f"keeps at least half the robot radius ({robot_radius / 2:g} m) from obstacles on "
            f"every world it reaches (smallest {lowest:.3f} m)",
            bool(lowest >= robot_radius / 2 - 1e-6), others[0], "clearance margin")
    safety = len(checks)
    for o in others:
        name = "apf" if o == "apf" else "its start"
        add(f"reaches {_count(int(t.reached), n)} {which} worlds; {name} "
            f"{_count(int(s.loc[o, 'reached']), n)}", bool(t.reached >= s.loc[o, "reached"]), o,
            "success")
    if "start" in others:
        add(f"is shorter than its start on the {common} worlds every system reached "
            f"({t.common_length:.3f} vs {s.loc['start', 'common_length']:.3f} m)",
            bool(t.common_length < s.loc["start", "common_length"]), "start", "length")
    unsafe_apf = [k for k in kind.get("apf", []) if k != "success"]
    safe = not unsafe_apf if "apf" in others else not [
        k for k in kind["start"] if k not in ("success", "length")]
    better_start = not kind.get("start")
    # ready only against the baseline: without apf there is nothing to call it ready against
    ready = "apf" in others and safe and better_start and "success" not in kind.get("apf", [])
    def clear(o: str) -> str:
        c = float(s.loc[o, "common_min_clearance"])
        own = float(s.loc[o, "min_clearance_reached"])
        text = f", smallest clearance {c:.3f} m" if math.isfinite(c) else ""
        # closer on a world the others missed (as printed: no 1e-5 differences)
        if math.isfinite(own) and not own >= c and (not math.isfinite(c)
                                                    or f"{own:.3f}" != f"{c:.3f}"):
            text += f" ({own:.3f} m on a world not every system reached)"
        return text

    figures = "; ".join(f"{o} reaches {int(s.loc[o, 'reached'])}, collides {crash[o]}{clear(o)}"
                        for o in ["tuned", *others])
    if common == 0:
        figures += " (no world every system reached: no clearance compared)"
    if "apf" not in others:
        end = ("no apf run to compare with: NOT judged ready to deploy"
               + ("" if better_start else " (and NOT better than its start: "
                  + ", ".join(dict.fromkeys(kind["start"])) + ")"))
    elif ready:
        end = ("no safety figure worse than apf's and better than its start on every figure: "
               "ready to deploy on worlds like these")
    elif not safe:
        worse = ", ".join(dict.fromkeys(unsafe_apf if "apf" in others else kind["start"]))
        end = (f"NOT ready to deploy: less safe than {'apf' if 'apf' in others else 'its start'}"
               f" ({worse})")
    elif not better_start:
        end = ("as safe as apf but NOT better than its start ("
               + ", ".join(dict.fromkeys(kind["start"])) + ")")
    else:
        end = "as safe as apf and better than its start, but reaches fewer worlds than apf"
    head = f"on the {which} set ({n} worlds) {figures} — {end}"
    return {"checks": checks, "better": ready, "safe": safe, "better_than_start": better_start,
            "safety_checks": safety, "headline": head}
